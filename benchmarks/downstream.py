"""The commands that read a synthesis after a cluster run, against its size (issue 25).

On the real samba (``fit-skin --bones 22 --seed 0``, ``build-graph``, cached in --work), for each
count N: ``synthesize GRAPH -n N -m 600 --seed 0 --cluster local:2`` (shards made afresh), then,
on its output, each downstream command as a user runs it:

- ``inspect OUT -q`` (every check), ``inspect OUT --json``, ``inspect OUT --digests``;
- ``preview OUT --animation N-1 -o last.png``, ``export OUT --animation N-1 -o last.glb``;
- and the caches ``synthesize`` itself writes after the cluster's work, each in a run of its own
  at each of ``--cache-counts`` (smaller: they hold every animation's vertices on disk, 72 MB per
  600-frame samba animation): ``--usd DIR``, ``--exr DIR``, ``--crowd X.usdc``, ``--plot DIR``
  (``--plot-count`` N), peak memory against the count.

One JSON line per (N, command): wall time (median of --repeats) and peak resident memory
(sampled from /proc, as :func:`datasets.run` does), then one line extrapolating each command to
10⁶ animations: time linear in N through the two largest counts (a time that does not grow is
kept), memory as measured at the largest (flat when the command's memory is bounded). With --keep, each command's stdout is kept in
``WORK/stdout/LABEL_N_COMMAND.txt`` (compare two versions' outputs byte for byte).

Each 10⁴ × 600 output holds about 6.6 GB of shards: give --work a folder with room.

    python benchmarks/downstream.py [--work DIR] [--counts 1000,10000] [--cache-counts 8,32] [--frames 600]
                                    [--repeats 1] [--keep LABEL]
"""

import argparse
import json
import os
import shutil
import tempfile

from cluster import CAPTURE, folder_bytes, graph_of
from datasets import run

TARGET = 10 ** 6


def commands(out, last):
    """(name, arguments) of each downstream command on ``out``, whose last animation is ``last``."""
    folder = os.path.dirname(out)
    return [("inspect -q", ["inspect", out, "-q"]),
            ("inspect --json", ["inspect", out, "--json"]),
            ("inspect --digests", ["inspect", out, "--digests"]),
            ("preview --animation", ["preview", out, "--animation", str(last), "-o", os.path.join(folder, "last.png"),
                                     "-q"]),
            ("export --animation", ["export", out, "--animation", str(last), "-o", os.path.join(folder, "last.glb"),
                                    "-q"])]


def caches(folder, count):
    """(name, the options of ``synthesize``) of each cache it writes, into ``folder``."""
    return [("--usd", ["--usd", os.path.join(folder, "usd")]), ("--exr", ["--exr", os.path.join(folder, "exr")]),
            ("--crowd", ["--crowd", os.path.join(folder, "crowd.usdc")]),
            ("--plot", ["--plot", os.path.join(folder, "plots"), "--plot-count", str(count)])]


def measure_caches(graph, work, counts, frames):
    """Each cache of :func:`caches` at each count, written by ``synthesize --cluster local:2``:
    one JSON line each, then the peak memory per cache against the count."""
    peaks = {}
    for count in counts:
        folder = os.path.join(work, f"caches_n{count}")
        for name, options in caches(folder, count):
            shutil.rmtree(folder, ignore_errors=True)
            os.makedirs(folder)
            out = os.path.join(folder, "bones.h5")
            seconds, peak, worker, _ = run(["synthesize", graph, "-o", out, "-n", str(count), "-m", str(frames),
                                            "--seed", "0", "-q", "--cluster", "local:2", *options], work)
            written = sum(os.path.getsize(os.path.join(d, n)) for d, _, names in os.walk(folder) for n in names
                          if not d.endswith(".shards") and n != "bones.h5")
            peaks.setdefault(name, {})[count] = round(peak)
            print(json.dumps({"capture": CAPTURE, "case": "synthesize_caches", "count": count, "frames": frames,
                              "cache": name, "seconds": round(seconds, 2), "peak_mib": round(peak),
                              "largest_worker_peak_mib": round(worker), "cache_gb": round(written / 1e9, 2)}),
                  flush=True)
        shutil.rmtree(folder, ignore_errors=True)
    print(json.dumps({"capture": CAPTURE, "case": "synthesize_caches_memory", "frames": frames,
                      "peak_mib_by_count": peaks}), flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", default=None)
    parser.add_argument("--counts", default="1000,10000", help="Animation counts, comma-separated ('' for none).")
    parser.add_argument("--cache-counts", default="8,32",
                        help="Animation counts for synthesize's own caches, comma-separated ('' for none).")
    parser.add_argument("--frames", type=int, default=600)
    parser.add_argument("--repeats", type=int, default=1, help="Runs of each downstream command (median time).")
    parser.add_argument("--keep", default=None, metavar="LABEL", help="Keep each command's stdout, named LABEL.")
    args = parser.parse_args()
    counts = sorted(int(c) for c in args.counts.split(",") if c)
    work = args.work or tempfile.mkdtemp(prefix="skinsynth-downstream-")
    os.makedirs(work, exist_ok=True)
    graph = graph_of(work)
    measured = {}
    for count in counts:
        out = os.path.join(work, f"n{count}", "bones.h5")
        os.makedirs(os.path.dirname(out), exist_ok=True)
        shutil.rmtree(out + ".shards", ignore_errors=True)  # no reuse: every batch computed
        seconds, peak, _, _ = run(["synthesize", graph, "-o", out, "-n", str(count), "-m", str(args.frames),
                                   "--seed", "0", "-q", "--cluster", "local:2"], work)
        stored = folder_bytes(out + ".shards") + os.path.getsize(out)
        print(json.dumps({"capture": CAPTURE, "case": "downstream", "count": count, "frames": args.frames,
                          "command": "synthesize --cluster local:2", "seconds": round(seconds, 2),
                          "peak_mib": round(peak), "stored_gb": round(stored / 1e9, 2)}), flush=True)
        for name, arguments in commands(out, count - 1):
            runs = [run(arguments, work) for _ in range(args.repeats)]
            seconds = sorted(r[0] for r in runs)[len(runs) // 2]
            peak, stdout = max(r[1] for r in runs), runs[0][3]
            measured[(count, name)] = (seconds, peak)
            print(json.dumps({"capture": CAPTURE, "case": "downstream", "count": count, "frames": args.frames,
                              "command": name, "seconds": round(seconds, 2), "peak_mib": round(peak),
                              "repeats": args.repeats}), flush=True)
            if args.keep:
                kept = os.path.join(work, "stdout")
                os.makedirs(kept, exist_ok=True)
                text = stdout.replace(out, "OUT")  # the file's name is the only difference between runs
                with open(os.path.join(kept, f"{args.keep}_{count}_{name.replace(' ', '_')}.txt"), "w") as handle:
                    handle.write(text)
    if args.cache_counts:
        measure_caches(graph, work, sorted(int(c) for c in args.cache_counts.split(",")), args.frames)
    if len(counts) >= 2:
        small, large = counts[-2], counts[-1]
        table = {}
        for name, _ in commands("OUT", 0):
            (t0, m0), (t1, m1) = measured[(small, name)], measured[(large, name)]
            slope = max(0.0, (t1 - t0) / (large - small))  # a command whose time does not grow: its time
            table[name] = {"seconds_per_1000": round(1000 * slope, 3),
                           f"seconds_at_{TARGET}": round(t1 + slope * (TARGET - large)),
                           f"peak_mib_at_{small}": round(m0), f"peak_mib_at_{large}": round(m1)}
        print(json.dumps({"capture": CAPTURE, "case": "downstream_extrapolation", "frames": args.frames,
                          "from_counts": [small, large], "to_count": TARGET, "commands": table}), flush=True)


if __name__ == "__main__":
    main()
