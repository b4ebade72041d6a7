"""A performance drives the puppet: optical markers carried over to its control points (Feng §6).

Feng et al. drive their puppets with a performer's markers ("the control points … are driven by
motion capture data", §6). A real take is in the performer's space, at the system's rate, with
gaps; the puppet wants its own control points, at its frame rate, every frame. The steps, in the
order :func:`drive_from_markers` runs them (each an option of ``play``):

1. **Units and up axis.** Metres to the mesh's units (``metersPerUnit``), the take's up axis (C3D:
   Z) turned onto the puppet's (:func:`up_axis_rotation`).
2. **The cut-off** (``cutoff`` Hz; default ``"auto"``, the take's own: the one whose filtered
   samples lie nearest the motion, :func:`.marker_filter.choose_cutoff`; None keeps the take raw).
   **Short gaps** (≤ ``max_gap`` take frames, default :data:`.marker_gaps.MAX_GAP_SECONDS` of them,
   both ends seen) are bridged by a smoothing spline through the samples around them at that
   bandwidth (:func:`.marker_gaps.fill_short_gaps`): a spinning marker's curve is carried through
   the gap, where a line cuts its chord, and the spline smooths the noisy ends as the filter will.
   Then every marker's runs of samples are **low-passed**: a zero-phase Butterworth along time, as
   mocap tools filter before anything reads the trajectories (:func:`.marker_filter.filter_take`) —
   before the neutral frame is read, whose noise would otherwise offset every frame.
3. **Stabilised** (``--stabilize A,B,C``): each frame's rigid motion of three or more markers
   (a face's head markers) relative to the neutral frame is removed from every marker
   (:func:`stabilize_markers`).
4. **The neutral frame** (the pose that matches the puppet's rest pose, as a facial capture's
   neutral calibration; default the frame closest to the rest pose among those seeing every
   marker the take has, :func:`.marker_neutral.closest_to_rest`) is mapped onto the puppet's
   reference controls by the least-squares similarity of Umeyama 1991 (scale, rotation,
   translation; :func:`similarity_transform`); on a filtered take where the pose is held (a
   calibration pose), its markers are their mean over the frames it is held
   (:func:`.marker_neutral.neutral_pose`). Markers sitting ``offset`` out from the skin are
   aimed at the rest control vertex moved that far along its normal.
5. **Retargeting.** ``delta`` (default): each control moves by its marker's displacement from
   the neutral frame, carried by that transform, so the rest shape is the character's own and a
   performer of other proportions does not distort it; ``absolute``: controls at the aligned
   markers (less the skin offset, turned with the frame). ``delta`` adds the neutral frame's
   residual to every frame, noise and all; on a filtered take that residual is shrunk by James
   and Stein's estimator towards none, by as much as the take's noise could explain
   (:func:`.marker_neutral.shrink_neutral_residual`).
6. **Long gaps** are filled from the other markers through the puppet's own training controls
   (:func:`.marker_gaps.fill_from_training`): least squares on their principal subspace, in place; then each
   filled run is offset by the line between the jumps at its seen ends (:func:`.marker_gaps.join_filled_runs`,
   a pattern fill's end correction: the subspace gives the run's motion, the seen ends where it
   is). A frame with fewer than ``min_markers`` markers is held from the last good one.
7. **Resampled** to the output's fps by linear interpolation, the first sample's time kept
   (:func:`resample_uniform`).
"""

import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import OptionError
from .marker_gaps import (MAX_GAP_SECONDS, fill_from_training, fill_rigid_clusters, fill_short_gaps, fill_uncertainty,
                          join_filled_runs, rigid_onto, training_subspace)
from .marker_filter import AUTO, ORDER, choose_cutoff, filter_take
from .marker_neutral import (choose_neutral_frame, neutral_pose, residual_summary, sample_noise,
                             shrink_neutral_residual)

#: A frame is reported as filled uncertainly where a filled marker's expected error
#: (:func:`.marker_gaps.fill_uncertainty`) exceeds this share of the rest controls' largest side: 1 %, about
#: 2 cm on a person, where a marker's misplacement starts to show.
UNCERTAIN = 0.01
RETARGETS = ("delta", "absolute")
_UP = {"X": 0, "Y": 1, "Z": 2}


@dataclass
class MarkerDrive:
    """What :func:`drive_from_markers` made of a take.

    controls (F, n, 3) the puppet's control points at the output frames; markers (F, n, 3) the
    markers themselves carried by the similarity (where ``absolute`` puts the controls; ``view``
    draws them beside the controls); times (F,) seconds of each output frame; scale, rotation
    (3, 3), translation (3,): the whole map from the take's metres to the puppet's space,
    ``x ↦ scale · rotation @ x + translation`` (units, up axis and Umeyama together);
    neutral_frame (take frame); interpolated, rigid (from the marker's rigid cluster) and
    subspace: {marker index: take frames filled that way}; held: take frames held from the last
    good one; min_markers: the rule used for ``held``;
    cutoff: the low-pass cut-off applied (Hz), None where the take was kept raw (too slow for it, or
    no run of samples long enough); chosen: whether the take chose it (``"auto"``); max_gap: the
    longest gap bridged in time (take frames); kept_raw: samples of a filtered take left raw, their runs too
    short (:func:`.marker_filter.shortest_run`); neutral: the
    neutral frame's residual from the rest controls ("residual", root mean square over the
    markers, mesh units), the noise in it ("noise"), the share kept ("kept",
    :func:`.marker_neutral.shrink_neutral_residual`) and the take frames its pose was read over
    ("frames": [first, last], the neutral frame twice where it was read alone); uncertainty (F,):
    each output frame's expected error of a marker filled from the others (:func:`.marker_gaps.fill_uncertainty`, 0
    where none is), over the rest controls' largest side; a held frame's is its pose's whole
    spread over the training poses (nothing was seen to fit).
    """

    controls: np.ndarray
    markers: np.ndarray
    times: np.ndarray
    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    neutral_frame: int
    interpolated: dict = field(default_factory=dict)
    subspace: dict = field(default_factory=dict)
    rigid: dict = field(default_factory=dict)
    held: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    min_markers: int = 3
    cutoff: float = None
    chosen: bool = False
    max_gap: int = 0
    uncertainty: np.ndarray = field(default_factory=lambda: np.zeros(0))
    neutral: dict = field(default_factory=dict)
    kept_raw: int = 0


def up_axis_rotation(source, target):
    """The rotation (3, 3) taking a right-handed frame whose up axis is ``source`` ("X"/"Y"/"Z")
    to one whose up axis is ``target``: a cyclic permutation of the axes, so no axis is mirrored
    (Z up → Y up maps (x, y, z) to (y, z, x)). Identity when they agree."""
    shift = (_UP[target.upper()] - _UP[source.upper()]) % 3
    return np.roll(np.eye(3), shift, axis=0)


def similarity_transform(source, target):
    """Umeyama 1991 (eq. 40–42): the scale s, rotation R (3, 3) and translation t (3,) minimising
    ``Σ_i |s R source_i + t − target_i|²`` for points source, target (n, 3), n ≥ 3 not collinear.
    A reflection is never returned (the sign correction S of eq. 39/43)."""
    source, target = np.asarray(source, dtype=np.float64), np.asarray(target, dtype=np.float64)
    mean_s, mean_t = source.mean(axis=0), target.mean(axis=0)
    centred_s, centred_t = source - mean_s, target - mean_t
    variance = np.mean(np.sum(centred_s ** 2, axis=1))
    covariance = centred_t.T @ centred_s / len(source)
    u, d, vt = np.linalg.svd(covariance)
    sign = np.ones(3)
    sign[2] = np.sign(np.linalg.det(u) * np.linalg.det(vt)) or 1.0
    rotation = (u * sign) @ vt
    scale = float(np.sum(d * sign) / variance) if variance > 0 else 1.0
    return scale, rotation, mean_t - scale * rotation @ mean_s


def stabilize_markers(points, stabilizers, neutral):
    """Remove from every marker the rigid motion of the ``stabilizers`` (indices, ≥ 3) relative to
    frame ``neutral``: points (T, M, 3) -> (T, M, 3). A frame seeing fewer than 3 of them keeps the
    last frame's correction (the first one seen for frames before it)."""
    stabilizers = np.asarray(stabilizers)
    seen = ~np.isnan(points[:, stabilizers]).any(axis=2)
    usable = seen.sum(axis=1) >= 3
    if not usable.any():
        raise OptionError("--stabilize: no frame sees 3 of its markers")
    rotations, translations = rigid_onto(points[:, stabilizers], points[neutral, stabilizers], seen)
    source = np.maximum.accumulate(np.where(usable, np.arange(len(points)), -1))
    source = np.where(source < 0, np.flatnonzero(usable)[0], source)
    rotations, translations = rotations[source], translations[source]
    return np.einsum("tab,tmb->tma", rotations, points) + translations[:, None]


def resampled_count(samples, rate, fps):
    """How many frames :func:`resample_uniform` makes of ``samples`` at ``rate`` Hz (a float: a
    count too large for memory is still a number to report)."""
    return float(np.floor((samples - 1) * fps / rate + 1e-9) + 1)


def check_take_size(take, shape, rate, fps, fps_from, vertices):
    """OptionError, before any work, when a take's samples (``shape``: samples T, markers M) at
    ``rate`` Hz, resampled to ``fps`` (``fps_from`` says whose: "--fps", "the puppet's"), make
    more frames than the memory holds: the controls and markers (F, M, 3) and the posed vertices
    (F, V, 3) of each frame, float64 (:func:`~..runtime.resources.check_memory`); ``take`` names it."""
    from ..runtime.resources import check_memory

    frames = resampled_count(shape[0], rate, fps)
    check_memory(frames * (2 * shape[1] + vertices) * 3 * 8,
                 f"{take}: {shape[0]:,} samples at {rate:g} per second, resampled to {fps:g} fps ({fps_from}), make "
                 f"{frames:,.0f} frames of {vertices:,} vertices, which")


def resample_uniform(values, rate, fps):
    """values (T, ...) sampled at ``rate`` Hz -> (F, ...) at ``fps`` by linear interpolation, frame
    k at k / fps seconds after the first sample (so the first sample's time is kept), up to the
    last sample. A sample time within 1e-9 of a frame's counts as on it (no interpolation)."""
    values = np.asarray(values, dtype=np.float64)
    count = int(resampled_count(len(values), rate, fps))
    position = np.arange(count) * (rate / fps)
    lower = np.minimum(np.floor(position + 1e-9).astype(np.int64), len(values) - 1)
    upper = np.minimum(lower + 1, len(values) - 1)
    mix = np.clip(position - lower, 0.0, 1.0).reshape(-1, *([1] * (values.ndim - 1)))
    return (1.0 - mix) * values[lower] + mix * values[upper]


def layout_vertex_ids(vertices, positions, rest_vertices):
    """A marker layout's vertex of each marker: vertices (M,) int, −1 where the marker is given by
    a rest position instead (positions (M, 3), NaN elsewhere), which takes the nearest vertex of
    rest_vertices (V, 3) (ties: the lowest id). -> (M,) int64."""
    vertices = np.array(vertices, dtype=np.int64)
    placed = np.flatnonzero(vertices < 0)
    if len(placed):
        rest = np.asarray(rest_vertices, dtype=np.float64)
        squared = (np.sum(rest ** 2, axis=1)[None] - 2.0 * np.asarray(positions)[placed] @ rest.T)  # |p|² is common
        vertices[placed] = np.argmin(squared, axis=1)
    return vertices


def layout_order(vertices, positions, rest_vertices, control_indices):
    """Each control's marker of a layout (its markers' vertices (M,), −1 where given by a rest
    position, positions (M, 3); :func:`layout_vertex_ids` on rest_vertices (V, 3)): (n_c,) the
    layout entry on each of ``control_indices`` (n_c,). ValueError when two markers sit on one
    vertex, or the markers' vertices are not the controls."""
    vertices = layout_vertex_ids(vertices, positions, rest_vertices)
    controls = np.asarray(control_indices)
    where = {int(v): i for i, v in enumerate(vertices)}
    if len(where) != len(vertices):
        raise ValueError("two markers sit on one vertex")
    if set(where) != set(controls.tolist()):
        extra = sorted(set(where) - set(controls.tolist()))
        lacking = sorted(set(controls.tolist()) - set(where))
        raise ValueError(f"its markers differ from the puppet's controls: vertices {extra[:6]} are not controls, "
                         f"controls {lacking[:6]} have no marker (select-controls --markers this layout, then "
                         "train-kcca, makes a puppet it drives)")
    return np.array([where[int(v)] for v in controls])


def drive_from_markers(points, rate, fps, reference, training, *, meters_per_unit=1.0, take_up="Z", puppet_up="Y",
                       offsets=None, normals=None, neutral_frame=None, retarget="delta", stabilize=(),
                       max_gap=None, min_markers=None, labels=None, cutoff=AUTO, bones=None):
    """A take's markers as the puppet's controls (the module's steps 1–7).

    points (T, n, 3) metres, the markers in the puppet's control order, NaN where missing; rate
    (Hz); fps (the output's); reference (n, 3) the puppet's reference (rest) controls; training
    (n_p, n, 3) its training controls in place (for the long-gap fill); offsets (n,) and normals
    (n, 3): markers sitting ``offset`` along the rest normal from their control (mesh units);
    neutral_frame: take frame of the neutral pose (default :func:`.marker_neutral.closest_to_rest`, after
    the short fill, over the markers the take has: a marker with no sample at all, one the take lacks,
    is filled every frame from the others); stabilize: marker indices; min_markers: a frame seeing
    fewer is held (default half the markers the take has, at least 3); labels (n,): the markers' names
    in messages (default their numbers);
    cutoff: the low-pass cut-off in Hz (step 2), ``"auto"`` the take's own, None for none; a take
    too slow for it (its Nyquist frequency below the filter's) is kept raw, ``MarkerDrive.cutoff``
    None (``MarkerDrive.chosen``: whether the take chose it); max_gap: the longest gap (take frames)
    bridged in time (None: :data:`.marker_gaps.MAX_GAP_SECONDS` of them); bones (n,):
    the bone each marker rides rigidly (:func:`.marker_gaps.rigid_clusters`, −1 none), whose clusters fill
    their gaps first (:func:`.marker_gaps.fill_rigid_clusters`); None: no such fill.
    -> :class:`MarkerDrive`; OptionError (one line) for an option the take cannot satisfy."""
    points = np.asarray(points, dtype=np.float64)
    frames, count = points.shape[:2]
    _check_drive_options(retarget, max_gap, fps, min_markers, count)
    offsets = np.zeros(count) if offsets is None else np.asarray(offsets, dtype=np.float64)
    normals = np.zeros((count, 3)) if normals is None else np.asarray(normals, dtype=np.float64)
    turn = up_axis_rotation(take_up, puppet_up) / meters_per_unit  # metres, take up -> mesh units, puppet up
    local = points @ turn.T
    noise = sample_noise(local)
    chosen = isinstance(cutoff, str) and cutoff == AUTO
    if chosen:
        cutoff = choose_cutoff(local, rate)
    if max_gap is None:
        max_gap = int(np.floor(MAX_GAP_SECONDS * rate + 1e-9))
    local, interpolated = fill_short_gaps(local, max_gap, rate, cutoff)
    filtered = filter_take(local, rate, cutoff, exclude=interpolated)
    local, cutoff = filtered.points, filtered.cutoff
    present = ~np.isnan(local).any(axis=2).all(axis=0)  # (n,) the markers the take has (seen at all)
    targets = reference + offsets[:, None] * normals
    neutral_frame = choose_neutral_frame(local, targets, present, noise, rate, cutoff, filtered.variances,
                                         frame=neutral_frame, labels=labels)
    if len(stabilize):
        if len(set(stabilize)) < 3:
            raise OptionError("--stabilize needs at least 3 distinct markers")
        local = stabilize_markers(local, stabilize, neutral_frame)
    # a filtered take's neutral pose is read over the frames the performer holds it (a calibration
    # pose), with its noise; a raw one's (--filter none) taken as measured at the frame
    still, pose = (neutral_frame, neutral_frame), np.where(present[:, None], local[neutral_frame], np.nan)
    if cutoff is not None:
        pose, gains, still = neutral_pose(local, neutral_frame, present, filtered.variances, rate, cutoff)
    scale, rotation, translation = similarity_transform(pose[present], targets[present])
    markers = scale * local @ rotation.T + translation  # NaN where still missing
    by_cluster = np.zeros((frames, count), dtype=bool)
    if bones is not None:
        markers, by_cluster = fill_rigid_clusters(markers, np.asarray(bones), neutral_frame)
    # the neutral pose's noise per coordinate, in the targets' units: what the filter leaves of each marker's there
    noise_there = filtered.variances * gains * scale ** 2 if cutoff is not None else np.zeros(count)
    aligned_pose = scale * pose @ rotation.T + translation
    controls, neutral = _retarget(markers, aligned_pose, reference, targets, offsets, normals, noise_there,
                                  retarget, shrink=cutoff is not None)
    neutral["frames"] = list(still)
    if min_markers is None:  # half the markers the take has (a partial set plays), at least 3
        min_markers = max(3, -(-int(present.sum()) // 2))
    controls, by_subspace, held, uncertainty = _fill_long_gaps(controls, training, min_markers, reference)
    # the drawn markers follow their controls where they were filled
    markers = np.where(np.isnan(markers), controls + (aligned_pose - reference
                                                      if retarget == "delta" else 0.0), markers)
    controls, markers = resample_uniform(controls, rate, fps), resample_uniform(markers, rate, fps)
    uncertainty = resample_uniform(uncertainty, rate, fps)
    total = scale * rotation @ turn
    return MarkerDrive(controls=controls, markers=markers, times=np.arange(len(controls)) / fps,
                       scale=float(np.cbrt(np.linalg.det(total))), rotation=total / np.cbrt(np.linalg.det(total)),
                       translation=translation, neutral_frame=int(neutral_frame),
                       interpolated=_frames_by_marker(interpolated), subspace=_frames_by_marker(by_subspace),
                       rigid=_frames_by_marker(by_cluster), held=held, min_markers=min_markers, cutoff=cutoff,
                       chosen=chosen, max_gap=max_gap,
                       uncertainty=uncertainty, kept_raw=filtered.kept_raw, neutral=neutral)


def _check_drive_options(retarget, max_gap, fps, min_markers, count):
    """OptionError (one line) for a value of :func:`drive_from_markers` no take can satisfy."""
    if retarget not in RETARGETS:
        raise OptionError(f"--retarget must be one of {', '.join(RETARGETS)} (got {retarget})")
    if max_gap is not None and max_gap < 0:
        raise OptionError(f"--max-gap must be ≥ 0 frames (got {max_gap})")
    if not (np.isfinite(fps) and fps > 0):
        raise OptionError(f"--fps must be a positive number (got {fps})")
    if min_markers is not None and not 3 <= min_markers <= count:
        raise OptionError(f"--min-markers must be between 3 and the layout's {count} markers (got {min_markers})")


def _retarget(markers, pose, reference, targets, offsets, normals, noise_there, retarget, shrink):
    """Step 5: the aligned markers (T, n, 3) as controls (T, n, 3), and the neutral pose's report
    (:func:`.marker_neutral.residual_summary`). ``delta``: the rest controls plus each marker's
    displacement, i.e. the markers plus the aligned neutral pose's (n, 3) residual from their
    targets (n, 3), shrunk (``shrink``, a filtered take) by its noise ``noise_there`` (n,) per
    coordinate; ``absolute``: the markers, less their skin offset along the rest normal turned with
    the frame."""
    residual = targets - pose  # (n, 3): the neutral pose's miss of its targets
    neutral = residual_summary(residual, noise_there, 1.0)
    if retarget == "delta":
        if shrink:  # a raw take (--filter none) is taken as measured
            residual, neutral["kept"] = shrink_neutral_residual(residual, noise_there)
        return markers + (reference - targets) + residual, neutral  # reference + displacement, less the noise
    if not np.any(offsets):
        return markers, neutral
    seen = ~np.isnan(markers).any(axis=2)
    turns, _ = rigid_onto(markers, targets, seen)  # frame -> rest; its transpose turns rest normals
    return markers - offsets[None, :, None] * np.einsum("tba,mb->tma", turns, normals), neutral


def _fill_long_gaps(controls, training, min_markers, reference):
    """Step 6 on controls (T, n, 3), NaN where missing, from the training controls (n_p, n, 3):
    (filled controls, by_subspace (T, n) bool, held (take frames), uncertainty (T,) over the rest
    controls' largest side; a held frame's is its pose's whole spread over the training poses)."""
    count = controls.shape[1]
    subspace = training_subspace(training)
    filled, by_subspace, held = fill_from_training(controls, training, min_markers, subspace=subspace)
    filled = join_filled_runs(filled, by_subspace, controls, training, subspace=subspace)
    side = max(float(np.ptp(reference, axis=0).max()), 1e-300)
    uncertainty = fill_uncertainty(by_subspace, training, subspace=subspace) / side
    uncertainty[held] = np.sqrt(3.0 * subspace[2].sum() / count) / side
    return filled, by_subspace, held, uncertainty


def _frames_by_marker(done):
    """done (T, n) bool -> {marker: its take frames} for the markers with any."""
    return {m: np.flatnonzero(done[:, m]) for m in range(done.shape[1]) if done[:, m].any()}


def frame_ranges(frames):
    """Sorted frame ids -> "a–b, c" text."""
    frames = np.asarray(frames)
    if len(frames) == 0:
        return ""
    breaks = np.flatnonzero(np.diff(frames) > 1)
    starts, ends = frames[np.r_[0, breaks + 1]], frames[np.r_[breaks, len(frames) - 1]]
    return ", ".join(f"{a}" if a == b else f"{a}–{b}" for a, b in zip(starts, ends))


def take_report(path, take, matched, labels, drive, fps, retarget):
    """A take's report: (summary, lines). ``path``: the take's; take: the C3D as read (points
    (T, M, 3), rate, units and where they came from, first_time: ``formats.c3d``'s record);
    matched: its labels matched to the layout (missing, unmatched); labels (n_c,) the marker on
    each control; drive: the :class:`MarkerDrive` it gave at ``fps`` with ``retarget``."""
    ways = (drive.interpolated, drive.rigid, drive.subspace)
    filled = {labels[m]: {"interpolated": frame_ranges(drive.interpolated.get(m, [])),
                          **({"from_rigid_cluster": frame_ranges(drive.rigid[m])} if m in drive.rigid else {}),
                          "from_other_markers": frame_ranges(drive.subspace.get(m, [])),
                          "frames": int(sum(len(way.get(m, [])) for way in ways))}
              for m in sorted(set().union(*ways))}
    summary = {"take": str(path), "take_frames": int(take.points.shape[0]), "take_rate": float(take.rate),
               "units": take.units, "units_from": take.units_source, "start_time": float(take.first_time),
               "fps": fps, "frames": int(len(drive.controls)), "neutral_frame": drive.neutral_frame,
               "neutral_residual": dict(drive.neutral), "retarget": retarget, "markers": list(labels),
               "missing_markers": list(matched.missing), "unmatched_labels": list(matched.unmatched),
               "transform": {"scale": drive.scale, "rotation": drive.rotation.tolist(),
                             "translation": drive.translation.tolist()},
               "filled": filled, "held_frames": frame_ranges(drive.held), "min_markers": drive.min_markers,
               "filter": ({"cutoff_hz": drive.cutoff, "chosen": "auto" if drive.chosen else "given", "order": ORDER,
                           "passes": 2, "samples_kept_raw": drive.kept_raw} if drive.cutoff is not None
                          else "none"),
               "max_gap_frames": drive.max_gap,
               "fill_uncertainty": {"per_frame": [round(float(u), 6) for u in drive.uncertainty],
                                    "worst": float(drive.uncertainty.max(initial=0.0)),
                                    "uncertain_frames": frame_ranges(np.flatnonzero(drive.uncertainty
                                                                                    > UNCERTAIN))}}
    name = os.path.basename(str(path))
    held = drive.neutral.get("frames", [drive.neutral_frame] * 2)
    lines = [f"{name}: {take.points.shape[0]} frames at {take.rate:g} Hz ({take.units}, from {take.units_source}) -> "
             f"{len(drive.controls)} frames at {fps:g} fps from {take.first_time:g} s; {len(labels)} markers, aligned "
             f"at take frame {drive.neutral_frame}" + (f" (its pose held over frames {held[0]}–{held[1]})"
                                                       if held[1] > held[0] else "")
             + f" (scale {drive.scale:.4g}), {retarget} retargeting"
             + (f" (of the neutral frame's residual {drive.neutral['residual']:.3g}, its noise about "
                f"{drive.neutral['noise']:.3g}, {drive.neutral['kept']:.0%} kept), "
                if drive.neutral.get("kept", 1.0) < 1.0 else ", ")
             + (f"low-passed at {drive.cutoff:g} Hz" + (" (chosen from the take: --filter auto)" if drive.chosen else "")
                + (f" ({drive.kept_raw} samples in runs too short for it kept raw)" if drive.kept_raw else "")
                if drive.cutoff is not None else "not filtered")]
    if matched.unmatched:
        lines.append(f"{name}: labels not in the layout, ignored: {', '.join(matched.unmatched)}")
    if matched.missing:
        lines.append(f"{name}: the layout's {', '.join(matched.missing)} missing from the take: filled from the "
                     "other markers every frame (--allow-missing)")
    for label, what in filled.items():
        ways = [f"interpolated {what['interpolated']}" if what["interpolated"] else "",
                f"from its rigid cluster {what['from_rigid_cluster']}" if what.get("from_rigid_cluster") else "",
                f"from the other markers {what['from_other_markers']}" if what["from_other_markers"] else ""]
        lines.append(f"{name}: {label} filled in {what['frames']} take frames ({'; '.join(w for w in ways if w)})")
    if len(drive.held):
        lines.append(f"{name}: take frames {frame_ranges(drive.held)} see fewer than {drive.min_markers} markers: "
                     "held from the last good frame")
    if summary["fill_uncertainty"]["uncertain_frames"]:
        lines.append(f"{name}: frames {summary['fill_uncertainty']['uncertain_frames']} filled uncertainly (a filled "
                     f"marker's expected error over {UNCERTAIN:.0%} of the character's size; --json: fill_uncertainty)")
    return summary, lines
