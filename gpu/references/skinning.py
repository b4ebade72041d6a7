"""Linear-blend and dual-quaternion skinning of many frames at once, in numpy (float64).

    v_i(t) = sum_k w_ik (R_{b_ik}(t) @ rest_i + t_{b_ik}(t))

Shapes: rest (V, 3); bone indices and weights (V, K); rotations (F, B, 3, 3); translations
(F, B, 3); dual quaternions (F, B, 8); result (F, V, 3). Weights are used as given (not
normalised). A slot whose weight is 0 is padding: its bone index is ignored and may be anything
(e.g. -1). The warp versions are ``gpu.skinning.lbs`` and ``gpu.skinning.dq_skin``.
"""

import numpy as np

from ..validation import checked_offsets, checked_skin

# Bounds the per-chunk working set: ~64 MiB of float64 gathered rotations.
_REFERENCE_CHUNK = 1 << 23


def lbs_reference(rest_vertices, bone_indices, bone_weights, rotations, translations, rest_offsets=None) -> np.ndarray:
    """Skinned vertices (F, V, 3) float64, computed in numpy in float64, in chunks of frames.

    rest_offsets (F, V, 3), optional: added to the rest pose of each frame before skinning."""
    rest, idx, w, rot, trans = checked_skin(rest_vertices, bone_indices, bone_weights, rotations, translations)
    frames, verts = rot.shape[0], rest.shape[0]
    offsets = checked_offsets(rest_offsets, frames, verts)
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
    rest, idx, w, _, _ = checked_skin(rest_vertices, bone_indices, bone_weights,
                                      np.zeros(dual_quaternions.shape[:2] + (3, 3)),
                                      np.zeros(dual_quaternions.shape[:2] + (3,)))
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
    offsets = checked_offsets(rest_offsets, frames, verts)
    out = np.empty((frames, verts, 3))
    step = max(1, _REFERENCE_CHUNK // max(1, 8 * verts * idx.shape[1]))
    for f0 in range(0, frames, step):
        blend = _blend(idx, w, pivot, dq[f0 : f0 + step])
        p = rest if offsets is None else rest + offsets[f0 : f0 + step]
        w0, v0, we, ve = blend[..., :1], blend[..., 1:4], blend[..., 4:5], blend[..., 5:8]
        translation = 2.0 * (w0 * ve - we * v0 + np.cross(v0, ve))
        out[f0 : f0 + step] = p + 2.0 * np.cross(v0, np.cross(v0, p) + w0 * p) + translation
    return out
