"""The ``synthesis`` stage file written by ``synthesize`` (bones.h5).

Copies forward ``/mesh``, ``/examples`` and ``/skin`` (the weights skin the new bones) and adds
``/synthesis``:

- ``bone_matrices (N, M, B, 3, 3)`` float32, ``bone_translations (N, M, B, 3)`` float32: every
  animation's bones in the world, v = Σ w (F ū + t) (affine near transitions, Zheng eq. 9–10);
  written uncompressed (they are most of the file and gzip would dominate the write time); after
  ``synthesize --cluster`` they are HDF5 virtual datasets over the run's shards
  (:mod:`.synthesis_shards`), read as any dataset while the shard folder stays beside the file;
- ``sources (C, N, M)`` int32: the input frame each component plays at each output frame, a
  global frame number when the input holds several clips (the clip table in the copied
  ``/examples``, ``clip_frames`` and ``@clip_names``, maps it back to ``clip:frame``);
  ``seams (N,)`` int64 the transitions each animation took (all components; with several clips
  a step from one clip's last frame onto the next one's first counts too);
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
import os
import types

import h5py
import numpy as np

from .hdf5_storage import DeclaredTooLarge, held_bytes
from .model import CopyFrom, Uncompressed, VirtualRows, estimated_bytes
from .errors import FormatError
from .synthesis_shards import MOTIONS, reading_output, shard_bytes


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
        "sources": np.asarray(result.sources, dtype=np.int32),
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


class _PlannedRows:
    """The rows a cluster run's workers will store, one piece per batch ``batches`` [(batch id,
    count)]: what the output's virtual datasets will map (``runs``, as ``StoredRows`` gives)."""

    def __init__(self, batches, tail):
        self.batches, self.shape = list(batches), (sum(n for _, n in batches),) + tuple(tail)

    def runs(self):
        starts = np.cumsum([0] + [n for _, n in self.batches])
        return [(f"batch_{b:06d}.h5", n, 0, int(at), n) for (b, n), at in zip(self.batches, starts)]


def planned_bytes(source, request, components, bones, fps, batches=None):
    """(bytes of the output file, bytes of the shards still to write) of a synthesis of
    ``request`` (count, frames) over ``components`` (each with ``bones``) of a ``bones``-bone skin,
    before any of it is made. The output's is :func:`~.model.estimated_bytes` of
    :func:`synthesis_groups` itself, for a stand-in result whose arrays are sized but never
    allocated (broadcast views): the estimate ``write_model`` checks at the end, so a request
    that passes here is not refused there. ``batches`` [(batch id, count, reused)], for a cluster
    run: the batches whose rows the output maps (virtual rows); each one not ``reused`` (a shard an
    earlier run finished) is a shard still to write, of :func:`~.synthesis_shards.shard_bytes`."""
    count, frames, parts = request.count, request.frames, len(components)

    def sized(shape, dtype):
        return np.broadcast_to(np.zeros((), dtype), shape)

    if batches is None:
        F, t = sized((count, frames, bones, 3, 3), np.float32), sized((count, frames, bones, 3), np.float32)
    else:  # the output maps every batch's rows, reused or not
        layout = [(b, n) for b, n, _ in batches]
        F, t = _PlannedRows(layout, (frames, bones, 3, 3)), _PlannedRows(layout, (frames, bones, 3))
    result = types.SimpleNamespace(
        F=F, t=t, sources=sized((parts, count, frames), np.int32), seams_used=sized((count,), np.int64),
        distinct=count, rejected=dict.fromkeys(("collisions", "too_similar", "merges"), 0),
        statistics={key: np.zeros(parts) for key in ("coverage", "mean_segment_frames", "shortest_segment")})
    output = estimated_bytes(synthesis_groups(source, result, components, request, fps,
                                              shards=None if batches is None else "shards"))
    shards = sum(shard_bytes(n, frames, bones, parts) for _, n, reused in (batches or ()) if not reused)
    return output, shards



def space_needs(source, output, request, components, bones, fps, shards=None, batches=None):
    """What a synthesis written to ``output`` needs on disk, [(what, bytes, folder)]: the output
    file (:func:`planned_bytes`) in its folder and, for a cluster run (``shards``:
    :func:`~.synthesis_shards.run_shards`'s; ``batches`` [(batch id, count)] the first round's),
    the shards still to write (those an earlier run finished are reused) in theirs."""
    marked = None if shards is None else [(b, n, (b, n) in shards["stored"]) for b, n in batches]
    file_bytes, shard_bytes = planned_bytes(source, request, components, bones, fps, marked)
    needs = [("the output", file_bytes, os.path.dirname(os.path.abspath(output)))]
    if shards is not None:
        needs.append(("its shards", shard_bytes, shards["folder"]))
    return needs


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


@contextlib.contextmanager
def written_motions(path, result):
    """``result`` (a synthesis: a dataclass with bone motions F and t), its motions those of the
    file written at ``path``, read one animation at a time (:func:`open_motions`: a cluster run's,
    mapped from its shards)."""
    import dataclasses

    with open_motions(path) as (F, t):
        yield dataclasses.replace(result, F=F, t=t)


def read_sources(path, animations=None):
    """sources (C, N, M) int64 of a synthesis file: the input frame each component plays; with
    ``animations`` (indices below N) only theirs, (C, len(animations), M), read one animation at
    a time (the sources of 10⁶ animations of 600 frames are 2.4 GB per component)."""
    with h5py.File(path, "r") as f:
        sources = f["synthesis"]["sources"]
        if animations is None:
            return np.asarray(sources[()], dtype=np.int64)
        return np.stack([np.asarray(sources[:, a], dtype=np.int64) for a in animations], axis=1)


def synthesis_count(path):
    """The number of animations a synthesis file holds (its sources' second axis), read from the
    dataset's shape alone."""
    with h5py.File(path, "r") as f:
        return int(f["synthesis"]["sources"].shape[1])


def component_bones(path):
    """The bone ids (B_c,) int64 of each of a synthesis file's components, in order
    (``/synthesis/component_NNN/bones``)."""
    with h5py.File(path, "r") as f:
        group = f["synthesis"]
        names = sorted(k for k in group if k.startswith("component_"))
        if not names:
            raise FormatError(path, "/synthesis has no components: the file is incomplete")
        return [np.asarray(group[name]["bones"][()], dtype=np.int64) for name in names]
