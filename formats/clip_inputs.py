"""Several input clips of one mesh, read as one sequence with named clips (``fit-skin A B …``).

Each INPUT is one clip, in any form :func:`~.meshseq.read_mesh_sequence` reads. ``NAME=INPUT``
names it; otherwise its name is the input's file or folder name without extension (glob
characters and trailing ``-``/``_``/``.`` dropped), and with several clips the prefix every name
shares up to a ``_``, ``-`` or ``.`` is dropped too: ``horse_gallop.npz horse_collapse.npz`` are
the clips ``gallop`` and ``collapse``. Characters other than letters, digits, ``_``, ``.``, ``-``
become ``_``.

The clips must be one mesh: the same vertex count and the same faces (vertex i the same point
in every clip), the same frame rate and the same scene (units, up axis). The first difference
is refused in one line naming both files. The sequence is the clips' frames in the order given;
the scene, prim path and material UVs are the first clip's.
"""

import functools
import glob
import os
import re
from dataclasses import replace

import numpy as np

from .errors import FormatError
from .meshseq import read_mesh_sequence

_NAME = re.compile(r"^[A-Za-z0-9_.\-]+$")
_SEPARATORS = "_-."


def split_named(spec):
    """``NAME=INPUT`` -> (NAME, INPUT); a spec without a usable name (or an existing path with
    '=' in it) -> (None, spec)."""
    spec = os.fspath(spec)
    name, sep, rest = spec.partition("=")
    if sep and rest and _NAME.match(name) and not os.path.exists(spec):
        return name, rest
    return None, spec


def default_name(spec):
    """A clip's name from its input path (module notes)."""
    path = os.path.normpath(os.fspath(spec))
    base = os.path.basename(path)
    if not os.path.isdir(path):
        base = os.path.splitext(base)[0] if not glob.has_magic(base) else re.sub(r"\.[A-Za-z0-9]+$", "", base)
    base = re.sub(r"[*?\[\]]", "", base).strip(_SEPARATORS + " ")
    if not base:
        base = os.path.basename(os.path.dirname(path)) or "clip"
    return re.sub(r"[^A-Za-z0-9_.\-]", "_", base) or "clip"


def clip_names(specs):
    """Names of the clips ``specs`` (``NAME=INPUT`` or INPUT) -> (names, inputs): each unnamed
    clip's :func:`default_name`, without the prefix every default name shares (module notes)."""
    pairs = [split_named(spec) for spec in specs]
    names = [name or default_name(spec) for name, spec in pairs]
    unnamed = [k for k, (name, _) in enumerate(pairs) if name is None]
    if len(unnamed) > 1:
        common = os.path.commonprefix([names[k] for k in unnamed])
        cut = max((common.rfind(s) for s in _SEPARATORS), default=-1) + 1
        shortened = [names[k][cut:] for k in unnamed]
        if cut and all(shortened) and len(set(shortened)) == len(shortened):
            for k, short in zip(unnamed, shortened):
                names[k] = short
    return names, [spec for _, spec in pairs]


def read_clips(specs, prim=None, fps=None, progress=None):
    """Read ``specs`` (one or more clip inputs) -> a MeshSequence of every frame, with
    ``clip_names`` and ``clip_frames`` set. Clips of different meshes, rates or scenes raise
    FormatError naming the file and the first difference (module notes). progress(name, done,
    total): called as Blender reads an ``.abc``/``.fbx`` clip's frames."""
    names, inputs = clip_names(specs)
    if len(set(names)) != len(names):
        twice = next(n for n in names if names.count(n) > 1)
        raise FormatError(inputs[names.index(twice)], f"two clips are named {twice!r}; name them as NAME=INPUT")
    sequences = [read_mesh_sequence(spec, prim=prim, fps=fps, progress=None if progress is None else
                                    functools.partial(progress, name)) for name, spec in zip(names, inputs)]
    first = sequences[0]
    for other in sequences[1:]:
        _require_same_mesh(first, other)
    if len(sequences) == 1:
        return replace(first, clip_names=(names[0],), clip_frames=(len(first.vertices),))
    return replace(first, vertices=np.concatenate([s.vertices for s in sequences]),
                   source=" ".join(os.fspath(s) for s in specs),
                   clip_names=tuple(names), clip_frames=tuple(len(s.vertices) for s in sequences))


def mesh_difference(count, faces, reference_count, reference_faces, reference):
    """The first way a mesh of ``count`` vertices and ``faces (T, 3)`` differs from the one named
    ``reference`` (its vertex count, then its triangle count, then the first face that differs),
    as a phrase ("has 8430 vertices where clip a.npz has 8431"), or None for the same mesh."""
    if count != reference_count:
        return f"has {count} vertices where {reference} has {reference_count}"
    if faces.shape != reference_faces.shape:
        return f"has {len(faces)} triangles where {reference} has {len(reference_faces)}"
    differ = np.flatnonzero(np.any(faces != reference_faces, axis=1))
    if differ.size:
        k = int(differ[0])
        return (f"has face {k} = {tuple(int(v) for v in faces[k])} where {reference} has "
                f"{tuple(int(v) for v in reference_faces[k])}")
    return None


def read_rig(path, sequence):
    """The skin file ``path`` whose rig new clips are fitted on (``fit-skin --rig``), read as a
    SkinModel; FormatError unless its mesh is the clips' (``sequence``), vertices in the same order."""
    from .skin_file import read_skin

    rig = read_skin(path)
    difference = mesh_difference(len(rig.rest_vertices), rig.faces, sequence.vertices.shape[1], sequence.faces,
                                 sequence.source)
    if difference:
        raise FormatError(path, f"the rig {difference}: --rig needs the clips' own mesh, its vertices in the same "
                                "order")
    return rig


def _require_same_mesh(first, other):
    """FormatError naming ``other``'s first difference from ``first``: vertices, faces, fps, scene."""
    where = f"(clip {first.source} has"
    difference = mesh_difference(other.vertices.shape[1], other.faces, first.vertices.shape[1], first.faces,
                                 f"clip {first.source}")
    if difference:
        raise FormatError(other.source, f"{difference}: the clips must be one mesh, its vertices in the same order")
    if other.fps != first.fps:
        raise FormatError(other.source, f"plays at {other.fps:g} fps {where} {first.fps:g}); give --fps to "
                                        "read every clip at one rate")
    for name in ("meters_per_unit", "up_axis"):
        mine, theirs = getattr(other.scene, name), getattr(first.scene, name)
        if mine != theirs:
            raise FormatError(other.source, f"states {name} {mine} {where} {theirs}); the clips must share "
                                            "their units and up axis")
