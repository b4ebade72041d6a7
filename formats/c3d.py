"""Optical motion capture: marker takes in C3D files (c3d.org), read with ezc3d.

Why ezc3d: its C++ core is maintained by the biomechanics community (pyomeca), it reads the
Intel and DEC processor types (integer and float samples; the MIPS type of old SGI systems it
refuses in one line, "MIPS processor type not supported yet", as of 1.7.2), turns missing samples
into NaN, also writes C3D (the tests write their takes with it) and is fast: 25 ms for a
1,092-frame take of 39 markers. The alternative was the pure-Python ``c3d`` package.

What ezc3d does not do, this module does: it refuses files ezc3d would read silently wrong or not
survive. A truncated data section gives fewer frames without a word (ezc3d even rewrites the
header and ``POINT:FRAMES`` to match), so the frames the file declares are read from its own bytes
and compared. A file cut inside its parameter section crashed ezc3d outright (a segmentation fault,
an endless loop, gigabytes allocated: measured on heads of a real take), so the parameter records
are walked first, and ezc3d only ever sees a file whose parameter section it can read to the end.
"""

import math
import mmap
import os
import struct
from dataclasses import dataclass

import numpy as np

from .errors import MAX_COORDINATE, FormatError

#: Metres per unit of each unit a take may declare (``POINT:UNITS``) or the user may give
#: (``--marker-units``); matched without case after the padding is stripped.
MARKER_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048}

_PROCESSORS = {84: "<", 85: "<", 86: ">"}  # Intel, DEC: little-endian integers; MIPS: big-endian


@dataclass
class MarkerTake:
    """One take of M markers over T samples.

    ``labels`` (M,): the file's ``POINT:LABELS`` as written ("Derrick:C7"); a marker with an empty
    label is named ``MARKER_<column>`` (``MARKER_07``). ``points`` (T, M, 3) float64 in metres, NaN
    where a sample is missing (all three coordinates). ``rate``: samples per second. ``first_time``:
    seconds of the first sample (its frame number, counted from 0, over the rate). ``units``: the
    unit the file's coordinates were in (a key of :data:`MARKER_UNITS`); ``units_source``:
    "POINT:UNITS" or "override"."""

    path: str
    labels: tuple
    points: np.ndarray
    rate: float
    first_time: float
    units: str
    units_source: str


def marker_key(label):
    """The name two marker labels are matched by: everything up to the last ':' dropped (the
    subject prefix: "Derrick:C7" -> "C7"), all whitespace removed, upper case (" l ank " -> "LANK")."""
    return "".join(str(label).rpartition(":")[2].split()).upper()


def read_c3d(path, units=None):
    """The :class:`MarkerTake` of the C3D file ``path``; ``units`` (a key of :data:`MARKER_UNITS`,
    the user's ``--marker-units``) overrides the file's ``POINT:UNITS``. FormatError naming the
    file for a file that is missing, not a C3D, corrupt or truncated, holds no markers or no
    frames or no sample (every marker missing in every frame), declares no known unit (and none is
    given), has a rate that is not a positive number,
    a coordinate that is infinite or too large, or two labels that are one marker under
    :func:`marker_key`, and for a ``units`` not in :data:`MARKER_UNITS` (the user's option, named
    with the take it was given for)."""
    path = os.fspath(path)
    if units is not None and units.lower() not in MARKER_UNITS:
        raise FormatError(path, f"--marker-units {units!r} is not a unit skinsynth knows: one of "
                                f"{', '.join(MARKER_UNITS)}")
    if not os.path.exists(path):
        raise FormatError(path, "no such C3D file")
    if not os.path.isfile(path):
        raise FormatError(path, "not a file (a C3D take is one file)")
    declared_frames = _check_structure(path)
    if declared_frames == 0:  # ezc3d fails on such a file with a message about its own internals
        raise FormatError(path, "no marker samples to play: the file declares 0 frames")
    import ezc3d

    try:
        c3d = ezc3d.c3d(path)
    except MemoryError:
        raise
    except Exception as error:  # ezc3d raises OSError, RuntimeError, ValueError, IndexError
        problem = (str(error) or type(error).__name__).splitlines()[0]
        if declared_frames and "maximum number of frames is 0" in problem:  # cut before its first frame ended
            raise FormatError(path, f"truncated: the file declares {declared_frames} frames but holds only 0") from None
        raise FormatError(path, f"not a readable C3D file: {problem}") from None
    data = c3d["data"]
    coordinates = np.asarray(data["points"], dtype=np.float64)  # (4, M, T)
    found = coordinates.shape[2] if coordinates.ndim == 3 else 0
    if declared_frames is not None and found < declared_frames:
        raise FormatError(path, f"truncated: the file declares {declared_frames} frames but holds only {found}")
    if coordinates.ndim != 3 or 0 in coordinates.shape[1:]:
        markers = coordinates.shape[1] if coordinates.ndim == 3 else 0
        raise FormatError(path, f"no marker samples to play: {markers} markers over {found} frames")
    parameters = c3d["parameters"]["POINT"]
    labels = _labels(parameters, coordinates.shape[1])
    _require_distinct(path, labels)
    rate = _rate(path, parameters, c3d["header"]["points"]["frame_rate"])
    units, units_source = _units(path, parameters, units)

    points = np.ascontiguousarray(coordinates[:3].transpose(2, 1, 0)) * MARKER_UNITS[units]  # (T, M, 3), metres
    residuals = np.asarray(data["meta_points"]["residuals"], dtype=np.float64)  # (1, M, T)
    missing = np.isnan(points).any(axis=2)  # (T, M)
    if residuals.shape == (1,) + coordinates.shape[1:]:
        # A negative residual marks a missing sample, whatever its coordinates (old writers leave
        # them (0, 0, 0)); ezc3d already gives NaN there, this keeps the rule whatever it does.
        missing |= residuals[0].T < 0
    points[missing] = np.nan
    if missing.all():
        raise FormatError(path, "holds no marker sample: every marker is missing in every frame")
    _require_coordinates(path, points, labels)
    first_time = c3d["header"]["points"]["first_frame"] / rate
    return MarkerTake(path, labels, points, rate, float(first_time), units, units_source)


def _labels(parameters, count):
    """The first ``count`` labels of ``POINT:LABELS``, ``LABELS2``, … (files of more than 255
    markers continue the list); an empty or absent one is named after its column."""
    written = []
    for name in ["LABELS"] + [f"LABELS{i}" for i in range(2, 100)]:
        if name not in parameters:
            break
        value = parameters[name]["value"]
        written += [value] if isinstance(value, str) else list(value)
    written = [str(label) for label in written[:count]]
    written += [""] * (count - len(written))
    return tuple(label if label.strip(" \x00") else f"MARKER_{column:02d}" for column, label in enumerate(written))


def _require_distinct(path, labels):
    seen = {}
    for label in labels:
        key = marker_key(label)
        if key in seen:
            raise FormatError(path, f"the labels {seen[key]!r} and {label!r} are one marker, {key}, once subject "
                                    "prefixes, spaces and case are dropped (two subjects in one take?)")
        seen[key] = label


def _rate(path, parameters, header_rate):
    """``POINT:RATE``, else the header's frame rate; FormatError unless positive and finite."""
    value = np.ravel(parameters["RATE"]["value"]) if "RATE" in parameters else []
    rate = float(value[0]) if len(value) and value[0] != 0 else float(header_rate)
    if not (math.isfinite(rate) and rate > 0):
        raise FormatError(path, f"the point rate is {rate:g} samples per second: it must be a positive number")
    return rate


def _units(path, parameters, override):
    """(unit key, where it came from): the override, else ``POINT:UNITS`` without its NUL or space
    padding; FormatError when the file declares none or one not in :data:`MARKER_UNITS`."""
    if override is not None:
        return override.lower(), "override"
    value = parameters["UNITS"]["value"] if "UNITS" in parameters else []
    value = [value] if isinstance(value, str) else list(value)
    declared = str(value[0]).strip(" \x00") if value else ""
    known = ", ".join(MARKER_UNITS)
    if not declared:
        raise FormatError(path, f"declares no unit (POINT:UNITS): give --marker-units (one of {known})")
    if declared.lower() not in MARKER_UNITS:
        raise FormatError(path, f"declares the unit {declared!r} (POINT:UNITS), not one of {known}: "
                                "give --marker-units")
    return declared.lower(), "POINT:UNITS"


def _require_coordinates(path, points, labels):
    """FormatError naming the frame and the marker of the first sample that is infinite or beyond
    MAX_COORDINATE (NaN is a missing sample, allowed)."""
    with np.errstate(invalid="ignore"):
        bad = (np.abs(points) >= MAX_COORDINATE).any(axis=2)
    if bad.any():
        frame, marker = np.argwhere(bad)[0]
        raise FormatError(path, f"frame {frame}, marker {labels[marker]}: coordinate {points[frame, marker]} is "
                                f"infinite or beyond {MAX_COORDINATE:.0e} m")


def _check_structure(path):
    """The frames the file declares, as ezc3d counts them (``POINT:FRAMES``, else the header's);
    None when it declares no points, or when only the header counts and says 65,535 or more (its
    16-bit count cannot say how many). FormatError for a file ezc3d must not be given: no C3D
    header, a parameter section cut short or whose records run off the file."""
    size = os.path.getsize(path)
    if size < 512:
        raise FormatError(path, f"not a C3D file: {size} bytes, shorter than a C3D header (512 bytes)")
    with open(path, "rb") as handle, mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ) as data:
        if data[1] != 0x50 or data[0] == 0:
            raise FormatError(path, "not a C3D file: it does not begin with a C3D header (second byte 0x50)")
        start = (data[0] - 1) * 512
        if start + 4 > size:
            raise FormatError(path, f"truncated: the file ends ({size} bytes) before its parameter section "
                                    f"(byte {start})")
        first, check, blocks, processor = data[start:start + 4]
        if (first, check) == (0, 0):  # Qualisys leaves these two bytes zero
            first, check = 1, 0x50
        if check != 0x50 or processor not in _PROCESSORS:
            raise FormatError(path, "corrupt C3D file: its parameter section does not begin with a C3D signature")
        end = start + blocks * 512
        if end > size:
            raise FormatError(path, f"truncated: the file ends ({size} bytes) inside its parameter section "
                                    f"(bytes {start} to {end})")
        point = _walk_parameters(path, data, start + 3 + first, processor)
        points, _, first_frame, last_frame = struct.unpack_from(_PROCESSORS[processor] + "4H", data, 2)
    if math.isnan(point.get("RATE", 0.0)):  # ezc3d would fail on it, saying only "vector::_M_default_append"
        raise FormatError(path, "the point rate is nan samples per second: it must be a positive number")
    if points == 0:
        return None
    if "FRAMES" in point:  # ezc3d reads as many frames as POINT:FRAMES says, else as the header says
        return point["FRAMES"]
    first_frame, last_frame = max(first_frame - 1, 0), max(last_frame - 1, 0)  # 1-based, or 0 by some writers
    return last_frame - first_frame + 1 if -1 <= last_frame - first_frame < 0xFFFE else None


def _walk_parameters(path, data, position, processor):
    """Walk the parameter records from ``position`` the way ezc3d reads them, checking each lies
    inside the file; returns the scalars ``POINT:FRAMES`` (an unsigned whole number) and
    ``POINT:RATE`` (a float) the file holds, by name."""
    size, groups, point, order = len(data), {}, {}, _PROCESSORS[processor]

    def corrupt(problem):
        return FormatError(path, f"corrupt C3D parameter section: {problem}")

    def need(at, count):
        if at + count > size:
            raise corrupt(f"a record at byte {position} runs past the end of the file (truncated?)")

    while True:
        need(position, 1)
        name_length = abs(_signed(data[position]))
        if name_length == 0:
            return point
        need(position, 2 + name_length + 2)
        group = _signed(data[position + 1])
        name = bytes(data[position + 2:position + 2 + name_length]).decode("latin-1").upper()
        offset_at = position + 2 + name_length
        (offset,) = struct.unpack_from(order + "H", data, offset_at)
        cursor = offset_at + 2
        if group < 0:
            groups[-group] = name
        elif group == 0:
            raise corrupt(f"the record {name!r} belongs to no group")
        else:
            need(cursor, 2)
            kind, dimensions = _signed(data[cursor]), _signed(data[cursor + 1])
            if kind not in (-1, 1, 2, 4) or dimensions < 0 or (kind == -1 and dimensions == 0):
                raise corrupt(f"the parameter {name!r} has an unknown type or shape")
            need(cursor + 2, dimensions)
            shape = list(data[cursor + 2:cursor + 2 + dimensions])
            cursor += 2 + dimensions
            nonzero = shape[:shape.index(0)] if 0 in shape else shape
            if math.prod(nonzero) > size:  # ezc3d loops over every leading dimension, even before a zero
                raise corrupt(f"the parameter {name!r} declares dimensions {shape}")
            need(cursor, abs(kind) * math.prod(shape))
            if (groups.get(group), name, kind, math.prod(shape)) == ("POINT", "FRAMES", 2, 1):
                (point["FRAMES"],) = struct.unpack_from(order + "H", data, cursor)
            if (groups.get(group), name, kind, math.prod(shape)) == ("POINT", "RATE", 4, 1):
                point["RATE"] = _float(data[cursor:cursor + 4], processor)
            cursor += abs(kind) * math.prod(shape)
        need(cursor, 1)
        description = _signed(data[cursor])
        if description < 0:
            raise corrupt(f"the record {name!r} has a negative description length")
        need(cursor + 1, description)
        if offset == 0:
            return point
        if offset_at + offset != cursor + 1 + description:  # ezc3d refuses this too, but only after reading on
            raise corrupt(f"the record {name!r} does not end where its offset says")
        position = offset_at + offset


def _float(four, processor):
    """A 4-byte float of the processor type, converted as ezc3d converts it (DEC: words swapped,
    exponent byte less one)."""
    if processor == 85:
        four = bytes([four[2], four[3], four[0], four[1] - 1 if four[1] else 0])
    return struct.unpack(_PROCESSORS[processor] + "f", four)[0]


def _signed(byte):
    """A byte read as a signed 8-bit number."""
    return byte - 256 if byte > 127 else byte
