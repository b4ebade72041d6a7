"""``skinsynth synthesize``: one clip in, many different animations out (Zheng 2013).

The graph's input may be several clips of one mesh (issue 26): input frames are named
``CLIP:FRAME`` (``gallop:0``; a negative FRAME counts from the clip's end) or by their global
number (``--start``, ``--end``, ``--target``; :meth:`~skinsynth.pipeline.inputs.clips.Clips.frame`),
walks cross between clips by the graph's transitions, and the summary counts coverage per clip
and the transitions taken from each clip to each. One clip runs exactly as before."""

import contextlib
import os
import time

import click

from skinsynth.formats.output_file import check_output_path
from skinsynth.formats.output_folder import FolderOutputs
from skinsynth.pipeline.runtime.execution import Cluster
from skinsynth.pipeline.runtime.resources import check_memory, check_space

from .options import (FINITE_FLOAT, FiniteFloatRange, check_max_width, device_option, texture_options,
                      up_axis_option)
from .outputs import SynthesisOutputs, check_texture_output, write_synthesis_outputs
from .common import report, summary_options, Progress, command_line, tool_version, user_errors


def _target(text):
    """``[CLIP:]FRAME@TIME`` -> (the frame's text, read once the clips are known; TIME)."""
    frame, sep, when = text.rpartition("@")
    try:
        if not sep or not frame.strip():
            raise ValueError
        return frame.strip(), int(when)
    except ValueError:
        raise click.BadParameter(f"{text!r}: expected [CLIP:]FRAME@TIME, e.g. 12@100 or gallop:12@100") from None


@click.command("synthesize")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Bone motions file to write (.h5).")
@click.option("--count", "-n", required=True, type=int, help="Number of animations.")
@click.option("--frames", "-m", required=True, type=int, help="Frames per animation.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0), help="Seed of every random choice.")
@click.option("--start", "--start-frame", "start_frame", default=None, metavar="CLIP:FRAME",
              help="Input frame every animation starts with: CLIP:FRAME (gallop:0; a negative FRAME counts from "
                   "the clip's end) or a global frame number.")
@click.option("--end", "--end-frame", "end_frame", default=None, metavar="CLIP:FRAME",
              help="Input frame every animation ends with (as --start).")
@click.option("--target", "targets", multiple=True, type=_target, metavar="[CLIP:]FRAME@TIME",
              help="Input frame (as --start) must appear at output TIME (repeatable).")
@click.option("--obstacle", "obstacles", multiple=True, type=click.Path(dir_okay=False),
              help="A mesh (OBJ/PLY/OFF/STL…) no frame may penetrate (repeatable).")
@click.option("--ground-plane", is_flag=True, help="No vertex may go below the input clip's lowest point.")
@click.option("--min-difference", default=0.0, show_default=True, type=FINITE_FLOAT,
              help="Drop an animation that shares more than 1 − X of its frames (same input frame at the same time) with an earlier one.")
@click.option("--single-component", is_flag=True, help="Synthesise the whole rig as one component, ignoring cut nodes.")
@click.option("--min-segment", type=int, default=None,
              help="Shortest stretch (frames) a walk plays between two seams (half of it to leave a loop it would "
                   "replay).  [default: the graph's, set by build-graph: half a second]")
@click.option("--window", default=None, type=int,
              help="Frames blended on each side of a transition.  [default: a sixth of a second (4 frames at 24 fps), at most 12]")
@click.option("--blend", type=click.Choice(["bones", "key-vertices"]), default="bones", show_default=True,
              help="What a transition blends: each bone's rotation and pivot in the reference bone's frame (rigid "
                   "bones), or Zheng's deformation gradients at key vertices solved back to affine bones (eq. 8–9).")
@click.option("--alignment", type=click.Choice(["ground", "full"]), default="ground", show_default=True,
              help="How a segment is placed after a transition: turned about the up axis and shifted on the ground "
                   "(motion-graph practice: no drift off the ground, however long), or by Zheng's full rigid "
                   "transform (eq. 7), for clips that truly turn over (a swimmer, a cloth in the wind).")
@click.option("--cut-damping", default=1e-3, show_default=True, type=FINITE_FLOAT,
              help="Pull of the cut nodes' eq. 9 solve towards their source positions (relative; 0: none). "
                   "A cut node is seen by one side's key vertices only; undamped it stretches in blends.")
@click.option("--spread-velocity/--no-spread-velocity", default=True, show_default=True,
              help="Spread each transition's velocity jump evenly over its blend window (off: Zheng's plain "
                   "guidance, the input's own accelerations).")
@click.option("--contact/--no-contact", default=True, show_default=True,
              help="Keep the feet on the ground. A graph with the input's ground contacts: each plant stays on its "
                   "anchor (the patch follows the input's own steps and height, the body's travel follows the "
                   "planted feet, the legs take the rest), blended in and out with a 0.1 s half-life, gaps of "
                   "at most 0.2 s bridged; a swinging foot stays no lower than the input's (docs/contact.md). "
                   "Then, and alone for a graph without contacts: where a frame's lowest point would leave the "
                   "input's own range of lowest points, the whole character moves vertically back.")
@click.option("--shape-check/--no-shape-check", default=True, show_default=True,
              help="Keep the body whole: walk only the transitions whose splice keeps it (each spliced once and its "
                   "frames measured against the capture's edges), and cut a planted limb's turn that would strain "
                   "its skin past them (the foot slides a little instead; docs/contact.md). Off: every transition, "
                   "every turn.")
@click.option("--measure-feet", "measure_feet", default=4, show_default=True, type=click.IntRange(min=0),
              metavar="N",
              help="Measure how well the feet stay planted (slide, float and penetration of the contact vertices, "
                   "worst acceleration; where a limb could not hold its foot, and how much it slid there) and the "
                   "body keeps its shape (frames whose edges strain far past the capture's; docs/contact.md) on the "
                   "first N animations, skinned, and on the input; reported in the summary and --json's "
                   "\"contact\" and \"shape\" (their own seconds, not in the run's). 0: "
                   "skip. It skins N whole animations: about 1.4 s each for 600 frames of 42,000 vertices on 2 cores.")
@click.option("--usd", "usd_dir", type=click.Path(file_okay=False), default=None, help="Also write one USD point cache per animation here.")
@click.option("--crowd", type=click.Path(dir_okay=False), default=None, help="Also write one USD stage with every animation on a grid.")
@click.option("--gltf", type=click.Path(dir_okay=False), default=None, metavar="FILE.glb",
              help="Also write the rig as one glTF 2.0 skinned mesh with every animation as a clip (Y up, metres).")
@click.option("--root-motion", is_flag=True,
              help="--gltf: the root joint carries each animation's ground motion, the bones move in place under it.")
@click.option("--exr", "exr_dir", type=click.Path(file_okay=False), default=None,
              help="Also write an engine-ready vertex animation here: per animation offsets and normals textures, "
                   "the rest mesh with texel UVs (rest.obj, rest.glb), vat.json (docs/vat.md).")
@texture_options("--exr: 16-bit half floats instead of 32-bit.",
                 "--exr: texture width limit; vertices wrap to more rows.")
@click.option("--plot", "plot_dir", type=click.Path(file_okay=False), default=None,
              help="Write PNGs here for the first --plot-count animations: the input frame each component plays "
                   "at each output frame, seams marked, and the largest vertex acceleration against the input's.")
@click.option("--plot-count", default=4, show_default=True, type=int, help="Animations --plot draws.")
@up_axis_option("Up axis (ground alignment, ground plane, crowd grid, USD).  [default: the graph's, Y]")
@device_option("Where vertex caches are skinned: auto, cpu, cuda or cuda:N.")
@click.option("--jobs", "-j", default=None, type=int,
              help="Worker processes for the bone motions, and threads skinning the caches on the CPU (the "
                   "result does not depend on it).  [default: all cores]")
@click.option("--cluster", default=None, metavar="ADDRESS",
              help="Make the animations on a Dask cluster: a running scheduler (tcp://host:8786) or local:N (N "
                   "worker processes here, started and closed by the command). Each batch of 250 is written by its "
                   "worker to OUT's shard folder (<OUT>.shards/, on a file system every worker sees at "
                   "the same path), which OUT then maps (HDF5 virtual datasets): keep the two together. A rerun "
                   "reuses the finished shards. Same datasets as without it (docs/cluster.md).")
@click.option("--cluster-timeout", default=Cluster.ANSWER_TIMEOUT, show_default=True, metavar="SECONDS",
              type=FiniteFloatRange(min=0.0, min_open=True, max=600.0),
              help="--cluster tcp://: give up when the scheduler has not answered within this many seconds (a "
                   "line says the command is waiting after 3 s); one that answers then has 60 s to get a worker.")
@summary_options
@user_errors
def synthesize(path, output, count, frames, seed, start_frame, end_frame, targets, obstacles, ground_plane,
               min_difference, single_component, min_segment, window, blend, alignment, cut_damping, spread_velocity, contact,
               shape_check, measure_feet, usd_dir, crowd, gltf, root_motion, exr_dir, half,
               max_width, up_axis, plot_dir, plot_count, device, jobs, cluster, cluster_timeout, as_json, quiet):
    """Synthesise many different animations from the clip analysed in a graph file.

    Random walks over the motion graph (or walks through targeted frames), splicing at the
    candidate transitions with deformation-gradient blending at key vertices (Zheng §3.3),
    independent synthesis of the bone components and their merge through cut nodes (§4.2),
    collision avoidance against obstacle meshes and a diversity filter (§3.4).

    \b
    Examples:
      skinsynth synthesize horse.graph.h5 -o herd.h5 --count 1000 --frames 600 --seed 7
      skinsynth synthesize dancer.graph.h5 -o d.h5 -n 20 -m 300 --start-frame 0 --end-frame 0 --crowd dancers.usdc
      skinsynth synthesize horse.graph.h5 -o h.h5 -n 50 -m 240 --start gallop:0 --end collapse:-1
      skinsynth synthesize cloth.graph.h5 -o c.h5 -n 60 -m 480 --obstacle sphere.obj --usd cloths/
    """
    from skinsynth.formats.graph_file import read_graph
    from skinsynth.formats.model import write_model
    from skinsynth.formats.obstacles import read_obstacle
    from skinsynth.formats.provenance import provenance_record
    from skinsynth.formats.synthesis_file import synthesis_groups, written_motions
    from skinsynth.gpu import resolve_device
    from skinsynth.pipeline.synthesis import prepare_synthesis, report_measures, synthesis_request, synthesis_summary

    sides = SynthesisOutputs(usd_dir, crowd, gltf, root_motion, exr_dir, plot_dir, plot_count, half, max_width)
    folders, jobs = _check_options(path, output, obstacles, sides, cluster, jobs)
    skinning_device = resolve_device(device) if sides.skinned else None  # the feet resolve it when measured
    # a cluster starts (local:N) or is reached in the background while the graph is read
    with (_cluster_starting(cluster, cluster_timeout) if cluster else contextlib.nullcontext()) as joined:
        graph_file = read_graph(path)
        skin = graph_file.skin
        request = synthesis_request(graph_file, start_frame, end_frame, targets, min_segment, up_axis, count=count,
                                    frames=frames, seed=seed, min_difference=min_difference, window=window,
                                    spread_velocity=spread_velocity, cut_damping=cut_damping, blend=blend,
                                    alignment=alignment, contact=contact, shape_check=shape_check)
        what = _check_resources(path, output, graph_file, request, sides, cluster)
        components = prepare_synthesis(request, graph_file, [read_obstacle(o) for o in obstacles], ground_plane,
                                       single_component)
        parameters = request.parameters(obstacles, ground_plane, single_component)
        record = provenance_record("synthesis", command_line(), parameters, [path, *obstacles], tool_version(),
                                   request.seed)
        shards = _shards(path, output, request, record, components, skin, what) if cluster else None
        result, remote, ran, seconds = _make(components, skin, request, jobs, joined if cluster else None, shards,
                                             quiet or as_json)
    write_model(output, "synthesis",
                synthesis_groups(path, result, components, request, skin.fps,
                                 shards=os.path.basename(shards["folder"]) if shards else None),
                graph_file.provenance + [record], tool_version())
    # a cluster's motions are read back from the shards
    with written_motions(output, result) if remote else contextlib.nullcontext(result) as motions:
        written = [output] + write_synthesis_outputs(sides, skin, motions, "XYZ"[request.up_axis], skinning_device,
                                                     folders, jobs, path, request.clips)
        measures = report_measures(skin, motions.F, motions.t, motions.sources, min(measure_feet, count),
                                   request.up_axis, resolve_device(device),
                                   result.limited if request.contact and request.plants is not None else None,
                                   request.envelope) \
            if measure_feet and count else None
    summary, lines = synthesis_summary(output, result, components, frames, request.min_segment, jobs, seconds, written,
                                       measures, _cluster_report(cluster, ran, remote, result, shards))
    report(summary, lines, as_json, quiet)


def _check_options(path, output, obstacles, sides, cluster, jobs):
    """Refuse, before any work, outputs that cannot be written (``sides``: the
    :class:`~skinsynth.cli.outputs.SynthesisOutputs`) and options out of range: (the command's
    :class:`~skinsynth.cli.common.FolderOutputs`, the worker processes)."""
    from skinsynth.formats.synthesis_shards import shard_folder
    from skinsynth.pipeline.errors import OptionError

    if cluster is not None and not cluster.strip():
        raise OptionError("--cluster needs an address: tcp://HOST:PORT of a running scheduler, or local:N")
    check_output_path(output, (".h5", ".hdf5"), inputs=[path, *obstacles])
    if sides.crowd is not None:
        check_output_path(sides.crowd, (".usd", ".usda", ".usdc"), inputs=[path, *obstacles, output])
    if sides.gltf is not None:
        check_output_path(sides.gltf, (".glb",), inputs=[path, *obstacles, output])
    if sides.root_motion and sides.gltf is None:
        raise OptionError("--root-motion is for the --gltf output: give --gltf FILE.glb")
    folders = FolderOutputs([path, *obstacles], [output, sides.crowd, sides.gltf, sides.usd, sides.exr, sides.plots,
                                                 shard_folder(output) if cluster else None])
    for folder in (sides.usd, sides.exr, sides.plots):  # side folders: safe to write before any work
        folders.check(folder)
    if jobs is None:
        jobs = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if jobs < 1:
        raise OptionError(f"--jobs must be at least 1 (got {jobs})")
    if sides.plot_count < 1:
        raise OptionError(f"--plot-count must be at least 1 (got {sides.plot_count})")
    check_max_width(sides.max_width)
    return folders, jobs


def _check_resources(path, output, graph_file, request, sides, cluster):
    """Refuse, before any work, a run the memory cannot hold, a texture too large, an output
    its disk cannot hold (a cluster run's, with its shards: :func:`_shards`); the run in words."""
    skin = graph_file.skin
    # the bone motions (float32 3×3 + 3 per bone) and sources (int32 per component), in memory
    # (on a cluster, in the shards on disk): refused before any is allocated; then the output
    # file on its disk (a cluster run's, with its shards, once the reusable shards are known)
    count, frames, bones = request.count, request.frames, skin.rotations.shape[1]
    what = f"{count} animations × {frames} frames of {bones} bones"
    if not cluster:
        check_memory(count * frames * (bones * 12 * 4 + len(graph_file.components) * 4), what)
    if sides.exr:  # the texture's size, before any work
        check_texture_output(sides.exr, "folder", skin.rest_vertices.shape[0], frames, sides.max_width)
    if not cluster:
        _check_space(path, output, request, graph_file.components, skin, what)
    return what


def _shards(path, output, request, record, components, skin, what):
    """A cluster run's shards (:func:`~skinsynth.formats.synthesis_shards.run_shards`), once the
    output and the shards still to write are known to fit their disks."""
    from skinsynth.formats.synthesis_shards import run_shards
    from skinsynth.pipeline.synthesis import BATCH_REVISION

    shards = run_shards(output, record, request.frames, skin.rotations.shape[1], BATCH_REVISION)
    _check_space(path, output, request, components, skin, what, shards)
    return shards


def _check_space(path, output, request, components, skin, what, shards=None):
    """Refuse, before any work, an output larger than the free space of its folder, and on a
    cluster (``shards``: :func:`~skinsynth.formats.synthesis_shards.run_shards`'s) the shards
    still to write against their folder's: the estimates the writers check at the end, made from
    the request's shapes (:func:`~skinsynth.formats.synthesis_file.space_needs`)."""
    from skinsynth.formats.synthesis_file import space_needs
    from skinsynth.pipeline.synthesis import batch_sizes

    check_space(what, space_needs(path, output, request, components, skin.rotations.shape[1], skin.fps, shards,
                                  batch_sizes(request.count)))


def _make(components, skin, request, jobs, joined, shards, quiet):
    """Synthesise, here (``joined`` None) or on the cluster ``joined()`` returns, whose workers
    write their batches to the run's ``shards``, with a progress bar; (result, remote or None,
    the cluster's (workers, dashboard) or None, seconds)."""
    from skinsynth.formats.synthesis_shards import kept_shard_folder
    from skinsynth.pipeline.synthesis import synthesize

    started = time.perf_counter()
    with (kept_shard_folder(shards["folder"]) if joined else contextlib.nullcontext()), \
            Progress(request.count, "synthesize", quiet) as bar:
        done = [0]

        def progress(finished):
            bar.update(finished - done[0], f"{finished}/{request.count} animations")
            done[0] = finished

        remote = on_cluster = None
        if joined:
            # a scheduler slow to answer is announced (pipeline/runtime/execution.py: Cluster.starting)
            on_cluster = joined(waiting=None if quiet else lambda text: click.echo(f"skinsynth: {text}", err=True))
            from skinsynth.pipeline.runtime.execution import Remote

            remote = Remote(on_cluster, shards["store"], shards["stored"])
            if on_cluster.dashboard and not quiet:
                click.echo(f"Dask dashboard: {on_cluster.dashboard}", err=True)
        result = synthesize(components, skin.rotations, skin.translations, skin.rest_vertices, skin.bone_indices,
                            skin.bone_weights, request, jobs=jobs, progress=progress, remote=remote)
    ran = None if on_cluster is None else (on_cluster.workers, on_cluster.dashboard)
    return result, remote, ran, time.perf_counter() - started


def _cluster_report(address, ran, remote, result, shards):
    """A cluster run's report (:func:`~skinsynth.pipeline.synthesis.cluster_summary`), once the old
    output's shards this one does not use are removed; None for a run here."""
    from skinsynth.formats.synthesis_shards import remove_unused_shards
    from skinsynth.pipeline.synthesis import cluster_summary

    if remote is None:
        return None
    kept = remove_unused_shards(shards["folder"], {handle for handle, _ in result.F.pieces}) is None
    return cluster_summary(address, *ran, remote, shards["folder"], kept)


def _cluster_starting(address, answer_timeout):
    return Cluster.starting(address, preload=("skinsynth.pipeline.synthesis.synthesis",),
                            answer_timeout=answer_timeout)
