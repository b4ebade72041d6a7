"""The transform step of the skin fit, compiled: the per-bone Procrustes sweep of
:func:`.bone_transforms.update_bone_transforms` and the vertex sums it needs
(:func:`.bone_transforms.weighted_sums`).

Each frame's transforms depend only on that frame's sums, so frames run in parallel (numba,
every core) while the bones of one frame are updated in order, Gauss-Seidel, exactly as the
numpy sweep does; the result does not depend on the thread count.
"""

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def _polar_rotation(cross, out):
    """out (3, 3) ← the nearest proper rotation to ``cross`` (as :func:`.rotations.polar_rotation`).

    The products go through ``np.dot(a, b, out)`` (the same BLAS call as ``@``): numba's ``@``
    compiles shape checks whose error messages add 5 s to the first compile."""
    u, _, vt = np.linalg.svd(cross)
    np.dot(u, vt, out)
    det = (out[0, 0] * (out[1, 1] * out[2, 2] - out[1, 2] * out[2, 1])
           - out[0, 1] * (out[1, 0] * out[2, 2] - out[1, 2] * out[2, 0])
           + out[0, 2] * (out[1, 0] * out[2, 1] - out[1, 1] * out[2, 0]))
    if det < 0.0:
        for a in range(3):
            u[a, 2] = -u[a, 2]
        np.dot(u, vt, out)


@numba.njit(cache=True, parallel=True, nogil=True)
def _sweep(transforms, p, q, order, coupled):
    frames, bones = transforms.shape[:2]
    for t in numba.prange(frames):
        moment = np.empty((3, 4))
        cross = np.empty((3, 3))
        rotation = np.empty((3, 3))
        for j in order:
            for a in range(3):
                for d in range(4):
                    total = p[j, t, a, d]
                    for k in range(bones):
                        if k != j and coupled[k, j]:
                            for c in range(4):
                                total -= transforms[t, k, a, c] * q[k, j, c, d]
                    moment[a, d] = total
            mass = q[j, j, 3, 3]
            for a in range(3):
                for b in range(3):
                    cross[a, b] = moment[a, b] - moment[a, 3] * q[j, j, b, 3] / mass
            _polar_rotation(cross, rotation)
            for a in range(3):
                shift = moment[a, 3] / mass
                for b in range(3):
                    transforms[t, j, a, b] = rotation[a, b]
                    shift -= rotation[a, b] * q[j, j, b, 3] / mass
                transforms[t, j, a, 3] = shift


def sweep_bone_transforms(transforms, p, q):
    """One Gauss-Seidel sweep of per-bone weighted Procrustes: transforms (F, B, 3, 4), p (B, F,
    3, 4), q (B, B, 4, 4) -> the updated transforms (F, B, 3, 4); bones without weight keep theirs."""
    coupled = q[:, :, 3, 3] > 0.0
    order = np.flatnonzero(np.diag(coupled)).astype(np.int64)
    out = np.array(transforms, dtype=np.float64, order="C", copy=True)
    _sweep(out, np.ascontiguousarray(p, dtype=np.float64), np.ascontiguousarray(q, dtype=np.float64), order, coupled)
    return out


@numba.njit(cache=True, parallel=True, nogil=True)
def _sums(bone_indices, bone_weights, rest_h, flat, members, starts, p, q):
    """p (B, 4, F·3): Σ_i w_ij ũ_ic v_i(t)_a at [j, c, (t, a)], the innermost loop along the vertex's
    contiguous trajectory (vectorised: 40 % faster than along ũ, the same sums bit for bit)."""
    bones, columns = p.shape[0], p.shape[2]
    k = bone_indices.shape[1]
    for j in numba.prange(bones):
        for m in range(starts[j], starts[j + 1]):
            i, slot = members[m] // k, members[m] % k
            w = bone_weights[i, slot]
            for c in range(4):
                h = rest_h[i, c]
                for column in range(columns):
                    p[j, c, column] += (w * flat[i, column]) * h
            for other in range(k):
                ww = w * bone_weights[i, other]
                if ww != 0.0:
                    target = bone_indices[i, other]
                    for c in range(4):
                        for d in range(4):
                            q[j, target, c, d] += ww * rest_h[i, c] * rest_h[i, d]


def sparse_weighted_sums(bone_indices, bone_weights, data, bones):
    """The sums of :func:`.bone_transforms.weighted_sums` from sparse weights (V, K): P (B, F, 3,
    4), Q (B, B, 4, 4). Bones in parallel, each summing its vertices in index order, so the sums
    do not depend on the thread count."""
    k = bone_indices.shape[1]
    used = bone_weights.ravel() != 0.0
    flat_bones = bone_indices.ravel()
    members = np.flatnonzero(used)  # entries i*K + slot, grouped by bone below, vertex order kept
    members = members[np.argsort(flat_bones[members], kind="stable")].astype(np.int64)
    starts = np.searchsorted(flat_bones[members], np.arange(bones + 1)).astype(np.int64)
    p = np.zeros((bones, 4, data.frames * 3))
    q = np.zeros((bones, bones, 4, 4))
    _sums(np.ascontiguousarray(bone_indices, dtype=np.int64), np.ascontiguousarray(bone_weights, dtype=np.float64),
          data.homogeneous, data.flat, members, starts, p, q)
    return np.ascontiguousarray(p.reshape(bones, 4, data.frames, 3).transpose(0, 2, 3, 1)), q
