"""fit-skin benchmark: one JSON line per (dataset, bones) with seconds, peak memory and RMSE/diagonal.

Datasets: every sequence under ../shared/data (each subfolder, read as skinsynth reads any input:
a folder of frames, or the first .usd/.npz/.h5 file in it) plus built-in procedural ones, so the
script reports figures even where the real data is absent. When ``py-dem-bones`` is installed
(``pip install -e .[bench]``) it fits the same data with the same bone count, 30 iterations and
≤ 4 influences, and the line carries its figures and the ratios ours/theirs.

RMSE: sqrt of the mean over all frames and vertices of the squared distance between the LBS
reconstruction and the input, divided by the rest-pose (frame 0) bounding-box diagonal.

    python benchmarks/fit_skin.py [--only NAME] [--no-dembones] [--iterations 30]
"""

import argparse
import json
import multiprocessing as mp
import pathlib
import resource
import time

import numpy as np

SHARED_DATA = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data"
#: bone counts of the issue's table (Zheng Table 1 for the horse); others get DEFAULT_BONES.
BONES = {"horse_gallop": 22, "vlasic_samba": 30, "vellum_sheet": 30}
DEFAULT_BONES = 20


def _real_inputs():
    if not SHARED_DATA.is_dir():
        return []
    found = []
    for folder in sorted(p for p in SHARED_DATA.iterdir() if p.is_dir()):
        candidates = [folder] + sorted(folder.rglob("*"))
        found.append((folder.name, [str(c) for c in candidates if c.is_dir() or c.suffix.lower() in
                                    (".usd", ".usda", ".usdc", ".npz", ".h5", ".hdf5")]))
    return found


def _load(name, specs):
    """(vertices (F, V, 3), faces) of a dataset: built-in generators or the first spec that reads."""
    from skinsynth.formats.errors import FormatError
    from skinsynth.formats.meshseq import read_mesh_sequence
    from skinsynth.pipeline.examples import bending_bar

    if name == "bending_bar_horse_size":
        return bending_bar(frames=48, rings=200, segments=42)
    if name == "bending_bar_samba_size":
        return bending_bar(frames=175, rings=200, segments=50)
    if name == "bending_bar_small":
        return bending_bar(frames=60, rings=40, segments=16)
    errors = []
    for spec in specs:
        try:
            seq = read_mesh_sequence(spec)
            return seq.vertices, seq.faces
        except FormatError as error:
            errors.append(str(error))
    raise FormatError(name, "no readable sequence: " + "; ".join(errors[:3]))


def _rmse(recon, vertices):
    diag = np.linalg.norm(vertices[0].max(axis=0) - vertices[0].min(axis=0))
    return float(np.sqrt(np.mean(np.sum((recon - vertices) ** 2, axis=2))) / diag)


def _peak_mib():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _ours(name, specs, bones, iterations, queue):
    from skinsynth.gpu import lbs_reference
    from skinsynth.pipeline.skin_fit import fit_skin

    vertices, _ = _load(name, specs)
    base = _peak_mib()
    start = time.perf_counter()
    fit = fit_skin(vertices, bones, max_influences=4, iterations=iterations, rest_frame=0, seed=0)
    seconds = time.perf_counter() - start
    recon = lbs_reference(fit.rest_vertices, fit.bone_indices, fit.bone_weights, fit.rotations, fit.translations)
    queue.put(dict(frames=int(vertices.shape[0]), vertices=int(vertices.shape[1]), seconds=round(seconds, 3),
                   peak_mib=round(_peak_mib(), 1), input_mib=round(base, 1), rmse_over_diagonal=_rmse(recon, vertices),
                   iterations=fit.iterations, converged=fit.converged, bones_used=bones - fit.bones_without_weight))


def _dembones(name, specs, bones, iterations, queue):
    import py_dem_bones

    vertices, faces = _load(name, specs)
    start = time.perf_counter()
    result = py_dem_bones.solve_skinning(vertices[0], vertices, bones, faces=faces, max_influences=4,
                                         iterations=iterations)
    seconds = time.perf_counter() - start
    homogeneous = np.c_[vertices[0], np.ones(len(vertices[0]))]
    recon = np.einsum("bv,fbac,vc->fva", result.weights, result.transforms[:, :, :3, :], homogeneous)
    queue.put(dict(seconds=round(seconds, 3), peak_mib=round(_peak_mib(), 1), rmse_over_diagonal=_rmse(recon, vertices),
                   bones_used=int((result.weights.sum(axis=1) > 0).sum())))


def _isolated(target, *args):
    """Run one measurement in a fresh process so its peak memory is its own."""
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=target, args=args + (queue,))
    proc.start()
    proc.join()
    if proc.exitcode != 0 or queue.empty():
        return {"error": f"exit code {proc.exitcode}"}
    return queue.get()


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", help="run only this dataset name")
    parser.add_argument("--no-dembones", action="store_true", help="skip the py-dem-bones comparison")
    parser.add_argument("--iterations", type=int, default=30)
    args = parser.parse_args()

    cases = [(name, specs, BONES.get(name, DEFAULT_BONES)) for name, specs in _real_inputs()]
    if not cases:
        print(json.dumps({"dataset": "shared/data", "skipped": f"no real data at {SHARED_DATA}"}), flush=True)
    # Procedural stand-ins at the sizes of the table: horse (8.4k vertices, 48 frames, 22
    # bones) and samba (10k vertices, 175 frames, 30 bones).
    cases += [("bending_bar_small", [], 8), ("bending_bar_horse_size", [], 22), ("bending_bar_samba_size", [], 30)]
    import importlib.util

    have_dembones = importlib.util.find_spec("py_dem_bones") is not None and not args.no_dembones
    for name, specs, bones in cases:
        if args.only and name != args.only:
            continue
        line = {"dataset": name, "bones": bones, "iterations_max": args.iterations, "max_influences": 4}
        line["skinsynth"] = _isolated(_ours, name, specs, bones, args.iterations)
        if have_dembones:
            theirs = _isolated(_dembones, name, specs, bones, args.iterations)
            line["dem_bones"] = theirs
            ours = line["skinsynth"]
            if "error" not in theirs and "error" not in ours:
                line["time_ratio"] = round(ours["seconds"] / theirs["seconds"], 3)
                line["rmse_ratio"] = round(ours["rmse_over_diagonal"] / theirs["rmse_over_diagonal"], 3)
        print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
