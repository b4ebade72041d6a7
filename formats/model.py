"""The skinsynth HDF5 model file (format version 1): one file per stage output.

Layout (docs/format.md is the full reference):

- root attributes ``format = "skinsynth"``, ``format_version``, ``stage``, ``tool_version``;
- ``/provenance/NN_<stage>`` one group per stage that contributed, oldest first, with
  attributes ``command``, ``parameters`` (JSON), ``inputs`` (JSON list of {path, sha256}),
  ``tool_version``, ``seed``, ``date``;
- one group per concept (``/mesh``, ``/examples``, ``/skin``, …) holding datasets (and, where a
  concept repeats, subgroups such as ``/graph/component_000``); their attributes hold scalars.

Writers go through :func:`~skinsynth.formats.atomic.atomic_output`, so a failed command leaves
no file. Datasets are written without timestamps and with fixed filters so that the same
inputs and seed give byte-identical datasets.
"""

import json
import os

import h5py
import numpy as np

from .atomic import atomic_output
from .errors import FormatError, require_finite
from .hdf5_storage import BLOCK_BYTES, DatasetSummary, DeclaredTooLarge, check_stored, held_bytes, read_blocks
from .synthesis_shards import reading_output

FORMAT_NAME = "skinsynth"
FORMAT_VERSION = 1

#: stage name -> the command that writes it, for error messages.
STAGES = {
    "skin": "fit-skin",
    "controls": "select-controls",
    "puppet": "train-kcca",
    "graph": "build-graph",
    "synthesis": "synthesize",
}


class Uncompressed:
    """Marks a large dataset to be written without compression (gzip would dominate the write)."""

    def __init__(self, array):
        self.array = np.asarray(array)


class VirtualRows:
    """Marks a dataset written as an HDF5 virtual dataset over other files' rows (the shards of
    a cluster run): ``shape``, ``dtype``, ``runs`` [(file relative to this file's folder,
    dataset name, the source's rows, first source row, first row here, length)]. Rows no run
    covers, or whose file is gone, read as NaN (readers here refuse such a file first)."""

    def __init__(self, shape, dtype, runs):
        self.shape, self.dtype, self.runs = tuple(shape), np.dtype(dtype), list(runs)

    def layout(self):
        layout = h5py.VirtualLayout(shape=self.shape, dtype=self.dtype)
        for file, name, rows, first, at, length in self.runs:
            source = h5py.VirtualSource(file, name, shape=(rows,) + self.shape[1:], dtype=self.dtype)
            layout[at:at + length] = source[first:first + length]
        return layout


class CopyFrom:
    """A whole group forwarded from another model file as stored (HDF5 object copy: compressed
    chunks are copied, not decompressed and compressed again)."""

    def __init__(self, path, name):
        self.path, self.name = os.fspath(path), name


def _write_group(group, contents):
    for name, value in contents.items():
        if name.startswith("@"):
            group.attrs[name[1:]] = value
            continue
        if isinstance(value, dict):  # a nested group, e.g. /graph/component_000
            _write_group(group.create_group(name, track_order=True), value)
            continue
        if isinstance(value, Uncompressed):
            group.create_dataset(name, data=value.array, track_times=False)
            continue
        if isinstance(value, VirtualRows):
            group.create_virtual_dataset(name, value.layout(), fillvalue=np.nan)
            continue
        array = np.asarray(value)
        if array.ndim == 0:
            group.create_dataset(name, data=array, track_times=False)
        elif array.dtype.kind in "fiub" and array.size >= 64:
            group.create_dataset(name, data=array, compression="gzip", compression_opts=4,
                                 shuffle=True, track_times=False)
        else:
            group.create_dataset(name, data=array, track_times=False)


def _require_finite_groups(path, groups, prefix=""):
    """Refuse to write any float dataset or attribute holding NaN or inf (named in the error)."""
    for name, value in groups.items():
        if isinstance(value, (CopyFrom, VirtualRows)):
            continue  # forwarded from a file, or rows of files, checked when they were written
        if isinstance(value, dict):
            _require_finite_groups(path, value, f"{prefix}/{name}")
            continue
        array = value.array if isinstance(value, Uncompressed) else value
        if isinstance(array, (str, bytes)):
            continue
        label = f"{prefix}/@{name[1:]}" if name.startswith("@") else f"{prefix}/{name}"
        require_finite(path, label, array)


def estimated_bytes(groups):
    """An upper bound of a file's size: its arrays uncompressed, forwarded groups as stored,
    plus 1 MiB of HDF5 structure. (What :func:`write_model` checks the free space against; a
    caller may estimate before any work from arrays sized but never allocated, e.g.
    ``np.broadcast_to``, as ``synthesize`` does.)"""
    total = 1 << 20
    for value in groups.values():
        if isinstance(value, CopyFrom):
            total += os.path.getsize(value.path)
        elif isinstance(value, VirtualRows):
            total += 64 * len(value.runs)
        elif isinstance(value, dict):
            total += estimated_bytes(value) - (1 << 20)
        else:
            total += getattr(value.array if isinstance(value, Uncompressed) else np.asarray(value), "nbytes", 0)
    return total


def write_model(path, stage, groups, provenance, tool_version):
    """Write a model file atomically.

    groups: {group name: {dataset name: array, "@attribute": scalar}}; provenance: list of
    dicts with keys command, parameters (dict), inputs (list), tool_version, seed, date
    (earlier stages first; the caller appends its own record).
    """
    if stage not in STAGES:
        raise ValueError(f"unknown stage {stage!r}")
    _require_finite_groups(path, groups)
    with atomic_output(path, expected_bytes=estimated_bytes(groups)) as tmp:
        with h5py.File(tmp, "w", track_order=True) as f:
            f.attrs["format"] = FORMAT_NAME
            f.attrs["format_version"] = FORMAT_VERSION
            f.attrs["stage"] = stage
            f.attrs["tool_version"] = tool_version
            prov = f.create_group("provenance", track_order=True)
            for number, record in enumerate(provenance):
                g = prov.create_group(f"{number:02d}_{record['stage']}")
                for key in ("stage", "command", "tool_version", "date"):
                    g.attrs[key] = str(record.get(key, ""))
                g.attrs["seed"] = -1 if record.get("seed") is None else int(record["seed"])
                g.attrs["parameters"] = json.dumps(record.get("parameters", {}), sort_keys=True)
                g.attrs["inputs"] = json.dumps(record.get("inputs", []))
            for name, contents in groups.items():
                if isinstance(contents, CopyFrom):
                    with h5py.File(contents.path, "r") as source:
                        source.copy(source[contents.name], f, name=name)
                    continue
                _write_group(f.create_group(name, track_order=True), contents)


def _read_group(group, summarise_above=None):
    out = {f"@{k}": (v.decode() if isinstance(v, bytes) else v) for k, v in group.attrs.items()}
    for name, item in group.items():
        if isinstance(item, h5py.Dataset):
            # Sizes are checked against what the file holds before anything is allocated: a
            # small file must not make a reader ask for gigabytes (unwritten chunks read as fill).
            check_stored(item, item.name)
            if summarise_above is not None and item.ndim and item.dtype.kind in "biuf" \
                    and item.size * item.dtype.itemsize > summarise_above:
                out[name] = DatasetSummary(item, summarise_above)  # read a block at a time, not whole
            else:
                out[name] = item[()]
        elif isinstance(item, h5py.Group):
            out[name] = _read_group(item, summarise_above)
    return out


#: What a file that is no model file may be, by its suffix, and the command that takes it (issue 68:
#: ``build-graph capture.npz`` said only "not an HDF5 file").
_SEQUENCE_SUFFIXES = (".npz", ".obj", ".ply", ".off", ".usd", ".usda", ".usdc", ".usdz")
_EXPORT_SUFFIXES = (".glb", ".gltf", ".exr", ".png", ".mp4", ".gif", ".json")


def _what_it_is(path):
    """A hint naming what a file that HDF5 cannot open probably is, from its suffix ('' if none)."""
    suffix = os.path.splitext(str(path))[1].lower()
    if os.path.isdir(str(path)) or suffix in _SEQUENCE_SUFFIXES:
        return ("; it looks like a mesh sequence: `skinsynth fit-skin` reads it and writes the .h5 skin file the "
                "other commands take")
    if suffix == ".c3d":
        return "; it looks like a marker take: `skinsynth play PUPPET -c` reads it"
    if suffix in _EXPORT_SUFFIXES:
        return "; it looks like an export or a picture skinsynth wrote: the commands read the .h5 files it wrote first"
    return ""


def read_header(path):
    """Return (stage, format_version) of a model file, refusing what is not one."""
    try:
        f = h5py.File(path, "r")
    except FileNotFoundError:
        raise FormatError(path, "no such file") from None
    except OSError:
        raise FormatError(path, "not an HDF5 file (or unreadable)" + _what_it_is(path)) from None
    with f:
        if f.attrs.get("format") != FORMAT_NAME:
            raise FormatError(path, "not a skinsynth model file (no format = 'skinsynth' attribute); if it holds a "
                                    "mesh sequence, `skinsynth fit-skin` reads it and writes the skin file the other "
                                    "commands take")
        raw = f.attrs.get("format_version", -1)
        if np.ndim(raw) != 0 or np.asarray(raw).dtype.kind not in "iu":  # 1.5 or "1" is not a version
            raise FormatError(path, f"invalid format_version {np.asarray(raw).tolist()!r}: an integer is needed")
        version = int(raw)
        stage = f.attrs.get("stage", "")
        stage = stage.decode() if isinstance(stage, bytes) else stage
        if stage not in STAGES:
            raise FormatError(path, f"its stage is {stage!r}, not one of {', '.join(STAGES)}")
        tool = f.attrs.get("tool_version", "")
        if not isinstance(tool, (str, bytes)):
            raise FormatError(path, f"its tool_version is {tool!r}, not a version text")
    if version > FORMAT_VERSION:
        raise FormatError(path, f"format_version {version} is newer than this skinsynth reads "
                                f"({FORMAT_VERSION}); upgrade skinsynth")
    if version < 1:
        raise FormatError(path, f"invalid format_version {version}")
    return stage, version


def read_model(path, stages=None, groups=None, summarise_above=None):
    """Read a whole model file into nested dicts.

    stages: the stages the caller accepts (None = any); groups: the groups to read (None = all:
    a caller that needs only the skin need not load a synthesis's motions). Returns {"stage",
    "format_version", "provenance": [records], group name: {dataset: array, "@attr": value}}.
    summarise_above: bytes; a numeric dataset larger than this is read that many bytes at a time,
    in the same order and with the same errors, and stands as a
    :class:`~skinsynth.formats.hdf5_storage.DatasetSummary` (shape, dtype, smallest and largest
    value: what the checks need) instead of an array: ``inspect`` checks a file of any size in
    bounded memory (a 10⁶-animation synthesis holds 661 GB of motions).
    """
    stage, version = read_header(path)
    if stages is not None and stage not in stages:
        wanted = " or ".join(f"a '{s}' file (from {STAGES[s]})" for s in stages)
        raise FormatError(path, f"is a '{stage}' file (from {STAGES[stage]}); this command needs {wanted}")
    model = {"stage": stage, "format_version": version, "provenance": []}
    try:
        with reading_output(path), h5py.File(path, "r") as f:
            for _, g in f.get("provenance", {}).items():
                record = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in g.attrs.items()}
                record["parameters"] = json.loads(record.get("parameters", "{}"))
                record["inputs"] = json.loads(record.get("inputs", "[]"))
                record["seed"] = None if int(record.get("seed", -1)) < 0 else int(record["seed"])
                model["provenance"].append(record)
            for name, item in f.items():
                if name != "provenance" and isinstance(item, h5py.Group) and (groups is None or name in groups):
                    model[name] = _read_group(item, summarise_above)
    except DeclaredTooLarge as exc:
        raise FormatError(path, f"damaged model file: {exc}") from None
    except (OSError, KeyError, ValueError) as exc:
        raise FormatError(path, f"damaged model file ({exc})") from None
    return model


def text(value):
    """A stored string as str: HDF5 hands some back as bytes (UTF-8)."""
    return value.decode("utf-8") if isinstance(value, bytes) else str(value)


def require(model, path, group, names):
    """Check that ``model[group]`` holds every dataset in ``names``; FormatError otherwise."""
    missing = [n for n in names if n not in model.get(group, {})]
    if missing:
        raise FormatError(path, f"/{group} lacks {', '.join(missing)}: the file is incomplete")
    return model[group]


def content_digests(path, block_bytes=BLOCK_BYTES):
    """{name: sha256 hex} of every dataset (its dtype, shape and values) and attribute of a model
    file, the provenance's aside (it holds dates and command lines). Two files with equal digests
    hold the same data bit for bit however it is stored: compressed, contiguous, or virtual over
    a cluster run's shards. Datasets are read ``block_bytes`` at a time."""
    import hashlib

    read_header(path)  # refuses what is not a model file
    digests = {}

    def visit(name, item):
        if name.split("/", 1)[0] == "provenance":
            return
        for key, value in sorted(item.attrs.items()):
            digests[f"{name}@{key}"] = hashlib.sha256(repr(value).encode()).hexdigest()
        if isinstance(item, h5py.Dataset):
            held_bytes(item)  # a virtual dataset's missing source would read as fill values
            digest = hashlib.sha256(f"{item.dtype.str} {item.shape}".encode())
            if item.shape and item.dtype.kind != "O":
                for block in read_blocks(item, block_bytes):  # the values' bytes in C order, whatever the blocks
                    digest.update(block)
            else:
                value = item[()]
                digest.update(repr(value.tolist() if hasattr(value, "tolist") else value).encode())
            digests[name] = digest.hexdigest()

    try:
        with reading_output(path), h5py.File(path, "r") as f:
            f.visititems(visit)
    except DeclaredTooLarge as exc:
        raise FormatError(path, f"damaged model file: {exc}") from None
    except (OSError, KeyError, ValueError) as exc:
        raise FormatError(path, f"damaged model file ({exc})") from None
    return digests
