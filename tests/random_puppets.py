"""Random puppets and rigid frames for the kernel tests of the puppet's run time and the correctives' tests."""

import numpy as np

import skinsynth.gpu as gpu
from skinsynth.pipeline.rig.rotations import rigid_to_dual_quaternion

from rigs import random_skin


def relative_error(got, expected):
    """Largest absolute difference over the data's scale (its largest absolute value)."""
    assert got.shape == expected.shape and got.dtype == np.float64
    return np.abs(got - expected).max() / max(np.abs(expected).max(), 1e-30)


def random_rotations(rng, shape):
    q, r = np.linalg.qr(rng.normal(size=shape + (3, 3)))
    q = q * np.sign(np.diagonal(r, axis1=-2, axis2=-1))[..., None, :]
    return q * np.sign(np.linalg.det(q))[..., None, None]


def random_dual_quaternions(rng, samples, bones, flip=True, scale=1.0):
    """Unit dual quaternions scaled by `scale` (the skinning normalises), half of them negated."""
    dq = rigid_to_dual_quaternion(random_rotations(rng, (samples, bones)), rng.normal(size=(samples, bones, 3)) * 2)
    if flip:
        dq *= np.where(rng.random((samples, bones, 1)) < 0.5, -1.0, 1.0)
    return dq * scale


def random_rigid_frames(rng, samples):
    frames = np.zeros((samples, 4, 4))
    frames[:, :3, :3] = random_rotations(rng, (samples,))
    frames[:, :3, 3] = rng.normal(size=(samples, 3)) * 5.0
    frames[:, 3, 3] = 1.0
    return frames


def random_puppet(rng, kind, influences=4, verts=400, bones=10, n_p=15, n_c=4, solver=True):
    rest, idx, w = random_skin(rng, verts, bones, influences)
    # M, m around a unit dual quaternion per bone, so predictions stay away from |q0| = 0
    base = random_dual_quaternions(rng, 1, bones)[0].reshape(-1)
    return gpu.PuppetArrays(
        rest_vertices=rest, bone_indices=idx, bone_weights=w, training_controls=rng.normal(size=(n_p, 3 * n_c)) * 0.3,
        kernel=kind, offset=0.2, degree=5, predictor=rng.normal(size=(8 * bones, n_p)) * 0.05, bias=base,
        rotation_operator=rng.normal(size=(bones, bones, 3)) * 0.1 if solver else None,
        control_operator=rng.normal(size=(bones, n_c)) * 0.2 if solver else None,
        prior_operator=rng.normal(size=(bones, bones)) * 1e-4 if solver else None)
