"""fit-skin against py-dem-bones, side by side in the same run, on every sequence in ../shared/data.

One JSON line per (capture, bones):

- ``skinsynth``: ``skinsynth fit-skin INPUT -o OUT --bones B --seed 0 --json`` with default
  options otherwise, timed as the whole command (process start, reading, fitting, writing), its
  peak resident memory, the RMSE over the rest bounding-box diagonal it reports, iterations,
  why it stopped, and from its per-iteration history the time to reach py-dem-bones' error
  (command start to that iteration's end);
- ``dem_bones``: py-dem-bones 0.13.1 (Electronic Arts' Dem Bones, C++/OpenMP) on the same
  vertices, bones, ≤ 4 influences and 30 iterations (its CLI defaults otherwise) in its own
  process, timed from process start to the solved weights and transforms (reading the same
  .npz included, writing nothing), and its RMSE over the diagonal, measured the same way;
- the same-run ratios ``time_ratio`` = ours / theirs (goal ≤ 0.5) and ``rmse_ratio`` (goal ≤ 0.7).

Both use every core. py-dem-bones is optional (``pip install -e .[bench]``); without it only
our figures are printed. Built-in procedural stand-ins run only when ../shared/data is absent.
The command run is $SKINSYNTH when set (another checkout's, for a before/after table).

With ``--device cuda`` our command runs its warp kernels on the GPU (``fit-skin --device``).

    python benchmarks/fit_skin.py [--only NAME] [--no-dembones] [--work DIR] [--device cuda]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

from datasets import captures, run

#: bones per capture (the horse's is Zheng's Table 1); others get DEFAULT_BONES.
BONES = {"horse_gallop": 22, "vlasic_samba": 30, "vellum_sheet": 30}
DEFAULT_BONES = 20

_DEM_BONES = """
import sys, time, json
started = float(sys.argv[3])
import numpy as np
import py_dem_bones
data = np.load(sys.argv[1])
vertices = np.asarray(data["vertices"], dtype=np.float64)
faces = np.asarray(data["faces"]) if "faces" in data else None
result = py_dem_bones.solve_skinning(vertices[0], vertices, int(sys.argv[2]), faces=faces, max_influences=4,
                                     iterations=30)
seconds = time.time() - started
homogeneous = np.c_[vertices[0], np.ones(len(vertices[0]))]
recon = np.einsum("bv,fbac,vc->fva", result.weights, result.transforms[:, :, :3, :], homogeneous)
diagonal = np.linalg.norm(vertices[0].max(axis=0) - vertices[0].min(axis=0))
rmse = float(np.sqrt(np.mean(np.sum((recon - vertices) ** 2, axis=2))) / diagonal)
print(json.dumps({"seconds": round(seconds, 3), "rmse_over_diagonal": rmse,
                  "bones_used": int((result.weights.sum(axis=1) > 0).sum())}))
"""


def dem_bones(path, bones):
    """py-dem-bones in a fresh process: (summary dict); seconds from process start."""
    started = time.time()
    done = subprocess.run([sys.executable, "-c", _DEM_BONES, path, str(bones), repr(started)], capture_output=True,
                          text=True)
    if done.returncode != 0:
        return {"error": done.stderr.strip()[-400:]}
    return json.loads(done.stdout)


def ours(path, bones, work, device="cpu"):
    out = os.path.join(work, "fit.h5")
    seconds, peak, _, stdout = run(["fit-skin", path, "-o", out, "--bones", str(bones), "--seed", "0", "--json",
                                    "--device", device], work)
    summary = json.loads(stdout)
    # history times count from the fit's start; the command's own start is `seconds − fit seconds` earlier
    offset = seconds - summary["seconds"] if "seconds" in summary else 0.0
    history = [(offset + t, e) for t, e in summary.get("history", [])]
    return {"seconds": round(seconds, 3), "peak_rss_mib": round(peak), "rmse_over_diagonal": summary["rmse_over_diagonal"],
            "iterations": summary["iterations"], "converged": summary["converged"],
            "stopped": summary.get("stopped"), "fit_seconds": summary.get("seconds")}, history


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", help="run only this capture")
    parser.add_argument("--no-dembones", action="store_true", help="skip the py-dem-bones comparison")
    parser.add_argument("--work", default=None)
    parser.add_argument("--device", default="cpu", help="fit-skin --device (cpu, cuda, cuda:N)")
    args = parser.parse_args()
    work = args.work or tempfile.mkdtemp(prefix="skinsynth-fit-")
    os.makedirs(work, exist_ok=True)
    import importlib.util

    have_dembones = importlib.util.find_spec("py_dem_bones") is not None and not args.no_dembones
    for name, path in captures(work):
        if args.only and name != args.only:
            continue
        bones = BONES.get(name, DEFAULT_BONES)
        line = {"capture": name, "bones": bones, "device": args.device}
        line["skinsynth"], history = ours(path, bones, work, args.device)
        if have_dembones and path.endswith(".npz"):
            theirs = line["dem_bones"] = dem_bones(path, bones)
            if "error" not in theirs:
                mine = line["skinsynth"]
                line["time_ratio"] = round(mine["seconds"] / theirs["seconds"], 3)
                line["rmse_ratio"] = round(mine["rmse_over_diagonal"] / theirs["rmse_over_diagonal"], 3)
                reached = [t for t, e in history if e <= theirs["rmse_over_diagonal"]]
                mine["seconds_to_dem_bones_error"] = round(reached[0], 2) if reached else None
                reached = [t for t, e in history if e <= 0.7 * theirs["rmse_over_diagonal"]]
                mine["seconds_to_0.7x_dem_bones_error"] = round(reached[0], 2) if reached else None
        print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
