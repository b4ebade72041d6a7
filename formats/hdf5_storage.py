"""What an HDF5 dataset's bytes really are: the storage its file holds for it, or, for a virtual
dataset, the storage of every source it maps, each checked to be there.

HDF5 reads anything it cannot find as the dataset's fill value, without an error: unwritten
chunks, a virtual dataset's missing source file, a source file without the mapped dataset, or a
source dataset smaller than its mapping. A reader that trusted that would fit, play or inspect
zeros (or NaN) as if they were the user's data, so every reader sizes a dataset with
:func:`held_bytes` before reading it.
"""

import contextlib
import math
import os
import re

import h5py
import numpy as np

from .errors import FormatError, declared_size_problem

#: Bytes a reader that streams a dataset holds of it at once (:func:`read_blocks`): datasets
#: larger than this are never read whole by ``inspect`` (checks and digests).
BLOCK_BYTES = 64 << 20


class DeclaredTooLarge(ValueError):
    """A dataset declares far more data than its file holds, or maps data that is not there."""


#: A source file that names its key (a cluster run's shard: ``batch_NNNNNN_<first 16 hex of its key>.h5``).
_KEYED_SOURCE = re.compile(r"batch_\d+_([0-9a-f]{16})\.h5$")


def held_bytes(dataset):
    """Bytes stored for ``dataset`` (h5py.Dataset): its own storage, or for a virtual dataset the
    storage of the sources it maps. DeclaredTooLarge naming the first source that is missing,
    unreadable, lacks the mapped dataset or is smaller than the mapping (HDF5 would read those
    parts as fill values, silently), or is a shard that does not carry the key its name gives
    (another run's shard planted under its name would be read as this run's animations)."""
    if not dataset.is_virtual:
        return dataset.id.get_storage_size()
    folder = os.path.dirname(os.path.abspath(dataset.file.filename))
    held, seen = 0, set()
    for mapping in dataset.virtual_sources():
        key = (mapping.file_name, mapping.dset_name)
        if key in seen:
            continue
        seen.add(key)
        held += _source_bytes(dataset, folder, mapping)
    return held


def check_stored(dataset, what):
    """DeclaredTooLarge unless the file (or a virtual dataset's sources) holds ``dataset``'s data:
    what is missing would read as fill values, and a small file must not make a reader allocate
    gigabytes (:func:`~skinsynth.formats.errors.declared_size_problem`). ``what`` names it."""
    problem = declared_size_problem(what, dataset.size * dataset.dtype.itemsize, held_bytes(dataset))
    if problem:
        raise DeclaredTooLarge(problem)


def _source_bytes(dataset, folder, mapping):
    named = _KEYED_SOURCE.search(mapping.file_name)
    hint = "keep the shard folder beside the file" if named else "the virtual dataset's sources must be beside it"
    same_file = mapping.file_name == "."
    source = dataset.file.filename if same_file else os.path.join(folder, mapping.file_name)
    try:
        with (h5py.File(source, "r") if not same_file else contextlib.nullcontext(dataset.file)) as f:
            item = f.get(mapping.dset_name)
            if not isinstance(item, h5py.Dataset):
                raise KeyError(mapping.dset_name)
            covered = _covers(item.shape, mapping)
            held = item.id.get_storage_size()
            carried = f.attrs.get("key", "")
    except (OSError, KeyError):
        raise DeclaredTooLarge(f"{dataset.name} maps {mapping.dset_name} in {mapping.file_name}, which is missing or "
                               f"unreadable ({hint})") from None
    if not covered:
        raise DeclaredTooLarge(f"{dataset.name} maps more of {mapping.dset_name} in {mapping.file_name} than it "
                               f"holds (shape {item.shape}): the rest would read as fill values")
    if named and not str(carried.decode() if isinstance(carried, bytes) else carried).startswith(named.group(1)):
        raise DeclaredTooLarge(f"{dataset.name} maps {mapping.file_name}, which holds another run's batch (its key "
                               "is not the one its name gives): rerun the command to make this run's shard")
    return held


def _covers(shape, mapping):
    """Whether a source dataset of ``shape`` holds every element the mapping reads: up to the
    bounds of a hyperslab source selection, else (the whole source is mapped) as many elements as
    the mapping fills in the virtual dataset. (HDF5 2 reports an all-selection's source space as
    scalar, so its stated shape cannot be used.)"""
    space = mapping.src_space
    if space.get_select_type() == h5py.h5s.SEL_HYPERSLABS and len(space.get_simple_extent_dims()) == len(shape):
        needed = tuple(end + 1 for end in space.get_select_bounds()[1])
        return all(have >= need for have, need in zip(shape, needed))
    return math.prod(shape) >= mapping.vspace.get_select_npoints()


def block_selections(shape, itemsize, block_bytes=BLOCK_BYTES):
    """Selections (tuples of indices and one slice) that cover an array of ``shape`` in C order,
    each a run of consecutive elements of the flattened array of at most ``block_bytes`` (one
    element at least): rows of the first axis while a row fits, else rows of a later axis
    (sources (C, N, M) of 10⁶ animations have rows of gigabytes). Their values laid end to end
    are the array's bytes in C order, however ``block_bytes`` cuts them."""
    if not shape or 0 in shape:
        return
    axis = next((k for k in range(len(shape)) if itemsize * math.prod(shape[k + 1:]) <= block_bytes), len(shape) - 1)
    step = max(1, block_bytes // (itemsize * math.prod(shape[axis + 1:])))
    for index in np.ndindex(*shape[:axis]):
        for start in range(0, shape[axis], step):
            yield index + (slice(start, min(start + step, shape[axis])),)


def read_blocks(dataset, block_bytes=BLOCK_BYTES):
    """``dataset``'s values block by block (:func:`block_selections`), each a C-contiguous array
    of the dataset's dtype; numeric blocks are read into one reused buffer (a block is valid until
    the next is read: the caller reduces it, hashes it or copies it)."""
    tail = None
    buffer = None
    for selection in block_selections(dataset.shape, dataset.dtype.itemsize, block_bytes):
        if dataset.dtype.kind not in "biuf":  # strings, compounds: as h5py reads them
            yield np.ascontiguousarray(dataset[selection])
            continue
        axis = len(selection) - 1
        if buffer is None:
            tail = dataset.shape[axis + 1:]
            step = selection[-1].stop - selection[-1].start
            buffer = np.empty((step,) + tail, dtype=dataset.dtype)
        rows = selection[-1].stop - selection[-1].start
        dataset.read_direct(buffer, source_sel=selection, dest_sel=np.s_[:rows])
        yield buffer[:rows]


class DatasetSummary:
    """A numeric dataset read block by block instead of whole (``read_model(..., summarise_above=)``):
    its ``dtype`` and ``shape`` and, over every value, :meth:`min`, :meth:`max` and
    :meth:`all_finite`, what the checks of :mod:`.validation` ask of an array, so a file of any
    size is checked in the memory of one block. ``np.asarray(summary)`` reads the whole dataset
    (for a check that needs its values)."""

    def __init__(self, dataset, block_bytes=BLOCK_BYTES):
        self.dtype, self.shape = dataset.dtype, tuple(dataset.shape)
        self.filename, self.name = dataset.file.filename, dataset.name
        lows, highs = [], []
        for block in read_blocks(dataset, block_bytes):
            lows.append(block.min())  # NaN when any value is (as numpy's min of the whole), -inf when any is
            highs.append(block.max())
        self._low = np.array(lows, dtype=self.dtype).min() if lows else None
        self._high = np.array(highs, dtype=self.dtype).max() if highs else None

    @property
    def ndim(self):
        return len(self.shape)

    @property
    def size(self):
        return math.prod(self.shape)

    def __len__(self):
        return self.shape[0]

    def min(self):
        return self._low

    def max(self):
        return self._high

    def all_finite(self):
        """Whether every value is finite (as ``np.isfinite(array).all()``): NaN makes the
        smallest and the largest NaN, an infinity one of them infinite."""
        if self.dtype.kind != "f" or self._low is None:
            return True
        return bool(np.isfinite(self._low) and np.isfinite(self._high))

    def __array__(self, dtype=None, copy=None):
        try:
            with h5py.File(self.filename, "r") as f:
                values = f[self.name][()]
        except (OSError, KeyError) as exc:
            raise FormatError(self.filename, f"damaged model file ({exc})") from None
        return values if dtype is None else values.astype(dtype, copy=False)
