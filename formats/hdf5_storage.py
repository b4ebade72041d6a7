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

from .errors import declared_size_problem


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
