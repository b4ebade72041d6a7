"""The trained puppet's run-time path (Feng et al. 2008, §6) in numpy (float64): each stage's
reference, and :func:`reference_run_puppet`, their composition.

Per sample n (frames × characters, flattened): ξ = k(x, training) (N, n_p), d = M ξ + m (N, B, 8)
(Feng §6.1), unit d with its rotations (N, B, 3, 3) and translations (N, B, 3), the Poisson
translations t = Γ·R + Q·c + Π·t̂ (N, B, 3) (Feng §6.2), the pose-space correctives' rest offsets
Σ_j w_j O_j (N, V, 3), dual-quaternion skinning (N, V, 3) (Feng §6.3) or linear-blend skinning by
each bone's rigid transform. The device versions are in ``gpu.puppet_stages`` and
``gpu.puppet_run``; the pipeline's own computations call these.
"""

import numpy as np

from ..puppet_arrays import host_arrays
from ..validation import check_kind, checked_run_inputs
from .skinning import dqs_reference, lbs_reference

#: The skinnings a puppet plays with (``run_puppet``'s ``skinning``).
SKINNINGS = ("dual-quaternion", "linear")


def check_skinning(skinning):
    """Raise ValueError unless ``skinning`` is one of SKINNINGS."""
    if skinning not in SKINNINGS:
        raise ValueError(f"skinning must be one of {', '.join(SKINNINGS)}, got {skinning!r}")


def kernel_vectors_reference(x, training, kind, offset=0.0, degree=5):
    """ξ (N, n_p) float64 between standardised controls x (N, d) and training (n_p, d) (what
    ``pipeline.kcca.ControlKernel.matrix`` computes): "gaussian" exp(-|x-y|²/2), "polynomial"
    (xᵀy + offset)^degree, "linear" xᵀy."""
    check_kind(kind)
    x, training = np.asarray(x, dtype=np.float64), np.asarray(training, dtype=np.float64)
    if kind == "linear":
        return x @ training.T
    if kind == "polynomial":
        return (x @ training.T + offset) ** degree
    sq = np.sum(x * x, axis=1)[:, None] + np.sum(training * training, axis=1)[None, :] - 2.0 * x @ training.T
    return np.exp(-0.5 * np.maximum(sq, 0.0))


def predict_dual_quaternions_reference(xi, predictor, bias):
    """d (N, B, 8) = M ξ + m with M (8B, n_p) (row b·8 + m is bone b's m-th number), m (8B,)."""
    predictor = np.asarray(predictor, dtype=np.float64)
    bones = predictor.shape[0] // 8
    return (np.einsum("bmn,fn->fbm", predictor.reshape(bones, 8, -1), np.asarray(xi, dtype=np.float64))
            + np.asarray(bias, dtype=np.float64).reshape(bones, 8))


def _hamilton(a, b):
    """Hamilton products a ⊗ b of (..., 4) quaternions, (w, x, y, z)."""
    w = a[..., :1] * b[..., :1] - np.sum(a[..., 1:] * b[..., 1:], axis=-1, keepdims=True)
    v = a[..., :1] * b[..., 1:] + b[..., :1] * a[..., 1:] + np.cross(a[..., 1:], b[..., 1:])
    return np.concatenate([w, v], axis=-1)


def normalise_dual_quaternions_reference(d):
    """(unit d (N, B, 8), rotations (N, B, 3, 3), translations (N, B, 3)), dividing by |q0|: the
    rotation in closed form from the unit real part q0 = (w, x, y, z), the translation
    t = 2 qe q0* (Kavan et al. 2007); an oracle independent of ``pipeline.rotations``."""
    d = np.asarray(d, dtype=np.float64)
    unit = d / np.linalg.norm(d[..., :4], axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(unit[..., :4], -1, 0)
    rotations = np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                          np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                          np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)
    conjugate = unit[..., :4] * np.array([1.0, -1.0, -1.0, -1.0])
    return unit, rotations, 2.0 * _hamilton(unit[..., 4:], conjugate)[..., 1:]


def rigid_transforms_reference(dual_quaternions, translations=None, world_frames=None):
    """Each bone's final 3×4 matrix [R | t] (N, B, 3, 4) for linear skinning: the rotation and
    translation of unit dual quaternions (N, B, 8), the translation replaced by ``translations``
    (N, B, 3) if given (the solver's), then composed with the sample's rigid world frame (N, 4, 4)
    if given: [F_R R | F_R t + F_t]. Composed as matrices, an oracle for the device's composition
    of dual quaternions."""
    _, rot, trans = normalise_dual_quaternions_reference(dual_quaternions)
    if translations is not None:
        trans = np.asarray(translations, dtype=np.float64)
    if world_frames is not None:
        f = np.asarray(world_frames, dtype=np.float64)
        rot = np.einsum("nac,nbcd->nbad", f[:, :3, :3], rot)
        trans = np.einsum("nac,nbc->nba", f[:, :3, :3], trans) + f[:, None, :3, 3]
    return np.concatenate([rot, trans[..., None]], axis=-1)


def solve_translations_reference(rotations, controls, predicted_translations, rotation_operator,
                                 control_operator, prior_operator):
    """Feng §6.2's translations t = Γ·R + Q·c + Π·t̂ (N, B, 3): rotations (N, B, 3, 3), controls
    (N, n_c, 3) in place, predicted t̂ (N, B, 3); Γ (B, B, 3), Q (B, n_c), Π (B, B)."""
    return (np.einsum("bkc,fkac->fba", np.asarray(rotation_operator, dtype=np.float64), rotations, optimize=True)
            + np.einsum("bl,fla->fba", np.asarray(control_operator, dtype=np.float64), controls)
            + np.einsum("bk,fka->fba", np.asarray(prior_operator, dtype=np.float64), predicted_translations))


def corrective_weights_reference(xi, x, weights, power=1.0, tail=None, axes=None):
    """Blend weights w (N, n_p) float64 of the pose-space correctives: ``A ξ^p + B [1, x Pᵀ]`` for
    kernel vectors ξ (N, n_p) and standardised controls x (N, d); weights A (n_p, n_p), tail B
    (n_p, 1 + r) and axes P (r, d), or None for no affine tail."""
    w = (np.asarray(xi, dtype=np.float64) ** power) @ np.asarray(weights).T
    if tail is not None:
        tail = np.asarray(tail)
        w += tail[:, 0] + (np.asarray(x, dtype=np.float64) @ np.asarray(axes).T) @ tail[:, 1:].T
    return w


def corrective_offsets_reference(blend_weights, offsets):
    """Rest offsets (N, V, 3) Σ_j w_j O_j of blend weights w (N, n_p) and offsets O (n_p, V, 3)."""
    return np.einsum("nj,jvc->nvc", blend_weights, offsets)


def blend_weights(arrays, xi, x):
    """:func:`corrective_weights_reference` (N, n_p) of a ``PuppetArrays``' correctives, for kernel
    vectors ξ (N, n_p) and standardised controls x (N, d)."""
    return corrective_weights_reference(xi, x, arrays.corrective_weights, arrays.corrective_power,
                                        arrays.corrective_tail, arrays.corrective_axes)


def reference_run_puppet(puppet, standardised_controls, controls_in_place, world_frames=None,
                         translation_solver=True, skinning="dual-quaternion"):
    """numpy reference of ``run_puppet`` (same arguments, no device): vertices (N, V, 3).

    Composes the stage references; skinning "dual-quaternion" (``dqs_reference``) or "linear"
    (``lbs_reference`` by the rigid transforms of the unit dual quaternions). The world frames are
    applied to the skinned vertices, as ``pipeline.puppet.predict_vertices`` does (the device
    version folds them into the bones).
    """
    check_skinning(skinning)
    arrays = host_arrays(puppet)
    x, c, f = checked_run_inputs(arrays, standardised_controls, controls_in_place, world_frames, translation_solver)
    xi = kernel_vectors_reference(x, arrays.training_controls, arrays.kernel, arrays.offset, arrays.degree)
    d, rot, trans = normalise_dual_quaternions_reference(
        predict_dual_quaternions_reference(xi, arrays.predictor, arrays.bias))
    if translation_solver:
        trans = solve_translations_reference(rot, c, trans, arrays.rotation_operator, arrays.control_operator,
                                             arrays.prior_operator)
        pure = np.concatenate([np.zeros(trans.shape[:-1] + (1,)), trans], axis=-1)
        d = np.concatenate([d[..., :4], 0.5 * _hamilton(pure, d[..., :4])], axis=-1)
    offsets = None
    if arrays.has_correctives:
        offsets = corrective_offsets_reference(blend_weights(arrays, xi, x), arrays.corrective_offsets)
    if skinning == "linear":
        _, rot, trans = normalise_dual_quaternions_reference(d)  # d is unit: its rigid transforms
        placed = lbs_reference(arrays.rest_vertices, arrays.bone_indices, arrays.bone_weights, rot, trans, offsets)
    else:
        placed = dqs_reference(arrays.rest_vertices, arrays.bone_indices, arrays.bone_weights, d, offsets)
    if f is None:
        return placed
    return np.einsum("nab,nvb->nva", f[:, :3, :3], placed) + f[:, None, :3, 3]
