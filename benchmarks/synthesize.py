"""synthesize benchmark on the real captures: seams, drift, segments, coverage, speed, memory.

One JSON line per (capture, mode), mode = multi_component (build-graph's defaults) or
single_component (``--single-component``). Every figure comes from the command line as a user
runs it, with default options: ``fit-skin`` (cached in --work), ``build-graph``, then

- ``synthesize GRAPH -n 1000 -m 600 --seed 0 --measure-feet 0`` (the feet are measured here, below,
  by the same function), timed as the whole command (reading the graph
  and writing the result included), with the peak resident memory of its largest process and of
  the next largest (a worker; the shared result block counts in both);
- smoothness on baked vertices of the first 50 of those animations (LBS with the skin file's own
  weights, every vertex): per output frame the largest vertex acceleration
  ‖x(m+1) − 2x(m) + x(m−1)‖, over the input clip's largest (``worst_accel_ratio``; goal ≤ 1.5),
  the median of the per-frame largest over the input's median (``median_accel_ratio``), and the
  share of output frames above 1.5× the input's largest;
- components, transitions per component, mean segment length (output frames between seams of
  one component), coverage (the smallest share, over components, of input frames that the
  1,000 walks play; goal ≥ 0.9);
- shape (issue 62; docs/contact.md, ``pipeline/mesh/shape.py``): over the same first ``--feet``
  animations, on every capture, the share of broken frames (more than 0.5 % of their edges strained
  a quarter of their rest length past anything the capture and the fit's playback of it show), the
  worst frame's share of such edges, and the largest vertex acceleration over the input's;
- feet (issue 35 part 4; every definition in docs/contact.md and
  ``pipeline/mesh/contact_measures.py``): on the captures with a ground (``GROUNDED``) and the
  walker, the first ``--feet`` (16) of the 1,000 animations skinned and measured against the input
  by ``measure_feet``, the function behind ``synthesize --json``'s ``"contact"``: for the input and
  the output the slide of the contact vertices (median and 95th percentile per frame, over the
  height), the share of contact steps sliding over 0.5 % of the height, float and penetration
  during contact, the largest acceleration, and the output/input ratios (``contact``), and the
  same against the input frames replayed along the measured walks (``played``, ``ratios_played``:
  what synthesis adds at the frames it plays; docs/contact.md), and against the fit's own playback of
  the input (``fit``, ``ratios_fit``: what the rig itself holds; issue 64);
- ground drift: ``synthesize -n 3 -m 3000``; the lowest vertex of every frame against
  the input's range of lowest vertices, how far it goes below the input's lowest and above the
  input's highest lowest point, each as a share of the character's height (goal ≤ 0.01 each:
  ``lowest_below_input``, ``lowest_above_input``; ``ground_drift_over_height`` is the larger),
  the tilt of the whole mesh (the rotation of a best rigid fit to the rest pose: the angle
  between its image of the up axis and the up axis) against the input's largest tilt, in
  degrees.

Which shared captures have a ground (``GROUNDED``): vlasic_samba (a dancer on a floor), vlasic_crane
(the same performer's slow crane form, both feet on the floor most of the time), geomvideo_dance
(Zheng's own dancer, spinning on a floor),
horse_gallop, elephant_clips (the elephant's gallop; its key poses are no animation) and horse_clips
(the horse's gallop and its collapse onto the floor, fitted as one rig and walked together:
:func:`datasets.clip_sets`; the collapse alone is 53 frames that end lying down, a clip no walk
of 600 frames can play without looping its lying end): each rests on a floor in most frames. Not
dembones_bone (a bending limb whose lowest point wanders over 128 % of its height) nor
vellum_sheet (a falling cloth). ``--feet-only`` skips the smoothness bake and the long runs.

Besides the captures, ``walker`` (``skinsynth example walker``: an articulated figure whose legs
are components of their own) is measured too, and ``walker_planted`` (``example walker --planted``:
the same figure walking forward on feet that truly plant, its input's slide 0), the one whose feet
a synthesis must keep planted (the default walker's own feet slide 3.5 % of its height a frame), and
``walker_tempo`` (``--planted --frames 400 --cycles 4 --tempo 0.6``: a walk that gets going, from 0.4
to 1.6 times its mean speed, so that no two strides are alike, as in a captured walk), and
``walker_pivot`` (``--pivot``: the figure turning 180° on the ball of its left foot, its sole
sweeping round the ball, as a dancer's foot pivots). ``--synthesize-args`` adds options to every
``synthesize`` (e.g. ``--no-contact`` for a before/after table).

Built-in procedural stand-ins run only when ../shared/data is absent.

The command run is $SKINSYNTH when set (e.g. another checkout's, for a before/after table).

Issue 62's table: ``--count 20 --frames 600 --seed 3 --feet 20 --feet-only``.

    python benchmarks/synthesize.py [--only NAME] [--mode multi_component] [--count 1000] [--frames 600] [--seed 0]
                                    [--synthesize-args "--no-contact"] [--feet 16] [--feet-only]
"""

import argparse
import json
import os
import pathlib
import tempfile

import h5py
import numpy as np
from datasets import BONES, clip_sets, run, walker_inputs

UP = 1  # every capture in shared/data is Y up
#: Captures that rest on a ground (module notes): their feet are measured.
GROUNDED = {"vlasic_samba", "vlasic_crane", "horse_gallop", "elephant_clips", "horse_clips", "geomvideo_dance", "walker",
            "walker_planted", "walker_tempo", "walker_pivot"}


def bake(skin, F, t):
    """Vertices (M, V, 3) of one animation, skinned with the file's own weights (float64)."""
    from skinsynth.gpu import lbs

    return lbs(skin["rest"], skin["indices"], skin["weights"], F, t, device="cpu")


def frame_accel(vertices):
    """Largest vertex acceleration per frame 1..M−2: (M−2,)."""
    from skinsynth.pipeline.mesh.geometry import frame_accelerations

    return frame_accelerations(vertices)[1:-1]


def rigid_tilt(rest, frames, up=UP):
    """Per frame, degrees between the up axis and its image under the best rigid fit rest → frame."""
    a = rest - rest.mean(axis=0)
    b = frames - frames.mean(axis=1, keepdims=True)
    u, _, vt = np.linalg.svd(np.einsum("fvi,vj->fij", b, a))
    d = np.sign(np.linalg.det(u @ vt))
    u[:, :, -1] *= d[:, None]
    rotation = u @ vt
    return np.degrees(np.arccos(np.clip(rotation[:, up, up], -1.0, 1.0)))


def read_skin(path):
    with h5py.File(path, "r") as f:
        examples = f["examples/vertices"][()]
        frames = f["examples/clip_frames"][()] if "clip_frames" in f["examples"] else [examples.shape[0]]
        return {"rest": f["mesh/rest_vertices"][()], "indices": f["skin/bone_indices"][()],
                "weights": f["skin/bone_weights"][()], "examples": examples,
                "rotations": f["skin/rotations"][()], "translations": f["skin/translations"][()],
                "starts": np.concatenate([[0], np.cumsum(frames)]).astype(np.int64)}


def feet(skin, path, count):
    """``synthesize --json``'s "contact" figures (docs/contact.md) of the first ``count``
    animations of the synthesis at ``path``, rounded."""
    from types import SimpleNamespace

    from skinsynth.pipeline.synthesis import measure_feet

    arrays = SimpleNamespace(examples=skin["examples"], rest_vertices=skin["rest"], bone_indices=skin["indices"],
                             bone_weights=skin["weights"], rotations=skin["rotations"], translations=skin["translations"])
    with h5py.File(path, "r") as f:
        sources = f["synthesis/sources"][()]
        count = min(count, sources.shape[1])
        figures = measure_feet(arrays, f["synthesis/bone_matrices"], f["synthesis/bone_translations"], sources,
                               skin["starts"], count, UP, "cpu")

    def rounded(value):
        if isinstance(value, dict):
            return {k: rounded(v) for k, v in value.items()}
        return float(f"{value:.4g}") if isinstance(value, float) and np.isfinite(value) else value

    return {"animations": count, **{k: rounded(figures[k]) for k in ("input", "output", "ratios", "played", "ratios_played",
                                                                    "fit", "ratios_fit")}}


def shape(skin_path, path, count):
    """Issue 62's shape figures of the first ``count`` animations of the synthesis at ``path``
    (``synthesize --json``'s "shape": :func:`skinsynth.pipeline.synthesis.measure_shape`, frames whose
    edges strain far past the capture's and its fit's; docs/contact.md), and the largest vertex
    acceleration over them against the input's largest (``worst_accel``)."""
    from types import SimpleNamespace

    from skinsynth.pipeline.mesh.geometry import largest_acceleration
    from skinsynth.pipeline.synthesis import measure_shape

    with h5py.File(skin_path, "r") as f:
        skin = SimpleNamespace(examples=f["examples/vertices"][()], faces=f["mesh/faces"][()],
                               rest_vertices=f["mesh/rest_vertices"][()], bone_indices=f["skin/bone_indices"][()],
                               bone_weights=f["skin/bone_weights"][()], rotations=f["skin/rotations"][()],
                               translations=f["skin/translations"][()])
        frames = f["examples/clip_frames"][()] if "clip_frames" in f["examples"] else [skin.examples.shape[0]]
    starts = np.concatenate([[0], np.cumsum(frames)]).astype(np.int64)
    with h5py.File(path, "r") as f:
        F, t = f["synthesis/bone_matrices"], f["synthesis/bone_translations"]
        count = min(count, F.shape[0])
        figures = measure_shape(skin, F, t, count)
        worst = max(largest_acceleration(bake({"rest": skin.rest_vertices, "indices": skin.bone_indices,
                                                "weights": skin.bone_weights}, F[a], t[a])) for a in range(count))
    accel_in = largest_acceleration(skin.examples.astype(np.float64), starts)
    return {"animations": count, "broken_share": round(figures["broken_share"], 4),
            "worst_frame": round(figures["worst_frame"], 4), "worst_accel": round(float(worst / accel_in), 3)}


def walks(sources, graph_path, count):
    """Issue 48's walk figures over the first ``count`` animations, per component: the median and
    least number of distinct input frames an animation plays, over the frames on the largest
    strongly connected part of the graph (``distinct_over_recurrent``), and how many animations
    are stuck in a loop (:mod:`skinsynth.pipeline.synthesis.walk_measures`)."""
    from skinsynth.pipeline.synthesis.motion_graph import recurrent_frames
    from skinsynth.pipeline.synthesis.walk_measures import distinct_frames, stuck_walks

    with h5py.File(graph_path, "r") as f:
        fps = float(f["examples"].attrs.get("fps", 24.0))
        names = sorted(k for k in f["graph"] if k.startswith("component_"))
        frames = f["examples/vertices"].shape[0]
        clip_frames = f["examples/clip_frames"][()] if "clip_frames" in f["examples"] else None
        pairs = [f[f"graph/{k}/transitions"][()] for k in names]
    clips = None
    if clip_frames is not None and len(clip_frames) > 1:
        from skinsynth.pipeline.inputs.clips import Clips

        clips = Clips([str(c) for c in range(len(clip_frames))], [int(c) for c in clip_frames])
    out = {"distinct_median": [], "distinct_least": [], "distinct_over_recurrent": [], "stuck": [], "fps": fps}
    for c, p in enumerate(pairs):
        d = distinct_frames(sources[c, :count])
        recurrent = int(recurrent_frames(frames, p, clips).sum())
        out["distinct_median"].append(float(np.median(d)))
        out["distinct_least"].append(int(d.min()))
        out["distinct_over_recurrent"].append(round(float(np.median(d)) / recurrent, 3))
        out["stuck"].append(int(stuck_walks(sources[c, :count], fps).sum()))
    return out


def measure(name, spec, single, work, args):
    from skinsynth.pipeline.synthesis import walk_statistics
    from skinsynth.pipeline.synthesis.contact.ground import ground_excess, lowest_heights

    mode = "single_component" if single else "multi_component"
    skin_path = os.path.join(work, f"{name}.skin.h5")
    if not os.path.exists(skin_path):
        run(["fit-skin", *spec, "-o", skin_path, "--bones", str(BONES.get(name, 20)), "--seed", "0", "-q"], work)
    graph_path = os.path.join(work, f"{name}.{mode}.graph.h5")
    run(["build-graph", skin_path, "-o", graph_path, "-q"] + (["--single-component"] if single else []), work)
    with h5py.File(graph_path, "r") as f:
        names = sorted(k for k in f["graph"] if k.startswith("component_"))
        transitions = [int(f[f"graph/{k}/transitions"].shape[0]) for k in names]
    line = {"dataset": name, "mode": mode, "components": len(names), "transitions": transitions}
    out = os.path.join(work, f"{name}.{mode}.bones.h5")
    extra = args.synthesize_args.split()
    seconds, peak, worker, _ = run(["synthesize", graph_path, "-o", out, "-n", str(args.count), "-m",
                                    str(args.frames), "--seed", str(args.seed), "-q", "--measure-feet", "0", *extra],
                                   work)
    line.update(seconds=round(seconds, 2), peak_rss_mib=round(peak), peak_rss_second_process_mib=round(worker))
    skin = read_skin(skin_path)
    examples = skin["examples"]
    starts = skin["starts"]  # per clip: the step from one clip to the next is no motion
    accel_in = np.concatenate([frame_accel(examples[a:b]) for a, b in zip(starts[:-1], starts[1:])])
    with h5py.File(out, "r") as f:
        sources = f["synthesis/sources"][()]
        stats = walk_statistics(sources, examples.shape[0])
        line["transitions_used_per_animation"] = [round(s / sources.shape[1], 1) for s in stats["transitions"]]
        line["mean_segment_frames"] = [round(m, 1) for m in stats["mean_segment_frames"]]
        line["shortest_segment"] = stats["shortest_segment"]
        line["coverage"] = round(min(stats["coverage"]), 3)
        line["walks"] = walks(sources, graph_path, args.feet or 20)
    if name in GROUNDED and args.feet:
        line["contact"] = feet(skin, out, args.feet)
    if args.feet:
        line["shape"] = shape(skin_path, out, args.feet)
    with h5py.File(out, "r") as f:
        worst = []
        for a in range(0 if args.feet_only else min(args.smooth, sources.shape[1])):
            worst.append(frame_accel(bake(skin, f["synthesis/bone_matrices"][a], f["synthesis/bone_translations"][a])))
    if args.feet_only:
        os.remove(out)
        return line
    worst = np.concatenate(worst)
    line["worst_accel_ratio"] = round(float(worst.max() / accel_in.max()), 3)
    line["median_accel_ratio"] = round(float(np.median(worst) / np.median(accel_in)), 3)
    line["frames_over_1.5x"] = round(float(np.mean(worst > 1.5 * accel_in.max())), 4)
    os.remove(out)

    long_out = os.path.join(work, f"{name}.{mode}.long.h5")
    run(["synthesize", graph_path, "-o", long_out, "-n", str(args.long_count), "-m", str(args.long_frames),
         "--seed", "0", "-q", "--measure-feet", "0", *extra], work)
    low_in = examples[..., UP].min(axis=1)
    height = float(np.ptp(skin["rest"][:, UP]))
    subset = np.linspace(0, skin["rest"].shape[0] - 1, min(2000, skin["rest"].shape[0])).astype(int)
    tilt_in = rigid_tilt(skin["rest"][subset], examples[:, subset])
    below, above, tilt_excess = 0.0, 0.0, 0.0
    with h5py.File(long_out, "r") as f:
        for a in range(f["synthesis/sources"].shape[1]):
            v = bake(skin, f["synthesis/bone_matrices"][a], f["synthesis/bone_translations"][a])
            b, u = ground_excess(lowest_heights(v, UP), low_in, height)
            below, above = max(below, b), max(above, u)
            tilt_excess = max(tilt_excess, float(rigid_tilt(skin["rest"][subset], v[:, subset]).max() - tilt_in.max()))
    os.remove(long_out)
    line["lowest_below_input"], line["lowest_above_input"] = round(below, 4), round(above, 4)
    line["ground_drift_over_height"] = round(max(below, above), 4)
    line["tilt_beyond_input_deg"] = round(max(tilt_excess, 0.0), 2)
    line["long_animations"] = f"{args.long_count} x {args.long_frames}"
    return line


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only")
    parser.add_argument("--mode", choices=["multi_component", "single_component"])
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0, help="synthesize --seed of the main run")
    parser.add_argument("--frames", type=int, default=600)
    parser.add_argument("--smooth", type=int, default=50, help="animations whose vertices are baked")
    parser.add_argument("--long-count", type=int, default=3)
    parser.add_argument("--long-frames", type=int, default=3000)
    parser.add_argument("--work", default=None, help="folder kept between runs (skin fits are reused)")
    parser.add_argument("--feet", type=int, default=16, help="animations whose feet are measured (0: none)")
    parser.add_argument("--feet-only", action="store_true", help="skip the smoothness bake and the long runs")
    parser.add_argument("--synthesize-args", default="", help="more options for every synthesize")
    args = parser.parse_args()
    work = args.work or tempfile.mkdtemp(prefix="skinsynth_bench_")
    os.makedirs(work, exist_ok=True)
    work = str(pathlib.Path(work).resolve())
    for name, spec in list(clip_sets(work)) + [(n, [p]) for n, p in walker_inputs(work, only=args.only)]:
        if args.only and args.only != name:
            continue
        for single in (False, True):
            mode = "single_component" if single else "multi_component"
            if args.mode and args.mode != mode:
                continue
            try:
                line = measure(name, spec, single, work, args)
            except RuntimeError as error:
                line = {"dataset": name, "mode": mode, "error": str(error)}
            print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
