"""The skin fit's two heavy steps on a warp device, for ``fit-skin --device cuda`` (host side:
uploads, scratch, one launch each of ``gpu.kernels.skin_fit``). Each vertex and each frame is
independent, so a launch gives the same result however the device schedules it; on the CPU the
kernels are tested against the numpy references."""

import numpy as np

from . import runtime

MAX_CANDIDATES = 16  # a vertex's candidate bones (2K = 8 by default); scratch is sized by the call


def solve_vertex_weights_warp(products, rest_h, chosen, linear, start, squared_norm, max_influences, device,
                              ridge=1e-10, tolerance=1e-12):
    """:func:`skinsynth.pipeline.skin.vertex_weights.solve_vertex_weights` as one warp launch on
    ``device``: (bone_indices (V, K) int32, bone_weights (V, K), squared error (V,))."""
    wp = runtime.warp()
    from .kernels.skin_fit import vertex_weights

    bones = products.shape[0]
    count, c = chosen.shape
    k = min(max_influences, c)
    if c > MAX_CANDIDATES:
        raise ValueError(f"at most {MAX_CANDIDATES} candidate bones per vertex on a warp device (got {c})")

    def up(array, dtype):
        return wp.array(np.ascontiguousarray(array, dtype=dtype), device=device)

    f64, i32 = np.float64, np.int32
    scratch = dict(gram=wp.empty((count, c, c), dtype=wp.float64, device=device),
                   work=wp.empty((count, c, c), dtype=wp.float64, device=device),
                   sub_linear=wp.empty((count, c), dtype=wp.float64, device=device),
                   weights=wp.empty((count, c), dtype=wp.float64, device=device),
                   free=wp.empty((count, c), dtype=wp.int32, device=device),
                   kkt=wp.empty((count, c + 1, c + 2), dtype=wp.float64, device=device),
                   z=wp.empty((count, c), dtype=wp.float64, device=device),
                   ratio=wp.empty((count, c), dtype=wp.float64, device=device),
                   keep=wp.empty((count, c), dtype=wp.int32, device=device),
                   order=wp.empty((count, c), dtype=wp.int32, device=device),
                   taken=wp.empty((count, c), dtype=wp.int32, device=device))
    out_bones = wp.empty((count, k), dtype=wp.int32, device=device)
    out_weights = wp.empty((count, k), dtype=wp.float64, device=device)
    out_error = wp.empty(count, dtype=wp.float64, device=device)
    wp.launch(vertex_weights, dim=count, device=device,
              inputs=[up(products.reshape(bones * bones, 16), f64), bones, up(rest_h, f64), up(chosen, i32),
                      up(linear, f64), up(start, f64), up(squared_norm, f64), k, f64(ridge), f64(tolerance),
                      *scratch.values(), out_bones, out_weights, out_error])
    return out_bones.numpy(), out_weights.numpy(), out_error.numpy()


def sweep_bone_transforms_warp(transforms, p, q, device):
    """:func:`skinsynth.pipeline.skin.transform_sweep.sweep_bone_transforms` as one warp launch (a
    thread per frame) on ``device``: the updated transforms (F, B, 3, 4)."""
    wp = runtime.warp()
    from .kernels.skin_fit import bone_sweep

    coupled = q[:, :, 3, 3] > 0.0
    order = np.flatnonzero(np.diag(coupled)).astype(np.int32)
    out = wp.array(np.ascontiguousarray(transforms, dtype=np.float64), device=device)
    wp.launch(bone_sweep, dim=transforms.shape[0], device=device,
              inputs=[out, wp.array(np.ascontiguousarray(p, dtype=np.float64), device=device),
                      wp.array(np.ascontiguousarray(q, dtype=np.float64), device=device),
                      wp.array(order, device=device), wp.array(coupled.astype(np.int32), device=device)])
    return out.numpy()
