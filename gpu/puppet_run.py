"""The trained puppet's whole run-time path on a warp device (Feng et al. 2008, §6; host side):
the stages of ``gpu.puppet_stages`` chained with the arrays staying on the device between
launches, in chunks of samples, over Python threads on the CPU.

A per-sample rigid world transform is folded into every bone's dual quaternion before skinning
(so the skinning writes world positions directly); the skinning is dual-quaternion (Feng §6.3) or
linear-blend (the composing kernel writes each bone's 3×4 matrix [R | t] instead of its dual
quaternion, and the LBS kernel blends those per vertex); ``reference_run_puppet`` is the same in numpy
(it applies the world transforms to the skinned vertices instead). The host side of the run time
stays in numpy: aligning the controls (``pipeline.puppet.in_place``) and standardising them;
``pipeline.playback.host_inputs`` does both for a ``Puppet`` and world controls.
"""

import threading
import time

import numpy as np

from . import runtime
from .cpu_blas import SOLVE_ROWS, cpu_corrective_offsets, in_threads, solve_with_blas
from .device_arrays import float32_array, float64_array
from .device_puppet import DevicePuppet, Workspace
from .references.puppet import blend_weights, check_skinning
from .validation import checked_run_inputs

# Samples per chunk: at most 2**24 skinned vertices (a 192 MiB float32 output buffer) per launch,
# so any N × V fits in bounded device memory.
_DEVICE_CHUNK = 1 << 24

_timings_lock = threading.Lock()


def _run_chunk(puppet, space, x, c, f, out, device, timings=None, offsets_host=None, skinning="dual-quaternion"):
    """Run the whole path for one chunk of n samples: numpy inputs in, skinned (n, V, 3) into `out`.
    offsets_host: on the CPU, the chunk's corrective offsets (n, V, 3) float32, already computed
    (``cpu_corrective_offsets``; may be ``out`` itself: each vertex is read, then written)."""
    wp = runtime.warp()
    from .kernels.puppet import (compose_kernel, compose_rigid_kernel, corrective_offsets_kernel, frames_kernel,
                                 kernel_vector_kernel, normalise_kernel, predict_kernel, solve_kernel)

    host = puppet.host
    n = x.shape[0]
    stamp = [time.perf_counter()]

    def mark(name):
        if timings is not None:
            wp.synchronize_device(device)
            now = time.perf_counter()
            with _timings_lock:
                timings[name] = timings.get(name, 0.0) + now - stamp[0]
            stamp[0] = now

    x_d = float64_array(x, wp.float64, device)
    solve = c is not None
    if f is not None:
        wp.launch(frames_kernel, dim=n, inputs=[float32_array(f, wp.mat44, device)], outputs=[space.frames[:n]],
                  device=device)
    mark("upload")
    xi, raw, unit, rot, trans = space.xi[:n], space.raw[:n], space.unit[:n], space.rot[:n], space.trans[:n]
    bones = puppet.bones
    wp.launch(kernel_vector_kernel(host.kernel, int(host.degree)), dim=(n, xi.shape[1]),
              inputs=[x_d, puppet.training, float(host.offset)], outputs=[xi], device=device)
    mark("kernel_vectors")
    wp.launch(predict_kernel, dim=(n, bones), inputs=[xi, puppet.predictor, puppet.bias], outputs=[raw],
              device=device)
    mark("predict")
    wp.launch(normalise_kernel, dim=(n, bones), inputs=[raw], outputs=[unit, rot, trans], device=device)
    mark("normalise")
    if solve and device == "cpu":
        solve_with_blas(puppet.host_operators, rot.numpy(), c, trans.numpy(), space.solved[:n].numpy())
        mark("solve_translations")
    elif solve:
        wp.launch(solve_kernel, dim=(n, bones),
                  inputs=[rot, float32_array(c, wp.vec3, device), trans, puppet.gamma, puppet.control_operator,
                          puppet.prior],
                  outputs=[space.solved[:n]], device=device)
        mark("solve_translations")
    linear = skinning == "linear"
    # linear: each bone's [R | t] straight from its composed dual quaternion, in the same launch
    composed = space.matrices[:n] if linear else space.final[:n]
    wp.launch(compose_rigid_kernel if linear else compose_kernel, dim=(n, bones),
              inputs=[unit, space.solved[:n], space.frames[:n], int(solve), int(f is not None)],
              outputs=[composed], device=device)
    mark("compose")
    offsets = None
    if offsets_host is not None:
        offsets = wp.array(offsets_host, dtype=wp.vec3, device="cpu", copy=False)
    elif puppet.corrective_offsets is not None:
        offsets = space.offsets[:n]
        w = blend_weights(host, xi.numpy(), x)  # small (n, n_p), float64 on the host
        wp.launch(corrective_offsets_kernel, dim=offsets.shape,
                  inputs=[float64_array(w, wp.float64, device), puppet.corrective_offsets],
                  outputs=[offsets], device=device)
        mark("correctives")
    direct = (device == "cpu" and out.dtype == np.float32 and out.flags.c_contiguous)
    if direct:  # skin straight into the caller's float32 buffer: no copy at all on the CPU
        target = wp.array(out.reshape(n, -1, 3), dtype=wp.vec3, device="cpu", copy=False)
    else:
        target = space.out[:n]
    if linear:
        puppet.skin.launch_linear(composed, target, device, offsets)
    else:
        puppet.skin.launch(composed, target, device, offsets)
    mark("skin")
    if not direct:
        out[...] = target.numpy()
    mark("download")


def run_puppet(puppet, standardised_controls, controls_in_place=None, world_frames=None, translation_solver=True,
               device="cpu", out=None, threads=1, timings=None, skinning="dual-quaternion") -> np.ndarray:
    """The trained puppet's whole run-time path on a device: vertices (N, V, 3).

    puppet: a ``pipeline.puppet.Puppet``, ``PuppetArrays`` or :class:`DevicePuppet` (uploaded
    once; its device wins over ``device``). Per sample n (frames × characters, flattened):
    standardised_controls (N, d) the in-place control vector, standardised
    (``puppet.kernel.standardise``); controls_in_place (N, n_c, 3) the in-place control points
    (needed only with the translation solver); world_frames (N, 4, 4) rigid column-vector
    homogeneous transforms from the in-place result to the world, or None for in-place output.
    ``pipeline.playback.host_inputs`` computes all three from world controls.

    Stages (all on the device, arrays stay there between launches): ξ, d = M ξ + m,
    normalise, [t = Γ·R + Q·c + Π·t̂], rebuild each bone's dual quaternion with t and compose
    it with the sample's world frame, then skinning: ``skinning`` "dual-quaternion" (Feng §6.3) or
    "linear" (each bone's rotation and translation from its composed unit dual quaternion, in the
    composing launch, then linear-blend skinning; the correctives' rest offsets are added to the
    rest pose first either way). Samples go in chunks of at most 2**24 skinned vertices.

    out: optional (N, V, 3) array to fill (float32 avoids the float64 conversion; on the CPU a
    C-contiguous float32 ``out`` is written in place by the kernel); returned. Default: a new
    float64 array. threads: on the CPU, split the samples over this many Python threads (warp
    releases the GIL during CPU launches; each thread runs the whole path on its slice).
    timings: optional dict, accumulates seconds per stage (synchronises after each stage).
    """
    check_skinning(skinning)
    dev_puppet = puppet if isinstance(puppet, DevicePuppet) else DevicePuppet(puppet, device)
    device = dev_puppet.device
    x, c, f = checked_run_inputs(dev_puppet.host, standardised_controls, controls_in_place, world_frames,
                                 translation_solver)
    samples, verts = x.shape[0], dev_puppet.verts
    if out is None:
        out = np.empty((samples, verts, 3))
    elif out.shape != (samples, verts, 3):
        raise ValueError(f"out must be ({samples}, {verts}, 3), got {out.shape}")
    if samples == 0:
        return out
    threads = max(1, min(int(threads), samples)) if device == "cpu" else 1
    step = max(1, min(_DEVICE_CHUNK // verts, -(-samples // threads)))
    if device == "cpu":  # chunks start on the translation solve's blocks (cpu_blas.SOLVE_ROWS)
        step = max(SOLVE_ROWS, step // SOLVE_ROWS * SOLVE_ROWS)
    offsets = None
    if device == "cpu" and dev_puppet.host.has_correctives:
        direct = out.dtype == np.float32 and out.flags.c_contiguous
        offsets = out if direct else np.empty((samples, verts, 3), dtype=np.float32)
        cpu_corrective_offsets(dev_puppet, x, offsets, threads)

    def work(lo, hi):
        space = Workspace(min(step, hi - lo), dev_puppet, device)
        for n0 in range(lo, hi, step):
            n1 = min(n0 + step, hi)
            _run_chunk(dev_puppet, space, x[n0:n1], None if c is None else c[n0:n1],
                       None if f is None else f[n0:n1], out[n0:n1], device, timings,
                       None if offsets is None else offsets[n0:n1], skinning)

    if threads == 1:
        work(0, samples)
        return out
    blocks = -(-samples // SOLVE_ROWS)  # threads start on the solve's blocks too
    bounds = np.minimum(np.linspace(0, blocks, threads + 1).astype(int) * SOLVE_ROWS, samples)
    # Each thread already has a core: a multi-threaded BLAS in the translation solve would
    # oversubscribe them (measured: 2,000 → 2,250 face frames/s with one BLAS thread each).
    in_threads(work, [(lo, hi) for lo, hi in zip(bounds[:-1], bounds[1:]) if hi > lo])
    return out
