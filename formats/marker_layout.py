"""Marker layouts: where on the mesh each motion-capture marker sits, and a take's markers matched
to them.

A layout is a JSON object ``{"LABEL": entry, …}``. An entry is a vertex index (a whole number
≥ 0), a rest position ``[x, y, z]`` (in the mesh's rest-pose units), or an object
``{"vertex": i}`` / ``{"position": [x, y, z]}`` with an optional ``"offset": d``: how far the
marker sits out from the skin along the vertex normal (≥ 0, mesh units; 0 when not given). The
whole may be wrapped as ``{"markers": {…}, "skin_offset": d}``, ``skin_offset`` then being the
offset of every entry that gives none; the two keys are reserved at the top (a layout with either
is the wrapped form). Labels are matched by :func:`~skinsynth.formats.c3d.marker_key` (subject
prefix, spaces and case dropped), so no two labels of a layout may be one marker under it.
"""

import json
import math
import os
from dataclasses import dataclass

import numpy as np

from .atomic import atomic_output
from .c3d import marker_key
from .errors import MAX_COORDINATE, FormatError

_ENTRY = 'a vertex index, [x, y, z], or {"vertex": i} or {"position": [x, y, z]} with an optional "offset"'


@dataclass
class MarkerLayout:
    """M markers, in the file's order: ``labels`` (M,) as written; ``vertices`` (M,) int64, -1
    where the entry gives a position; ``positions`` (M, 3) float64 rest positions, NaN where it
    gives a vertex; ``offsets`` (M,) float64 distances out from the skin (mesh units)."""

    path: str
    labels: tuple
    vertices: np.ndarray
    positions: np.ndarray
    offsets: np.ndarray

    @classmethod
    def on_vertices(cls, path, labels, vertices, offsets):
        """A layout whose every marker sits on a vertex, ``vertices`` (M,) (the one select-controls
        --markers stores with the controls, read from the file at ``path``)."""
        return cls(path=path, labels=tuple(labels), vertices=np.asarray(vertices, dtype=np.int64),
                   positions=np.full((len(vertices), 3), np.nan), offsets=np.asarray(offsets))


@dataclass
class MatchedMarkers:
    """A take's markers in a layout's order: ``points`` (T, M, 3) in the take's units (metres),
    NaN for the layout's markers the take lacks; ``missing``: those layout labels; ``unmatched``:
    the take's labels the layout does not name; ``take_labels`` (M,): the take's label matched to
    each layout label ("" where missing)."""

    points: np.ndarray
    missing: tuple
    unmatched: tuple
    take_labels: tuple


def read_marker_layout(path, vertex_count=None):
    """The :class:`MarkerLayout` of the JSON file ``path``; with ``vertex_count``, every vertex
    index must lie in the mesh. FormatError naming the file for a missing or unreadable file,
    invalid JSON, a layout that is not an object or is empty, an entry of the wrong kind or
    length, a bool or a fraction where a vertex index goes, a number that is not finite, a
    negative offset, a label given twice or two labels that are one marker, or a vertex outside
    the mesh."""
    path = os.fspath(path)
    document = _load(path)
    markers, default_offset = document, 0.0
    if "markers" in document or "skin_offset" in document:
        markers = document.get("markers")
        extra = sorted(set(document) - {"markers", "skin_offset"})
        if not isinstance(markers, dict) or extra:
            raise FormatError(path, 'a wrapped marker layout is {"markers": {LABEL: entry, …}, "skin_offset": d}'
                                    + (f", not the key {extra[0]!r}" if extra else ""))
        default_offset = _offset(path, "skin_offset", document.get("skin_offset", 0.0))
    if not markers:
        raise FormatError(path, "the marker layout names no markers")
    rows = [_entry(path, label, entry, default_offset) for label, entry in markers.items()]
    labels = tuple(markers)
    _require_distinct(path, labels)
    vertices = np.array([vertex for vertex, _, _ in rows], dtype=np.int64)
    if vertex_count is not None and (vertices >= vertex_count).any():
        index = int(np.argmax(vertices >= vertex_count))
        raise FormatError(path, f"marker {labels[index]}: vertex {vertices[index]} is outside the mesh's "
                                f"{vertex_count} vertices")
    positions = np.array([position for _, position, _ in rows], dtype=np.float64).reshape(-1, 3)
    offsets = np.array([offset for _, _, offset in rows], dtype=np.float64)
    return MarkerLayout(path, labels, vertices, positions, offsets)


def write_marker_layout(path, layout):
    """Write ``layout`` to ``path`` as JSON, atomically: a vertex entry as its whole number, a
    position as [x, y, z], either wrapped with its offset when that is not 0; reading it back gives
    the same arrays exactly. FormatError ("not written") for a record that is not a valid layout."""
    labels, vertices = tuple(layout.labels), np.asarray(layout.vertices)
    positions, offsets = np.asarray(layout.positions, dtype=np.float64), np.asarray(layout.offsets, np.float64)
    count = len(labels)
    if count == 0 or vertices.shape != (count,) or positions.shape != (count, 3) or offsets.shape != (count,):
        raise FormatError(path, f"not written: a marker layout of {count} labels needs vertices ({count},), positions "
                                f"({count}, 3) and offsets ({count},), not {vertices.shape}, {positions.shape}, "
                                f"{offsets.shape}")
    _require_distinct(path, labels)
    document = {}
    for label, vertex, position, offset in zip(labels, vertices.tolist(), positions.tolist(), offsets.tolist()):
        if not (math.isfinite(offset) and offset >= 0):
            raise FormatError(path, f"not written: marker {label}: offset {offset} is not a finite distance ≥ 0")
        if vertex >= 0:
            entry, kind = int(vertex), "vertex"
        elif all(math.isfinite(value) for value in position):
            entry, kind = position, "position"
        else:
            raise FormatError(path, f"not written: marker {label} has neither a vertex nor a finite position")
        document[label] = {kind: entry, "offset": offset} if offset != 0 else entry
    text = json.dumps(document, indent=2, ensure_ascii=False, allow_nan=False) + "\n"
    with atomic_output(path) as temporary:
        with open(temporary, "w", encoding="utf-8") as handle:
            handle.write(text)


def match_markers(take, layout, allow_missing=False):
    """The :class:`MatchedMarkers` of ``take`` (a :class:`~skinsynth.formats.c3d.MarkerTake`, its
    labels distinct under ``marker_key``, as ``read_c3d`` makes sure) for ``layout``, matched by
    :func:`~skinsynth.formats.c3d.marker_key`. FormatError naming the take when fewer than 3 of the
    layout's markers are in it (whatever ``allow_missing``), or when any is missing and
    ``allow_missing`` is false."""
    columns = {marker_key(label): column for column, label in enumerate(take.labels)}
    keys = [marker_key(label) for label in layout.labels]
    found = np.array([columns.get(key, -1) for key in keys], dtype=np.int64)  # (M,) take column, -1 if missing
    matched = [label for label, column in zip(layout.labels, found) if column >= 0]
    missing = tuple(label for label, column in zip(layout.labels, found) if column < 0)
    if len(matched) < 3:
        raise FormatError(take.path, f"fewer than 3 markers of {layout.path} found in the take: "
                                     f"{'only ' + ', '.join(matched) if matched else 'none'}; the take's markers are "
                                     f"{_listing(take.labels)}")
    if missing and not allow_missing:
        raise FormatError(take.path, f"lacks markers {', '.join(missing)} named by {layout.path} "
                                     "(give --allow-missing to play without them)")
    points = np.full((take.points.shape[0], len(keys), 3), np.nan)
    points[:, found >= 0] = take.points[:, found[found >= 0]]
    named = set(keys)
    unmatched = tuple(label for label in take.labels if marker_key(label) not in named)
    take_labels = tuple(take.labels[column] if column >= 0 else "" for column in found)
    return MatchedMarkers(points, missing, unmatched, take_labels)


def _listing(labels, shown=8):
    """Up to ``shown`` labels, then how many there are in all."""
    text = ", ".join(labels[:shown])
    return text + (f", … ({len(labels)} in all)" if len(labels) > shown else "")


def _load(path):
    """The JSON object of ``path``; FormatError for a missing or unreadable file, invalid JSON,
    NaN or Infinity, a key given twice, or a document that is not an object."""
    def unique_keys(pairs):
        document = {}
        for key, value in pairs:
            if key in document:
                raise FormatError(path, f"the label {key!r} is given twice")
            document[key] = value
        return document

    def no_constant(name):
        raise FormatError(path, f"the number {name} is not finite")

    try:
        with open(path, encoding="utf-8") as handle:
            document = json.load(handle, object_pairs_hook=unique_keys, parse_constant=no_constant)
    except FileNotFoundError:
        raise FormatError(path, "no such marker layout file") from None
    except OSError as error:
        raise FormatError(path, f"cannot read the marker layout: {error.strerror}") from None
    except UnicodeDecodeError:
        raise FormatError(path, "not a marker layout: the file is not UTF-8 text") from None
    except json.JSONDecodeError as error:
        raise FormatError(path, f"not valid JSON: {error}") from None
    except RecursionError:
        raise FormatError(path, "not a marker layout: JSON nested too deeply") from None
    if not isinstance(document, dict):
        raise FormatError(path, f"a marker layout is a JSON object {{LABEL: entry, …}}, not {_kind(document)}")
    return document


def _entry(path, label, entry, default_offset):
    """(vertex or -1, position or NaN (3,), offset) of one layout entry; FormatError naming the
    marker for an entry of the wrong kind."""
    offset = default_offset
    if isinstance(entry, dict):
        unknown = sorted(set(entry) - {"vertex", "position", "offset"})
        given = [key for key in ("vertex", "position") if key in entry]
        if unknown or len(given) != 1:
            problem = f"the key {unknown[0]!r}" if unknown else " and ".join(given) or "neither vertex nor position"
            raise FormatError(path, f"marker {label}: an entry is {_ENTRY}, not an object with {problem}")
        if "offset" in entry:
            offset = _offset(path, f"marker {label}: offset", entry["offset"])
        if given[0] == "position":
            return -1, _position(path, label, entry["position"]), offset
        return _vertex(path, label, entry["vertex"]), (math.nan,) * 3, offset
    if isinstance(entry, list):
        return -1, _position(path, label, entry), offset
    if isinstance(entry, (int, float)) and not isinstance(entry, bool):
        return _vertex(path, label, entry), (math.nan,) * 3, offset
    raise FormatError(path, f"marker {label}: an entry is {_ENTRY}, not {_kind(entry)}")


def _vertex(path, label, value):
    """A vertex index: a whole number ≥ 0 written without a decimal point (not a bool)."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise FormatError(path, f"marker {label}: a vertex index is a whole number ≥ 0 without a decimal point, "
                                f"not {_kind(value)}")
    if value < 0 or value > np.iinfo(np.int64).max:
        raise FormatError(path, f"marker {label}: vertex {value} is not an index of a mesh's vertices")
    return value


def _position(path, label, value):
    """A rest position: a list of 3 finite numbers (not bools), below MAX_COORDINATE."""
    if (not isinstance(value, list) or len(value) != 3
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value)):
        raise FormatError(path, f"marker {label}: a position is [x, y, z], three numbers, not {_kind(value)}")
    if not all(_finite(x) for x in value):
        raise FormatError(path, f"marker {label}: position {value} is not finite (or beyond {MAX_COORDINATE:.0e})")
    return tuple(float(x) for x in value)


def _offset(path, what, value):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise FormatError(path, f"{what} is a distance (a number ≥ 0), not {_kind(value)}")
    if not (_finite(value) and value >= 0):
        raise FormatError(path, f"{what} {value} is not a finite distance ≥ 0")
    return float(value)


def _finite(number):
    """Whether a JSON number is finite and below MAX_COORDINATE in magnitude (a whole number too
    large for a float is not)."""
    try:
        return math.isfinite(float(number)) and abs(float(number)) < MAX_COORDINATE
    except OverflowError:
        return False


def _require_distinct(path, labels):
    seen = {}
    for label in labels:
        key = marker_key(label)
        if not key:
            raise FormatError(path, f"the label {label!r} names no marker (empty once subject prefix and spaces "
                                    "are dropped)")
        if key in seen:
            other = seen[key]
            raise FormatError(path, f"the labels {other!r} and {label!r} are one marker, {key}, once subject "
                                    "prefixes, spaces and case are dropped")
        seen[key] = label


def _kind(value):
    """What a JSON value is, for a message: "a list of 2", "a string", "true"…"""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, list):
        return f"a list of {len(value)}"
    names = {dict: "an object", str: "a string", int: "a whole number", float: "a number"}
    return f"{names.get(type(value), type(value).__name__)} {json.dumps(value)[:40]}"
