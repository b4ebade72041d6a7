"""fit-skin's two heavy steps as warp kernels (``fit-skin --device cuda``), everything in float64.

The same algorithms as the numba steps of ``pipeline`` (``vertex_weights``, ``transform_sweep``)
and their numpy references, step for step: one thread per vertex solves its simplex QP over its
candidate bones (active set, Gaussian elimination on the KKT system) and re-solves the K
largest; one thread per frame sweeps the bones in order (weighted Procrustes, Gauss-Seidel),
with warp's 3×3 SVD for the polar factor. Launched by ``gpu.skin_fit``.
"""

from .. import runtime
from .simplex_qp import largest_first, simplex_qp

wp = runtime.warp()


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
    """Vertex i's weights over its C candidate bones chosen[i] (V, C), then over the K largest:
    out_bones, out_weights (V, K) largest first, out_error (V,) its squared error. The Gram matrix
    of bones a, b is rest_hᵀ P_ab rest_h with P = products (B·B, 16); the rest are scratch."""
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
    """Frame t's bone transforms (F, B, 3, 4), updated in place one bone at a time in ``order``
    (weighted Procrustes against the moments p (B, F, 3, 4) and q (B, B, 4, 4), the other bones
    held: Gauss-Seidel), bone k coupled to j where coupled[k, j] (B, B) is non-zero."""
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
