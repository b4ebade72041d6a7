"""Deformation gradients at key vertices and the bone solve from them (Zheng §3.3, eq. 8–9).

Everything here is in the local frame of the reference bone b_r (Zheng eq. 2): the non-reference
bones' local positions {F_b→r, t_b→r} (rotations while they come from the fit, general affine
matrices once solved by eq. 9), and b_r itself at the identity (F = I, t = 0). ``reference=None``
means there is no reference bone: every bone is given (e.g. world-frame positions).

- :func:`deformation_gradients` evaluates eq. 8 at the key vertices.
- :func:`rotation_strain` / :func:`rotation_strain_to_matrix`: the 9-vector d = [Φ(U), upper
  triangle of S] of the polar decomposition D = U S (Zheng §3.3 "Representation of Deformation
  Gradient"), the coordinates that are blended over time.
- :func:`gradient_operator` writes eq. 8 as d = G p + c (eq. 9) and factorises its normal
  equations once, so :meth:`GradientOperator.solve` turns blended gradients of many frames back
  into local bone positions with batched triangular solves (one, plus one refinement step).

Layouts: p stacks, per non-reference bone in ``bone_ids`` order, 12 numbers: the 9 entries of
F_b→r row-major, then t_b→r. d stacks, per key vertex, the 9 entries of D_i row-major.

Eq. 8 is separable by output row α: row α of D_i depends only on row α of each F_b and on
t_b[α], through the same matrix G₀ (3n × 4B') for α = 0, 1, 2. The solve uses that: it factorises
G₀ᵀG₀ + λI (4B' unknowns, dense Cholesky) and solves all 3·T right-hand sides at once; rank G =
3 rank G₀. The ridge λ = ``ridge`` × mean diagonal of G₀ᵀG₀ (default 1e-9) only matters where a
bone's translation or affine part is not determined by the key vertices (e.g. a bone that only
appears at vertices where its weight gradient vanishes): those components are pulled to 0. One
step of iterative refinement in :meth:`GradientOperator.solve` removes the ridge's first-order
bias on the determined components (see there), so a full-rank G gives the exact least-squares
solution to rounding.
"""

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from ..rig.rotations import polar_rotation, rotation_exp, rotation_log

_UPPER = (np.array([0, 0, 0, 1, 1, 2]), np.array([0, 1, 2, 1, 2, 2]))


def _slots(key_bones, local_bone_ids, reference):
    """Map key_bones (n, K') to slots of the extended bone list: 0..B'-1 the local bones,
    B' the reference (identity), B'+1 nothing (padding, zero)."""
    local_bone_ids = np.asarray(local_bone_ids, dtype=np.int64)
    key_bones = np.asarray(key_bones, dtype=np.int64)
    count = local_bone_ids.shape[0]
    if reference is not None and np.any(local_bone_ids == reference):
        raise ValueError(f"the reference bone {reference} must not be among the local bones")
    size = max(int(key_bones.max(initial=-1)), int(local_bone_ids.max(initial=-1)), -1 if reference is None
               else int(reference)) + 1
    table = np.full(size + 1, -2, dtype=np.int64)  # last entry: key_bones == -1 (padding)
    table[local_bone_ids] = np.arange(count)
    if reference is not None:
        table[reference] = count
    table[-1] = count + 1
    slots = table[np.where(key_bones >= 0, key_bones, size)]
    if np.any(slots == -2):
        missing = np.unique(key_bones[slots == -2])
        raise ValueError(f"key vertices use bones {missing.tolist()} that are neither local bones nor the reference")
    return slots


def deformation_gradients(R_local, t_local, local_bone_ids, reference, rest, key, key_bones, key_weights,
                          key_gradients):
    """Deformation gradients at key vertices by Zheng eq. 8.

    R_local (F, B', 3, 3) (rotations or general affine), t_local (F, B', 3): local-frame positions
    of the bones ``local_bone_ids (B',)``; reference: the reference bone id (identity position)
    or None; rest (V, 3); key (n,) vertex ids; key_bones (n, K') with -1 padding, key_weights
    (n, K') the vertices' own weights of those bones, key_gradients (n, K', 3) their ∂w_ib/∂v̄_i.
    Returns D (F, n, 3, 3).
    """
    R_local = np.asarray(R_local, dtype=np.float64)
    t_local = np.asarray(t_local, dtype=np.float64)
    frames, count = R_local.shape[:2]
    slots = _slots(key_bones, local_bone_ids, reference)
    r_ext = np.concatenate([R_local, np.broadcast_to(np.eye(3), (frames, 1, 3, 3)), np.zeros((frames, 1, 3, 3))], 1)
    t_ext = np.concatenate([t_local, np.zeros((frames, 2, 3))], 1)
    r = r_ext[:, slots]  # (F, n, K', 3, 3)
    v = np.asarray(rest, dtype=np.float64)[np.asarray(key)]  # v̄_i (n, 3)
    moved = np.einsum("fnkab,nb->fnka", r, v) + t_ext[:, slots]  # R_b v̄_i + t_b
    # Zheng eq. 8: D_i = Σ_b (R_b v̄_i + t_b) ∇w_ibᵀ + w_ib R_b.
    return (np.einsum("fnka,nkb->fnab", moved, np.asarray(key_gradients, dtype=np.float64))
            + np.einsum("nk,fnkab->fnab", np.asarray(key_weights, dtype=np.float64), r))


def rotation_strain(D):
    """D (..., 3, 3) -> rotation-strain coordinates d (..., 9) (Zheng §3.3).

    Polar decomposition D = U S with U the proper rotation of :func:`polar_rotation` and
    S = sym(Uᵀ D); d = [Φ(U) (3), s00, s01, s02, s11, s12, s22]. :func:`rotation_strain_to_matrix`
    inverts it exactly (to rounding) for every non-singular D: for det D < 0, U is still proper
    and S takes the negative eigenvalue.
    """
    D = np.asarray(D, dtype=np.float64)
    u = polar_rotation(D)
    s = np.swapaxes(u, -1, -2) @ D
    s = 0.5 * (s + np.swapaxes(s, -1, -2))
    return np.concatenate([rotation_log(u), s[..., _UPPER[0], _UPPER[1]]], axis=-1)


def rotation_strain_to_matrix(d):
    """d (..., 9) rotation-strain coordinates -> D = exp(Φ) S (..., 3, 3)."""
    d = np.asarray(d, dtype=np.float64)
    return rotation_times_strain(rotation_exp(d[..., :3]), d[..., 3:])


def rotation_times_strain(r, strain6):
    """r (..., 3, 3) times the symmetric matrix of strain6 (..., 6) = s00 s01 s02 s11 s12 s22."""
    s00, s01, s02, s11, s12, s22 = (strain6[..., i, None] for i in range(6))
    # R S column by column on (…, 3) arrays: numpy's stacked 3×3 matmul is several times slower.
    out = np.empty(np.broadcast_shapes(r.shape, strain6.shape[:-1] + (3, 3)))
    out[..., :, 0] = r[..., :, 0] * s00 + r[..., :, 1] * s01 + r[..., :, 2] * s02
    out[..., :, 1] = r[..., :, 0] * s01 + r[..., :, 1] * s11 + r[..., :, 2] * s12
    out[..., :, 2] = r[..., :, 0] * s02 + r[..., :, 1] * s12 + r[..., :, 2] * s22
    return out


@dataclass
class GradientOperator:
    """Eq. 8 as the linear map d = G p + c of Zheng eq. 9, with a factorisation for solving it.

    matrix: G, scipy.sparse CSR (9n × 12B'); constant: c (9n,), the reference bone's identity
    contribution (0 when reference is None); reduced: G₀ (3n × 4B', dense), the row-separable
    block of G (module notes); bone_ids (B',), reference, key (n,); ridge: the relative ridge and
    ``lam`` the absolute one added to G₀ᵀG₀ before its Cholesky factorisation ``factor``.
    """

    matrix: sp.csr_matrix
    constant: np.ndarray
    reduced: np.ndarray
    bone_ids: np.ndarray
    reference: object
    key: np.ndarray
    ridge: float
    lam: float
    factor: tuple

    def rank(self, tol=None):
        """Numerical rank of G (3 × rank G₀)."""
        return 3 * int(np.linalg.matrix_rank(self.reduced, tol=tol))

    def apply(self, F_local, t_local):
        """G p + c for F_local (T, B', 3, 3), t_local (T, B', 3) -> D (T, n, 3, 3)."""
        p = pack_positions(F_local, t_local)
        d = self.matrix @ p.T + self.constant[:, None]
        return d.T.reshape(p.shape[0], -1, 3, 3)

    def solve_damped(self, D_tilde, damped, damping, refine=1):
        """Eq. 9 with the bones ``damped`` (ids) pulled towards p = 0: min ‖G p − (d − c)‖² +
        μ Σ_{b ∈ damped} ‖p_b‖², μ = ``damping`` × the mean diagonal of G₀ᵀG₀. Used on the change
        from the source positions, so a damped bone keeps near its source position where the key
        vertices barely determine it. Same shapes as :meth:`solve`; ``damping = 0`` or no damped
        bone is :meth:`solve`. The factorisation is kept per (damped bones, damping)."""
        damped = np.intersect1d(np.asarray(damped, dtype=np.int64), self.bone_ids)
        if damping <= 0.0 or damped.size == 0:
            return self.solve(D_tilde, refine)
        key = (tuple(int(b) for b in damped), float(damping))
        cache = self.__dict__.setdefault("_damped_factors", {})
        if key not in cache:
            normal = self.reduced.T @ self.reduced
            mask = np.repeat(np.isin(self.bone_ids, damped), 4).astype(np.float64)
            mu = damping * float(np.mean(np.diag(normal)))
            cache[key] = scipy.linalg.cho_factor(normal + np.diag(mu * mask + self.lam), lower=True)
        return self._solve_with(cache[key], D_tilde, refine)

    def solve(self, D_tilde, refine=1):
        """Least-squares local bone positions from gradients at the key vertices (Zheng eq. 9).

        D_tilde (T, n, 3, 3) -> (F_local (T, B', 3, 3), t_local (T, B', 3)); many frames at once:
        one matrix product with G₀ᵀ and a pair of triangular solves for all 3·T right-hand sides,
        plus ``refine`` more pairs of iterative refinement against the unridged normal equations:
        x ← x + λ N_λ⁻¹ x (as G₀ᵀd − G₀ᵀG₀x = λx for the ridge solution). Each shrinks the ridge's
        relative bias on a determined direction from λ/(σ²+λ) to its square, and leaves
        undetermined directions (σ = 0) at 0: the solution tends to the minimum-norm one.
        """
        return self._solve_with(self.factor, D_tilde, refine)

    def _solve_with(self, factor, D_tilde, refine):
        """:meth:`solve` with the Cholesky factor of (normal matrix + λI) given; the refinement
        removes λ's bias whatever else that normal matrix holds."""
        D_tilde = np.asarray(D_tilde, dtype=np.float64)
        frames, n = D_tilde.shape[0], self.key.shape[0]
        rhs = D_tilde - self.constant.reshape(n, 3, 3)  # (T, n, α, β)
        rhs = rhs.transpose(0, 2, 1, 3).reshape(frames * 3, n * 3)  # rows (t, α), cols (i, β)
        x = scipy.linalg.cho_solve(factor, self.reduced.T @ rhs.T)  # (4B', 3T): (b, γ|t) × (t, α)
        for _ in range(refine):
            x = x + self.lam * scipy.linalg.cho_solve(factor, x)
        x = x.T.reshape(frames, 3, -1, 4)  # (T, α, b, 4)
        return x[..., :3].transpose(0, 2, 1, 3), x[..., 3].transpose(0, 2, 1)


def pack_positions(F_local, t_local):
    """F_local (T, B', 3, 3), t_local (T, B', 3) -> p (T, 12B') in eq. 9's layout."""
    F_local = np.asarray(F_local, dtype=np.float64)
    t_local = np.asarray(t_local, dtype=np.float64)
    frames, count = F_local.shape[:2]
    return np.concatenate([F_local.reshape(frames, count, 9), t_local], axis=-1).reshape(frames, -1)


def gradient_operator(local_bone_ids, reference, rest, key, key_bones, key_weights, key_gradients, ridge=1e-9):
    """Build eq. 9's G, c (d = G p + c) and factorise the reduced normal equations.

    Arguments as in :func:`deformation_gradients` (without the positions). ``ridge``: λ relative
    to the mean diagonal of G₀ᵀG₀ (module notes). Returns :class:`GradientOperator`.
    """
    local_bone_ids = np.asarray(local_bone_ids, dtype=np.int64)
    key = np.asarray(key, dtype=np.int64)
    count, n = local_bone_ids.shape[0], key.shape[0]
    slots = _slots(key_bones, local_bone_ids, reference)
    w = np.asarray(key_weights, dtype=np.float64)
    g = np.asarray(key_gradients, dtype=np.float64)
    v = np.asarray(rest, dtype=np.float64)[key]
    # Zheng eq. 8, entry (α, β): Σ_b Σ_γ F_b[α, γ] M_ib[γ, β] + t_b[α] ∇w_ib[β],
    # with M_ib = v̄_i ∇w_ibᵀ + w_ib I.
    m = np.einsum("ng,nkb->nkgb", v, g) + w[..., None, None] * np.eye(3)  # (n, K', γ, β)
    coeff = np.concatenate([m, g[:, :, None, :]], axis=2)  # (n, K', 4, β): γ = 0..2 then t
    local = slots < count
    nk_n, nk_k = np.nonzero(local)
    b = slots[nk_n, nk_k]
    # G₀: rows (i, β), columns (b, γ|t); duplicate bones in a row add up.
    rows = (3 * nk_n[:, None, None] + np.arange(3)[None, None, :]).repeat(4, axis=1)
    cols = (4 * b[:, None, None] + np.arange(4)[None, :, None]).repeat(3, axis=2)
    reduced = np.zeros((3 * n, 4 * count))
    np.add.at(reduced, (rows.ravel(), cols.ravel()), coeff[nk_n, nk_k].ravel())
    # c: the reference bone at F = I, t = 0 contributes M_ir[α, β] to D_i[α, β].
    ref = slots == count
    constant = np.einsum("nk,nkab->nab", ref.astype(np.float64), m).reshape(-1)
    # Full G (9n × 12B'): row 9i + 3α + β, column 12b + 3α + γ (F) or 12b + 9 + α (t).
    r0, c0 = np.nonzero(reduced)
    i, beta = np.divmod(r0, 3)
    bb, gamma = np.divmod(c0, 4)
    alpha = np.arange(3)
    full_rows = (9 * i[:, None] + 3 * alpha[None] + beta[:, None]).ravel()
    full_cols = np.where(gamma[:, None] < 3, 12 * bb[:, None] + 3 * alpha[None] + gamma[:, None],
                         12 * bb[:, None] + 9 + alpha[None]).ravel()
    values = np.repeat(reduced[r0, c0], 3)
    matrix = sp.csr_matrix((values, (full_rows, full_cols)), shape=(9 * n, 12 * count))
    normal = reduced.T @ reduced
    lam = ridge * float(np.mean(np.diag(normal))) if count else 0.0
    factor = scipy.linalg.cho_factor(normal + lam * np.eye(4 * count), lower=True)
    return GradientOperator(matrix=matrix, constant=constant, reduced=reduced, bone_ids=local_bone_ids,
                            reference=reference, key=key, ridge=ridge, lam=lam, factor=factor)
