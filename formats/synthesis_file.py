"""The ``synthesis`` stage file written by ``synthesize`` (bones.h5).

Copies forward ``/mesh``, ``/examples`` and ``/skin`` (the weights skin the new bones) and adds
``/synthesis``:

- ``bone_matrices (N, M, B, 3, 3)`` float32, ``bone_translations (N, M, B, 3)`` float32: every
  animation's bones in the world, v = Σ w (F ū + t) (affine near transitions, Zheng eq. 9–10);
  written uncompressed (they are most of the file and gzip would dominate the write time); after
  ``synthesize --cluster`` they are HDF5 virtual datasets over the run's shards
  (:mod:`.synthesis_shards`), read as any dataset while the shard folder stays beside the file;
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

import contextlib
import json

import h5py
import numpy as np

from .hdf5_storage import DeclaredTooLarge, held_bytes
from .model import CopyFrom, Uncompressed, VirtualRows
from .errors import FormatError
from .synthesis_shards import MOTIONS, reading_output


def _motion(rows, name, shards):
    """A bone-motion dataset: the array itself, or (rows the cluster's workers stored, which have
    ``runs()``) a virtual dataset over the shards in the folder ``shards`` beside the file."""
    if not hasattr(rows, "runs"):
        return Uncompressed(np.asarray(rows, dtype=np.float32))  # no copy when already float32
    return VirtualRows(rows.shape, np.float32, [(f"{shards}/{handle}", name, *run) for handle, *run in rows.runs()])


def synthesis_groups(source, result, components, request, fps, shards=None):
    """The groups of a synthesis file; ``/mesh``, ``/examples`` and ``/skin`` are copied as
    stored from the graph file ``source``; ``shards``: the shard folder's name, when the bone
    motions are rows the workers of a cluster stored."""
    groups = {name: CopyFrom(source, name) for name in ("mesh", "examples", "skin")}
    synthesis = {
        MOTIONS[0]: _motion(result.F, MOTIONS[0], shards),
        MOTIONS[1]: _motion(result.t, MOTIONS[1], shards),
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



@contextlib.contextmanager
def open_motions(path):
    """(bone_matrices, bone_translations) of a synthesis file as h5py datasets, read one
    animation at a time (``F[a]``): a cluster run's motions need not fit in memory. The shards a
    cluster run's motions map are checked first (present, readable, this run's): FormatError
    naming the file otherwise, as every reader of the file says."""
    with reading_output(path), h5py.File(path, "r") as f:
        motions = f["synthesis"][MOTIONS[0]], f["synthesis"][MOTIONS[1]]
        try:
            for dataset in motions:
                held_bytes(dataset)
        except DeclaredTooLarge as exc:
            raise FormatError(path, f"damaged model file: {exc}") from None
        yield motions


def read_sources(path):
    """sources (C, N, M) int64 of a synthesis file: the input frame each component plays."""
    with h5py.File(path, "r") as f:
        return np.asarray(f["synthesis"]["sources"][()], dtype=np.int64)
