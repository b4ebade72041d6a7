"""Looking at animations without a DCC: a headless z-buffered rasteriser with a framing camera and
a ground plane (:mod:`.rasteriser`), and previews laid out as panels with captions (:mod:`.preview`).

Public: render, frame_bounds, ground_layer, Panel, Preview, error_colors.
"""

from .._lazy import lazy_exports

_EXPORTS = {"render": "rasteriser", "frame_bounds": "rasteriser", "ground_layer": "rasteriser", "Panel": "preview",
            "Preview": "preview", "error_colors": "preview"}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
