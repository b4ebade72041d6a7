"""Benchmark LBS of many frames: numpy reference vs warp (cpu, and cuda when present).

Prints one JSON line per mesh size. `seconds` is the median of --repeats calls after one warm-up
(kernel compile / cache load excluded) of the public function, numpy in and float64 numpy out;
`kernel_seconds` times the launch alone on arrays already on the device.

    python benchmarks/lbs.py [--repeats 5] [--sizes 8431 23728 100000]
"""

import argparse
import json

import numpy as np

from skinsynth.gpu import available_devices, lbs, lbs_reference
from skinsynth.gpu.runtime import warp
from timing import median_seconds


def random_rig(rng, verts, bones, frames, influences):
    rest = rng.normal(size=(verts, 3))
    idx = np.stack([rng.permutation(bones)[:influences] for _ in range(verts)])
    w = rng.random((verts, influences))
    w /= w.sum(axis=1, keepdims=True)
    q, _ = np.linalg.qr(rng.normal(size=(frames, bones, 3, 3)))
    return rest, idx, w, q, rng.normal(size=(frames, bones, 3))


def kernel_seconds(rig, device, repeats):
    wp = warp()
    from skinsynth.gpu.kernels.skinning import lbs_kernel

    rest, idx, w, rot, trans = rig
    args = [
        wp.array(rest.astype(np.float32), dtype=wp.vec3, device=device),
        wp.array(idx.astype(np.int32), dtype=wp.int32, device=device),
        wp.array(w.astype(np.float32), dtype=wp.float32, device=device),
        wp.array(rot.astype(np.float32), dtype=wp.mat33, device=device),
        wp.array(trans.astype(np.float32), dtype=wp.vec3, device=device),
        wp.empty((1, 1), dtype=wp.vec3, device=device),  # rest offsets, unread without correctives
    ]
    out = wp.empty((rot.shape[0], rest.shape[0]), dtype=wp.vec3, device=device)

    def launch():
        wp.launch(lbs_kernel(idx.shape[1]), dim=out.shape, inputs=args, outputs=[out], device=device)
        wp.synchronize_device(device)

    return median_seconds(launch, repeats)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[8431, 23728, 100000])
    parser.add_argument("--influences", type=int, default=4)
    parser.add_argument("--bones", type=int, default=60)
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=5)
    opts = parser.parse_args()
    devices = [d for d in available_devices() if d == "cpu" or d == "cuda:0"]
    rng = np.random.default_rng(0)
    for verts in opts.sizes:
        rig = random_rig(rng, verts, opts.bones, opts.frames, opts.influences)
        vertex_frames = verts * opts.frames
        expected = lbs_reference(*rig)
        scale = np.ptp(expected.reshape(-1, 3), axis=0).max()
        record = {"V": verts, "K": opts.influences, "B": opts.bones, "F": opts.frames}
        s = median_seconds(lambda: lbs_reference(*rig), opts.repeats)
        record["numpy"] = {"seconds": s, "vertex_frames_per_s": vertex_frames / s}
        for device in devices:
            s = median_seconds(lambda: lbs(*rig, device=device), opts.repeats)
            k = kernel_seconds(rig, device, opts.repeats)
            err = np.abs(lbs(*rig, device=device) - expected).max() / scale
            record[f"warp_{device.split(':')[0]}"] = {
                "device": device,
                "seconds": s,
                "vertex_frames_per_s": vertex_frames / s,
                "kernel_seconds": k,
                "kernel_vertex_frames_per_s": vertex_frames / k,
                "max_error_rel_bbox": float(err),
            }
        print(json.dumps(record), flush=True)


if __name__ == "__main__":
    main()
