"""Random but well-formed skinning rigs and skin-fit problems for the kernel and fit tests."""

import numpy as np

from skinsynth.pipeline.rig.rotations import rotation_exp
from skinsynth.pipeline.skin.bone_transforms import Trajectories
from skinsynth.pipeline.skin.skin_weights import update_weights


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


def random_problem(seed, frames=12, count=400, bones=7, noise=0.02):
    """Trajectories of vertices skinned by random rigid bones with random sparse weights, plus
    noise, and the bones' transforms (F, B, 3, 4); current weights are one random bone each."""
    rng = np.random.default_rng(seed)
    rest = rng.normal(size=(count, 3))
    rotations = rotation_exp(rng.normal(scale=0.6, size=(frames, bones, 3)))
    translations = rng.normal(size=(frames, bones, 3))
    transforms = np.concatenate([rotations, translations[..., None]], axis=-1)
    weights = rng.random((count, bones)) * (rng.random((count, bones)) < 0.4)
    weights[np.arange(count), rng.integers(0, bones, count)] += 0.5
    weights /= weights.sum(axis=1, keepdims=True)
    homogeneous = np.c_[rest, np.ones(count)]
    vertices = np.einsum("vb,fbij,vj->fvi", weights, transforms, homogeneous)
    vertices += noise * rng.normal(size=vertices.shape)
    current = rng.integers(0, bones, (count, 1)).astype(np.int32)
    return transforms, Trajectories(vertices, rest), current, np.ones((count, 1))


def sweep_problem(seed, frames, unused):
    """(start transforms (F, B, 3, 4) off the truth, P, Q) of a random problem's fitted weights,
    bone ``unused`` given no weight (it must keep its transform)."""
    from skinsynth.pipeline.skin.bone_transforms import weighted_sums

    transforms, data, indices, weights = random_problem(seed, frames=frames)
    indices, weights, _ = update_weights(transforms, data, indices, weights, 3, solver="numpy")
    dense = np.zeros((data.count, transforms.shape[1]))
    np.put_along_axis(dense, indices, weights, axis=1)
    dense[:, unused] = 0.0
    p, q = weighted_sums(dense, data)
    return transforms + 0.1 * np.random.default_rng(seed).normal(size=transforms.shape), p, q
