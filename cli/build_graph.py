"""``skinsynth build-graph``: transitions, bone graph and splicing operators from one clip."""

import os
import time

import click

from skinsynth.pipeline.synthesis.graph_options import GraphOptions

from .common import FolderOutputs, report, summary_options, check_output_path, command_line, tool_version, user_errors
from .options import up_axis_option

DEFAULTS = GraphOptions()


@click.command("build-graph")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Graph file to write (.h5).")
@click.option("--threshold-scale", default=DEFAULTS.threshold_scale, show_default=True, type=float,
              help="Transition threshold T_c as a multiple of the playback step cost D(i, i−1) (see --threshold-reference).")
@click.option("--threshold-reference", type=click.Choice(["median-step", "max-step"]),
              default=DEFAULTS.threshold_reference,
              show_default=True,
              help="Step the scale multiplies: the median, or the maximum as in Zheng (whose 40 × max admits "
                   "almost every pair on real clips).")
@click.option("--edge-threshold", default=DEFAULTS.edge_threshold, show_default=True, type=float,
              help="Drop bone-graph edges weaker than this fraction of the strongest (never disconnecting the graph).")
@click.option("--single-component", is_flag=True, help="Treat the whole mesh as one component (no cut-node split).")
@click.option("--svd-threshold", default=DEFAULTS.svd_threshold, show_default=True, type=float,
              help="Keep reduced coordinates whose singular value is at least this fraction of the largest.")
@click.option("--min-gap", default=DEFAULTS.min_gap, show_default=True, type=int, help="Smallest |i − j| of a transition.")
@click.option("--min-segment", type=int, default=None,
              help="Shortest stretch (frames) walks play between two seams; transitions closer than half of it "
                   "to a cheaper one are dropped. Stored as synthesize's default.  [default: half a second at the "
                   "clip's frame rate]")
@click.option("--coverage", default=DEFAULTS.coverage, show_default=True, type=float,
              help="Admit transitions above the threshold (cheapest first, only those that help) until this share "
                   "of the frames lies on one strongly connected part of the motion graph, so walks can reach "
                   "the whole clip.")
@up_axis_option("The clip's up axis: synthesize places segments by a turn about it and a shift on the ground "
                "(default: the input's, as fit-skin recorded it; Y for files from before).")
@click.option("--posture-weight", default=DEFAULTS.posture_weight, show_default=True, type=float,
              help="Weight of the reference bone's tilt and height in the transition cost (balanced like "
                   "Zheng's α, β; 0: his eq. 5 alone, for synthesize --alignment full).")
@click.option("--plot", "plot_dir", type=click.Path(file_okay=False), default=None,
              help="Write PNGs here: the cost matrix of each component with its transitions, and the bone graph.")
@summary_options
@user_errors
def build_graph(path, output, threshold_scale, threshold_reference, edge_threshold, single_component, svd_threshold,
                min_gap, min_segment, coverage, up_axis, posture_weight, plot_dir, quiet, as_json):
    """Analyse a skin fit for synthesis (Zheng 2013 §3.2, §3.3, §4.1).

    Finds, per weakly coupled bone component, its reference bone, reduced coordinates and the
    candidate transitions between frames (eq. 2–6, local minima below the threshold); the bone
    graph (eq. 11), its cut nodes and components; and the key vertices, weight gradients
    (Appendix A), rotation–strain deformation-gradient series (eq. 8) and the factorised
    operator of eq. 9 that splicing needs.

    \b
    Examples:
      skinsynth build-graph horse.skin.h5 -o horse.graph.h5 --plot horse_plots
      skinsynth build-graph dancer.skin.h5 -o dancer.graph.h5 --single-component --threshold-scale 4
    """
    from skinsynth.formats.graph_file import graph_groups
    from skinsynth.formats.model import read_model, write_model
    from skinsynth.formats.provenance import provenance_record
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.synthesis import build_graph as analyse, validate_graph_options
    from skinsynth.pipeline.synthesis import default_min_segment

    check_output_path(output, (".h5", ".hdf5"), inputs=[path])
    folders = FolderOutputs([path], [output, plot_dir])
    folders.check(plot_dir)
    model = read_model(path)
    skin = read_skin(path, model)
    if min_segment is None:
        min_segment = default_min_segment(skin.fps)
    up_axis = up_axis or skin.scene.up_axis
    validate_graph_options(skin.rotations.shape[0], threshold_scale, edge_threshold, svd_threshold, min_gap,
                           min_segment, coverage, posture_weight)
    started = time.perf_counter()
    analysis = analyse(skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights, skin.rotations,
                       skin.translations, threshold_scale=threshold_scale, threshold_reference=threshold_reference,
                       edge_threshold=edge_threshold, single_component=single_component, svd_threshold=svd_threshold,
                       min_gap=min_gap, min_segment=min_segment, coverage=coverage, up_axis="XYZ".index(up_axis),
                       posture_weight=posture_weight)
    seconds = time.perf_counter() - started
    parameters = dict(threshold_scale=threshold_scale, threshold_reference=threshold_reference,
                      edge_threshold=edge_threshold, single_component=single_component, svd_threshold=svd_threshold,
                      min_gap=min_gap, min_segment=min_segment, coverage=coverage, up_axis=up_axis,
                      posture_weight=posture_weight)
    record = provenance_record("graph", command_line(), parameters, [path], tool_version())
    write_model(output, "graph", graph_groups(model, analysis), model["provenance"] + [record], tool_version())
    if plot_dir is not None:
        _write_plots(plot_dir, skin, analysis, folders)
    summary, lines = _summary(output, analysis, min_segment, up_axis, seconds)
    report(summary, lines, as_json, quiet)
    if analysis.transition_count == 0:
        click.echo("warning: no candidate transitions: the clip has no repeated states at this threshold; "
                   "try a larger --threshold-scale", err=True)


def _write_plots(plot_dir, skin, analysis, folders):
    """The folder of PNGs: each component's transition-cost matrix and the bone graph."""
    from skinsynth.formats.output_folder import atomic_folder
    from skinsynth.formats.plots import write_bone_graph_plot, write_cost_matrix_plot
    from skinsynth.pipeline.synthesis import bone_layout

    with atomic_folder(plot_dir, **folders.guard(plot_dir)) as tmp:
        for number, component in enumerate(analysis.components):
            t = component.transitions
            write_cost_matrix_plot(os.path.join(tmp, f"costs_component_{number:03d}.png"), t.D, t.pairs,
                                   t.threshold, f"component {number}: {len(component.bones)} bones, "
                                   f"{len(t.pairs)} transitions (T_c = {t.threshold:.3g})", start=t.start)
        positions = bone_layout(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.bones)
        write_bone_graph_plot(os.path.join(tmp, "bone_graph.png"), positions, analysis.weights,
                              analysis.kept_edges, [c.bones for c in analysis.components], analysis.cut_nodes,
                              f"bone graph: {len(analysis.components)} component(s), "
                              f"{len(analysis.cut_nodes)} cut node(s)")


def _summary(output, analysis, min_segment, up_axis, seconds):
    """The command's summary (--json) and its text lines."""
    lines = [f"wrote {output}: {len(analysis.components)} component(s), cut nodes {analysis.cut_nodes}, "
             f"{analysis.transition_count} transitions, segments ≥ {min_segment} frames; {seconds:.1f} s"]
    components = []
    for number, component in enumerate(analysis.components):
        t = component.transitions
        extra = f", {t.admitted} above T_c for coverage" if t.admitted else ""
        lines.append(f"  component {number}: bones {component.bones} (reference {t.reference}), "
                     f"{len(t.pairs)} transitions{extra}, {t.share:.0%} of the frames on one strongly connected "
                     f"part, {len(component.key)} key vertices, {t.q.shape[1]} reduced coordinates")
        components.append({"bones": list(component.bones), "reference": int(t.reference),
                           "transitions": len(t.pairs), "admitted": int(t.admitted), "share": float(t.share),
                           "key_vertices": len(component.key), "reduced_coordinates": int(t.q.shape[1])})
    summary = {"output": output, "components": components, "cut_nodes": list(analysis.cut_nodes),
               "transitions": int(analysis.transition_count), "min_segment": int(min_segment), "up_axis": up_axis,
               "seconds": round(seconds, 3)}
    return summary, lines
