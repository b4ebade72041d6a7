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
import numpy as np

from .options import check_max_width, device_option, texture_options, up_axis_option
from .outputs import check_texture_output, write_gltf, write_textures
from .common import check_memory, check_space, report, summary_options, Progress, check_output_path, FolderOutputs, command_line, tool_version, user_errors


def _target(text):
    """``[CLIP:]FRAME@TIME`` -> (the frame's text, read once the clips are known; TIME)."""
    frame, sep, when = text.rpartition("@")
    try:
        if not sep or not frame.strip():
            raise ValueError
        return frame.strip(), int(when)
    except ValueError:
        raise click.BadParameter(f"{text!r}: expected [CLIP:]FRAME@TIME, e.g. 12@100 or gallop:12@100") from None


def _frames(clips, start, end, targets):
    """--start, --end and --target read against the clips: (start, end, [(frame, time)]), global
    frame numbers (None where not given); an unknown clip or a frame outside its clip is an
    OptionError naming the option."""
    start = None if start is None else clips.frame(start, "--start")
    end = None if end is None else clips.frame(end, "--end")
    return start, end, [(clips.frame(frame, "--target"), time) for frame, time in targets]


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
@click.option("--min-difference", default=0.0, show_default=True, type=float,
              help="Drop an animation that shares more than 1 − X of its frames (same input frame at the same time) with an earlier one.")
@click.option("--single-component", is_flag=True, help="Synthesise the whole rig as one component, ignoring cut nodes.")
@click.option("--min-segment", type=int, default=None,
              help="Shortest stretch (frames) a walk plays between two seams.  [default: the graph's, set by "
                   "build-graph: half a second]")
@click.option("--window", default=4, show_default=True, type=int,
              help="Frames blended on each side of a transition.")
@click.option("--blend", type=click.Choice(["bones", "key-vertices"]), default="bones", show_default=True,
              help="What a transition blends: each bone's rotation and pivot in the reference bone's frame (rigid "
                   "bones), or Zheng's deformation gradients at key vertices solved back to affine bones (eq. 8–9).")
@click.option("--alignment", type=click.Choice(["ground", "full"]), default="ground", show_default=True,
              help="How a segment is placed after a transition: turned about the up axis and shifted on the ground "
                   "(motion-graph practice: no drift off the ground, however long), or by Zheng's full rigid "
                   "transform (eq. 7), for clips that truly turn over (a swimmer, a cloth in the wind).")
@click.option("--cut-damping", default=1e-3, show_default=True, type=float,
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
@click.option("--measure-feet", "measure_feet", default=4, show_default=True, type=click.IntRange(min=0),
              metavar="N",
              help="Measure how well the feet stay planted (slide, float and penetration of the contact vertices, "
                   "worst acceleration; docs/contact.md) on the first N animations, skinned, and on the input; "
                   "reported in the summary and --json's \"contact\" (its own seconds, not in the run's). 0: skip. "
                   "It skins N whole animations: about 1.4 s each for 600 frames of 42,000 vertices on 2 cores.")
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
@summary_options
@user_errors
def synthesize(path, output, count, frames, seed, start_frame, end_frame, targets, obstacles, ground_plane,
               min_difference, single_component, min_segment, window, blend, alignment, cut_damping, spread_velocity, contact,
               measure_feet, usd_dir, crowd, gltf, root_motion, exr_dir, half,
               max_width, up_axis, plot_dir, plot_count, device, jobs, cluster, as_json, quiet):
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
    from skinsynth.formats.obstacles import read_obstacle
    from skinsynth.formats.model import write_model
    from skinsynth.formats.provenance import provenance_record
    from skinsynth.formats.synthesis_file import synthesis_groups
    from skinsynth.gpu import resolve_device
    from skinsynth.pipeline.inputs.clips import Clips
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.synthesis import (BATCH_REVISION, GraphOptions, Request, avoid_obstacles, default_min_segment,
                                              keep_input_plants, keep_input_support, synthesis_components,
                                              validate_request)

    if cluster is not None and not cluster.strip():
        raise OptionError("--cluster needs an address: tcp://HOST:PORT of a running scheduler, or local:N")
    check_output_path(output, (".h5", ".hdf5"), inputs=[path, *obstacles])
    if crowd is not None:
        check_output_path(crowd, (".usd", ".usda", ".usdc"), inputs=[path, *obstacles, output])
    if gltf is not None:
        check_output_path(gltf, (".glb",), inputs=[path, *obstacles, output])
    if root_motion and gltf is None:
        raise OptionError("--root-motion is for the --gltf output: give --gltf FILE.glb")
    from skinsynth.formats.synthesis_shards import run_shards, shard_folder

    folders = FolderOutputs([path, *obstacles], [output, crowd, gltf, usd_dir, exr_dir, plot_dir,
                                                 shard_folder(output) if cluster else None])
    for folder in (usd_dir, exr_dir, plot_dir):  # side folders: safe to write before any work
        folders.check(folder)
    if jobs is None:
        jobs = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if jobs < 1:
        raise OptionError(f"--jobs must be at least 1 (got {jobs})")
    if plot_count < 1:
        raise OptionError(f"--plot-count must be at least 1 (got {plot_count})")
    check_max_width(max_width)
    asked_device = device  # the feet are measured on it too (resolved then)
    device = resolve_device(device) if (usd_dir or crowd or exr_dir or plot_dir) else None
    # a cluster starts (local:N) or is reached in the background while the graph is read
    with (_cluster_starting(cluster) if cluster else contextlib.nullcontext()) as joined:
        graph_file = read_graph(path)
        skin = graph_file.skin
        if up_axis is None:
            up_axis = str(graph_file.options.get("up_axis", "Y"))
        if min_segment is None:
            min_segment = int(graph_file.options.get("min_segment", default_min_segment(skin.fps)))
        clips = Clips(skin.clip_names, skin.clip_frames)
        start_frame, end_frame, targets = _frames(clips, start_frame, end_frame, targets)
        # one clip: today's path exactly (no clip table handed down)
        request = Request(count=count, frames=frames, seed=seed, targets=list(targets), start=start_frame,
                          end=end_frame, min_difference=min_difference, window=window, spread_velocity=spread_velocity,
                          cut_damping=cut_damping, min_segment=min_segment, blend=blend, alignment=alignment,
                          up_axis=1 if up_axis == "Y" else 2, contact=contact,
                          clips=clips if len(clips) > 1 else None,
                          skeleton=None if skin.skeleton is None else tuple(skin.skeleton[k] for k in
                                                                            ("parents", "jointed", "joints")))
        validate_request(request, skin.rotations.shape[0])
        contacts = graph_file.contacts if graph_file.contacts is not None and graph_file.contacts.count else None
        if contact:
            keep_input_support(request, skin)
        # the bone motions (float32 3×3 + 3 per bone) and sources (int32 per component), in memory
        # (on a cluster, in the shards on disk): refused before any is allocated; then the output
        # file on its disk (a cluster run's, with its shards, once the reusable shards are known)
        motions = count * frames * (skin.rotations.shape[1] * 12 * 4 + len(graph_file.components) * 4)
        what = f"{count} animations × {frames} frames of {skin.rotations.shape[1]} bones"
        if not cluster:
            check_memory(motions, what)
        if exr_dir:  # the texture's size, before any work
            check_texture_output(exr_dir, "folder", skin.rest_vertices.shape[0], frames, max_width)
        if not cluster:
            _check_space(path, output, request, graph_file.components, skin, what)
        if obstacles or ground_plane:
            avoid_obstacles(request, skin, [read_obstacle(o) for o in obstacles], ground_plane)
        walk_clips = graph_file.graph.get("@clips")
        components = synthesis_components(skin, graph_file.components, single_component,
                                          GraphOptions.recorded(graph_file.options), request.clips,
                                          None if walk_clips is None else [str(n) for n in walk_clips],
                                          contacts=contacts if contact else None)
        if contact and contacts is not None:
            keep_input_plants(request, skin, contacts, components)

        parameters = dict(count=count, frames=frames, seed=seed, start_frame=start_frame, end_frame=end_frame,
                          targets=[list(t) for t in targets], obstacles=list(obstacles), ground_plane=ground_plane,
                          min_difference=min_difference, single_component=single_component, window=window,
                          spread_velocity=spread_velocity, cut_damping=cut_damping, min_segment=min_segment,
                          blend=blend, alignment=alignment, up_axis=up_axis, contact=contact)
        record = provenance_record("synthesis", command_line(), parameters, [path] + list(obstacles), tool_version(),
                                   seed)
        shards = run_shards(output, record, frames, skin.rotations.shape[1], BATCH_REVISION) if cluster else None
        if cluster:
            _check_space(path, output, request, components, skin, what, shards)

        started = time.perf_counter()
        result, remote, on_cluster = _make(components, skin, request, jobs, joined if cluster else None, shards,
                                           quiet or as_json)
        workers = on_cluster.workers if on_cluster is not None else None
        seconds = time.perf_counter() - started
    write_model(output, "synthesis",
                synthesis_groups(path, result, components, request, skin.fps,
                                 shards=os.path.basename(shards["folder"]) if shards else None),
                graph_file.provenance + [record], tool_version())
    written = [output]
    with _motions(output, result, remote) as motions:  # a cluster's motions are read back from the shards
        if usd_dir or crowd or exr_dir:
            written += _write_caches(skin, motions, usd_dir, crowd, exr_dir, up_axis, device, folders, threads=jobs,
                                     texture=dict(half=half, max_width=max_width))
        if gltf is not None:
            write_gltf(gltf, skin, ((f"animation_{a:04d}", motions.F[a], motions.t[a]) for a in range(count)),
                       up_axis, root_motion=root_motion, label=path, skeleton=skin.skeleton)
            written.append(gltf)
        if plot_dir is not None:
            written += _write_plots(plot_dir, skin, motions, min(plot_count, count), device, folders,
                                    request.clips)
        feet = None
        if measure_feet and count:
            feet = _measure_feet(skin, motions, clips, min(measure_feet, count), request.up_axis, device or asked_device)
    summary, lines = _summary(output, result, components, frames, min_segment, jobs, seconds, written)
    if feet is not None:
        summary["contact"], line = feet
        lines.append(line)
    if remote is not None:
        from skinsynth.formats.synthesis_shards import remove_unused_shards

        if remove_unused_shards(shards["folder"], {handle for handle, _ in result.F.pieces}) is None:
            lines.append("the old output's shards are kept: something still reads it (the next run removes them)")
        summary["cluster"] = {"address": cluster, "workers": workers, "tasks": remote.tasks,
                              "reused_batches": remote.reused, "retries": remote.retries,
                              "dashboard": on_cluster.dashboard, "shards": shards["folder"]}
        lines.append(f"cluster {cluster}: {workers} workers, {remote.tasks} tasks, {remote.retries} re-run after a "
                     f"lost worker, {remote.reused} batches reused; shards in {shards['folder']}")
    if len(written) > 1:
        lines.append(f"also wrote: {', '.join(written[1:]) if len(written) < 6 else written[1] + ' …'}")
    report(summary, lines, as_json, quiet)


def _check_space(path, output, request, components, skin, what, shards=None):
    """Refuse, before any work, an output larger than the free space of its folder, and on a
    cluster (``shards``: :func:`~skinsynth.formats.synthesis_shards.run_shards`'s) the shards
    still to write (those an earlier run finished are reused) against their folder's: the
    estimates the writers check at the end (``planned_bytes``), made from the request's shapes."""
    from skinsynth.formats.synthesis_file import planned_bytes
    from skinsynth.pipeline.synthesis import batch_sizes

    batches = None
    if shards is not None:  # the first round's batches, as synthesize makes them
        batches = [(b, n, (b, n) in shards["stored"]) for b, n in batch_sizes(request.count)]
    file_bytes, shard_bytes = planned_bytes(path, request, components, skin.rotations.shape[1], skin.fps, batches)
    needs = [("the output", file_bytes, os.path.dirname(os.path.abspath(output)))]
    if shards is not None:
        needs.append(("its shards", shard_bytes, shards["folder"]))
    check_space(what, needs)


def _make(components, skin, request, jobs, joined, shards, quiet):
    """Synthesise, here (``joined`` None) or on the cluster ``joined()`` returns, whose workers
    write their batches to the run's ``shards``, with a progress bar; (result, remote or None,
    cluster or None)."""
    from skinsynth.formats.synthesis_shards import kept_shard_folder
    from skinsynth.pipeline.synthesis import synthesize

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
    return result, remote, on_cluster


def _summary(output, result, components, frames, min_segment, jobs, seconds, written):
    """The command's summary (--json) and its text lines."""
    stats = result.statistics
    summary = {"animations": int(result.F.shape[0]), "frames": int(frames), "seconds": round(seconds, 3),
              "distinct": result.distinct, "transitions_used": int(np.sum(result.seams_used)),
              "components": len(components), "min_segment": int(min_segment), "jobs": int(jobs),
              "graph_transitions": [int(len(c.transitions.pairs)) for c in components],
              "transitions_used_per_component": stats["transitions"],
              "mean_segment_frames": [round(m, 2) for m in stats["mean_segment_frames"]],
              "shortest_segment": stats["shortest_segment"],
              "coverage": [round(c, 4) for c in stats["coverage"]],
              "rejected": result.rejected, "outputs": written}
    lines = [f"wrote {output}: {summary['animations']} animations × {frames} frames from {len(components)} "
             f"component(s), {result.distinct} distinct, {summary['transitions_used']} transitions used; "
             f"{seconds:.1f} s" + (f"; replaced {result.rejected}" if any(result.rejected.values()) else ""),
             f"segments: mean {', '.join(f'{m:.1f}' for m in stats['mean_segment_frames'])} frames, shortest "
             f"{', '.join(map(str, stats['shortest_segment']))} (≥ {min_segment} asked); input frames played: "
             f"{', '.join(f'{c:.0%}' for c in stats['coverage'])} (per component)"]
    if "coverage_per_clip" in stats:  # several clips: what each clip gave, and the way between them
        summary["coverage_per_clip"] = [{name: round(share, 4) for name, share in shares.items()}
                                        for shares in stats["coverage_per_clip"]]
        summary["transitions_between"] = [{pair: int(n) for pair, n in used.items()}
                                          for used in stats["transitions_between"]]
        for c, (shares, used) in enumerate(zip(stats["coverage_per_clip"], stats["transitions_between"])):
            played = ", ".join(f"{name} {share:.0%}" for name, share in shares.items())
            taken = ", ".join(f"{pair.replace('->', '→')} {n}" for pair, n in used.items() if n) or "none"
            lines.append(f"component {c}: frames played per clip {played}; transitions {taken}")
    return summary, lines


def _measure_feet(skin, motions, clips, count, up_axis, device):
    """The feet figures (docs/contact.md) of the input and the first ``count`` animations:
    (the --json "contact" object, one text line)."""
    from skinsynth.gpu import resolve_device
    from skinsynth.pipeline.synthesis import measure_feet

    started = time.perf_counter()
    figures = measure_feet(skin, motions.F, motions.t, motions.sources, clips.starts, count, up_axis,
                           resolve_device(device))
    figures["seconds"] = time.perf_counter() - started

    def plain(value):
        if isinstance(value, dict):
            return {k: plain(v) for k, v in value.items()}
        if isinstance(value, list):
            return [plain(v) for v in value]
        if isinstance(value, float):
            return float(f"{value:.6g}") if np.isfinite(value) else None
        return value

    figures = plain(figures)
    figures["seconds"] = round(figures["seconds"], 3)
    contact = {"animations": count, "definitions": "docs/contact.md", **figures}
    i, o, r = figures["input"], figures["output"], figures["ratios"]

    def share(side, key):
        return f"{side[key]:.2%}" if side.get(key) is not None else "n/a"

    accel = f"{r['largest_accel']:.2f}×" if r.get("largest_accel") is not None else "n/a"
    line = (f"feet (first {count} animations against the input, shares of the height; docs/contact.md): slide "
            f"median {share(o, 'slide_median')} (input {share(i, 'slide_median')}), 95th percentile "
            f"{share(o, 'slide_p95')} ({share(i, 'slide_p95')}), steps sliding over 0.5 % {share(o, 'sliding_share')} "
            f"({share(i, 'sliding_share')}); float p95 {share(o, 'float_p95')} ({share(i, 'float_p95')}), "
            f"penetration p95 {share(o, 'penetration_p95')} ({share(i, 'penetration_p95')}); "
            f"worst acceleration {accel} the input's")
    return contact, line


def _cluster_starting(address):
    from skinsynth.pipeline.runtime.execution import Cluster

    return Cluster.starting(address, preload=("skinsynth.pipeline.synthesis.synthesis",))


@contextlib.contextmanager
def _motions(output, result, remote):
    """``result``, with its bone motions readable by animation: as they are, or (a cluster run)
    the datasets of the written ``output``, read one animation at a time."""
    if remote is None:
        yield result
        return
    import dataclasses

    from skinsynth.formats.synthesis_file import open_motions

    with open_motions(output) as (F, t):
        yield dataclasses.replace(result, F=F, t=t)


def _write_plots(folder, skin, result, count, device, folders, clips=None):
    """One PNG per animation: sources per component and seams, max vertex acceleration / the
    input's (vertices baked with the skin's own weights). ``clips``: the input's several clips
    (None: one): seams by the clip-aware rule, and the input's largest acceleration measured
    inside each clip (never across the step from one clip's last frame to the next one's first)."""
    from skinsynth.formats.output_folder import atomic_folder
    from skinsynth.formats.plots import write_synthesis_plot
    from skinsynth.gpu import lbs
    from skinsynth.pipeline.mesh.geometry import frame_accelerations

    if clips is None:
        largest = np.nanmax(frame_accelerations(skin.examples))
    else:
        starts = clips.starts
        largest = max((np.nanmax(frame_accelerations(skin.examples[a:b])) for a, b in zip(starts[:-1], starts[1:])
                       if b - a >= 3), default=np.nan)
    written = []
    with atomic_folder(folder, **folders.guard(folder)) as tmp:
        for a in range(count):
            vertices = lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, result.F[a], result.t[a],
                           device=device)
            ratio = frame_accelerations(vertices) / largest
            name = f"animation_{a:04d}.png"
            mask = None if clips is None else clips.seams(result.sources[:, a])  # (C, M)
            seams = int(np.sum(result.sources[:, a, 1:] != result.sources[:, a, :-1] + 1)) if mask is None \
                else int(mask.sum())
            # no acceleration in an animation under 3 frames
            peak = f"{np.max(ratio[1:-1]):.2f}× the input's" if len(ratio) > 2 else "none (under 3 frames)"
            write_synthesis_plot(os.path.join(tmp, name), result.sources[:, a], ratio,
                                 f"animation {a}: {seams} seams, largest acceleration {peak}", seams=mask,
                                 clip_starts=None if clips is None else clips.starts)
            written.append(os.path.join(folder, name))
    return written


def _write_caches(skin, result, usd_dir, crowd, exr_dir, up_axis, device, folders, threads=1, texture=None):
    from skinsynth.pipeline.synthesis import SkinnedAnimations
    from skinsynth.pipeline.mesh.geometry import grid_offsets, largest_side

    count = result.F.shape[0]
    none = np.zeros((count, 3))
    written = []
    if usd_dir or exr_dir:
        from skinsynth.formats.output_folder import atomic_folder

        frames = SkinnedAnimations(skin, result.F, result.t, none, device, threads)
        usd_folder = atomic_folder(usd_dir, **folders.guard(usd_dir)) if usd_dir else contextlib.nullcontext()

        def each(usd_tmp):  # every animation skinned once, for both outputs
            from skinsynth.formats.usd import write_points_cache

            for a in range(count):
                vertices = frames[a]
                if usd_dir:
                    name = f"animation_{a:04d}.usdc"
                    write_points_cache(os.path.join(usd_tmp, name), vertices, skin.faces, skin.fps, up_axis=up_axis,
                                       scene=skin.scene)
                    written.append(os.path.join(usd_dir, name))
                yield f"animation_{a:04d}", vertices

        try:
            with usd_folder as usd_tmp:
                if exr_dir:
                    write_textures(exr_dir, "folder", skin.rest_vertices, skin.faces, each(usd_tmp), skin.fps,
                                   skin.scene, texture["half"], texture["max_width"], folders.guard(exr_dir))
                    written.append(exr_dir)
                else:
                    for _ in each(usd_tmp):
                        pass
        finally:
            frames.close()
    if crowd:
        from skinsynth.formats.usd import write_points_characters

        offsets = grid_offsets(count, 1.5 * largest_side(skin.rest_vertices), up_axis)
        characters = SkinnedAnimations(skin, result.F, result.t, offsets, device, threads)
        try:
            write_points_characters(crowd, characters, skin.faces, skin.fps,
                                    names=[f"animation_{a:04d}" for a in range(count)], up_axis=up_axis,
                                    scene=skin.scene)
        finally:
            characters.close()
        written.append(crowd)
    return written
