"""A motion-capture take (C3D) as a puppet's control trajectory: what ``play`` and ``view`` share.

Reads the take and the marker layout with ``formats``, ties the layout to the puppet's control
vertices, and hands the arrays to ``pipeline.puppet.drive_from_markers``; returns the
trajectory with a summary for ``--json`` and the lines a person reads.
"""

import os
from dataclasses import dataclass

import numpy as np

from skinsynth.pipeline.puppet.markers import MAX_GAP

#: The options of :func:`skinsynth.cli.options.marker_take_options` and their defaults, by name.
TAKE_DEFAULTS = {"marker_layout": None, "marker_units": None, "take_up_axis": "Z", "fps": None, "neutral_frame": None,
             "retarget": "delta", "stabilize": None, "max_gap": MAX_GAP, "min_markers": None, "allow_missing": False}


@dataclass
class TakeControls:
    """controls (F, n_c, 3) world; markers (F, n_c, 3) the aligned markers; fps; start_time
    (seconds of the first frame, the take's); labels (n_c,) the marker on each control;
    summary (JSON-ready) and lines (text)."""

    controls: np.ndarray
    markers: np.ndarray
    fps: float
    start_time: float
    labels: tuple
    summary: dict
    lines: list


def is_take(path):
    """Whether a --controls path is a motion-capture take (read by :func:`take_controls`)."""
    return str(path).lower().endswith(".c3d")


def check_take_options(control_files, options):
    """OptionError when a take option is given without a .c3d --controls (it would do nothing)."""
    from skinsynth.pipeline.errors import OptionError

    if any(is_take(f) for f in control_files):
        return
    given = [name for name, default in TAKE_DEFAULTS.items() if options.get(name, default) != default]
    if given:
        flag = "--" + given[0].replace("_", "-").replace("marker-layout", "markers")
        raise OptionError(f"{flag} applies to a motion-capture take: give --controls a .c3d file")


def _ranges(frames):
    """Sorted frame ids -> "a–b, c" text."""
    frames = np.asarray(frames)
    if len(frames) == 0:
        return ""
    breaks = np.flatnonzero(np.diff(frames) > 1)
    starts, ends = frames[np.r_[0, breaks + 1]], frames[np.r_[breaks, len(frames) - 1]]
    return ", ".join(f"{a}" if a == b else f"{a}–{b}" for a, b in zip(starts, ends))


def _layout_on_controls(layout, puppet, skin):
    """The layout's markers in the puppet's control order: (order (n_c,) layout entry of each
    control, offsets (n_c,)); FormatError when its vertices are not the puppet's controls."""
    from skinsynth.formats.errors import FormatError
    from skinsynth.pipeline.puppet.markers import layout_vertex_ids

    vertices = layout_vertex_ids(layout.vertices, layout.positions, skin.rest_vertices)
    controls = np.asarray(puppet.control_indices)
    where = {int(v): i for i, v in enumerate(vertices)}
    if len(where) != len(vertices):
        raise FormatError(layout.path, "two markers sit on one vertex")
    if set(where) != set(controls.tolist()):
        extra = sorted(set(where) - set(controls.tolist()))
        lacking = sorted(set(controls.tolist()) - set(where))
        raise FormatError(layout.path, f"its markers differ from the puppet's controls: vertices {extra[:6]} are not "
                                       f"controls, controls {lacking[:6]} have no marker (select-controls --markers "
                                       "this layout, then train-kcca, makes a puppet it drives)")
    order = np.array([where[int(v)] for v in controls])
    return order, layout.offsets[order]


def take_controls(path, puppet, record, skin, options, puppet_path):
    """The take at ``path`` as the puppet's controls (:class:`TakeControls`). puppet: the
    ``pipeline.puppet.Puppet``; record: its ``PuppetRecord`` (``marker_labels``: the layout
    select-controls --markers stored, or empty); skin: its SkinModel; options: the values of
    ``marker_take_options`` by name."""
    from skinsynth.formats.c3d import read_c3d
    from skinsynth.formats.errors import FormatError
    from skinsynth.formats.marker_layout import MarkerLayout, match_markers, read_marker_layout
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.mesh.geometry import vertex_normals
    from skinsynth.pipeline.puppet import drive_from_markers, host_inputs

    options = {**TAKE_DEFAULTS, **options}
    if options["marker_layout"] is not None:
        layout = read_marker_layout(options["marker_layout"], vertex_count=skin.rest_vertices.shape[0])
    elif record.marker_labels:
        count = len(puppet.control_indices)
        layout = MarkerLayout(path=puppet_path, labels=tuple(record.marker_labels),
                              vertices=np.asarray(puppet.control_indices, dtype=np.int64),
                              positions=np.full((count, 3), np.nan), offsets=np.asarray(record.marker_offsets))
    else:
        raise OptionError(f"{path}: a motion-capture take needs a marker layout: give --markers LAYOUT.json, or "
                          "train the puppet on controls chosen by select-controls --markers")
    order, offsets = _layout_on_controls(layout, puppet, skin)
    take = read_c3d(path, units=options["marker_units"])
    matched = match_markers(take, layout, allow_missing=options["allow_missing"])
    labels = tuple(layout.labels[i] for i in order)
    stabilize = ()
    if options["stabilize"]:
        from skinsynth.formats.c3d import marker_key

        keys = [marker_key(label) for label in labels]
        names = [item for item in options["stabilize"].replace(" ", "").split(",") if item]
        unknown = [name for name in names if marker_key(name) not in keys]
        if unknown:
            raise OptionError(f"--stabilize names markers the layout lacks: {', '.join(unknown)}")
        stabilize = [keys.index(marker_key(name)) for name in names]
    fps = float(skin.fps if options["fps"] is None else options["fps"])
    training = host_inputs(puppet, skin.examples[puppet.train_frames][:, puppet.control_indices])[1]
    normals = vertex_normals(skin.rest_vertices[None], skin.faces)[0][puppet.control_indices]
    drive = drive_from_markers(matched.points[:, order], take.rate, fps, puppet.reference_controls, training,
                               meters_per_unit=skin.scene.meters_per_unit, take_up=options["take_up_axis"],
                               puppet_up=skin.scene.up_axis, offsets=offsets, normals=normals,
                               neutral_frame=options["neutral_frame"], retarget=options["retarget"],
                               stabilize=stabilize, max_gap=options["max_gap"], min_markers=options["min_markers"])
    if not np.isfinite(drive.controls).all():
        raise FormatError(path, "the take gives no finite control positions")
    filled = {labels[m]: {"interpolated": _ranges(drive.interpolated.get(m, [])),
                          "from_other_markers": _ranges(drive.subspace.get(m, [])),
                          "frames": int(len(drive.interpolated.get(m, [])) + len(drive.subspace.get(m, [])))}
              for m in sorted(set(drive.interpolated) | set(drive.subspace))}
    name = os.path.basename(str(path))
    summary = {"take": str(path), "take_frames": int(take.points.shape[0]), "take_rate": float(take.rate),
               "units": take.units, "units_from": take.units_source, "start_time": float(take.first_time),
               "fps": fps, "frames": int(len(drive.controls)), "neutral_frame": drive.neutral_frame,
               "retarget": options["retarget"], "markers": list(labels),
               "missing_markers": list(matched.missing), "unmatched_labels": list(matched.unmatched),
               "transform": {"scale": drive.scale, "rotation": drive.rotation.tolist(),
                             "translation": drive.translation.tolist()},
               "filled": filled, "held_frames": _ranges(drive.held), "min_markers": drive.min_markers}
    lines = [f"{name}: {take.points.shape[0]} frames at {take.rate:g} Hz ({take.units}, from {take.units_source}) -> "
             f"{len(drive.controls)} frames at {fps:g} fps from {take.first_time:g} s; {len(labels)} markers, aligned "
             f"at take frame {drive.neutral_frame} (scale {drive.scale:.4g}), {options['retarget']} retargeting"]
    if matched.unmatched:
        lines.append(f"{name}: labels not in the layout, ignored: {', '.join(matched.unmatched)}")
    if matched.missing:
        lines.append(f"{name}: the layout's {', '.join(matched.missing)} missing from the take: filled from the "
                     "other markers every frame (--allow-missing)")
    for label, what in filled.items():
        ways = [f"interpolated {what['interpolated']}" if what["interpolated"] else "",
                f"from the other markers {what['from_other_markers']}" if what["from_other_markers"] else ""]
        lines.append(f"{name}: {label} filled in {what['frames']} take frames ({'; '.join(w for w in ways if w)})")
    if len(drive.held):
        lines.append(f"{name}: take frames {_ranges(drive.held)} see fewer than {drive.min_markers} markers: held "
                     "from the last good frame")
    return TakeControls(controls=drive.controls, markers=drive.markers, fps=fps, start_time=float(take.first_time),
                        labels=labels, summary=summary, lines=lines)
