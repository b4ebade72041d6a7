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
  ``@targets`` (JSON), ``@window``, ``@spread_velocity``, ``@cut_damping``.
"""

import json

import numpy as np

from .model import Uncompressed


def synthesis_groups(model, result, components, request, fps):
    groups = {name: model[name] for name in ("mesh", "examples", "skin")}
    synthesis = {
        "bone_matrices": Uncompressed(result.F.astype(np.float32)),
        "bone_translations": Uncompressed(result.t.astype(np.float32)),
        "sources": result.sources.astype(np.int32),
        "seams": np.asarray(result.seams_used, dtype=np.int64),
        "@count": int(result.F.shape[0]), "@frames": int(result.F.shape[1]), "@seed": int(request.seed),
        "@distinct": int(result.distinct), "@transitions_used": int(np.sum(result.seams_used)),
        "@rejected_collisions": int(result.rejected["collisions"]),
        "@rejected_too_similar": int(result.rejected["too_similar"]),
        "@rejected_merges": int(result.rejected["merges"]), "@fps": float(fps),
        "@targets": json.dumps([list(map(int, t)) for t in request.targets]), "@window": int(request.window),
        "@spread_velocity": bool(request.spread_velocity), "@cut_damping": float(request.cut_damping),
    }
    for number, component in enumerate(components):
        synthesis[f"component_{number:03d}"] = {"bones": np.asarray(component.bones, dtype=np.int64)}
    groups["synthesis"] = synthesis
    return groups

