"""Random but well-formed skinning rigs for the kernel tests."""

import numpy as np


def random_skin(rng, verts, bones, influences, offset=1.0):
    """rest (V, 3), bone_indices (V, K) and weights (V, K) summing to 1, with padding slots
    (weight 0, index −1) that kernels must ignore."""
    rest = rng.normal(size=(verts, 3)) * [1.0, 2.0, 0.5] + offset
    idx = np.stack([rng.permutation(bones)[:influences] for _ in range(verts)])
    w = rng.random((verts, influences))
    if influences > 1:
        pad = rng.random((verts, influences)) < 0.3
        pad[:, 0] = False
        w[pad] = 0.0
        idx[pad] = -1
    return rest, idx, w / w.sum(axis=1, keepdims=True)
