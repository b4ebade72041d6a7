"""Transition candidates of one clip, or of several clips of one character, from its fitted LBS
model (Zheng §3.2).

Inputs are a fitted LBS model: ``bone_indices (V, K)`` int, ``bone_weights (V, K)`` (≥ 0, rows sum
to 1, zero padding), ``rotations (F, B, 3, 3)`` and ``translations (F, B, 3)`` acting on column
vectors, ``v = Σ_k w_k (R_k ū + t_k)`` (Zheng eq. 1).

Steps, each a function here:

1. :func:`reference_bone`: the most influential bone b_r (largest Σ_v w_vb).
2. :func:`local_frame_positions`: every other bone in b_r's frame (eq. 2); this removes any rigid
   transform of the whole mesh, per frame.
3. :func:`reduced_coordinates`: per bone ``p = [t; Φ(R)]`` (eq. 3), stacked into A_r (6B' × F),
   truncated SVD (eq. 4), one reduced vector q_i per frame.
4. :func:`reference_motion`: b_r's own frame-to-frame motion r_i in its local frame (eq. 6).
5. :func:`transition_costs`: D(i, j) for all pairs of frames (eq. 5), and :func:`start_costs`:
   D(i, −1), every frame against a virtual frame −1 before the clip's start (below).
6. :func:`transition_threshold` and :func:`candidate_transitions`: T_c, and the pairs below it
   that are local minima of D.

:func:`find_transitions` runs them all. Choices the paper leaves open, made here:

- SVD truncation "thresholded at 0.005" is read as a *relative* cut: keep singular values
  σ_k ≥ 0.005 σ_1 (an absolute cut would depend on the units of the translations).
- α in eq. 5 is printed as max‖q‖²/max‖q‖² (= 1, a typo); the stated intent is to balance the
  terms, so α = max‖q_i‖² / max‖q̇_i‖² and β = max‖q_i‖² / max‖r_i‖².
- q̇_0 and r_0 need frame −1: q̇_0 := q̇_1 and r_0 := r_1, i.e. the clip is taken to arrive at
  frame 0 with its own first step (constant velocity).
- The wrap: a transition (i, j) plays j + 1 after i, so with j ≥ 0 nothing could ever continue
  at frame 0, and a clip whose last frame is followed (in the world) by its first, a clip of one
  cycle, had no way back (the bending bar's default: 0 transitions, "no transition leads
  back"). A *virtual frame −1* closes the gap: the clip continued backwards one step at its
  first velocity, q₋₁ = 2q_0 − q_1, q̇₋₁ = q_1 − q_0 (= q̇_0, as above), r₋₁ = r_0 (= r_1: the
  reference bone's pose P(−1) = P(0) P(1)⁻¹ P(0), which :mod:`.splicing` uses), π₋₁ = 2π_0 − π_1
  (:func:`posture_costs`). It adds one column to D, D(i, −1) (:func:`start_costs`, the same α,
  β, γ), and a transition (i, −1), "after i, continue at frame 0", is then a candidate under
  exactly the rules of any other (T_c, a local minimum over its 3×3 neighbourhood in the padded
  matrix [D(·, −1) | D], |i − j| ≥ min_gap, spacing, coverage): so a clip whose end runs into
  its start gets its end→start loop, and any near-repeat across its ends too. The extrapolation
  is exact for motion at constant velocity through frame 0 and second order otherwise (like the
  finite differences of eq. 5). j = 0 stays out, as before: (i, 0) continues at frame 1, one
  frame from (i, −1), and admitting it would change the transitions of every clip. It still
  counts as a neighbour, and columns −1 and 0 share their velocity and r terms (q̇₋₁ = q̇_0,
  r₋₁ = r_0), so the position term alone decides between them: where the clip's first frames
  barely move but accelerate hard, the minimum can fall on j = 0 and no wrap is listed (the
  horse gallop's first cycle cut alone: D(23, 0) = 0.70 T_c against D(23, −1) = 0.72 T_c).
  Leaving j = 0 out of the virtual column's neighbourhood was tried (issue 63): the gallop's
  frames all joined the strongly connected part (96 % at 24 fps, 83 % at 12), but the samba's
  arm got a wrap one step from the diagonal's valley ((3, −1) at 0.01 T_c) and its body a cheaper,
  shorter one, and its walks played 155 distinct frames where they played 163. Listing the wrap
  only where the minimum falls on j = 0 (it stands in for it) kept the samba but made the elephant
  clips' walks loop each 1 s clip (13 and 16 of 20 stuck, none before) and broke 1.3 % of the
  horse clips' frames (0.4 %).
  Extrapolating, rather than comparing i + 1 with frame 0, keeps the meaning of a pair (i, j)
  and needs nothing past the clip's end (the clip's last frame, the very frame that must go back,
  has no i + 1). Only the column is virtual: frame −1 is never played, and no row −1 exists.
- T_c defaults to 3 × the *median* of the steps D(i, i−1), not Zheng's 40 × their max (see
  :func:`transition_threshold`).
- Which local minima become transitions (:func:`select_transitions`): one per neighbourhood of
  ``spacing`` frames (the cheapest), all of those below T_c, and past T_c only the cheapest
  ones that let walks reach more of the clip, until ``coverage`` of the frames lie on one
  strongly connected part of the motion graph. Measured on the real captures (default
  options, before this rule): 62–150 transitions per component (the samba's 3-bone leg: 68,
  walks seaming every ~6 frames) where Zheng's Table 1 has tens, and none at all on a Vellum
  cloth (its cheapest local minimum costs 5.5 median steps), while walks on the samba played
  only 57 % of the frames of a component.
- The spread (``spread`` frames, build-graph: 4 × ``--min-segment``, two seconds at the default;
  :func:`_spread`): last, every candidate below ``admit_scale`` × T_c with no transition yet
  within ``spread`` frames of it in both i and j is admitted, cheapest first: each pair of
  two-second stretches that resemble each other gets its cheapest way across. T_c is counted in
  playback steps, and a step shrinks with the frame rate and the motion's speed while two strides
  of a real walk differ by what they differ by: on a walk that gets going (``example walker
  --planted --tempo 0.6``, 4 strides from 0.4 to 1.6 times the mean speed) every transition below
  T_c or admitted for coverage lay in the fast last strides, and walks that reached the clip's
  end stayed there (issue 48: a held-out walking bird, 8 transitions, none in its first 270 of
  400 frames). Two seconds is the horizon of a stuck walk (:mod:`.walk_measures`) and a middle
  measured on the captures: at half a second the slow crane form (vlasic_crane) got 75
  transitions where it had 11, its feet's largest acceleration rose from 1.10 to 1.27 times the
  input's, and the samba's feet slid 1.6 times the input's median (0.8 before); at two seconds
  the crane gets 13, the samba's feet pass their test, and walks on the walk that gets going play
  a median 268 of its 400 frames (196 without the spread; ``benchmarks/synthesize.py --only
  walker_tempo``).
- Coverage counts the frame graph as walks take it (``segment``, build-graph: ``--min-segment``):
  a transition only after ``segment`` frames since the last seam, so one that leaves a frame
  fewer than ``segment`` frames after every way into it joins nothing (the samba's arm: the graph
  of frames said 99 % of its frames lay on one part, walks could reach 66 %).

Several clips (issue 26; ``clips``: a :class:`.clips.Clips` of the F frames, whose conventions
bind here: playback f → f + 1 only inside a clip, a transition (i, j) plays j + 1 after i, j =
−(c+1) continues at the first frame of clip c). ``clips=None`` is one clip and runs the steps
above with the same numbers, bit for bit (``Clips.single(F)`` gives them too). With several:

- Eq. 2–4 are per frame: q is computed over all clips' frames at once (one basis, so D compares
  frames of different clips in one space). The differences are taken within each clip: q̇_i =
  q_i − q_{i−1} and r_i (eq. 6) only where i − 1 plays on to i; each clip's first frame takes
  its own first step (q̇_s := q̇_{s+1}, r_s := r_{s+1}), as frame 0 does; a clip of one frame gets
  q̇ = r = 0 there. α and β (eq. 5) balance these clip-wise differences.
- D (F, F) compares every pair of frames, of one clip or of two; a transition between clips is
  found by exactly the rule of one within a clip (the point: a gallop that falls into the
  collapse). The virtual column becomes one per clip: D(i, −(c+1)), frame i against clip c's
  virtual frame before its start s_c, continued back at its first velocity as for clip 0
  (:func:`virtual_costs`; a clip of one frame has none: +inf).
- Local minima are searched per (clip of i, clip entered) block, each clip's virtual column
  placed before its first column, blocks apart by +inf (:func:`clip_blocks`): a neighbourhood
  never spans a clip boundary, where D's rows and columns are no longer neighbours in time.
- A candidate leaves a frame i that is not its clip's first (its velocity needs a previous
  frame, as i ≥ 1) and enters by j = −(c+1) or a j ≥ 0 neither first nor last of its clip
  (j ≥ 1 and j + 1 < F, clip by clip). ``min_gap`` applies within a clip only, j measured as
  the frame before the one entered (j, or s_c − 1); between clips no pair is a playback step.
- T_c uses the playback steps D(i, i−1) within clips only (:func:`transition_threshold`); the
  spacing rule compares only candidates whose i share a clip and whose entered frames share a
  clip; coverage counts the clip-aware motion graph (:func:`.motion_graph.recurrent_frames`).
"""

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import minimum_filter

from ..inputs.clips import Clips
from ..errors import OptionError
from ..rig.influence import bone_centroids, weight_sums  # noqa: F401 (bone_centroids: part of this module's API)
from ..rig.rotations import heading_and_posture, rotation_log

THRESHOLD_REFERENCES = ("median-step", "max-step")
#: The frame rate a playback step is counted at (:func:`transition_threshold`): a step is what the
#: motion does in 1/24 s, the rate Zheng's and most captures' clips play at, so a 24 fps file keeps
#: the threshold it always had.
REFERENCE_FPS = 24.0


def reference_bone(bone_indices, bone_weights, bones, subset=None):
    """The bone with the largest weight sum Σ_v w_vb (Zheng §3.2, "most influential bone").

    bone_indices (V, K) int, bone_weights (V, K), bones: B. ``subset``: optional iterable of bone
    ids to choose from (a component of the bone graph). Ties go to the lowest id. Returns an int.
    """
    totals = weight_sums(bone_indices, bone_weights, bones)
    candidates = np.arange(bones) if subset is None else _bone_ids(subset, bones)
    if candidates.size == 0:
        raise OptionError("cannot choose a reference bone from an empty set of bones")
    # argmax returns the first maximum; candidates are sorted, so ties go to the lowest id.
    return int(candidates[np.argmax(totals[candidates])])


def local_frame_positions(rotations, translations, reference, bones_subset=None):
    """Non-reference bones in the reference bone's local frame (Zheng eq. 2).

    rotations (F, B, 3, 3), translations (F, B, 3), reference: b_r. ``bones_subset``: bone ids
    to use (default all B); it must contain ``reference``. Returns ``(R_local (F, B', 3, 3),
    t_local (F, B', 3), bone_ids)`` where bone_ids lists the B' bones of the subset other than
    b_r in increasing order (the order of R_local/t_local and of the rows of A_r):
    ``R_{i→r} = R_rᵀ R_i``, ``t_{i→r} = R_rᵀ (t_i − t_r)``.
    """
    rotations = np.asarray(rotations, dtype=np.float64)
    translations = np.asarray(translations, dtype=np.float64)
    bones = rotations.shape[1]
    subset = np.arange(bones) if bones_subset is None else _bone_ids(bones_subset, bones)
    if reference not in subset:
        raise OptionError(f"reference bone {reference} is not in the bone subset {subset.tolist()}")
    ids = subset[subset != reference]
    r_ref_t = np.swapaxes(rotations[:, reference], -1, -2)  # (F, 3, 3) = R_rᵀ
    # Zheng eq. 2
    r_local = r_ref_t[:, None] @ rotations[:, ids]
    t_local = np.einsum("fab,fkb->fka", r_ref_t, translations[:, ids] - translations[:, reference, None])
    return r_local, t_local, ids.tolist()


def bone_coordinate_matrix(R_local, t_local):
    """A_r of Zheng eq. 3: R_local (F, B', 3, 3), t_local (F, B', 3) -> A (6B', F).

    Column j stacks ``p_i^j = [t_{i→r}(j); Φ(R_{i→r}(j))]`` for the B' bones, Φ the axis-angle
    vector (rotation angle in [0, π]; rotations that cross π jump across the branch cut, a
    limitation of Φ the paper shares).
    """
    frames, count = np.shape(t_local)[:2]
    p = np.concatenate([np.asarray(t_local, np.float64), rotation_log(np.asarray(R_local, np.float64))],
                       axis=-1)  # (F, B', 6), Zheng eq. 3
    return p.reshape(frames, 6 * count).T


def reduced_coordinates(R_local, t_local, svd_threshold=0.005):
    """Reduced bone coordinates by truncated SVD of A_r (Zheng eq. 3–4).

    R_local (F, B', 3, 3), t_local (F, B', 3). Returns ``(q (F, r), basis (6B', r), singular (r,))``
    with ``A_r ≈ basis @ diag(singular) @ Vᵀ = basis @ q.T``. "Thresholded at 0.005" is read as
    relative: the kept singular values are those ≥ ``svd_threshold`` × the largest (0 keeps all
    non-zero ones). The squared Frobenius error of the reconstruction is the sum of the dropped
    σ². q_i, the i-th column of Q_r = S_r V_rᵀ, is computed as ``U_rᵀ a_i`` (the same thing), so
    identical frames get bit-identical q. No mean is removed (the paper does not; D only uses
    differences, which the projection preserves inside the kept subspace).
    """
    a = bone_coordinate_matrix(R_local, t_local)
    frames = a.shape[1]
    if a.shape[0] == 0:  # a one-bone subset: no non-reference bones, q is empty
        return np.zeros((frames, 0)), np.zeros((0, 0)), np.zeros(0)
    u, s, _ = np.linalg.svd(a, full_matrices=False)  # Zheng eq. 4
    keep = (s > 0.0) & (s >= svd_threshold * s[0]) if s.size and s[0] > 0.0 else np.zeros(s.size, bool)
    rank = int(np.count_nonzero(keep))
    basis = u[:, :rank]
    return a.T @ basis, basis, s[:rank]


def reference_motion(rotations, translations, reference, clips=None):
    """Frame-to-frame motion of the reference bone in its own frame (Zheng eq. 6) -> r (F, 6).

    ``r_i = [R_r(i)ᵀ (t_r(i−1) − t_r(i)); Φ(R_r(i)ᵀ R_r(i−1))]`` for i ≥ 1, and r_0 := r_1 (there
    is no frame −1). A single frame gives r = 0. r is unchanged by one rigid transform applied
    to the whole clip, but not by a rigid transform that varies per frame. ``clips``
    (:class:`.clips.Clips`, None: one clip): differences within each clip only; each clip's
    first frame takes its own first step, as frame 0 does (module notes: several clips).
    """
    r_ref = np.asarray(rotations, np.float64)[:, reference]
    t_ref = np.asarray(translations, np.float64)[:, reference]
    frames = r_ref.shape[0]
    out = np.zeros((frames, 6))
    if frames < 2:
        return out
    r_t = np.swapaxes(r_ref[1:], -1, -2)  # R_r(i)ᵀ, i = 1..F−1
    # Zheng eq. 6
    out[1:, :3] = np.einsum("fab,fb->fa", r_t, t_ref[:-1] - t_ref[1:])
    out[1:, 3:] = rotation_log(r_t @ r_ref[:-1])
    return _first_takes_next(out, clips)


def velocities(q, clips=None):
    """Finite-difference velocities q̇_i = q_i − q_{i−1} (Zheng §3.2), q̇_0 := q̇_1: (F, r) -> (F, r).
    ``clips`` (None: one clip): within each clip, its first frame taking its own first step."""
    q = np.asarray(q, np.float64)
    qdot = np.zeros_like(q)
    if q.shape[0] >= 2:
        qdot[1:] = q[1:] - q[:-1]
        _first_takes_next(qdot, clips)
    return qdot


def _first_takes_next(x, clips):
    """x (F, n), rows i ≥ 1 holding the step from frame i − 1: each clip's first row (which would
    hold the step from the previous clip's last frame) := the clip's own first step, row s + 1,
    or 0 for a clip of one frame. In place; returns x."""
    frames = x.shape[0]
    if frames < 2:
        return x
    if clips is None:
        x[0] = x[1]
        return x
    first, counts = clips.starts[:-1], np.asarray(clips.frames)
    x[first[counts >= 2]] = x[first[counts >= 2] + 1]
    x[first[counts < 2]] = 0.0
    return x


def pairwise_squared_distances(x):
    """‖x_i − x_j‖² for all rows of x (F, n) -> (F, F), by one matrix product.

    Exactly symmetric with a zero diagonal; round-off negatives are clipped to 0.
    """
    x = np.asarray(x, np.float64)
    norms = np.einsum("fn,fn->f", x, x)
    d = norms[:, None] + norms[None, :] - 2.0 * (x @ x.T)
    d = 0.5 * (d + d.T)
    np.fill_diagonal(d, 0.0)
    return np.maximum(d, 0.0)


def transition_costs(q, r, alpha=None, beta=None, clips=None):
    """Transition cost between every pair of frames (Zheng eq. 5).

    q (F, r) reduced coordinates, r (F, 6) reference motion. Returns ``(D (F, F), alpha, beta)``
    with ``D(i, j) = ‖q_i − q_j‖² + α ‖q̇_i − q̇_j‖² + β ‖r_i − r_j‖²``, q̇_i = q_i − q_{i−1}
    (q̇_0 := q̇_1). Unless given, α = max‖q_i‖² / max‖q̇_i‖² and β = max‖q_i‖² / max‖r_i‖²
    (the paper's α formula has a typo; both weights balance a term against ‖q‖²). Guards: a
    zero denominator gives weight 1 (its term is identically 0 then); a zero numerator (no
    non-reference motion, e.g. a one-bone component) is replaced by 1, so the other terms are
    normalised to a unit maximum instead of vanishing. ``clips`` (None: one clip): q̇ within each
    clip (:func:`velocities`); r must be made with the same clips (:func:`reference_motion`).
    """
    q = np.asarray(q, np.float64)
    r = np.asarray(r, np.float64)
    qdot = velocities(q, clips)
    scale = _max_squared_norm(q)
    scale = scale if scale > 0.0 else 1.0
    if alpha is None:
        alpha = _ratio(scale, _max_squared_norm(qdot))
    if beta is None:
        beta = _ratio(scale, _max_squared_norm(r))
    # Zheng eq. 5
    d = pairwise_squared_distances(q) + alpha * pairwise_squared_distances(qdot) \
        + beta * pairwise_squared_distances(r)
    return d, float(alpha), float(beta)


def before_start(x):
    """The virtual frame −1 of a state series x (F, n), F ≥ 2: the clip continued backwards one
    step at its first velocity, 2 x_0 − x_1 (n,) (module notes: the wrap)."""
    x = np.asarray(x, np.float64)
    return 2.0 * x[0] - x[1]


def start_costs(q, r, alpha, beta, posture=None, gamma=0.0):
    """D(i, −1): every frame against the virtual frame −1 before the clip's start -> (F,).

    The column eq. 5 would have for frame −1 (module notes: the wrap): ``‖q_i − q₋₁‖² +
    α ‖q̇_i − q̇₋₁‖² + β ‖r_i − r₋₁‖²`` with q₋₁ = 2q_0 − q_1, q̇₋₁ = q̇_0 = q_1 − q_0 and
    r₋₁ = r_0, plus ``γ ‖π_i − π₋₁‖²`` (π₋₁ = 2π_0 − π_1) with a posture (F, 4) and its weight γ
    (:func:`posture_costs`). α, β, γ are D's own: the column is scaled like every other. Computed
    from the differences themselves, so D(0, −1), a playback step at the first velocity, has
    exactly no velocity or r term. Needs F ≥ 2."""
    q = np.asarray(q, np.float64)
    return _virtual_column(q, velocities(q), np.asarray(r, np.float64), alpha, beta, posture, gamma, 0)


def virtual_costs(q, r, alpha, beta, posture=None, gamma=0.0, clips=None):
    """D(i, −(c+1)) for every clip c: each frame against the virtual frame before clip c's start
    -> (F, C) (module notes: several clips). Column c is :func:`start_costs` with clip c's first
    frames s_c, s_c + 1 in place of 0, 1 (q̇ and r within clips: q, r as :func:`transition_costs`
    takes them); a clip of one frame has no first velocity to continue back at, so its column is
    +inf (nothing enters it by a transition). ``clips`` None: one clip, the column (F, 1) of
    :func:`start_costs`, bit for bit."""
    q = np.asarray(q, np.float64)
    r = np.asarray(r, np.float64)
    qdot = velocities(q, clips)
    if clips is None:
        return _virtual_column(q, qdot, r, alpha, beta, posture, gamma, 0)[:, None]
    columns = [_virtual_column(q, qdot, r, alpha, beta, posture, gamma, int(first)) if count >= 2
               else np.full(q.shape[0], np.inf) for first, count in zip(clips.starts[:-1], clips.frames)]
    return np.stack(columns, axis=1)


def _virtual_column(q, qdot, r, alpha, beta, posture, gamma, first):
    """Eq. 5 (and γ's posture term) of every frame against the virtual frame before ``first``:
    q₋ = 2 q_s − q_{s+1}, q̇₋ = q̇_s, r₋ = r_s, π₋ = 2 π_s − π_{s+1} (s = first) -> (F,)."""
    s = first
    costs = _squared_distances_to(q, before_start(q[s:s + 2])) + alpha * _squared_distances_to(qdot, qdot[s]) \
        + beta * _squared_distances_to(r, r[s])
    if posture is not None and gamma:
        costs = costs + gamma * _squared_distances_to(posture, before_start(np.asarray(posture)[s:s + 2]))
    return costs


def padded_costs(D, start):
    """The cost matrix with the virtual frame's column first: D (F, F), start (F,) D(i, −1) ->
    (F, F + 1), column c holding j = c − 1 (the layout :func:`candidate_transitions` searches)."""
    D = np.asarray(D, np.float64)
    return np.concatenate([np.asarray(start, np.float64).reshape(D.shape[0], 1), D], axis=1)


def transition_threshold(D, scale=3.0, reference="median-step", clips=None, moving=None, fps=REFERENCE_FPS):
    """T_c = ``scale`` × (median or max) of the playback steps D(i, i−1), i = 1..F−1 (with
    ``clips``: only the steps within a clip, i not the first frame of its clip), in the clip's time:
    × (fps / :data:`REFERENCE_FPS`)².

    **Sampling (issue 63).** Every term of a step D(i, i−1) grows with the square of the frame
    interval (its pose term ‖q_i − q_{i−1}‖² directly; its velocity and reference-motion terms
    because α and β divide by the largest squared per-frame velocity), while D(i, j) between two
    strides does not change: at 48 fps the steps are a quarter of those at 24 and the samba's
    strides no longer joined (a quarter of its frames on the strongly connected part). A step is
    therefore counted over about 1/24 s: D(i, i − k), k = round(fps / 24) frames, × (fps / 24k)²
    (:func:`_spans`): the same threshold for the same motion at 12, 24, 48 or 96 fps, and for a file
    at 24 fps (every shared capture, and the default of ``fit-skin --fps``) exactly today's. Over k
    frames, not one frame scaled by (fps / 24)²: a clip in-betweened linearly has no acceleration
    at every other frame, and its one-frame steps' median fell twelvefold at 48 fps, not fourfold. Only the ``moving`` (F,) bool frames' steps
    count (:attr:`.held_poses.HeldPoses.moving`, None: all): a held pose's frames step by nothing
    and dragged the median to a tenth (the samba with 5 s held: 29 % on the strongly connected part).

    ``reference="max-step"`` with ``scale=40`` is Zheng's literal rule (§3.2, "T_c = 40 max
    D(i, i−1)"). It does not transfer: on a 201-frame, 27-bone dancer fit (shared/NOTES.md) the
    steps have median 3.3 but max 55 (one outlier dominated by the velocity term), so 40 × max
    admits 39,402 of ~40,000 frame pairs (702 local minima), splices between unlike poses, while
    the off-diagonal D has its 1st percentile at 9.4. The max of the steps is one outlier's
    value; the median is robust, and 2–4 × the median step gave 12–24 local-minimum transitions
    there (Zheng report 58 for that dancer). Hence the default: 3 × the median step. Requires at
    least 2 frames (in one clip).
    """
    D = np.asarray(D, np.float64)
    if D.shape[0] < 2:
        raise OptionError(f"a transition threshold needs at least 2 frames (got {D.shape[0]})")
    if clips is not None and not clips.plays_on()[:-1].any():
        raise OptionError("a transition threshold needs a clip of at least 2 frames "
                          f"(the clips have {', '.join(str(f) for f in clips.frames)})")
    steps, span = _spans(D, clips, moving, fps)
    return float(scale * _step_reference(steps, reference) * _time_scale(fps, span))


def _spans(D, clips, moving, fps, owner=None):
    """The playback steps a threshold is sized by: D(i, i − k) over k = max(1, round(fps / 24))
    frames, about 1/24 s (:func:`transition_threshold`), i − k and i in one clip and both ``moving``
    (a clip whose frames never move, or are too few: all of its steps over one frame) -> (steps,
    k), or with ``owner`` a clip id: that clip's alone."""
    frames = D.shape[0]
    span = max(1, int(round(float(fps) / REFERENCE_FPS)))
    clip = np.zeros(frames, np.int64) if clips is None else clips.clip_of(np.arange(frames))
    for k in (span, 1):  # a loop over two spans at most
        i = np.arange(k, frames)
        within = clip[i] == clip[i - k]
        if owner is not None:
            within &= clip[i] == owner
        counted = within & (True if moving is None else np.asarray(moving, bool)[i] & np.asarray(moving, bool)[i - k])
        chosen = counted if counted.any() else within  # a clip that never moves: its own steps
        if chosen.any() or k == 1:
            return D[i[chosen], i[chosen] - k], k


def _step_reference(steps, reference):
    if reference == "median-step":
        return float(np.median(steps))
    if reference == "max-step":
        return float(np.max(steps))
    raise OptionError(f"unknown threshold reference {reference!r}; choose one of {THRESHOLD_REFERENCES}")


def _time_scale(fps, span=1):
    """(fps / (span · :data:`REFERENCE_FPS`))²: a step over ``span`` frames counted over 1/24 s
    (:func:`transition_threshold`)."""
    return (float(fps) / (span * REFERENCE_FPS)) ** 2


def clip_thresholds(D, scale=3.0, reference="median-step", clips=None, moving=None, fps=REFERENCE_FPS):
    """T_c per (clip left, clip entered) -> (C, C): ``scale`` × the larger of the two clips' step
    references (the median or max of each clip's own playback steps D(i, i−1)); the diagonal is
    each clip's own T_c. One clip: [[:func:`transition_threshold`]].

    Why per clip: clips of one character can move at very different speeds, and the playback step
    measures what a frame-to-frame change looks like in each. On the horse the gallop's median
    step is 31.7 and the collapse's (which stands nearly still before it falls) 0.32: one T_c
    over both (3 × 5.45, their pooled median) held the gallop to a sixth of its own steps and
    admitted no transition into or out of the collapse. A transition between two clips may cost
    what a step of the faster of them does (the larger reference), a transition within a clip
    what its own steps do. A clip with no step of its own (one frame) takes the other clip's; two
    such, the pooled reference."""
    if clips is None or len(clips) == 1:
        return np.array([[transition_threshold(D, scale, reference, clips, moving, fps)]])
    D = np.asarray(D, np.float64)
    pooled = transition_threshold(D, scale, reference, clips, moving, fps) / scale
    base = np.full(len(clips), np.nan)
    for c in range(len(clips)):  # a loop over clips
        own, span = _spans(D, clips, moving, fps, owner=c)
        if own.size:
            base[c] = _step_reference(own, reference) * _time_scale(fps, span)
    pair = np.fmax(base[:, None], base[None, :])
    return scale * np.where(np.isnan(pair), pooled, pair)


def candidate_transitions(D, threshold, min_gap=2, start=None, clips=None):
    """Candidate transitions: local minima of D below the threshold (Zheng §3.2).

    D (F, F); start (F,): D(i, −1), the virtual frame's column (:func:`start_costs`), or None
    (no pair (i, −1)). Keeps pairs (i, j) with D(i, j) < ``threshold``, |i − j| ≥ ``min_gap`` (a
    jump of one frame is just playback), i ≥ 1 and j ≥ 1 or j = −1 (the velocity terms need a
    previous frame; −1 is the virtual one), that are minima of D over their 3×3 neighbourhood
    (so one good transition is not listed ten times). The neighbourhood test runs on the full
    padded matrix [D(·, −1) | D] (:func:`padded_costs`), diagonal included: pairs on the slope of
    the trivial D(i, i) = 0 valley are never minima; a pair (i, j ≥ 1) has the same neighbours as
    without the column. Values within 1e-9 × max|D| (the real frames' D) of the neighbourhood
    minimum count as minima, so a flat valley (an exact loop: D(i, i+P) = 0 for every i) lists
    each of its pairs rather than whichever round-off happens to favour. Both (i, j) and (j, i)
    may appear. Returns ``(pairs (M, 2) int, costs (M,))`` sorted by cost (ties by i, then j).

    ``clips`` (:class:`.clips.Clips`; None: one clip) with start (F, C): D(i, −(c+1))
    (:func:`virtual_costs`). The search runs per block (clip of i, clip of j + 1), each column
    block led by its clip's virtual column (:func:`clip_blocks`), so no neighbourhood spans a
    clip boundary; "i ≥ 1" and "j ≥ 1" read "not the first frame of its clip", and the gap
    applies only within a clip, measured to the frame before the one entered (j, or s_c − 1 for
    the virtual frame of clip c starting at s_c; −1 for clip 0, as above). A transition from
    one clip into another is no playback step, so it needs no gap.
    """
    D = np.asarray(D, np.float64)
    frames = D.shape[0]
    if frames == 0:
        return np.zeros((0, 2), np.int64), np.zeros(0)
    clips = Clips.single(frames) if clips is None else clips
    finite = np.isfinite(D)
    tolerance = 1e-9 * (np.max(np.abs(D[finite])) if finite.any() else 0.0)
    padded, row_i, column_j = clip_blocks(D, start, clips)
    neighbourhood_min = minimum_filter(np.where(np.isfinite(padded), padded, np.inf), size=3, mode="constant",
                                       cval=np.inf)
    first = clips.first_frames()
    real_row, real_column = row_i >= 0, column_j > _SEPARATOR
    i = np.where(real_row, row_i, 0)[:, None]  # (R, 1): separators read as frame 0, then dropped
    j = np.where(real_column, column_j, 0)[None, :]  # (1, K)
    clip_entered, before = _entered(clips, j)
    gap_ok = (clips.clip_of(i) != clip_entered) | (np.abs(i - before) >= min_gap)
    j_ok = (j < 0) | ~first[np.maximum(j, 0)]
    keep = (real_row[:, None] & real_column[None, :] & (padded < threshold) & gap_ok & ~first[i] & j_ok
            & (padded <= neighbourhood_min + tolerance))
    rows, columns = np.nonzero(keep)
    pairs = np.stack([row_i[rows], column_j[columns]], axis=1).astype(np.int64)
    costs = padded[rows, columns]
    order = np.lexsort((pairs[:, 1], pairs[:, 0], costs))
    return pairs[order], costs[order]


def _entered(clips, j):
    """For j (any int shape): the clip a transition (·, j) enters and the position of j in the
    global numbering: j itself, or s_c − 1 for the virtual frame of clip c (starting at s_c; −1
    for clip 0). A j ≥ 0 belongs to its own clip even when it is the clip's last frame."""
    j = np.asarray(j, np.int64)
    virtual_clip = np.clip(-j - 1, 0, len(clips) - 1)
    clip = np.where(j >= 0, clips.clip_of(np.maximum(j, 0)), virtual_clip)
    return clip, np.where(j >= 0, j, clips.starts[virtual_clip] - 1)


_SEPARATOR = np.iinfo(np.int64).min  # a column of +inf between two clips' blocks (clip_blocks)


def clip_blocks(D, start=None, clips=None):
    """The layout :func:`candidate_transitions` searches: D (F, F) in blocks (clip of i, clip of
    j), each clip's columns led by its virtual frame's column, blocks apart by a row or column of
    +inf (so a 3×3 neighbourhood never spans two clips: at a block's edge it sees what it sees at
    the matrix's edge). start: None (no virtual columns), (F,) D(i, −1) of one clip, or (F, C)
    D(i, −(c+1)). Returns ``(padded (R, K), row_i (R,), column_j (K,))``: the frame i of each row
    (−1: a separator) and the j of each column (−(c+1): clip c's virtual frame; ``_SEPARATOR``:
    a separator). One clip: ``[D(·, −1) | D]`` (:func:`padded_costs`) or D, with no separator."""
    D = np.asarray(D, np.float64)
    frames = D.shape[0]
    clips = Clips.single(frames) if clips is None else clips
    count = len(clips)
    virtual = None if start is None else np.asarray(start, np.float64).reshape(frames, count)
    starts = clips.starts
    rows, columns = [], []
    for c in range(count):
        own = np.arange(starts[c], starts[c + 1])
        rows.append(own if c == 0 else np.concatenate([[-1], own]))
        lead = ([] if c == 0 else [_SEPARATOR]) + ([] if virtual is None else [-(c + 1)])
        columns.append(np.concatenate([np.asarray(lead, np.int64), own]))
    row_i, column_j = np.concatenate(rows).astype(np.int64), np.concatenate(columns).astype(np.int64)
    # Gather from [D | virtual columns | +inf]: column F + c is clip c's virtual frame, the last +inf.
    extended = np.concatenate([D, np.zeros((frames, 0)) if virtual is None else virtual, np.full((frames, 1), np.inf)],
                              axis=1)
    source = np.where(column_j >= 0, column_j, np.where(column_j == _SEPARATOR, extended.shape[1] - 1, frames - column_j - 1))
    padded = extended[np.maximum(row_i, 0)][:, source]
    padded[row_i < 0] = np.inf
    return padded, row_i, column_j


def select_transitions(D, threshold, min_gap=2, spacing=0, coverage=0.95, admit_scale=10.0, start=None, clips=None,
                       walkable=None, spread=0, segment=1):
    """Transitions of one clip: cheap, spread out, and enough to reach the whole clip.

    D (F, F) costs; threshold T_c; start (F,): D(i, −1) (:func:`start_costs`), or None for no
    wrap. Candidates are the local minima of D (3×3 neighbourhood, as
    :func:`candidate_transitions`, with |i − j| ≥ ``min_gap``, i ≥ 1 and j + 1 < F so that the
    transition has somewhere to continue; j = −1 continues at frame 0 and is judged like any
    other, its j = −1 one frame before j = 0). They are visited by increasing cost (ties by i,
    then j); a candidate within ``spacing`` frames of an accepted one in both i and j is the
    same choice made a few frames earlier or later and is dropped (greedy non-maximum
    suppression: a seam needs segments of several frames on both sides anyway, and without it a
    flat valley such as an exact loop, D(i, i+P) = 0 for every i, lists a transition per frame).
    Every surviving candidate with D < T_c is a transition. If fewer than ``coverage`` of the
    frames then lie on the largest strongly connected part of the frame graph
    (:func:`.motion_graph.recurrent_frames`: walks get trapped or dead-end), further candidates
    are admitted in order of cost, each only if it enlarges that part, until it holds
    ``coverage`` of the frames or none is left below ``admit_scale`` × T_c (past that a splice
    shows: on the Dem Bones example, whose median step is tiny beside its fast flexes, admitting
    up to 160 T_c for coverage made 3.7× the input's acceleration). Last, in the same way, the
    candidates below T_c that the spacing rule dropped: spacing says a neighbour is the same
    choice, but where every transition kept leaves frames off the part, a neighbour as cheap
    that reaches them is not (issue 63: the gallop at 12 fps, one stride 12 frames, kept (15, 3)
    and dropped (13, 1), at cost 0, so frames 0–3 only led in). Tried among the survivors, by
    cost, they crowded a few places with near copies (the dancer's arm component: walks replayed
    them); tried above T_c too, they added a splice at 9.8 T_c to the samba at 96 fps for 0.6 %
    more of its arm component's frames, and its walks played fewer of its poses.

    ``clips`` (None: one clip), start (F, C) D(i, −(c+1)): j must name a frame that plays on in
    its clip (:meth:`.clips.Clips.valid_j`), and spacing compares only candidates whose i lie in
    one clip and whose entered frames j + 1 lie in one clip (j measured as the frame before the
    one entered, as :func:`candidate_transitions`' gap); coverage counts the clip-aware graph.
    ``walkable`` (F,) bool (None: every frame): only transitions that leave and enter such frames
    (``build-graph --clips``: a pose library kept out of the walks). ``threshold`` may then be
    (C, C), T_c per (clip left, clip entered) (:func:`clip_thresholds`):
    each candidate is judged against its own, past-T_c admissions go by cost in units of it, and
    last every clip gets a way in from another clip and a way out to another, the cheapest below
    ``admit_scale`` × its T_c where it has none yet (:func:`_clip_links`), so that walks can pass
    between the clips.

    Returns ``(pairs (M, 2) int64, costs (M,), admitted (int): how many of them lie above T_c,
    share (float): the frames on the largest strongly connected part)``, sorted by cost.
    """
    from .motion_graph import recurrent_frames

    D = np.asarray(D, np.float64)
    frames = D.shape[0]
    layout = Clips.single(frames) if clips is None and frames else clips
    every, costs = candidate_transitions(D, np.inf, min_gap, start, clips)
    if frames:
        inside = layout.valid_j(every[:, 1])
        if walkable is not None:
            inside &= walkable[every[:, 0]] & walkable[layout.targets(np.where(inside, every[:, 1], 0))]
        every, costs = every[inside], costs[inside]
    spacing = max(0, int(spacing))
    if frames and len(every):
        clip_entered, before = _entered(layout, every[:, 1])
        i = every[:, 0]
        clip_left = layout.clip_of(i)
        key = clip_left * len(layout) + clip_entered  # (clip of i, clip entered)
    kept = np.zeros(len(every), np.int64)  # the accepted candidates, kept[:count]
    count = 0
    for n in range(len(every)):
        k = kept[:count]
        if not ((key[k] == key[n]) & (np.abs(i[k] - i[n]) <= spacing) & (np.abs(before[k] - before[n]) <= spacing)).any():
            kept[count], count = n, count + 1
    kept = kept[:count]
    limit = np.asarray(threshold, np.float64)
    if limit.ndim and len(every):  # (C, C): each candidate's own T_c (:func:`clip_thresholds`)
        limit = limit[clip_left, clip_entered]
    else:
        limit = np.full(len(every), float(np.max(limit)) if limit.size else 0.0)
    below = kept[costs[kept] < limit[kept]]
    chosen = list(below)
    share = float(recurrent_frames(frames, every[chosen], clips, segment).mean()) if frames else 0.0
    admitted = 0
    over = kept[(costs[kept] >= limit[kept]) & (costs[kept] < admit_scale * limit[kept])]
    spared = np.setdiff1d(np.arange(len(every)), kept)  # dropped by the spacing rule (sorted: every[] is by cost)
    spared = spared[costs[spared] < limit[spared]]
    if clips is not None and len(clips) > 1:
        over = over[np.argsort(costs[over] / limit[over], kind="stable")]  # by cost in units of their T_c
        spared = spared[np.argsort(costs[spared] / limit[spared], kind="stable")]
    grown = False
    for n in np.concatenate([over, spared]):  # the spacing rule's survivors first
        if share >= coverage:
            break
        trial = float(recurrent_frames(frames, every[chosen + [n]], clips, segment).mean())
        if trial > share:
            chosen.append(n)
            share, grown = trial, True
            admitted += int(costs[n] >= limit[n])
    if clips is not None and len(clips) > 1 and len(every):
        for n in _clip_links(chosen, over, clip_left, clip_entered, len(clips)):
            chosen.append(n)
            admitted += 1
    if spread > 0 and len(over):
        for n in _spread(chosen, over, key, i, before, spread):
            chosen.append(n)
            admitted += 1
    if admitted or grown:
        share = float(recurrent_frames(frames, every[chosen], clips, segment).mean())
    chosen = np.asarray(sorted(chosen), dtype=np.int64)  # every[] is sorted by cost already
    return every[chosen].reshape(-1, 2), costs[chosen], admitted, share


def select_held(D, threshold, min_gap=2, spacing=0, coverage=0.95, start=None, clips=None, walkable=None, spread=0,
                segment=1, held=None):
    """:func:`select_transitions` with each held pose one place (issue 63; ``held`` a
    :class:`.held_poses.HeldPoses`, None or no run: :func:`select_transitions` itself, bit for bit).

    The frames a held run hides (:attr:`.held_poses.HeldPoses.hidden`) are left out and the rest
    selected from as one sequence, in which a run's last kept frame plays on to its last frame: so
    the rules (local minima, spacing, coverage, spread) see a still of any length as ``keep`` + 1
    frames, and its many near-zero costs neither crowd the candidates nor fill the strongly
    connected part. The pairs found are numbered back in the clip's frames ((i, j) plays j + 1
    after i: j becomes the frame before the one entered) and each run's skip
    (:attr:`.held_poses.HeldPoses.skips`) is added, with its cost D. ``share``: the moving frames
    (a held pose once) on the largest strongly connected part of the clip's graph, skips taken and
    hidden frames never shown. Returns what :func:`select_transitions` returns."""
    from .motion_graph import recurrent_frames

    if held is None or not len(held.runs):
        return select_transitions(D, threshold, min_gap, spacing, coverage, start=start, clips=clips,
                                  walkable=walkable, spread=spread, segment=segment)
    frames = D.shape[0]
    layout = Clips.single(frames) if clips is None else clips
    shown = np.flatnonzero(~held.hidden)
    counts = np.bincount(layout.clip_of(shown), minlength=len(layout))
    reduced = Clips(layout.names, counts) if clips is not None else None
    pairs, costs, admitted, _ = select_transitions(
        D[np.ix_(shown, shown)], threshold, min_gap, spacing, coverage, start=None if start is None else start[shown],
        clips=reduced, walkable=None if walkable is None else walkable[shown], spread=spread, segment=segment)
    entered = np.where(pairs[:, 1] >= 0, shown[np.maximum(pairs[:, 1], -1) + 1] - 1, pairs[:, 1])
    skips = held.skips
    pairs = np.concatenate([np.stack([shown[pairs[:, 0]], entered], axis=1).reshape(-1, 2), skips]).astype(np.int64)
    costs = np.concatenate([costs, D[skips[:, 0], skips[:, 1]]])
    order = np.lexsort((pairs[:, 1], pairs[:, 0], costs))
    pairs, costs = pairs[order], costs[order]
    recurrent = recurrent_frames(frames, pairs, clips, segment, hidden=held.hidden)
    return pairs, costs, admitted, float(recurrent[held.moving].mean())


def _spread(chosen, over, key, i, before, radius):
    """Candidates to add (of ``over``, in its order: by cost) so that transitions lie all along the
    clip: each one with no transition yet within ``radius`` frames of it in both the frame left
    and the frame entered (within its pair of clips, ``key``). A greedy disk cover by cost, like
    the spacing rule but wider and applied to the candidates above T_c: where a motion repeats
    (one stride into the next), each pair of repeats gets its cheapest way across, even where the
    repeats differ by more than T_c (module notes: the spread)."""
    added = []
    taken = np.asarray(chosen, np.int64)
    picked = set(int(n) for n in chosen)
    for n in over:
        if int(n) in picked:
            continue
        near = (key[taken] == key[n]) & (np.abs(i[taken] - i[n]) <= radius) & (np.abs(before[taken] - before[n]) <= radius)
        if not near.any():
            added.append(int(n))
            picked.add(int(n))
            taken = np.append(taken, n)
    return added


def _clip_links(chosen, over, clip_left, clip_entered, count):
    """Candidates to add so that every clip has a way in from another clip and a way out to
    another (when one exists below ``admit_scale`` × its T_c): for each clip lacking one, the
    cheapest in units of its T_c (``over`` is in that order). The coverage rule alone admits one
    transition only if it enlarges the strongly connected part by itself, so a clip that needs a
    way in and a way out together (the horse's collapse) was never joined."""
    links = []
    taken = list(chosen)
    for c in range(count):  # a loop over clips
        for leaving in (False, True):
            between = clip_left[taken] != clip_entered[taken] if taken else np.zeros(0, bool)
            side = clip_left if leaving else clip_entered
            if taken and (between & (side[taken] == c)).any():
                continue
            pick = [n for n in over if clip_left[n] != clip_entered[n] and side[n] == c and n not in taken]
            if pick:
                links.append(pick[0])
                taken.append(pick[0])
    return links


@dataclass
class Transitions:
    """Everything :func:`find_transitions` computed for one clip (or one bone component).

    reference: b_r; bones: the bones considered, sorted (b_r included); local_bones: the
    non-reference bones, in the order of A_r's rows (6 per bone); q (F, r) reduced coordinates;
    basis (6B', r); singular (r,) kept singular values; r (F, 6) reference motion (eq. 6);
    alpha, beta: eq. 5 weights; D (F, F) costs; threshold: T_c; pairs (M, 2) and costs (M,):
    the candidate transitions, by increasing cost, j = −1 meaning "continue at frame 0"; plus
    the options used; start (F,): D(i, −1), the virtual frame's column (:func:`start_costs`;
    None when not computed, e.g. read back from a graph file, which stores the pairs' costs only).
    thresholds (C, C): T_c per (clip left, clip entered) with several clips (:func:`clip_thresholds`;
    None with one); clips: the :class:`.clips.Clips` the frames were read as (None: one clip); virtual (F, C):
    D(i, −(c+1)) for every clip (:func:`virtual_costs`; column 0 is ``start``), None when not
    computed. With clips, j = −(c+1) continues at the first frame of clip c.
    """

    reference: int
    bones: list
    local_bones: list
    q: np.ndarray
    basis: np.ndarray
    singular: np.ndarray
    r: np.ndarray
    alpha: float
    beta: float
    D: np.ndarray
    threshold: float
    pairs: np.ndarray
    costs: np.ndarray
    options: dict = field(default_factory=dict)
    admitted: int = 0
    share: float = 1.0
    start: np.ndarray | None = None
    clips: Clips | None = None
    virtual: np.ndarray | None = None
    thresholds: np.ndarray | None = None

    @property
    def steps(self):
        """The playback steps D(i, i−1), i = 1..F−1 (i − 1 and i in one clip)."""
        steps = np.diagonal(self.D, offset=-1).copy()
        return steps if self.clips is None else steps[self.clips.plays_on()[:-1]]


def reference_posture(rotations, translations, pivot, up, scale):
    """The reference bone's posture per frame, what a ground-plane alignment keeps from the input
    (:func:`.rotations.heading_and_posture`): rotations (F, 3, 3), translations (F, 3) of the
    bone, its rest pivot (3,), the unit up axis (3,), scale: a length (the rest pose's size) ->
    (F, 4) = [Φ(Π_R) (its tilt, no turn about up), the pivot's height / scale]."""
    _, _, posture_R, posture_t = heading_and_posture(rotations, translations, pivot, up)
    height = (posture_R @ np.asarray(pivot, dtype=np.float64) + posture_t) @ (np.asarray(up) / np.linalg.norm(up))
    return np.concatenate([rotation_log(posture_R), (height / scale)[:, None]], axis=1)


def posture_costs(D, q, posture, weight=1.0):
    """D + γ ‖π_i − π_j‖² with π the :func:`reference_posture`: with segments placed by a turn
    about up and a ground shift, frames i and j must also agree in tilt and height (Zheng's eq. 5
    is blind to them: his eq. 7 moves a segment by any rigid transform). γ = ``weight`` ×
    max‖q_i‖² / max‖π_i − π̄‖² balances the term as α and β balance theirs (1 where either is 0)."""
    centred = posture - posture.mean(axis=0)
    gamma = weight * _ratio(_max_squared_norm(q) or 1.0, _max_squared_norm(centred))
    return D + gamma * pairwise_squared_distances(posture), float(gamma)


def find_transitions(rotations, translations, bone_indices, bone_weights, bones_subset=None, svd_threshold=0.005,
                     threshold_scale=3.0, threshold_reference="median-step", min_gap=2, spacing=0, coverage=0.95,
                     up=None, pivots=None, scale=1.0, posture_weight=1.0, clips=None, walkable=None, spread=0,
                     segment=1, held=None, fps=REFERENCE_FPS):
    """Zheng §3.2 end to end: reference bone, eq. 2–6, threshold, candidate transitions.

    rotations (F, B, 3, 3), translations (F, B, 3), bone_indices (V, K), bone_weights (V, K);
    ``bones_subset``: restrict everything (reference choice included) to these bones, e.g. a
    component of the bone graph; spacing, coverage: :func:`select_transitions`; up (3,), pivots
    (B, 3), scale: with ``up`` given, D also weighs the reference bone's posture
    (:func:`posture_costs`, ``posture_weight``; 0 leaves Zheng's eq. 5). ``clips``
    (:class:`.clips.Clips` of the F frames; None: one clip, the same numbers as
    ``Clips.single(F)``): several clips of one character, transitions within and between them
    (module notes: several clips); ``walkable`` (F,) bool: transitions only between such frames
    (:func:`select_transitions`); ``held``: the clip's :class:`.held_poses.HeldPoses` (None: none),
    each held pose one place (:func:`select_held`); fps: the clip's frame rate, the time a playback
    step is counted in (:func:`transition_threshold`). Returns a :class:`Transitions`.
    """
    rotations = np.asarray(rotations, np.float64)
    translations = np.asarray(translations, np.float64)
    frames, bones = rotations.shape[:2]
    if rotations.shape != (frames, bones, 3, 3) or translations.shape != (frames, bones, 3):
        raise ValueError(f"rotations {rotations.shape} and translations {translations.shape} do not match "
                         "(F, B, 3, 3) and (F, B, 3)")
    if frames < 2:
        raise OptionError(f"finding transitions needs at least 2 frames (got {frames})")
    if clips is not None and clips.total != frames:
        raise ValueError(f"the clips hold {clips.total} frames, the bone transforms {frames}")
    subset = np.arange(bones) if bones_subset is None else _bone_ids(bones_subset, bones)
    reference = reference_bone(bone_indices, bone_weights, bones, subset)
    r_local, t_local, local_bones = local_frame_positions(rotations, translations, reference, subset)
    q, basis, singular = reduced_coordinates(r_local, t_local, svd_threshold)
    r = reference_motion(rotations, translations, reference, clips)
    D, alpha, beta = transition_costs(q, r, clips=clips)
    posture, gamma = None, 0.0
    if up is not None and posture_weight > 0.0:
        posture = reference_posture(rotations[:, reference], translations[:, reference], pivots[reference], up, scale)
        D, gamma = posture_costs(D, q, posture, posture_weight)
    virtual = virtual_costs(q, r, alpha, beta, posture, gamma, clips)  # a virtual frame per clip (module notes)
    moving = None if held is None else held.moving
    threshold = transition_threshold(D, threshold_scale, threshold_reference, clips, moving, fps)
    thresholds = None if clips is None or len(clips) == 1 else \
        clip_thresholds(D, threshold_scale, threshold_reference, clips, moving, fps)
    pairs, costs, admitted, share = select_held(D, threshold if thresholds is None else thresholds, min_gap,
                                                spacing, coverage, start=virtual, clips=clips, walkable=walkable,
                                                spread=spread, segment=segment, held=held)
    options = dict(svd_threshold=svd_threshold, threshold_scale=threshold_scale,
                   threshold_reference=threshold_reference, min_gap=min_gap, spacing=spacing, spread=spread, segment=segment,
                   coverage=coverage,
                   posture_weight=posture_weight if up is not None else 0.0)
    return Transitions(reference=reference, bones=subset.tolist(), local_bones=local_bones, q=q, basis=basis,
                       singular=singular, r=r, alpha=alpha, beta=beta, D=D, threshold=threshold, pairs=pairs,
                       costs=costs, options=options, admitted=admitted, share=share, start=virtual[:, 0].copy(),
                       clips=clips, virtual=virtual, thresholds=thresholds)


def _bone_ids(subset, bones):
    ids = np.unique(np.asarray(list(subset), dtype=np.int64))
    if ids.size and (ids[0] < 0 or ids[-1] >= bones):
        raise OptionError(f"bone ids {ids.tolist()} are outside 0..{bones - 1}")
    return ids


def _squared_distances_to(x, y):
    """‖x_i − y‖² per row of x (F, n) -> (F,)."""
    difference = np.asarray(x, np.float64) - np.asarray(y, np.float64)
    return np.einsum("fn,fn->f", difference, difference)


def _max_squared_norm(x):
    return float(np.max(np.einsum("fn,fn->f", x, x))) if x.size else 0.0


def _ratio(numerator, denominator):
    return numerator / denominator if denominator > 0.0 else 1.0
