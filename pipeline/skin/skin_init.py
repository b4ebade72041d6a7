"""Clustering initialisation of a skinning decomposition: exactly B rigid clusters of vertices.

Le & Deng 2012 start from rigid clusters; Dem Bones grows them by LBG vector quantisation but
can stop short of the bone count asked for. Here clusters are split until there are exactly
``bones`` of them:

1. start with one cluster holding every vertex;
2. each round, split the clusters that explain their vertices worst (at most as many as bones are
   still missing): a new bone takes the quarter of the cluster nearest (in the rest pose) to a seed
   vertex drawn with probability proportional to its error (k-means++ style; the only random
   choice, driven by ``seed``);
3. refine by a few k-means steps in transform space: fit one rigid transform per cluster and
   frame, relabel every vertex by the bone whose transforms reproduce its trajectory best,
   discard emptied clusters;
4. if rounds run out before B clusters survive relabelling, finish with splits that are not
   relabelled, which always succeed while B ≤ V.
"""

import numpy as np

from .bone_transforms import fit_cluster_transforms, single_bone_errors


def split_off(labels, members, seed_vertex, label, rest, neighbourhood=4):
    """Give ``label`` to the 1/``neighbourhood`` of a cluster's ``members`` nearest (in the rest
    pose, rest (V, 3)) to ``seed_vertex``, in ``labels`` (V,) in place: a new bone's first cluster."""
    distance = np.linalg.norm(rest[members] - rest[seed_vertex], axis=1)
    # Stable sort: ties broken by vertex order, so the split is deterministic given the seed.
    labels[members[np.argsort(distance, kind="stable")[: max(1, members.size // neighbourhood)]]] = label


def _split(labels, n_clusters, errors, order, rest, rng, neighbourhood=4):
    """Split the clusters listed in ``order``; return the new labels and cluster count."""
    labels = labels.copy()
    for cluster in order:
        members = np.flatnonzero(labels == cluster)
        if members.size < 2:
            continue
        weight = errors[members]
        prob = weight / weight.sum() if weight.sum() > 0.0 else None
        split_off(labels, members, members[rng.choice(members.size, p=prob)], n_clusters, rest, neighbourhood)
        n_clusters += 1
    return labels, n_clusters


def relabel(labels, n_clusters, data):
    """k-means step in transform space; returns compacted labels and the surviving count."""
    transforms = fit_cluster_transforms(labels, n_clusters, data)
    labels = np.argmin(single_bone_errors(transforms, data), axis=1)
    used, labels = np.unique(labels, return_inverse=True)
    return labels, used.size


def initial_clusters(data, rest, bones, seed=0, rounds=None, kmeans_steps=3):
    """Labels (V,) assigning each vertex to one of exactly ``bones`` clusters.

    data: :class:`~.bone_transforms.Trajectories`; rest (V, 3). ``rounds`` bounds the
    split-and-relabel rounds (default 2·log2(B) + 4). Raises ValueError if bones > V.
    """
    if bones > data.count:
        raise ValueError(f"{bones} bones need at least as many vertices; the mesh has {data.count}")
    rng = np.random.default_rng(seed)
    labels = np.zeros(data.count, dtype=np.int64)
    n_clusters = 1
    rounds = int(2 * np.log2(max(bones, 2))) + 4 if rounds is None else rounds
    for _ in range(rounds):
        if n_clusters >= bones:
            break
        transforms = fit_cluster_transforms(labels, n_clusters, data)
        errors = single_bone_errors(transforms, data)[np.arange(data.count), labels]
        cluster_error = np.bincount(labels, weights=errors, minlength=n_clusters)
        sizes = np.bincount(labels, minlength=n_clusters)
        cluster_error[sizes < 2] = -1.0
        order = np.argsort(-cluster_error, kind="stable")[: bones - n_clusters]
        labels, n_clusters = _split(labels, n_clusters, errors, order[cluster_error[order] >= 0.0], rest, rng)
        for _ in range(kmeans_steps):
            labels, n_clusters = relabel(labels, n_clusters, data)
    while n_clusters < bones:
        # Largest clusters first: each split is guaranteed to leave two non-empty halves.
        sizes = np.bincount(labels, minlength=n_clusters)
        order = np.argsort(-sizes, kind="stable")[: bones - n_clusters]
        transforms = fit_cluster_transforms(labels, n_clusters, data)
        errors = single_bone_errors(transforms, data)[np.arange(data.count), labels]
        labels, n_clusters = _split(labels, n_clusters, errors, order, rest, rng)
    if n_clusters > bones:
        raise AssertionError("initial_clusters produced more clusters than asked")
    return labels
