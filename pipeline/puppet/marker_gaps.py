"""Gaps in a motion-capture take filled, as mocap tools fill them (:func:`.markers.drive_from_markers`'s
steps 2 and 6): short ones bridged in time by a smoothing spline (:func:`fill_short_gaps`); a marker riding one
bone with three others from their rigid motion (:func:`fill_rigid_clusters`); the rest from the
other markers through the puppet's training controls, a Gaussian's conditional mean on their
principal subspace (:func:`fill_from_training`, its expected error :func:`fill_uncertainty`),
each filled run joined to its seen ends (:func:`join_filled_runs`).
"""

import numpy as np

from ..errors import OptionError
from ..runtime.rows import unique_rows
from ..rig.rotations import polar_rotation

#: The short-gap rule: gaps of at most this long (seconds) with a seen sample on both sides are
#: bridged in time (:func:`fill_short_gaps`; ``--max-gap`` takes frames), longer ones filled from
#: the other markers (:func:`fill_from_training`). Measured on Zheng's dancer, the fastest shared
#: capture (spins; issue 66's held-out takes at 100 Hz, gaps of 0.01–1.3 s, five draws, a filled
#: control's error over the height by gap length, filtered at 10 Hz): the spline beat the other
#: markers' fill up to 0.4 s, clean or with noise (0.26–0.30 s: 0.68 % against 0.82 % clean, 0.92 %
#: against 0.88 % with noise; 0.36–0.40 s: 0.71 % against 1.35 % clean; 0.41–0.45 s: 2.2 % against
#: 1.1 %), and the line over gaps of up to 10 frames done before at every length (1–5 frames: 0.07 %
#: against 0.14 %). A slower body changes less over a gap, so its spline holds longer: 0.3 s, short
#: of where the fastest body's stopped, holds for any.
MAX_GAP_SECONDS = 0.3
#: The smoothing spline reads the samples this long (seconds) on each side of a gap.
SPLINE_REACH_SECONDS = 0.2
#: The spline penalises the squared differences of this order (3: the jerk; its limit without noise
#: is a quintic spline, whose velocity and acceleration run on through the gap: a spinning marker's
#: curve is carried, where a line cuts the chord). Order 2 (a cubic) did a third worse on the
#: dancer's takes (control error over every sample 0.039 % of the height against 0.029 %, clean).
SPLINE_ORDER = 3
#: :func:`roughness` compares paths between samples this far apart (seconds): 0.05 s, where a
#: marker's turn outweighs 1 mm of noise (at 100 Hz, between neighbouring samples the noise chose
#: the world's frame for a spinning hand, 33 mm off, where the body's was 10 mm off).
ROUGHNESS_SECONDS = 0.05
#: Principal directions of the training controls kept for the long-gap fill: the smallest number
#: explaining this share of their in-place variance (and never more than the seen markers'
#: coordinates less the 6 of a rigid motion can determine). All of them: the fit's prior
#: (:data:`SUBSPACE_RIDGE`, a Gaussian on each coefficient with its direction's variance) already
#: keeps a direction the seen markers hardly see near the mean, so cutting the last 1 % of the
#: variance only threw away what the seen markers do determine (issue 45's held-out takes with 5 %
#: of the samples missing, vertex error over the clean controls': crane 1.17 → 1.13, samba 1.05 →
#: 1.03 against 99 %).
SUBSPACE_VARIANCE = 1.0
#: The subspace fit's noise, as a share of the largest retained variance: a Gaussian prior on each
#: coefficient with its direction's training variance v_j gives the ridge ``ridge · v_0 / v_j``, so a
#: direction the seen markers barely see stays near the training mean instead of being thrown far
#: outside the training poses, and the well-seen ones are fitted almost freely.
SUBSPACE_RIDGE = 1e-4
#: The fill alternates the rigid fit of a frame's seen markers onto its fitted pose and the pose's
#: subspace coefficients (both least squares, so the error never grows); at most this many rounds.
FILL_ITERATIONS = 50
#: A marker rides one bone rigidly where that bone carries at least this share of its control
#: vertex's skin weight; markers riding the same bone form a rigid cluster (:func:`fill_rigid_clusters`).
RIGID_WEIGHT = 0.9


def runs(missing):
    """Runs of True in missing (T,): (starts, ends) with ends exclusive."""
    edges = np.diff(np.concatenate([[0], missing.astype(np.int8), [0]]))
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)


def fill_short_gaps(points, max_gap, rate, cutoff):
    """points (T, M, 3) sampled at ``rate`` Hz, NaN where missing -> (filled copy, filled (T, M)
    bool): every gap of at most ``max_gap`` frames with a seen frame on both sides bridged by
    :func:`smoothing_spline_gap` at the take's bandwidth ``cutoff`` Hz (None, a take kept raw:
    :data:`.marker_filter.BODY_CUTOFF`), in the world's frame or the body's (:func:`_bridged`). Gaps
    at the take's start or end, or longer, stay NaN
    (:func:`fill_from_training` takes them)."""
    from .marker_filter import BODY_CUTOFF

    points = np.array(points, dtype=np.float64)
    missing = np.isnan(points).any(axis=2)
    filled = np.zeros_like(missing)
    reach = max(SPLINE_ORDER + 1, int(round(SPLINE_REACH_SECONDS * rate)))
    stiffness = spline_stiffness(rate, BODY_CUTOFF if cutoff is None else cutoff)
    stride = max(1, int(round(ROUGHNESS_SECONDS * rate)))
    for marker in np.flatnonzero(missing.any(axis=0)):  # markers, never vertices
        starts, ends = runs(missing[:, marker])
        short = (starts > 0) & (ends < len(points)) & (ends - starts <= max_gap)
        for start, end in zip(starts[short], ends[short]):  # gaps, never vertices
            points[start:end, marker] = _bridged(points, missing, marker, start, end, reach, stiffness, stride)
            filled[start:end, marker] = True
    return points, filled


def _bridged(points, missing, marker, start, end, reach, stiffness, stride):
    """The gap [start, end) of ``marker`` (points (T, M, 3), missing (T, M)) bridged by
    :func:`smoothing_spline_gap` in the frame where its seen path around the gap is smoother
    (:func:`roughness`, samples ``stride`` apart): the world's, or the body's, the rigid motion of the
    other markers seen
    throughout (:func:`rigid_onto`, each weighed by its nearness: a Gaussian of its distance from
    the marker as the gap begins, as wide as the median one, so a hand is carried by the arm and
    chest more than by the feet). A spin turns the world path, not the body's: a hand hidden for
    0.3 s of a 360°-a-second turn came back 0.006 mm off in the body's frame, 1 mm in the world's
    (tests/pipeline/puppet/test_marker_spin_fills.py); on Zheng's dancer, whose limbs move on their
    own, the choice did as well as the world's frame alone (0.031 % and 0.123 % of the height per
    sample, clean and with noise), the body's frame alone a little worse (0.034 %, 0.126 %)."""
    low, high = max(0, start - reach), min(len(points), end + reach)
    seen = ~missing[:, marker]
    world = smoothing_spline_gap(points[:, marker], seen, start, end, reach, stiffness)
    others = ~missing[low:high].any(axis=0)
    others[marker] = False
    if others.sum() < 3:
        return world
    distance = np.linalg.norm(points[start - 1, others] - points[start - 1, marker], axis=1)
    nearness = np.exp(-(distance / max(float(np.median(distance)), 1e-300)) ** 2) + 1e-3
    turns, shifts = rigid_onto(points[low:high][:, others], points[start - 1, others],
                               np.broadcast_to(nearness, (high - low, int(others.sum()))))
    body = np.full_like(points[:, marker], np.nan)
    body[low:high] = np.einsum("tab,tb->ta", turns, points[low:high, marker]) + shifts
    window = seen & (np.arange(len(points)) >= low) & (np.arange(len(points)) < high)
    if not roughness(body, window, stride) < roughness(points[:, marker], window, stride):
        return world
    path = smoothing_spline_gap(body, window, start, end, reach, stiffness)
    gap = slice(start - low, end - low)
    return np.einsum("tba,tb->ta", turns[gap], path - shifts[gap])


def roughness(values, seen, stride):
    """The mean squared third difference of values (T, 3), between samples ``stride`` apart all
    seen (``seen`` (T,) bool): how much a path turns away from a smooth curve (inf where no four
    such samples are). Over :data:`ROUGHNESS_SECONDS`, not one sample: between neighbouring samples
    the noise outweighs the motion's turn (its third difference 20 times the noise's variance; a
    motion's grows with the cube of the stride)."""
    h = stride
    third = values[3 * h:] - 3.0 * values[2 * h:-h] + 3.0 * values[h:-2 * h] - values[:-3 * h]
    whole = seen[3 * h:] & seen[2 * h:-h] & seen[h:-2 * h] & seen[:-3 * h]
    return float(np.mean(np.sum(third[whole] ** 2, axis=1))) if whole.any() else np.inf


def spline_stiffness(rate, cutoff):
    """λ of :func:`smoothing_spline_gap` for a bandwidth of ``cutoff`` Hz at ``rate`` Hz: a penalty
    λ Σ (Δᵏ x)² (k = :data:`SPLINE_ORDER`) passes a frequency f with the gain
    1 / (1 + λ (2 sin(π f / rate))^2k), a half at λ = (2 sin(π f / rate))^−2k: the spline then
    has the same bandwidth as the take's low-pass (a clean take's high cut-off: a spline that all
    but interpolates its seen samples; a noisy one's: a spline that smooths them as the filter will)."""
    return float((2.0 * np.sin(np.pi * min(cutoff / rate, 0.45))) ** (-2 * SPLINE_ORDER))


def smoothing_spline_gap(values, seen, start, end, reach, stiffness):
    """The gap [start, end) of one marker's values (T, 3) (seen (T,) bool) bridged by the discrete
    smoothing spline through the seen samples within ``reach`` samples of it (Whittaker): the path x
    minimising Σ_seen |x_t − values_t|² + ``stiffness`` Σ |Δᵏ x|² (k = :data:`SPLINE_ORDER`),
    read in the gap -> (end − start, 3). A marker seen fewer than k + 1 times there: the line
    between the gap's ends."""
    low, high = max(0, start - reach), min(len(values), end + reach)
    observed = seen[low:high].copy()
    observed[start - low:end - low] = False
    if observed.sum() <= SPLINE_ORDER:
        share = (np.arange(start, end) - start + 1.0) / (end - start + 1.0)
        return values[start - 1] + share[:, None] * (values[end] - values[start - 1])
    difference = np.diff(np.eye(high - low), SPLINE_ORDER, axis=0)
    system = np.diag(observed.astype(np.float64)) + stiffness * difference.T @ difference
    path = np.linalg.solve(system, np.where(observed[:, None], values[low:high], 0.0))
    return path[start - low:end - low]


def rigid_onto(points, reference, weights):
    """Per-frame rigid fits (R (T, 3, 3), t (T, 3)) of points (T, M, 3) onto reference (M, 3) or
    (T, M, 3) over the markers with weight 1 in weights (T, M) (NaN points allowed where the
    weight is 0)."""
    w = weights.astype(np.float64)
    reference = np.broadcast_to(reference, points.shape)
    count = np.maximum(w.sum(axis=1), 1.0)[:, None]
    safe = np.where(w[..., None] > 0, points, 0.0)
    mean_p = np.einsum("tm,tma->ta", w, safe) / count
    mean_r = np.einsum("tm,tma->ta", w, reference) / count
    cross = np.einsum("tm,tma,tmb->tab", w, reference - mean_r[:, None], safe - mean_p[:, None])
    rotations = polar_rotation(cross)
    return rotations, mean_r - np.einsum("tab,tb->ta", rotations, mean_p)


def training_subspace(training, variance=SUBSPACE_VARIANCE):
    """The principal subspace of training controls (n_p, n, 3), in place: (mean (n, 3), bases
    (k, n, 3) orthonormal as 3n-vectors, variances (k,)), k the smallest explaining ``variance``
    of the total (at least 1 where anything varies)."""
    flat = np.asarray(training, dtype=np.float64).reshape(len(training), -1)
    mean = flat.mean(axis=0)
    _, singular, vt = np.linalg.svd(flat - mean, full_matrices=False)
    energy = singular ** 2
    if energy.sum() <= 0:
        return mean.reshape(-1, 3), np.zeros((0, *training.shape[1:])), np.zeros(0)
    k = int(np.searchsorted(np.cumsum(energy) / energy.sum(), variance - 1e-12) + 1)
    k = min(k, int(np.sum(energy > energy[0] * 1e-12)))
    return mean.reshape(-1, 3), vt[:k].reshape(k, -1, 3), energy[:k] / len(flat)


def fill_from_training(controls, training, min_markers, ridge=SUBSPACE_RIDGE, subspace=None):
    """Fill the markers still missing in controls (T, n, 3) (NaN) from the seen ones through the
    training controls' principal subspace (training (n_p, n, 3), in place):
    each frame's seen controls are brought rigidly onto the subspace mean, the subspace
    coefficients fitted to them by ridge least squares (``ridge``, :data:`SUBSPACE_RIDGE`), the missing ones
    read off and moved back. Frames are solved together by which markers they miss.

    A frame seeing fewer than ``min_markers`` (≥ 3) markers is held: a copy of the last good
    frame (of the first, before it). ``subspace``: :func:`training_subspace` of ``training`` where
    already at hand. Returns (filled (T, n, 3), subspace_filled (T, n) bool, held (h,) frame
    indices); OptionError when no frame has enough."""
    controls = np.array(controls, dtype=np.float64)
    missing = np.isnan(controls).any(axis=2)
    good = (~missing).sum(axis=1) >= min_markers
    if not good.any():
        raise OptionError(f"no frame of the take sees {min_markers} of its {controls.shape[1]} markers")
    mean, bases, variances = training_subspace(training) if subspace is None else subspace
    filled = np.zeros_like(missing)
    todo = good & missing.any(axis=1)
    patterns, which = unique_rows(missing[todo], return_inverse=True)
    frames = np.flatnonzero(todo)
    for number, pattern in enumerate(patterns):  # one solve per pattern of missing markers
        at = frames[which.reshape(-1) == number]
        seen = ~pattern
        k = min(len(variances), max(3 * int(seen.sum()) - 6, 0))
        design = bases[:k, seen].reshape(k, -1).T  # (3 |seen|, k)
        penalty = np.diag(ridge * variances[0] / variances[:k]) if k else np.zeros((0, 0))
        solve = np.linalg.inv(design.T @ design + penalty) @ design.T if k else np.zeros((0, design.shape[0]))
        weights = np.broadcast_to(seen, (len(at), len(seen)))
        shape = np.broadcast_to(mean, (len(at), *mean.shape))  # the fitted pose, in place
        for _ in range(FILL_ITERATIONS):  # alternate: the rigid fit onto the pose, the pose's coefficients
            rotations, translations = rigid_onto(controls[at], shape, weights)
            local = np.einsum("tab,tmb->tma", rotations, np.where(seen[None, :, None], controls[at], 0.0)) \
                + translations[:, None]
            coefficients = solve @ (local[:, seen] - mean[seen]).reshape(len(at), -1).T
            previous, shape = shape, mean[None] + np.einsum("kt,kma->tma", coefficients, bases[:k])
            if np.abs(shape - previous).max() <= 1e-12 * (1.0 + np.abs(mean).max()):
                break
        back = np.einsum("tba,tmb->tma", rotations, shape[:, pattern] - translations[:, None])  # Rᵀ (x − t)
        controls[at[:, None], np.flatnonzero(pattern)[None, :]] = back
        filled[at[:, None], np.flatnonzero(pattern)[None, :]] = True
    good_frames = np.flatnonzero(good)
    source = np.maximum.accumulate(np.where(good, np.arange(len(controls)), -1))
    source = np.where(source < 0, good_frames[0], source)
    held = np.flatnonzero(~good)
    controls[held] = controls[source[held]]
    return controls, filled, held


def rigid_clusters(bone_indices, bone_weights):
    """The bone each marker rides rigidly, from its control vertex's skin weights (bone_indices,
    bone_weights (n, K)): (n,) the bone carrying at least :data:`RIGID_WEIGHT` of it, −1 where
    none does (a marker over a joint moves with two bones)."""
    weights = np.asarray(bone_weights, dtype=np.float64)
    strongest = np.argmax(weights, axis=1)
    rows = np.arange(len(weights))
    return np.where(weights[rows, strongest] >= RIGID_WEIGHT, np.asarray(bone_indices)[rows, strongest], -1)


def fill_rigid_clusters(markers, bones, neutral):
    """Fill markers (T, n, 3) (NaN where missing) from the others riding the same bone (``bones``
    (n,), :func:`rigid_clusters`), as motion-capture tools fill a rigid body: where a frame sees
    at least 3 of a missing marker's cluster, not on a line, the rigid motion taking them from the
    ``neutral`` frame to this one carries the missing marker from where the neutral frame saw it
    (exact for a rigid cluster). Returns (filled copy, rigid (T, n) bool: the samples filled)."""
    markers = np.array(markers, dtype=np.float64)
    missing = np.isnan(markers).any(axis=2)
    rigid = np.zeros_like(missing)
    for bone in np.unique(bones[bones >= 0]):  # bones, never vertices
        cluster = np.flatnonzero(bones == bone)
        if len(cluster) < 4:
            continue
        seen = ~missing[:, cluster]
        frames = np.flatnonzero(missing[:, cluster].any(axis=1) & (seen.sum(axis=1) >= 3))
        if not len(frames) or np.isnan(markers[neutral, cluster]).any():
            continue
        # each frame's rigid motion of its seen cluster markers from the neutral frame (R maps now -> neutral)
        turns, shifts = rigid_onto(markers[frames][:, cluster], markers[neutral, cluster], seen[frames])
        weights = seen[frames].astype(np.float64)  # the seen markers must span a plane
        points = np.where(seen[frames][..., None], markers[frames][:, cluster], 0.0)
        centred = points - (np.einsum("tm,tma->ta", weights, points) / weights.sum(axis=1)[:, None])[:, None]
        spread = np.linalg.eigvalsh(np.einsum("tm,tma,tmb->tab", weights, centred, centred))  # ascending
        usable = spread[:, 1] > 1e-12 * np.maximum(spread[:, 2], 1e-300)
        for slot, marker in enumerate(cluster):
            take = usable & missing[frames, marker]
            if not take.any():
                continue
            # Rᵀ (x_neutral − t): the neutral position carried back to the frame
            placed = np.einsum("tba,tb->ta", turns[take], markers[neutral, marker] - shifts[take])
            markers[frames[take], marker] = placed
            rigid[frames[take], marker] = True
    return markers, rigid


def fill_uncertainty(missing, training, ridge=SUBSPACE_RIDGE, subspace=None):
    """Each frame's expected error of :func:`fill_from_training`'s fill: missing (T, n) bool, the
    markers it fills; training (n_p, n, 3). The fit is a Gaussian's conditional mean (each
    coefficient's prior its direction's variance v_j, the seen coordinates' noise ``ridge`` · v_0),
    so the filled markers' error has the covariance B_m (DᵀD + Λ)⁻¹ B_mᵀ · ridge · v_0 from the
    directions fitted, plus Σ v_j B_j B_jᵀ over those left out (more than the seen markers can
    determine); it depends only on which markers are seen. -> (T,) the RMS distance of a filled
    marker from where it should be (0 where nothing is filled), in the controls' units; the rigid
    alignment's own error is left out. ``subspace``: as :func:`fill_from_training`'s."""
    _, bases, variances = training_subspace(training) if subspace is None else subspace
    out = np.zeros(len(missing))
    todo = missing.any(axis=1) & ~missing.all(axis=1)
    if not todo.any() or not len(variances):
        return out
    patterns, which = unique_rows(missing[todo], return_inverse=True)
    frames = np.flatnonzero(todo)
    for number, pattern in enumerate(patterns):
        seen = ~pattern
        k = min(len(variances), max(3 * int(seen.sum()) - 6, 0))
        design = bases[:k, seen].reshape(k, -1).T
        noise = ridge * variances[0]
        posterior = noise * np.linalg.inv(design.T @ design + np.diag(noise / variances[:k]))
        lost = bases[:, pattern].reshape(len(variances), -1)  # (K, 3 |missing|)
        fitted = np.einsum("ka,kl,la->a", lost[:k], posterior, lost[:k])
        left = np.einsum("k,ka->a", variances[k:], lost[k:] ** 2)
        out[frames[which.reshape(-1) == number]] = np.sqrt(3.0 * np.mean(fitted + left))
    return out


def join_filled_runs(points, filled, seen_points=None, training=None, ridge=SUBSPACE_RIDGE, subspace=None):
    """points (T, M, 3) with ``filled`` (T, M) samples made by :func:`fill_from_training`: each
    filled run with a seen sample on both sides is offset by the line from the jump at its start
    to the jump at its end (the subspace gives the run's motion, its seen ends where it is: a
    pattern fill's end correction); a run at the take's start or end by the jump at its one seen
    end. Returns a corrected copy.

    The jump at a seen end: with ``seen_points`` (T, M, 3), the take before the fill (NaN where
    missing), and ``training``, the seen sample beside the run less what the same fill makes of
    it there from the markers the run's adjacent filled frame sees (:func:`fill_from_training`
    with the run's pattern hidden): the fill's own error, measured at one frame. Without them (or
    where fewer than 3 markers are seen there), the seen sample less the run's first filled one,
    which also counts one frame's motion as error (issue 45's held-out takes with noise and gaps:
    crane 1.19× → 1.17× the clean controls' error over five seeds; averaging the measured jump
    over the 3 or 10 seen samples beyond the end did worse, 1.18× and 1.20×: the fill's error
    changes faster than the filtered noise). Where the pattern changes inside the run (another
    marker lost or found) the line between the ends is all the correction there is."""
    points = np.array(points, dtype=np.float64)
    total = len(points)
    jumps = _measured_jumps(filled, seen_points, training, ridge, subspace) \
        if seen_points is not None and training is not None else {}
    for marker in np.flatnonzero(filled.any(axis=0)):  # markers, never vertices
        starts, ends = runs(filled[:, marker])
        for start, end in zip(starts, ends):
            before = jumps.get((start - 1, marker, start), points[start - 1, marker] - points[start, marker]) \
                if start > 0 else None
            after = jumps.get((end, marker, end - 1), points[end, marker] - points[end - 1, marker]) \
                if end < total else None
            if before is None and after is None:
                continue
            before = after if before is None else before
            after = before if after is None else after
            share = (np.arange(start, end) - start + 1.0) / (end - start + 1.0)
            points[start:end, marker] += before + share[:, None] * (after - before)
    return points


def _measured_jumps(filled, seen_points, training, ridge, subspace):
    """{(frame, marker, filled frame): the jump (3,)} at each seen sample beside a filled run, for
    :func:`join_filled_runs`: the sample less its fill from the markers seen there that the run's
    adjacent filled frame also sees (the same pattern as the run's fill, so the same error; ≥ 3)."""
    seen = ~np.isnan(seen_points).any(axis=2)
    rows = []
    for step in (1, -1):  # the frame before a run (its filled frame next), the frame after one
        beside = np.zeros_like(filled)
        if step == 1:
            beside[:-1] = filled[1:] & ~filled[:-1]
        else:
            beside[1:] = filled[:-1] & ~filled[1:]
        frames, markers = np.nonzero(beside & seen)
        rows += [(f, m, f + step) for f, m in zip(frames, markers)]
    rows = [(f, m, g) for f, m, g in rows if (seen[f] & seen[g]).sum() >= 3]
    if not rows:
        return {}
    frames, markers, adjacent = (np.array(column) for column in zip(*rows))
    hidden = np.where(seen[adjacent][..., None], seen_points[frames], np.nan)  # the run's pattern there
    fill, _, _ = fill_from_training(hidden, training, 3, ridge=ridge, subspace=subspace)
    jumps = seen_points[frames, markers] - fill[np.arange(len(frames)), markers]
    return {(int(f), int(m), int(g)): jump for f, m, g, jump in zip(frames, markers, adjacent, jumps)}
