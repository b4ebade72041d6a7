"""Bones of a free fit that are no part of the body, put where the fit lacks one (issue 65).

A free fit (:mod:`.skin_fit`) settles in a local minimum: on a character built of rigid parts it
often spends a bone as a *blend helper*, a bone with weight on the vertices between two others
but the heaviest on none of them, while a part of the body has no bone of its own (the generated
humanoid's neck, merged into its head or chest; a quadruped's hoof, into its shin). The skeleton
found from such a layout inherits it: the merged part's joints are missing, and the helper is a
joint no animator can find on the mesh.

So before a skeleton is found (``fit-skin --skeleton``), :func:`reseed_helpers` gives every
bone that dominates no vertex a new place: the half of the worst-fitted bone's vertices nearest its
worst vertex (where the fit most lacks a bone), with the rigid motion of those vertices, then goes
on with the fit from there (:func:`.skin_fit.fit_skin` ``start``). The new layout is kept only
where its error is lower (:data:`HELPER_ROUNDS` rounds at most, each ending when one does not
lower it). A capture whose bones all dominate vertices (the samba, the crane, the horses, the
elephant, the cow) is left untouched, bit for bit.

Measured (``python benchmarks/skeleton_truth.py``, the generated humanoid and quadruped at three
limb lengths and three seeds, ``fit-skin --bones B --skeleton`` with B the true bone count): the
free fits left two or three helpers on most of them; reseeded, their error fell 2–5× (the
humanoid's, seed 0, 2.3e-3 → 4.8e-4 of the diagonal), the parts merged away went from 1–3 to 0–2
per character, the trees' right parents from 75–100 % to 88–100 %, joints within 3 % of the height
from 79–100 % to 87–100 %, the chains named right from 61–94 % to 89–100 %.
"""

import numpy as np

from ..rig.influence import dense_weights
from .bone_transforms import Trajectories, fit_cluster_transforms

#: Rounds of reseeding at most (each one a fit from the reseeded layout to its stopping rule).
HELPER_ROUNDS = 3


def vertex_errors(fit, vertices):
    """(V,): each vertex's squared error over the frames of a fit (:class:`.skin_fit.SkinFit`) of
    ``vertices`` (F, V, 3), its skin played by the project's LBS (``gpu.lbs_reference``, as
    :func:`.skin_fit.finish_fit` measures a fit)."""
    from skinsynth.gpu import lbs_reference

    model = lbs_reference(fit.rest_vertices, fit.bone_indices, fit.bone_weights, fit.rotations, fit.translations)
    return ((vertices - model) ** 2).sum(axis=(0, 2))


def reseeded_layout(fit, vertices):
    """(bone_indices (V, K), bone_weights (V, K), transforms (F, B, 3, 4)): ``fit``'s rig with each
    bone that dominates no vertex moved to the half of the worst-fitted bone's vertices nearest its
    worst vertex (module notes), one helper after the other (the vertices given to one are no
    longer the worst for the next), or None where every bone dominates a vertex."""
    bones = fit.rotations.shape[1]
    dense = dense_weights(fit.bone_indices, fit.bone_weights, bones)
    owner = np.argmax(dense, axis=1)
    helpers = np.flatnonzero(np.bincount(owner, minlength=bones) == 0)
    if helpers.size == 0:  # the model's error is needed only where a helper is moved
        return None
    errors = vertex_errors(fit, vertices)
    transforms = np.concatenate([fit.rotations, fit.translations[..., None]], axis=-1)
    rest = fit.rest_vertices
    data = Trajectories(vertices, rest)
    transforms = transforms.copy()
    for helper in helpers:
        dense[:, helper] = 0.0
        worst = int(np.argmax(np.bincount(owner, weights=errors, minlength=bones)))
        mine = np.flatnonzero(owner == worst)
        seed = mine[np.argmax(errors[mine])]
        near = mine[np.argsort(np.linalg.norm(rest[mine] - rest[seed], axis=1), kind="stable")[:max(3, mine.size // 2)]]
        labels = np.zeros(len(rest), dtype=np.int64)
        labels[near] = 1
        transforms[:, helper] = fit_cluster_transforms(labels, 2, data)[:, 1]
        dense[near] = 0.0
        dense[near, helper] = 1.0
        owner[near], errors[near] = helper, 0.0
    slots = fit.bone_indices.shape[1]
    indices = np.argsort(-dense, axis=1, kind="stable")[:, :slots]
    weights = np.take_along_axis(dense, indices, axis=1)
    return indices.astype(np.int32), weights / weights.sum(axis=1, keepdims=True), transforms


def reseed_helpers(fit, vertices, fit_from, rounds=HELPER_ROUNDS):
    """The free ``fit`` of ``vertices`` (F, V, 3) with its helper bones reseeded (module notes):
    ``fit_from(start)`` goes on with the fit from a layout (:func:`reseeded_layout`'s), as
    :func:`.skin_fit.fit_skin` ``start`` does; its result is kept where its RMSE is lower, up to
    ``rounds`` times. Returns the best fit (``fit`` itself when no bone is a helper)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    for _ in range(rounds):
        start = reseeded_layout(fit, vertices)
        if start is None:
            break
        again = fit_from(start)
        if not again.rmse < fit.rmse:
            break
        fit = again
    return fit
