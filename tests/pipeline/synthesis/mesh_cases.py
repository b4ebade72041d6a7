"""Irregular meshes and random sparse influences, shared by the key-vertex and deformation-gradient tests."""

import numpy as np
from scipy.spatial import ConvexHull



def irregular_sphere(count=300, seed=0):
    """Random points on a bumpy sphere, triangulated by their convex hull: an irregular mesh."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(count, 3))
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    faces = ConvexHull(x).simplices.astype(np.int64)
    return x * rng.uniform(0.9, 1.1, size=(count, 1)), faces


def random_sparse_weights(count, bones, k, seed=0, zero_fraction=0.3):
    """Random influence lists: distinct bones, some zero slots, rows summing to 1."""
    rng = np.random.default_rng(seed)
    idx = np.argsort(rng.random((count, bones)), axis=1)[:, :k]
    w = rng.random((count, k))
    w[:, 1:] *= rng.random((count, k - 1)) > zero_fraction
    w /= w.sum(axis=1, keepdims=True)
    return idx, w


def dense(idx, w, bones):
    out = np.zeros((idx.shape[0], bones))
    np.add.at(out, (np.arange(idx.shape[0])[:, None].repeat(idx.shape[1], 1), idx), w)
    return out
