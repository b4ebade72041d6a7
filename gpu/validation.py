"""Checks of the arrays that the kernels' launchers and their numpy references take (numpy only)."""

import numpy as np

KERNEL_KINDS = ("gaussian", "polynomial", "linear")


def check_kind(kind):
    """Raise ValueError unless ``kind`` is one of KERNEL_KINDS."""
    if kind not in KERNEL_KINDS:
        raise ValueError(f"kernel kind must be one of {', '.join(KERNEL_KINDS)}, got {kind!r}")


def checked_skin(rest_vertices, bone_indices, bone_weights, rotations, translations):
    """Validated float64/int64 copies; padding slots' indices set to 0 so gathers stay in range."""
    rest = np.asarray(rest_vertices, dtype=np.float64)
    idx = np.asarray(bone_indices)
    w = np.asarray(bone_weights, dtype=np.float64)
    rot = np.asarray(rotations, dtype=np.float64)
    trans = np.asarray(translations, dtype=np.float64)
    if rest.ndim != 2 or rest.shape[1] != 3:
        raise ValueError(f"rest_vertices must be (V, 3), got {rest.shape}")
    if idx.ndim != 2 or idx.shape[0] != rest.shape[0] or w.shape != idx.shape:
        raise ValueError(
            f"bone_indices {idx.shape} and bone_weights {w.shape} must both be (V, K) with V = {rest.shape[0]}"
        )
    if not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"bone_indices must be integers, got {idx.dtype}")
    if rot.ndim != 4 or rot.shape[2:] != (3, 3) or trans.shape != rot.shape[:2] + (3,):
        raise ValueError(
            f"rotations must be (F, B, 3, 3) and translations (F, B, 3), got {rot.shape} and {trans.shape}"
        )
    idx = np.where(w != 0.0, idx, 0).astype(np.int64)
    bones = rot.shape[1]
    if idx.size and (idx.min() < 0 or idx.max() >= bones):
        raise ValueError(f"bone_indices with non-zero weight must lie in [0, {bones}), got {idx.min()}..{idx.max()}")
    return rest, idx, w, rot, trans


def checked_offsets(rest_offsets, frames, verts):
    """Per-frame rest offsets (F, V, 3) float64 or None (pose-space correctives, added to the rest
    pose before skinning)."""
    if rest_offsets is None:
        return None
    offsets = np.asarray(rest_offsets, dtype=np.float64)
    if offsets.shape != (frames, verts, 3):
        raise ValueError(f"rest_offsets must be ({frames}, {verts}, 3), got {offsets.shape}")
    return offsets


def checked_run_inputs(arrays, standardised_controls, controls_in_place, world_frames, translation_solver):
    """(x (N, d), c (N, n_c, 3) or None, world frames (N, 4, 4) or None), float64, of a puppet run
    (``run_puppet``'s arguments) for the :class:`~skinsynth.gpu.puppet_arrays.PuppetArrays` ``arrays``."""
    x = np.asarray(standardised_controls, dtype=np.float64)
    samples = x.shape[0]
    if x.ndim != 2 or x.shape[1] != arrays.training_controls.shape[1]:
        raise ValueError(f"standardised_controls must be (N, {arrays.training_controls.shape[1]}), got {x.shape}")
    c = None
    if translation_solver:
        if not arrays.has_solver:
            raise ValueError("this puppet has no translation operator (trained without the solver)")
        n_c = arrays.control_operator.shape[1]
        c = np.asarray(controls_in_place, dtype=np.float64)
        if c.shape != (samples, n_c, 3):
            raise ValueError(f"controls_in_place must be ({samples}, {n_c}, 3), got {c.shape}")
    f = None
    if world_frames is not None:
        f = np.asarray(world_frames, dtype=np.float64)
        if f.shape != (samples, 4, 4):
            raise ValueError(f"world_frames must be ({samples}, 4, 4) or None, got {f.shape}")
    return x, c, f


def checked_operator(rotation_operator, control_operator, prior_operator):
    """The translation operator as arrays, Γ (B, B, 3), Q (B, n_c), Π (B, B), checked for shape."""
    gamma, q, prior = (np.asarray(a) for a in (rotation_operator, control_operator, prior_operator))
    bones = gamma.shape[0]
    if gamma.shape != (bones, bones, 3) or q.ndim != 2 or q.shape[0] != bones or prior.shape != (bones, bones):
        raise ValueError(f"expected Γ (B, B, 3), Q (B, n_c), Π (B, B); got {gamma.shape}, {q.shape}, {prior.shape}")
    return gamma, q, prior
