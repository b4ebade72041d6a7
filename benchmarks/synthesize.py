"""synthesize benchmark: 1,000 animations × 600 frames, seconds, distinct walks, smoothness.

One JSON line per (dataset, mode): every sequence under ../shared/data (when present) and two
built-in clips — the demo's bending bar (two bend cycles) and a horse-sized tube whose body
bends through two exact cycles while its tail swings at its own rate (see benchmarks/graph.py).

Reported: seconds for the bone motions of all animations (--jobs 1 and 2), seconds to skin
vertex caches with the warp LBS kernel on the CPU, in one thread and in two (measured on 100
animations, scaled to all), distinct
animations, transitions used, and smoothness = the largest per-vertex acceleration
‖v(k+1) − 2 v(k) + v(k−1)‖ within a window of any splice, over the largest in the input clip
(measured on 50 animations and a subset of ≤ 512 vertices), and the same ratio away from splices
(more than window + 2 frames from any seam), and for several components the ratio of the same
components assembled from seamless walks (what recombination alone does, before any splice).
Seconds and peak resident memory are measured in a freshly spawned process per run (the parent
process and, with 2 jobs, its largest worker; the workers write the result into memory shared
with the parent, which counts in the workers' figures, not the parent's). Goal: < 10 s on 2 cores, ratio ≤ 1.5.

    python benchmarks/synthesize.py [--only NAME] [--count 1000] [--frames 600]
"""

import argparse
import json
import resource
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from datasets import BONES, shared_sequences


def _datasets():
    from skinsynth.pipeline.examples import articulated_tube, bending_bar

    for name, vertices, faces in shared_sequences():
        yield name, vertices, faces, BONES.get(name, 20)
    yield ("bending_bar_two_cycles", *bending_bar(frames=96, cycles=2), 8)
    periods = np.array([[24.0, 24.0, 24.0, 17.0, 17.0]] * 2)
    yield ("tube_body_and_tail", *articulated_tube(frames=48, rings=350, segments=24, joints=5, periods=periods,
                                                   seed=3), 22)


def smoothness(result, skin_fit, input_vertices, window, animations=50):
    """(max acceleration near splices, max acceleration elsewhere) / max acceleration in the input
    (vertex subset; "elsewhere" is None when every frame is near a splice). Near = within
    window + 2 frames of a seam of any component."""
    from skinsynth.gpu import lbs_reference
    from skinsynth.pipeline.collisions import vertex_subset

    subset = vertex_subset(input_vertices.shape[1])
    accel_in = np.linalg.norm(np.diff(input_vertices[:, subset], n=2, axis=0), axis=-1).max()
    worst_near, worst_far = 0.0, None
    for a in range(min(animations, result.F.shape[0])):
        v = lbs_reference(skin_fit.rest_vertices[subset], skin_fit.bone_indices[subset],
                          skin_fit.bone_weights[subset], result.F[a], result.t[a])
        accel = np.linalg.norm(np.diff(v, n=2, axis=0), axis=-1).max(axis=1)  # (M-2,) at frames 1..M-2
        src = result.sources[:, a]
        seam = np.any(src[:, 1:] != src[:, :-1] + 1, axis=0)  # (M-1,) seam at k+1
        near = np.zeros(accel.shape[0], dtype=bool)
        for k in np.flatnonzero(seam) + 1:
            near[max(0, k - window - 2): k + window] = True
        if near.any():
            worst_near = max(worst_near, float(accel[near].max()))
        if (~near).any():
            worst_far = max(worst_far or 0.0, float(accel[~near].max()))
    return worst_near / accel_in, None if worst_far is None else worst_far / accel_in


def seamless_recombination(analysis, skin_fit, input_vertices, animations=1000, frames=30, seed=0):
    """Max acceleration / the input's when the components are assembled (Alg. 1) from walks
    *without* seams — each component plays its own stretch of the clip — so the ratio measures
    what recombining independent components does on its own, before any splice (None for one
    component or a clip shorter than ``frames``)."""
    from skinsynth.gpu import lbs_reference
    from skinsynth.pipeline.assembly import assemble
    from skinsynth.pipeline.collisions import vertex_subset
    from skinsynth.pipeline.splicing import splice_local

    length = skin_fit.rotations.shape[0]
    if len(analysis.components) < 2 or length <= frames:
        return None
    rng = np.random.default_rng(seed)
    parts = [splice_local(c, skin_fit.rotations, skin_fit.translations,
                          rng.integers(0, length - frames, size=animations)[:, None] + np.arange(frames))
             for c in analysis.components]
    F, t, _, _ = assemble([c.bones for c in analysis.components], parts, skin_fit.rotations.shape[1], rng)
    subset = vertex_subset(input_vertices.shape[1])
    accel_in = np.linalg.norm(np.diff(input_vertices[:, subset], n=2, axis=0), axis=-1).max()
    worst = max(np.linalg.norm(np.diff(lbs_reference(skin_fit.rest_vertices[subset], skin_fit.bone_indices[subset],
                                                     skin_fit.bone_weights[subset], F[a], t[a]), n=2, axis=0),
                               axis=-1).max() for a in range(animations))
    return float(worst / accel_in)


def _timed_synthesis(fit, faces, single, request, jobs):
    """(seconds of synthesize alone, peak RSS MiB of this process, of its largest worker)."""
    from skinsynth.pipeline.graph import build_graph
    from skinsynth.pipeline.synthesis import synthesize

    analysis = build_graph(fit.rest_vertices, faces, fit.bone_indices, fit.bone_weights, fit.rotations,
                           fit.translations, single_component=single)
    started = time.perf_counter()
    synthesize(analysis.components, fit.rotations, fit.translations, fit.rest_vertices, fit.bone_indices,
               fit.bone_weights, request, jobs=jobs)
    seconds = time.perf_counter() - started
    return seconds, _own_peak_mib(), resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0


def _own_peak_mib():
    """This process's peak resident memory: VmHWM where /proc has it (getrusage's maxrss would
    also count the spawning parent's size, kept across fork and exec on Linux)."""
    try:
        with open("/proc/self/status") as status:
            for row in status:
                if row.startswith("VmHWM:"):
                    return int(row.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _in_fresh_process(function, *args):
    """function(*args) in a newly spawned interpreter, so its peak memory is its own."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn")) as pool:
        return pool.submit(function, *args).result()


def main():
    from skinsynth.gpu import lbs
    from skinsynth.pipeline.graph import build_graph
    from skinsynth.pipeline.skin_fit import fit_skin
    from skinsynth.pipeline.synthesis import Request, synthesize

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only")
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--frames", type=int, default=600)
    args = parser.parse_args()
    for name, vertices, faces, bones in _datasets():
        if args.only and args.only != name:
            continue
        fit = fit_skin(vertices, bones, iterations=30)
        for mode, single in (("multi_component", False), ("single_component", True)):
            analysis = build_graph(fit.rest_vertices, faces, fit.bone_indices, fit.bone_weights, fit.rotations,
                                   fit.translations, single_component=single)
            line = {"dataset": name, "mode": mode, "vertices": int(vertices.shape[1]), "bones": bones,
                    "components": len(analysis.components), "candidate_transitions": analysis.transition_count,
                    "animations": args.count, "frames": args.frames}
            request = Request(count=args.count, frames=args.frames, seed=0)
            try:
                for jobs in (1, 2):  # timed, and memory measured, in a fresh process each
                    seconds, peak, peak_workers = _in_fresh_process(_timed_synthesis, fit, faces, single, request, jobs)
                    line[f"seconds_jobs{jobs}"] = round(seconds, 2)
                    line[f"peak_rss_mib_jobs{jobs}"] = round(peak)
                    if jobs > 1:
                        line["peak_rss_per_worker_mib"] = round(peak_workers)
                result = synthesize(analysis.components, fit.rotations, fit.translations, fit.rest_vertices,
                                    fit.bone_indices, fit.bone_weights, request, jobs=2)
            except Exception as error:  # e.g. a component without an infinite walk
                line["error"] = str(error)
                print(json.dumps(line), flush=True)
                continue
            sample = min(100, args.count)

            def skin(a):
                return lbs(fit.rest_vertices, fit.bone_indices, fit.bone_weights, result.F[a], result.t[a], device="cpu")

            started = time.perf_counter()
            for a in range(sample):
                skin(a)
            line["vertex_cache_seconds_all"] = round((time.perf_counter() - started) * args.count / sample, 1)
            with ThreadPoolExecutor(2) as pool:  # as synthesize --jobs 2 skins its caches
                started = time.perf_counter()
                for _ in pool.map(skin, range(sample)):
                    pass  # each animation's vertices are dropped as soon as they are made
            line["vertex_cache_seconds_all_2_threads"] = round((time.perf_counter() - started) * args.count / sample, 1)
            line["distinct"] = result.distinct
            line["transitions_used"] = int(result.seams_used.sum())
            near, far = smoothness(result, fit, vertices, request.window)
            line["smoothness_ratio"] = round(near, 3)
            # Context for multi-component runs: independent components recombine the input's
            # motions, which can out-accelerate the input away from any splice too.
            line["away_from_splices_ratio"] = None if far is None else round(far, 3)
            recombined = seamless_recombination(analysis, fit, vertices)
            line["seamless_recombination_ratio"] = None if recombined is None else round(recombined, 3)
            print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
