"""The plants' compiled loops (:mod:`.planting_loops`) built ahead of use: a tiny two-bone bar
with one planted patch, its :class:`.planting.PlantRig` made and :func:`.planting.warm_up` run, so
the specialisation synthesize needs is compiled (or loaded) into numba's cache
(:mod:`skinsynth.pipeline.runtime.compiled`)."""

import numpy as np

from ..runtime import compiled


def tiny_rig():
    """The :class:`.planting.PlantRig` of a three-bone strip (a heavy body, a shin, a foot) with the
    foot's patch planted in all six frames while the shin swings: what loading (or compiling) the
    loops runs them on, its limb's inverse kinematics and the check of its seams included."""
    from skinsynth.gpu import lbs_reference

    from ..rig.rotations import rotation_exp
    from .contact import planting

    x = np.arange(12, dtype=np.float64)
    rest = np.concatenate([np.stack([x, np.zeros(12), np.zeros(12)], 1), np.stack([x, np.ones(12), np.zeros(12)], 1)])
    faces = np.array([f for i in range(11) for f in ([i, i + 1, 12 + i], [i + 1, 13 + i, 12 + i])])
    bone = np.clip(x - 8.0, 0.0, 2.0)  # 0 up to x = 8, then 1, then 2 at the strip's end
    lower = np.minimum(np.floor(bone).astype(np.int64), 1)
    share = bone - lower
    indices = np.tile(np.stack([lower, lower + 1], 1), (2, 1))
    weights = np.tile(np.stack([1.0 - share, share], 1), (2, 1))
    frames = 6
    rotations = np.broadcast_to(np.eye(3), (frames, 3, 3, 3)).copy()
    rotations[:, 1:] = rotation_exp(np.outer(np.linspace(0.0, 0.5, frames), [0.0, 0.0, 1.0]))[:, None]
    joint = np.array([9.0, 0.0, 0.0])
    translations = np.zeros((frames, 3, 3))
    translations[:, 1:] = joint - np.einsum("fij,j->fi", rotations[:, 1], joint)[:, None]
    examples = lbs_reference(rest, indices, weights, rotations, translations)
    planted = np.ones((frames, 1), bool)
    from ..rig.joint_tree import skin_joint_tree
    from ..mesh.shape import shape_envelope

    tree = skin_joint_tree(rest, faces, indices, weights, rotations, translations)
    return planting.plant_rig(rest, indices, weights, rotations, translations, examples, [np.array([11, 23])], planted,
                              np.zeros(1), np.array([0, frames]), 24.0, [[0, 1, 2]], tree,
                              envelope=shape_envelope(examples, faces))


def compile_loops():
    """Compile (or load from numba's cache) synthesize's numba loops; returns
    :func:`skinsynth.pipeline.runtime.compiled.compile_run`'s report."""
    from ..mesh import shape
    from .contact import limb_reach, limb_shape, planting, planting_loops

    def exercise():
        planting.warm_up(tiny_rig())
        shape.edge_strain(np.zeros((1, 2, 3)), np.array([[0, 1]]), np.ones(1))

    return compiled.compile_run("synthesis", [planting_loops, limb_reach, limb_shape, shape], exercise)
