"""The headless rasteriser's compiled loop (:mod:`.rasteriser`) built ahead of use: one tiny mesh
rendered flat, smooth and with vertex colours over the ground, so every specialisation preview
needs is compiled (or loaded) into numba's cache (:mod:`skinsynth.pipeline.runtime.compiled`)."""

import numpy as np

from ..runtime import compiled
from ..inputs.examples import cylinder_mesh


def compile_loops():
    """Compile (or load from numba's cache) the rasteriser's numba loop; returns
    :func:`skinsynth.pipeline.runtime.compiled.compile_run`'s report."""
    from . import rasteriser

    rest, faces = cylinder_mesh(rings=3, segments=4)
    camera = rasteriser.frame_bounds(rest.min(axis=0), rest.max(axis=0))
    colors = np.linspace(0.0, 1.0, rest.size).reshape(rest.shape)

    def exercise():
        for smooth in (False, True):
            rasteriser.render(rest, faces, camera, width=8, height=6, smooth=smooth)
            rasteriser.render(rest, faces, camera, width=8, height=6, smooth=smooth, ground=rest[:, 1].min(),
                              vertex_colors=colors)

    return compiled.compile_run("view", [rasteriser], exercise)
