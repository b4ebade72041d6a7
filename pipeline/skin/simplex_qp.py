"""Many small convex quadratic programs over the probability simplex, solved together.

Each skinning-weight solve (Le & Deng 2012, used by Zheng §3.1) is, per vertex,

    minimise  ½ wᵀ G w − bᵀ w   subject to  w ≥ 0,  Σ w = 1,

with only a handful of unknowns (the candidate bones). Solving them one vertex at a time in
Python would dominate the fit, so this is a primal active-set method run in lock-step over all
problems: every step solves one batch of small KKT systems with ``numpy.linalg.solve``.
"""

import numpy as np


def _solve_on_free_set(gram, linear, free):
    """Minimiser of the objective restricted to ``free`` with Σ w = 1, and its multiplier.

    gram (N, C, C), linear (N, C), free (N, C) bool -> (w (N, C) zero off the free set, nu (N,)).
    Non-free rows and columns are replaced by the identity so one batched solve serves all.
    """
    n, c = linear.shape
    ff = free[:, :, None] & free[:, None, :]
    kkt = np.zeros((n, c + 1, c + 1))
    kkt[:, :c, :c] = np.where(ff, gram, 0.0)
    idx = np.arange(c)
    kkt[:, idx, idx] = np.where(free, gram[:, idx, idx], 1.0)
    kkt[:, :c, c] = free
    kkt[:, c, :c] = free
    rhs = np.zeros((n, c + 1))
    rhs[:, :c] = np.where(free, linear, 0.0)
    rhs[:, c] = 1.0
    sol = np.linalg.solve(kkt, rhs[..., None])[..., 0]
    return np.where(free, sol[:, :c], 0.0), sol[:, c]


def solve_simplex_qp(gram, linear, start=None, ridge=1e-10, max_steps=None, tolerance=1e-12):
    """Solve many simplex-constrained QPs ``min ½ wᵀGw − bᵀw, w ≥ 0, Σw = 1`` exactly.

    gram (N, C, C) symmetric positive semi-definite, linear (N, C), start (N, C) feasible
    warm start or None -> weights (N, C).

    ``ridge`` (relative to each problem's mean diagonal) is added to G so that ties between
    bones that move identically at a vertex have one answer; at 1e-10 it does not move an
    exact fit measurably. Without a warm start each problem starts at its best single vertex
    of the simplex. The method stops when every problem meets the KKT conditions (dual
    feasibility to ``tolerance`` relative to the diagonal scale) or after ``max_steps``
    (default 4·C) active-set steps; each step keeps every iterate feasible.
    """
    gram = np.asarray(gram, dtype=np.float64)
    linear = np.asarray(linear, dtype=np.float64)
    n, c = linear.shape
    idx = np.arange(c)
    scale = np.maximum(np.einsum("nii->n", gram) / c, np.finfo(float).tiny)
    gram = gram.copy()
    gram[:, idx, idx] += ridge * scale[:, None]
    if start is None:
        vertex_cost = 0.5 * gram[:, idx, idx] - linear
        weights = np.zeros((n, c))
        weights[np.arange(n), np.argmin(vertex_cost, axis=1)] = 1.0
    else:
        weights = np.array(start, dtype=np.float64, copy=True)
    free = weights > 0.0
    active = np.ones(n, dtype=bool)
    max_steps = 4 * c if max_steps is None else max_steps
    for _ in range(max_steps):
        rows = np.flatnonzero(active)
        if rows.size == 0:
            break
        g, b, f, w = gram[rows], linear[rows], free[rows], weights[rows]
        z, nu = _solve_on_free_set(g, b, f)
        blocked = (z < 0.0) & f
        feasible = ~blocked.any(axis=1)

        # Feasible step: take it, then add the most violated inactive constraint (if any).
        residual = np.einsum("nij,nj->ni", g, z) - b + nu[:, None]
        violation = np.where(f, 0.0, residual) / scale[rows, None]
        worst = np.argmin(violation, axis=1)
        optimal = violation[np.arange(rows.size), worst] >= -tolerance
        enter = feasible & ~optimal
        w = np.where(feasible[:, None], z, w)
        f[np.flatnonzero(enter), worst[enter]] = True

        # Infeasible step: move towards z until the first weight hits zero, drop it.
        rb = np.flatnonzero(~feasible)
        if rb.size:
            wb, zb = w[rb], z[rb]
            ratio = np.where(blocked[rb], wb / np.maximum(wb - zb, np.finfo(float).tiny), np.inf)
            alpha = np.clip(ratio.min(axis=1), 0.0, 1.0)
            wb = wb + alpha[:, None] * (zb - wb)
            hit = blocked[rb] & (ratio <= alpha[:, None] * (1.0 + 1e-12))
            wb[hit] = 0.0
            wb = np.maximum(wb, 0.0)
            w[rb] = wb / wb.sum(axis=1, keepdims=True)
            f[rb] &= ~hit
        weights[rows], free[rows] = w, f
        active[rows] = ~(feasible & optimal)
    return weights
