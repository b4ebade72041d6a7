"""Looking at animations without a DCC: a headless z-buffered rasteriser with a framing camera and
a ground plane (:mod:`.rasteriser`), previews laid out as panels with captions (:mod:`.preview`),
what ``skinsynth view`` shows, as pure functions on arrays (:mod:`.scenes`), and the web page that
shows it (:mod:`.pages`: a viser server, one page per kind of file, each from a plain record).

Public: render, frame_bounds, ground_layer, Panel, Preview, error_colors, compared_panels, skin_panels, preview_summary, frame_captions, walk_captions,
compile_loops (the rasteriser built ahead of use: ``skinsynth precompile``),
split_by_key, error_levels, level_colors, vertex_errors, vertex_components, face_components, component_colors,
seam_frames, extrapolation, extrapolation_distances, extrapolation_scale, extrapolation_report, extrapolation_color, resample_session, side_by_side,
planted_vertices, skeleton_lines,
serve, open_page, TrajectoryView, PuppetView, SkinView, SynthesisView, SequenceView, skin_view,
synthesis_view (:mod:`.pages`).
"""

from .._lazy import lazy_exports

_EXPORTS = {"render": "rasteriser", "frame_bounds": "rasteriser", "ground_layer": "rasteriser", "Panel": "preview",
            "Preview": "preview", "error_colors": "preview", "compared_panels": "preview", "skin_panels": "preview",
            "preview_summary": "preview", "frame_captions": "preview",
            "walk_captions": "preview", "compile_loops": "precompile", **{name: "scenes" for name in (
                "split_by_key", "error_levels", "level_colors", "vertex_errors", "vertex_components",
                "face_components", "component_colors", "seam_frames", "extrapolation", "extrapolation_distances", "extrapolation_scale",
                "extrapolation_report",
                "extrapolation_color", "resample_session", "side_by_side", "planted_vertices", "skeleton_lines")},
            **{name: "pages" for name in ("serve", "open_page", "TrajectoryView", "PuppetView", "SkinView",
                                          "SynthesisView", "SequenceView", "skin_view", "synthesis_view")}}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
