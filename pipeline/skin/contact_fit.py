"""A fit that keeps the capture's ground contacts (issue 64): where the capture's vertices are near
its ground, the fitted rig replays them as the capture has them.

Why a plain fit skates. Zheng eq. 1 weighs every vertex and frame alike, so a few millimetres of
error on a foot cost the fit no more than the same error on a shoulder; but on the ground they are
what a user sees. On the samba (22 bones) the fit's playback slides 2.7× the capture's in the
median and puts 12 % of its contact steps over 0.5 % of the height against the capture's 2.7 %.
Most of those steps are not planted feet moving: they are a swinging foot or a hem fitted a
centimetre low, which enters the contact band while the capture keeps it above, and then slides
as the capture's swinging foot does. So the weight goes to every vertex *near* the ground, planted
or swinging, not to the planted ones alone: a residual there decides both whether the vertex is in
contact and how far it slides.

The weighted fit. Each (frame t, vertex v) whose capture position lies within ``band`` of the
height H above its clip's ground (build-graph's contact height, 2 %) weighs ``1 + weight`` in the
error; every other weighs 1. The weight is lowered where the near pairs would carry more than a
fifth of the weighted error (:func:`contact_weight`): the walker stands on 3.3 % of its pairs,
the horse lying on its side on 7.7 %, and at the full weight their fits lost 12 % of their
accuracy; the samba's 1 % keep the full weight. After the free fit has converged, ``rounds`` rounds of

1. the bone transforms: per-bone weighted Procrustes, Gauss-Seidel over the bones as
   :mod:`.transform_sweep` does, with the near pairs' sums added per frame (their Q varies by
   frame, for the few bones that weigh a near vertex; :func:`contact_sums`);
2. every vertex's weights re-solved for those transforms (the usual solve, :func:`.skin_weights.update_weights`);
3. the near vertices' weights re-solved with their frame weights (a simplex-constrained least
   squares per vertex over its candidate bones, :func:`weighted_vertex_weights`).

Why the defaults hold in general. The band is the height build-graph enters a contact within;
a vertex further up is in no contact band however the fit errs. The weight (20) is where the
samba's playback stops sliding more than its capture (1.04× median, 0.86× p95, 0.50× sliding
steps) at 1.8 % more RMSE; 5 leaves it at 1.37×, 100 costs 5.8 % RMSE for nothing more (issue 64's
closing note). The near pairs are a few per cent of a character that stands on the ground (its
feet), so the rest of the fit keeps its accuracy; a capture with no ground (a swinging bar, a
falling cloth) gets none (the caller decides: fit-skin weighs only clips where build-graph's
contact finder finds a ground). Three rounds: after one the samba's playback still slides
1.13× / 1.70× (p95 / sliding steps), after two 0.99× / 0.74×, after three 0.90× / 0.50×; a round
costs about an iteration of the free fit.

Where the gain comes from: the weighted transforms (step 1) alone give nearly all of it on the
samba (median / p95 / sliding steps 0.93× / 0.89× / 0.52×); the weighted weights (step 3) alone
give none (2.53× / 2.02× / 4.38×), and with the transforms change them by a few per cent (0.97× /
0.85× / 0.50×).
"""

import numpy as np
import scipy.sparse as sp

from ..rig.rotations import polar_rotation
from .skin_weights import sparse_simplex_weights

#: Share of the height above a clip's ground within which a vertex's residual is weighted.
NEAR_BAND = 0.02
#: The extra weight of a near (frame, vertex) pair's residual.
CONTACT_WEIGHT = 20.0
#: Rounds of (transforms, weights) under the weighting after the free fit.
CONTACT_ROUNDS = 3
#: The largest share of the weighted error the near pairs may carry (the weight is lowered to it).
NEAR_SHARE = 0.2


def contact_weight(near_share, weight=CONTACT_WEIGHT, share=NEAR_SHARE):
    """The extra weight of the near pairs when they are ``near_share`` of all (frame, vertex)
    pairs: ``weight``, lowered so that they carry at most ``share`` of the weighted error,
    s (1 + w) / (s (1 + w) + 1 − s) ≤ share (0 where they are that share already: a body lying on
    the floor). Module notes: the rest of the fit keeps its accuracy."""
    if near_share <= 0.0:
        return 0.0
    return float(max(0.0, min(weight, share * (1.0 - near_share) / ((1.0 - share) * near_share) - 1.0)))


def near_ground(vertices, starts, grounds, up_axis, height, band=NEAR_BAND):
    """near (F, V) bool: the capture's vertices (F, V, 3) within ``band`` × ``height`` above (or
    anywhere below) their clip's ground; clip c is frames starts[c] … starts[c+1] − 1, its ground
    grounds[c] (NaN: a clip without one, never near)."""
    vertices = np.asarray(vertices)
    starts = np.asarray(starts, np.int64)
    level = np.repeat(np.asarray(grounds, np.float64), np.diff(starts))  # (F,)
    with np.errstate(invalid="ignore"):
        return vertices[..., up_axis] - level[:, None] <= band * height


def contact_sums(bone_indices, bone_weights, vertices, rest, near, weight, bones):
    """The near pairs' share of the weighted sums: (P (B, F, 3, 4), Q (F, S, S, 4, 4), slot (B,)):
    P[j, t] = weight · Σ_v∈near(t) w_vj v_v(t) ũ_vᵀ and Q[t, s(j), s(k)] = weight · Σ_v∈near(t)
    w_vj w_vk ũ_v ũ_vᵀ over the S bones that weigh some near vertex (slot (B,): s(j), −1 for the
    others), to add to :func:`.transform_sweep.sparse_weighted_sums`' P and Q. Gathered by sparse
    matrix products (scipy's, single-threaded: the same sums on any machine)."""
    frames = near.shape[0]
    t, v = np.nonzero(near)
    k = bone_indices.shape[1]
    touched = np.unique(v)
    used = np.unique(bone_indices[touched][bone_weights[touched] > 0.0])
    slot = np.full(bones, -1, np.int64)
    slot[used] = np.arange(used.size)
    if not v.size:
        return np.zeros((bones, frames, 3, 4)), np.zeros((frames, 0, 0, 4, 4)), slot
    u = np.concatenate([rest[v], np.ones((v.size, 1))], axis=1)  # (n, 4)
    w = weight * bone_weights[v]  # (n, K)
    j = bone_indices[v].astype(np.int64)
    # P: a sparse (B·F, n) matrix of the weights times the pairs' outer products (n, 12)
    rows = (j * frames + t[:, None]).ravel()
    gather = sp.csr_matrix((w.ravel(), (rows, np.repeat(np.arange(v.size), k))), shape=(bones * frames, v.size))
    outer = (vertices[t, v][:, :, None] * u[:, None, :]).reshape(-1, 12)  # (n, 3·4)
    P = np.asarray(gather @ outer).reshape(bones, frames, 3, 4)
    # Q: the same with the pairs' (bone, bone) weight products over (F·S·S) rows and ũũᵀ (n, 16)
    pair = bone_weights[v][:, :, None] * w[:, None, :]  # (n, K, K): w_vj · weight · w_vk
    a, b = slot[j][:, :, None], slot[j][:, None, :]
    live = (pair != 0.0) & (a >= 0) & (b >= 0)
    n_index = np.broadcast_to(np.arange(v.size)[:, None, None], pair.shape)[live]
    rows = ((t[:, None, None] * used.size + a) * used.size + b)[live]
    gather = sp.csr_matrix((pair[live], (rows, n_index)), shape=(frames * used.size ** 2, v.size))
    uu = (u[:, :, None] * u[:, None, :]).reshape(-1, 16)
    Q = np.asarray(gather @ uu).reshape(frames, used.size, used.size, 4, 4)
    return P, Q, slot


def weighted_sweep(transforms, p, q, extra_q, slot):
    """One Gauss-Seidel sweep of per-bone weighted Procrustes, as :func:`.transform_sweep.sweep_bone_transforms`
    (the same order, the same closed form) with a per-frame Q: transforms (F, B, 3, 4), p (B, F,
    3, 4) (the near pairs' P added), q (B, B, 4, 4), extra_q (F, S, S, 4, 4) and slot (B,) from
    :func:`contact_sums`. Vectorised over frames; a loop over the bones (each needs the last's
    update). Returns the updated transforms."""
    T = np.array(transforms, dtype=np.float64, copy=True)
    coupled = q[:, :, 3, 3] > 0.0
    for j in np.flatnonzero(np.diag(coupled)):
        others = np.flatnonzero(coupled[:, j] & (np.arange(q.shape[0]) != j))
        moment = p[j] - np.einsum("fkac,kcd->fad", T[:, others], q[others, j])
        second = np.broadcast_to(q[j, j], (T.shape[0], 4, 4))
        if slot[j] >= 0:  # the bones j shares a near vertex with: their per-frame coupling
            linked = np.flatnonzero(slot >= 0)
            linked = linked[linked != j]
            moment = moment - np.einsum("fkac,fkcd->fad", T[:, linked], extra_q[:, slot[linked], slot[j]])
            second = second + extra_q[:, slot[j], slot[j]]
        mass = second[:, 3, 3]
        mean = second[:, :3, 3] / mass[:, None]
        cross = moment[..., :3] - moment[..., 3][:, :, None] * mean[:, None, :]
        rotation = polar_rotation(cross)
        T[:, j, :, :3] = rotation
        T[:, j, :, 3] = moment[..., 3] / mass[:, None] - np.einsum("fab,fb->fa", rotation, mean)
    return T


def weighted_vertex_weights(transforms, vertices, rest, near, weight, bone_indices, bone_weights, max_influences,
                            candidates=None, block_bytes=1 << 26):
    """Weights of the vertices ever near the ground, solved with their frame weights: each such
    vertex v minimises Σ_t ω_tv |Σ_j w_j T_tj ũ_v − v_v(t)|² (ω = 1 + weight where near, else 1)
    over w ≥ 0, Σ w = 1, first over its ``candidates`` best single bones (by that error; its
    current bones always among them, so the error cannot grow), then over the ``max_influences``
    largest, as :func:`.skin_weights.update_weights` does unweighted. transforms (F, B, 3, 4);
    vertices (F, V, 3); near (F, V). Returns (vertex ids (n,), bone_indices (n, K) int32,
    bone_weights (n, K), squared_error (n,): Σ_t |v̂ − v|² unweighted), columns by decreasing weight;
    vertices in blocks of ``block_bytes``."""
    frames, bones = transforms.shape[:2]
    k = min(max_influences, bones)
    c = min(bones, max(candidates or 2 * k, k))
    ids = np.flatnonzero(near.any(axis=0))
    out_i = np.zeros((ids.size, k), np.int32)
    out_w = np.zeros((ids.size, k))
    out_e = np.zeros(ids.size)
    gram_frames = np.einsum("fbia,fbic->fbac", transforms, transforms).reshape(frames, bones * 16)  # T_fbᵀ T_fb
    images = transforms.transpose(0, 2, 3, 1).reshape(frames * 12, bones)  # T_fb as (F·3·4, B) columns
    step = max(1, int(block_bytes // (frames * 8 * max(12 * c, bones))))
    for s in range(0, ids.size, step):
        v = ids[s:s + step]
        u = np.concatenate([rest[v], np.ones((v.size, 1))], axis=1)
        omega = 1.0 + weight * near[:, v].T  # (n, F)
        y = vertices[:, v].transpose(1, 0, 2)  # (n, F, 3)
        # each bone's weighted error Σ_f ω |T_fb ũ − y|² = ũᵀ (Σ ω TᵀT) ũ − 2 Σ ω yᵀ T ũ + Σ ω |y|², as products
        quadratic = np.einsum("nbk,nk->nb", (omega @ gram_frames).reshape(v.size, bones, 16),
                              (u[:, :, None] * u[:, None, :]).reshape(v.size, 16))
        cross = ((omega[:, :, None] * y)[:, :, :, None] * u[:, None, None, :]).reshape(v.size, frames * 12) @ images
        error = quadratic - 2.0 * cross + np.einsum("nf,nfi,nfi->n", omega, y, y)[:, None]
        rows = np.arange(v.size)[:, None]
        error[rows, bone_indices[v]] = np.where(bone_weights[v] > 0.0, -np.inf, error[rows, bone_indices[v]])
        chosen = np.argsort(error, axis=1, kind="stable")[:, :c]
        Ac = np.einsum("fncij,nj->nfic", transforms[:, chosen], u)  # (n, F, 3, c): the candidates' images
        gram = np.einsum("nf,nfia,nfib->nab", omega, Ac, Ac)
        linear = np.einsum("nf,nfia,nfi->na", omega, Ac, y)
        current = np.zeros((v.size, bones))
        current[rows, bone_indices[v]] = bone_weights[v]
        start = current[rows, chosen]
        start = np.where(start.sum(axis=1, keepdims=True) > 0.0, start, 1.0 / c)
        chosen, w, _, _ = sparse_simplex_weights(gram, linear, chosen, start, k, again=True)
        out_i[s:s + step], out_w[s:s + step] = chosen, w
        fitted = np.einsum("fnkij,nj,nk->nfi", transforms[:, chosen], u, w)
        out_e[s:s + step] = np.einsum("nfi,nfi->n", fitted - y, fitted - y)
    return ids, out_i, out_w, out_e


def keep_contacts(fit, vertices, near, weight=CONTACT_WEIGHT, rounds=CONTACT_ROUNDS, max_influences=4,
                  candidates=None, device=None, progress=None):
    """The free fit (a :class:`.skin_fit.SkinFit` of vertices (F, V, 3)) refitted with the
    residuals of the ``near`` (F, V) pairs weighted 1 + ``weight`` (lowered by
    :func:`contact_weight`; module notes): ``rounds`` rounds
    of transforms, every vertex's weights, the near vertices' weighted weights. ``device``: the
    weight solve's (None: compiled on the CPU); ``progress(round, rmse)`` after each round. Returns a new SkinFit (its rmse unweighted, over
    every vertex and frame; error_history extended by one entry per round)."""
    from dataclasses import replace

    from .bone_transforms import Trajectories
    from .skin_weights import update_weights
    from .transform_sweep import sparse_weighted_sums

    vertices = np.asarray(vertices, dtype=np.float64)
    near = np.asarray(near, dtype=bool)
    weight = contact_weight(float(near.mean()) if near.size else 0.0, weight)
    if rounds < 1 or weight <= 0.0:
        return fit
    rest = fit.rest_vertices
    bones = fit.rotations.shape[1]
    data = Trajectories(vertices, rest)
    transforms = np.concatenate([fit.rotations, fit.translations[..., None]], axis=-1)
    indices, weights = fit.bone_indices, fit.bone_weights
    history = list(fit.error_history)
    for _ in range(rounds):
        p, q = sparse_weighted_sums(indices, weights, data, bones)
        extra_p, extra_q, slot = contact_sums(indices, weights, vertices, rest, near, weight, bones)
        transforms = weighted_sweep(transforms, p + extra_p, q, extra_q, slot)
        indices, weights, error = update_weights(transforms, data, indices, weights, max_influences, candidates,
                                                 device=device)
        ids, near_indices, near_weights, near_error = weighted_vertex_weights(
            transforms, vertices, rest, near, weight, indices, weights, max_influences, candidates)
        indices, weights, error = (np.array(a, copy=True) for a in (indices, weights, error))
        indices[ids], weights[ids], error[ids] = near_indices, near_weights, near_error
        history.append(float(np.sqrt(error.sum() / error.size / vertices.shape[0])))
        if progress is not None:
            progress(len(history) - len(fit.error_history), history[-1])
    return replace(fit, bone_indices=indices, bone_weights=weights, rotations=transforms[..., :3],
                   translations=transforms[..., 3], rmse=history[-1], error_history=history,
                   iterations=fit.iterations + rounds)


#: playback_feet measures the vertices that come within this share of the height of their clip's
#: ground in some captured frame (module notes of :func:`playback_feet`).
MEASURED_BAND = 0.1


def playback_feet(fit, vertices, starts, up_axis, block=64):
    """How the fit's playback of its capture keeps the capture's feet (issue 64; definitions in
    docs/contact.md, :mod:`~skinsynth.pipeline.mesh.contact_measures`): the capture's vertices (F,
    V, 3) and the fit's (skinned in blocks of ``block`` frames) measured against the capture's
    ground of each clip (clip c: frames starts[c] … starts[c+1] − 1), over the rest pose's height
    along ``up_axis`` (an index). Only the vertices that come within :data:`MEASURED_BAND` (10 %)
    of the height of the ground in some captured frame are skinned and measured: a contact vertex
    lies within 1 %, so the capture's figures are exact, and the playback's are unless the fit
    errs by 9 % of the height at a vertex (a fit that broke). Returns a dict: capture, playback
    (the measures' summary less the acceleration, which needs every vertex: slide median and 95th
    percentile, sliding share, float, penetration) and ratios (playback over capture)."""
    from skinsynth.gpu import lbs_reference

    from ..mesh.contact_measures import character_height, clip_ground, input_steps, ratios, steps_of_input, summary

    height = character_height(fit.rest_vertices, up_axis)
    starts = np.asarray(starts, np.int64)
    grounds = np.array([clip_ground(vertices[a:b], up_axis) for a, b in zip(starts[:-1], starts[1:])])
    measured = np.flatnonzero(near_ground(vertices, starts, grounds, up_axis, height, MEASURED_BAND).any(axis=0))
    capture = input_steps(vertices[:, measured], starts, height, up_axis, block, grounds=grounds)
    played = np.concatenate([lbs_reference(fit.rest_vertices[measured], fit.bone_indices[measured],
                                           fit.bone_weights[measured], fit.rotations[s:s + block],
                                           fit.translations[s:s + block])
                             for s in range(0, fit.rotations.shape[0], block)])
    playback = input_steps(played, starts, height, up_axis, block, grounds=grounds)
    figures = {side: {k: v for k, v in summary(steps_of_input(table, starts)).items() if k != "largest_accel"}
               for side, table in (("capture", capture), ("playback", playback))}
    figures["ratios"] = {k: v for k, v in ratios(figures["playback"], figures["capture"]).items() if k != "largest_accel"}
    return figures
