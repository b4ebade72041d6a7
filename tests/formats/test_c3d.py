"""C3D marker takes: read_c3d's record, units, missing samples, and every refusal in one line."""

import shutil
import struct

import numpy as np
import pytest

from c3d_writing import write_c3d
from skinsynth.formats.c3d import MARKER_UNITS, marker_key, read_c3d
from skinsynth.formats.errors import FormatError

LABELS = ["Derrick:LKNE", "Derrick:RKNE", "Derrick:C7", "Derrick:CLAV"]


def float32_points(frames=30, markers=4, seed=0):
    """(T, M, 3) millimetre-sized values a C3D holds exactly (it stores float32)."""
    return (np.random.default_rng(seed).normal(size=(frames, markers, 3)) * 500).astype(np.float32).astype(float)


def refusal(path, needle, **options):
    with pytest.raises(FormatError) as caught:
        read_c3d(path, **options)
    message = str(caught.value)
    assert message.startswith(f"{path}: ") and "\n" not in message, message
    assert needle in message, message
    return message


def patched(path, old, new, count=1):
    """Replace the bytes ``old`` (found ``count`` times) by ``new`` in the file ``path``."""
    data = path.read_bytes()
    assert data.count(old) == count, (old, data.count(old))
    path.write_bytes(data.replace(old, new))
    return path


def test_round_trip_in_millimetres_with_gaps(tmp_path):
    points = float32_points()
    points[3:7, 1] = np.nan
    points[12, 3] = np.nan
    path = write_c3d(tmp_path / "take.c3d", LABELS, points, 120.0, first_frame=10)
    take = read_c3d(path)
    assert take.path == str(path) and take.labels == tuple(LABELS)
    assert take.points.shape == (30, 4, 3) and take.points.dtype == np.float64
    assert np.array_equal(np.isnan(take.points), np.isnan(points))
    assert np.allclose(take.points, points * 0.001, rtol=1e-12, atol=0, equal_nan=True)
    assert take.rate == 120.0 and take.first_time == pytest.approx(10 / 120, rel=1e-15)
    assert (take.units, take.units_source) == ("mm", "POINT:UNITS")


@pytest.mark.parametrize("units", sorted(MARKER_UNITS))
def test_every_unit_becomes_metres(tmp_path, units):
    points = float32_points(frames=3)
    take = read_c3d(write_c3d(tmp_path / "take.c3d", LABELS, points, 50, units=units))
    assert np.allclose(take.points, points * MARKER_UNITS[units], rtol=1e-12, atol=0)
    assert take.units == units and take.first_time == 0.0


@pytest.mark.parametrize("written", [b"mm\x00\x00", b"mm  ", b" mm\x00", b"MM\x00 "])
def test_padded_units_are_cleaned(tmp_path, written):
    # Real files NUL-pad POINT:UNITS (the shared takes do: "m\0\0\0"); written "mm@@", then patched.
    path = write_c3d(tmp_path / "take.c3d", LABELS, float32_points(frames=2), 50, units="mm@@")
    take = read_c3d(patched(path, b"mm@@", written))
    assert (take.units, take.units_source) == ("mm", "POINT:UNITS")
    assert np.allclose(take.points, float32_points(frames=2) * 0.001, rtol=1e-12, atol=0)


def test_override_units(tmp_path):
    points = float32_points(frames=2)
    take = read_c3d(write_c3d(tmp_path / "take.c3d", LABELS, points, 50, units="mm"), units="cm")
    assert (take.units, take.units_source) == ("cm", "override")
    assert np.allclose(take.points, points * 0.01, rtol=1e-12, atol=0)
    unknown = write_c3d(tmp_path / "pixels.c3d", LABELS, points, 50, units="px")
    assert read_c3d(unknown, units="M").units == "m"
    refusal(unknown, "--marker-units 'furlong' is not a unit skinsynth knows: one of m, cm, mm, in, ft",
            units="furlong")


def test_unknown_or_absent_units_are_refused(tmp_path):
    points = float32_points(frames=2)
    message = refusal(write_c3d(tmp_path / "px.c3d", LABELS, points, 50, units="px"), "declares the unit 'px'")
    assert "--marker-units" in message
    blank = patched(write_c3d(tmp_path / "blank.c3d", LABELS, points, 50, units="mm@@"), b"mm@@", b"\x00\x00  ")
    assert "--marker-units" in refusal(blank, "declares no unit (POINT:UNITS)")


def test_marker_key():
    assert marker_key("Derrick:C7") == "C7"
    assert marker_key(" l ank ") == "LANK"
    assert marker_key("A:B:RSHO") == "RSHO"
    assert marker_key("Derrick: r kne\t") == "RKNE"


def test_an_empty_label_is_named_by_its_column(tmp_path):
    take = read_c3d(write_c3d(tmp_path / "take.c3d", ["A", "", "C"], float32_points(frames=2, markers=3), 50))
    assert take.labels == ("A", "MARKER_01", "C")


@pytest.mark.parametrize("labels,names", [(["S:LKNE", "T:l kne", "C7"], "'S:LKNE' and 'T:l kne'"),
                                          (["A", "A", "B"], "'A' and 'A'")])
def test_labels_that_are_one_marker_are_refused(tmp_path, labels, names):
    path = write_c3d(tmp_path / "take.c3d", labels, float32_points(frames=2, markers=3), 50)
    refusal(path, f"the labels {names} are one marker")


def test_truncated_data_is_refused_with_the_frames_expected_and_found(tmp_path):
    path = write_c3d(tmp_path / "take.c3d", LABELS, float32_points(frames=200), 100)
    data = path.read_bytes()
    frame_bytes = 4 * len(LABELS) * 4
    data_start = (struct.unpack_from("<H", data, 16)[0] - 1) * 512
    assert len(data) >= data_start + 200 * frame_bytes
    path.write_bytes(data[:data_start + 80 * frame_bytes])  # a whole number of frames: ezc3d reads 80, silently
    refusal(path, "truncated: the file declares 200 frames but holds only 80")
    path.write_bytes(data[:data_start + 80 * frame_bytes + 7])
    refusal(path, "truncated: the file declares 200 frames but holds only")


def test_every_cut_of_a_take_is_refused_in_one_line(tmp_path):
    # Cut inside the parameter section, ezc3d crashed (a segmentation fault), looped forever or
    # allocated gigabytes: every head of a take must be one FormatError line.
    whole = write_c3d(tmp_path / "whole.c3d", LABELS, float32_points(frames=20), 100).read_bytes()
    data_end = (struct.unpack_from("<H", whole, 16)[0] - 1) * 512 + 20 * 4 * len(LABELS) * 4  # then block padding
    path = tmp_path / "cut.c3d"
    for length in list(range(0, 600, 3)) + list(range(600, data_end, 11)):
        path.write_bytes(whole[:length])
        with pytest.raises(FormatError) as caught:
            read_c3d(path)
        assert "\n" not in str(caught.value)
        assert "truncated" in str(caught.value) or length < 512, (length, str(caught.value))


def test_a_corrupt_parameter_record_is_refused(tmp_path):
    path = write_c3d(tmp_path / "take.c3d", LABELS, float32_points(frames=2), 50)
    refusal(patched(path, b"\xfa\x01FRAMES", b"\xfa\x00FRAMES"), "corrupt C3D parameter section")


@pytest.mark.parametrize("content,needle", [
    (b"", "not a C3D file: 0 bytes"),
    (bytes(range(256)) * 16, "not a C3D file"),
    (b"\x02\x50" + bytes(2000), "corrupt C3D file"),
    (b"\x05\x50" + bytes(1000), "truncated: the file ends (1002 bytes) before its parameter section"),
])
def test_not_a_c3d_file(tmp_path, content, needle):
    path = tmp_path / "take.c3d"
    path.write_bytes(content)
    refusal(path, needle)


def test_missing_file_and_folder(tmp_path):
    refusal(tmp_path / "absent.c3d", "no such C3D file")
    refusal(tmp_path, "not a file")


def test_no_markers_or_no_frames(tmp_path):
    refusal(write_c3d(tmp_path / "none.c3d", [], np.zeros((5, 0, 3)), 50), "no marker samples to play: 0 markers")
    # A take of no frames, as a capture system writes it: POINT:FRAMES 0, last frame 0, no data.
    path = write_c3d(tmp_path / "empty.c3d", LABELS, float32_points(frames=1), 50)
    data = bytearray(patched(path, b"FRAMES\x07\x00\x02\x00\x01\x00", b"FRAMES\x07\x00\x02\x00\x00\x00").read_bytes())
    struct.pack_into("<H", data, 8, 0)
    path.write_bytes(data[:(struct.unpack_from("<H", data, 16)[0] - 1) * 512])
    refusal(path, "no marker samples to play: the file declares 0 frames")


@pytest.mark.parametrize("rate", [0.0, -123.25, float("nan"), float("inf")])
def test_a_rate_that_is_not_positive_is_refused(tmp_path, rate):
    path = write_c3d(tmp_path / "take.c3d", LABELS, float32_points(frames=2), 123.25)
    # the header's rate, POINT:RATE (and ANALOG:RATE, left alone)
    path.write_bytes(path.read_bytes().replace(struct.pack("<f", 123.25), struct.pack("<f", rate), 2))
    refusal(path, "samples per second: it must be a positive number")


def test_an_infinite_coordinate_is_refused(tmp_path):
    points = float32_points(frames=4)
    points[2, 3, 1] = np.inf
    refusal(write_c3d(tmp_path / "take.c3d", LABELS, points, 50), "frame 2, marker Derrick:CLAV")


@pytest.mark.slow
def test_the_real_takes(shared_data, tmp_path):
    folder = shared_data / "mocap_c3d"
    whole, gaps = folder / "kinematics_tennis_serve.c3d", folder / "kinematics_tennis_serve_nan.c3d"
    if not whole.is_file() or not gaps.is_file():
        pytest.skip(f"the real C3D takes (kinematics_tennis_serve*.c3d) are not in {folder}")
    for path in (whole, gaps):
        take = read_c3d(path)
        assert take.points.shape == (1092, 39, 3) and len(set(take.labels)) == 39
        assert take.rate == 50.0 and take.first_time == 0.0
        assert (take.units, take.units_source) == ("m", "POINT:UNITS")  # written NUL-padded
        assert all(label.startswith("Derrick:") for label in take.labels)
    assert not np.isnan(read_c3d(whole).points).any()
    take = read_c3d(gaps)
    with_gaps = np.flatnonzero(np.isnan(take.points).any(axis=(0, 2)))
    assert [marker_key(take.labels[m]) for m in with_gaps] == ["RSHO"]
    assert np.isnan(take.points[:, with_gaps[0]]).all(axis=1).sum() == 145
    head = tmp_path / "head.c3d"
    shutil.copyfile(whole, head)
    head.write_bytes(head.read_bytes()[:20000])
    refusal(head, "truncated: the file declares 1092 frames but holds only 26")
