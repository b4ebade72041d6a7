"""Pose-space correctives: what the skinned puppet misses at its examples, learnt over control space.

Feng's puppet can be no better than its skin: dual-quaternion skinning with the fitted bones and
weights does not reproduce a bending tube or a cloth sheet exactly however well the bones are
predicted (the Dem Bones bone with 12 bones: puppet 1.5× the PCA blendshape baseline while direct
RBF regression, which has no skin, was 4× better than the puppet). Park and Hodgins (2006), cited
by Feng §2, follow their skinning with "RBF-based interpolation of the residual errors"; Lewis et
al. (2000) keep such residuals in the rest pose, so they turn with the skin. Here:

1. At each training example j the puppet's own prediction is skinned. Each vertex's blended dual
   quaternion is a rigid motion (R, t), so the residual carried back to the rest pose,
   ``o_j = Rᵀ (y_j − t) − rest`` (V, 3), makes skinning reproduce the example: skin(rest + o_j) = y_j.
2. Over control space the offsets are interpolated by kernel ridge regression on Feng's kernel
   vector ξ (same kernel and width as the regression, so the run time has ξ already):
   ``w(ξ) = (K + λ k̄ I)⁻¹ ξ`` (n_p,) with k̄ the mean diagonal of K, and ``o(ξ) = Σ_j w_j o_j``.
   Far from every example a Gaussian ξ → 0, so the correction fades and the puppet falls back on
   its skin rather than extrapolating residuals.
3. The run time adds o(ξ) to the rest pose before skinning: n_p blend shapes with weights w(ξ)
   (how UsdSkel plays them).

λ is relative to k̄. ``"auto"`` picks it from RIDGE_GRID, or no correctives at all, by the
cross-validated vertex error of the whole prediction (:func:`cross_validated_errors`); ties go
to no correctives, then to the larger λ (the smoother choice).
"""

from dataclasses import dataclass

import numpy as np

from skinsynth.gpu import vertex_dual_quaternions

from .errors import OptionError
from .rotations import dual_quaternion_to_rigid

RIDGE_GRID = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0)
#: Frames per chunk when carrying residuals back to the rest pose (bounds the (f, V, K, 8) gather).
_CHUNK_VALUES = 1 << 22


@dataclass
class Correctives:
    """weights (n_p, n_p): w(ξ) = weights @ ξ; offsets (n_p, V, 3) the examples' rest-pose residuals;
    ridge the relative λ; reason why (as chosen or given)."""

    weights: np.ndarray
    offsets: np.ndarray
    ridge: float
    reason: str = ""


def rest_offsets(rest, bone_indices, bone_weights, dual_quaternions, targets):
    """Rest-pose offsets (F, V, 3) that make dual-quaternion skinning with dual_quaternions
    (F, B, 8) reproduce targets (F, V, 3) exactly: o = Rᵀ (y − t) − rest per vertex."""
    frames, verts = targets.shape[:2]
    out = np.empty((frames, verts, 3))
    step = max(1, _CHUNK_VALUES // max(1, 8 * verts * bone_indices.shape[1]))
    for f0 in range(0, frames, step):
        rot, trans = dual_quaternion_to_rigid(
            vertex_dual_quaternions(bone_indices, bone_weights, dual_quaternions[f0:f0 + step]))
        out[f0:f0 + step] = np.einsum("fvji,fvj->fvi", rot, targets[f0:f0 + step] - trans) - rest
    return out


def weight_operator(kernel_matrix, ridge):
    """(K + λ k̄ I)⁻¹ (n_p, n_p) for kernel_matrix K (n_p, n_p) and relative λ ``ridge``."""
    n = kernel_matrix.shape[0]
    mean_diagonal = max(float(np.mean(np.diag(kernel_matrix))), np.finfo(float).tiny)
    system = kernel_matrix + ridge * mean_diagonal * np.eye(n)
    try:
        return np.linalg.solve(system, np.eye(n))
    except np.linalg.LinAlgError:
        raise OptionError(f"corrective ridge {ridge:g} leaves the kernel matrix singular; use a larger one") from None


def fit_correctives(kernel_matrix, offsets, ridge, reason=""):
    """Correctives from the examples' rest offsets (n_p, V, 3) and their kernel matrix (n_p, n_p)."""
    if not (np.isfinite(ridge) and ridge > 0.0):
        raise OptionError(f"--correctives must be a positive ridge, 'auto' or 'off' (got {ridge})")
    return Correctives(weights=weight_operator(kernel_matrix, ridge), offsets=offsets, ridge=float(ridge),
                       reason=reason)


def corrective_offsets(correctives, kernel_vectors):
    """Rest offsets (F, V, 3) for kernel vectors ξ (F, n_p): Σ_j w_j(ξ) o_j (the run time's own reference)."""
    from skinsynth.gpu import corrective_offsets_reference

    return corrective_offsets_reference(kernel_vectors, correctives.weights, correctives.offsets)


def cross_validated_errors(kernel_matrix, folds, fold_predictions, targets, rest, bone_indices, bone_weights,
                           grid=RIDGE_GRID):
    """{λ: RMS vertex error} over held-out frames, λ = inf meaning no correctives.

    kernel_matrix (n, n) of the training frames; folds: list of held-out row indices;
    fold_predictions: per fold, the unit bone dual quaternions (n, B, 8) of a puppet trained
    without that fold's rows, for all n rows; targets (n, V', 3) the examples in place (a vertex
    subset, with rest (V', 3) and the skin's bone_indices / bone_weights rows to match). Each
    fold's correctives are fitted from its own training rows' residuals, as training does."""
    n = kernel_matrix.shape[0]
    total = dict.fromkeys((np.inf,) + tuple(grid), 0.0)
    for test, d in zip(folds, fold_predictions):
        train = np.setdiff1d(np.arange(n), test)
        offsets = rest_offsets(rest, bone_indices, bone_weights, d[train], targets[train])
        rot, trans = dual_quaternion_to_rigid(vertex_dual_quaternions(bone_indices, bone_weights, d[test]))
        skinned = np.einsum("fvij,vj->fvi", rot, rest) + trans
        residual = targets[test] - skinned
        total[np.inf] += float(np.sum(residual ** 2))
        for ridge in grid:
            weights = kernel_matrix[np.ix_(test, train)] @ weight_operator(kernel_matrix[np.ix_(train, train)], ridge)
            moved = np.einsum("fvij,fvj->fvi", rot, np.einsum("fj,jvc->fvc", weights, offsets))
            total[ridge] += float(np.sum((residual - moved) ** 2))
    count = n * rest.shape[0]
    return {ridge: float(np.sqrt(error / count)) for ridge, error in total.items()}


def choose_ridge(errors):
    """(ridge or None for no correctives, reason) from :func:`cross_validated_errors`' result."""
    best = min(errors.values())
    chosen = np.inf if errors[np.inf] <= best else max(r for r, e in errors.items() if e <= best)
    listed = ", ".join(f"{'off' if r == np.inf else f'{r:g}'} {e:.4g}" for r, e in sorted(errors.items()))
    if chosen == np.inf:
        return None, f"off: correctives did not lower the cross-validated RMS vertex error ({listed})"
    return chosen, f"ridge {chosen:g} (cross-validated RMS vertex error {listed})"
