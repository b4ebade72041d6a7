"""Several clips of one character (issue 26) on the shared clip folders: one JSON line per figure.

Every figure comes from the command line as a user runs it (``datasets.run``: wall time of the
whole command and the peak resident memory of its largest process).

- ``joint_fit`` (horse gallop + collapse, 22 bones): ``fit-skin gallop collapse``, against each
  clip fitted alone with the same bones: per clip the RMSE over the diagonal of the rest pose of
  the joint fit and alone, their ratio (goal ≤ 1.1), and the seconds of the joint fit against
  the two alone together; and the ratio per clip of joint fits with 33 and 44 bones against the
  clips alone at 22 (one rig shares its bones between the clips).
- ``rig``: ``fit-skin collapse --rig gallop.h5`` (the collapse on the gallop's rig) against a full
  fit of the collapse: RMSE over the diagonal and seconds. Also the poses on the joint rig.
- ``synthesis`` (the two-clip graph): ``build-graph`` then ``synthesize -n 1000 -m 600``: the
  graph's transitions per direction, the transitions the walks use per direction, coverage per
  clip, and on the first 50 animations baked (LBS, every vertex) the largest vertex acceleration
  against the input's largest within a clip (a clip's end is not followed by the next clip's
  start, so no acceleration is measured across it; goal ≤ 1.5).
- ``start_end``: ``synthesize --start gallop:0 --end collapse:52 -n 16 -m 600``: how many
  animations begin on gallop:0, end on collapse:52, and the clips each one visits in order.
- ``elephant`` (gallop + poses, 42,321 vertices; the largest mesh in ../shared/data): the joint
  fit, build-graph and ``synthesize -n 1000 -m 600``, seconds and peak memory of each.
- ``elephant_stages``: select-controls, train-kcca, evaluate, play (16 characters driven by the
  gallop's own control vertices), export (.usdc, .glb), preview and inspect on the elephant: seconds
  and peak memory of each.
- ``hold_out``: ``select-controls``, ``train-kcca`` on the gallop, ``evaluate --hold-out-clip
  collapse``: KCCA's error against the baselines' on a clip it never saw.

    python benchmarks/clips.py [--work DIR] [--only joint_fit,rig,synthesis,start_end,elephant,hold_out]
"""

import argparse
import json
import os
import tempfile

import h5py
import numpy as np
from datasets import SHARED_DATA, run

HORSE = SHARED_DATA / "horse_clips"
ELEPHANT = SHARED_DATA / "elephant_clips"
BONES = 22
MORE_BONES = (33, 44)
PARTS = ("joint_fit", "rig", "synthesis", "start_end", "elephant", "elephant_stages", "hold_out")


def fit(work, out, *inputs, extra=()):
    """Run fit-skin; (seconds, peak MiB, summary)."""
    seconds, peak, _, stdout = run(["fit-skin", *map(str, inputs), "-o", out, "--json", *extra], work)
    return seconds, peak, json.loads(stdout)


def joint_fit(work):
    gallop, collapse = HORSE / "horse_gallop.npz", HORSE / "horse_collapse.npz"
    seconds, peak, joint = fit(work, "horse_joint.h5", gallop, collapse, extra=["--bones", str(BONES)])
    line = {"figure": "joint_fit", "capture": "horse gallop + collapse", "bones": BONES,
            "joint_seconds": round(seconds, 2), "joint_peak_rss_mib": round(peak)}
    alone_seconds = 0.0
    for clip, path in zip(joint["clips"], (gallop, collapse)):
        s, _, alone = fit(work, f"horse_{clip['name']}.h5", path, extra=["--bones", str(BONES)])
        alone_seconds += s
        # both over the joint file's diagonal (the rest pose of the gallop's frame 0 in both)
        alone_rmse = alone["rmse"] / joint["rmse"] * joint["rmse_over_diagonal"]
        line[clip["name"]] = {"alone_rmse": alone["rmse"],
                              "joint_rmse_over_diagonal": round(clip["rmse_over_diagonal"], 6),
                              "alone_rmse_over_diagonal": round(alone_rmse, 6),
                              "ratio": round(clip["rmse_over_diagonal"] / alone_rmse, 3),
                              "alone_seconds": round(s, 2)}
    line["alone_seconds_total"] = round(alone_seconds, 2)
    # one rig shares its bones between the clips: how many it needs to match each clip alone at BONES
    for bones in MORE_BONES:
        _, _, more = fit(work, f"horse_joint_{bones}.h5", gallop, collapse, extra=["--bones", str(bones)])
        line[f"joint_{bones}_bones_ratio"] = {c["name"]: round(c["rmse"] / line[c["name"]]["alone_rmse"], 3)
                                              for c in more["clips"]}
    return line


def rig(work):
    if not os.path.exists(os.path.join(work, "horse_gallop.h5")):
        joint_fit(work)
    collapse = HORSE / "horse_collapse.npz"
    s_rig, peak, on_rig = fit(work, "collapse_on_gallop_rig.h5", collapse, extra=["--rig", "horse_gallop.h5"])
    s_full, _, full = fit(work, "horse_collapse.h5", collapse, extra=["--bones", str(BONES)])
    s_poses, _, poses = fit(work, "poses_on_joint_rig.h5", HORSE / "horse_poses.npz", extra=["--rig", "horse_joint.h5"])
    s_poses_full, _, poses_full = fit(work, "poses_full.h5", HORSE / "horse_poses.npz", extra=["--bones", str(BONES)])
    return {"figure": "rig", "collapse_on_gallop_rig": {"rmse_over_diagonal": round(on_rig["rmse_over_diagonal"], 6),
                                                       "seconds": round(s_rig, 2), "peak_rss_mib": round(peak),
                                                       "iterations": on_rig["iterations"]},
            "collapse_full_fit": {"rmse_over_diagonal": round(full["rmse_over_diagonal"], 6),
                                  "seconds": round(s_full, 2)},
            "rmse_ratio": round(on_rig["rmse_over_diagonal"] / full["rmse_over_diagonal"], 2),
            "poses_on_joint_rig": {"rmse_over_diagonal": round(poses["rmse_over_diagonal"], 6),
                                   "seconds": round(s_poses, 2)},
            "poses_full_fit": {"rmse_over_diagonal": round(poses_full["rmse_over_diagonal"], 6),
                               "seconds": round(s_poses_full, 2)}}


def bake(rest, indices, weights, F, t):
    """Vertices (M, V, 3) of one animation's bones (the skin's own LBS)."""
    moved = np.einsum("mvkab,vb->mvka", F[:, indices], rest) + t[:, indices]
    return np.einsum("mvka,vk->mva", moved, weights)


def clip_accel_max(examples, frames, animated=None):
    """The input's largest vertex acceleration within any clip (``animated``: only these clips,
    by position: a clip of unrelated key poses has no acceleration worth the name)."""
    from skinsynth.pipeline.mesh.geometry import frame_accelerations

    starts = np.concatenate([[0], np.cumsum(frames)])
    return max(float(frame_accelerations(examples[a:b])[1:-1].max())
               for c, (a, b) in enumerate(zip(starts[:-1], starts[1:]))
               if b - a >= 3 and (animated is None or c in animated))


def synthesis(work, skin="horse_joint.h5", name="horse", smooth=50, animated=None, graph_args=()):
    from skinsynth.pipeline.inputs.clips import Clips
    from skinsynth.pipeline.synthesis import walk_statistics

    if not os.path.exists(os.path.join(work, skin)):
        joint_fit(work)
    graph = f"{name}_joint.graph.h5"
    s_graph, p_graph, _, out = run(["build-graph", skin, "-o", graph, "--json", *graph_args], work)
    built = json.loads(out)
    seconds, peak, second, out = run(["synthesize", graph, "-o", f"{name}_joint.bones.h5", "-n", "1000", "-m", "600",
                                      "--seed", "0", "--json"], work)
    summary = json.loads(out)
    line = {"figure": "synthesis", "capture": name, "build_graph_seconds": round(s_graph, 2),
            "build_graph_peak_rss_mib": round(p_graph), "synthesize_seconds": round(seconds, 2),
            "synthesize_peak_rss_mib": round(peak), "synthesize_second_process_mib": round(second),
            "graph_transitions_between": built.get("transitions_between"),
            "components": len(built.get("components", [])) or built.get("component_count")}
    with h5py.File(os.path.join(work, skin), "r") as f:
        rest, indices, weights = f["mesh/rest_vertices"][()], f["skin/bone_indices"][()], f["skin/bone_weights"][()]
        examples = f["examples/vertices"][()]
        clips = Clips(tuple(str(n) for n in f["examples"].attrs["clip_names"]), tuple(f["examples/clip_frames"][()]))
    with h5py.File(os.path.join(work, f"{name}_joint.bones.h5"), "r") as f:
        sources = f["synthesis/sources"][()]
        stats = walk_statistics(sources, clips.total, clips)
        line["transitions_used_between"] = stats.get("transitions_between")
        line["coverage_per_clip"] = stats.get("coverage_per_clip")
        line["coverage"] = [round(c, 3) for c in stats["coverage"]]
        worst = []
        for a in range(min(smooth, sources.shape[1])):
            v = bake(rest, indices, weights, f["synthesis/bone_matrices"][a], f["synthesis/bone_translations"][a])
            from skinsynth.pipeline.mesh.geometry import frame_accelerations

            worst.append(frame_accelerations(v)[1:-1])
    line["worst_accel_ratio"] = round(float(np.concatenate(worst).max()
                                            / clip_accel_max(examples, clips.frames, animated)), 3)
    line["accel_reference"] = "every clip" if animated is None else [clips.names[c] for c in animated]
    line["summary_coverage_per_clip"] = summary.get("coverage_per_clip")
    os.remove(os.path.join(work, f"{name}_joint.bones.h5"))
    return line


def start_end(work):
    from skinsynth.pipeline.inputs.clips import Clips

    graph = "horse_joint.graph.h5"
    if not os.path.exists(os.path.join(work, graph)):
        synthesis(work)
    out = "horse_start_end.bones.h5"
    seconds, _, _, _ = run(["synthesize", graph, "-o", out, "-n", "16", "-m", "600", "--seed", "0", "-q",
                            "--start", "gallop:0", "--end", "collapse:52"], work)
    with h5py.File(os.path.join(work, out), "r") as f:
        sources = f["synthesis/sources"][()]  # (C, N, M)
        clips = Clips(tuple(str(n) for n in f["examples"].attrs["clip_names"]), tuple(f["examples/clip_frames"][()]))
    first, last = clips.frame("gallop:0"), clips.frame("collapse:52")
    visits = []
    for walk in sources[0]:
        order = clips.clip_of(walk)
        changes = np.concatenate([[0], np.flatnonzero(np.diff(order)) + 1])
        visits.append(" ".join(clips.names[c] for c in order[changes]))
    return {"figure": "start_end", "seconds": round(seconds, 2),
            "start_on_gallop_0": int(np.all(sources[:, :, 0] == first, axis=0).sum()),
            "end_on_collapse_52": int(np.all(sources[:, :, -1] == last, axis=0).sum()), "animations": 16,
            "clip_order_per_animation_component_0": visits}


def elephant(work):
    s_fit, p_fit, joint = fit(work, "elephant_joint.h5", ELEPHANT / "elephant_gallop.npz",
                              ELEPHANT / "elephant_poses.npz", extra=["--bones", str(BONES)])
    # the poses clip is 10 unrelated key poses: its "playback" jumps are no motion to compare with
    line = synthesis(work, "elephant_joint.h5", "elephant", smooth=10, animated=[0])
    line.update(figure="elephant", fit_seconds=round(s_fit, 2), fit_peak_rss_mib=round(p_fit),
                clips={c["name"]: round(c["rmse_over_diagonal"], 6) for c in joint["clips"]})
    # the same rig, walks on the gallop only (build-graph --clips gallop): the poses left out
    gallop_only = synthesis(work, "elephant_joint.h5", "elephant_gallop_only", smooth=10, animated=[0],
                            graph_args=["--clips", "gallop"])
    line["walks_on_gallop_only"] = {k: gallop_only[k] for k in ("worst_accel_ratio", "synthesize_seconds",
                                                                "synthesize_peak_rss_mib", "coverage_per_clip")}
    return line


def elephant_stages(work):
    """Every other stage on the elephant (42,321 vertices, the largest mesh here): seconds and
    peak MiB of each command, from the joint fit of :func:`elephant`."""
    if not os.path.exists(os.path.join(work, "elephant_joint.h5")):
        elephant(work)
    gallop = str(ELEPHANT / "elephant_gallop.npz")
    commands = {
        "select-controls": ["select-controls", "elephant_joint.h5", "-o", "elephant.controls.h5"],
        "train-kcca": ["train-kcca", "elephant.controls.h5", "-o", "elephant.puppet.h5"],
        "evaluate": ["evaluate", "elephant.puppet.h5", "--json"],
        "play 16 x 48 (.usdc crowd)": ["play", "elephant.puppet.h5", "--controls", gallop, "--instances", "16", "-o",
                                       "elephant_crowd.usdc"],
        "export .usdc (skel)": ["export", "elephant_joint.h5", "-o", "elephant.usdc"],
        "export .glb (2 clips)": ["export", "elephant_joint.h5", "-o", "elephant.glb"],
        "preview .png": ["preview", "elephant_joint.h5", "-o", "elephant.png"],
        "inspect --digests": ["inspect", "elephant_joint.h5", "--digests", "-q"],
    }
    line = {"figure": "elephant_stages"}
    for name, args in commands.items():
        seconds, peak, _, _ = run(args + (["-q"] if "--json" not in args and "-q" not in args else []), work)
        line[name] = {"seconds": round(seconds, 2), "peak_rss_mib": round(peak)}
    return line


def hold_out(work):
    if not os.path.exists(os.path.join(work, "horse_joint.h5")):
        joint_fit(work)
    run(["select-controls", "horse_joint.h5", "-o", "horse_joint.controls.h5", "-q"], work)
    run(["train-kcca", "horse_joint.controls.h5", "-o", "horse_joint.puppet.h5", "-q"], work)
    seconds, _, _, out = run(["evaluate", "horse_joint.puppet.h5", "--hold-out-clip", "collapse", "--json"], work)
    report = json.loads(out)
    errors = ("kcca", "kcca_no_translation_solver", "pca_blendshape", "rbf")
    held = report["clip_hold_out"]
    return {"figure": "hold_out", "seconds": round(seconds, 2),
            "clip_hold_out": {**{k: round(held[k], 4) for k in errors}, "train_clips": held["train_clips"],
                              "test_clips": held["test_clips"], "train_frames": len(held["train_frames"]),
                              "test_frames": len(held["test_frames"])},
            "frame_hold_out": {**{k: round(report[k], 4) for k in errors}, "train_frames": len(report["train_frames"]),
                               "test_frames": len(report["test_frames"])}}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", default=None, help="Folder for the files (default: a temporary one).")
    parser.add_argument("--only", default=",".join(PARTS), help="Comma-separated figures to measure.")
    args = parser.parse_args()
    if not HORSE.is_dir() or not ELEPHANT.is_dir():
        print(json.dumps({"figure": "clips", "skipped": f"no clip folders under {SHARED_DATA}"}))
        return
    work = args.work or tempfile.mkdtemp(prefix="skinsynth_clips_")
    os.makedirs(work, exist_ok=True)
    for part in args.only.split(","):
        print(json.dumps(globals()[part](work)), flush=True)


if __name__ == "__main__":
    main()
