"""The ``synthesis`` stage file written by ``synthesize`` (bones.h5).

Copies forward ``/mesh``, ``/examples`` and ``/skin`` (the weights skin the new bones) and adds
``/synthesis``:

- ``bone_matrices (N, M, B, 3, 3)`` float32, ``bone_translations (N, M, B, 3)`` float32: every
  animation's bones in the world, v = Σ w (F ū + t) (affine near transitions, Zheng eq. 9–10);
  written uncompressed (they are most of the file and gzip would dominate the write time);
- ``sources (C, N, M)`` int32: the input frame each component plays at each output frame;
  ``seams (N,)`` int64 the transitions each animation took (all components);
- ``component_NNN/bones`` the bone ids of each component;
- attributes ``@count``, ``@frames``, ``@seed``, ``@distinct``, ``@transitions_used``,
  ``@rejected_collisions``, ``@rejected_too_similar``, ``@rejected_merges``, ``@fps``,
  ``@targets`` (JSON), ``@window``, ``@spread_velocity``, ``@cut_damping``, ``@min_segment``,
  ``@blend``, ``@alignment``, ``@up_axis``;
- per component (C,): ``coverage`` (share of the clip's frames the walks play),
  ``mean_segment_frames``, ``shortest_segment`` (frames between two seams).
"""

import json

import numpy as np

from .model import CopyFrom, Uncompressed


def synthesis_groups(source, result, components, request, fps):
    """The groups of a synthesis file; ``/mesh``, ``/examples`` and ``/skin`` are copied as
    stored from the graph file ``source``."""
    groups = {name: CopyFrom(source, name) for name in ("mesh", "examples", "skin")}
    synthesis = {
        "bone_matrices": Uncompressed(np.asarray(result.F, dtype=np.float32)),  # no copy when already float32
        "bone_translations": Uncompressed(np.asarray(result.t, dtype=np.float32)),
        "sources": result.sources.astype(np.int32),
        "seams": np.asarray(result.seams_used, dtype=np.int64),
        "@count": int(result.F.shape[0]), "@frames": int(result.F.shape[1]), "@seed": int(request.seed),
        "@distinct": int(result.distinct), "@transitions_used": int(np.sum(result.seams_used)),
        "@rejected_collisions": int(result.rejected["collisions"]),
        "@rejected_too_similar": int(result.rejected["too_similar"]),
        "@rejected_merges": int(result.rejected["merges"]), "@fps": float(fps),
        "@targets": json.dumps([list(map(int, t)) for t in request.targets]), "@window": int(request.window),
        "@spread_velocity": bool(request.spread_velocity), "@cut_damping": float(request.cut_damping),
        "@min_segment": int(request.min_segment), "@blend": str(request.blend), "@alignment": str(request.alignment),
        "@up_axis": "XYZ"[int(request.up_axis)],
    }
    for key in ("coverage", "mean_segment_frames", "shortest_segment"):
        synthesis[key] = np.asarray(result.statistics[key])
    for number, component in enumerate(components):
        synthesis[f"component_{number:03d}"] = {"bones": np.asarray(component.bones, dtype=np.int64)}
    groups["synthesis"] = synthesis
    return groups

