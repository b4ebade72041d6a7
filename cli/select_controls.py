"""``skinsynth select-controls``: choose the control points of a puppet (Feng et al. 2008 §3)."""

import click
import numpy as np

from skinsynth.formats.output_file import check_output_path
from skinsynth.pipeline.errors import OptionError

from .options import FINITE_FLOAT
from .common import command_line, report, summary_options, tool_version, user_errors


@click.command("select-controls")
@click.argument("input_path", metavar="SKIN", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Controls file to write (.h5).")
@click.option("--count", "-n", default=None, type=int,
              help="Number of control points n_c  [default: 8, or as many as --vertices gives].")
@click.option("--vertices", "vertex_list", default=None, metavar="I,J,...",
              help="Use these vertex ids (comma-separated, 0-based) instead of the automatic choice.")
@click.option("--markers", "marker_layout", default=None, type=click.Path(dir_okay=False),
              help="Use the vertices of this marker layout (JSON {LABEL: vertex | [x, y, z] rest position}, "
                   "docs/mocap.md) as the controls, where a performer's markers sit (Feng §6), and store the "
                   "layout so play and view read C3D takes with it.")
@click.option("--components", "-k", default=None, type=int,
              help="Number of PCA bases K  [default: smallest explaining 99% of the in-place variance, "
                   "at least ceil(n_c/2), at most min(frames-1, 3 x vertices)].")
@click.option("--min-spacing", default=0.1, show_default=True, type=FINITE_FLOAT,
              help="Automatic rule: skip candidates closer than this fraction of the rest bounding-box "
                   "diagonal to a chosen control that moves with them (see --rigid-tolerance).")
@click.option("--rigid-tolerance", default=0.1, show_default=True, type=FINITE_FLOAT,
              help="Two near points whose distance changes less than this (relative) in every example "
                   "move as one piece: the second is skipped. Near points that move apart (lips) are both kept.")
@click.option("--clips", "clip_list", default=None, metavar="A,B,...",
              help="Select from these clips' frames only (names as fit-skin stored them; inspect lists them)  "
                   "[default: every clip].")
@summary_options
@user_errors
def select_controls(input_path, output, count, vertex_list, marker_layout, components, min_spacing, rigid_tolerance, clip_list, quiet,
                    as_json):
    """Choose control points from a skin file's examples (Feng et al. 2008 §3).

    PCA of the example vertex positions (each frame first brought in place by a rigid fit onto
    the rest pose), varimax rotation of the K retained bases, and two representative vertices
    per rotated basis: the vertex the basis moves most, and the vertex whose motion differs
    most from it. From these 2K candidates n_c are chosen by a fixed rule instead of the
    paper's manual pick: bases by variance share, largest first; first the top vertex of each
    basis, then the second ones; a candidate within --min-spacing of a chosen control that
    moves with it (their distance stays within --rigid-tolerance) is skipped; any shortfall is filled farthest-point first. The rule uses no randomness, so the
    same input always gives the same controls. --vertices takes your own choice instead.
    A skin file of several clips (fit-skin CLIP...) is analysed over every clip's frames, or over
    those of --clips; the clips used are recorded (/controls/@clips).

    Prints one line per control: vertex id, basis, its variance share, and why it was chosen.

    \b
    Examples:
      skinsynth select-controls face.skin.h5 -o face.controls.h5
      skinsynth select-controls face.skin.h5 -o face.controls.h5 --count 12 --components 10
      skinsynth select-controls face.skin.h5 -o face.controls.h5 --vertices 120,455,873,1021
      skinsynth select-controls horse.skin.h5 -o horse.controls.h5 --clips gallop
      skinsynth select-controls samba.skin.h5 -o samba.controls.h5 --markers samba.layout.json
    """
    from skinsynth.formats.controls_file import controls_groups
    from skinsynth.formats.model import read_model, write_model
    from skinsynth.formats.provenance import provenance_record
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.inputs.clips import Clips
    from skinsynth.pipeline.puppet import select_controls as select, selection_summary

    check_output_path(output, (".h5", ".hdf5"), inputs=[input_path])
    user = None if vertex_list is None else _vertex_ids(vertex_list)
    model = read_model(input_path, stages=("skin",))
    skin = read_skin(input_path, model)
    user, markers = (user, None) if marker_layout is None else _layout_controls(marker_layout, skin, user)
    clips = Clips(skin.clip_names, skin.clip_frames)
    frames = clips.select(clip_list, "--clips")
    used = tuple(clips.names[c] for c in np.unique(clips.clip_of(frames)))
    examples = skin.examples if len(frames) == clips.total else skin.examples[frames]

    # No progress bar: one SVD of F x 3V and a K x K varimax take seconds even on large meshes.
    selection = select(examples, skin.rest_vertices, count=count, components=components,
                       user_vertices=user, min_spacing_fraction=min_spacing, rigid_tolerance=rigid_tolerance)

    if markers is not None:
        selection.reasons = [f"marker {label} of {marker_layout}" for label in markers[0]]
    parameters = dict(count=len(selection.indices), vertices=user, markers=marker_layout, components=selection.components,
                      components_option=components, min_spacing=min_spacing, rigid_tolerance=rigid_tolerance,
                      method=selection.method, clips=list(used))
    record = provenance_record("controls", command_line(), parameters, [input_path], tool_version(), None)
    write_model(output, "controls", controls_groups(selection, model, clips=used, markers=markers), model["provenance"] + [record],
                tool_version())
    for warning in selection.warnings:
        click.echo(f"warning: {warning}", err=True)
    report(*selection_summary(output, selection, frames, clips, used), as_json, quiet)


def _vertex_ids(vertex_list):
    """The vertex ids of ``--vertices I,J,...``; OptionError for anything but integers, or none."""
    try:
        user = [int(item) for item in vertex_list.replace(" ", "").split(",") if item != ""]
    except ValueError:
        raise OptionError(f"--vertices takes comma-separated integer vertex ids (got {vertex_list!r})") from None
    if not user:
        raise OptionError("--vertices needs at least one vertex id")
    return user


def _layout_controls(path, skin, user=None):
    """A marker layout's vertices as the user's controls: (vertex ids, (labels, offsets)), in the
    layout's order; a marker given by a rest position takes the nearest vertex. Refused with
    ``--vertices`` (``user``), which chooses them too."""
    from skinsynth.formats.errors import FormatError
    from skinsynth.formats.marker_layout import read_marker_layout
    from skinsynth.pipeline.puppet.markers import layout_vertex_ids

    if user is not None:
        raise OptionError("--markers and --vertices both choose the controls: give one")
    layout = read_marker_layout(path, vertex_count=skin.rest_vertices.shape[0])
    vertices = layout_vertex_ids(layout.vertices, layout.positions, skin.rest_vertices)
    if len(set(vertices.tolist())) != len(vertices):
        twice = [label for label, v in zip(layout.labels, vertices) if (vertices == v).sum() > 1]
        raise FormatError(path, f"markers {', '.join(twice)} sit on one vertex: each control needs its own")
    return vertices.tolist(), (layout.labels, layout.offsets)
