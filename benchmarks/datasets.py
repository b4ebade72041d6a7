"""The real sequences under ../shared/data, read as skinsynth reads any input, for the benchmarks.

Also the CLI runner the command-line benchmarks share (:func:`run`, peak memory included), the
captures as files (:func:`captures`) and the bone count each capture is fitted with (``BONES``).

Each subfolder is one dataset: the folder itself if it holds frame files, else its first
.usd/.npz/.h5 file that reads. When the folder is absent a JSON line says so, and the
benchmarks go on with their built-in procedural stand-ins.
"""

import json
import os
import pathlib
import shutil
import subprocess
import sys
import threading
import time

SHARED_DATA = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data"


def shared_sequences():
    """Yield (name, vertices (F, V, 3), faces (T, 3)) for every readable dataset in ../shared/data."""
    from skinsynth.formats.errors import FormatError
    from skinsynth.formats.meshseq import read_mesh_sequence

    if not SHARED_DATA.is_dir():
        print(json.dumps({"dataset": "shared/data", "skipped": f"no real data at {SHARED_DATA}"}), flush=True)
        return
    for folder in sorted(p for p in SHARED_DATA.iterdir() if p.is_dir()):
        for spec in [folder] + sorted(folder.rglob("*")):
            if spec.is_dir() or spec.suffix.lower() in (".usd", ".usda", ".usdc", ".npz", ".h5", ".hdf5"):
                try:
                    sequence = read_mesh_sequence(str(spec))
                except FormatError:
                    continue
                yield folder.name, sequence.vertices, sequence.faces
                break


#: Bones per capture (the issues' tables; Zheng Table 1 for the horse).
BONES = {"horse_gallop": 22, "vlasic_samba": 22, "vlasic_crane": 22, "vellum_sheet": 30, "dembones_bone": 12,
         "walker": 12, "geomvideo_dance": 27}


def _hwm_mib(pid):
    """Peak resident memory (VmHWM) of a live process in MiB, or 0 once it is gone."""
    try:
        with open(f"/proc/{pid}/status") as status:
            for row in status:
                if row.startswith("VmHWM:"):
                    return int(row.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


def _children(pid):
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            return [int(c) for c in f.read().split()]
    except OSError:
        return []


def run(args, work):
    """Run the skinsynth CLI; returns (seconds, peak RSS MiB of the command, of its largest worker,
    stdout). Peaks are sampled from /proc every 20 ms (getrusage's maxrss would carry this
    benchmark's own size across the fork)."""
    exe = os.environ.get("SKINSYNTH") or shutil.which("skinsynth", path=os.path.dirname(sys.executable)) \
        or "skinsynth"
    started = time.perf_counter()
    process = subprocess.Popen([exe, *args], cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    peaks = {}

    def sample():
        while process.poll() is None:
            main = process.pid
            peaks[main] = max(peaks.get(main, 0.0), _hwm_mib(main))
            stack = _children(main)
            while stack:  # the command may be a wrapper script: follow its whole tree
                pid = stack.pop()
                peaks[pid] = max(peaks.get(pid, 0.0), _hwm_mib(pid))
                stack += _children(pid)
            time.sleep(0.02)

    sampler = threading.Thread(target=sample)
    sampler.start()
    stdout, stderr = process.communicate()
    seconds = time.perf_counter() - started
    sampler.join()
    if process.returncode != 0:
        raise RuntimeError(f"skinsynth {' '.join(args)} failed ({process.returncode}): {stderr.strip()[-800:]}")
    ordered = sorted(peaks.values(), reverse=True)
    return seconds, (ordered[0] if ordered else 0.0), (ordered[1] if len(ordered) > 1 else 0.0), stdout


def clip_sets(work):
    """(name, [input paths]) of every capture as synthesis reads it: a folder of several clips of
    one mesh (``horse_clips``: gallop and collapse) gives all of them, fitted as one rig and walked
    together, as a user synthesizing from that folder would; a clip of separate key poses
    (``*_poses``: "not a continuous animation", SOURCE.md) is left out, as it has no motion to
    walk. Any other capture: its one input, as :func:`captures`."""
    for name, path in captures(work):
        folder = pathlib.Path(path).parent
        clips = sorted(p for p in folder.glob("*.npz") if not p.stem.endswith("_poses")) \
            if name.endswith("_clips") else []
        yield name, [str(p) for p in clips] if len(clips) > 1 else [path]


#: The generated walkers the benchmarks measure beside the captures: name -> ``skinsynth example
#: walker`` options (``walker_tempo``: a walk that gets going, no two strides alike).
WALKERS = {"walker": [], "walker_planted": ["--planted"],
           "walker_tempo": ["--planted", "--frames", "400", "--cycles", "4", "--tempo", "0.6"],
           "walker_pivot": ["--pivot"]}


def walker_inputs(work, names=WALKERS, only=None):
    """[(name, input path)] of the generated walkers ``names``, written into ``work`` unless there
    already (only the one named ``only``, when given)."""
    out = []
    for name in names:
        path = os.path.join(work, f"{name}.npz")
        if not os.path.exists(path) and only in (None, name):
            run(["example", "walker", *WALKERS[name], "-o", path, "-q"], work)
        out.append((name, path))
    return out


def captures(work):
    """(name, input path) of every capture, or the built-in stand-ins without real data."""
    if SHARED_DATA.is_dir():
        for folder in sorted(p for p in SHARED_DATA.iterdir() if p.is_dir()):
            files = sorted(folder.glob("*.npz"))
            if files:
                yield folder.name, str(files[0])
        return
    print(json.dumps({"dataset": "shared/data", "skipped": f"no real data at {SHARED_DATA}; stand-ins only"}))
    path = os.path.join(work, "bending_bar.npz")
    run(["example", "bending-bar", "-o", path, "--frames", "96", "--cycles", "2"], work)
    yield "bending_bar", path
