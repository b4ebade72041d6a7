"""A bulging tube with known controls and random dual quaternions, shared by the correctives' and the linear puppet's tests."""

import numpy as np

from skinsynth.pipeline.inputs.examples import synthetic_lbs
from skinsynth.pipeline.rig.rotations import rigid_to_dual_quaternion



CONTROLS = np.array([3, 30, 60, 90, 110, 125])


def random_dual_quaternions(rng, frames, bones):
    from scipy.spatial.transform import Rotation

    rotations = Rotation.random(frames * bones, random_state=rng).as_matrix().reshape(frames, bones, 3, 3)
    return rigid_to_dual_quaternion(rotations, rng.normal(size=(frames, bones, 3)))


def bulging_tube(frames=40):
    """An LBS tube whose four bones follow a smooth one-parameter motion (a walk-like cycle),
    plus a bulge no bone motion makes: vertices near the middle move along their own radial
    direction by an amount that depends on the pose (the case skinning cannot fit)."""
    from skinsynth.pipeline.rig.rotations import rotation_exp

    data = synthetic_lbs(bones=4, frames=2, rings=16, segments=8, seed=3)
    rng = np.random.default_rng(1)
    phase = np.linspace(0.0, 2.0 * np.pi, frames, endpoint=False)
    pose = np.stack([np.sin(phase), np.cos(2.0 * phase)], axis=1)  # (F, 2)
    rotations = rotation_exp(np.einsum("fp,pbc->fbc", pose, rng.normal(size=(2, 4, 3)) * 0.3))
    translations = np.einsum("fp,pbc->fbc", pose, rng.normal(size=(2, 4, 3)) * 0.2)
    rest, idx, w = data["rest"], data["bone_indices"], data["bone_weights"]
    moved = np.einsum("fvkab,vb->fvka", rotations[:, idx], rest) + translations[:, idx]
    vertices = np.einsum("fvka,vk->fva", moved, w)
    radial = rest * np.array([0.0, 1.0, 1.0])
    radial /= np.maximum(np.linalg.norm(radial, axis=1, keepdims=True), 1e-9)  # 0 on the axis
    envelope = np.exp(-((rest[:, 0] - 2.0) / 0.8) ** 2)
    amount = 0.2 * pose[:, 0] * pose[:, 1]
    data.update(vertices=vertices + amount[:, None, None] * envelope[None, :, None] * radial[None],
                rotations=rotations, translations=translations)
    return data
