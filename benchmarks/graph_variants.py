"""Motion graphs on resampled clips and clips with stills (issue 63): one JSON line per variant.

Each shared capture named (default: the samba, the crane and the horse gallop) is written again as
a user would bring it, and run through the command line at the defaults, as a user would:
``fit-skin --bones 22 --seed 0 --fps F``, ``build-graph``, ``synthesize -n 20 -m M --seed 3
--measure-feet 20 --json`` with M the frames of 25 s (600 at 24 fps: :data:`SECONDS`). The variants:

- ``fps12``: every other frame, declared 12 fps;
- ``fps24``: the clip as shared;
- ``fps48`` and ``fps96``: each pair of frames linearly in-betweened (1 and 3 frames between),
  declared 48 and 96 fps;
- ``stills``: 3 s held in the first pose before the clip and 2 s held at its middle frame (frame
  100 of a longer clip), at 24 fps;

and first the generated one-time event (``skinsynth example walker --event``: stands 2 s, walks,
stumbles once, runs off; 12 bones), with the frames build-graph names as reached one way only.

Printed per variant: the frames and the held poses build-graph found, per component the share of
the moving frames on the strongly connected part (``recurrent_share``), the median (and least)
distinct poses per animation (a held pose once) over the clip's moving poses, the stuck walks and
the worst acceleration over the input's (``synthesize --measure-feet``'s). The work folder keeps
every file, so a second run reuses the fits (``--fresh`` starts over).

    python benchmarks/graph_variants.py --work /tmp/variants [--only vlasic_samba|walker_event] [--variants fps48,stills]
"""

import argparse
import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
from datasets import shared_sequences

CAPTURES = ("vlasic_samba", "vlasic_crane", "horse_gallop")
VARIANTS = ("fps12", "fps24", "fps48", "fps96", "stills")
#: The animations' length: 600 frames at 24 fps, the same 25 s at any other rate (a share of the
#: clip's poses played is only comparable over the same time: 600 frames at 96 fps are 6 s).
SECONDS = 25.0


def in_between(vertices, factor):
    """vertices (F, V, 3) -> ((F − 1) · factor + 1, V, 3): ``factor − 1`` frames linearly between each pair."""
    weights = np.arange(factor) / factor
    pairs = vertices[:-1, None] * (1.0 - weights[None, :, None, None]) + vertices[1:, None] * weights[None, :, None, None]
    return np.concatenate([pairs.reshape(-1, *vertices.shape[1:]), vertices[-1:]])


def with_stills(vertices, fps=24, before=3.0, inside=2.0, at=100):
    """The clip with ``before`` s held in its first pose before it and ``inside`` s held at frame
    ``at`` (its middle frame where it is shorter)."""
    middle = min(at, vertices.shape[0] // 2)
    return np.concatenate([np.repeat(vertices[:1], int(before * fps), axis=0), vertices[:middle],
                           np.repeat(vertices[middle:middle + 1], int(inside * fps), axis=0), vertices[middle:]])


def variant(vertices, name):
    """(vertices, fps) of the variant ``name`` of a 24 fps clip."""
    if name == "fps12":
        return vertices[::2], 12
    if name == "fps24":
        return vertices, 24
    if name == "fps48":
        return in_between(vertices, 2), 48
    if name == "fps96":
        return in_between(vertices, 4), 96
    if name == "stills":
        return with_stills(vertices), 24
    raise SystemExit(f"unknown variant {name!r}; choose from {', '.join(VARIANTS)}")


def run(*args):
    done = subprocess.run([str(Path(sys.executable).parent / "skinsynth"), *map(str, args)], capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f"skinsynth {' '.join(map(str, args))} failed:\n{done.stderr}")
    return done.stdout


def measure(work, name, vertices, faces, fps, fresh, bones=22):
    clip, skin, graph, out = (work / f"{name}{suffix}" for suffix in (".npz", ".skin.h5", ".graph.h5", ".out.h5"))
    if fresh or not skin.exists():
        np.savez_compressed(clip, vertices=vertices.astype(np.float32), faces=faces)
        run("fit-skin", clip, "-o", skin, "--bones", bones, "--seed", 0, "--fps", fps, "-q")
    built = json.loads(run("build-graph", skin, "-o", graph, "--json").strip().splitlines()[-1])
    length = int(round(SECONDS * fps))
    summary = json.loads(run("synthesize", graph, "-o", out, "-n", 20, "-m", length, "--seed", 3, "--measure-feet", 20,
                             "--json").strip().splitlines()[-1])
    with h5py.File(graph, "r") as f:
        runs = np.asarray(f["graph"]["held_runs"]) if "held_runs" in f["graph"] else np.zeros((0, 2), np.int64)
        shares = [float(f["graph"][c].attrs["recurrent_share"]) for c in sorted(f["graph"]) if c.startswith("component_")]
    frames = int(vertices.shape[0])
    moving = frames - int(np.sum(runs[:, 1] - runs[:, 0])) if len(runs) else frames
    poses = summary.get("distinct_poses", summary["distinct_frames"])
    contact = summary.get("contact") or {}
    return {"frames": frames, "fps": fps, "animation_frames": length, "held_runs": runs.tolist(), "moving_poses": moving,
            "recurrent_share": [round(s, 3) for s in shares],
            "distinct_poses_median": [round(float(np.median(p)) / moving, 3) for p in poses],
            "distinct_poses_least": [round(float(np.min(p)) / moving, 3) for p in poses],
            "stuck": summary["stuck"], "worst_accel": (contact.get("ratios") or {}).get("largest_accel"),
            "one_way_frames": [_spans(c.get("one_way_frames", [])) for c in built["components"]],
            "transitions": summary["graph_transitions"], "seconds": summary["seconds"]}


def _spans(frames):
    """[[first, last], …] of sorted frame ids."""
    frames = np.asarray(frames, np.int64)
    if not frames.size:
        return []
    cuts = np.flatnonzero(np.diff(frames) != 1) + 1
    return [[int(r[0]), int(r[-1])] for r in np.split(frames, cuts)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", required=True, type=Path, help="folder for the variants' files (kept)")
    parser.add_argument("--only", help="one capture (default: " + ", ".join(CAPTURES) + ")")
    parser.add_argument("--variants", default=",".join(VARIANTS), help="comma-separated, of " + ", ".join(VARIANTS))
    parser.add_argument("--fresh", action="store_true", help="fit and build again even where the files exist")
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    if args.only in (None, "walker_event"):  # the generated one-time event: stands, walks, stumbles, runs off
        from skinsynth.pipeline.inputs.examples import walker_event

        vertices, faces = walker_event()
        line = {"dataset": "walker_event", "variant": "fps24",
                **measure(args.work, "walker_event", vertices, faces, 24, args.fresh, bones=12)}
        print(json.dumps(line), flush=True)
        if args.only:
            return
    names = [args.only] if args.only else list(CAPTURES)
    found = {name: (vertices, faces) for name, vertices, faces in shared_sequences() if name in names}
    for name in names:
        if name not in found:
            print(json.dumps({"dataset": name, "skipped": "not in ../shared/data"}), flush=True)
            continue
        vertices, faces = found[name]
        for label in args.variants.split(","):
            clip, fps = variant(np.asarray(vertices, np.float64), label)
            line = {"dataset": name, "variant": label, **measure(args.work, f"{name}_{label}", clip, faces, fps, args.fresh)}
            print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
