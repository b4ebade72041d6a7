"""The baselines the puppet is judged against: PCA blendshapes and direct RBF regression.

Feng et al. compare kernel CCA with a PCA-based blendshape model whose weights are "solved for
[...] from new control point positions using least-squares" (§7) and with "direct RBF-based
regression" from the control point coordinates (§4.3, Fig. 3). Both are implemented here as
honest, tuned-on-training-data-only competitors, predicting every vertex from the control points.

Global motion is handled exactly as for the puppet (``global_motion``):

- ``"control-frame"``: every training frame is brought in place by the rigid transform that maps
  its control points onto the reference (rest) control points (:func:`.alignment.control_frames`);
  the model is fitted to the aligned frames. At prediction time the query controls are aligned
  the same way, the prediction is made in place and moved back by the inverse transform.
- ``"world"``: no alignment; the model sees the world-space coordinates as they are.

Vertices are (n_p, V, 3) / (F, V, 3) arrays; control points are the vertices
``control_indices`` (n_c,), queried as (F, n_c, 3).
"""

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RBFInterpolator

from .alignment import apply_frames, control_frames, invert_frames
from ..errors import OptionError

GLOBAL_MOTIONS = ("control-frame", "world")

# Singular values of the control rows below this fraction of the largest are treated as zero
# (pseudo-inverse); it only matters with ridge=0, where such columns are round-off.
_PINV_CUTOFF = 1e-12
# Cross-validated choice of k: the smallest k whose error is within this fraction of the best.
_CV_PARSIMONY = 1e-3


# ----------------------------------------------------------------------------------------------
# Shared: checks and the in-place frame


def _check_training(train_vertices, control_indices, reference_controls, global_motion):
    vertices = np.asarray(train_vertices, dtype=np.float64)
    if vertices.ndim != 3 or vertices.shape[2] != 3:
        raise ValueError(f"train_vertices must be (n_p, V, 3), got shape {vertices.shape}")
    if vertices.shape[0] < 2:
        raise OptionError(f"need at least 2 training frames, got {vertices.shape[0]}")
    if not np.all(np.isfinite(vertices)):
        raise ValueError("train_vertices contain NaN or inf")
    indices = np.asarray(control_indices)
    if indices.ndim != 1 or indices.size == 0 or not np.issubdtype(indices.dtype, np.integer):
        raise ValueError("control_indices must be a non-empty 1-D array of vertex ids")
    vertex_count = vertices.shape[1]
    if indices.min() < 0 or indices.max() >= vertex_count:
        raise OptionError(f"control vertex ids must lie in 0..{vertex_count - 1}")
    if np.unique(indices).size != indices.size:
        raise OptionError("control vertex ids must be distinct")
    reference = np.asarray(reference_controls, dtype=np.float64)
    if reference.shape != (indices.size, 3):
        raise ValueError(f"reference_controls must be ({indices.size}, 3), got shape {reference.shape}")
    if global_motion not in GLOBAL_MOTIONS:
        raise OptionError(f"global_motion must be one of {GLOBAL_MOTIONS}, got {global_motion!r}")
    return vertices, indices.astype(np.int64), reference


def _check_controls(controls, count):
    controls = np.asarray(controls, dtype=np.float64)
    if controls.ndim != 3 or controls.shape[1:] != (count, 3):
        raise ValueError(f"controls must be (F, {count}, 3), got shape {controls.shape}")
    if not np.all(np.isfinite(controls)):
        raise ValueError("controls contain NaN or inf")
    return controls


def _in_place(vertices, control_indices, reference, global_motion):
    """Training frames brought in place (unchanged for ``"world"``)."""
    if global_motion == "world":
        return vertices
    rotations, translations = control_frames(vertices[:, control_indices], reference)
    return apply_frames(rotations, translations, vertices)


def _predict_in_place(controls, reference, global_motion, predict):
    """Align ``controls``, call ``predict(aligned controls) -> (F, V, 3)``, move the result back."""
    if global_motion == "world":
        return predict(controls)
    rotations, translations = control_frames(controls, reference)
    placed = predict(apply_frames(rotations, translations, controls))
    return apply_frames(*invert_frames(rotations, translations), placed)


def _coordinate_columns(control_indices):
    """Columns of the flattened (3V) vertex vector holding the control points, in (n_c, 3) order."""
    return (3 * control_indices[:, None] + np.arange(3)).ravel()


# ----------------------------------------------------------------------------------------------
# PCA blendshapes


@dataclass
class PcaBlendshape:
    """Blendshape model ``vertices = mean + Σ_i w_i bases[i]`` with weights from the controls.

    ``bases`` are the principal directions of the (aligned) training frames, each scaled by the
    RMS of the training weights along it (singular value / √n_p), so a weight of ±1 is one
    "standard deviation" of the examples and the ridge acts as the same prior on every weight.
    ``cv_errors[k-1]`` is the leave-one-out vertex RMS error with k components (None when
    ``components`` was given).
    """

    mean: np.ndarray  # (V, 3)
    bases: np.ndarray  # (k, V, 3)
    control_indices: np.ndarray  # (n_c,)
    reference: np.ndarray  # (n_c, 3)
    global_motion: str
    ridge: float
    cv_errors: np.ndarray | None = None  # (k_max,)

    @property
    def components(self):
        return self.bases.shape[0]


def _ridge_pinv(control_rows, ridge):
    """Tikhonov-regularised pseudo-inverse of the control rows A (..., 3n_c, k) -> (..., k, 3n_c).

    Minimises ``|A w − b|² + λ|w|²`` with ``λ = ridge · s_max(A)²``: through the SVD
    ``A = U S Vᵀ`` this is ``w = V diag(s / (s² + λ)) Uᵀ b``. Singular values below
    ``_PINV_CUTOFF · s_max`` are dropped (only matters for ridge = 0).
    """
    u, s, vt = np.linalg.svd(control_rows, full_matrices=False)
    s_max = s[..., :1]
    lam = ridge * s_max**2
    keep = s > _PINV_CUTOFF * s_max
    denom = np.where(keep, s**2 + lam, 1.0)
    filt = np.where(keep, s / denom, 0.0)
    return np.einsum("...ji,...j,...kj->...ik", vt, filt, u)


def _pca_weights(bases_flat, control_columns, targets, ridge):
    """Least-squares weights (..., F, k) so the bases' control rows match targets (..., F, 3n_c)."""
    control_rows = np.swapaxes(bases_flat[..., control_columns], -1, -2)  # (..., 3n_c, k)
    return targets @ np.swapaxes(_ridge_pinv(control_rows, ridge), -1, -2)


def _cross_validate_components(flat, control_columns, k_max, ridge):
    """Leave-one-out vertex RMS error of the blendshape model for k = 1..k_max, (k_max,).

    Every training frame is held out in turn; PCA is refitted on the others and the frame is
    predicted from its own control points. All folds are done at once in the coordinates of the
    full data's principal directions (the held-out frame and every fold's mean and bases lie in
    their span, and the directions are orthonormal, so the errors are exact) - one large SVD,
    then n_p small ones, batched; only k is looped over.
    """
    n_p, width = flat.shape
    centred = flat - flat.mean(axis=0)
    _, s, vt = np.linalg.svd(centred, full_matrices=False)
    coefficients = centred @ vt.T  # (n_p, r): the frames in the principal coordinates
    control_vt = vt[:, control_columns]  # (r, 3n_c)
    others = np.array([np.delete(np.arange(n_p), j) for j in range(n_p)])  # (n_p, n_p-1)
    fold = coefficients[others]  # (n_p, m, r)
    fold_mean = fold.mean(axis=1)
    _, fold_s, fold_vt = np.linalg.svd(fold - fold_mean[:, None], full_matrices=False)
    fold_bases = fold_s[..., None] / np.sqrt(n_p - 1) * fold_vt  # (n_p, r_f, r)
    fold_control = fold_bases @ control_vt  # (n_p, r_f, 3n_c)
    held_out = coefficients - fold_mean  # (n_p, r)
    targets = held_out @ control_vt  # (n_p, 3n_c)
    vertex_count = width // 3
    errors = np.empty(k_max)
    for k in range(1, k_max + 1):
        pinv = _ridge_pinv(np.swapaxes(fold_control[:, :k], -1, -2), ridge)  # (n_p, k, 3n_c)
        weights = np.einsum("fkc,fc->fk", pinv, targets)
        residual = held_out - np.einsum("fk,fkr->fr", weights, fold_bases[:, :k])
        errors[k - 1] = np.sqrt(np.sum(residual**2) / (n_p * vertex_count))
    return errors


def fit_pca_blendshape(
    train_vertices, control_indices, reference_controls, components=None, global_motion="control-frame", ridge=1e-6
):
    """Fit a PCA blendshape model to training frames (n_p, V, 3).

    The frames are brought in place (``global_motion``), centred on their mean and decomposed by
    SVD; the first k principal directions are the blendshape bases. Weights for new controls are
    the Tikhonov-regularised least-squares fit of the bases' control vertices to the (aligned)
    control positions, ``λ = ridge · s_max²`` with s_max the largest singular value of the
    (3n_c × k) control rows of the bases: 3n_c equations need not determine k weights, and the
    ridge keeps the solve stable at a relative bias of about ``ridge · (s_max / s_i)²`` per weight.
    With ``"control-frame"`` the alignment fixes 6 of the 3n_c control coordinates, so only
    3n_c − 6 equations carry information about the weights.

    ``components=None`` chooses k by leave-one-out cross-validation over the training frames
    (never on test data): every frame is predicted from its controls by a model refitted on the
    others, for k = 1..min(n_p − 1, 2 · 3n_c) (beyond twice the number of equations more
    components only add directions the controls cannot see), and the smallest k whose vertex RMS
    error is within 0.1 % of the best is taken (so ties at round-off pick the simpler model).
    Needs n_p ≥ 3 for cross-validation.
    """
    vertices, indices, reference = _check_training(train_vertices, control_indices, reference_controls, global_motion)
    if not np.isfinite(ridge) or ridge < 0.0:
        raise OptionError(f"ridge must be a finite number ≥ 0, got {ridge}")
    n_p, vertex_count, _ = vertices.shape
    flat = _in_place(vertices, indices, reference, global_motion).reshape(n_p, -1)
    columns = _coordinate_columns(indices)
    rank_limit = min(n_p - 1, flat.shape[1])
    cv_errors = None
    if components is None:
        if n_p < 3:
            raise OptionError(f"choosing components by cross-validation needs ≥ 3 training frames, got {n_p}")
        k_max = min(n_p - 1, 2 * columns.size, flat.shape[1])
        cv_errors = _cross_validate_components(flat, columns, k_max, ridge)
        components = int(np.flatnonzero(cv_errors <= cv_errors.min() * (1.0 + _CV_PARSIMONY))[0]) + 1
    elif not 1 <= int(components) <= rank_limit:
        raise OptionError(
            f"components must lie in 1..{rank_limit} (n_p − 1) for {n_p} training frames, got {components}"
        )
    components = int(components)
    mean = flat.mean(axis=0)
    _, s, vt = np.linalg.svd(flat - mean, full_matrices=False)
    bases = (s[:components, None] / np.sqrt(n_p)) * vt[:components]
    return PcaBlendshape(
        mean=mean.reshape(vertex_count, 3),
        bases=bases.reshape(components, vertex_count, 3),
        control_indices=indices,
        reference=reference,
        global_motion=global_motion,
        ridge=float(ridge),
        cv_errors=cv_errors,
    )


def predict_pca_blendshape(model, controls):
    """Vertices (F, V, 3) of the blendshape model for control positions (F, n_c, 3).

    All frames' weights come from one batched solve (one regularised pseudo-inverse applied to
    every frame's control targets).
    """
    controls = _check_controls(controls, model.control_indices.size)
    vertex_count = model.mean.shape[0]
    bases_flat = model.bases.reshape(model.components, -1)
    mean_flat = model.mean.reshape(-1)
    columns = _coordinate_columns(model.control_indices)

    def predict(placed):
        targets = placed.reshape(placed.shape[0], -1) - mean_flat[columns]
        weights = _pca_weights(bases_flat, columns, targets, model.ridge)  # (F, k)
        return (mean_flat + weights @ bases_flat).reshape(-1, vertex_count, 3)

    return _predict_in_place(controls, model.reference, model.global_motion, predict)


# ----------------------------------------------------------------------------------------------
# Direct RBF regression


@dataclass
class RbfRegression:
    """Direct RBF regression from the control vector (3n_c) to all vertex positions (3V).

    Inputs are reduced to ``z = (c − input_mean) @ input_axes.T / input_scale`` before the
    interpolator (see :func:`fit_rbf`); ``interpolator`` maps z (F, r) to flattened vertices.
    """

    interpolator: RBFInterpolator
    input_mean: np.ndarray  # (3n_c,)
    input_axes: np.ndarray  # (r, 3n_c), orthonormal rows
    input_scale: float
    vertex_count: int
    control_indices: np.ndarray  # (n_c,)
    reference: np.ndarray  # (n_c, 3)
    global_motion: str
    kernel: str
    smoothing: float


def fit_rbf(
    train_vertices,
    control_indices,
    reference_controls,
    global_motion="control-frame",
    kernel="thin_plate_spline",
    smoothing=0.0,
    epsilon=None,
    input_tolerance=1e-6,
    merge_tolerance=1e-3,
):
    """Fit direct RBF regression, aligned control vector (3n_c) -> aligned vertices (3V).

    The regression itself is ``scipy.interpolate.RBFInterpolator`` (default thin-plate spline
    with a degree-1 polynomial tail; ``smoothing=0`` interpolates the training frames).

    Inputs, for conditioning: the training control vectors are centred and expressed in their
    principal directions, keeping those whose singular value exceeds ``input_tolerance`` times
    the largest, and divided by their total standard deviation (RMS distance from their mean),
    so the inputs have unit spread whatever the units. Thin-plate spline and the linear tail are
    invariant under rotation and uniform scaling, so when the controls span all 3n_c directions
    this changes nothing but the conditioning. When they do not (fewer than 3n_c + 1 frames, or
    aligned controls confined to a subspace), the degree-1 tail would be undetermined in the
    missing directions, and dropping them is what makes the fit possible; query components
    along dropped directions are ignored. When r = n_p − 1 directions are kept, the degree-1 tail
    alone interpolates the n_p frames and the kernel part vanishes: the regression is then
    a single affine map of the reduced inputs (fine on smooth families, brittle on noisy controls;
    raise ``input_tolerance`` to keep fewer directions). ``epsilon`` (shape parameter) is needed only by the
    scale-dependent kernels and defaults to 1 (the inputs have unit spread).

    Training frames whose reduced inputs lie within ``merge_tolerance`` of an earlier one (in
    units of the spread) are merged into it, outputs averaged: an interpolating spline through two
    nearly equal inputs with different outputs has an enormous gradient between them and predicts
    nonsense elsewhere (a periodic capture holds each pose twice, up to file rounding: the horse
    gallop's frames k and k + 24 differ by 1e-4, and the spline's error was 600× the mesh).
    """
    vertices, indices, reference = _check_training(train_vertices, control_indices, reference_controls, global_motion)
    if not np.isfinite(smoothing) or smoothing < 0.0:
        raise OptionError(f"smoothing must be a finite number ≥ 0, got {smoothing}")
    n_p, vertex_count, _ = vertices.shape
    placed = _in_place(vertices, indices, reference, global_motion)
    inputs = placed[:, indices].reshape(n_p, -1)
    outputs = placed.reshape(n_p, -1)
    spread = float(np.sqrt(np.sum(inputs.var(axis=0))))
    if not spread > 0.0:
        raise OptionError("the (aligned) control points do not move over the training frames; nothing to regress on")
    inputs, outputs = _merge_repeated_inputs(inputs / spread, outputs, merge_tolerance)
    inputs *= spread
    input_mean = inputs.mean(axis=0)
    _, s, vt = np.linalg.svd(inputs - input_mean, full_matrices=False)
    input_axes = vt[s > input_tolerance * s[0]]
    input_scale = float(np.sqrt(np.sum(s**2) / inputs.shape[0]))
    reduced = (inputs - input_mean) @ input_axes.T / input_scale
    if epsilon is None:
        epsilon = 1.0
    try:
        interpolator = RBFInterpolator(reduced, outputs, kernel=kernel, smoothing=smoothing, degree=1, epsilon=epsilon)
    except (ValueError, np.linalg.LinAlgError) as error:
        raise OptionError(f"RBF regression cannot be fitted: {error}") from None
    return RbfRegression(
        interpolator=interpolator,
        input_mean=input_mean,
        input_axes=input_axes,
        input_scale=input_scale,
        vertex_count=vertex_count,
        control_indices=indices,
        reference=reference,
        global_motion=global_motion,
        kernel=kernel,
        smoothing=float(smoothing),
    )


def _merge_repeated_inputs(inputs, outputs, tolerance):
    """(inputs (m, r), outputs (m, p)) with every input within ``tolerance`` of an earlier kept one
    merged into it (outputs averaged); m ≤ n, first-seen order."""
    from .kcca import repeat_groups

    group = repeat_groups(inputs, tolerance)
    _, first = np.unique(group, return_index=True)  # group ids are in first-seen order
    if first.size == inputs.shape[0]:
        return inputs, outputs
    sums = np.zeros((first.size, outputs.shape[1]))
    np.add.at(sums, group, outputs)
    return inputs[first], sums / np.bincount(group)[:, None]


def predict_rbf(model, controls):
    """Vertices (F, V, 3) predicted by direct RBF regression from control positions (F, n_c, 3)."""
    controls = _check_controls(controls, model.control_indices.size)

    def predict(placed):
        reduced = (placed.reshape(placed.shape[0], -1) - model.input_mean) @ model.input_axes.T / model.input_scale
        return model.interpolator(reduced).reshape(-1, model.vertex_count, 3)

    return _predict_in_place(controls, model.reference, model.global_motion, predict)
