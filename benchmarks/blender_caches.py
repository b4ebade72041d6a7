"""Alembic and FBX read through Blender (issue 67, formats/blender.py): one JSON line per case.

- ``round_trip``: every shared capture (each .npz under ../shared/data) written by Blender to .abc
  and to .fbx (metres), as a user's DCC would (tests/formats/blender_writer.py: a shape key per
  frame), then read back by skinsynth: the largest vertex error over the diagonal, frames, rate,
  units, up axis, the seconds Blender took to write it and skinsynth to read it.
- ``export_speed``: ``export``'s Alembic writer on the same bar: seconds, the error read back.
- ``speed``: a generated 10,000-vertex, 1,000-frame cache (a bending bar) read from .abc and .fbx:
  seconds, frames per second, the peak memory of Blender and of the reading process against the
  output's size (read in a fresh process).

Needs a Python with bpy: SKINSYNTH_BLENDER, else ../.venv-blender (make blender).

    python benchmarks/blender_caches.py [--work DIR] [--only round_trip|speed|export_speed] [--captures A,B]
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np
from datasets import SHARED_DATA

ROOT = pathlib.Path(__file__).resolve().parents[1]
WRITER = ROOT / "tests" / "formats" / "blender_writer.py"


def blender_python():
    named = os.environ.get("SKINSYNTH_BLENDER")
    beside = ROOT / ".venv-blender" / "bin" / "python"
    return named or (str(beside) if beside.is_file() else None)


def write(python, capture, output, **options):
    """``capture`` (.npz) written by Blender to ``output``; the seconds it took."""
    started = time.perf_counter()
    run = subprocess.run([python, str(WRITER), str(capture), str(output), json.dumps(options)], capture_output=True,
                         text=True)
    if run.returncode:
        raise RuntimeError(run.stderr[-2000:])
    return time.perf_counter() - started


_FRESH = """
import json, resource, sys, time
from skinsynth.formats.meshseq import read_mesh_sequence
started = time.perf_counter()
sequence = read_mesh_sequence(sys.argv[1])
seconds = time.perf_counter() - started
print(json.dumps({"seconds": seconds, "frames": len(sequence.vertices), "vertices": sequence.vertices.shape[1],
                  "blender_peak_mib": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0,
                  "reader_peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}))
"""


def read(path):
    """(sequence, seconds) of reading ``path`` here."""
    from skinsynth.formats.meshseq import read_mesh_sequence

    started = time.perf_counter()
    sequence = read_mesh_sequence(str(path))
    return sequence, time.perf_counter() - started


def read_fresh(path):
    """Reading ``path`` in a fresh process: seconds, frames, vertices, the peak memory of Blender
    (its only child) and of the process itself, MiB."""
    run = subprocess.run([sys.executable, "-c", _FRESH, str(path)], capture_output=True, text=True)
    if run.returncode:
        raise RuntimeError(run.stderr[-2000:])
    return json.loads(run.stdout)


def round_trip(work, python, names):
    for capture in sorted(SHARED_DATA.rglob("*.npz")):
        if names and capture.stem not in names:
            continue
        with np.load(capture) as data:
            if "vertices" not in data:
                continue
            frames, fps = np.asarray(data["vertices"], dtype=np.float64), float(data["fps"]) if "fps" in data else 24.0
        diagonal = float(np.linalg.norm(np.ptp(frames[0], axis=0)))
        for suffix in (".abc", ".fbx"):
            cache = pathlib.Path(work, capture.stem + suffix)
            written = write(python, capture, cache, fps=fps, unit="m")
            sequence, seconds = read(cache)
            same = sequence.vertices.shape == frames.shape
            error = float(np.abs(sequence.vertices * sequence.scene.meters_per_unit - frames).max()) / diagonal \
                if same else None
            print(json.dumps({"benchmark": "blender_caches", "case": "round_trip", "capture": capture.stem,
                              "format": suffix[1:], "frames": len(sequence.vertices), "frames_capture": len(frames),
                              "vertices": int(sequence.vertices.shape[1]), "fps": sequence.fps, "fps_capture": fps,
                              "up_axis": sequence.scene.up_axis, "meters_per_unit": sequence.scene.meters_per_unit,
                              "mesh": sequence.scene.prim_path, "error_over_diagonal": error,
                              "write_seconds": round(written, 2), "read_seconds": round(seconds, 2),
                              "file_mib": round(cache.stat().st_size / 2 ** 20, 1)}), flush=True)
            cache.unlink()


def speed(work, python):
    from skinsynth.formats.meshseq import write_array_sequence
    from skinsynth.pipeline.inputs.examples import bending_bar

    vertices, faces = bending_bar(frames=1000, rings=250, segments=40)  # 10,000 vertices
    source = pathlib.Path(work, "bar10k.npz")
    write_array_sequence(source, vertices, faces, 30.0)
    output_mib = vertices.size * 8 / 2 ** 20
    for suffix in (".abc", ".fbx"):
        cache = pathlib.Path(work, "bar10k" + suffix)
        written = write(python, source, cache, fps=30, unit="m")
        fresh = read_fresh(cache)
        print(json.dumps({"benchmark": "blender_caches", "case": "speed", "format": suffix[1:],
                          "frames": fresh["frames"], "vertices": fresh["vertices"],
                          "read_seconds": round(fresh["seconds"], 2),
                          "frames_per_second": round(fresh["frames"] / fresh["seconds"], 1),
                          "blender_peak_mib": round(fresh["blender_peak_mib"], 1),
                          "reader_peak_mib": round(fresh["reader_peak_mib"], 1), "output_mib": round(output_mib, 1),
                          "write_seconds": round(written, 2), "file_mib": round(cache.stat().st_size / 2 ** 20, 1),
                          "threads": os.cpu_count()}), flush=True)


def export_speed(work):
    """``export``'s Alembic writer (formats/blender.write_alembic) on the 10,000-vertex, 1,000-frame
    bar: seconds, and the largest error of the cache read back over the diagonal."""
    from skinsynth.formats.blender import write_alembic
    from skinsynth.formats.meshseq import read_mesh_sequence
    from skinsynth.formats.scene import Scene
    from skinsynth.pipeline.inputs.examples import bending_bar

    vertices, faces = bending_bar(frames=1000, rings=250, segments=40)
    out = pathlib.Path(work, "exported.abc")
    started = time.perf_counter()
    write_alembic(out, vertices, faces, 30.0, Scene())
    seconds = time.perf_counter() - started
    back = read_mesh_sequence(str(out))
    diagonal = float(np.linalg.norm(np.ptp(vertices[0], axis=0)))
    print(json.dumps({"benchmark": "blender_caches", "case": "export_speed", "format": "abc",
                      "frames": len(vertices), "vertices": int(vertices.shape[1]), "write_seconds": round(seconds, 2),
                      "frames_per_second": round(len(vertices) / seconds, 1),
                      "error_over_diagonal": float(np.abs(back.vertices - vertices).max()) / diagonal,
                      "file_mib": round(out.stat().st_size / 2 ** 20, 1), "threads": os.cpu_count()}), flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", default=None, help="folder for the caches (default: a temporary one)")
    parser.add_argument("--only", default=None, choices=["round_trip", "speed", "export_speed"])
    parser.add_argument("--captures", default=None, help="round_trip: only these captures (file stems), comma-separated")
    options = parser.parse_args()
    python = blender_python()
    if python is None:
        print(json.dumps({"benchmark": "blender_caches", "skipped": "no Python with bpy: make blender"}))
        return
    os.environ["SKINSYNTH_BLENDER"] = python
    work = options.work or tempfile.mkdtemp(prefix="blender_bench_")
    os.makedirs(work, exist_ok=True)
    if options.only in (None, "round_trip"):
        if SHARED_DATA.is_dir():
            round_trip(work, python, set(options.captures.split(",")) if options.captures else None)
        else:
            print(json.dumps({"benchmark": "blender_caches", "case": "round_trip", "skipped": f"no {SHARED_DATA}"}))
    if options.only in (None, "speed"):
        speed(work, python)
    if options.only in (None, "export_speed"):
        export_speed(work)


if __name__ == "__main__":
    sys.exit(main())
