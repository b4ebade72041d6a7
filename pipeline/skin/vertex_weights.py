"""Each vertex's sparse skinning weights, solved in compiled code on every core (numba).

The same problem as :func:`.skin_weights.update_weights`' numpy path (Le & Deng 2012, used by
Zheng §3.1): per vertex, over its candidate bones, ``min ½ wᵀGw − bᵀw`` with ``w ≥ 0``,
``Σ w = 1``, then the K largest weights re-solved alone. ``G`` is built inside the loop from
the frame-summed transform products ``H`` and the vertex's rest position
(``G[a, b] = ũᵀ H[c_a, c_b] ũ``), so the (V, C, C) Gram array the numpy path gathers is never
made. The active-set method is the one of :mod:`.simplex_qp` step for step; each vertex is
independent, so the result does not depend on the thread count.
"""

import numba
import numpy as np

TINY = np.finfo(np.float64).tiny
_jit = numba.njit(cache=True, nogil=True)


@_jit
def _solve_on_free_set(gram, linear, free, kkt, z):
    """z (C,) ← minimiser over the free set with Σ w = 1 (zero off it); returns its multiplier.

    The KKT system of :func:`.simplex_qp._solve_on_free_set`, solved by Gaussian elimination with
    partial pivoting in the scratch ``kkt (C+1, C+2)``."""
    c = linear.shape[0]
    n = c + 1
    for a in range(c):
        for b in range(c):
            kkt[a, b] = gram[a, b] if (free[a] and free[b]) else 0.0
        if not free[a]:
            kkt[a, a] = 1.0
        kkt[a, c] = 1.0 if free[a] else 0.0
        kkt[c, a] = 1.0 if free[a] else 0.0
        kkt[a, n] = linear[a] if free[a] else 0.0
    kkt[c, c] = 0.0
    kkt[c, n] = 1.0
    for col in range(n):
        pivot = col
        for row in range(col + 1, n):
            if abs(kkt[row, col]) > abs(kkt[pivot, col]):
                pivot = row
        if pivot != col:
            for j in range(col, n + 1):
                kkt[col, j], kkt[pivot, j] = kkt[pivot, j], kkt[col, j]
        for row in range(col + 1, n):
            factor = kkt[row, col] / kkt[col, col]
            if factor != 0.0:
                for j in range(col, n + 1):
                    kkt[row, j] -= factor * kkt[col, j]
    for row in range(n - 1, -1, -1):
        total = kkt[row, n]
        for j in range(row + 1, n):
            total -= kkt[row, j] * kkt[j, n]
        kkt[row, n] = total / kkt[row, row]
    for a in range(c):
        z[a] = kkt[a, n] if free[a] else 0.0
    return kkt[c, n]


@_jit
def _simplex_qp(gram, linear, weights, ridge, tolerance, max_steps, kkt, z):
    """One problem of :func:`.simplex_qp.solve_simplex_qp`: ``weights`` (a feasible start) is
    replaced by the minimiser. ``gram`` gets the ridge added in place."""
    c = linear.shape[0]
    scale = 0.0
    for a in range(c):
        scale += gram[a, a]
    scale = max(scale / c, TINY)
    for a in range(c):
        gram[a, a] += ridge * scale
    free = weights > 0.0
    residual = np.empty(c)
    for _ in range(max_steps):
        nu = _solve_on_free_set(gram, linear, free, kkt, z)
        blocked = False
        for a in range(c):
            if free[a] and z[a] < 0.0:
                blocked = True
        if not blocked:
            worst, least = 0, np.inf
            for a in range(c):
                value = 0.0
                if not free[a]:
                    total = -linear[a] + nu
                    for b in range(c):
                        total += gram[a, b] * z[b]
                    value = total / scale
                if value < least:
                    worst, least = a, value
            for a in range(c):
                weights[a] = z[a]
            if least >= -tolerance:
                return
            free[worst] = True
            continue
        alpha = np.inf
        for a in range(c):
            if free[a] and z[a] < 0.0:
                residual[a] = weights[a] / max(weights[a] - z[a], TINY)
                alpha = min(alpha, residual[a])
            else:
                residual[a] = np.inf
        alpha = min(max(alpha, 0.0), 1.0)
        total = 0.0
        for a in range(c):
            value = weights[a] + alpha * (z[a] - weights[a])
            if free[a] and z[a] < 0.0 and residual[a] <= alpha * (1.0 + 1e-12):
                value = 0.0
                free[a] = False
            weights[a] = max(value, 0.0)
            total += weights[a]
        for a in range(c):
            weights[a] /= total


@_jit
def _stable_descending(values, count):
    """Indices of the ``count`` largest values, largest first, ties by index: a stable insertion
    sort (``np.argsort(-values, kind="mergesort")[:count]`` for the few candidates a vertex has,
    NaN last as there, without numba's merge sort, which took 2.8 s of the first compile)."""
    n = values.shape[0]
    order = np.empty(n, dtype=np.int64)
    for a in range(n):
        value = values[a]
        b = a
        while b > 0 and (values[order[b - 1]] < value or (values[order[b - 1]] != values[order[b - 1]]
                                                           and value == value)):
            order[b] = order[b - 1]
            b -= 1
        order[b] = a
    return order[:count]


@numba.njit(cache=True, parallel=True, nogil=True)
def _vertex_weights(products, rest_h, chosen, linear, start, squared_norm, k, ridge, tolerance,
                    out_bones, out_weights, out_error):
    """Every vertex i: G from ``products (B*B, 16)`` and ``rest_h[i]``, the QP over ``chosen[i]``
    from ``start[i]``, the K largest re-solved, written sorted into the outputs."""
    count, c = chosen.shape
    bones = int(np.sqrt(products.shape[0]) + 0.5)
    for i in numba.prange(count):
        outer = np.empty(16)
        for a in range(4):
            for b in range(4):
                outer[4 * a + b] = rest_h[i, a] * rest_h[i, b]
        gram = np.empty((c, c))
        for a in range(c):
            for b in range(a, c):
                row = chosen[i, a] * bones + chosen[i, b]
                total = 0.0
                for e in range(16):
                    total += outer[e] * products[row, e]
                gram[a, b] = total
                gram[b, a] = total
        kkt = np.empty((c + 1, c + 2))
        z = np.empty(c)
        weights = start[i].copy()
        work = gram.copy()
        _simplex_qp(work, linear[i], weights, ridge, tolerance, 4 * c, kkt, z)
        keep = _stable_descending(weights, k)
        sub_gram = np.empty((k, k))
        sub_linear = np.empty(k)
        sub_weights = np.empty(k)
        total = 0.0
        for a in range(k):
            sub_linear[a] = linear[i, keep[a]]
            sub_weights[a] = weights[keep[a]]
            total += sub_weights[a]
            for b in range(k):
                sub_gram[a, b] = gram[keep[a], keep[b]]
        if c > k:
            for a in range(k):
                sub_weights[a] = sub_weights[a] / total if total > 0.0 else 1.0 / k
            work = sub_gram.copy()
            # a scratch of its own (not a view of kkt): one specialisation of the solve, not two
            _simplex_qp(work, sub_linear, sub_weights, ridge, tolerance, 4 * k, np.empty((k + 1, k + 2)), z[:k])
        order = _stable_descending(sub_weights, k)
        error = squared_norm[i]
        for a in range(k):
            out_bones[i, a] = chosen[i, keep[order[a]]]
            out_weights[i, a] = sub_weights[order[a]]
            error -= 2.0 * sub_weights[a] * sub_linear[a]
            for b in range(k):
                error += sub_weights[a] * sub_gram[a, b] * sub_weights[b]
        out_error[i] = max(error, 0.0)


def solve_vertex_weights(products, rest_h, chosen, linear, start, squared_norm, max_influences, ridge=1e-10,
                         tolerance=1e-12):
    """Sparse weights of every vertex over its candidate bones.

    products (B, B, 4, 4) = Σ_t T_jᵀ T_k; rest_h (V, 4) homogeneous rest positions; chosen (V, C)
    candidate bones; linear (V, C) = b over them; start (V, C) feasible warm starts; squared_norm
    (V,) = Σ_t |v_i(t)|². Returns (bone_indices (V, K) int32, bone_weights (V, K), squared error
    (V,)), columns by decreasing weight: what :func:`.skin_weights.update_weights` returns."""
    bones = products.shape[0]
    count, c = chosen.shape
    k = min(max_influences, c)
    out_bones = np.empty((count, k), dtype=np.int32)
    out_weights = np.empty((count, k))
    out_error = np.empty(count)
    _vertex_weights(np.ascontiguousarray(products.reshape(bones * bones, 16)), np.ascontiguousarray(rest_h),
                    np.ascontiguousarray(chosen, dtype=np.int64), np.ascontiguousarray(linear, dtype=np.float64),
                    np.ascontiguousarray(start, dtype=np.float64), np.ascontiguousarray(squared_norm), k,
                    float(ridge), float(tolerance), out_bones, out_weights, out_error)
    return out_bones, out_weights, out_error
