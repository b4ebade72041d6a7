"""synthesize on a Dask cluster against one machine, on the real samba (issue 14).

Every figure comes from the command line as a user runs it (``fit-skin`` and ``build-graph``
with default options, cached in --work), ``synthesize GRAPH -n 1000 -m 600 --seed 0``:

- ``--jobs 2`` and ``--cluster local:2`` alternately, ``--repeats`` times each, wall time of the
  whole command (median; this machine's timings swing), and whether every dataset and attribute
  of the two outputs is byte-identical;
- a cluster started the way several machines would start one (``dask scheduler`` and two
  ``dask worker`` processes, each standing for a machine), one worker killed outright (SIGKILL
  of its process group) mid-run once the first shard exists: the same datasets, and the
  retries the command reports;
- the measured throughput and output size per animation, and from them the sizing table of
  docs/cluster.md (10⁴, 10⁵, 10⁶ animations × 600 frames; hours at 2 (this machine), 16, 64 and 256 worker cores;
  storage), for the samba's bones and scaled to a 27-bone rig (bytes and work are linear in bones).

One JSON line per measurement.

    python benchmarks/cluster.py [--work DIR] [--repeats 3] [--count 1000] [--frames 600]
"""

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import h5py
from datasets import BONES, captures, run

from skinsynth.formats.model import content_digests as contents

CAPTURE = "vlasic_samba"
WORKERS = (2, 16, 64, 256)  # this machine's cores, and clusters


def folder_bytes(folder):
    return sum(os.path.getsize(os.path.join(folder, n)) for n in os.listdir(folder))


def graph_of(work):
    spec = dict(captures(work)).get(CAPTURE)
    if spec is None:
        raise SystemExit(json.dumps({"skipped": f"{CAPTURE} is not in ../shared/data"}))
    skin = os.path.join(work, f"{CAPTURE}.skin.h5")
    graph = os.path.join(work, f"{CAPTURE}.graph.h5")
    if not os.path.exists(skin):
        run(["fit-skin", spec, "-o", skin, "--bones", str(BONES[CAPTURE]), "--seed", "0", "-q"], work)
    if not os.path.exists(graph):
        run(["build-graph", skin, "-o", graph, "-q"], work)
    return graph


def synthesize(graph, out, work, args, *where):
    seconds, _, _, stdout = run(["synthesize", graph, "-o", out, "-n", str(args.count), "-m", str(args.frames),
                                 "--seed", "0", "--json", *where], work)
    return seconds, json.loads(stdout)


def dask_command(name):
    return [os.path.join(os.path.dirname(sys.executable), "dask"), name]


def killed_worker_run(graph, work, args, reference):
    """A scheduler and two workers started as on separate machines; one killed mid-run."""
    scheduler_file = os.path.join(work, "scheduler.json")
    if os.path.exists(scheduler_file):
        os.remove(scheduler_file)
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    scheduler = subprocess.Popen(dask_command("scheduler") + ["--scheduler-file", scheduler_file, "--port", "0",
                                                              "--dashboard-address", ":0"], **quiet)
    workers = []
    try:
        while not os.path.exists(scheduler_file):
            time.sleep(0.1)
        time.sleep(0.5)
        with open(scheduler_file) as handle:
            address = json.load(handle)["address"]
        workers = [subprocess.Popen(dask_command("worker") + ["--scheduler-file", scheduler_file, "--nthreads", "1"],
                                    **quiet) for _ in range(2)]
        out = os.path.join(work, "killed.h5")
        shards = os.path.join(work, "killed.shards")
        shutil.rmtree(shards, ignore_errors=True)
        exe = shutil.which("skinsynth", path=os.path.dirname(sys.executable))
        started = time.perf_counter()
        command = subprocess.Popen([exe, "synthesize", graph, "-o", out, "-n", str(args.count), "-m", str(args.frames),
                                    "--seed", "0", "--json", "--cluster", address], cwd=work,
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        killed_at = None
        while command.poll() is None:
            if killed_at is None and os.path.isdir(shards) and any(n.startswith("batch_") for n in os.listdir(shards)):
                os.killpg(workers[0].pid, signal.SIGKILL)  # a machine lost: nanny, worker and all
                killed_at = time.perf_counter() - started
            time.sleep(0.05)
        stdout, stderr = command.communicate()
        if command.returncode != 0:
            raise RuntimeError(f"synthesize on the cluster failed: {stderr.strip()[-800:]}")
        summary = json.loads(stdout)
        return {"capture": CAPTURE, "case": "worker_killed", "killed_after_s": round(killed_at or -1, 2),
                "seconds": round(time.perf_counter() - started, 2), "retries": summary["cluster"]["retries"],
                "workers_at_end": summary["cluster"]["workers"], "tasks": summary["cluster"]["tasks"],
                "identical_to_jobs_2": contents(out) == reference}
    finally:
        for process in workers + [scheduler]:
            try:
                os.killpg(process.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
            process.wait()


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", default=None)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--frames", type=int, default=600)
    args = parser.parse_args()
    work = args.work or tempfile.mkdtemp(prefix="skinsynth-cluster-")
    os.makedirs(work, exist_ok=True)
    graph = graph_of(work)
    local, cluster = os.path.join(work, "jobs2.h5"), os.path.join(work, "local2.h5")
    times = {"jobs_2": [], "local_2": []}
    for _ in range(args.repeats):
        seconds, _ = synthesize(graph, local, work, args, "--jobs", "2")
        times["jobs_2"].append(round(seconds, 2))
        shutil.rmtree(os.path.join(work, "local2.shards"), ignore_errors=True)  # no reuse: all computed
        seconds, summary = synthesize(graph, cluster, work, args, "--cluster", "local:2")
        times["local_2"].append(round(seconds, 2))
    reference = contents(local)
    median = {k: sorted(v)[len(v) // 2] for k, v in times.items()}
    print(json.dumps({"capture": CAPTURE, "case": "local_2_vs_jobs_2", "count": args.count, "frames": args.frames,
                      "seconds": times, "median_s": median,
                      "ratio": round(median["local_2"] / median["jobs_2"], 3),
                      "identical": contents(cluster) == reference}), flush=True)
    print(json.dumps(killed_worker_run(graph, work, args, reference)), flush=True)

    # Sizing: core-seconds and bytes per animation as measured (cluster start and write included).
    with h5py.File(cluster, "r") as f:
        bones = int(f["synthesis/bone_translations"].shape[2])
    core_seconds = median["local_2"] * 2 / args.count
    stored = (folder_bytes(os.path.join(work, "local2.shards")) + os.path.getsize(cluster)) / args.count
    sizing = []
    for rig, scale in ((f"samba ({bones} bones)", 1.0), ("27 bones", 27.0 / bones)):
        for n in (10 ** 4, 10 ** 5, 10 ** 6):
            sizing.append({"rig": rig, "animations": n, "storage_gb": round(n * stored * scale / 1e9, 1),
                           "hours": {str(w): round(n * core_seconds * scale / w / 3600, 3) for w in WORKERS}})
    print(json.dumps({"capture": CAPTURE, "case": "sizing", "frames": args.frames, "bones": bones,
                      "core_seconds_per_animation": round(core_seconds, 4), "bytes_per_animation": round(stored),
                      "write_mb_s_per_worker": round(stored / core_seconds / 1e6, 1),
                      "write_mb_s_at": {str(w): round(w * stored / core_seconds / 1e6) for w in WORKERS},
                      "table": sizing}), flush=True)

if __name__ == "__main__":
    main()
