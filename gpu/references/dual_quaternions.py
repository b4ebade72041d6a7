"""Quaternion and dual-quaternion arithmetic in numpy: the lowest floor, shared by the kernels'
numpy references here and by ``pipeline`` (which imports them through ``pipeline.rotations``).

Conventions: quaternions scalar first ``(w, x, y, z)``; a dual quaternion is 8 numbers, the real
quaternion then the dual one, ``q0 + ε qe`` with ``qe = ½ (0, t) q0`` (Kavan et al. 2007, Feng §4.3).
"""

import numpy as np


def quaternion_to_matrix(quaternions):
    """quaternions (..., 4), (w, x, y, z), any non-zero length -> rotations (..., 3, 3)."""
    shape = quaternions.shape[:-1]
    q = quaternions.reshape(-1, 4)
    xyzw = np.concatenate([q[:, 1:], q[:, :1]], axis=1)
    from scipy.spatial.transform import Rotation  # here: scipy.spatial costs every command ~0.5 s to import

    return Rotation.from_quat(xyzw).as_matrix().reshape(shape + (3, 3))


def quaternion_multiply(a, b):
    """Hamilton product of (..., 4) quaternions in (w, x, y, z) order."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], axis=-1)


def dual_quaternion_to_rigid(dual_quaternions):
    """dual quaternions (..., 8), not necessarily unit -> (rotations (..., 3, 3), translations (..., 3)).

    The dual quaternion is normalised first (divide both parts by ``|q0|``), as blending
    and regression leave it off the unit sphere.
    """
    q0 = dual_quaternions[..., :4]
    qe = dual_quaternions[..., 4:]
    norm = np.linalg.norm(q0, axis=-1, keepdims=True)
    q0 = q0 / norm
    qe = qe / norm
    conj = q0 * np.array([1.0, -1.0, -1.0, -1.0])
    t = 2.0 * quaternion_multiply(qe, conj)[..., 1:]
    return quaternion_to_matrix(q0), t


def with_translations(dual_quaternions, translations):
    """Unit dual quaternions (..., 8) with their dual part rebuilt from translations (..., 3)."""
    pure = np.concatenate([np.zeros(translations.shape[:-1] + (1,)), translations], axis=-1)
    real = dual_quaternions[..., :4]
    return np.concatenate([real, 0.5 * quaternion_multiply(pure, real)], axis=-1)
