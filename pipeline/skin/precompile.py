"""The skin fit's compiled loops (:mod:`.vertex_weights`, :mod:`.transform_sweep`, and for
``--skeleton`` the winding numbers and surface crossings it places its joints inside the mesh by,
:mod:`..mesh.winding`, :mod:`..mesh.crossing`, and its rig's normal equations,
:mod:`.rig_normal_equations`) built ahead of use: ``fit_skin`` run once on a tiny bending bar, the
bar's own points tested against it and a two-bone rig's equations formed, so every specialisation fit-skin needs is compiled (or loaded) with the
argument types the command passes, into numba's cache (:mod:`skinsynth.pipeline.runtime.compiled`)."""

import numpy as np

from ..runtime import compiled
from ..inputs.examples import bending_bar


def compile_loops():
    """Compile (or load from numba's cache) every numba loop of fit-skin on the CPU; returns
    :func:`skinsynth.pipeline.runtime.compiled.compile_run`'s report."""
    from ..mesh import crossing, winding
    from . import rig_normal_equations, transform_sweep, vertex_weights
    from .skin_fit import fit_skin

    vertices, faces = bending_bar(frames=4, rings=3, segments=4)

    def exercise():
        fit_skin(vertices, bones=3, max_influences=2, iterations=2)
        winding.winding_numbers(vertices[0], vertices[0], faces)
        crossing.last_crossings(vertices[0], vertices[0][::-1], winding.triangle_corners(vertices[0], faces))
        frames, bones, anchors = 2, 2, 1
        n = 3 * (bones + anchors)
        rig_normal_equations.normal_equations(
            np.tile(np.eye(3), (frames, bones, 1, 1)), np.eye(3 * bones), np.zeros((anchors, bones, 3)),
            np.eye(anchors), np.zeros((frames, bones, 3, 3)), np.zeros((frames, anchors, 3)),
            np.zeros((frames, anchors, 3)), np.empty((frames, n, n)), np.empty((frames, n)))

    loops = [vertex_weights, transform_sweep, winding, crossing, rig_normal_equations]
    return compiled.compile_run("skin", loops, exercise)
