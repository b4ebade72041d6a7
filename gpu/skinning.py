"""Linear-blend and dual-quaternion skinning of many frames at once on a warp device (host side:
validation, uploads, chunks, launches of ``gpu.kernels.skinning``).

Shapes as the references' (``gpu.references.skinning``): rest (V, 3); bone indices and weights
(V, K), a zero weight a padding slot; rotations (F, B, 3, 3) and translations (F, B, 3), bone
matrices [R | t] (F, B, 3, 4) (``linear_skin``, the puppet's linear skinning), or dual
quaternions (F, B, 8); result (F, V, 3) float64, computed in float32.
"""

import numpy as np

from . import runtime
from .device_arrays import float32_array
from .validation import checked_offsets, checked_skin

# Bounds the per-chunk working set: a 192 MiB float32 output buffer on the device (so F*V of any
# size fits in bounded device memory).
_DEVICE_CHUNK = 1 << 24


def lbs(rest_vertices, bone_indices, bone_weights, rotations, translations, device="cpu",
        rest_offsets=None) -> np.ndarray:
    """Skinned vertices (F, V, 3) float64 from one warp launch over (frames, vertices) per chunk.

    Computes in float32 on `device` (any `resolve_device` spelling, e.g. "cpu", "cuda:0", "auto").
    Frames go in chunks of at most 2**24 vertex-frames so device memory stays bounded.
    rest_offsets (F, V, 3), optional: added to the rest pose of each frame first.
    """
    rest, idx, w, rot, trans = checked_skin(rest_vertices, bone_indices, bone_weights, rotations, translations)
    frames, verts = rot.shape[0], rest.shape[0]
    offsets = checked_offsets(rest_offsets, frames, verts)
    device = runtime.resolve_device(device)
    out = np.empty((frames, verts, 3))
    if out.size == 0:
        return out
    wp = runtime.warp()
    from .kernels.skinning import lbs_kernel

    kernel = lbs_kernel(idx.shape[1], offsets is not None)
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


def skin_arrays(rest_vertices, bone_indices, bone_weights, bones):
    """Validated rest, indices (padding -> 0) and weights, numpy, each vertex's slots sorted by
    weight, largest first (stably: the first largest is slot 0, the pivot of dqs_reference)."""
    rest, idx, w, _, _ = checked_skin(rest_vertices, bone_indices, bone_weights, np.zeros((0, bones, 3, 3)),
                                      np.zeros((0, bones, 3)))
    order = np.argsort(-w, axis=1, kind="stable")
    return rest, np.take_along_axis(idx, order, axis=1), np.take_along_axis(w, order, axis=1)


class SkinBuffers:
    """Rest (V,) vec3, bone indices and weights (V, K), slots sorted by :func:`skin_arrays`, on the
    device, for dual-quaternion skinning (:meth:`launch`) or linear-blend skinning by bone
    matrices (:meth:`launch_linear`)."""

    def __init__(self, rest, idx, w, device):
        wp = runtime.warp()
        self.verts, self.influences = idx.shape
        self.rest = float32_array(rest, wp.vec3, device)
        self.idx = wp.array(idx.astype(np.int32), dtype=wp.int32, device=device)
        self.w = float32_array(w, wp.float32, device)

    def launch(self, dual_quaternions, out, device, offsets=None):
        """Skin into out (n, V) vec3 by dual_quaternions (n, B) vec8; offsets (n, V) vec3 added to
        the rest pose first, or None."""
        wp = runtime.warp()
        from .kernels.skinning import dq_skin_kernel

        corrected = offsets is not None
        if not corrected:
            offsets = wp.empty((1, 1), dtype=wp.vec3, device=device)
        wp.launch(dq_skin_kernel(self.influences, corrected), dim=out.shape,
                  inputs=[self.rest, self.idx, self.w, dual_quaternions, offsets], outputs=[out], device=device)

    def launch_linear(self, matrices, out, device, offsets=None):
        """Linear-blend skin into out (n, V) vec3 by bone matrices (n, B) vec12 (each bone's
        [R | t], ``kernels.skinning.vec12``); offsets (n, V) vec3 added to the rest pose first, or None."""
        wp = runtime.warp()
        from .kernels.skinning import blended_lbs_kernel

        corrected = offsets is not None
        if not corrected:
            offsets = wp.empty((1, 1), dtype=wp.vec3, device=device)
        wp.launch(blended_lbs_kernel(self.influences, corrected), dim=out.shape,
                  inputs=[self.rest, self.idx, self.w, matrices, offsets], outputs=[out], device=device)


def linear_skin(rest_vertices, bone_indices, bone_weights, matrices, device="cpu", rest_offsets=None) -> np.ndarray:
    """Linear-blend skinning by bone matrices, vertices (N, V, 3) float64: ``lbs_reference`` with
    rotations matrices[..., :3] and translations matrices[..., 3], by the puppet's linear kernel
    (``blended_lbs_kernel``: each vertex's matrices blended, then applied) in one launch over
    (samples, vertices) per chunk of at most 2**24 vertex-samples. matrices (N, B, 3, 4) [R | t];
    rest_offsets (N, V, 3), optional: added to the rest pose of each sample first."""
    m = np.asarray(matrices)
    if m.ndim != 4 or m.shape[2:] != (3, 4):
        raise ValueError(f"bone matrices must be (N, B, 3, 4), got {m.shape}")
    rest, idx, w = skin_arrays(rest_vertices, bone_indices, bone_weights, m.shape[1])
    samples, verts = m.shape[0], rest.shape[0]
    offsets = checked_offsets(rest_offsets, samples, verts)
    if samples * verts == 0:
        return np.empty((samples, verts, 3))
    device = runtime.resolve_device(device)
    runtime.warp()
    from .kernels.skinning import vec12

    skin = SkinBuffers(rest, idx, w, device)
    return _skin_in_chunks(skin.launch_linear, float32_array(m.reshape(samples, -1, 12), vec12, device), offsets,
                           samples, verts, device)


def _skin_in_chunks(launch, transforms, rest_offsets, samples, verts, device):
    """(N, V, 3) float64 vertices from ``launch(transforms[chunk], out, device, offsets[chunk])``
    (a :class:`SkinBuffers` launcher; transforms on the device, rest_offsets (N, V, 3) or None
    on the host), in chunks of at most 2**24 vertex-samples through one device buffer."""
    wp = runtime.warp()
    out = np.empty((samples, verts, 3))
    step = max(1, _DEVICE_CHUNK // verts)
    buf = wp.empty((min(step, samples), verts), dtype=wp.vec3, device=device)
    offsets = None if rest_offsets is None else float32_array(rest_offsets, wp.vec3, device)
    for n0 in range(0, samples, step):
        n = min(step, samples - n0)
        launch(transforms[n0 : n0 + n], buf[:n], device, None if offsets is None else offsets[n0 : n0 + n])
        out[n0 : n0 + n] = buf[:n].numpy()
    return out


def dq_skin(rest_vertices, bone_indices, bone_weights, dual_quaternions, device="cpu", rest_offsets=None) -> np.ndarray:
    """Dual-quaternion skinning, vertices (N, V, 3) float64: ``dqs_reference`` in one launch over
    (samples, vertices) per chunk of at most 2**24 vertex-samples. dual_quaternions (N, B, 8);
    rest_offsets (N, V, 3), optional: added to the rest pose of each sample first."""
    dq = np.asarray(dual_quaternions)
    if dq.ndim != 3 or dq.shape[2] != 8:
        raise ValueError(f"dual quaternions must be (N, B, 8), got {dq.shape}")
    rest, idx, w = skin_arrays(rest_vertices, bone_indices, bone_weights, dq.shape[1])
    samples, verts = dq.shape[0], rest.shape[0]
    rest_offsets = checked_offsets(rest_offsets, samples, verts)
    if samples * verts == 0:
        return np.empty((samples, verts, 3))
    device = runtime.resolve_device(device)
    runtime.warp()
    from .kernels.dual_quaternion import vec8

    skin = SkinBuffers(rest, idx, w, device)
    return _skin_in_chunks(skin.launch, float32_array(dq, vec8, device), rest_offsets, samples, verts, device)
