"""Pose-space correctives: what the skinned puppet misses at its examples, learnt over control space.

Feng's puppet can be no better than its skin: dual-quaternion skinning with the fitted bones and
weights does not reproduce a bending tube or a cloth sheet exactly however well the bones are
predicted (the Dem Bones bone with 12 bones: puppet 1.5× the PCA blendshape baseline while direct
RBF regression, which has no skin, was 4× better than the puppet). Park and Hodgins (2006), cited
by Feng §2, follow their skinning with "RBF-based interpolation of the residual errors"; Lewis et
al. (2000) keep such residuals in the rest pose, so they turn with the skin. Here:

1. At each training example j the puppet's own prediction is skinned, with the skinning the
   puppet is trained for. Under dual quaternions each vertex's blended dual quaternion is a rigid
   motion (R, t), so the residual carried back to the rest pose, ``o_j = Rᵀ (y_j − t) − rest``
   (V, 3), makes skinning reproduce the example: skin(rest + o_j) = y_j. Under linear blend
   skinning each vertex moves by an affine map ``p ↦ A p + t`` (A = Σ_b w_b R_b, t = Σ_b w_b t_b),
   which is not rigid and can be near singular where bones twist apart (the candy wrapper), so
   ``o_j = (AᵀA + ε I)⁻¹ Aᵀ (y_j − t − A rest)`` with ε = LINEAR_RIDGE: exact to ~ε/σ_min² of
   what the skin misses where A is well conditioned, and where it collapses the least offset that
   does what it can (0 where the skin already fits).
2. Over control space the offsets are interpolated by kernel ridge regression with an optional
   affine tail, on the standardised control vector x and Feng's kernel vector ξ (so the run time
   has both already): ``o(x) = Σ_j w_j(x) o_j`` with blend weights
   ``w(x) = A ξ^p + B [1, x Pᵀ]`` (n_p,). ξ^p, elementwise, is the regression's Gaussian at
   1/√p of its width (p = 1 for the other kernels); P (r, d) holds the r leading principal axes
   of the training controls. ``A``, ``B`` solve the interpolation system with ridge λ k̄ (k̄ the
   mean diagonal of the kernel matrix) and the tail unpenalised. Far from every example a
   Gaussian ξ → 0, so without the tail the correction fades and the puppet falls back on its skin;
   the tail carries trends that are linear in the controls (the Dem Bones bone at every:4: 0.00067
   of the box without it, 0.00027 with).
3. The run time adds o(x) to the rest pose before skinning: n_p blend shapes with weights w(x)
   (how UsdSkel plays them).

``"auto"`` chooses p from POWER_GRID, the tail (on or off), and λ from RIDGE_GRID, or no
correctives at all, by the cross-validated vertex error of the whole prediction
(:func:`cross_validated_errors`); ties go to no correctives, then to the simpler model (no tail,
p = 1, the larger λ).
"""

from dataclasses import dataclass

import numpy as np

from skinsynth.gpu import corrective_offsets_reference, corrective_weights_reference, vertex_dual_quaternions

from ..errors import OptionError
from ..rig.rotations import dual_quaternion_to_rigid

RIDGE_GRID = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0)
#: Powers of a Gaussian ξ tried: the corrective's kernel at 1, 1/2 and 1/4 of the regression's width.
POWER_GRID = (1.0, 4.0, 16.0)
#: Frames per chunk when carrying residuals back to the rest pose (bounds the (f, V, K, 8) gather).
_CHUNK_VALUES = 1 << 22
#: ε of the regularised inverse of a vertex's linear-blend map A (entries of order 1: A blends rotations).
LINEAR_RIDGE = 1e-6


@dataclass
class Correctives:
    """weights A (n_p, n_p), power p, tail B (n_p, 1 + r) and axes P (r, d) or both None:
    blend weights w(x) = A ξ^p + B [1, x Pᵀ]; offsets (n_p, V, 3) the examples' rest-pose
    residuals; ridge the relative λ; reason why (as chosen or given)."""

    weights: np.ndarray
    offsets: np.ndarray
    ridge: float
    power: float = 1.0
    tail: np.ndarray | None = None
    axes: np.ndarray | None = None
    reason: str = ""


@dataclass(frozen=True)
class Model:
    """One corrective model of the cross-validated grid: ridge (inf: no correctives), power, tail."""

    ridge: float
    power: float = 1.0
    tail: bool = False

    def __str__(self):
        if self.ridge == np.inf:
            return "off"
        return f"ridge {self.ridge:g}" + (f", width 1/{np.sqrt(self.power):g}" if self.power != 1.0 else "") + (
            ", affine tail" if self.tail else "")


def rest_offsets(rest, bone_indices, bone_weights, dual_quaternions, targets, skinning="dual-quaternion"):
    """Rest-pose offsets (F, V, 3) that make ``skinning`` ("dual-quaternion" or "linear") with the
    bones dual_quaternions (F, B, 8) reproduce targets (F, V, 3): per vertex o = Rᵀ (y − t) − rest
    (rigid, exact), or the regularised inverse of the vertex's linear-blend map (module docstring)."""
    frames, verts = targets.shape[:2]
    out = np.empty((frames, verts, 3))
    step = max(1, _CHUNK_VALUES // max(1, 8 * verts * bone_indices.shape[1]))
    for f0 in range(0, frames, step):
        chunk = slice(f0, f0 + step)
        if skinning == "linear":
            maps, trans = linear_vertex_maps(bone_indices, bone_weights, dual_quaternions[chunk])
            missed = targets[chunk] - trans - _apply_maps(maps, rest)  # what LBS of the rest misses
            normal = sum(maps[..., row, :, None] * maps[..., row, None, :] for row in range(3))  # AᵀA
            normal += LINEAR_RIDGE * np.eye(3)
            out[chunk] = np.linalg.solve(normal, _apply_maps(np.swapaxes(maps, -1, -2), missed)[..., None])[..., 0]
            continue
        rot, trans = dual_quaternion_to_rigid(
            vertex_dual_quaternions(bone_indices, bone_weights, dual_quaternions[chunk]))
        out[chunk] = _apply_maps(np.swapaxes(rot, -1, -2), targets[chunk] - trans) - rest
    return out


def _apply_maps(maps, vectors):
    """maps (..., V, 3, 3) applied to vectors (..., V, 3), broadcast over the leading axes: (..., V, 3),
    as three broadcast products (twice as fast as ``einsum`` over the small axes)."""
    return sum(maps[..., column] * vectors[..., None, column] for column in range(3))


def linear_vertex_maps(bone_indices, bone_weights, dual_quaternions):
    """Each vertex's linear-blend map: (A (F, V, 3, 3), t (F, V, 3)) with A = Σ_k w_k R_(b_k) and
    t = Σ_k w_k t_(b_k), for bones dual_quaternions (F, B, 8), so LBS moves p to A p + t."""
    from scipy.sparse import csr_matrix

    rotations, translations = dual_quaternion_to_rigid(dual_quaternions)
    frames, bones = rotations.shape[:2]
    verts = bone_indices.shape[0]
    used = bone_weights > 0.0  # a zero-weight slot is padding: its index may be anything
    blend = csr_matrix((bone_weights[used], (np.nonzero(used)[0], bone_indices[used])), shape=(verts, bones))
    motion = np.concatenate([rotations.reshape(frames, bones, 9), translations], axis=2)  # (F, B, 12)
    blended = (blend @ motion.transpose(1, 0, 2).reshape(bones, -1)).reshape(verts, frames, 12).transpose(1, 0, 2)
    return blended[..., :9].reshape(frames, verts, 3, 3), blended[..., 9:]


def tail_axes(x, n_p=None):
    """Principal axes P (r, d) of standardised controls x (n, d) for the affine tail: those above
    1e-6 of the largest singular value, at most n // 2 (the tail must leave the kernel part data)."""
    _, s, vt = np.linalg.svd(x - x.mean(axis=0), full_matrices=False)
    r = min(int(np.sum(s > 1e-6 * s[0])) if s.size and s[0] > 0 else 0, x.shape[0] // 2)
    return vt[:r]


def _features(x, axes):
    return np.hstack([np.ones((x.shape[0], 1)), x @ axes.T])


def blend_operator(kernel_matrix, ridge, features=None):
    """(A (n, n), B (n, 1 + r) or None) with w(x) = A k(x) + B f(x) interpolating the examples:
    kernel_matrix K (n, n), features F (n, 1 + r) of the examples or None; solves
    [[K + λ k̄ I, F], [Fᵀ, 0]] [Aᵀ; Bᵀ] = [I; 0]."""
    n = kernel_matrix.shape[0]
    mean_diagonal = max(float(np.mean(np.diag(kernel_matrix))), np.finfo(float).tiny)
    system = kernel_matrix + ridge * mean_diagonal * np.eye(n)
    m = 0 if features is None else features.shape[1]
    if m:
        system = np.block([[system, features], [features.T, np.zeros((m, m))]])
    right = np.vstack([np.eye(n), np.zeros((m, n))])
    try:
        solution = np.linalg.solve(system, right)
    except np.linalg.LinAlgError:
        raise OptionError(f"corrective ridge {ridge:g} leaves the kernel system singular; use a larger one") from None
    return solution[:n].T, (solution[n:].T if m else None)


def fit_correctives(kernel_matrix, x, offsets, model, reason=""):
    """Correctives from the examples' rest offsets (n_p, V, 3), their kernel matrix (n_p, n_p)
    (the regression's ξ at the examples) and standardised controls x (n_p, d), for ``model``."""
    if not (np.isfinite(model.ridge) and model.ridge > 0.0):
        raise OptionError(f"--correctives must be a positive ridge, 'auto' or 'off' (got {model.ridge})")
    axes = tail_axes(x) if model.tail else None
    weights, tail = blend_operator(kernel_matrix ** model.power, model.ridge,
                                   None if axes is None else _features(x, axes))
    return Correctives(weights=weights, offsets=offsets, ridge=float(model.ridge), power=float(model.power),
                       tail=tail, axes=axes, reason=reason)


def blend_weights(correctives, kernel_vectors, x):
    """Blend weights w (F, n_p) for kernel vectors ξ (F, n_p) and standardised controls x (F, d)
    (the run time's own reference computes them)."""
    c = correctives
    return corrective_weights_reference(kernel_vectors, x, c.weights, c.power, c.tail, c.axes)


def corrective_offsets(correctives, kernel_vectors, x):
    """Rest offsets (F, V, 3) for kernel vectors ξ (F, n_p) and standardised controls x (F, d)."""
    return corrective_offsets_reference(blend_weights(correctives, kernel_vectors, x), correctives.offsets)


def cross_validated_errors(kernel_matrix, x, folds, fold_predictions, targets, rest, bone_indices, bone_weights,
                           powers=(1.0,), ridges=RIDGE_GRID, skinning="dual-quaternion"):
    """{Model: RMS vertex error} over held-out rows, ``Model(inf)`` meaning no correctives.

    kernel_matrix (n, n) of the training rows, x (n, d) their standardised controls; folds: list
    of held-out row indices; fold_predictions: per fold, the unit bone dual quaternions (n, B, 8)
    of a puppet trained without that fold's rows, for all n rows; targets (n, V', 3) the examples
    in place (a vertex subset, with rest (V', 3) and the skin's bone_indices / bone_weights rows to
    match). Each fold's correctives are fitted from its own training rows' residuals, as training
    does. Under dual quaternions errors are measured in the rest pose (skinning is rigid per vertex,
    so lengths agree); under linear skinning each held-out offset error is carried through its
    vertex's map A (:func:`linear_vertex_maps`), so the error is the posed one."""
    n = kernel_matrix.shape[0]
    models = [Model(ridge, power, tail) for tail in (False, True) for power in powers for ridge in ridges]
    total = dict.fromkeys([Model(np.inf)] + models, 0.0)
    for test, d in zip(folds, fold_predictions):
        train = np.setdiff1d(np.arange(n), test)
        offsets = rest_offsets(rest, bone_indices, bone_weights, d, targets, skinning).reshape(n, -1)
        if skinning == "linear":
            error = _posed_error(offsets[train], *linear_vertex_maps(bone_indices, bone_weights, d[test]), rest,
                                 targets[test])
            total[Model(np.inf)] += error(np.zeros((len(test), len(train))))
        else:
            error = _rest_pose_error(offsets[test], offsets[train])
            total[Model(np.inf)] += float(np.sum(offsets[test] ** 2))
        axes = tail_axes(x[train])
        features = _features(x, axes)
        for model in models:
            k = kernel_matrix ** model.power
            try:
                a, b = blend_operator(k[np.ix_(train, train)], model.ridge, features[train] if model.tail else None)
            except OptionError:  # this fold cannot fit it: the model is out
                total[model] = np.inf
                continue
            weights = k[np.ix_(test, train)] @ a.T + (features[test] @ b.T if model.tail else 0.0)
            total[model] += error(weights)
    count = n * rest.shape[0]
    return {model: float(np.sqrt(error / count)) for model, error in total.items()}


def _rest_pose_error(held_out, shapes):
    """weights (T, n) ↦ the summed squared error of the blended shapes (n, 3V) against the
    held-out rows' own offsets (T, 3V), in the rest pose (skinning rigid per vertex)."""
    return lambda weights: float(np.sum((held_out - weights @ shapes) ** 2))


def _posed_error(shapes, maps, shifts, rest, targets):
    """weights (T, n) ↦ the summed squared error of linear blend skinning with the blended
    shapes (n, V·3) added to the rest pose (V, 3), against targets (T, V, 3), each held-out row
    skinned by its vertices' maps A (T, V, 3, 3) and shifts t (T, V, 3): Σ_t ‖Σ_j w_tj A_t O_j +
    (A_t rest + t_t − y_t)‖², which also counts what no offset reaches where a map is near
    singular. Expanded once per fold into each row's Gram matrix (G_t G_tᵀ, G_t = A_t O_j for
    the n shapes), so every model costs O(T n²) instead of a pass over the vertices."""
    shapes = shapes.reshape(len(shapes), *rest.shape)
    missed = (_apply_maps(maps, rest) + shifts - targets).reshape(len(maps), -1)  # (T, 3V)
    gram, cross = np.empty((len(maps),) + (len(shapes),) * 2), np.empty((len(maps), len(shapes)))
    step = max(1, _CHUNK_VALUES // max(1, shapes.size))  # rows per chunk of the (t, n, V, 3) products
    for t0 in range(0, len(maps), step):
        rows = slice(t0, t0 + step)
        moved = _apply_maps(maps[rows, None], shapes[None]).reshape(-1, len(shapes), missed.shape[1])  # A_t O_j
        gram[rows] = moved @ moved.transpose(0, 2, 1)  # batched BLAS: einsum's loop took 18x as long
        cross[rows] = (moved @ missed[rows, :, None])[..., 0]
    constant = float(np.sum(missed ** 2))
    return lambda weights: float(np.einsum("tj,tjk,tk->", weights, gram, weights)
                                 + 2.0 * np.sum(weights * cross) + constant)


def choose_model(errors):
    """(Model or None for no correctives, reason) from :func:`cross_validated_errors`' result:
    the lowest error; ties to none, then no tail, p = 1 and the larger λ."""
    best = min(errors.values())
    order = sorted(errors, key=lambda m: (errors[m] > best, m.ridge != np.inf, m.tail, m.power, -m.ridge))
    chosen = order[0]
    off = errors[Model(np.inf)]
    if chosen.ridge == np.inf:
        return None, f"off: correctives did not lower the cross-validated RMS vertex error ({off:.4g})"
    return chosen, f"{chosen} (cross-validated RMS vertex error {errors[chosen]:.4g}, without correctives {off:.4g})"
