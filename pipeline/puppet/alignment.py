"""Global motion: rigid frames fitted to control points, to bring examples in place and back.

Feng's examples are in place; real sequences travel and turn. Training and run time both use
the same definition of "in place": the rigid transform that best maps a frame's control points
onto the reference (rest-frame) control points (unweighted Procrustes). At run time only the
control points are known, so a frame fitted to them is the one definition both sides can share.
"""

import numpy as np

from ..rig.rotations import polar_rotation


def control_frames(controls, reference):
    """Rigid transforms taking each frame's control points onto the reference.

    controls (F, n, 3), reference (n, 3) -> (rotations (F, 3, 3), translations (F, 3))
    minimising ``Σ_l |R c_l + t − r_l|²``. Needs n ≥ 3 non-collinear points for a unique
    rotation (with fewer, the nearest rotation of a rank-deficient covariance is returned).
    """
    controls = np.asarray(controls, dtype=np.float64)
    mean_c = controls.mean(axis=1)
    mean_r = reference.mean(axis=0)
    cross = np.einsum("na,fnb->fab", reference - mean_r, controls - mean_c[:, None])
    rotations = polar_rotation(cross)
    translations = mean_r - np.einsum("fab,fb->fa", rotations, mean_c)
    return rotations, translations


def apply_frames(rotations, translations, points):
    """points (F, n, 3) moved by per-frame transforms: ``p @ R[f].T + t[f]``."""
    return np.einsum("fab,fnb->fna", rotations, points) + translations[:, None, :]


def invert_frames(rotations, translations):
    """Inverse rigid transforms: (Rᵀ, −Rᵀ t)."""
    inverse = np.swapaxes(rotations, -1, -2)
    return inverse, -np.einsum("fab,fb->fa", inverse, translations)


def frame_conditioning(controls):
    """How well control points (F, n, 3) fix a rotation: min over frames of s₂/s₁.

    s₁ ≥ s₂ are the two largest singular values of the centred points; a rotation is determined
    when the points are not collinear (s₂ > 0), and is unstable (it can flip by up to 180°
    between similar frames) when s₂ is small next to s₁."""
    centred = controls - controls.mean(axis=1, keepdims=True)
    singular = np.linalg.svd(centred, compute_uv=False)
    if singular.shape[1] < 2:
        return 0.0
    return float(np.min(singular[:, 1] / np.maximum(singular[:, 0], np.finfo(float).tiny)))

