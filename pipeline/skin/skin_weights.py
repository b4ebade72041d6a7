"""Sparse skinning weights: per vertex non-negative, summing to one, at most K non-zeros.

For fixed bone transforms the weights of vertex i minimise Σ_t |Σ_j w_ij T_j(t) ũ_i − v_i(t)|²
(Le & Deng 2012). Its normal equations need only ``G_i[j, k] = ũ_iᵀ H_jk ũ_i`` with
``H_jk = Σ_t T_jᵀ T_k`` and ``b_i[j] = Σ_t (T_j ũ_i)·v_i``, so the frame count drops out of the
per-vertex work. Each vertex considers a few candidate bones: its current bones plus those that
best explain its trajectory alone (``candidates``, default 2K); the simplex QP is solved over
the candidates, the K largest weights are kept and the QP is solved again on them, as Le & Deng
do to enforce sparsity.
"""

import numpy as np

from .bone_transforms import bone_projections, single_bone_errors, transform_products
from .simplex_qp import solve_simplex_qp


def _gram(products, rest_h, bones, chunk_elements=1 << 24):
    """G (V, C, C) = ũᵀ H[bones_j, bones_k] ũ for each vertex's bone list bones (V, C).

    Computed as one matrix product (ũ⊗ũ) · H over all bone pairs, in vertex chunks of at most
    ``chunk_elements`` entries, then gathered: BLAS does the work instead of a 5-D einsum.
    """
    count, c = bones.shape
    n_bones = products.shape[0]
    flat_h = products.reshape(n_bones * n_bones, 16).T
    outer = (rest_h[:, :, None] * rest_h[:, None, :]).reshape(count, 16)
    pair = bones[:, :, None] * n_bones + bones[:, None, :]
    gram = np.empty((count, c, c))
    step = max(1, chunk_elements // (n_bones * n_bones))
    for start in range(0, count, step):
        block = outer[start:start + step] @ flat_h
        gram[start:start + step] = np.take_along_axis(block, pair[start:start + step].reshape(-1, c * c), axis=1).reshape(-1, c, c)
    return gram


def _select(columns, chosen, weights, linear, gram):
    """Per-vertex column selection/reordering (V, C') of the candidate arrays and their Gram blocks."""
    def pick(a):
        return np.take_along_axis(a, columns, axis=1)

    gram = np.take_along_axis(np.take_along_axis(gram, columns[:, :, None], axis=1), columns[:, None, :], axis=2)
    return pick(chosen), pick(weights), pick(linear), gram


def sparse_simplex_weights(gram, linear, chosen, start, k, again=False):
    """The weights of many vertices over their C candidate bones ``chosen`` (V, C): the simplex QP
    min ½ wᵀGw − bᵀw (gram (V, C, C), linear (V, C)) from ``start`` (V, C), then the K largest kept
    (all of them when C == K) and the QP solved again on those (when C == K too with ``again``, as
    the contact fit does). Returns (chosen, weights, linear, gram), each (V, K) or (V, K, K),
    columns by decreasing weight (as they come when C == K and not ``again``)."""
    candidates = chosen.shape[1]
    weights = solve_simplex_qp(gram, linear, start=start / start.sum(axis=1, keepdims=True))
    keep = np.argsort(-weights, axis=1, kind="stable")[:, :k]
    chosen, weights, linear, gram = _select(keep, chosen, weights, linear, gram)
    if candidates > k or again:
        start = np.where(weights.sum(axis=1, keepdims=True) > 0.0, weights, 1.0 / k)
        weights = solve_simplex_qp(gram, linear, start=start / start.sum(axis=1, keepdims=True))
        order = np.argsort(-weights, axis=1, kind="stable")
        chosen, weights, linear, gram = _select(order, chosen, weights, linear, gram)
    return chosen, weights, linear, gram


def update_weights(transforms, data, bone_indices, bone_weights, max_influences, candidates=None, solver="compiled",
                   device=None):
    """New sparse weights for fixed transforms.

    transforms (F, B, 3, 4); data: Trajectories; bone_indices (V, K0) and bone_weights (V, K0),
    the current weights (their bones stay candidates, so the error cannot grow before
    sparsification). Returns (bone_indices (V, K), bone_weights (V, K), squared_error (V,)),
    columns sorted by decreasing weight; unused slots have weight 0. ``solver``: "compiled"
    (:mod:`.vertex_weights`, every core; with a warp ``device`` such as "cuda:0", the same solve
    as a warp kernel there) or "numpy" (the batched reference below).
    """
    bones = transforms.shape[1]
    k = min(max_influences, bones)
    c = min(bones, max(candidates or 2 * k, k))
    products = transform_products(transforms)
    projections = bone_projections(transforms, data)
    score = single_bone_errors(transforms, data, products, projections)
    rows = np.arange(data.count)[:, None]
    score[rows, bone_indices] = np.where(bone_weights > 0.0, -np.inf, score[rows, bone_indices])
    chosen = np.argpartition(score, c - 1, axis=1)[:, :c] if c < bones else np.tile(np.arange(bones), (data.count, 1))

    current = np.zeros((data.count, bones))
    current[rows, bone_indices] = bone_weights
    start = current[rows, chosen]
    start = np.where(start.sum(axis=1, keepdims=True) > 0.0, start, 1.0 / c)
    if solver == "compiled":
        problem = (products, data.homogeneous, chosen, projections[rows, chosen],
                   start / start.sum(axis=1, keepdims=True), data.squared_norm, k)
        if device is None:
            from .vertex_weights import solve_vertex_weights

            return solve_vertex_weights(*problem)
        from skinsynth.gpu import solve_vertex_weights_warp

        return solve_vertex_weights_warp(*problem, device=device)
    gram = _gram(products, data.homogeneous, chosen)
    linear = projections[rows, chosen]
    chosen, weights, linear, gram = sparse_simplex_weights(gram, linear, chosen, start, k)
    # Squared error Σ_t |v̂ − v|² = wᵀGw − 2 bᵀw + Σ_t |v|², from quantities already at hand.
    error = (np.einsum("ij,ijk,ik->i", weights, gram, weights)
             - 2.0 * np.einsum("ij,ij->i", weights, linear) + data.squared_norm)
    return chosen.astype(np.int32), weights, np.maximum(error, 0.0)
