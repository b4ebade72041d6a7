"""``skinsynth build-graph``: transitions, bone graph and splicing operators from one clip, or from
several clips of one character (transitions within and between them)."""

import time

import click

from skinsynth.pipeline.synthesis.graph_options import GraphOptions

from skinsynth.formats.output_file import check_output_path
from skinsynth.formats.output_folder import FolderOutputs

from .common import report, summary_options, command_line, tool_version, user_errors
from .options import FINITE_FLOAT, up_axis_option

DEFAULTS = GraphOptions()


@click.command("build-graph")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Graph file to write (.h5).")
@click.option("--threshold-scale", default=DEFAULTS.threshold_scale, show_default=True, type=FINITE_FLOAT,
              help="Transition threshold T_c as a multiple of the playback step cost D(i, i−1) (see --threshold-reference).")
@click.option("--threshold-reference", type=click.Choice(["median-step", "max-step"]),
              default=DEFAULTS.threshold_reference,
              show_default=True,
              help="Step the scale multiplies: the median, or the maximum as in Zheng (whose 40 × max admits "
                   "almost every pair on real clips).")
@click.option("--edge-threshold", default=DEFAULTS.edge_threshold, show_default=True, type=FINITE_FLOAT,
              help="Drop bone-graph edges weaker than this fraction of the strongest (never disconnecting the graph).")
@click.option("--single-component", is_flag=True, help="Treat the whole mesh as one component (no cut-node split).")
@click.option("--svd-threshold", default=DEFAULTS.svd_threshold, show_default=True, type=FINITE_FLOAT,
              help="Keep reduced coordinates whose singular value is at least this fraction of the largest.")
@click.option("--min-gap", default=DEFAULTS.min_gap, show_default=True, type=int, help="Smallest |i − j| of a transition.")
@click.option("--min-segment", type=int, default=None,
              help="Shortest stretch (frames) walks play between two seams; transitions closer than half of it "
                   "to a cheaper one are dropped. Stored as synthesize's default.  [default: half a second at the "
                   "clip's frame rate]")
@click.option("--coverage", default=DEFAULTS.coverage, show_default=True, type=FINITE_FLOAT,
              help="Admit transitions above the threshold (cheapest first, only those that help) until this share "
                   "of the frames lies on one strongly connected part of the motion graph, so walks can reach "
                   "the whole clip.")
@up_axis_option("The clip's up axis: synthesize places segments by a turn about it and a shift on the ground "
                "(default: the input's, as fit-skin recorded it; Y for files from before).")
@click.option("--posture-weight", default=DEFAULTS.posture_weight, show_default=True, type=FINITE_FLOAT,
              help="Weight of the reference bone's tilt and height in the transition cost (balanced like "
                   "Zheng's α, β; 0: his eq. 5 alone, for synthesize --alignment full).")
@click.option("--clips", "walk_clips", default=None, metavar="A,B",
              help="With several clips: the clips walks may play (default every clip). The others get no "
                   "transition in or out, so synthesize never plays them: e.g. a library of unrelated key poses "
                   "that shares the rig (and trains the puppet) but is no motion to walk through.")
@click.option("--no-contacts", "no_contacts", is_flag=True,
              help="Do not look for the input's ground contacts (the graph file then holds none).")
@click.option("--contact-height", default=DEFAULTS.contact_height, show_default=True, type=FINITE_FLOAT,
              help="A vertex enters contact within this share of the character's height above its clip's ground "
                   "(a low percentile of the clip's lowest points).")
@click.option("--contact-speed", default=DEFAULTS.contact_speed, show_default=True, type=FINITE_FLOAT,
              help="... and slower than this share of the height per second, sideways, relative to the ground "
                   "(a treadmill's belt is the ground's own travel).")
@click.option("--contact-release", default=DEFAULTS.contact_release, show_default=True, type=FINITE_FLOAT,
              help="A vertex leaves contact beyond this multiple (≥ 1) of both thresholds (hysteresis).")
@click.option("--contact-min-duration", default=DEFAULTS.contact_min_duration, show_default=True, type=FINITE_FLOAT,
              help="Shortest plant kept, in seconds (shorter ones are dropped).")
@click.option("--contact-min-support", default=DEFAULTS.contact_min_support, show_default=True, type=FINITE_FLOAT,
              help="A ground bears the body often: a clip keeps no plant unless some patch is planted in at least "
                   "this share of its frames (a part that only pauses at its lowest is no contact).")
@click.option("--plot", "plot_dir", type=click.Path(file_okay=False), default=None,
              help="Write PNGs here: the cost matrix of each component with its transitions, and the bone graph.")
@summary_options
@user_errors
def build_graph(path, output, min_segment, up_axis, walk_clips, no_contacts, plot_dir, quiet, as_json, **options):
    """Analyse a skin fit for synthesis (Zheng 2013 §3.2, §3.3, §4.1).

    Finds, per weakly coupled bone component, its reference bone, reduced coordinates and the
    candidate transitions between frames (eq. 2–6, local minima below the threshold); the bone
    graph (eq. 11), its cut nodes and components; and the key vertices, weight gradients
    (Appendix A), rotation–strain deformation-gradient series (eq. 8) and the factorised
    operator of eq. 9 that splicing needs.

    It also finds the input's ground contacts: per input frame, the patches of the mesh that
    rest on the ground (near the clip's ground, slow, facing it; with hysteresis and a shortest
    plant), stored in the graph file and drawn by --plot on a timeline. Transitions within a
    clip that would take a planted patch to a swinging one (or back) are refused, unless that
    leaves the walks under 90 % of the frames they could play. A capture that never rests on a
    ground has none, and its graph file is the same as with --no-contacts.

    The threshold counts the clip's motion per unit of time (the moving frames' playback steps over
    about 1/24 s, at the frame rate fit-skin --fps stored), so the same motion gives the same graph
    at 12, 24, 48 or 96 fps: declare a capture's frame rate when you fit it. A pose held still for a
    second or more (a performer standing before the dance) is one place in the graph: walks show it
    for half a second and go on. The summary names the held poses and, per component, the frames
    a walk can reach but never leave (what follows a one-time event: played once, at the end).
    docs/motion_graph.md has the rules and why they hold.

    A skin fitted to several clips (fit-skin A.npz B.npz) keeps them apart: playback never runs
    from one clip's last frame into the next clip's first, and transitions are found within each
    clip and between clips by the same rule (a gallop that falls into the collapse). The summary
    counts them per direction (gallop→collapse, collapse→gallop) and per component.

    \b
    Examples:
      skinsynth build-graph horse.skin.h5 -o horse.graph.h5 --plot horse_plots
      skinsynth build-graph dancer.skin.h5 -o dancer.graph.h5 --single-component --threshold-scale 4
      skinsynth build-graph horse_clips.skin.h5 -o horse_clips.graph.h5   # gallop + collapse
      skinsynth build-graph elephant.skin.h5 -o elephant.graph.h5 --clips gallop   # poses left out
    """
    from skinsynth.formats.graph_file import graph_groups
    from skinsynth.formats.model import read_model, write_model
    from skinsynth.formats.plots import write_graph_plots
    from skinsynth.formats.provenance import provenance_record
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.synthesis import analyse_fit, bone_layout, default_min_segment, graph_summary

    check_output_path(output, (".h5", ".hdf5"), inputs=[path])
    folders = FolderOutputs([path], [output, plot_dir])
    folders.check(plot_dir)
    model = read_model(path)
    skin = read_skin(path, model)
    # the other options are GraphOptions' own, by name
    options = GraphOptions(**options, min_segment=default_min_segment(skin.fps) if min_segment is None else min_segment,
                           up_axis="XYZ".index(up_axis or skin.scene.up_axis), contacts=not no_contacts)
    started = time.perf_counter()
    analysis = analyse_fit(skin, options, None if walk_clips is None else
                           [n.strip() for n in walk_clips.split(",") if n.strip()] or [""])
    seconds = time.perf_counter() - started
    record = provenance_record("graph", command_line(), options.parameters(analysis.options["walk_clips"]), [path],
                               tool_version())
    write_model(output, "graph", graph_groups(model, analysis), model["provenance"] + [record], tool_version())
    if plot_dir is not None:  # a transition into clip c's start drawn at c's virtual column
        write_graph_plots(plot_dir, analysis, bone_layout(skin.rest_vertices, skin.bone_indices, skin.bone_weights,
                                                          skin.bones), analysis.drawn_transitions(),
                          **folders.guard(plot_dir))
    summary, lines = graph_summary(output, analysis, seconds)
    report(summary, lines, as_json, quiet)
    if analysis.transition_count == 0:
        click.echo("warning: no candidate transitions: the clip has no repeated states at this threshold; "
                   "try a larger --threshold-scale", err=True)
