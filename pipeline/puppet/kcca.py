"""Per-bone kernel CCA regression from control points to bone dual quaternions (Feng §4).

Only the control side is kernelised (Feng §4.2): bases ``u_c = φ(C) f_c`` on the input side,
linear bases ``u_d`` on the 8 dual-quaternion numbers of a bone. Choices the paper leaves open,
made here and exposed as options:

- Centring. The kernel matrix is centred (``K̃ = H K H``) and the targets are centred, so the
  regression carries a constant term; at run time this is still ``d = M ξ + m`` (Feng §6.1 with
  a bias), ξ being the raw kernel vector.
- Regularisation. Without it kernel CCA finds trivial correlations of 1 (Hardoon et al. 2004):
  the input-side constraint becomes ``f_cᵀ (K̃² + κ K̃) f_c = 1``. κ is relative to the mean
  eigenvalue of K̃; ``"auto"`` picks it per bone by k-fold cross-validation of the dual-quaternion
  prediction error over the training frames. A tiny ridge (1e-8 of the mean variance) whitens
  the output side when a bone's dual quaternions are degenerate (e.g. a bone that never moves).
- Kernel parameters from the data (Feng §7): the Gaussian's σ is the standard deviation of the
  training control vectors (root of the summed per-coordinate variances, so a typical squared
  distance between examples is ~2σ²); the polynomial kernel ``(xᵀy + c)^5`` takes ``c`` = 0.1 ×
  the mean norm of the control vectors. Control vectors are standardised (mean removed, divided
  by that σ) before any kernel, which leaves the Gaussian unchanged and keeps the polynomial's
  fifth power well scaled.

With a linear kernel and κ → 0 this is ordinary CCA between control vectors and dual
quaternions (tests check the canonical correlations against a direct SVD of the whitened
cross-covariance).
"""

from dataclasses import dataclass

import numpy as np

from ..errors import OptionError

KERNELS = ("gaussian", "polynomial", "linear")
REGULARIZATION_GRID = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0)


@dataclass
class ControlKernel:
    """A kernel on standardised control vectors: kind, and for standardising: mean (d,), scale."""

    kind: str
    mean: np.ndarray
    scale: float
    offset: float = 0.0
    degree: int = 5

    def standardise(self, controls):
        """controls (n, d) -> standardised (n, d)."""
        return (controls - self.mean) / self.scale

    def matrix(self, x, y):
        """Kernel values (n, m) between standardised vectors x (n, d) and y (m, d) (standardised
        inputs have σ = 1, so the Gaussian is exp(-|x-y|²/2)); the run time's own reference."""
        from skinsynth.gpu import kernel_vectors_reference

        return kernel_vectors_reference(x, y, self.kind, self.offset, self.degree)


def control_kernel(kind, controls):
    """Kernel with its parameters estimated from training control vectors (n_p, d) (Feng §7)."""
    if kind not in KERNELS:
        raise OptionError(f"--kernel {kind!r} does not exist; choose one of {', '.join(KERNELS)}")
    mean = controls.mean(axis=0)
    scale = float(np.sqrt(np.sum(controls.var(axis=0))))
    if not scale > 0.0:
        raise OptionError("the control points do not move over the training frames: nothing to learn from")
    offset = 0.1 * float(np.mean(np.linalg.norm((controls - mean) / scale, axis=1)))
    return ControlKernel(kind=kind, mean=mean, scale=scale, offset=offset)


@dataclass
class KccaRegression:
    """Per-bone predictors: d_b = predictor[b] @ ξ + bias[b].

    predictor (B, m, n_p), bias (B, m), correlations (B, n_f) canonical correlations,
    regularization (B,) the κ used (relative to the mean eigenvalue of K̃).
    """

    predictor: np.ndarray
    bias: np.ndarray
    correlations: np.ndarray
    regularization: np.ndarray


def _inverse_sqrt(sym):
    """(…, m, m) symmetric positive definite -> its inverse square root."""
    values, vectors = np.linalg.eigh(sym)
    return (vectors / np.sqrt(values)[..., None, :]) @ np.swapaxes(vectors, -1, -2)


def fit_kcca(kernel_matrix, targets, bases=8, regularization=1e-3):
    """Kernel CCA and regression for every bone at once.

    kernel_matrix (n_p, n_p) of the training controls; targets (B, n_p, m) per bone (m = 8 for
    dual quaternions); ``bases`` n_f; regularization scalar or (B,) relative κ. Returns
    :class:`KccaRegression`.
    """
    n = kernel_matrix.shape[0]
    bones, _, m = targets.shape
    centre = np.eye(n) - 1.0 / n
    kc = centre @ kernel_matrix @ centre
    values, vectors = np.linalg.eigh(0.5 * (kc + kc.T))
    keep = values > 1e-10 * max(values.max(), np.finfo(float).tiny)
    values, vectors = values[keep], vectors[:, keep]
    if values.size == 0:
        raise OptionError("the training controls are all identical under this kernel: nothing to learn from")
    kappa = np.broadcast_to(np.asarray(regularization, dtype=float), (bones,)) * values.mean()
    shrink = 1.0 / np.sqrt(1.0 + kappa[:, None] / values[None, :])  # (B, r)

    mean_y = targets.mean(axis=1)
    y = targets - mean_y[:, None, :]
    cov_y = np.einsum("bni,bnj->bij", y, y)
    ridge = 1e-8 * np.maximum(np.einsum("bii->b", cov_y) / m, np.finfo(float).tiny)
    whiten_y = _inverse_sqrt(cov_y + ridge[:, None, None] * np.eye(m))
    cross = shrink[:, :, None] * np.einsum("nr,bnm,bmk->brk", vectors, y, whiten_y, optimize=True)  # (B, r, m)
    u, s, wt = np.linalg.svd(cross, full_matrices=False)
    nf = min(bases, u.shape[-1])
    u, s, w = u[..., :nf], s[..., :nf], np.swapaxes(wt, -1, -2)[..., :nf]

    # Training projections: C_r = K̃ F_c with F_c = V Λ⁻¹ S U, i.e. C_r = V S U; D_r = Y Σ⁻½ W.
    f_c = np.einsum("nr,brk->bnk", vectors, (shrink / values)[:, :, None] * u)
    c_r = np.einsum("nr,brk->bnk", vectors, shrink[:, :, None] * u)
    d_r = np.einsum("bnm,bmk,bkf->bnf", y, whiten_y, w, optimize=True)
    b_c = _lstsq(c_r, d_r)  # B_cᵀ (B, nf, nf): C_r B_cᵀ ≈ D_r   (Feng eq. 8)
    h_d = _lstsq(d_r, y)  # H_dᵀ (B, nf, m): D_r H_dᵀ ≈ Y       (Feng eq. 9)
    # d(x) = mean + H_d B_c F_cᵀ H (ξ − K 1/n)   (Feng eq. 7–9 with centring)
    chain = np.einsum("bfm,bgf,bng->bmn", h_d, b_c, f_c, optimize=True) @ centre  # (B, m, n)
    bias = mean_y - np.einsum("bmn,n->bm", chain, kernel_matrix.mean(axis=1))
    return KccaRegression(predictor=chain, bias=bias, correlations=s,
                          regularization=np.broadcast_to(np.asarray(regularization, dtype=float), (bones,)).copy())


def _lstsq(a, b, ridge=1e-12):
    """Batched least squares X = argmin |a X − b|: a (B, n, k), b (B, n, m) -> (B, k, m)."""
    ata = np.einsum("bnk,bnl->bkl", a, a)
    scale = np.maximum(np.einsum("bkk->b", ata) / ata.shape[-1], np.finfo(float).tiny)
    ata = ata + ridge * scale[:, None, None] * np.eye(ata.shape[-1])
    return np.linalg.solve(ata, np.einsum("bnk,bnm->bkm", a, b))


def predict(regression, kernel_vectors):
    """kernel_vectors (F, n_p) -> predictions (F, B, m)."""
    return np.einsum("bmn,fn->fbm", regression.predictor, kernel_vectors) + regression.bias[None]


def repeat_groups(inputs, tolerance=1e-3):
    """Group id (n,) of each row of inputs (n, d): rows within ``tolerance`` of an earlier row
    share its group (ids are first-seen order, 0…g−1). A periodic capture holds each pose twice."""
    squared = np.sum((inputs[:, None, :] - inputs[None, :, :]) ** 2, axis=-1)
    owner = np.arange(inputs.shape[0])
    for i in range(1, inputs.shape[0]):  # over training frames (tens to hundreds), not vertices
        earlier = np.flatnonzero(squared[i, :i] <= tolerance ** 2)
        if earlier.size:
            owner[i] = owner[earlier[0]]
    return np.unique(owner, return_inverse=True)[1]


def cv_folds(controls, folds):
    """Test indices of each cross-validation fold over training rows controls (n, d), standardised.

    Interleaved (row i to fold i mod k, so each fold spans the clip), except that repeated poses
    (:func:`repeat_groups`) share a fold: with a pose's twin left in training, a fold would only
    test memory, and the narrowest kernel and the weakest κ would always win (the horse gallop
    is one cycle twice: at every:4 its 12 training frames are 6 poses)."""
    groups = repeat_groups(controls)
    count = groups.max() + 1
    folds = max(2, min(folds, count))
    return [np.flatnonzero(groups % folds == fold) for fold in range(folds)]


def choose_regularization(kernel, controls, targets, bases=8, grid=REGULARIZATION_GRID, folds=5):
    """Per-bone κ from ``grid`` minimising k-fold cross-validated squared prediction error.

    controls (n_p, d) standardised; targets (B, n_p, m). Folds are interleaved frames
    (frame i goes to fold i mod k), so each fold spans the whole clip; repeated poses share a
    fold (:func:`cv_folds`). Returns (B,) κ.
    """
    n = controls.shape[0]
    error = np.zeros((len(grid), targets.shape[0]))
    for test in cv_folds(controls, folds):
        train = np.setdiff1d(np.arange(n), test)
        k_train = kernel.matrix(controls[train], controls[train])
        k_test = kernel.matrix(controls[test], controls[train])
        for g, kappa in enumerate(grid):
            model = fit_kcca(k_train, targets[:, train], bases=bases, regularization=kappa)
            residual = predict(model, k_test) - np.swapaxes(targets[:, test], 0, 1)
            error[g] += np.sum(residual ** 2, axis=(0, 2))
    return np.asarray(grid)[np.argmin(error, axis=0)]


#: Gaussian widths tried by ``--kernel-width auto``, as multiples of the controls' spread σ (Feng
#: §7 takes σ from the data, but no fixed multiple suits every capture: chosen by
#: ``pipeline.puppet``'s cross-validated vertex error, with κ and the translation prior).
WIDTH_GRID = (0.5, 1.0, 2.0, 4.0, 8.0)
