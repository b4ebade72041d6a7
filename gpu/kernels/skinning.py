"""Skinning kernels, each specialised on the number of influences K and on whether per-frame rest
offsets (pose-space correctives) are added to the rest pose first.

``blended_lbs_kernel`` is the puppet's linear skinning: each bone's transform one ``vec12`` (its
3×4 matrix [R | t], row after row), blended per vertex before it is applied, so one gather of 12
numbers per influence and one matrix-vector product per vertex (``lbs_kernel``, which takes
rotations and translations apart, gathers twice per influence and transforms every influence).

K is a compile-time constant (one small module per K) so the slot loop unrolls: 1.4x faster on
the CPU than a loop bounded by the array shape. No zero-weight branch either (it costs as much
again): padding slots point at bone 0 and add 0 * finite. Launched by ``gpu.skinning``.
"""

import functools

from .. import runtime
from .dual_quaternion import vec8

wp = runtime.warp()

#: A bone's 3×4 matrix [R | t], its rows one after another: (R00, R01, R02, t0, R10, …, t2).
vec12 = wp.types.vector(length=12, dtype=wp.float32)


@functools.cache
def lbs_kernel(influences: int, corrected: bool = False):
    """Linear-blend skinning over (frames F, vertices V): v = Σ_k w_k (R_{b_k} p + t_{b_k})."""

    @wp.kernel(module="unique")
    def lbs_kernel(
        rest: wp.array(dtype=wp.vec3),
        bone_indices: wp.array2d(dtype=wp.int32),
        bone_weights: wp.array2d(dtype=wp.float32),
        rotations: wp.array2d(dtype=wp.mat33),
        translations: wp.array2d(dtype=wp.vec3),
        offsets: wp.array2d(dtype=wp.vec3),  # (F, V) rest offsets, read only when corrected
        out: wp.array2d(dtype=wp.vec3),
    ):
        f, i = wp.tid()
        p = rest[i]
        if wp.static(corrected):
            p = p + offsets[f, i]
        acc = wp.vec3(0.0)
        for k in range(influences):
            b = bone_indices[i, k]
            acc += bone_weights[i, k] * (rotations[f, b] @ p + translations[f, b])
        out[f, i] = acc

    return lbs_kernel


@functools.cache
def blended_lbs_kernel(influences: int, corrected: bool = False):
    """Linear-blend skinning over (samples n, vertices V) by bone matrices (n, B) vec12:
    v = (Σ_k w_k A_{b_k}) [p; 1], which equals Σ_k w_k (R_{b_k} p + t_{b_k}) up to rounding. On the
    CPU (horse-sized: 8,431 vertices, 150 bones, K = 4) about 1.2× as fast as the two-gather
    ``lbs_kernel`` and 1.5× ``dq_skin_kernel`` (benchmarks/play.py, stage "skin")."""

    @wp.kernel(module="unique")
    def blended_lbs_kernel(
        rest: wp.array(dtype=wp.vec3),
        bone_indices: wp.array2d(dtype=wp.int32),
        bone_weights: wp.array2d(dtype=wp.float32),
        matrices: wp.array2d(dtype=vec12),  # (n, B)
        offsets: wp.array2d(dtype=wp.vec3),  # (n, V) rest offsets, read only when corrected
        out: wp.array2d(dtype=wp.vec3),  # (n, V)
    ):
        f, i = wp.tid()
        a = bone_weights[i, 0] * matrices[f, bone_indices[i, 0]]
        for k in range(1, influences):
            a += bone_weights[i, k] * matrices[f, bone_indices[i, k]]
        p = rest[i]
        if wp.static(corrected):
            p = p + offsets[f, i]
        out[f, i] = wp.vec3(a[0] * p[0] + a[1] * p[1] + a[2] * p[2] + a[3],
                            a[4] * p[0] + a[5] * p[1] + a[6] * p[2] + a[7],
                            a[8] * p[0] + a[9] * p[1] + a[10] * p[2] + a[11])

    return blended_lbs_kernel


@functools.cache
def dq_skin_kernel(influences: int, corrected: bool = False):
    """Dual-quaternion skinning (Kavan et al. 2007; Feng §6.3) over (samples n, vertices V).

    Slots come sorted by weight, largest first (stable, so ties keep the first, as argmax does):
    slot 0 is the pivot, whose sign is never flipped, so no extra gather. Padding slots point at
    bone 0 with weight 0. The normalisation is folded into one scale: with the blend (a0, av; ae,
    aev) and n² = a0² + |av|², dqs_reference's p + 2 v0 × (v0 × p + w0 p) + 2 (w0 ve − we v0 +
    v0 × ve) on the normalised blend equals p + (2/n²) (av × (av × p + a0 p + aev) + a0 aev − ae av):
    no square root (1.5× faster on the CPU than normalising first).
    """

    @wp.kernel(module="unique")
    def dq_skin_kernel(
        rest: wp.array(dtype=wp.vec3),
        bone_indices: wp.array2d(dtype=wp.int32),  # (V, K), slot 0 the largest weight
        bone_weights: wp.array2d(dtype=wp.float32),
        dual_quaternions: wp.array2d(dtype=vec8),  # (n, B)
        offsets: wp.array2d(dtype=wp.vec3),  # (n, V) rest offsets, read only when corrected
        out: wp.array2d(dtype=wp.vec3),  # (n, V)
    ):
        f, i = wp.tid()
        pivot = dual_quaternions[f, bone_indices[i, 0]]
        acc = bone_weights[i, 0] * pivot
        for k in range(1, influences):
            q = dual_quaternions[f, bone_indices[i, k]]
            dot = q[0] * pivot[0] + q[1] * pivot[1] + q[2] * pivot[2] + q[3] * pivot[3]
            w = bone_weights[i, k]
            acc += wp.where(dot < 0.0, -w, w) * q
        scale = 2.0 / (acc[0] * acc[0] + acc[1] * acc[1] + acc[2] * acc[2] + acc[3] * acc[3])
        a0 = acc[0]
        av = wp.vec3(acc[1], acc[2], acc[3])
        aev = wp.vec3(acc[5], acc[6], acc[7])
        p = rest[i]
        if wp.static(corrected):
            p = p + offsets[f, i]
        out[f, i] = p + scale * (wp.cross(av, wp.cross(av, p) + a0 * p + aev) + a0 * aev - acc[4] * av)

    return dq_skin_kernel
