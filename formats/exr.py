"""Vertex animation textures (VAT) in OpenEXR, for game engines.

Layout: one RGB texel per vertex holding its offset from the rest position (engine adds it in
the vertex shader). The image is ``width = min(V, max_width)`` texels wide; a frame takes
``rows_per_frame = ceil(V / width)`` rows, vertex i of frame f at row
``f * rows_per_frame + i // width``, column ``i % width``; frames run top to bottom; texels past
the last vertex are zero. Header attributes ``vat_*`` carry the layout, the frame rate and the
offset bounds (for engines that normalise to them).

Files are ZIP-compressed: lossless, so offsets read back bit-exact, and decoded once on import by
every EXR reader that engines use (OpenEXR, tinyexr). What engines need is set on their side:
import as linear data, no mips, no texture compression, point filtering.
"""

from __future__ import annotations

import os

import numpy as np

from .errors import require_finite
import OpenEXR

from skinsynth.formats.atomic import atomic_output
from skinsynth.formats.errors import FormatError

HALF_MAX = float(np.finfo(np.float16).max)
_INT_KEYS = ("vat_vertex_count", "vat_frame_count", "vat_rows_per_frame", "vat_width")


def check_half_range(path, offsets, what="offsets from the rest pose"):
    """FormatError naming ``path`` when ``offsets`` (any shape) do not fit in half floats (--half)."""
    if np.abs(offsets).max() > HALF_MAX:
        raise FormatError(path, f"{what} exceed the half-float range ({HALF_MAX:g}); drop --half")


def write_vat(path, rest_vertices, vertices, fps, max_width=8192, half=False) -> dict:
    """Write offsets ``vertices - rest_vertices`` as a VAT; return the ``vat_*`` metadata written.

    rest_vertices (V, 3); vertices (F, V, 3); ``half`` stores 16-bit floats (half the size,
    about 3 significant digits). Raises ValueError for malformed arguments; nothing is left on
    disk when writing fails.
    """
    rest = np.asarray(rest_vertices, dtype=np.float64)
    vertices = np.asarray(vertices, dtype=np.float64)
    if rest.ndim != 2 or rest.shape[1] != 3 or len(rest) == 0:
        raise ValueError(f"rest_vertices must have shape (V, 3) with V > 0, got {rest.shape}")
    if vertices.ndim != 3 or vertices.shape[1:] != rest.shape or len(vertices) == 0:
        raise ValueError(f"vertices must have shape (F, {len(rest)}, 3) with F > 0, got {vertices.shape}")
    require_finite(path, "the rest pose", rest)
    require_finite(path, "the vertices", vertices)
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be positive, got {fps}")
    if int(max_width) != max_width or max_width < 1:
        raise ValueError(f"max_width must be a positive integer, got {max_width}")
    if os.path.splitext(os.fspath(path))[1].lower() != ".exr":
        raise FormatError(path, "a vertex animation texture must end in .exr")

    offsets = vertices - rest
    if half:
        check_half_range(path, offsets)
    offsets = offsets.astype(np.float16 if half else np.float32)
    frames, count = offsets.shape[:2]
    width = int(min(count, max_width))
    rows = -(-count // width)
    image = np.zeros((frames, rows * width, 3), dtype=offsets.dtype)
    image[:, :count] = offsets
    image = image.reshape(frames * rows, width, 3)

    metadata = {
        "vat_vertex_count": count,
        "vat_frame_count": frames,
        "vat_rows_per_frame": rows,
        "vat_width": width,
        # EXR float attributes are 32-bit: report the value a reader will get back.
        "vat_fps": float(np.float32(fps)),
        "vat_bounds_min": offsets.min(axis=(0, 1)).astype(np.float32),
        "vat_bounds_max": offsets.max(axis=(0, 1)).astype(np.float32),
    }
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, **metadata}
    with atomic_output(path, expected_bytes=image.nbytes + (1 << 16)) as tmp:
        with OpenEXR.File(header, {"RGB": image}) as exr:
            exr.write(tmp)
    return metadata


def read_vat(path) -> tuple[np.ndarray, dict]:
    """Read a VAT written by write_vat: (offsets (F, V, 3) float32, metadata dict as write_vat returned).

    Raises FormatError for a missing file, a non-EXR file or an EXR that is not a VAT.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FormatError(path, "no such file")
    try:
        with OpenEXR.File(path) as exr:
            # File empties its header and channel dicts on exit: take copies while it is open.
            header = dict(exr.header())
            channels = {name: channel.pixels for name, channel in exr.channels().items()}
    except Exception as error:  # OpenEXR raises RuntimeError/IOError with library messages
        raise FormatError(path, f"cannot read as OpenEXR: {error}") from None

    metadata = {}
    for key in _INT_KEYS + ("vat_fps", "vat_bounds_min", "vat_bounds_max"):
        if key not in header:
            raise FormatError(path, f"not a vertex animation texture: no {key} attribute")
        metadata[key] = header[key]
    try:
        for key in _INT_KEYS:
            metadata[key] = int(metadata[key])
        metadata["vat_fps"] = float(metadata["vat_fps"])
        for key in ("vat_bounds_min", "vat_bounds_max"):
            metadata[key] = np.asarray(metadata[key], dtype=np.float32).reshape(3)
    except (TypeError, ValueError) as error:
        raise FormatError(path, f"malformed vat_* attribute: {error}") from None

    if "RGB" not in channels:
        raise FormatError(path, f"no RGB channels (found {', '.join(sorted(channels)) or 'none'})")
    image = channels["RGB"]
    count, frames = metadata["vat_vertex_count"], metadata["vat_frame_count"]
    rows, width = metadata["vat_rows_per_frame"], metadata["vat_width"]
    if min(count, frames, rows, width) < 1 or rows * width < count or image.shape != (frames * rows, width, 3):
        raise FormatError(path, f"image of shape {image.shape[:2]} does not fit {frames} frames of "
                                f"{count} vertices in {rows} rows of {width}")
    offsets = image.reshape(frames, rows * width, 3)[:, :count].astype(np.float32)
    return offsets, metadata
