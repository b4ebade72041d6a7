"""How much each bone carries of a skin: weight sums, dense weights and weighted rest centroids (the "most
influential bone" of Zheng §3.2 is the largest sum). A floor module: synthesis's transitions and
the engine skeleton's root motion both use it."""

import numpy as np


def weight_sums(bone_indices, bone_weights, bones):
    """Σ_v w_vb per bone: bone_indices (V, K), bone_weights (V, K) -> (B,)."""
    return np.bincount(np.asarray(bone_indices).ravel(), weights=np.asarray(bone_weights, float).ravel(),
                       minlength=bones)[:bones]


def dense_weights(bone_indices, bone_weights, bones):
    """Sparse skin weights (V, K) -> dense (V, B)."""
    idx = np.asarray(bone_indices, dtype=np.int64)
    w = np.asarray(bone_weights, dtype=np.float64)
    dense = np.zeros((idx.shape[0], bones))
    np.add.at(dense, (np.repeat(np.arange(idx.shape[0]), idx.shape[1]), idx.ravel()), w.ravel())
    return dense


def bone_centroids(rest, bone_indices, bone_weights, bones):
    """Each bone's weighted rest centroid Σ_v w_vb ū_v / Σ_v w_vb: rest (V, 3) -> (B, 3) (a bone
    without weight gets the origin)."""
    mass = weight_sums(bone_indices, bone_weights, bones)
    centre = np.stack([np.bincount(np.asarray(bone_indices).ravel(), minlength=bones,
                                   weights=(np.asarray(bone_weights, float) * np.asarray(rest)[:, a, None]).ravel())[:bones]
                       for a in range(3)], axis=1)
    return centre / np.maximum(mass, 1e-300)[:, None]


def most_influential_bone(bone_indices, bone_weights, bones):
    """The bone with the largest Σ_v w_vb (ties: the lowest id), and its rest centroid is the
    pivot of its ground motion."""
    return int(np.argmax(weight_sums(bone_indices, bone_weights, bones)))
