"""A skeleton grown from more bones than asked, its redundant bones merged away (Le & Deng
2014, §5: more bones than needed at the start, the redundant ones pruned).

Found after a free fit of B bones, a skeleton inherits that fit's layout: bones placed to move
freely, some across a bend, whose joints then drift and slide. Here
(:func:`fit_pruned_skeleton`, ``fit-skin --skeleton --surplus-bones S``):

1. a free fit of ``round((1 + S) · B)`` bones (:func:`.skin_fit.fit_skin`): smaller bones are
   more nearly rigid, so more of their joints hold (the horse gallop: 32 of 32 fixed at 33
   bones, 18 of 21 at 22);
2. rounds: the skeleton found on the current rig (:func:`.joints.find_skeleton`: neighbours,
   joints, tree, fixed or sliding), :data:`ROUND_ITERATIONS` jointed iterations
   (:func:`.jointed_fit.fit_jointed`), then merges: every pair of neighbouring bones costed
   exactly, both ways (:func:`merge_costs`), the cheapest made (:func:`cheapest_merges`, up to
   half the bones still in excess, no bone in two of them: each cost was measured with the
   others in place; :func:`merge_bones`), until B bones remain;
3. the jointed fit of those, to convergence.

A merge's cost is exact for everything else held: the rise in Σ_f Σ_i ‖v_i(f) − model_i(f)‖²
when bone a's weights go to b, δ_i(f) = w_ia (T_b(f) − T_a(f)) r̃_i. Merging into any neighbour
and finding the tree again each round, not merging each bone into its tree parent, is what the
walker needed: a small chest bone whose tree parent was an arm took the arm's place in the tree,
and the other arm hung from it. Half the excess per round, not one bone: the horse gallop gave
1.23× the free fit's error in 23 s one by one (parent merges), 1.34× in 12.6 s by halves.

Off by default (``surplus`` 0): measured on the shared captures (docs/skeleton.md) it raises the
fixed joints where the bones are clean (horse gallop 86 % → 95 %, crane 81 % → 90 %, at about the
same error) but costs 2–6× the free fit and raises the error on the elephant (1.48× → 1.68×: every
joint fixed, where the default keeps one sliding). Each round's skeleton is found on the
jointed rig, where last round's joints show no drift; found on bones solved freely for the
round's weights instead, the elephant's joints all stay fixed (1.52×) and the horse loses
(1.30× → 1.40×), so the jointed rig is kept.
"""

import numpy as np

from ..rig.influence import dense_weights

#: Jointed iterations between two rounds of merges.
ROUND_ITERATIONS = 2


def merge_costs(vertices, rest, bone_indices, bone_weights, rotations, translations, pairs):
    """costs (P,): the rise in the squared error Σ_f Σ_i ‖v_i(f) − model_i(f)‖² if the first bone
    of each pair (P, 2) gave its weights to the second, all else held (module notes).

    vertices (F, V, 3), rest (V, 3), bone_indices / bone_weights (V, K), rotations (F, B, 3, 3),
    translations (F, B, 3). With D_f = T_b(f) − T_a(f) (3 × 4) and r̃_i = (r_i, 1), the rise is
    Σ_f tr(D_f M_a D_fᵀ) − 2 ⟨D_f, N_a(f)⟩, M_a = Σ_i w_ia² r̃_i r̃_iᵀ, N_a(f) = Σ_i w_ia e_i(f) r̃_iᵀ
    and e_i(f) the vertex's error: four products over the vertices for every pair at once."""
    R, t = np.asarray(rotations, np.float64), np.asarray(translations, np.float64)
    frames, bones = R.shape[:2]
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    dense = dense_weights(bone_indices, bone_weights, bones)
    T = np.concatenate([R, t[..., None]], axis=-1)  # (F, B, 3, 4)
    homogeneous = np.concatenate([np.asarray(rest, np.float64), np.ones((len(rest), 1))], axis=1)  # (V, 4)
    model = np.einsum("fbxy,vby->fvx", T, dense[:, :, None] * homogeneous[:, None, :], optimize=True)
    error = np.asarray(vertices, np.float64) - model  # (F, V, 3)
    M = np.einsum("vb,vx,vy->bxy", dense ** 2, homogeneous, homogeneous, optimize=True)  # (B, 4, 4)
    N = np.stack([(error * homogeneous[None, :, y, None]).transpose(0, 2, 1).reshape(frames * 3, -1) @ dense
                  for y in range(4)], axis=-1).reshape(frames, 3, bones, 4).transpose(0, 2, 1, 3)  # (F, B, 3, 4)
    a, b = pairs[:, 0], pairs[:, 1]
    D = T[:, b] - T[:, a]  # (F, P, 3, 4)
    return (np.einsum("fpxy,pyz,fpxz->p", D, M[a], D, optimize=True)
            - 2.0 * np.einsum("fpxy,fpxy->p", D, N[:, a], optimize=True))


def merge_bones(bone_indices, bone_weights, rotations, translations, merges):
    """The rig after each ``merges`` (M, 2) pair's first bone gave its weights to the second (no
    bone in two merges): (bone_indices, bone_weights (V, K), each row's K largest kept and summing
    to 1, rotations (F, B − M, 3, 3), translations (F, B − M, 3)), the bones left in their order."""
    merges = np.asarray(merges, dtype=np.int64).reshape(-1, 2)
    bones = np.asarray(rotations).shape[1]
    dense = dense_weights(bone_indices, bone_weights, bones)
    np.add.at(dense.T, merges[:, 1], dense[:, merges[:, 0]].T)
    keep = np.delete(np.arange(bones), merges[:, 0])
    dense = dense[:, keep]
    slots = np.asarray(bone_indices).shape[1]
    indices = np.argsort(-dense, axis=1, kind="stable")[:, :slots]
    weights = np.take_along_axis(dense, indices, axis=1)
    weights /= weights.sum(axis=1, keepdims=True)
    return (indices.astype(np.int32), weights, np.asarray(rotations)[:, keep],
            np.asarray(translations)[:, keep])


def cheapest_merges(pairs, costs, count):
    """Up to ``count`` merges (M, 2) from ``pairs`` (P, 2) by rising ``costs`` (P,), no bone in two
    of them (each cost was measured with every other bone in place)."""
    used, chosen = set(), []
    for p in np.argsort(costs, kind="stable"):
        if len(chosen) == count:
            break
        a, b = (int(x) for x in pairs[p])
        if a not in used and b not in used:
            chosen.append((a, b))
            used.update((a, b))
    return np.array(chosen, dtype=np.int64).reshape(-1, 2)


def fit_pruned_skeleton(vertices, faces, bones, surplus, max_influences=4, iterations=100, rest_frame=0, seed=0,
                        tolerance=0.02, patience=5, joint_steps=0, device=None, max_drift=None, max_sliding_share=None,
                        jointed_iterations=40, diagonal=None, progress=lambda phase, length: None):
    """A jointed rig of ``bones`` bones grown from ``round((1 + surplus)·bones)`` (module notes).

    vertices (F, V, 3), faces (T, 3); the free fit's options as :func:`.skin_fit.fit_skin`'s;
    ``max_drift`` (share of ``diagonal``) and ``max_sliding_share`` as :func:`.joints.find_skeleton`'s. ``progress`` as
    :func:`.rig_fit.fit_rig`'s: phases ``"grow"`` (the larger free fit), ``"prune"`` (one step per
    bone merged) and ``"joints"``. Returns what :func:`.jointed_fit.fit_jointed` does (the
    skeleton's ``drift``: its joints' on the rig of the last merges)."""
    from .jointed_fit import fit_jointed
    from .joints import MAX_JOINT_DRIFT, MAX_SLIDING_SHARE, bone_neighbours, find_skeleton
    from .skin_fit import fit_skin

    start = int(round((1.0 + surplus) * bones))
    max_drift = MAX_JOINT_DRIFT if max_drift is None else max_drift
    max_sliding_share = MAX_SLIDING_SHARE if max_sliding_share is None else max_sliding_share
    free = fit_skin(vertices, start, max_influences=max_influences, iterations=iterations, rest_frame=rest_frame,
                    seed=seed, tolerance=tolerance, patience=patience, joint_steps=joint_steps, device=device,
                    progress=progress("grow", iterations))
    rest = free.rest_vertices
    indices, weights, R, t = free.bone_indices, free.bone_weights, free.rotations, free.translations
    step = progress("prune", start - bones)
    while True:
        skeleton = find_skeleton(rest, faces, indices, weights, R, t, max_drift=max_drift, diagonal=diagonal,
                                 max_sliding_share=max_sliding_share)
        if skeleton.bones == bones:
            break
        fitted, skeleton = fit_jointed(vertices, rest, indices, weights, R, skeleton, faces=faces,
                                       max_influences=max_influences, iterations=ROUND_ITERATIONS, tolerance=0.0,
                                       patience=ROUND_ITERATIONS)
        indices, weights, R, t = fitted.bone_indices, fitted.bone_weights, fitted.rotations, fitted.translations
        pairs, _, _ = bone_neighbours(rest, faces, indices, weights, skeleton.bones)
        pairs = np.concatenate([pairs, pairs[:, ::-1]])
        costs = merge_costs(vertices, rest, indices, weights, R, t, pairs)
        merges = cheapest_merges(pairs, costs, (skeleton.bones - bones + 1) // 2)
        indices, weights, R, t = merge_bones(indices, weights, R, t, merges)
        if step is not None:
            for _ in merges:
                step(0, fitted.rmse)
    return fit_jointed(vertices, rest, indices, weights, R, skeleton, faces=faces, max_influences=max_influences,
                       iterations=jointed_iterations, progress=progress("joints", jointed_iterations))
