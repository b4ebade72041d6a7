"""The skin fit's two heavy steps as warp kernels, for ``fit-skin --device cuda``.

The same algorithms as the numba steps of ``pipeline`` (``vertex_weights``, ``transform_sweep``)
and their numpy references, step for step: one thread per vertex solves its simplex QP over its
candidate bones (active set, Gaussian elimination on the KKT system) and re-solves the K
largest; one thread per frame sweeps the bones in order (weighted Procrustes, Gauss-Seidel),
with warp's 3×3 SVD for the polar factor. Everything in float64. Each vertex and each frame is
independent, so a launch gives the same result however the device schedules it; on the CPU the
kernels are tested against the numpy references.
"""

import functools

import numpy as np

from . import runtime

MAX_CANDIDATES = 16  # a vertex's candidate bones (2K = 8 by default); scratch is sized by the call


@functools.cache
def _kernels():
    wp = runtime.warp()
    tiny = wp.constant(wp.float64(np.finfo(np.float64).tiny))

    @wp.func
    def solve_free(i: int, n: int, gram: wp.array3d(dtype=wp.float64), linear: wp.array2d(dtype=wp.float64),
                   free: wp.array2d(dtype=wp.int32), kkt: wp.array3d(dtype=wp.float64),
                   z: wp.array2d(dtype=wp.float64)):
        m = n + 1
        for a in range(n):
            for b in range(n):
                kkt[i, a, b] = wp.float64(0.0)
                if free[i, a] != 0 and free[i, b] != 0:
                    kkt[i, a, b] = gram[i, a, b]
            kkt[i, a, n] = wp.float64(0.0)
            kkt[i, n, a] = wp.float64(0.0)
            kkt[i, a, m] = wp.float64(0.0)
            if free[i, a] != 0:
                kkt[i, a, n] = wp.float64(1.0)
                kkt[i, n, a] = wp.float64(1.0)
                kkt[i, a, m] = linear[i, a]
            else:
                kkt[i, a, a] = wp.float64(1.0)
        kkt[i, n, n] = wp.float64(0.0)
        kkt[i, n, m] = wp.float64(1.0)
        for col in range(m):
            pivot = col
            for row in range(col + 1, m):
                if wp.abs(kkt[i, row, col]) > wp.abs(kkt[i, pivot, col]):
                    pivot = row
            if pivot != col:
                for j in range(col, m + 1):
                    held = kkt[i, col, j]
                    kkt[i, col, j] = kkt[i, pivot, j]
                    kkt[i, pivot, j] = held
            for row in range(col + 1, m):
                factor = kkt[i, row, col] / kkt[i, col, col]
                if factor != wp.float64(0.0):
                    for j in range(col, m + 1):
                        kkt[i, row, j] = kkt[i, row, j] - factor * kkt[i, col, j]
        for back in range(m):
            row = m - 1 - back
            total = kkt[i, row, m]
            for j in range(row + 1, m):
                total = total - kkt[i, row, j] * kkt[i, j, m]
            kkt[i, row, m] = total / kkt[i, row, row]
        for a in range(n):
            z[i, a] = wp.float64(0.0)
            if free[i, a] != 0:
                z[i, a] = kkt[i, a, m]
        return kkt[i, n, m]

    @wp.func
    def simplex_qp(i: int, n: int, ridge: wp.float64, tolerance: wp.float64, gram: wp.array3d(dtype=wp.float64),
                   linear: wp.array2d(dtype=wp.float64), weights: wp.array2d(dtype=wp.float64),
                   free: wp.array2d(dtype=wp.int32), kkt: wp.array3d(dtype=wp.float64),
                   z: wp.array2d(dtype=wp.float64), ratio: wp.array2d(dtype=wp.float64)):
        scale = wp.float64(0.0)
        for a in range(n):
            scale = scale + gram[i, a, a]
        scale = wp.max(scale / wp.float64(n), tiny)
        for a in range(n):
            gram[i, a, a] = gram[i, a, a] + ridge * scale
            free[i, a] = 0
            if weights[i, a] > wp.float64(0.0):
                free[i, a] = 1
        for _step in range(4 * n):
            nu = solve_free(i, n, gram, linear, free, kkt, z)
            blocked = int(0)
            for a in range(n):
                if free[i, a] != 0 and z[i, a] < wp.float64(0.0):
                    blocked = 1
            if blocked == 0:
                worst = int(0)
                least = wp.float64(1.0e300)
                for a in range(n):
                    value = wp.float64(0.0)
                    if free[i, a] == 0:
                        total = nu - linear[i, a]
                        for b in range(n):
                            total = total + gram[i, a, b] * z[i, b]
                        value = total / scale
                    if value < least:
                        worst = a
                        least = value
                for a in range(n):
                    weights[i, a] = z[i, a]
                if least >= -tolerance:
                    return
                free[i, worst] = 1
            else:
                alpha = wp.float64(1.0e300)
                for a in range(n):
                    ratio[i, a] = wp.float64(1.0e300)
                    if free[i, a] != 0 and z[i, a] < wp.float64(0.0):
                        ratio[i, a] = weights[i, a] / wp.max(weights[i, a] - z[i, a], tiny)
                        alpha = wp.min(alpha, ratio[i, a])
                alpha = wp.min(wp.max(alpha, wp.float64(0.0)), wp.float64(1.0))
                total = wp.float64(0.0)
                for a in range(n):
                    value = weights[i, a] + alpha * (z[i, a] - weights[i, a])
                    if free[i, a] != 0 and z[i, a] < wp.float64(0.0):
                        if ratio[i, a] <= alpha * wp.float64(1.0 + 1.0e-12):
                            value = wp.float64(0.0)
                            free[i, a] = 0
                    weights[i, a] = wp.max(value, wp.float64(0.0))
                    total = total + weights[i, a]
                for a in range(n):
                    weights[i, a] = weights[i, a] / total

    @wp.func
    def largest_first(i: int, n: int, count: int, values: wp.array2d(dtype=wp.float64),
                      order: wp.array2d(dtype=wp.int32), taken: wp.array2d(dtype=wp.int32)):
        """order[i, :count] ← indices of the count largest values, largest first, ties by index."""
        for a in range(n):
            taken[i, a] = 0
        for r in range(count):
            best = int(-1)
            for a in range(n):
                if taken[i, a] == 0:
                    if best < 0:
                        best = a
                    elif values[i, a] > values[i, best]:
                        best = a
            taken[i, best] = 1
            order[i, r] = best

    @wp.kernel
    def vertex_weights(products: wp.array2d(dtype=wp.float64), bones: int, rest_h: wp.array2d(dtype=wp.float64),
                       chosen: wp.array2d(dtype=wp.int32), linear: wp.array2d(dtype=wp.float64),
                       start: wp.array2d(dtype=wp.float64), squared_norm: wp.array(dtype=wp.float64), k: int,
                       ridge: wp.float64, tolerance: wp.float64, gram: wp.array3d(dtype=wp.float64),
                       work: wp.array3d(dtype=wp.float64), sub_linear: wp.array2d(dtype=wp.float64),
                       weights: wp.array2d(dtype=wp.float64), free: wp.array2d(dtype=wp.int32),
                       kkt: wp.array3d(dtype=wp.float64), z: wp.array2d(dtype=wp.float64),
                       ratio: wp.array2d(dtype=wp.float64), keep: wp.array2d(dtype=wp.int32),
                       order: wp.array2d(dtype=wp.int32), taken: wp.array2d(dtype=wp.int32),
                       out_bones: wp.array2d(dtype=wp.int32), out_weights: wp.array2d(dtype=wp.float64),
                       out_error: wp.array(dtype=wp.float64)):
        i = wp.tid()
        c = chosen.shape[1]
        for a in range(c):
            for b in range(a, c):
                row = chosen[i, a] * bones + chosen[i, b]
                total = wp.float64(0.0)
                for e in range(16):
                    total = total + rest_h[i, e // 4] * rest_h[i, e % 4] * products[row, e]
                gram[i, a, b] = total
                gram[i, b, a] = total
        for a in range(c):
            weights[i, a] = start[i, a]
            sub_linear[i, a] = linear[i, a]
            for b in range(c):
                work[i, a, b] = gram[i, a, b]
        simplex_qp(i, c, ridge, tolerance, work, sub_linear, weights, free, kkt, z, ratio)
        largest_first(i, c, k, weights, keep, taken)
        total = wp.float64(0.0)
        for a in range(k):
            z[i, a] = weights[i, keep[i, a]]  # z: the kept weights for now
            total = total + z[i, a]
        for a in range(k):
            sub_linear[i, a] = linear[i, keep[i, a]]
            weights[i, a] = z[i, a]
            if c > k:
                if total > wp.float64(0.0):
                    weights[i, a] = z[i, a] / total
                else:
                    weights[i, a] = wp.float64(1.0) / wp.float64(k)
            for b in range(k):
                work[i, a, b] = gram[i, keep[i, a], keep[i, b]]
        if c > k:
            simplex_qp(i, k, ridge, tolerance, work, sub_linear, weights, free, kkt, z, ratio)
        largest_first(i, k, k, weights, order, taken)
        error = squared_norm[i]
        for a in range(k):
            out_bones[i, a] = chosen[i, keep[i, order[i, a]]]
            out_weights[i, a] = weights[i, order[i, a]]
            error = error - wp.float64(2.0) * weights[i, a] * sub_linear[i, a]
            for b in range(k):
                error = error + weights[i, a] * gram[i, keep[i, a], keep[i, b]] * weights[i, b]
        out_error[i] = wp.max(error, wp.float64(0.0))

    @wp.kernel
    def bone_sweep(transforms: wp.array4d(dtype=wp.float64), p: wp.array4d(dtype=wp.float64),
                   q: wp.array4d(dtype=wp.float64), order: wp.array(dtype=wp.int32),
                   coupled: wp.array2d(dtype=wp.int32)):
        t = wp.tid()
        bones = transforms.shape[1]
        for n in range(order.shape[0]):
            j = order[n]
            linear_part = wp.mat33d()  # the moment's first three columns
            last = wp.vec3d()  # and its fourth
            for a in range(3):
                for d in range(4):
                    total = p[j, t, a, d]
                    for k in range(bones):
                        if k != j and coupled[k, j] != 0:
                            for c in range(4):
                                total = total - transforms[t, k, a, c] * q[k, j, c, d]
                    if d < 3:
                        linear_part[a, d] = total
                    else:
                        last[a] = total
            mass = q[j, j, 3, 3]
            cross = wp.mat33d()
            for a in range(3):
                for b in range(3):
                    cross[a, b] = linear_part[a, b] - last[a] * q[j, j, b, 3] / mass
            U, sigma, V = wp.svd3(cross)
            rotation = U @ wp.transpose(V)
            if wp.determinant(rotation) < wp.float64(0.0):
                U = U @ wp.mat33d(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0)
                rotation = U @ wp.transpose(V)
            for a in range(3):
                shift = last[a] / mass
                for b in range(3):
                    transforms[t, j, a, b] = rotation[a, b]
                    shift = shift - rotation[a, b] * q[j, j, b, 3] / mass
                transforms[t, j, a, 3] = shift

    return vertex_weights, bone_sweep


def solve_vertex_weights_warp(products, rest_h, chosen, linear, start, squared_norm, max_influences, device,
                              ridge=1e-10, tolerance=1e-12):
    """:func:`skinsynth.pipeline.skin.vertex_weights.solve_vertex_weights` as one warp launch on
    ``device``: (bone_indices (V, K) int32, bone_weights (V, K), squared error (V,))."""
    wp = runtime.warp()
    vertex_weights, _ = _kernels()
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
    _, bone_sweep = _kernels()
    coupled = q[:, :, 3, 3] > 0.0
    order = np.flatnonzero(np.diag(coupled)).astype(np.int32)
    out = wp.array(np.ascontiguousarray(transforms, dtype=np.float64), device=device)
    wp.launch(bone_sweep, dim=transforms.shape[0], device=device,
              inputs=[out, wp.array(np.ascontiguousarray(p, dtype=np.float64), device=device),
                      wp.array(np.ascontiguousarray(q, dtype=np.float64), device=device),
                      wp.array(order, device=device), wp.array(coupled.astype(np.int32), device=device)])
    return out.numpy()
