"""The skin fit's compiled loops (:mod:`.vertex_weights`, :mod:`.transform_sweep`, and the winding
numbers ``--skeleton`` places its joints inside the mesh by, :mod:`..mesh.winding`) built ahead
of use: ``fit_skin`` run once on a tiny bending bar and the bar's own points tested against it,
so every specialisation fit-skin needs is compiled (or loaded) with the argument types the command
passes, into numba's cache (:mod:`skinsynth.pipeline.runtime.compiled`)."""

from ..runtime import compiled
from ..inputs.examples import bending_bar


def compile_loops():
    """Compile (or load from numba's cache) every numba loop of fit-skin on the CPU; returns
    :func:`skinsynth.pipeline.runtime.compiled.compile_run`'s report."""
    from ..mesh import winding
    from . import transform_sweep, vertex_weights
    from .skin_fit import fit_skin

    vertices, faces = bending_bar(frames=4, rings=3, segments=4)

    def exercise():
        fit_skin(vertices, bones=3, max_influences=2, iterations=2)
        winding.winding_numbers(vertices[0], vertices[0], faces)

    return compiled.compile_run("skin", [vertex_weights, transform_sweep, winding], exercise)
