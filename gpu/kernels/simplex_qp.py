"""One vertex's skinning-weight QP on the device, in float64 (``pipeline.skin.simplex_qp``'s
primal active-set method, one thread per vertex i): minimise ½ wᵀ G w − bᵀ w subject to w ≥ 0,
Σ w = 1 over its n candidate bones. Every array's first index is the vertex; the scratch arrays
(kkt (V, n+1, n+2), z, ratio, free, taken (V, n)) are the calling kernel's
(``gpu.kernels.skin_fit``)."""

import numpy as np

from .. import runtime

wp = runtime.warp()

tiny = wp.constant(wp.float64(np.finfo(np.float64).tiny))


@wp.func
def solve_free(i: int, n: int, gram: wp.array3d(dtype=wp.float64), linear: wp.array2d(dtype=wp.float64),
               free: wp.array2d(dtype=wp.int32), kkt: wp.array3d(dtype=wp.float64),
               z: wp.array2d(dtype=wp.float64)):
    """z[i, :n] ← the minimiser on the free set with Σ z = 1 (Gaussian elimination with partial
    pivoting on the KKT system kkt[i] (n+1, n+2)); returns the multiplier ν."""
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
    """weights[i, :n] ← the QP's solution, from the start weights[i, :n] (their support the first
    free set); gram[i] gets the ridge ``ridge · mean diagonal`` added in place."""
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
