"""A motion-capture take (C3D) as a puppet's control trajectory, what ``play`` and ``view`` share:
the take and layout read with ``formats``, tied to the control vertices, handed to
``pipeline.puppet.drive_from_markers``; the trajectory returned with its ``--json`` summary and lines."""

from dataclasses import dataclass

import numpy as np

from skinsynth.pipeline.puppet.marker_filter import AUTO, cutoff_option
from skinsynth.pipeline.puppet.marker_gaps import rigid_clusters

#: The options of :func:`skinsynth.cli.options.marker_take_options` and their defaults, by name.
TAKE_DEFAULTS = {"marker_layout": None, "marker_units": None, "take_up_axis": "Z", "fps": None, "neutral_frame": None,
             "retarget": "delta", "stabilize": None, "max_gap": None, "min_markers": None, "allow_missing": False,
             "cutoff": AUTO}


@dataclass
class TakeControls:
    """controls (F, n_c, 3) world; markers (F, n_c, 3) the aligned markers; fps; start_time (seconds
    of the first frame, the take's); labels (n_c,) each control's marker; summary (JSON) and lines."""

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
    if given := [name for name, default in TAKE_DEFAULTS.items() if options.get(name, default) != default]:
        flag = "--" + given[0].replace("_", "-").replace("marker-layout", "markers")
        raise OptionError(f"{flag} applies to a motion-capture take: give --controls a .c3d file")


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
    from skinsynth.pipeline.puppet import drive_from_markers, host_inputs, layout_order, take_report
    from skinsynth.pipeline.puppet.markers import check_take_size

    options = {**TAKE_DEFAULTS, **options}
    if options["marker_layout"] is not None:
        layout = read_marker_layout(options["marker_layout"], vertex_count=skin.rest_vertices.shape[0])
    elif record.marker_labels:
        layout = MarkerLayout.on_vertices(puppet_path, record.marker_labels, puppet.control_indices,
                                          record.marker_offsets)
    else:
        raise OptionError(f"{path}: a motion-capture take needs a marker layout: give --markers LAYOUT.json, or "
                          "train the puppet on controls chosen by select-controls --markers")
    try:
        order = layout_order(layout.vertices, layout.positions, skin.rest_vertices, puppet.control_indices)
    except ValueError as problem:
        raise FormatError(layout.path, str(problem)) from None
    offsets = layout.offsets[order]
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
    fps_from = "--fps" if options["fps"] is not None else "the puppet's"
    check_take_size(path, matched.points.shape[:2], take.rate, fps, fps_from, skin.rest_vertices.shape[0])
    ids = puppet.control_indices
    training = host_inputs(puppet, skin.examples[puppet.train_frames][:, ids])[1]
    drive = drive_from_markers(matched.points[:, order], take.rate, fps, puppet.reference_controls, training,
                               meters_per_unit=skin.scene.meters_per_unit, take_up=options["take_up_axis"],
                               puppet_up=skin.scene.up_axis, offsets=offsets,
                               normals=vertex_normals(skin.rest_vertices[None], skin.faces)[0][ids],
                               neutral_frame=options["neutral_frame"], retarget=options["retarget"],
                               stabilize=stabilize, max_gap=options["max_gap"], min_markers=options["min_markers"],
                               labels=labels, cutoff=cutoff_option(options["cutoff"]),
                               bones=rigid_clusters(skin.bone_indices[ids], skin.bone_weights[ids]))
    if not np.isfinite(drive.controls).all():
        raise FormatError(path, "the take gives no finite control positions")
    summary, lines = take_report(path, take, matched, labels, drive, fps, options["retarget"])
    return TakeControls(controls=drive.controls, markers=drive.markers, fps=fps, start_time=float(take.first_time),
                        labels=labels, summary=summary, lines=lines)

