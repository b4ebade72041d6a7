"""Vertex animation textures: exact round trip, row wrapping, header metadata, clean failures."""

import os

import numpy as np
import OpenEXR
import pytest

from skinsynth.formats.errors import FormatError
from skinsynth.formats.exr import read_vat, write_vat


@pytest.fixture
def animation():
    rng = np.random.default_rng(3)
    rest = rng.normal(size=(10, 3))
    vertices = rest + rng.normal(scale=0.3, size=(4, 10, 3))
    return rest, vertices


def test_float_round_trip_is_exact(tmp_path, animation):
    rest, vertices = animation
    path = tmp_path / "pos.exr"

    written = write_vat(path, rest, vertices, fps=30)
    offsets, metadata = read_vat(path)

    assert offsets.dtype == np.float32 and offsets.shape == (4, 10, 3)
    np.testing.assert_array_equal(offsets, (vertices - rest).astype(np.float32))
    assert metadata.keys() == written.keys()
    for key, value in written.items():
        np.testing.assert_array_equal(metadata[key], value)
    assert metadata["vat_width"] == 10 and metadata["vat_rows_per_frame"] == 1
    assert os.listdir(tmp_path) == ["pos.exr"]


def test_half_round_trip_within_half_precision(tmp_path, animation):
    rest, vertices = animation
    path = tmp_path / "pos.exr"
    write_vat(path, rest, vertices, fps=24, half=True)
    offsets, _ = read_vat(path)
    with OpenEXR.File(str(path)) as exr:
        assert exr.channels()["RGB"].pixels.dtype == np.float16
    np.testing.assert_allclose(offsets, vertices - rest, rtol=2 ** -10, atol=2 ** -24)


def test_rows_wrap_past_max_width(tmp_path, animation):
    rest, vertices = animation  # 10 vertices in rows of 4: 3 rows per frame, 2 padding texels
    path = tmp_path / "wrap.exr"

    written = write_vat(path, rest, vertices, fps=24, max_width=4)

    assert (written["vat_width"], written["vat_rows_per_frame"]) == (4, 3)
    with OpenEXR.File(str(path)) as exr:
        image = exr.channels()["RGB"].pixels
    assert image.shape == (4 * 3, 4, 3)
    expected = (vertices - rest).astype(np.float32)
    # vertex 9 of frame 2 sits at row 2 * 3 + 9 // 4, column 9 % 4
    np.testing.assert_array_equal(image[2 * 3 + 2, 1], expected[2, 9])
    np.testing.assert_array_equal(image[2 * 3 + 2, 2:], 0)  # padding
    np.testing.assert_array_equal(read_vat(path)[0], expected)


def test_header_carries_layout_and_bounds(tmp_path, animation):
    rest, vertices = animation
    path = tmp_path / "pos.exr"
    write_vat(path, rest, vertices, fps=29.97, max_width=8)
    with OpenEXR.File(str(path)) as exr:
        header = dict(exr.header())  # the File empties its dict on exit
    assert header["vat_vertex_count"] == 10 and header["vat_frame_count"] == 4
    assert header["vat_rows_per_frame"] == 2 and header["vat_fps"] == pytest.approx(29.97)
    offsets = vertices - rest
    np.testing.assert_allclose(header["vat_bounds_min"], offsets.min(axis=(0, 1)), rtol=1e-6)
    np.testing.assert_allclose(header["vat_bounds_max"], offsets.max(axis=(0, 1)), rtol=1e-6)
    assert header["compression"] == OpenEXR.ZIP_COMPRESSION


@pytest.mark.parametrize("change", ["rest shape", "vertex count", "nan", "fps", "max width", "half range"])
def test_writer_failure_leaves_no_file(tmp_path, animation, change):
    rest, vertices = animation
    kwargs = dict(fps=24.0)
    if change == "rest shape":
        rest = rest[:, :2]
    elif change == "vertex count":
        vertices = vertices[:, :9]
    elif change == "nan":
        vertices = vertices.copy()
        vertices[1, 1, 1] = np.nan
    elif change == "fps":
        kwargs["fps"] = 0
    elif change == "max width":
        kwargs["max_width"] = 0
    elif change == "half range":
        vertices, kwargs["half"] = vertices + 1e5, True
    # A NaN or offsets too large for --half: a user error naming the file; the rest are programming errors.
    user = {"nan": "x.exr: not written", "half range": "x.exr: offsets from the rest pose exceed the half-float range"}
    with pytest.raises(FormatError if change in user else ValueError, match=user.get(change)):
        write_vat(tmp_path / "x.exr", rest, vertices, **kwargs)
    assert os.listdir(tmp_path) == []


def test_writer_rejects_other_extensions(tmp_path, animation):
    with pytest.raises(FormatError, match=".exr"):
        write_vat(tmp_path / "x.png", *animation, fps=24)
    assert os.listdir(tmp_path) == []


def test_read_errors(tmp_path):
    with pytest.raises(FormatError, match="no such file"):
        read_vat(tmp_path / "missing.exr")
    (tmp_path / "junk.exr").write_bytes(b"not an exr")
    with pytest.raises(FormatError, match="junk.exr: cannot read as OpenEXR"):
        read_vat(tmp_path / "junk.exr")
    plain = tmp_path / "plain.exr"
    with OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": np.zeros((2, 2, 3), np.float32)}) as exr:
        exr.write(str(plain))
    with pytest.raises(FormatError, match="plain.exr: not a vertex animation texture"):
        read_vat(plain)
