"""The numpy reference of :func:`skinsynth.pipeline.synthesis.contact.planting_loops.plant_animations`:
the same steps (:mod:`skinsynth.pipeline.synthesis.contact.planting`'s module notes) on whole arrays of
animations, patches and frames, as they were first written, giving the same targets (each patch's
pivot, turn and correction, the root's offset). The compiled loops must match it to rounding
(tests/pipeline/synthesis/test_planting.py)."""

import numpy as np

from skinsynth.pipeline.synthesis.contact.ground import _raise
from skinsynth.pipeline.synthesis.contact.planting import PlantTargets, centre_operator, target_heights


def plant_targets_reference(F, t, sources, rig, block=16):
    """:func:`skinsynth.pipeline.synthesis.contact.planting.plant_targets` in numpy (F, t unchanged):
    its :class:`~skinsynth.pipeline.synthesis.contact.planting.PlantTargets`."""
    A, M, P = F.shape[0], F.shape[1], rig.owner.size
    out = PlantTargets(states=np.zeros((A, P, M), bool), centre=np.zeros((A, P, M, 3)), turn=np.zeros((A, P, M, 3)),
                       correction=np.zeros((A, P, M, 3)), root=np.zeros((A, M, 3)))
    for a in range(0, A, block):
        parts = _plant_block(F[a:a + block].copy(), t[a:a + block].copy(), sources[:, a:a + block], rig)
        for name, value in zip(("states", "centre", "turn", "correction", "root"), parts):
            getattr(out, name)[a:a + block] = value
    return out


def turned_lowest(F, t, sources, rig):
    """(A, P, M): the patches' lowest sample vertices once the feet are turned (step 1), what the
    plants' floor and heights are measured on."""
    F, t = F.copy(), t.copy()
    src = np.moveaxis(sources[rig.owner], 0, 1)
    state = _bridged(rig.planted[src, np.arange(rig.owner.size)[None, :, None]], rig.bridge)
    _turn_feet(F, t, src, state, _centres(F, t, rig), rig)
    return _lowest(F, t, rig)


def _shifted(x, by, fill):
    """x (..., M) moved by ``by`` frames along the last axis (x[m − by] at m), ``fill`` outside."""
    out = np.full_like(x, fill)
    if by > 0:
        out[..., by:] = x[..., :-by]
    else:
        out[..., :by] = x[..., -by:]
    return out


def _plant_block(F, t, sources, rig):
    from scipy.ndimage import gaussian_filter1d

    P, up = rig.owner.size, rig.up_axis
    patches = np.arange(P)[None, :, None]
    src = np.moveaxis(sources[rig.owner], 0, 1)  # (A, P, M)
    state = _bridged(rig.planted[src, patches], rig.bridge)
    A, M = F.shape[:2]
    if not state.any():
        return state, 0.0, 0.0, 0.0, 0.0
    centre = _centres(F, t, rig)  # (A, P, M, 3)
    turn = _turn_feet(F, t, src, state, centre, rig)
    # the input's step into the source frame, carried by the patch bone's input → output map
    anchor = np.moveaxis(F[:, :, rig.bones[rig.anchor_bone]], 2, 1).astype(np.float64)  # (A, P, M, 3, 3)
    expected = (anchor @ rig.steps_in[src, patches][..., None])[..., 0]
    slide = np.zeros_like(centre)
    slide[:, :, 1:] = centre[:, :, 1:] - centre[:, :, :-1] - expected[:, :, 1:]
    slide[..., up] = 0.0
    stepping = state & _shifted(state, 1, False)  # (A, P, M): steps m−1 → m inside a plant
    # the root: horizontal, the planted patches' mean slide undone, smoothed and summed into an offset
    count = stepping.sum(axis=1)
    push = -(stepping[..., None] * slide).sum(axis=1) / np.maximum(count, 1)[..., None]  # (A, M, 3)
    push = np.stack([_smooth_push(row, rig) for row in push])
    root = np.cumsum(push, axis=1)
    # vertical: the planted patches' mean height error, a normalised smoothing (0 far from plants)
    target = target_heights(rig, src, sources[0])  # the input's heights, spliced as the motion is
    lowest = _lowest(F, t, rig)
    error = np.where(state, target - lowest, 0.0)
    weight = gaussian_filter1d(state.sum(axis=1).astype(np.float64), rig.sigma, axis=1, mode="constant")
    level = gaussian_filter1d(error.sum(axis=1), rig.sigma, axis=1, mode="constant")
    root[..., up] = level / np.maximum(weight, 1.0)
    # each limb: the residual slide summed (leaking) from its plant's first frame, the residual height
    residual = np.where(stepping[..., None], -slide - push[:, None], 0.0)
    # a step's residual taken at most up to the cap (edge_limit / 2 decay), the foot sliding by the rest
    size = np.linalg.norm(residual, axis=-1, keepdims=True)
    cap = rig.edge_limit / (2.0 * rig.decay) if rig.edge_limit > 0.0 else np.inf
    residual = residual * np.where(size > cap, cap / np.maximum(size, 1e-300), 1.0)
    first = state & ~_shifted(state, 1, False)
    last = state & ~_shifted(state, -1, False)
    keep = np.exp(-1.0 / rig.memory)  # past rig.hold frames what exceeds rig.bound leaks (planting.HOLD, …)
    # inside a bridged gap (the input's foot lifted) the sum is let go along a raised cosine
    lifted = stepping & ~rig.planted[src, patches]
    into, left = np.zeros(lifted.shape, np.int64), np.zeros(lifted.shape, np.int64)
    for m in range(1, M):
        into[..., m] = np.where(lifted[..., m], into[..., m - 1] + 1, 0)
    for m in range(M - 1, -1, -1):
        left[..., m] = np.where(lifted[..., m], (left[..., m + 1] if m + 1 < M else 0) + 1, 0)
    span = np.maximum(into + left - 1, rig.release)  # a gap's release: as long as the gap, at least rig.release

    def share(k, span):
        return 0.5 * (1.0 + np.cos(np.pi * np.minimum(k, span) / span))

    correction = np.zeros_like(residual)
    height = np.where(state, error - root[:, None, :, up], 0.0)  # the vertical correction, at the plants
    age = np.zeros(state.shape[:2], np.int64)  # frames since each plant's first, or its last gap
    last_end = np.where(last[:, :, 0], 0, -1)  # each patch's last plant's last frame (−1: none yet)
    rows = np.indices(state.shape[:2])
    for m in range(1, M):  # frame by frame, every animation and patch at once
        starting = first[:, :, m] & (last_end >= 0)
        # what the last plant's spring leaves at a plant's first frame (horizontal): carried
        end = np.maximum(last_end, 0)
        x_end = correction[rows[0], rows[1], end]
        x_end[..., up] = height[rows[0], rows[1], end]
        before = correction[rows[0], rows[1], np.maximum(end - 1, 0)]
        before[..., up] = height[rows[0], rows[1], np.maximum(end - 1, 0)]
        v_end = np.where(stepping[rows[0], rows[1], end][..., None], x_end - before, 0.0)
        y = _rate(x_end, rig.decay, rig.edge_limit)
        kept = _spring(x_end, v_end, (m - end)[..., None].astype(np.float64), y)
        kept[..., up] = 0.0
        slowed = starting & (y[..., 0] != rig.decay)  # too large to let go at the default rate: its age goes on
        age = np.where(stepping[:, :, m], np.where(lifted[:, :, m], 0, age + 1),
                       np.where(first[:, :, m], np.where(slowed, age + m - last_end, 0), age))
        lift = lifted[:, :, m]
        now = span[:, :, m]
        released = np.where(lift, share(into[:, :, m], now) / np.where(lift, share(into[:, :, m] - 1, now), 1.0), 1.0)
        summed = released[..., None] * correction[:, :, m - 1] + residual[:, :, m]
        size = np.linalg.norm(summed, axis=-1, keepdims=True)
        leaking = (age[..., None] > rig.hold) & (size > rig.bound)
        summed = np.where(leaking, summed * (rig.bound + (size - rig.bound) * keep) / np.maximum(size, 1e-300), summed)
        correction[:, :, m] = np.where(stepping[:, :, m, None], summed, 0.0)
        correction[:, :, m] = np.where(starting[..., None], kept, correction[:, :, m])
        last_end = np.where(last[:, :, m], m, last_end)
    correction = np.where(state[..., None], correction, 0.0)
    correction[..., up] = height
    _blend_edges(correction, state, stepping, first, last, rig.decay, rig.edge_limit, carried=True)
    # the floor: a swinging patch no lower than the input's at its source frame, lifted smoothly and
    # tapered off at the plants
    need = np.where(state, 0.0, np.maximum(0.0, target - (lowest + root[:, None, :, up] + correction[..., up])))
    for a, p in zip(*np.nonzero(need.any(axis=2))):
        correction[a, p, :, up] += _floor_lift(need[a, p], state[a, p], rig)
    # animations with no plant keep their targets 0
    some = state.any(axis=(1, 2))
    return (state, centre * some[:, None, None, None], turn, correction * some[:, None, None, None],
            root * some[:, None, None])


def _smooth_push(push, rig):
    """push (M, 3) smoothed by a Gaussian of σ = rig.sigma, widened by the ratio while the root's
    acceleration (the smoothed push's largest step) exceeds rig.edge_limit (three times at most, σ
    at most rig.hold)."""
    from scipy.ndimage import gaussian_filter1d

    sigma = rig.sigma
    for attempt in range(4):
        out = gaussian_filter1d(push, sigma, axis=0, mode="constant")
        largest = np.linalg.norm(np.diff(out, axis=0), axis=1).max() if push.shape[0] > 1 else 0.0
        if not rig.edge_limit > 0.0 or largest <= rig.edge_limit or attempt == 3 or sigma >= rig.hold:
            return out
        sigma = min(float(rig.hold), sigma * largest / rig.edge_limit)


def _floor_lift(need, state, rig):
    """(M,) one swinging patch's lift: its need dilated and smoothed over rig.lift_radius frames and
    tapered at its plants, the radius widened by √ of the ratio while the lift's second difference
    exceeds rig.edge_limit (three times at most, at most rig.hold)."""
    radius = rig.lift_radius
    for attempt in range(4):
        out = _raise(need[None], radius)[0] * _taper(state[None], radius)[0]
        largest = np.abs(np.diff(out, 2)).max() if out.size > 2 else 0.0
        if not rig.edge_limit > 0.0 or largest <= rig.edge_limit or attempt == 3 or radius >= rig.hold:
            return out
        radius = min(rig.hold, int(np.ceil(radius * np.sqrt(largest / rig.edge_limit))))


def _bridged(state, longest):
    """state (A, P, M) with every gap of at most ``longest`` frames between two plants filled."""
    state = state.copy()
    M = state.shape[-1]
    frames = np.arange(M)
    before = np.maximum.accumulate(np.where(state, frames, -1), axis=-1)  # latest planted frame
    after = np.flip(np.minimum.accumulate(np.flip(np.where(state, frames, M), axis=-1), axis=-1), axis=-1)
    inside = (before >= 0) & (after < M) & (after - before - 1 <= longest)
    return state | inside


def _taper(state, radius):
    """(A, P, M): 0 at the planted frames, a smoothstep to 1 at ``radius`` frames from the nearest
    (1 where a patch has none)."""
    M = state.shape[-1]
    frames = np.arange(M)
    before = np.maximum.accumulate(np.where(state, frames, -(M + radius + 1)), axis=-1)
    after = np.flip(np.minimum.accumulate(np.flip(np.where(state, frames, 2 * M + radius + 1), axis=-1), axis=-1),
                    axis=-1)
    x = np.minimum(np.minimum(frames - before, after - frames), radius) / radius
    return x * x * (3.0 - 2.0 * x)


def _rate(x0, decay, limit):
    """(..., 1): a spring's rate from x0 (..., 3): ``decay``, slowed to √(limit / ‖x₀‖) where y² ‖x₀‖
    would exceed ``limit`` (a number, or one per patch (P, 1, 1); not positive: nothing to bound by)."""
    size = np.linalg.norm(x0, axis=-1, keepdims=True)
    bound = np.nan_to_num(np.asarray(limit, dtype=np.float64), nan=0.0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        slowed = np.sqrt(bound / np.maximum(size, 1e-300))
    return np.where((bound <= 0.0) | (size * decay * decay <= bound), decay, slowed)


def _spring(x0, step, k, y):
    """x(0) = x0, x(1) − x(0) = step, then (x0 + c k) e^(−y k)."""
    c = (x0 + step) * np.exp(y) - x0
    return (x0 + c * k) * np.exp(-y * k)


def _blend_edges(correction, state, stepping, first, last, decay, limit=np.inf, carried=False):
    """Outside the plants, ``correction`` (A, P, M, 3) (zero there on entry) becomes the decay of
    the correction at the nearest plant edges: forward from a plant's last frame and backward into
    the next plant's first, each a critically damped spring (Holden's inertialization) whose first
    step across the edge equals the last step inside (matched per frame, not only in continuous
    time: y = 0.58 a frame at 24 fps). In a gap between two plants the backward spring starts from
    what the forward one leaves at the next plant (value and step), so the two add up to the
    next plant's correction there. Each spring's rate y is ``decay``, slowed to √(limit / ‖x₀‖)
    where y² ‖x₀‖ would exceed ``limit`` (the acceleration its start adds), and both edges keep
    their steps (the forward spring's first step less what the backward one holds there).""" 
    M = state.shape[-1]
    frames = np.arange(M)
    outside = ~state

    def rate(x0):  # (..., 3) -> (..., 1)
        return _rate(x0, decay, limit)

    spring = _spring

    def step_term(k, y):  # spring = x0 (1 + (g − 1) k) e^(−y k) + step · step_term(k, y)
        return np.exp(y) * k * np.exp(-y * k)

    def gather(values, at):
        return np.take_along_axis(values, np.clip(at, 0, M - 1)[..., None], axis=2)

    stepped = np.where(stepping[..., None], correction - _shifted_frames(correction, 1), 0.0)
    ahead = np.where((state & _shifted(state, -1, False))[..., None],
                     correction - _shifted_frames(correction, -1), 0.0)
    ended = np.maximum.accumulate(np.where(last, frames, -1), axis=2)
    coming = np.flip(np.minimum.accumulate(np.flip(np.where(first, frames, M), axis=2), axis=2), axis=2)
    after_ok = (ended >= 0)[..., None]
    x_end, v_end = gather(correction, ended), gather(stepped, ended)
    since = np.maximum(frames - ended, 0)[..., None].astype(np.float64)
    until = np.maximum(coming - frames, 0)[..., None].astype(np.float64)
    gap = (coming - ended - 1)[..., None].astype(np.float64)

    def backward_start(y_end):  # the next plant's value and step less what the forward spring leaves there
        left_there = np.where(after_ok, spring(x_end, v_end, since + until, y_end), 0.0)
        left_before = np.where(after_ok, spring(x_end, v_end, since + until - 1.0, y_end), 0.0)
        return gather(correction, coming) - left_there, gather(ahead, coming) - (left_before - left_there)

    def coupling(y_end, y_start):  # κ (blend_edges_row's _coupling)
        b_there, b_before = step_term(gap + 1.0, y_end), step_term(gap, y_end)
        return b_there * (1.0 + (np.exp(y_start) - 1.0) * gap) * np.exp(-y_start * gap) + \
            (b_before - b_there) * step_term(gap, y_start)

    # each spring's rate slowed for a large start (y² ‖x₀‖ ≤ limit), unless the gap is too short for
    # that (κ ≥ 0.5): then both at ``decay``
    inner = after_ok & (coming < M)[..., None] & outside[..., None]
    y_end = rate(x_end)
    x_start, v_start = backward_start(y_end)
    y_start = rate(x_start)
    kappa = np.where(inner, coupling(y_end, y_start), 1.0)
    fall = inner & (kappa >= 0.5) & ((y_end != decay) | (y_start != decay)) & (not carried)
    y_end, y_start = np.where(fall, decay, y_end), np.where(fall, decay, y_start)
    x_default, v_default = backward_start(np.full_like(y_end, decay))
    x_start, v_start = np.where(fall, x_default, x_start), np.where(fall, v_default, v_start)
    kappa = np.where(fall, coupling(y_end, y_start), kappa)
    # what the backward spring holds at the gap's first frame comes off the forward one's first step
    # (both linear in their starts), where that is well posed (κ < 0.5: a one-frame gap cannot keep both)
    solve = np.broadcast_to(inner & (kappa < 0.5), x_start.shape)
    delta = np.divide(spring(x_start, v_start, gap, y_start), 1.0 - kappa, out=np.zeros_like(x_start), where=solve)
    b_there, b_before = step_term(gap + 1.0, y_end), step_term(gap, y_end)
    after = np.where(after_ok, spring(x_end, v_end - delta, since, y_end), 0.0)
    x_start, v_start = x_start + delta * b_there, v_start + delta * (b_before - b_there)
    before = np.where((coming < M)[..., None], spring(x_start, v_start, until, y_start), 0.0)
    correction += np.where(outside[..., None], after + before, 0.0)


def _shifted_frames(x, by):
    """x (A, P, M, 3) moved by ``by`` frames along axis 2, edge values repeated."""
    out = np.empty_like(x)
    if by > 0:
        out[:, :, by:], out[:, :, :by] = x[:, :, :-by], x[:, :, :1]
    else:
        out[:, :, :by], out[:, :, by:] = x[:, :, -by:], x[:, :, -1:]
    return out


def _centres(F, t, rig):
    """The patches' centroids (A, P, M, 3) from F (A, M, B, 3, 3), t (A, M, B, 3): one product."""
    A, M = F.shape[:2]
    b = rig.bones.size
    rows = np.concatenate([F[:, :, rig.bones].reshape(A * M, 9 * b), t[:, :, rig.bones].reshape(A * M, 3 * b)],
                          axis=1)
    operator = centre_operator(rig.rest_terms, rig.weight_terms).astype(rows.dtype)  # float32 bones: a float32 product, its sums then widened
    return np.moveaxis((rows @ operator).reshape(A, M, -1, 3), 2, 1).astype(np.float64)


def _heading(matrices, up_axis):
    """The turn about the up axis within each matrix (..., 3, 3) (any, not only rotations) -> (..., 3, 3)."""
    from skinsynth.pipeline.rig.rotations import rotation_exp

    i, j = (up_axis + 1) % 3, (up_axis + 2) % 3
    angle = np.arctan2(matrices[..., j, i] - matrices[..., i, j], matrices[..., i, i] + matrices[..., j, j])
    return rotation_exp(angle[..., None] * np.eye(3)[up_axis])


def _turn_feet(F, t, src, state, centre, rig):
    """Turn each planted patch's own bones about its centroid so that the patch's anchor bone has,
    at a plant's first frame, the input's orientation at the source frame (the fit's error at the
    patch undone, E) under the output's heading, and later in the plant the orientation it was
    turned to one frame before, turned by the input's own step (module notes), blended in and
    out like the translations; F, t and the
    centroids centre (A, P, M, 3) (the patches that share a turned bone move with it) in place.
    Returns each patch's turn (A, P, M, 3)."""
    from skinsynth.pipeline.rig.rotations import rotation_exp

    turning = np.flatnonzero([bones.size > 0 for bones in rig.own])
    turns = np.zeros(centre.shape)
    if not turning.size:
        return turns
    state = state[:, turning]
    src = src[:, turning]
    slots = rig.anchor_bone[turning]
    now = np.moveaxis(F[:, :, rig.bones[slots]], 2, 1).astype(np.float64)  # (A, p, M, 3, 3)
    patches = turning[None, :, None]
    heading = _heading(now @ rig.inverse_in[src, patches], rig.up_axis)  # (A, p, M, 3, 3)
    first = heading @ rig.orientation_in[src, patches]  # a plant's first frame: the input's, under the heading
    step = heading @ rig.turn_steps_in[src, patches] @ np.swapaxes(heading, -1, -2)  # the input's own step
    stepping = state & _shifted(state, 1, False)
    holding = stepping & rig.planted[src, patches]  # inside a plant, the input's foot down: held
    turn = np.zeros(now.shape[:-1])
    final = now[:, :, 0].copy()
    age = np.zeros(state.shape[:2], np.int64)
    keep = np.exp(-1.0 / rig.memory)
    for m in range(now.shape[2]):  # inside a plant each frame starts from the last one's turned orientation
        age = np.where(holding[:, :, m], age + 1, 0)
        wanted = np.where(holding[:, :, m, None, None], step[:, :, m] @ final, first[:, :, m])
        change = _near_log(wanted @ np.swapaxes(now[:, :, m], -1, -2))
        if m > 0:  # inside a plant a turn changes by at most its cap a frame
            cap = (rig.turn_limit[turning] / (2.0 * rig.decay))[None, :, None]
            moved = change - turn[:, :, m - 1]
            size = np.linalg.norm(moved, axis=-1, keepdims=True)
            capped = turn[:, :, m - 1] + moved * np.minimum(1.0, cap / np.maximum(size, 1e-300))
            change = np.where(stepping[:, :, m, None] & (size > cap), capped, change)
        angle = np.linalg.norm(change, axis=-1, keepdims=True)
        leaking = (age[..., None] > rig.hold) & (angle > rig.turn_bound)  # past the hold what exceeds the bound leaks
        change = np.where(leaking, change * (rig.turn_bound + (angle - rig.turn_bound) * keep) / np.maximum(angle, 1e-300),
                          change)
        angle = np.linalg.norm(change, axis=-1, keepdims=True)
        turn[:, :, m] = np.where(state[:, :, m, None], change * np.minimum(1.0, rig.max_turn / np.maximum(angle, 1e-12)),
                                 0.0)
        final = rotation_exp(turn[:, :, m]) @ now[:, :, m]
    _blend_edges(turn, state, stepping, state & ~_shifted(state, 1, False), state & ~_shifted(state, -1, False),
                 rig.decay, rig.turn_limit[turning][:, None, None])
    slot_of = {int(b): k for k, b in enumerate(rig.bones)}
    for k, p in enumerate(turning):  # few patches: each turns its own bones about its centroid
        rotation = rotation_exp(turn[:, k])  # (A, M, 3, 3)
        c = centre[:, p].copy()
        turns[:, p] = turn[:, k]
        for b in rig.own[p]:
            before_F, before_t = F[:, :, b].astype(np.float64), t[:, :, b].astype(np.float64)
            after_F = rotation @ before_F
            after_t = (rotation @ (before_t - c)[..., None])[..., 0] + c
            F[:, :, b], t[:, :, b] = after_F, after_t
            # every patch the bone moves moves with it: Δcentroid_q = ΔF ā_qb + ω_qb Δt
            slot = slot_of[int(b)]
            change_F, change_t = after_F - before_F, after_t - before_t
            centre += np.moveaxis(change_F @ rig.rest_terms[:, slot].T, -1, 1) \
                + rig.weight_terms[None, :, slot, None, None] * change_t[:, None]
    return turns


def _near_log(matrices):
    """Axis-angle (..., 3) of matrices (..., 3, 3) near rotations, from their skew part and trace
    (angle below π; what is not a rotation in them, a blend window's stretch, is ignored): entry
    by entry, no decomposition (scipy's from_matrix orthonormalises each by an SVD)."""
    m = matrices
    skew = 0.5 * np.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1)
    sine = np.linalg.norm(skew, axis=-1)
    angle = np.arctan2(sine, 0.5 * (m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2] - 1.0))
    return skew * np.where(sine > 1e-12, angle / np.maximum(sine, 1e-300), 1.0)[..., None]


def _lowest(F, t, rig):
    """The patches' lowest points (A, P, M): the lowest of their sample vertices, skinned."""
    up = rig.up_axis
    bones, weights, rest = rig.sample_bones, rig.sample_weights, rig.sample_rest  # (P, S, K), (P, S, K), (P, S, 3)
    rows = F[:, :, bones, up, :].astype(np.float64)  # (A, M, P, S, K, 3)
    heights = (weights * (np.einsum("ampskj,psj->ampsk", rows, rest) + t[:, :, bones, up])).sum(axis=-1)
    heights = np.where((weights.sum(axis=-1) > 0.0)[None, None], heights, np.inf)
    return np.moveaxis(heights.min(axis=-1), 2, 1)
