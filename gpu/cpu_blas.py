"""The CPU path's matrix products: on warp's CPU device the translation solve and the correctives'
blend run as float32 BLAS products instead of kernels (6× and 80× faster), over Python threads
with one BLAS thread each (host code, numpy)."""

import threading

import numpy as np

from .references.puppet import blend_weights, kernel_vectors_reference

#: Samples per block of the CPU correctives' matrix products. BLAS rounds a row differently
#: depending on where it sits in a product, so the blocks are fixed (rows kR…kR+R−1 of the
#: whole run, one BLAS thread) whatever the chunks and threads: byte-identical output.
_CORRECTIVE_ROWS = 64
#: Samples per block of the CPU translation solve's products, for the same reason: the run's
#: chunks and threads start on multiples of it (``run_puppet``), so each block holds the same
#: samples at the same rows whatever they are. (OpenBLAS's SkylakeX kernels happened to round a
#: row alike anywhere; its generic ones, as another CPU runs them, did not: play --threads 1 and
#: 2 differed in the last bits.)
SOLVE_ROWS = 64


def solve_with_blas(operators, rotations, controls, predicted, out):
    """t = Γ·R + Q·c + Π·t̂ as float32 matrix products into ``out`` (n, B, 3) (CPU views of the
    device arrays, so nothing is copied back): rotations (n, B, 3, 3), controls (n, n_c, 3),
    predicted t̂ (n, B, 3); operators the transposed Γ (3B, B), Q (n_c, B), Π (B, B) of
    ``DevicePuppet.host_operators``. Rows of each product are (sample, axis a). The products go
    in blocks of :data:`SOLVE_ROWS` samples from the first, with one BLAS thread, so a sample's
    rounding depends only on its place in its block (byte-identical whatever the caller's chunks,
    when they start on multiples of it)."""
    from threadpoolctl import threadpool_limits

    gamma_t, control_t, prior_t = operators
    n, bones = rotations.shape[:2]
    controls = np.asarray(controls, dtype=np.float32)
    with threadpool_limits(limits=1, user_api="blas"):
        for lo in range(0, n, SOLVE_ROWS):
            hi = min(lo + SOLVE_ROWS, n)
            r = rotations[lo:hi].transpose(0, 2, 1, 3).reshape((hi - lo) * 3, bones * 3)  # row (n, a), column (k, c)
            t = r @ gamma_t
            t += controls[lo:hi].transpose(0, 2, 1).reshape((hi - lo) * 3, -1) @ control_t
            t += predicted[lo:hi].transpose(0, 2, 1).reshape((hi - lo) * 3, bones) @ prior_t
            out[lo:hi] = t.reshape(hi - lo, 3, bones).transpose(0, 2, 1)


def cpu_corrective_offsets(puppet, x, out, threads):
    """Corrective rest offsets of all samples into out (N, V, 3) float32 for standardised controls
    x (N, d) of the ``DevicePuppet`` ``puppet``: per fixed block, ξ and the blend weights in
    float64 (numpy), then Σ_j w_j O_j as one float32 product (80× the corrective kernel's speed on
    the CPU; the kernel serves CUDA). Blocks go round-robin to ``threads``."""
    host = puppet.host
    flat = out.reshape(out.shape[0], -1)
    starts = range(0, x.shape[0], _CORRECTIVE_ROWS)

    def work(first):
        for start in starts[first::threads]:
            stop = start + _CORRECTIVE_ROWS
            xi = kernel_vectors_reference(x[start:stop], host.training_controls, host.kernel, host.offset, host.degree)
            w = blend_weights(host, xi, x[start:stop])
            np.matmul(w.astype(np.float32), puppet.host_offsets, out=flat[start:stop])

    in_threads(work, [(t,) for t in range(min(threads, len(starts)))])


def in_threads(work, arguments):
    """work(*a) for each a of arguments, each in its own Python thread (one BLAS thread each:
    the threads already hold the cores, and one BLAS thread keeps products byte-identical)."""
    from threadpoolctl import threadpool_limits

    errors = []

    def guarded(*a):
        try:
            work(*a)
        except BaseException as exc:  # re-raised in the caller's thread
            errors.append(exc)

    with threadpool_limits(limits=1, user_api="blas"):
        if len(arguments) == 1:
            work(*arguments[0])
        else:
            pool = [threading.Thread(target=guarded, args=a) for a in arguments]
            for t in pool:
                t.start()
            for t in pool:
                t.join()
    if errors:
        raise errors[0]
