"""Poisson translation solver (Feng §5, §6.2): bone translations from rotations and control points.

Edges are skinned like vertices (eq. 10: per-edge bone weights fitted to the examples), then
the bone translations minimise the mismatch between skinned edge vectors and differences of
skinned vertices, plus β times the control-point mismatch (eq. 11). The problem is linear least
squares in t with a matrix that does not change at run time, so its solution is a fixed linear
map of (rotations, control positions): ``t = Γ·R + Q·c`` (+ a tiny prior term, below), which is
all that is stored and all that runs per frame.

Choices the paper leaves open:
- Edge weights (eq. 10) are fitted over the bones of the edge's two end vertices (≤ 2K), by
  least squares with a small ridge (``edge_ridge``, relative to the mean diagonal) towards the
  mean of the two vertices' weights, so edges whose rotated copies are nearly parallel still
  get a stable answer.
- The prior Π: a term ``γ‖t − t̂‖²`` towards the regression's own predicted translations t̂,
  γ = ``prior`` × the mean diagonal of the normal matrix. A tiny γ (1e-6) only fixes the null
  space (a mesh component without a control point) and leaves Feng's solve as it is. A larger
  γ trades the solve's consistency between neighbouring bones against the regression's
  placement: on long, thin meshes the edge field integrated from a few control points drifts
  (measured on a 16-bone tube: the solve alone, even fed the *true* rotations, is 7× the skin
  fit's error, while the regression's translations are 2.5×), so ``train-kcca`` chooses γ by
  cross-validation over the training frames (:func:`choose_translation_prior`, grid
  ``PRIOR_GRID`` from Feng's plain solve to the regression's translations). Cross-validation
  trains on fewer, sparser frames than the final puppet, so it sees the regression at its worse
  and leans towards small γ: on that tube it picks 0.1 (held-out error 1.31e-3) where 1–10 would
  give 0.92e-3 and the plain solve 2.1e-3. ``--translation-prior`` overrides it.
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


def fit_edge_weights(rest, edges, bone_indices, bone_weights, rotations, edge_vectors, edge_ridge=1e-6):
    """Edge skinning weights by Feng eq. 10.

    rest (V, 3); edges (E, 2); bone_indices/bone_weights (V, K); rotations (F, B, 3, 3) and
    edge_vectors (F, E, 3) = v_k0 − v_k1 over the training frames. Returns (edge_bones (E, S),
    edge_weights (E, S)); S = 2K slots, a bone repeated in a row has weight only in its first slot.
    """
    frames, bones = rotations.shape[:2]
    e0 = rest[edges[:, 0]] - rest[edges[:, 1]]
    support = np.concatenate([bone_indices[edges[:, 0]], bone_indices[edges[:, 1]]], axis=1)
    prior = 0.5 * np.concatenate([bone_weights[edges[:, 0]], bone_weights[edges[:, 1]]], axis=1)
    first = _first_occurrence(support)
    prior = _fold_duplicates(support, prior, first)
    # Normal equations: G[s, s'] = e0ᵀ (Σ_j R_sᵀ R_s') e0, r[s] = e0ᵀ Σ_j R_sᵀ e_j.
    h = np.einsum("fbac,fkad->bkcd", rotations, rotations, optimize=True)
    gram = np.einsum("ec,eskcd,ed->esk", e0, h[support[:, :, None], support[:, None, :]], e0, optimize=True)
    stacked = rotations.transpose(0, 2, 1, 3).reshape(frames * 3, bones * 3)  # rows (f, a), cols (b, c)
    flat = edge_vectors.transpose(1, 0, 2).reshape(-1, frames * 3)
    rt_e = (flat @ stacked).reshape(-1, bones, 3)  # Σ_j R_bᵀ e_j per bone
    rhs = np.einsum("esc,ec->es", np.take_along_axis(rt_e, support[:, :, None], axis=1), e0)
    # Duplicated bones: keep only the first slot as an unknown (others pinned at zero).
    slots = support.shape[1]
    mask = first[:, :, None] & first[:, None, :]
    gram = np.where(mask, gram, 0.0)
    diag = np.arange(slots)
    scale = np.maximum(np.einsum("ess->e", gram) / slots, np.finfo(float).tiny)
    ridge = edge_ridge * scale
    gram[:, diag, diag] = np.where(first, gram[:, diag, diag] + ridge[:, None], 1.0)
    rhs = np.where(first, rhs + ridge[:, None] * prior, 0.0)
    weights = np.linalg.solve(gram, rhs[..., None])[..., 0]
    return support, weights


def _first_occurrence(support):
    """(E, S) bool: True where the bone is not repeated earlier in the row."""
    same = support[:, :, None] == support[:, None, :]
    earlier = np.tril(np.ones(support.shape[1], dtype=bool), k=-1)
    return ~np.any(same & earlier[None], axis=2)


def _fold_duplicates(support, weights, first):
    """Sum each row's weights of repeated bones into the bone's first slot."""
    same = support[:, :, None] == support[:, None, :]
    return np.where(first, np.einsum("est,et->es", same.astype(float), weights), 0.0)


@dataclass
class TranslationOperator:
    """``t[b] = Σ_b' R_b' Γ[b, b'] + Σ_l Q[b, l] c_l + Π[b] t̂`` (Feng §5 eq. 11, §6.2 ``t = P·T``).

    rotation_operator Γ (B, B, 3); control_operator Q (B, n_c); prior_operator Π (B, B).
    """

    rotation_operator: np.ndarray
    control_operator: np.ndarray
    prior_operator: np.ndarray


PRIOR_GRID = (1e-6, 1e-4, 1e-3, 1e-2, 1e-1, 1.0, 10.0, 100.0)


@dataclass
class TranslationSystem:
    """The normal equations of Feng eq. 11 before the prior: ``normal (B, B)`` = ΔWᵀΔW + β W_cᵀW_c,
    ``rotation_rhs (B, B·3)`` and ``control_rhs (B, n_c)`` their right-hand sides per rotation
    component and control point (:func:`translation_system`)."""

    normal: np.ndarray
    rotation_rhs: np.ndarray
    control_rhs: np.ndarray


def translation_system(rest, edges, bone_indices, bone_weights, edge_bones, edge_weights, control_indices, beta=100.0):
    """The normal equations of eq. 11 (module notes) -> :class:`TranslationSystem`."""
    count = rest.shape[0]
    bones = int(max(bone_indices.max(), edge_bones.max())) + 1
    w = sp.csr_matrix((bone_weights.ravel(), (np.repeat(np.arange(count), bone_weights.shape[1]),
                                              bone_indices.ravel())), shape=(count, bones))
    n_e = edges.shape[0]
    # Rows of ΔW: w_k0 − w_k1 (the translation part of a skinned edge difference).
    incidence = sp.csr_matrix((np.r_[np.ones(n_e), -np.ones(n_e)], (np.r_[np.arange(n_e), np.arange(n_e)],
                                                                     np.r_[edges[:, 0], edges[:, 1]])), shape=(n_e, count))
    dw = incidence @ w
    wc = w[control_indices]
    normal = (dw.T @ dw + beta * (wc.T @ wc)).toarray()

    # Rotation part of each residual: Σ_b R_b g_kb with g_kb = ŵ_kb e0_k − w_k0b v_k0 + w_k1b v_k1.
    e0 = rest[edges[:, 0]] - rest[edges[:, 1]]
    rows = np.repeat(np.arange(n_e), edge_bones.shape[1])
    g_hat = sp.csr_matrix((edge_weights.ravel(), (rows, edge_bones.ravel())), shape=(n_e, bones))
    blocks = []
    for c in range(3):  # x, y, z components of g
        g_c = g_hat.multiply(e0[:, c:c + 1]) - incidence.multiply(rest[:, c][None, :]) @ w
        # Control rows: −√β w_l v_l, paired with their √β weights in the normal equations → −β.
        g_ctrl = -beta * (wc.multiply(rest[control_indices, c][:, None]))
        blocks.append((dw.T @ g_c + wc.T @ g_ctrl).toarray())
    return TranslationSystem(normal=normal, rotation_rhs=np.stack(blocks, axis=-1).reshape(bones, -1),
                             control_rhs=beta * wc.T.toarray())


def operator_from_system(system, prior=1e-6):
    """The run-time operator of a :class:`TranslationSystem` with prior weight ``prior``
    (relative to the mean diagonal; module notes) -> :class:`TranslationOperator`."""
    bones = system.normal.shape[0]
    gamma = prior * max(np.trace(system.normal) / bones, np.finfo(float).tiny)
    normal = system.normal + gamma * np.eye(bones)
    gamma_op = np.linalg.solve(normal, system.rotation_rhs).reshape(bones, bones, 3)
    control_op = np.linalg.solve(normal, system.control_rhs)
    prior_op = gamma * np.linalg.inv(normal)
    return TranslationOperator(rotation_operator=gamma_op, control_operator=control_op, prior_operator=prior_op)


def translation_operator(rest, edges, bone_indices, bone_weights, edge_bones, edge_weights, control_indices,
                         beta=100.0, prior=1e-6):
    """Precompute the linear map from (rotations, controls, predicted translations) to translations."""
    system = translation_system(rest, edges, bone_indices, bone_weights, edge_bones, edge_weights, control_indices,
                                beta=beta)
    return operator_from_system(system, prior)


def choose_translation_prior(system, rotations, controls, predicted, vertex_error, grid=PRIOR_GRID):
    """The prior weight of ``grid`` with the lowest held-out vertex error (module notes).

    rotations (F, B, 3, 3), controls (F, n_c, 3), predicted (F, B, 3): out-of-fold predictions of
    the regression for F training frames; ``vertex_error(rotations, translations) -> float`` the
    summed squared vertex error of those frames. Returns (prior, {prior: error})."""
    errors = {}
    for prior in grid:
        translations = solve_translations(operator_from_system(system, prior), rotations, controls, predicted)
        errors[float(prior)] = float(vertex_error(rotations, translations))
    return min(errors, key=errors.get), errors


def solve_translations(operator, rotations, controls, predicted_translations):
    """rotations (F, B, 3, 3), controls (F, n_c, 3), predicted_translations (F, B, 3) -> (F, B, 3)
    (Feng §6.2; the run time's own reference computes it)."""
    from skinsynth.gpu import solve_translations_reference

    return solve_translations_reference(rotations, controls, predicted_translations, operator.rotation_operator,
                                        operator.control_operator, operator.prior_operator)
