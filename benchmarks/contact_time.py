"""What keeping the feet planted costs: ``synthesize -n 1000 -m 600`` with contacts against
``--no-contact``, side by side (issue 35: at most 1.1× on the samba, the elephant gallop and the
walker; issue 48: at most 1.15× and 10 s on every shared capture with a ground, the walkers too).

One JSON line per capture. Each capture is fitted and analysed with the defaults (cached in
--work, the same files as benchmarks/synthesize.py's), then ``synthesize GRAPH -n 1000 -m 600
--seed 0 --measure-feet 0`` is run ``--pairs`` times with contacts and as many times with
``--no-contact``, alternating (so a slower minute of the machine falls on both), each timed as the
whole command (reading the graph and writing the result included). Reported: every time, and the
ratio of the fastest runs (``ratio_best``: a timing's noise only ever adds, so the fastest of
several is the closest to the work itself) and of the medians (``ratio_median``). One run of this
machine's two cores varies by ±10 %: two pairs cannot tell 1.1× from 1.2×.

    python benchmarks/contact_time.py [--only NAME] [--pairs 5] [--work DIR]

(issue 48's figures: ``--pairs 3``, the median.)
"""

import argparse
import json
import os
import pathlib
import statistics
import tempfile

from datasets import BONES, clip_sets, run, walker_inputs

#: The captures timed: every shared capture with a ground (benchmarks/synthesize.py's GROUNDED) and the
#: walkers (``skinsynth example walker``, and ``--planted``).
TIMED = ("vlasic_samba", "vlasic_crane", "horse_gallop", "elephant_clips", "horse_clips", "walker", "walker_planted")


def timed_pairs(graph, work, pairs, count, frames):
    """([seconds with contacts], [seconds with --no-contact]), alternating."""
    out = os.path.join(work, "contact_time.bones.h5")
    times = {"": [], "--no-contact": []}
    for _ in range(pairs):
        for extra in times:
            seconds = run(["synthesize", graph, "-o", out, "-n", str(count), "-m", str(frames), "--seed", "0", "-q",
                           "--measure-feet", "0", *([extra] if extra else [])], work)[0]
            times[extra].append(round(seconds, 3))
    os.remove(out)
    return times[""], times["--no-contact"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only")
    parser.add_argument("--pairs", type=int, default=5)
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--frames", type=int, default=600)
    parser.add_argument("--work", default=None, help="folder kept between runs (skin fits are reused)")
    args = parser.parse_args()
    work = str(pathlib.Path(args.work or tempfile.mkdtemp(prefix="skinsynth_bench_")).resolve())
    os.makedirs(work, exist_ok=True)
    specs = dict(clip_sets(work))
    specs.update((n, [p]) for n, p in walker_inputs(work, ("walker", "walker_planted"), args.only))
    for name in TIMED:
        if (args.only and args.only != name) or name not in specs:
            continue
        skin = os.path.join(work, f"{name}.skin.h5")
        if not os.path.exists(skin):
            run(["fit-skin", *specs[name], "-o", skin, "--bones", str(BONES.get(name, 20)), "--seed", "0", "-q"], work)
        graph = os.path.join(work, f"{name}.multi_component.graph.h5")
        run(["build-graph", skin, "-o", graph, "-q"], work)
        contact, plain = timed_pairs(graph, work, args.pairs, args.count, args.frames)
        print(json.dumps({"dataset": name, "animations": f"{args.count} x {args.frames}", "contact_seconds": contact,
                          "no_contact_seconds": plain, "ratio_best": round(min(contact) / min(plain), 3),
                          "ratio_median": round(statistics.median(contact) / statistics.median(plain), 3)}),
              flush=True)


if __name__ == "__main__":
    main()
