"""The plants kept on the output (:mod:`.planting`), compiled: one pass per animation.

:func:`plant_animations` does what :mod:`.planting`'s module notes say, animation by animation
and frame by frame, reading the bones in place: the numpy version of the same steps took 0.6 s
of a 250-animation batch whose splice and merge take 0.8 s (arrays of every frame and patch
made, gathered and blended in some forty passes); compiled it takes a small part of that. The
numpy version is kept as the reference in the tests (``tests/pipeline/synthesis/
planting_reference.py``), which this must match to rounding.

Smoothing is scipy's ``gaussian_filter1d`` written out (truncated at 4 σ, weights normalised;
zeros beyond the ends for the root), so the two agree.
"""

import numba
import numpy as np



@numba.njit(cache=True, nogil=True)
def _smooth(values, kernel, nearest):
    """values (M,) convolved with a symmetric kernel (2r + 1,): zeros beyond the ends, or (nearest)
    the end values repeated."""
    M = values.shape[0]
    radius = kernel.shape[0] // 2
    out = np.zeros(M)
    for m in range(M):
        total = 0.0
        for k in range(-radius, radius + 1):
            i = m + k
            if i < 0:
                if not nearest:
                    continue
                i = 0
            elif i >= M:
                if not nearest:
                    continue
                i = M - 1
            total += kernel[k + radius] * values[i]
        out[m] = total
    return out


@numba.njit(cache=True, nogil=True)
def gaussian_kernel(sigma):
    """scipy.ndimage's Gaussian weights (2r + 1,), r = int(4 σ + 0.5), normalised (what
    ``gaussian_filter1d`` convolves with at its default truncation), for a widened σ only: the
    default σ's come from numpy (:func:`.planting.gaussian_weights`), whose vectorised exp differs
    from this one's in the last bit, so outputs that need no widening keep their bytes."""
    radius = int(4.0 * sigma + 0.5)
    weights = np.empty(2 * radius + 1)
    for k in range(-radius, radius + 1):
        weights[k + radius] = np.exp(-0.5 * k * k / (sigma * sigma))
    return weights / weights.sum()


@numba.njit(cache=True, nogil=True)
def smooth_push(push, kernel, sigma, up, limit, widest):
    """push (M, 3) (each step's undone slide, horizontal) smoothed in place with ``kernel`` (the
    Gaussian of σ = ``sigma``), or where the root it sums to would then accelerate by more than
    ``limit`` (the smoothed push's largest step), with a Gaussian widened by that ratio (up to three
    times, σ at most ``widest``): a root offset that pops moves every vertex (module notes of
    :mod:`.planting`, 3.). Returns the σ used."""
    M = push.shape[0]
    raw = push.copy()
    used = sigma
    for attempt in range(4):
        for d in range(3):
            if d != up:
                smooth = _smooth(raw[:, d], kernel, False)
                for m in range(M):
                    push[m, d] = smooth[m]
        largest = 0.0
        for m in range(1, M):
            size = 0.0
            for d in range(3):
                if d != up:
                    size += (push[m, d] - push[m - 1, d]) ** 2
            largest = max(largest, np.sqrt(size))
        if not limit > 0.0 or largest <= limit or attempt == 3 or used >= widest:
            break
        used = min(widest, used * largest / limit)
        kernel = gaussian_kernel(used)
    return used


@numba.njit(cache=True, nogil=True)
def _dilate(values, radius):
    """values (M,) → the largest within ±radius frames of each (the ends repeated)."""
    M = values.shape[0]
    out = np.empty(M)
    for m in range(M):
        largest = values[m]
        for i in range(max(0, m - radius), min(M, m + radius + 1)):
            largest = max(largest, values[i])
        out[m] = largest
    return out


@numba.njit(cache=True, nogil=True)
def _taper(state, radius, out):
    """out (M,): 0 at the planted frames of state (M,) bool, rising as a smoothstep to 1 at
    ``radius`` frames from the nearest (1 everywhere without one)."""
    M = state.shape[0]
    distance = np.full(M, M + radius + 1.0)
    last = -1
    for m in range(M):
        if state[m]:
            last = m
        if last >= 0:
            distance[m] = m - last
    last = -1
    for m in range(M - 1, -1, -1):
        if state[m]:
            last = m
        if last >= 0:
            distance[m] = min(distance[m], last - m)
    for m in range(M):
        x = min(distance[m], float(radius)) / radius
        out[m] = x * x * (3.0 - 2.0 * x)


@numba.njit(cache=True, nogil=True)
def raised_cosine_kernel(radius):
    """The raised-cosine kernel (2r + 1,), normalised (:func:`.ground.raised_cosine`, compiled)."""
    kernel = np.empty(2 * radius + 1)
    for k in range(2 * radius + 1):
        kernel[k] = 1.0 - np.cos(2.0 * np.pi * (k + 1.0) / (2 * radius + 2))
    return kernel / kernel.sum()


@numba.njit(cache=True, nogil=True)
def floor_lift(need, state, radius, kernel, limit, widest, out):
    """out (M,): the lift a swinging patch gets from its ``need`` (M,) (how far below the input's
    its lowest point is): dilated over ``radius`` frames, smoothed with ``kernel`` (the raised
    cosine of that radius) and tapered to 0 at the planted frames of ``state`` (M,) bool; where that
    would accelerate it by more than ``limit`` (largest second difference), with the radius widened
    by the square root of the ratio (up to three times, at most ``widest`` frames)."""
    M = need.shape[0]
    taper = np.empty(M)
    for attempt in range(4):
        lift = _smooth(_dilate(need, radius), kernel, True)
        _taper(state, radius, taper)
        largest = 0.0
        for m in range(M):
            out[m] = lift[m] * taper[m]
            if m >= 2:
                largest = max(largest, abs(out[m] - 2.0 * out[m - 1] + out[m - 2]))
        if not limit > 0.0 or largest <= limit or attempt == 3 or radius >= widest:
            break
        radius = min(widest, int(np.ceil(radius * np.sqrt(largest / limit))))
        kernel = raised_cosine_kernel(radius)
    return out


@numba.njit(cache=True, nogil=True)
def bridge_gaps(state, longest):
    """state (M,) bool with every run of False of at most ``longest`` frames between two runs of
    True set True, in place (:data:`.planting.BRIDGE`)."""
    M = state.shape[0]
    last = -1  # the latest planted frame
    for m in range(M):
        if state[m]:
            if last >= 0 and 1 < m - last <= longest + 1:
                for f in range(last + 1, m):
                    state[f] = True
            last = m
    return state


@numba.njit(cache=True, nogil=True)
def _spring(x0, step, k, decay, growth):
    """x(0) = x0, x(1) − x(0) = step, then (x0 + c k) e^(−y k) (:func:`.planting._blend_edges`)."""
    c = (x0 + step) * growth - x0
    return (x0 + c * k) * np.exp(-decay * k)


@numba.njit(cache=True, nogil=True)
def edge_decay(value, decay, limit):
    """The rate y of a spring from ``value`` (3,): ``decay``, slowed where the decay of a large
    value would accelerate it beyond ``limit`` (y² ‖x₀‖ ≤ limit: :data:`.planting.EDGE_ACCEL`). A
    limit that is not positive (an input that never accelerates, or too short to say: 0 or NaN)
    slows nothing: y = 0 would carry the value on for ever."""
    size = np.sqrt(value[0] ** 2 + value[1] ** 2 + value[2] ** 2)
    if not limit > 0.0 or size * decay * decay <= limit:
        return decay
    return np.sqrt(limit / size)


@numba.njit(cache=True, nogil=True)
def _step_term(k, y):
    """The weight of a spring's first step at k frames (:func:`_spring` = x₀ (1 + (g − 1) k) e^(−y k)
    + step g k e^(−y k), g = e^y)."""
    return np.exp(y) * k * np.exp(-y * k)


@numba.njit(cache=True, nogil=True)
def _coupling(G, y_end, y_start):
    """κ: how much of a change δ of the forward spring's first step comes back, through the
    backward spring's start, at the first of a gap of G frames (the backward spring's value there
    changes by κ δ)."""
    b_there, b_before = _step_term(G + 1.0, y_end), _step_term(G, y_end)
    return b_there * (1.0 + (np.exp(y_start) - 1.0) * G) * np.exp(-y_start * G) + (b_before - b_there) * _step_term(G, y_start)


@numba.njit(cache=True, nogil=True)
def _backward_start(x_end, v_end, there, ahead, until, y_end, has_end):
    """(x_start, v_start) (3,) each: the backward spring's start at the next plant's first frame,
    ``until`` frames after the last plant's last: that plant's value ``there`` and step ``ahead``
    (reversed) less what the forward spring (x_end, v_end, rate y_end) leaves there."""
    x_start = there.copy()
    v_start = ahead.copy()
    if has_end:
        g = np.exp(y_end)
        for d in range(3):
            left_there = _spring(x_end[d], v_end[d], float(until), y_end, g)
            left_before = _spring(x_end[d], v_end[d], float(until - 1), y_end, g)
            x_start[d] -= left_there
            v_start[d] -= left_before - left_there
    return x_start, v_start


@numba.njit(cache=True, nogil=True)
def blend_edges_row(values, state, decay, limit=np.inf, carried=False):
    """One row of :func:`.planting._blend_edges`: values (M, 3) (zero outside the plants on entry),
    state (M,) bool; the frames outside become the springs from the plants' edges, in place; the
    rate of each spring :func:`edge_decay` of its start (``limit``: inf for ``decay``). The backward
    spring starts from what the forward one leaves at the next plant (value and step), and the
    forward one's first step is lessened by what the backward one still holds at the gap's first
    frame (the two linear in their starts, solved at once), so both edges keep their steps exactly
    where that is well posed (:func:`_coupling` κ < 0.5; a one-frame gap cannot keep both: κ = 1).
    A gap too short for slowed springs (κ ≥ 0.5) gets the default rate, unless the next plant
    ``carried`` what the forward spring leaves (:func:`_carried`): then it keeps its slowed rate."""
    M = state.shape[0]
    last_end = -1
    m = 0
    while m < M:
        if state[m]:
            last_end = m  # the latest planted frame: a plant's last once the next gap begins
            m += 1
            continue
        gap_start = m
        while m < M and not state[m]:
            m += 1
        coming = m  # the next plant's first frame (M: none)
        x_end = np.zeros(3)
        v_end = np.zeros(3)
        there = np.zeros(3)  # the next plant's first value, and its first step reversed
        ahead = np.zeros(3)
        for d in range(3):
            if last_end >= 0:
                x_end[d] = values[last_end, d]
                if last_end >= 1 and state[last_end - 1]:
                    v_end[d] = values[last_end, d] - values[last_end - 1, d]
            if coming < M:
                there[d] = values[coming, d]
                if coming + 1 < M and state[coming + 1]:
                    ahead[d] = values[coming, d] - values[coming + 1, d]
        y_end = decay if last_end < 0 else edge_decay(x_end, decay, limit)
        x_start, v_start = _backward_start(x_end, v_end, there, ahead, coming - last_end, y_end, last_end >= 0)
        y_start = edge_decay(x_start, decay, limit)
        kappa = 1.0
        if last_end >= 0 and coming < M:
            kappa = _coupling(float(coming - last_end - 1), y_end, y_start)
            if kappa >= 0.5 and (y_end != decay or y_start != decay) and not carried:  # too short for slowed springs
                y_end = y_start = decay
                x_start, v_start = _backward_start(x_end, v_end, there, ahead, coming - last_end, decay, True)
                kappa = _coupling(float(coming - last_end - 1), decay, decay)
        g_end, g_start = np.exp(y_end), np.exp(y_start)
        if kappa < 0.5:  # the backward spring's reach to the gap's first frame, taken off the forward
            # one's first step (both linear in their starts: solved at once)
            G = float(coming - last_end - 1)
            b_there, b_before = _step_term(G + 1.0, y_end), _step_term(G, y_end)
            for d in range(3):
                delta = _spring(x_start[d], v_start[d], G, y_start, g_start) / (1.0 - kappa)
                v_end[d] -= delta
                x_start[d] += delta * b_there
                v_start[d] += delta * (b_before - b_there)
        for d in range(3):
            for f in range(gap_start, coming):
                total = 0.0
                if last_end >= 0:
                    total += _spring(x_end[d], v_end[d], float(f - last_end), y_end, g_end)
                if coming < M:
                    total += _spring(x_start[d], v_start[d], float(coming - f), y_start, g_start)
                values[f, d] = total
    return values


@numba.njit(cache=True, nogil=True)
def release_share(k, span):
    """The share of a limb's summed slide left k frames into a release of ``span`` frames: a
    raised cosine from 1 (k = 0) to 0 (k = span)."""
    return 0.5 * (1.0 + np.cos(np.pi * min(k, span) / span))


@numba.njit(cache=True, nogil=True)
def _taken_share(slide, push, up, cap):
    """The share of a step's residual (−slide − push, horizontal) a limb's sum takes: all of it, or
    what keeps the sum's step within ``cap`` (:data:`.planting.EDGE_ACCEL`: a sum that grows faster
    cannot be let go within the limit when the foot lifts, so the foot slides by the rest)."""
    size = 0.0
    for d in range(3):
        if d != up:
            size += (slide[d] + push[d]) ** 2
    size = np.sqrt(size)
    return 1.0 if size <= cap else cap / size


@numba.njit(cache=True, nogil=True)
def _carried(values, state, m, last_end, decay, limit, up, acc, age):
    """acc (3,) at a plant's first frame m: what the last plant's spring (ended at ``last_end``, −1:
    none) still holds there, horizontally (the spring :func:`blend_edges_row` lets it go with, of
    rate :func:`edge_decay` of its value); values (M, 3) the limb's correction so far, state (M,).
    The plant holds its foot where that leaves it, so a gap too short to let a large correction go
    within the limit does not throw it back. Returns the age the plant starts at: where the spring
    was slowed (a correction too large to let go at ``decay``), the last plant's, on (past the hold
    what exceeds the bound leaks, so carried corrections cannot grow step after step); else 0."""
    for d in range(3):
        acc[d] = 0.0
    if last_end < 0:
        return 0
    y = edge_decay(values[last_end], decay, limit)
    g = np.exp(y)
    for d in range(3):
        if d != up:
            step = values[last_end, d] - values[last_end - 1, d] if last_end >= 1 and state[last_end - 1] else 0.0
            acc[d] = _spring(values[last_end, d], step, float(m - last_end), y, g)
    return age + m - last_end if y != decay else 0


@numba.njit(cache=True, nogil=True)
def _cap_step(value, before, cap):
    """value (3,) moved towards ``before`` (3,) so it differs from it by at most ``cap``, in place
    (a planted foot's turn, whose steps are capped as a limb sum's are: :func:`_taken_share`)."""
    size = np.sqrt((value[0] - before[0]) ** 2 + (value[1] - before[1]) ** 2 + (value[2] - before[2]) ** 2)
    if size > cap:
        for d in range(3):
            value[d] = before[d] + (value[d] - before[d]) * cap / size


@numba.njit(cache=True, nogil=True)
def _release_step(k, span):
    """The share kept from frame k − 1 to frame k of a release (:func:`release_share`)."""
    return release_share(k, span) / release_share(k - 1, span)


@numba.njit(cache=True, nogil=True)
def _mul(a, b, out):
    """out = a @ b for 3×3 matrices (written out: no allocation, no BLAS call for a matrix this small)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


@numba.njit(cache=True, nogil=True)
def _mul_t(a, b, out):
    """out = a @ bᵀ for 3×3 matrices."""
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[j, 0] + a[i, 1] * b[j, 1] + a[i, 2] * b[j, 2]


@numba.njit(cache=True, nogil=True)
def _rotation_exp(x, y, z, r):
    """r = the rotation of axis-angle (x, y, z) (Rodrigues, the small-angle series near 0)."""
    theta2 = x * x + y * y + z * z
    if theta2 < 1e-8:
        a = 1.0 - theta2 / 6.0
        b = 0.5 - theta2 / 24.0
    else:
        theta = np.sqrt(theta2)
        a = np.sin(theta) / theta
        b = (1.0 - np.cos(theta)) / theta2
    r[0, 0] = 1.0 - b * (y * y + z * z)
    r[1, 1] = 1.0 - b * (x * x + z * z)
    r[2, 2] = 1.0 - b * (x * x + y * y)
    r[0, 1] = b * x * y - a * z
    r[1, 0] = b * x * y + a * z
    r[0, 2] = b * x * z + a * y
    r[2, 0] = b * x * z - a * y
    r[1, 2] = b * y * z - a * x
    r[2, 1] = b * y * z + a * x


@numba.njit(cache=True, nogil=True)
def _rotation_log(m, out):
    """out (3,): the axis-angle of a rotation m (3, 3) (or a matrix near one), a half turn included."""
    out[0] = 0.5 * (m[2, 1] - m[1, 2])
    out[1] = 0.5 * (m[0, 2] - m[2, 0])
    out[2] = 0.5 * (m[1, 0] - m[0, 1])
    sine = np.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2)
    cosine = 0.5 * (m[0, 0] + m[1, 1] + m[2, 2] - 1.0)
    angle = np.arctan2(sine, cosine)
    if sine > 1e-12:
        for d in range(3):
            out[d] *= angle / sine
    elif cosine < 0.0:  # a half turn: the axis from the symmetric part's largest column
        best = 0
        for d in range(3):
            if m[d, d] > m[best, best]:
                best = d
        for d in range(3):
            out[d] = 0.5 * (m[d, best] + m[best, d])
        norm = np.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2)
        for d in range(3):
            out[d] *= np.pi / max(norm, 1e-300)


@numba.njit(cache=True, nogil=True)
def _heading(m, up, out):
    """out = the turn about axis ``up`` within a 3×3 matrix (the reference's ``_heading``): its
    cosine and sine are the normalised (m_ii + m_jj, m_ji − m_ij), no angle taken (the identity
    for a matrix with no turn in it)."""
    i = (up + 1) % 3
    j = (up + 2) % 3
    c = m[i, i] + m[j, j]
    s = m[j, i] - m[i, j]
    norm = np.sqrt(c * c + s * s)
    if norm > 0.0:
        c /= norm
        s /= norm
    else:
        c = 1.0
        s = 0.0
    for k in range(3):
        for l in range(3):
            out[k, l] = 0.0
    out[up, up] = 1.0
    out[i, i] = c
    out[j, j] = c
    out[j, i] = s
    out[i, j] = -s


@numba.njit(cache=True, nogil=True)
def _bone_rows(F, t, a, bones, rows):
    """rows (M, 12b) of animation a: per frame the bones' F (row-major, bone after bone), then their
    t, in float64 (:func:`.planting.centre_operator`'s layout)."""
    M = F.shape[1]
    nb = bones.shape[0]
    for m in range(M):
        for k in range(nb):
            b = bones[k]
            for i in range(3):
                for j in range(3):
                    rows[m, 9 * k + 3 * i + j] = F[a, m, b, i, j]
                rows[m, 9 * nb + 3 * k + i] = t[a, m, b, i]


@numba.njit(cache=True, nogil=True)
def _centres(rows, centre_operator, out):
    """The patches' centroids out (P, M, 3) from the bones' rows (M, 12b): one product."""
    product = np.dot(rows, centre_operator)  # (M, 3P)
    for p in range(out.shape[0]):
        for m in range(out.shape[1]):
            for i in range(3):
                out[p, m, i] = product[m, 3 * p + i]


@numba.njit(cache=True, nogil=True)
def _lowest(rows, up_columns, lowest_operator, samples, out):
    """The patches' lowest points out (P, M): the lowest of each patch's sample vertices (LBS: one
    product of the bones' up rows by the samples' heights (4b, P·S); patch p's first samples[p]
    columns of its S). rows (M, 12b) (:func:`_bone_rows`); up_columns (4b,) its columns that a
    height reads (each bone's F[up, :], then t[up]): the other 8b would multiply zeros, two thirds of
    the product (on the horse's two clips, 13 patches of 39 samples: their plant loop 1.23 → 0.89 s
    a batch of 250 animations, the same numbers)."""
    heights = np.dot(rows[:, up_columns], lowest_operator)
    P, M = out.shape
    S = lowest_operator.shape[1] // P
    for p in range(P):
        for m in range(M):
            lowest = np.inf
            for s in range(samples[p]):
                lowest = min(lowest, heights[m, p * S + s])
            out[p, m] = lowest


@numba.njit(cache=True, nogil=True)
def plant_animations(F, t, src, aim, planted, bones, centre_operator, up_columns, lowest_operator, samples,
                     anchor_slot, inverse_in, steps_in, orientation_in, turn_steps_in, own,
                     decay, kernel, sigma, lift_kernel, max_turn, up, bridge, hold, keep, bound, release,
                     edge_limit, turn_limit, turn_bound, states, centre_out, correction_out, turn_out, root_out):
    """What keeps the plants of animations F (A, M, B, 3, 3), t (A, M, B, 3) (float32, read only):
    each patch's centroid (after its turn), correction and turn (A, P, M, 3) and the root's offset
    (A, M, 3), written
    into the ``*_out`` arrays for :func:`.limb_reach.reach_animations` to make; src
    (A, P, M) each patch's source frame, aim (A, P, M) the height its lowest point keeps there
    (:func:`.planting.target_heights`: the input's, spliced as the motion is); the
    :class:`.planting.PlantRig` tables (own (P, K) the slots in ``bones`` of each patch's own bones,
    padded with −1), the operators of the patches'
    centroids and of their sample vertices' heights (:func:`.planting.centre_operator`,
    :func:`.planting.lowest_operator` and its ``up_columns``; samples (P,) each patch's count); kernel
    the Gaussian weights of
    the root's smoothing, of σ = ``sigma`` (widened where the root would pop: :func:`smooth_push`); lift_kernel the raised cosine (2r + 1,) of a
    swinging patch's lift (r its dilation); bridge: the longest gap between two plants that is
    bridged (:func:`bridge_gaps`); hold: the frames a plant holds its patch exactly; keep: past
    them, the share of a limb's summed slide beyond ``bound`` (its length) kept from one frame to
    the next (:data:`.planting.HOLD`, :data:`.planting.LIMB_MEMORY`, :data:`.planting.LIMB_BOUND`); release: the fewest frames over which
    a bridged gap lets the sum go (:data:`.planting.RELEASE`); edge_limit: the acceleration a limb
    correction's springs at a plant's edges may add (:func:`edge_decay`), and what bounds every other
    correction (:mod:`.planting` notes, 6.), turn_limit (P,) the same for each patch's turn (radians a
    frame²); turn_bound: the turn (radians) a plant holds past ``hold`` before the part beyond it
    leaks (as a limb's sum does past ``bound``, :data:`.planting.TURN_BOUND`); states (A, P, M) written. An animation with no plant keeps its targets 0 (the caller's
    zeros)."""
    A, M, B = F.shape[0], F.shape[1], F.shape[2]
    P = planted.shape[1]
    step_cap = edge_limit / (2.0 * decay) if edge_limit > 0.0 else np.inf
    lift_radius = lift_kernel.shape[0] // 2
    state = np.zeros((P, M), dtype=np.bool_)
    centre = np.zeros((P, M, 3))
    low = np.zeros((P, M))
    turn = np.zeros((M, 3))
    correction = np.zeros((P, M, 3))
    rows = np.zeros((M, centre_operator.shape[0]))
    turned = np.empty((3, 3))
    step = np.empty(3)
    now = np.empty((3, 3))
    mapped = np.empty((3, 3))
    head = np.empty((3, 3))
    wanted = np.empty((3, 3))
    product = np.empty((3, 3))
    rotation = np.empty((3, 3))
    final = np.empty((3, 3))
    change = np.empty(3)
    Fw = np.empty((1, M, B, 3, 3))  # the bones as the feet's turn leaves them: what steps 2 and 3 measure
    tw = np.empty((1, M, B, 3))
    turned_centre = np.zeros((P, M, 3))  # each patch's centroid after the feet's turns, and its turn
    turned_by = np.zeros((P, M, 3))
    for a in range(A):
        anything = False
        for p in range(P):
            for m in range(M):
                state[p, m] = planted[src[a, p, m], p]
            bridge_gaps(state[p], bridge)
            for m in range(M):
                states[a, p, m] = state[p, m]
                anything = anything or state[p, m]
        if not anything:
            continue
        for m in range(M):
            for b in range(B):
                for i in range(3):
                    tw[0, m, b, i] = t[a, m, b, i]
                    for j in range(3):
                        Fw[0, m, b, i, j] = F[a, m, b, i, j]
        # 1. the feet's turn: the input's orientation under the output's heading, about each centroid
        # (on the work copy: the limbs' inverse kinematics makes it, 4.)
        for p in range(P):
            for m in range(M):
                for d in range(3):
                    turned_by[p, m, d] = 0.0
        if own[:, 0].max() >= 0:
            _bone_rows(Fw, tw, 0, bones, rows)
            _centres(rows, centre_operator, centre)  # then moved with each bone a turn moves
        for p in range(P):
            if own[p, 0] < 0:
                continue
            anchor = bones[anchor_slot[p]]
            age = 0  # frames the plant has held its foot's orientation
            for m in range(M):
                turn[m, 0] = 0.0
                turn[m, 1] = 0.0
                turn[m, 2] = 0.0
                if not state[p, m]:
                    continue
                f = src[a, p, m]
                for i in range(3):
                    for j in range(3):
                        now[i, j] = Fw[0, m, anchor, i, j]
                _mul(now, inverse_in[f, p], mapped)
                _heading(mapped, up, head)
                inside = m > 0 and state[p, m - 1]
                if inside and planted[f, p]:  # inside a plant: the last frame's, by the input's own step
                    age += 1
                    _mul(head, turn_steps_in[f, p], product)
                    _mul_t(product, head, rotation)
                    _mul(rotation, final, wanted)
                else:  # a plant's first frame, or the input's foot lifted inside a bridged gap: the
                    # input's orientation under the output's heading
                    age = 0
                    _mul(head, orientation_in[f, p], wanted)
                _mul_t(wanted, now, product)
                _rotation_log(product, change)
                if inside:  # a turn changes by at most its cap a frame inside a plant
                    _cap_step(change, turn[m - 1], turn_limit[p] / (2.0 * decay))
                angle = np.sqrt(change[0] ** 2 + change[1] ** 2 + change[2] ** 2)
                if age > hold and angle > turn_bound:  # past the hold, what exceeds the bound leaks
                    shrink = (turn_bound + (angle - turn_bound) * keep) / angle
                    for d in range(3):
                        change[d] *= shrink
                    angle *= shrink
                scale = min(1.0, max_turn / max(angle, 1e-12))
                for d in range(3):
                    turn[m, d] = change[d] * scale
                _rotation_exp(turn[m, 0], turn[m, 1], turn[m, 2], rotation)
                _mul(rotation, now, final)  # the anchor's orientation as turned: the next frame's start
            blend_edges_row(turn, state[p], decay, turn_limit[p])
            # the turn, about the patch's centroid; every patch centroid moves with each bone turned
            nb = bones.shape[0]
            for m in range(M):
                for d in range(3):
                    turned_by[p, m, d] = turn[m, d]
                _rotation_exp(turn[m, 0], turn[m, 1], turn[m, 2], rotation)
                for k in range(own.shape[1]):
                    slot = own[p, k]
                    if slot < 0:
                        break
                    b = bones[slot]
                    for i in range(3):
                        for j in range(3):
                            now[i, j] = Fw[0, m, b, i, j]
                    _mul(rotation, now, product)
                    for d in range(3):
                        change[d] = tw[0, m, b, d] - centre[p, m, d]
                    for i in range(3):
                        moved = (rotation[i, 0] * change[0] + rotation[i, 1] * change[1]
                                 + rotation[i, 2] * change[2] + centre[p, m, i])
                        step[i] = moved - tw[0, m, b, i]
                        tw[0, m, b, i] = moved
                        for j in range(3):
                            turned[i, j] = product[i, j] - now[i, j]
                            Fw[0, m, b, i, j] = product[i, j]
                    for q in range(P):  # Δc_q = ΔF ā_qb + ω_qb Δt (the centroid operator's entries)
                        for i in range(3):
                            total = step[i] * centre_operator[9 * nb + 3 * slot + i, 3 * q + i]
                            for j in range(3):
                                total += turned[i, j] * centre_operator[9 * slot + 3 * i + j, 3 * q + i]
                            centre[q, m, i] += total
        # 2. the centroids and lowest points after the turn; the input's steps, carried; the slide
        _bone_rows(Fw, tw, 0, bones, rows)
        _centres(rows, centre_operator, centre)
        _lowest(rows, up_columns, lowest_operator, samples, low)
        for p in range(P):  # what each correction moves from
            for m in range(M):
                for d in range(3):
                    turned_centre[p, m, d] = centre[p, m, d]
        slide = np.zeros((P, M, 3))  # each step's horizontal slide beyond the input's own, inside a plant
        push = np.zeros((M, 3))
        for m in range(1, M):
            count = 0
            for p in range(P):
                if state[p, m] and state[p, m - 1]:
                    count += 1
                    f = src[a, p, m]
                    b = bones[anchor_slot[p]]
                    for d in range(3):
                        if d != up:
                            expected = (Fw[0, m, b, d, 0] * steps_in[f, p, 0] + Fw[0, m, b, d, 1] * steps_in[f, p, 1]
                                        + Fw[0, m, b, d, 2] * steps_in[f, p, 2])
                            slide[p, m, d] = centre[p, m, d] - centre[p, m - 1, d] - expected
                            push[m, d] -= slide[p, m, d]
            if count > 0:
                for d in range(3):
                    push[m, d] /= count
        root = np.zeros((M, 3))
        smooth_push(push, kernel, sigma, up, edge_limit, float(hold))
        for d in range(3):
            if d == up:
                continue
            total = 0.0
            for m in range(M):
                total += push[m, d]
                root[m, d] = total
        level = np.zeros(M)
        weight = np.zeros(M)
        for m in range(M):
            for p in range(P):
                if state[p, m]:
                    weight[m] += 1.0
                    level[m] += aim[a, p, m] - low[p, m]
        level = _smooth(level, kernel, False)
        weight = _smooth(weight, kernel, False)
        for m in range(M):
            root[m, up] = level[m] / max(weight[m], 1.0)
        # 3. each limb: the residual slide summed over its plant (leaking; released where the input's
        # foot is off the ground inside a bridged gap), the residual height; blended
        for p in range(P):
            acc = np.zeros(3)
            age = 0  # frames since the plant's first, or since its last bridged gap
            last_end = -1  # the last plant's last frame
            lifted = 0  # frames into the current bridged gap
            span = 1  # frames its release takes
            for m in range(M):
                for d in range(3):
                    correction[p, m, d] = 0.0
                if not state[p, m]:
                    continue
                if m > 0 and state[p, m - 1]:
                    age += 1
                    kept = 1.0
                    if not planted[src[a, p, m], p]:  # the input's foot is lifted: let the sum go
                        if lifted == 0:
                            gap = 0
                            while m + gap < M and state[p, m + gap] and not planted[src[a, p, m + gap], p]:
                                gap += 1
                            span = max(gap, release)
                        lifted += 1
                        kept = _release_step(lifted, span)
                        age = 0
                    else:
                        lifted = 0
                    size = 0.0
                    taken = _taken_share(slide[p, m], push[m], up, step_cap)
                    for d in range(3):
                        if d != up:
                            acc[d] = kept * acc[d] - taken * (slide[p, m, d] + push[m, d])
                            size += acc[d] * acc[d]
                    size = np.sqrt(size)
                    if age > hold and size > bound:  # past the hold, what exceeds the bound leaks
                        for d in range(3):
                            acc[d] *= (bound + (size - bound) * keep) / size
                else:  # a plant's first frame: what the last plant's spring leaves here, carried
                    age = _carried(correction[p], state[p], m, last_end, decay, edge_limit, up, acc, age)
                for d in range(3):
                    correction[p, m, d] = acc[d]
                correction[p, m, up] = aim[a, p, m] - low[p, m] - root[m, up]
                if m + 1 == M or not state[p, m + 1]:
                    last_end = m
            blend_edges_row(correction[p], state[p], decay, edge_limit, True)
        # 3b. the floor: a swinging patch no lower than the input's at its source frame, lifted
        # smoothly (dilated, raised-cosine), the lift tapered to 0 at the plants
        need = np.zeros(M)
        lift = np.zeros(M)
        for p in range(P):
            below = False
            for m in range(M):
                need[m] = 0.0
                if state[p, m]:
                    continue
                want = aim[a, p, m]
                need[m] = max(0.0, want - (low[p, m] + root[m, up] + correction[p, m, up]))
                below = below or need[m] > 0.0
            if not below:
                continue
            floor_lift(need, state[p], lift_radius, lift_kernel, edge_limit, hold, lift)
            for m in range(M):
                correction[p, m, up] += lift[m]
        # 4. the targets, for the limbs' inverse kinematics (:mod:`.limb_reach`) and the root
        for p in range(P):
            for m in range(M):
                for d in range(3):
                    centre_out[a, p, m, d] = turned_centre[p, m, d]
                    correction_out[a, p, m, d] = correction[p, m, d]
                    turn_out[a, p, m, d] = turned_by[p, m, d]
        for m in range(M):
            for d in range(3):
                root_out[a, m, d] = root[m, d]
    return states


@numba.njit(cache=True, nogil=True)
def lowest_after(F, t, bones, up_columns, lowest_operator, samples, lowest):
    """lowest (A, M): the lowest of every patch's sample vertices (:func:`_lowest`) at each frame of
    the animations F (A, M, B, 3, 3), t (A, M, B, 3), as their bones are now."""
    A, M = F.shape[0], F.shape[1]
    rows = np.zeros((M, 12 * bones.shape[0]))
    low = np.zeros((samples.shape[0], M))
    for a in range(A):
        _bone_rows(F, t, a, bones, rows)
        _lowest(rows, up_columns, lowest_operator, samples, low)
        for m in range(M):
            lowest[a, m] = np.inf
            for p in range(low.shape[0]):
                lowest[a, m] = min(lowest[a, m], low[p, m])
