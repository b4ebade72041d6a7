"""The skin fit's compiled loops (:mod:`.vertex_weights`, :mod:`.transform_sweep`) built ahead of
use: ``fit_skin`` run once on a tiny bending bar, so every specialisation fit-skin needs is
compiled (or loaded) with the argument types the command passes, into numba's cache
(:mod:`skinsynth.pipeline.runtime.compiled`)."""

from ..runtime import compiled
from ..inputs.examples import bending_bar


def compile_loops():
    """Compile (or load from numba's cache) every numba loop of fit-skin on the CPU; returns
    :func:`skinsynth.pipeline.runtime.compiled.compile_run`'s report."""
    from . import transform_sweep, vertex_weights
    from .skin_fit import fit_skin

    vertices, _ = bending_bar(frames=4, rings=3, segments=4)
    return compiled.compile_run("skin", [vertex_weights, transform_sweep],
                                lambda: fit_skin(vertices, bones=3, max_influences=2, iterations=2))
