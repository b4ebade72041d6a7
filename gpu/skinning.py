"""Linear-blend skinning of many frames at once: a numpy reference and a warp kernel.

    v_i(t) = sum_k w_ik (R_{b_ik}(t) @ rest_i + t_{b_ik}(t))

Shapes: rest (V, 3); bone indices and weights (V, K); rotations (F, B, 3, 3); translations
(F, B, 3); result (F, V, 3). Weights are used as given (not normalised). A slot whose weight is 0
is padding: its bone index is ignored and may be anything (e.g. -1).
"""

import functools

import numpy as np

from . import runtime

# Bounds the per-chunk working set: ~64 MiB of float64 gathered rotations in the reference, and a
# 192 MiB float32 output buffer on the device (so F*V of any size fits in bounded device memory).
_REFERENCE_CHUNK = 1 << 23
_DEVICE_CHUNK = 1 << 24


def _checked(rest_vertices, bone_indices, bone_weights, rotations, translations):
    """Validated float64/int64 copies; padding slots' indices set to 0 so gathers stay in range."""
    rest = np.asarray(rest_vertices, dtype=np.float64)
    idx = np.asarray(bone_indices)
    w = np.asarray(bone_weights, dtype=np.float64)
    rot = np.asarray(rotations, dtype=np.float64)
    trans = np.asarray(translations, dtype=np.float64)
    if rest.ndim != 2 or rest.shape[1] != 3:
        raise ValueError(f"rest_vertices must be (V, 3), got {rest.shape}")
    if idx.ndim != 2 or idx.shape[0] != rest.shape[0] or w.shape != idx.shape:
        raise ValueError(
            f"bone_indices {idx.shape} and bone_weights {w.shape} must both be (V, K) with V = {rest.shape[0]}"
        )
    if not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"bone_indices must be integers, got {idx.dtype}")
    if rot.ndim != 4 or rot.shape[2:] != (3, 3) or trans.shape != rot.shape[:2] + (3,):
        raise ValueError(
            f"rotations must be (F, B, 3, 3) and translations (F, B, 3), got {rot.shape} and {trans.shape}"
        )
    idx = np.where(w != 0.0, idx, 0).astype(np.int64)
    bones = rot.shape[1]
    if idx.size and (idx.min() < 0 or idx.max() >= bones):
        raise ValueError(f"bone_indices with non-zero weight must lie in [0, {bones}), got {idx.min()}..{idx.max()}")
    return rest, idx, w, rot, trans


def _offsets(rest_offsets, frames, verts):
    """Per-frame rest offsets (F, V, 3) float64 or None (pose-space correctives, added to the rest
    pose before skinning)."""
    if rest_offsets is None:
        return None
    offsets = np.asarray(rest_offsets, dtype=np.float64)
    if offsets.shape != (frames, verts, 3):
        raise ValueError(f"rest_offsets must be ({frames}, {verts}, 3), got {offsets.shape}")
    return offsets


def lbs_reference(rest_vertices, bone_indices, bone_weights, rotations, translations, rest_offsets=None) -> np.ndarray:
    """Skinned vertices (F, V, 3) float64, computed in numpy in float64, in chunks of frames.

    rest_offsets (F, V, 3), optional: added to the rest pose of each frame before skinning."""
    rest, idx, w, rot, trans = _checked(rest_vertices, bone_indices, bone_weights, rotations, translations)
    frames, verts = rot.shape[0], rest.shape[0]
    offsets = _offsets(rest_offsets, frames, verts)
    out = np.zeros((frames, verts, 3))
    step = max(1, _REFERENCE_CHUNK // max(1, 9 * verts))
    for f0 in range(0, frames, step):
        block = out[f0 : f0 + step]
        posed = rest if offsets is None else rest + offsets[f0 : f0 + step]
        for k in range(idx.shape[1]):
            b = idx[:, k]
            spec = "fvij,vj->fvi" if offsets is None else "fvij,fvj->fvi"
            moved = np.einsum(spec, rot[f0 : f0 + step, b], posed) + trans[f0 : f0 + step, b]
            block += w[:, k, None] * moved
    return out


def _blend(idx, w, pivot, d):
    """Per-vertex normalised dual quaternions (f, V, 8) of bone dual quaternions d (f, B, 8):
    weighted sum after flipping those whose real part points away from the pivot bone's."""
    gathered = d[:, idx]  # (f, V, K, 8)
    sign = np.sign(np.einsum("fvkc,fvc->fvk", gathered[..., :4], d[:, pivot, :4]))
    sign[sign == 0.0] = 1.0
    blend = np.einsum("fvk,fvkc->fvc", sign * w, gathered)
    return blend / np.linalg.norm(blend[..., :4], axis=-1, keepdims=True)


def _dq_checked(rest_vertices, bone_indices, bone_weights, dual_quaternions):
    rest, idx, w, _, _ = _checked(rest_vertices, bone_indices, bone_weights,
                                  np.zeros(dual_quaternions.shape[:2] + (3, 3)), np.zeros(dual_quaternions.shape[:2] + (3,)))
    pivot = idx[np.arange(rest.shape[0]), np.argmax(w, axis=1)]
    return rest, idx, w, pivot, np.asarray(dual_quaternions, dtype=np.float64)


def vertex_dual_quaternions(bone_indices, bone_weights, dual_quaternions) -> np.ndarray:
    """Each vertex's blended unit dual quaternion (F, V, 8) under dual-quaternion skinning (the
    rigid motion :func:`dqs_reference` applies to it). dual_quaternions (F, B, 8)."""
    idx = np.asarray(bone_indices)
    _, idx, w, pivot, dq = _dq_checked(np.zeros((idx.shape[0], 3)), idx, bone_weights, dual_quaternions)
    return _blend(idx, w, pivot, dq)


def dqs_reference(rest_vertices, bone_indices, bone_weights, dual_quaternions, rest_offsets=None) -> np.ndarray:
    """Dual-quaternion skinning (Kavan et al. 2007; Feng §6.3) in numpy: vertices (F, V, 3) float64.

    dual_quaternions (F, B, 8): per bone, real then dual part, each (w, x, y, z), mapping rest
    positions to posed ones (need not be unit: the blend is normalised). Per vertex the weighted
    dual quaternions are summed after flipping those whose real part points away from the
    vertex's largest-weight bone (the pivot; OpenUSD's _SkinPointsDQS does the same), then
    normalised and applied: ``p' = p + 2 v0 × (v0 × p + w0 p) + 2 (w0 ve − we v0 + v0 × ve)``.
    rest_offsets (F, V, 3), optional: added to the rest pose of each frame before skinning.
    """
    rest, idx, w, pivot, dq = _dq_checked(rest_vertices, bone_indices, bone_weights, dual_quaternions)
    frames, verts = dq.shape[0], rest.shape[0]
    offsets = _offsets(rest_offsets, frames, verts)
    out = np.empty((frames, verts, 3))
    step = max(1, _REFERENCE_CHUNK // max(1, 8 * verts * idx.shape[1]))
    for f0 in range(0, frames, step):
        blend = _blend(idx, w, pivot, dq[f0 : f0 + step])
        p = rest if offsets is None else rest + offsets[f0 : f0 + step]
        w0, v0, we, ve = blend[..., :1], blend[..., 1:4], blend[..., 4:5], blend[..., 5:8]
        translation = 2.0 * (w0 * ve - we * v0 + np.cross(v0, ve))
        out[f0 : f0 + step] = p + 2.0 * np.cross(v0, np.cross(v0, p) + w0 * p) + translation
    return out


@functools.cache
def _kernel(influences: int, corrected: bool = False):
    # Built on first use so that importing this module does not import warp. K is a compile-time
    # constant (one small module per K) so the slot loop unrolls: 1.4x faster on the CPU than a
    # loop bounded by the array shape. No zero-weight branch either (it costs as much again):
    # padding slots point at bone 0 and add 0 * finite.
    wp = runtime.warp()

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


def lbs(rest_vertices, bone_indices, bone_weights, rotations, translations, device="cpu",
        rest_offsets=None) -> np.ndarray:
    """Skinned vertices (F, V, 3) float64 from one warp launch over (frames, vertices) per chunk.

    Computes in float32 on `device` (any `resolve_device` spelling, e.g. "cpu", "cuda:0", "auto").
    Frames go in chunks of at most 2**24 vertex-frames so device memory stays bounded.
    rest_offsets (F, V, 3), optional: added to the rest pose of each frame first.
    """
    rest, idx, w, rot, trans = _checked(rest_vertices, bone_indices, bone_weights, rotations, translations)
    frames, verts = rot.shape[0], rest.shape[0]
    offsets = _offsets(rest_offsets, frames, verts)
    device = runtime.resolve_device(device)
    out = np.empty((frames, verts, 3))
    if out.size == 0:
        return out
    wp = runtime.warp()
    kernel = _kernel(idx.shape[1], offsets is not None)
    f32 = np.float32
    rest_d = wp.array(rest.astype(f32), dtype=wp.vec3, device=device)
    idx_d = wp.array(idx.astype(np.int32), dtype=wp.int32, device=device)
    w_d = wp.array(w.astype(f32), dtype=wp.float32, device=device)
    rot_d = wp.array(rot.astype(f32), dtype=wp.mat33, device=device)
    trans_d = wp.array(trans.astype(f32), dtype=wp.vec3, device=device)
    step = max(1, _DEVICE_CHUNK // verts)
    buf = wp.empty((min(step, frames), verts), dtype=wp.vec3, device=device)
    none = wp.empty((1, 1), dtype=wp.vec3, device=device)
    for f0 in range(0, frames, step):
        n = min(step, frames - f0)
        shift = none if offsets is None else wp.array(offsets[f0 : f0 + n].astype(f32), dtype=wp.vec3, device=device)
        wp.launch(
            kernel,
            dim=(n, verts),
            inputs=[rest_d, idx_d, w_d, rot_d[f0 : f0 + n], trans_d[f0 : f0 + n], shift],
            outputs=[buf],
            device=device,
        )
        out[f0 : f0 + n] = buf[:n].numpy()  # .numpy() waits for the launch (and copies from a GPU)
    return out
