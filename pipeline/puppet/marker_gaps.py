"""Gaps in a motion-capture take filled, as mocap tools fill them (:func:`.markers.drive_from_markers`'s
steps 2 and 6): short ones interpolated in time (:func:`fill_short_gaps`); a marker riding one
bone with three others from their rigid motion (:func:`fill_rigid_clusters`); the rest from the
other markers through the puppet's training controls, a Gaussian's conditional mean on their
principal subspace (:func:`fill_from_training`, its expected error :func:`fill_uncertainty`),
each filled run joined to its seen ends (:func:`join_filled_runs`).
"""

import numpy as np

from ..errors import OptionError
from ..runtime.rows import unique_rows
from ..rig.rotations import polar_rotation

#: The short-gap rule: gaps of at most this many take frames are interpolated (Vicon Nexus and
#: Qualisys fill up to 10 frames by default).
MAX_GAP = 10
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


def fill_short_gaps(points, max_gap):
    """points (T, M, 3), NaN where missing -> (filled copy, filled (T, M) bool): every gap of at
    most ``max_gap`` frames with a seen frame on both sides interpolated linearly in time. Gaps at
    the take's start or end, or longer, stay NaN (:func:`fill_from_training` takes them)."""
    points = np.array(points, dtype=np.float64)
    missing = np.isnan(points).any(axis=2)
    filled = np.zeros_like(missing)
    frames = np.arange(len(points))
    for marker in np.flatnonzero(missing.any(axis=0)):  # markers, never vertices
        starts, ends = runs(missing[:, marker])
        short = (starts > 0) & (ends < len(points)) & (ends - starts <= max_gap)
        if not short.any():
            continue
        seen = ~missing[:, marker]
        take = np.concatenate([np.arange(s, e) for s, e in zip(starts[short], ends[short])])
        for axis in range(3):
            points[take, marker, axis] = np.interp(take, frames[seen], points[seen, marker, axis])
        filled[take, marker] = True
    return points, filled


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
