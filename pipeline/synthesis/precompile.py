"""The plants' compiled loops (:mod:`.planting_loops`) built ahead of use: a tiny two-bone bar
with one planted patch, its :class:`.planting.PlantRig` made and :func:`.planting.warm_up` run, so
the specialisation synthesize needs is compiled (or loaded) into numba's cache
(:mod:`skinsynth.pipeline.runtime.compiled`)."""

import numpy as np

from ..runtime import compiled


def tiny_rig():
    """The :class:`.planting.PlantRig` of a two-bone bar with one patch planted in all six frames:
    what loading (or compiling) the loops runs them on."""
    from .contact import planting

    rest = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    indices = np.array([[0, 1], [0, 1], [0, 1], [1, 0]])
    weights = np.array([[1.0, 0.0], [0.8, 0.2], [0.9, 0.1], [1.0, 0.0]])
    frames = 6
    rotations = np.broadcast_to(np.eye(3), (frames, 2, 3, 3)).copy()
    translations = np.zeros((frames, 2, 3))
    examples = np.broadcast_to(rest, (frames, 4, 3)).copy()
    planted = np.ones((frames, 1), bool)
    return planting.plant_rig(rest, indices, weights, rotations, translations, examples, [np.array([0, 1, 2])],
                              planted, np.zeros(1), np.array([0, frames]), 24.0, [[0, 1]])


def compile_loops():
    """Compile (or load from numba's cache) synthesize's numba loops; returns
    :func:`skinsynth.pipeline.runtime.compiled.compile_run`'s report."""
    from .contact import planting, planting_loops

    return compiled.compile_run("synthesis", [planting_loops], lambda: planting.warm_up(tiny_rig()))
