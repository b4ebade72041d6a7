"""One-to-many synthesis (Zheng 2013): the analysis build-graph stores (:mod:`.graph`: transitions
:mod:`.transitions` §3.2 eq. 2–6, the bone graph and its cut nodes :mod:`.bone_graph` eq. 11, key
vertices :mod:`.key_vertices` App. A, deformation gradients :mod:`.deformation_gradients` eq. 8),
and synthesize (:mod:`.synthesis`): walks on the motion graph (:mod:`.motion_graph`), splicing
with Poisson blending (:mod:`.splicing`, eq. 7–10), the multi-component merge
(:mod:`.assembly`, Alg. 1, eq. 12–14), ground contact (:mod:`.contact`: the input's plants kept, the support kept after the merge, the feet measures) and obstacles
(:mod:`.collisions`, §3.4).

Public: build_graph, analyse_fit, graph_summary, GraphOptions, validate_graph_options, bone_layout, default_min_segment, walk_statistics,
synthesize, batch_sizes, BATCH_REVISION, Request, validate_request, synthesis_request, prepare_synthesis, component_from_file, synthesis_components, avoid_obstacles,
keep_input_support, keep_input_plants, mark_contact_jumps, compile_loops (the plants' compiled loops built
ahead of use: ``skinsynth precompile``), SkinnedAnimations, measure_feet, measure_shape, report_measures, acceleration_plots, build_obstacles,
colliding, vertex_subset, find_contacts, validate_contact_options, synthesis_summary, cluster_summary (what synthesize
reports: :mod:`.summaries`).
"""

from .._lazy import lazy_exports

_EXPORTS = {"build_graph": "graph", "analyse_fit": "graph", "graph_summary": "summaries", "GraphOptions": "graph_options", "validate_graph_options": "graph", "bone_layout": "graph",
            "default_min_segment": "motion_graph", "walk_statistics": "motion_graph", "synthesize": "synthesis",
            "batch_sizes": "synthesis", "BATCH_REVISION": "synthesis", "Request": "synthesis", "validate_request": "synthesis", "component_from_file": "synthesis",
            "synthesis_components": "synthesis", "prepare_synthesis": "synthesis",
            "synthesis_request": "synthesis", "avoid_obstacles": "synthesis", "keep_input_support": "synthesis",
            "keep_input_plants": "synthesis", "mark_contact_jumps": "contact.planting", "compile_loops": "precompile",
            "SkinnedAnimations": "skinned", "find_contacts": "contact.patches",
            "validate_contact_options": "contact.patches", "measure_feet": "skinned", "measure_shape": "skinned", "report_measures": "skinned", "acceleration_plots": "skinned",
            "synthesis_summary": "summaries", "cluster_summary": "summaries", "build_obstacles": "collisions", "colliding": "collisions", "vertex_subset": "collisions"}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
