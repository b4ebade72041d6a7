"""A take's neutral frame: which one (:func:`closest_to_rest`), and how much of what it shows to
trust (:func:`shrink_neutral_residual`) (:func:`.markers.drive_from_markers`'s steps 4–5).

The neutral frame is the one pose where the performer matches the puppet's rest pose: the take is
aligned there, and a ``delta`` retargeting adds its residual from the rest controls to every
frame. So its noise does not average away over the take: it turns the whole performance (the
alignment) and offsets every frame (the residual). Three rules keep it small, all from the noise
the low-pass removed (:func:`.marker_filter.removed_noise`), i.e. the filter's own assumption that
what lies above its cut-off is noise:

- among the frames tied for nearest the rest pose, one inside a run of samples is preferred to a
  run's end sample, which the filter leaves with all its raw noise, where the noise saved
  outweighs the pose given up (:func:`closest_to_rest`);
- a pose held (a calibration pose) is read as its mean over the frames it is held, not at one
  (:func:`still_window`, :func:`neutral_pose`);
- the residual is shrunk towards none by as much as that noise could explain (James–Stein).
"""

import numpy as np

from .marker_filter import MAX_REACH, combined_noise_gain, noise_gains

#: How far after the first tie a quieter neutral frame is looked for (:func:`closest_to_rest`), in
#: periods of the filter's cut-off: the filter leaves a run's end sample all its raw noise and is
#: back within 10 % of its interior gain about a fifth of a period in (2 samples at 10 Hz of
#: 100 Hz, 5 of 240 Hz); half a period leaves room and gives up little pose.
QUIET_PERIODS = 0.5
#: The longest still stretch read for the neutral pose (:func:`still_window`), in seconds each way
#: from the neutral frame: a capture's calibration pose is held for a second or two, and a second
#: of samples already leaves its noise a few hundredths of one sample's. At most
#: :data:`.marker_filter.MAX_REACH` samples each way.
STILL_SECONDS = 1.0
#: A frame is as still as the neutral one while its markers' squared distance from the neutral
#: frame's, summed over them, stays within this many times the noise variance of one filtered
#: sample (summed the same way): twice what two independent samples' noise puts there on
#: average, beyond which noise alone rarely goes (16 markers: a χ² of 48 degrees of freedom,
#: 2× its mean is 5 standard deviations up) and motion soon does.
STILL_NOISE = 4.0
#: The shortest still stretch read as a pose held, in seconds: a calibration pose is held for a
#: second or more, while motion passing through the rest pose looks still for a few samples (the
#: held-out takes, which start in mid-motion: 60–90 ms at 100 Hz), too short for its mean to be
#: told from a drift; a quarter second of stillness is a pose held.
STILL_SHORTEST = 0.25
#: A take that begins in a held pose is aligned there (:func:`held_start`): real takes begin in the
#: performer's calibration pose, the one meant to match the character's (the shared tennis serve:
#: its first 1.5 s, then the serve; closest to the samba puppet's rest pose over the whole take
#: was frame 810, mid-serve, its residual 0.087 against 0.091 at frame 52 of the held start:
#: both are the performer's build, not the pose). Held: every marker within this share of the
#: body's size (the largest side of the markers' box) of where it was at the take's first frame
#: seeing them all —
#: a person standing sways a few centimetres (the serve's first second: 1.7 % of its size), a
#: take in motion leaves that in a tenth of a second.
HELD_SWAY = 0.03
#: …for at least this long (seconds): a calibration pose is held for a second or more, while a
#: dance that starts slowly stays within that sway for a little more than half a second (the
#: samba's and the crane's takes that begin mid-motion: 0.64 s and 0.58 s, aligned there 3–4×
#: worse than at their rest frame).
HELD_SHORTEST = 1.0


def sample_noise(points):
    """The variance of a take's measurement noise per marker sample, Σ over the 3 coordinates
    (points (T, M, 3), NaN where missing): from the second differences of seen samples,
    x(t+1) − 2 x(t) + x(t−1), whose variance is 6× that of white noise where the motion is smooth
    at the take's rate (an upper bound where it is not); 0 with fewer than 3 samples."""
    second = points[2:] - 2.0 * points[1:-1] + points[:-2]
    squared = np.sum(second ** 2, axis=2)
    seen = np.isfinite(squared)
    return float(np.mean(squared[seen]) / 6.0) if seen.any() else 0.0


def closest_to_rest(points, targets, present, noise=0.0, gains=None, variances=None, within=0):
    """The neutral frame of a take: among the frames of points (T, M, 3) seeing every marker it
    has (``present`` (M,) bool), the one whose markers a similarity brings nearest their targets
    (M, 3), the puppet's rest controls (Umeyama's least residual, Σ|t − t̄|² − tr(DS)²/Σ|s − s̄|²,
    all frames at once). Frames whose residual exceeds the least by no more than the take's noise
    could explain (twice its ``noise`` variance per sample, :func:`sample_noise`, over the markers,
    in the targets' scale; at least 1e-9 of their spread: a cyclic take returning to its rest pose)
    are ties, and the first of them is taken (noise alone would otherwise pick a neighbour of the
    rest frame). None when no frame sees them all.

    A filtered take (``gains``: frame -> (M,) the share of white noise the filter leaves there,
    :func:`frame_gains`; ``variances`` (M,): each marker's noise per coordinate,
    :func:`.marker_filter.removed_noise`) may take a tie up to ``within`` frames after the first
    (:data:`QUIET_PERIODS` of the cut-off) instead, the one where the noise saved, 3 Σ_m variance_m
    (gain_first − gain_tie) in the targets' scale, most exceeds what it costs: the residual it adds,
    and the rigid motion between the two (aligning there moves the whole take by it; ties are equal in
    shape, not in place: a performer may walk in the rest pose): the first tie is often a run's end
    sample (a take's first frame), which keeps all its raw noise — five times an interior sample's at
    10 Hz of 100 Hz. A clean take saves nothing and keeps the first."""
    complete = np.flatnonzero(~np.isnan(points[:, present]).any(axis=(1, 2)))
    if not len(complete):
        return None
    source = points[complete][:, present]
    source = source - source.mean(axis=1, keepdims=True)
    target = targets[present] - targets[present].mean(axis=0)
    covariance = np.einsum("ma,tmb->tab", target, source)
    singular = np.linalg.svd(covariance, compute_uv=False)  # (T', 3), descending
    turn = np.sign(np.linalg.det(covariance))  # det(U)·det(Vᵀ): no reflection (Umeyama's S)
    trace = singular[:, 0] + singular[:, 1] + np.where(turn < 0, -1.0, 1.0) * singular[:, 2]
    spread = np.maximum(np.sum(source ** 2, axis=(1, 2)), 1e-300)
    residual = np.sum(target ** 2) - trace ** 2 / spread
    best = int(np.argmin(residual))
    scale = trace[best] / spread[best]  # the best frame's similarity scale, take units -> the targets'
    floor = 1e-9 * np.sum(target ** 2)  # below this, residuals are equal (and noise none)
    tie = max(2.0 * noise * int(present.sum()) * scale ** 2, floor)
    ties = np.flatnonzero(residual <= residual[best] + tie)  # into complete
    ties = ties[complete[ties] <= complete[ties[0]] + within]
    if gains is None or variances is None or len(ties) == 1:
        return int(complete[ties[0]])
    kept = np.array([gains(int(frame))[present] for frame in complete[ties]])  # (K, M') the filter's gains
    saved = 3.0 * scale ** 2 * (kept[0] - kept) @ variances[present]  # the noise variance a tie saves
    moved = _rigid_motion(points[complete[ties]][:, present], points[complete[ties[0]], present]) * scale ** 2
    gain = saved - (residual[ties] - residual[ties[0]]) - moved
    return int(complete[ties[int(np.argmax(gain))] if gain.max() > floor else ties[0]])


def choose_neutral_frame(points, targets, present, noise, rate, cutoff, variances, frame=None, labels=None):
    """The take frame the take is aligned at (:func:`.markers.drive_from_markers`'s step 4):
    ``frame`` (the user's ``--neutral-frame``) checked, or :func:`closest_to_rest` (among the
    frames of the pose the take begins in, where it begins in one: :func:`held_start`) of points
    (T, M, 3) (filtered at ``cutoff`` Hz, None: raw; ``variances`` (M,) their noise per coordinate,
    :func:`.marker_filter.removed_noise`) to targets (M, 3) over the ``present`` (M,) markers.
    OptionError (one line; markers named by ``labels``) when no frame sees every marker the take
    has, the given one does not, or the markers there do not span a plane."""
    from ..errors import OptionError

    frames = len(points)
    if frame is None:
        within = int(np.ceil(QUIET_PERIODS * rate / cutoff)) if cutoff is not None else 0
        first, stop = held_start(points, present, rate) or (0, frames)  # a held start: aligned in it
        gains = (lambda at: frame_gains(points, rate, cutoff, first + at)) if cutoff is not None else None
        frame = closest_to_rest(points[first:stop], targets, present, noise, gains, variances, within)
        frame = None if frame is None else first + frame
        if frame is None:
            raise OptionError("no frame of the take sees every marker it has (after filling short gaps): give "
                              "--neutral-frame a frame that does, or --max-gap more frames")
    elif not 0 <= frame < frames:
        raise OptionError(f"--neutral-frame {frame} is outside the take's frames 0..{frames - 1}")
    elif np.isnan(points[frame, present]).any():
        lost = np.flatnonzero(present & np.isnan(points[frame]).any(axis=1))
        names = [str(labels[m]) if labels is not None else str(m) for m in lost]
        raise OptionError(f"--neutral-frame {frame} lacks markers {', '.join(names)}: the neutral "
                          "frame needs every marker the take has")
    spread = points[frame, present] - points[frame, present].mean(axis=0)
    singular = np.linalg.svd(spread, compute_uv=False)
    if present.sum() < 3 or singular[1] <= 1e-9 * max(singular[0], 1e-300):
        raise OptionError(f"the take's {int(present.sum())} markers at its neutral frame {frame} do not span "
                          "a plane (3 not in a line are needed to align it)")
    return int(frame)


def held_start(points, present, rate):
    """(first, stop): the frames of the pose a take begins in (stop exclusive), or None where it
    begins in motion: from the first frame of points (T, M, 3) seeing every ``present`` (M,)
    marker, the frames while each marker seen stays within :data:`HELD_SWAY` of the markers' size
    of where it was there, if that lasts :data:`HELD_SHORTEST` or more (``rate`` Hz)."""
    complete = np.flatnonzero(~np.isnan(points[:, present]).any(axis=(1, 2)))
    if not complete.size or present.sum() < 3:
        return None
    first = int(complete[0])
    start = points[first, present]
    size = float(np.ptp(start, axis=0).max())
    moved = np.linalg.norm(points[first:, present] - start, axis=2)  # (T', M), NaN where unseen
    away = np.where(np.isnan(moved), 0.0, moved).max(axis=1) > HELD_SWAY * size
    stop = first + (int(np.argmax(away)) if away.any() else len(away))
    return (first, stop) if stop - first >= HELD_SHORTEST * rate else None


def still_window(points, frame, present, noise, rate):
    """(first, last): the take frames around ``frame`` (both included) over which the performer
    holds the neutral pose, grown from it both ways while each frame sees at least half the
    ``present`` (M,) markers (3 at least) and Σ_m |points_t,m − points_frame,m|² over those it sees
    (points (T, M, 3)) stays within :data:`STILL_NOISE` × their ``noise`` (M,) (one sample's noise
    variance, Σ over coordinates), at most :data:`STILL_SECONDS` each way."""
    reach = max(0, min(int(STILL_SECONDS * rate), MAX_REACH))
    lo, hi = max(0, frame - reach), min(len(points), frame + reach + 1)
    squared = np.sum((points[lo:hi] - points[frame]) ** 2, axis=2)  # (L, M), NaN where either is unseen
    seen = present & np.isfinite(squared)
    moved = np.sum(np.where(seen, squared, 0.0), axis=1)
    enough = seen.sum(axis=1) >= max(3, -(-int(present.sum()) // 2))
    still = enough & (moved <= STILL_NOISE * (seen @ noise))
    at = frame - lo
    breaks = np.flatnonzero(~still)
    first = breaks[breaks < at].max(initial=-1) + 1
    last = breaks[breaks > at].min(initial=len(still)) - 1
    return int(lo + first), int(lo + last)


def neutral_pose(points, frame, present, variances, rate, cutoff):
    """The neutral markers (M, 3) (NaN where not ``present``) of points (T, M, 3) filtered at
    ``cutoff`` Hz, the share of white noise left in each (M,), and the frames read, (first, last):
    each marker's mean over the frames it is seen in the still window around ``frame``
    (:func:`still_window`, against one sample's noise there) where that is a pose held
    (:data:`STILL_SHORTEST` seconds or more) to within what the means' own noise explains — each
    marker's means over its first and second halves apart, summed over the markers seen in both,
    by no more than :data:`STILL_NOISE` / 2 × the variance noise alone puts between them
    (``variances`` (M,) each marker's per coordinate), so a slow drift that the per-frame test lets
    through is not averaged in — and where the means leave less noise than the frame; else the
    frame's own markers."""
    single = frame_gains(points, rate, cutoff, frame)
    window = first, last = still_window(points, frame, present, 3.0 * variances * single, rate)
    alone = (np.where(present[:, None], points[frame], np.nan), single * present, (frame, frame))
    length = last - first + 1
    if length < max(2, STILL_SHORTEST * rate):
        return alone
    inside = points[first:last + 1]
    seen = ~np.isnan(inside).any(axis=2) & present  # (L, M)
    half = length // 2
    halves = np.zeros((2, length), dtype=bool)
    halves[0, :half], halves[1, length - half:] = True, True
    pose = np.full(points.shape[1:], np.nan)
    gains, drift_gains, drift = np.zeros(points.shape[1]), np.zeros(points.shape[1]), 0.0
    cache = {}  # markers seen over the same frames of the same run share their filter rows
    for marker in np.flatnonzero(present):  # markers, never vertices
        mask = seen[:, marker]
        parts = [mask & h for h in halves]
        both = all(part.any() for part in parts)
        sums = np.stack([mask / mask.sum()] + ([parts[0] / parts[0].sum() - parts[1] / parts[1].sum()]
                                               if both else [np.zeros(length)]))  # the mean; the halves' drift
        bounds = _run_bounds(points[:, marker], first, last)
        key = (mask.tobytes(), both) + bounds
        if key not in cache:
            cache[key] = _window_noise_gains(bounds, first, sums, rate, cutoff)
        gains[marker], drift_gains[marker] = cache[key]
        pose[marker] = sums[0] @ np.nan_to_num(inside[:, marker])
        if both:
            drift += float(np.sum((sums[1] @ np.nan_to_num(inside[:, marker])) ** 2))
    if drift > STILL_NOISE / 2 * 3.0 * float(variances @ drift_gains) or gains @ variances >= single @ variances:
        return alone
    return pose, gains, window


def _run_bounds(track, first, last):
    """The (start, end) of each run of seen samples of track (T, 3) that meets frames first..last."""
    from .marker_gaps import runs

    starts, ends = runs(~np.isnan(track).any(axis=1))
    meets = (starts <= last) & (ends > first)
    return tuple(zip(starts[meets].tolist(), ends[meets].tolist()))


def _window_noise_gains(bounds, first, sums, rate, cutoff):
    """(W,): what the filter leaves of white noise of variance 1 in each weighted sum sums (W, L)
    of a marker's samples first..first + L − 1 (0 weight where unseen), whose runs of seen samples
    meeting them are ``bounds`` ((start, end), :func:`_run_bounds`): summed over those runs, which
    are filtered apart and so carry independent noise."""
    total = np.zeros(len(sums))
    for start, end in bounds:
        lo, hi = max(start, first), min(end, first + sums.shape[1])
        total += combined_noise_gain(rate, cutoff, lo - start, sums[:, lo - first:hi - first], end - start)
    return total


def _rigid_motion(frames, first):
    """How far the rigid motion from ``first`` (M, 3) to each of ``frames`` (K, M, 3) moves the
    markers: (K,) Σ_m |R first_m + t − first_m|² of the least-squares rigid fit (Kabsch). Aligning
    at another frame than the first moves the whole take by that much."""
    from .marker_gaps import rigid_onto

    rotations, translations = rigid_onto(np.broadcast_to(first, frames.shape), frames,
                                         np.ones(frames.shape[:2], dtype=bool))
    carried = np.einsum("kab,mb->kma", rotations, first) + translations[:, None]
    return np.sum((carried - first) ** 2, axis=(1, 2))


def frame_gains(filtered, rate, cutoff, frame):
    """(M,) the share of white noise :func:`.marker_filter.lowpass_runs` leaves at ``frame`` of
    each marker's run of samples (filtered (T, M, 3), NaN where missing: 0 there)."""
    from .marker_gaps import runs

    gains = np.zeros(filtered.shape[1])
    for marker in np.flatnonzero(~np.isnan(filtered[frame]).any(axis=1)):  # markers, never vertices
        starts, ends = runs(~np.isnan(filtered[:, marker]).any(axis=1))
        at = np.searchsorted(ends, frame, side="right")  # the run holding the frame
        gains[marker] = noise_gains(rate, cutoff, frame - starts[at], ends[at] - starts[at])[0]
    return gains


def shrink_neutral_residual(residual, variances):
    """The neutral frame's residual from the rest controls with its noise shrunk: residual (n, 3)
    the targets less the aligned neutral markers (NaN for a marker the take lacks), variances (n,)
    each one's noise variance per coordinate there. -> (shrunk residual (n, 3), share kept).

    ``delta`` retargeting adds this residual to every frame: the performer's proportions and the
    markers' placement, which it must keep, and the neutral frame's noise, which it should not.
    Which is which is unknown, so the residual is shrunk by the positive-part James–Stein
    estimator (James & Stein 1961; Efron & Morris 1973), towards none (``absolute``): each
    coordinate standardised by its noise, the whole residual scaled by max(0, 1 − (p − 2) / |z|²)
    with p = 3 n' − 7 (its n' markers' coordinates less the similarity's 7 fitted from them). A
    residual the noise explains (|z|² ≈ p) goes almost wholly; one of real offsets (|z|² ≫ p, a
    performer of other proportions: centimetres against the fraction of a millimetre a filtered
    marker is off) is kept almost whole — never changed by more than the noise could have put
    there, and for Gaussian noise never worse on average than keeping it raw (p > 2; fewer than
    4 markers: kept). Whole rather than per marker: James–Stein's guarantee needs the dimensions
    pooled, and one marker's three give too few."""
    residual = np.array(residual, dtype=np.float64)
    variances = np.asarray(variances, dtype=np.float64)
    use = np.isfinite(residual).all(axis=1) & (variances > 0)
    free = 3 * int(use.sum()) - 7
    squared = float(np.sum(residual[use] ** 2 / variances[use, None]))
    if free <= 2 or squared <= 0.0:
        return residual, 1.0
    kept = max(0.0, 1.0 - (free - 2) / squared)
    residual[use] *= kept
    return residual, kept


def residual_summary(residual, variances, kept):
    """The neutral frame's report (mesh units): {"residual": its RMS over the markers seen there,
    "noise": the RMS noise in it (variances (n,) per coordinate), "kept": the share kept}."""
    seen = np.isfinite(residual).all(axis=1)
    if not seen.any():
        return {"residual": 0.0, "noise": 0.0, "kept": float(kept)}
    return {"residual": float(np.sqrt(np.mean(np.sum(residual[seen] ** 2, axis=1)))),
            "noise": float(np.sqrt(3.0 * np.mean(variances[seen]))), "kept": float(kept)}
