"""Benchmark the puppet's run-time path (gpu.puppet_run): numpy reference vs warp on the CPU
(1 and 2 Python threads) and on CUDA when present, per stage and end to end.

One JSON line per (model, layout, solver, skinning). Skinnings: "dual-quaternion" (Feng §6.3)
and "linear" (each bone's rigid transform from its composed dual quaternion, then linear-blend
skinning), both the whole path on the device (``run_puppet(skinning=…)``). Models: "face" (V=23,728, B=260, n_c=8, n_p=38,
K=4), "face+correctives" (the same with 38 pose-space corrective blend shapes) and "horse"
(V=8,431, B=150, n_c=8, n_p=27, K=4), random but well-formed (unit dual
quaternions around which M ξ + m varies, weights summing to 1, Gaussian kernel). Layouts: 1000
frames × 1 character and 100 frames × 100 characters (N = samples = frames × characters).

Timings are seconds for all N samples, median of --repeats runs after one warm-up (kernel
compile / cache load excluded); the skinnings' runs are interleaved (one of each in turn, so a
machine whose load changes weighs on both alike), and with both skinnings the linear record's
`linear_over_dq` is its frames per second over the dual-quaternion one's, per device.
`frames_per_s` is samples per second end to end: standardised
controls, in-place controls and world frames in (numpy), skinned world vertices out (numpy,
float32 `out` buffer, written in place on the CPU; `f64_frames_per_s`: with the default float64
result, first layout only). `stages` synchronises after each stage (so sums slightly exceed the
end-to-end time; median of --repeats runs per stage). The numpy reference runs on at most --numpy-samples samples and is scaled.

Then, with --real DIR (the puppet benchmark's work folder, or an empty one), one line per real
capture: its puppet (``train-kcca --train-frames every:4``, built with the CLI when DIR lacks
it) played by ``skinsynth play`` from the capture's own control trajectories into an HDF5 bake
and a UsdSkel file; ``bake_error`` and ``usdskel_error`` are the largest vertex distances from
the float64 reference (``pipeline.puppet.predict_vertices``) over the rest diagonal (goal
≤ 1e-5), next to play's own frames per second (``--json``, compute only, the machine's threads).

    python benchmarks/play.py [--repeats 3] [--only face] [--skinning linear] [--layout 0]
                              [--numpy-samples 200] [--real DIR]
"""

import argparse
import json
import time

import numpy as np

import statistics

import skinsynth.gpu as gpu
from skinsynth.gpu import available_devices
from skinsynth.pipeline.rig.rotations import rigid_to_dual_quaternion

MODELS = {
    "face": dict(verts=23728, bones=260, controls=8, examples=38, influences=4),
    "face+correctives": dict(verts=23728, bones=260, controls=8, examples=38, influences=4, correctives=True),
    "horse": dict(verts=8431, bones=150, controls=8, examples=27, influences=4),
}
LAYOUTS = [(1000, 1), (100, 100)]
SKINNINGS = ("dual-quaternion", "linear")


def rotations(rng, shape, angle=1.0):
    from skinsynth.pipeline.rig.rotations import rotation_exp

    return rotation_exp(rng.uniform(-angle, angle, size=shape + (3,)))


def random_puppet(rng, verts, bones, controls, examples, influences, correctives=False):
    rest = rng.normal(size=(verts, 3))
    idx = np.stack([rng.choice(bones, influences, replace=False) for _ in range(verts)])
    w = rng.random((verts, influences)) ** 2
    w /= w.sum(axis=1, keepdims=True)
    base = rigid_to_dual_quaternion(rotations(rng, (bones,)), rng.normal(size=(bones, 3))).reshape(-1)
    return gpu.PuppetArrays(
        rest_vertices=rest, bone_indices=idx, bone_weights=w,
        training_controls=rng.normal(size=(examples, 3 * controls)) / np.sqrt(3 * controls), kernel="gaussian",
        predictor=rng.normal(size=(8 * bones, examples)) * 0.05, bias=base,
        rotation_operator=rng.normal(size=(bones, bones, 3)) * 0.05, control_operator=rng.normal(size=(bones, controls)) * 0.1,
        prior_operator=rng.normal(size=(bones, bones)) * 1e-6,
        corrective_weights=rng.normal(size=(examples, examples)) if correctives else None,
        corrective_offsets=rng.normal(size=(examples, verts, 3)) * 0.01 if correctives else None)


def random_inputs(rng, samples, puppet):
    d = puppet.training_controls.shape[1]
    x = rng.normal(size=(samples, d)) / np.sqrt(d)
    c = rng.normal(size=(samples, d // 3, 3))
    frames = np.zeros((samples, 4, 4))
    frames[:, :3, :3] = rotations(rng, (samples,))
    frames[:, :3, 3] = rng.normal(size=(samples, 3)) * 3.0
    frames[:, 3, 3] = 1.0
    return x, c, frames


def numpy_reference(puppet, x, c, frames, solver, skinning="dual-quaternion"):
    """Stage seconds of the numpy reference (composing the stage references)."""
    from skinsynth.gpu import dqs_reference, lbs_reference
    from skinsynth.pipeline.rig.rotations import with_translations

    stages, t0 = {}, time.perf_counter()

    def mark(name):
        nonlocal t0
        now = time.perf_counter()
        stages[name] = now - t0
        t0 = now

    xi = gpu.kernel_vectors_reference(x, puppet.training_controls, puppet.kernel)
    mark("kernel_vectors")
    d = gpu.predict_dual_quaternions_reference(xi, puppet.predictor, puppet.bias)
    mark("predict")
    d, rot, trans = gpu.normalise_dual_quaternions_reference(d)
    mark("normalise")
    if solver:
        trans = gpu.solve_translations_reference(rot, c, trans, puppet.rotation_operator, puppet.control_operator,
                                                puppet.prior_operator)
        mark("solve_translations")
        d = with_translations(d, trans)
        mark("compose")
    offsets = None
    if puppet.has_correctives:
        offsets = gpu.corrective_offsets_reference(
            gpu.corrective_weights_reference(xi, x, puppet.corrective_weights), puppet.corrective_offsets)
        mark("correctives")
    if skinning == "linear":
        _, rot, trans = gpu.normalise_dual_quaternions_reference(d)
        mark("rigid")
        placed = lbs_reference(puppet.rest_vertices, puppet.bone_indices, puppet.bone_weights, rot, trans, offsets)
    else:
        placed = dqs_reference(puppet.rest_vertices, puppet.bone_indices, puppet.bone_weights, d, offsets)
    mark("skin")
    np.einsum("nab,nvb->nva", frames[:, :3, :3], placed) + frames[:, None, :3, 3]
    mark("world_frames")
    return stages


def real_puppets(work):
    """One JSON line per real capture: play's bake and UsdSkel output against the float64 reference."""
    import os

    import h5py
    from datasets import BONES, captures, run

    from skinsynth.formats.puppet_file import read_puppet

    from skinsynth.pipeline.puppet import puppet_from_record
    from skinsynth.formats.usd import read_skel_points
    from skinsynth.pipeline.puppet import predict_vertices

    os.makedirs(work, exist_ok=True)
    for name, spec in captures(work):
        skin = os.path.join(work, f"{name}.skin.h5")
        controls = os.path.join(work, f"{name}.controls.h5")
        puppet_path = os.path.join(work, f"{name}.every4.puppet.h5")
        if not os.path.exists(skin):
            run(["fit-skin", spec, "-o", skin, "--bones", str(BONES.get(name, 20)), "--seed", "0", "-q"], work)
        if not os.path.exists(controls):
            run(["select-controls", skin, "-o", controls, "--count", "8", "-q"], work)
        if not os.path.exists(puppet_path):
            run(["train-kcca", controls, "-o", puppet_path, "--train-frames", "every:4", "-q"], work)
        bake, usd = os.path.join(work, f"{name}.play.h5"), os.path.join(work, f"{name}.play.usdc")
        _, _, _, stdout = run(["play", puppet_path, "-c", spec, "-o", bake, "--json"], work)
        run(["play", puppet_path, "-c", spec, "-o", usd, "--as", "skel"], work)
        record, _, _ = read_puppet(puppet_path)
        puppet = puppet_from_record(record)
        with h5py.File(puppet_path, "r") as f:
            examples = f["examples/vertices"][()]
        reference = predict_vertices(puppet, examples[:, puppet.control_indices])
        rest = puppet.rest_vertices
        diagonal = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
        with h5py.File(bake, "r") as f:
            baked = f["vertices"][()]
        skel = read_skel_points(usd)
        print(json.dumps({"dataset": name, "frames": int(examples.shape[0]), "vertices": int(rest.shape[0]),
                          "bones": int(puppet.regression.predictor.shape[0]),
                          "predictor_max": float(np.abs(puppet.regression.predictor).max()),
                          "bake_error": float(np.abs(baked - reference).max() / diagonal),
                          "usdskel_error": float(np.abs(skel - reference).max() / diagonal),
                          "play": json.loads(stdout)}), flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=sorted(MODELS))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--numpy-samples", type=int, default=100)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--skinning", choices=SKINNINGS, help="only this skinning (default: both)")
    parser.add_argument("--layout", type=int, choices=range(len(LAYOUTS)),
                        help=f"only this layout (index into {LAYOUTS})")
    parser.add_argument("--solver", choices=["on", "off"], help="only with / without the translation solver")
    parser.add_argument("--real", metavar="DIR", help="also play a puppet of every real capture (work folder)")
    parser.add_argument("--real-only", action="store_true", help="only the real puppets")
    opts = parser.parse_args()
    if opts.real:
        real_puppets(opts.real)
    if opts.real_only:
        return
    devices = [d for d in available_devices() if d in ("cpu", "cuda:0")]
    rng = np.random.default_rng(0)
    for name, size in MODELS.items():
        if opts.only and name != opts.only:
            continue
        puppet = random_puppet(rng, **size)
        on_device = {device: gpu.DevicePuppet(puppet, device) for device in devices}
        for layout_index, (frames_per_character, characters) in enumerate(LAYOUTS):
            samples = frames_per_character * characters
            x, c, frames = random_inputs(rng, samples, puppet)  # drawn for every layout: same inputs when filtered
            if opts.layout is not None and layout_index != opts.layout:
                continue
            out = np.empty((samples, size["verts"], 3), dtype=np.float32)
            skinnings = [s for s in SKINNINGS if opts.skinning in (None, s)]
            for solver in (True, False):
                if opts.solver is not None and solver != (opts.solver == "on"):
                    continue
                for record in _records(opts, name, size, puppet, on_device, layout_index, x, c, frames, out, solver,
                                       skinnings):
                    print(json.dumps(record), flush=True)


def interleaved_medians(runs, repeats):
    """{key: median seconds} of ``repeats`` calls of each of runs {key: fn}, after one warm-up call
    each, the calls interleaved (one of each in turn)."""
    for fn in runs.values():
        fn()
    times = {key: [] for key in runs}
    for _ in range(repeats):
        for key, fn in runs.items():
            t0 = time.perf_counter()
            fn()
            times[key].append(time.perf_counter() - t0)
    return {key: statistics.median(t) for key, t in times.items()}


def _records(opts, name, size, puppet, on_device, layout_index, x, c, frames, out, solver, skinnings):
    """One JSON record per skinning: the numpy reference and warp on each device, for one solver,
    the skinnings' warp runs interleaved."""
    frames_per_character, characters = LAYOUTS[layout_index]
    samples = frames_per_character * characters
    records, checks = {}, {}
    for skinning in skinnings:
        record = {"model": name, **size, "frames": frames_per_character, "characters": characters,
                  "samples": samples, "translation_solver": solver, "skinning": skinning}
        m = min(samples, opts.numpy_samples)
        t0 = time.perf_counter()
        stages = numpy_reference(puppet, x[:m], c[:m], frames[:m], solver, skinning)
        seconds = (time.perf_counter() - t0) * samples / m
        record["numpy"] = {"measured_samples": m, "seconds": seconds, "frames_per_s": samples / seconds,
                           "stages": {k: v * samples / m for k, v in stages.items()}}
        records[skinning] = record
        checks[skinning] = gpu.reference_run_puppet(puppet, x[:8], c[:8], frames[:8], translation_solver=solver,
                                                    skinning=skinning)

    def run(dev_puppet, skinning, threads=1, timings=None, into=out):
        return lambda: gpu.run_puppet(dev_puppet, x, c, frames, translation_solver=solver, out=into, threads=threads,
                                      timings=timings, skinning=skinning)

    for device, dev_puppet in on_device.items():
        label = "warp-cpu" if device == "cpu" else "warp-cuda"
        for threads in (opts.threads if device == "cpu" else [1]):
            key = label if threads == 1 else f"{label}-{threads}threads"
            seconds = interleaved_medians({s: run(dev_puppet, s, threads) for s in skinnings}, opts.repeats)
            for skinning in skinnings:
                run(dev_puppet, skinning, threads)()
                check = checks[skinning]
                err = float(np.abs(out[:8] - check).max() / np.abs(check).max())
                records[skinning][key] = {"seconds": seconds[skinning], "frames_per_s": samples / seconds[skinning],
                                          "max_rel_error": err}
            if len(skinnings) == 2:
                records["linear"][key]["linear_over_dq"] = seconds["dual-quaternion"] / seconds["linear"]
            if threads != 1:
                continue
            stages = {s: [] for s in skinnings}
            for _ in range(opts.repeats):
                for skinning in skinnings:
                    timings = {}
                    run(dev_puppet, skinning, timings=timings)()
                    stages[skinning].append(timings)
            for skinning in skinnings:
                records[skinning][key]["stages"] = {k: statistics.median(t[k] for t in stages[skinning])
                                                    for k in stages[skinning][0]}
            if layout_index == 0:
                s64 = interleaved_medians({s: run(dev_puppet, s, into=None) for s in skinnings}, 1)
                for skinning in skinnings:
                    records[skinning][key]["f64_frames_per_s"] = samples / s64[skinning]
    return list(records.values())


if __name__ == "__main__":
    main()
