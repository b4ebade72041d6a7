"""Shards of a synthesis run on a cluster (``synthesize --cluster``): one HDF5 file per batch of
animations, written (atomically) by the worker that made the batch.

They live in ``<OUT>.shards/`` beside the output (``take.h5.shards/``), which maps their bone motions as HDF5
virtual datasets (:class:`~skinsynth.formats.model.VirtualRows`), so the shards must stay there.
A shard is ``batch_NNNNNN_<key prefix>.h5``; only its attributes say what it holds:

- ``format = "skinsynth-shard"``, ``shard_version``, ``batch``, ``count``;
- ``key``: the sha256 of everything the batch's content depends on (the graph file's and
  obstacles' sha256, the options that change animations, the batch id and size, the tool
  version), and ``provenance`` the same record as JSON, for people;
- ``rejected_collisions``, ``rejected_too_similar``, ``rejected_merges``;
- ``bone_matrices (count, M, B, 3, 3)`` and ``bone_translations (count, M, B, 3)`` float32,
  uncompressed; ``sources (C, count, M)`` and ``choice (count, C)`` int64.

A rerun reuses a shard whose ``key`` matches (whatever it is called) and computes the rest.
"""

import contextlib
import functools
import hashlib
import json
import os

import h5py
import numpy as np

from .atomic import atomic_output
from .errors import FormatError, all_finite

#: The lock a run holds on its shard folder (hidden: no reader takes it for a shard).
LOCK = ".lock"
#: Readers of a cluster run's output hold a shared lock on this file while they read
#: (:func:`reading_output`); a rerun removes the shards only the old output mapped under the
#: exclusive lock (:func:`remove_unused_shards`). HDF5 opens a virtual dataset's sources when it
#: reads them, so a reader that opened the old output just before the new one was renamed in
#: found its shards gone (1 read in 4 failed during a rerun).
READERS = ".readers"
#: How long a rerun waits for readers of the old output before it leaves the old shards to the
#: next run (which removes every shard its output does not map).
READERS_WAIT = 10.0

SHARD_FORMAT = "skinsynth-shard"
#: 2: each shard holds ``limited`` (where the plants could not hold a foot).
SHARD_VERSION = 2
#: The outcome's large arrays, in order, as the shards and the output's /synthesis name them.
MOTIONS = ("bone_matrices", "bone_translations")
_REJECTED = ("collisions", "too_similar", "merges")


def shard_folder(output):
    """Where the shards of ``output`` live: ``<output>.shards`` beside it (the whole name, so
    ``take.h5`` and ``take.hdf5`` never share a folder, nor remove each other's shards)."""
    return os.path.abspath(output) + ".shards"


def shard_record(inputs, parameters, tool_version, batch_revision=0):
    """What every batch of a run depends on (batch id and size are added per shard):
    ``inputs`` [{path, sha256}], ``parameters`` (the options that change animations), the tool's
    version and ``batch_revision``, the revision of the code that makes a batch (a change of
    code between versions never reuses shards the older code made)."""
    return {"inputs": [item["sha256"] for item in inputs], "parameters": parameters, "tool_version": tool_version,
            "shard_version": SHARD_VERSION, "batch_revision": int(batch_revision)}


def _key(record, batch, count):
    text = json.dumps(dict(record, batch=int(batch), count=int(count)), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def shard_bytes(count, frames, bones, components):
    """An upper bound of one shard's size: ``count`` animations of ``frames`` frames, their bone
    motions (float32 3×3 + 3 per bone), walks (sources and choice, int64 per component) and limbs'
    limits (a byte a frame), plus 1 MiB of HDF5 structure. What the worker checks the free space against, and ``synthesize``
    sums over the batches before any work."""
    return 4 * 12 * count * frames * bones + 8 * components * count * (frames + 1) + count * frames + (1 << 20)


def write_synthesis_shard(folder, record, batch, count, outcome):
    """Write one batch (``outcome`` = [F, t, sources, choice, limited, rejected] from
    ``pipeline.synthesis.make_batch``) to its shard in ``folder``; returns the file's name."""
    key = _key(record, batch, count)
    name = f"batch_{int(batch):06d}_{key[:16]}.h5"
    F, t, sources, choice, limited, rejected = outcome
    path = os.path.join(folder, name)
    frames, bones = np.shape(t)[1:3]
    with atomic_output(path, expected_bytes=shard_bytes(len(t), frames, bones, np.shape(sources)[0])) as tmp:
        with h5py.File(tmp, "w", track_order=True) as f:
            f.attrs.update(format=SHARD_FORMAT, shard_version=SHARD_VERSION, batch=int(batch), count=int(count),
                           key=key, provenance=json.dumps(dict(record, batch=int(batch), count=int(count)),
                                                          sort_keys=True))
            for reason in _REJECTED:
                f.attrs[f"rejected_{reason}"] = int(rejected[reason])
            for dataset, array in zip(MOTIONS, (F, t)):
                f.create_dataset(dataset, data=np.asarray(array, dtype=np.float32), track_times=False)
            f.create_dataset("sources", data=np.asarray(sources, dtype=np.int64), track_times=False)
            f.create_dataset("choice", data=np.asarray(choice, dtype=np.int64), track_times=False)
            f.create_dataset("limited", data=np.asarray(limited, dtype=np.uint8), track_times=False)
    return name


def stored_shards(folder, record, frames, bones):
    """{(batch, count): (name, [sources, choice, limited, rejected])} for every complete shard in
    ``folder`` whose key matches ``record`` (names are not trusted: a shard is what its
    attributes and shapes say), and whose motions are finite (a damaged shard is computed again, as
    a fresh batch with NaN would be refused). Files that are not such shards are left alone."""
    found = {}
    if not os.path.isdir(folder):
        return found
    for name in sorted(os.listdir(folder)):
        if not name.endswith(".h5") or name.startswith("."):
            continue
        try:
            with h5py.File(os.path.join(folder, name), "r") as f:
                if f.attrs.get("format") != SHARD_FORMAT or int(f.attrs.get("shard_version", -1)) != SHARD_VERSION:
                    continue
                batch, count = int(f.attrs["batch"]), int(f.attrs["count"])
                if f.attrs.get("key") != _key(record, batch, count):
                    continue
                shapes = {"bone_matrices": (count, frames, bones, 3, 3), "bone_translations": (count, frames, bones, 3)}
                if any(f[d].shape != shape or f[d].id.get_storage_size() != 4 * int(np.prod(shape))
                       for d, shape in shapes.items()):
                    continue
                if not all(all_finite(f[d][()]) for d in shapes):  # checked as a fresh batch is: never reused
                    continue
                rest = [f["sources"][()], f["choice"][()], f["limited"][()],
                        {r: int(f.attrs[f"rejected_{r}"]) for r in _REJECTED}]
        except (OSError, KeyError, ValueError, TypeError):
            continue  # unreadable or not ours: computed again
        found[(batch, count)] = (name, rest)
    return found


def remove_unused_shards(folder, used, wait=None):
    """Remove the shards in ``folder`` that no output maps any more (``used``: file names);
    other files are left alone. Done under the exclusive readers' lock (:data:`READERS`): while a
    reader still reads the old output after ``wait`` seconds (default :data:`READERS_WAIT`),
    nothing is removed (the next run does it). Returns the number of shards removed, or None
    when they were left."""
    import fcntl
    import time

    handle = os.open(os.path.join(folder, READERS), os.O_RDWR | os.O_CREAT, 0o666)
    try:
        deadline = time.monotonic() + (READERS_WAIT if wait is None else wait)
        while True:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    return None
                time.sleep(0.05)
            except OSError:  # no flock here (some network file systems): remove as before
                break
        return _remove_unused(folder, used)
    finally:
        os.close(handle)


def _remove_unused(folder, used):
    removed = 0
    for name in os.listdir(folder):
        if name.startswith("batch_") and name.endswith(".h5") and name not in used:
            try:
                with h5py.File(os.path.join(folder, name), "r") as f:
                    ours = f.attrs.get("format") == SHARD_FORMAT
            except OSError:
                continue
            if ours:
                os.remove(os.path.join(folder, name))
                removed += 1
    return removed


def check_shard_folder(folder):
    """Create the shard folder (or check it) before any work; FormatError when it cannot be."""
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as error:
        raise FormatError(folder, f"cannot create the shard folder: {error.strerror}") from None
    if not os.access(folder, os.W_OK):
        raise FormatError(folder, "the shard folder is not writable")


def run_shards(output, record, frames, bones, batch_revision=0):
    """{folder, stored, store} of a ``synthesize --cluster`` run writing ``output``: the shard
    folder, the shards an earlier run finished with the same record (``record``: the output's
    provenance record; what a batch depends on is kept, not the total count or the obstacles'
    paths), and the store the workers call (:func:`write_synthesis_shard` with that record)."""
    folder = shard_folder(output)
    # what a batch's animations depend on: not the total count or the obstacles' paths (their bytes count)
    parameters = {k: v for k, v in record["parameters"].items() if k not in ("count", "obstacles")}
    shard = shard_record(record["inputs"], parameters, record["tool_version"], batch_revision)
    return {"folder": folder, "stored": stored_shards(folder, shard, frames, bones),
            "store": functools.partial(write_synthesis_shard, folder, shard)}


@contextlib.contextmanager
def reading_output(path):
    """Hold the shared readers' lock of ``path``'s shard folder, if it has one, while the body
    opens and reads ``path`` (a no-op for a file without shards, or where ``flock`` fails)."""
    import fcntl

    try:
        handle = os.open(os.path.join(shard_folder(path), READERS), os.O_RDONLY)
    except OSError:
        yield
        return
    try:
        with contextlib.suppress(OSError):
            fcntl.flock(handle, fcntl.LOCK_SH)  # waits only while a run removes old shards
        yield
    finally:
        os.close(handle)


@contextlib.contextmanager
def kept_shard_folder(folder):
    """The shard folder, made for the run and removed again if the run fails before any shard
    is in it (a failed command leaves nothing new behind; finished shards stay for a rerun).

    The run holds an exclusive lock on the folder (``flock`` on :data:`LOCK`, released however
    the process ends): a second run writing the same output at once is refused in one line
    instead of mixing its shards with the first's. (On a network file system without working
    ``flock``, runs are not kept apart.)"""
    import fcntl

    existed = os.path.isdir(folder)
    check_shard_folder(folder)
    lock = os.open(os.path.join(folder, LOCK), os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise FormatError(folder, "another synthesize is writing this output now (its shard folder is locked): "
                                      "wait for it to end, or write another file") from None
        os.close(os.open(os.path.join(folder, READERS), os.O_RDWR | os.O_CREAT, 0o666))  # readers lock it
        yield
    except BaseException:
        if not existed:
            with contextlib.suppress(OSError):
                for name in (LOCK, READERS):
                    os.remove(os.path.join(folder, name))
                os.rmdir(folder)  # only when empty
        raise
    finally:
        os.close(lock)
