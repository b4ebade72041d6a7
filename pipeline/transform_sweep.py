"""The per-bone Procrustes sweep of :func:`.bone_transforms.update_bone_transforms`, compiled.

Each frame's transforms depend only on that frame's sums, so frames run in parallel (numba,
every core) while the bones of one frame are updated in order, Gauss-Seidel, exactly as the
numpy sweep does; the result does not depend on the thread count.
"""

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def _polar_rotation(cross, out):
    """out (3, 3) ← the nearest proper rotation to ``cross`` (as :func:`.rotations.polar_rotation`)."""
    u, _, vt = np.linalg.svd(cross)
    r = u @ vt
    det = (r[0, 0] * (r[1, 1] * r[2, 2] - r[1, 2] * r[2, 1]) - r[0, 1] * (r[1, 0] * r[2, 2] - r[1, 2] * r[2, 0])
           + r[0, 2] * (r[1, 0] * r[2, 1] - r[1, 1] * r[2, 0]))
    if det < 0.0:
        for a in range(3):
            u[a, 2] = -u[a, 2]
        r = u @ vt
    out[:, :] = r


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
