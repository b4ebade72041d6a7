"""Marker layouts: every entry kind, the wrapped form, every refusal, the writer's round trip, and
a take's markers matched to a layout."""

import json

import numpy as np
import pytest

from skinsynth.formats.c3d import MarkerTake
from skinsynth.formats.errors import FormatError
from skinsynth.formats.marker_layout import MarkerLayout, match_markers, read_marker_layout, write_marker_layout


def layout_file(tmp_path, document, name="layout.json"):
    path = tmp_path / name
    path.write_text(document if isinstance(document, str) else json.dumps(document), encoding="utf-8")
    return path


def refusal(path, needle, **options):
    with pytest.raises(FormatError) as caught:
        read_marker_layout(path, **options)
    message = str(caught.value)
    assert message.startswith(f"{path}: ") and "\n" not in message and needle in message, message
    return message


def test_every_entry_kind(tmp_path):
    layout = read_marker_layout(layout_file(tmp_path, {
        "LKNE": 3, "Derrick:RKNE": [0.1, -2, 3e-5], "C7": {"vertex": 5, "offset": 0.01},
        "CLAV": {"position": [1, 2, 3]}, "T10": {"vertex": 0}}))
    assert layout.labels == ("LKNE", "Derrick:RKNE", "C7", "CLAV", "T10")
    assert layout.vertices.dtype == np.int64 and layout.vertices.tolist() == [3, -1, 5, -1, 0]
    assert layout.positions.shape == (5, 3) and layout.positions.dtype == np.float64
    assert np.isnan(layout.positions[[0, 2, 4]]).all()
    assert layout.positions[[1, 3]].tolist() == [[0.1, -2.0, 3e-5], [1.0, 2.0, 3.0]]
    assert layout.offsets.tolist() == [0, 0, 0.01, 0, 0]


def test_the_wrapped_form_gives_every_entry_its_skin_offset(tmp_path):
    layout = read_marker_layout(layout_file(tmp_path, {
        "skin_offset": 0.014, "markers": {"LKNE": 3, "RKNE": {"vertex": 4, "offset": 0}, "C7": [0, 0, 1]}}))
    assert layout.labels == ("LKNE", "RKNE", "C7") and layout.offsets.tolist() == [0.014, 0.0, 0.014]
    assert read_marker_layout(layout_file(tmp_path, {"markers": {"A": 1}}, "b.json")).offsets.tolist() == [0.0]


def test_vertices_must_lie_in_the_mesh(tmp_path):
    path = layout_file(tmp_path, {"C7": 12344, "LKNE": 99999})
    assert read_marker_layout(path).vertices.tolist() == [12344, 99999]
    assert read_marker_layout(path, vertex_count=100000).vertices.tolist() == [12344, 99999]
    refusal(path, "marker LKNE: vertex 99999 is outside the mesh's 12345 vertices", vertex_count=12345)


@pytest.mark.parametrize("document,needle", [
    ("{", "not valid JSON"),
    ("", "not valid JSON"),
    ("[1, 2]", "a marker layout is a JSON object {LABEL: entry, …}, not a list of 2"),
    ('"LKNE"', "not a string"),
    ({}, "names no markers"),
    ({"markers": {}}, "names no markers"),
    ({"markers": [1, 2]}, 'a wrapped marker layout is {"markers"'),
    ({"markers": {"A": 1}, "scale": 2}, "not the key 'scale'"),
    ({"skin_offset": 0.1, "A": 1}, 'a wrapped marker layout is {"markers"'),
    ({"markers": {"A": 1}, "skin_offset": -0.1}, "skin_offset -0.1 is not a finite distance ≥ 0"),
    ({"markers": {"A": 1}, "skin_offset": "1cm"}, "skin_offset is a distance (a number ≥ 0), not a string"),
    ({"A": "vertex 3"}, "marker A: an entry is a vertex index, [x, y, z]"),
    ({"A": None}, "marker A: an entry is a vertex index, [x, y, z], or {\"vertex\": i}"),
    ({"A": True}, "marker A: an entry is a vertex index"),
    ({"A": 3.0}, "marker A: a vertex index is a whole number ≥ 0 without a decimal point, not a number 3.0"),
    ({"A": 2.5}, "marker A: a vertex index is a whole number"),
    ({"A": -1}, "marker A: vertex -1 is not an index"),
    ({"A": 10 ** 30}, "is not an index of a mesh's vertices"),
    ({"A": [1, 2]}, "marker A: a position is [x, y, z], three numbers, not a list of 2"),
    ({"A": [1, 2, 3, 4]}, "not a list of 4"),
    ({"A": [1, True, 3]}, "a position is [x, y, z], three numbers"),
    ({"A": [1, "2", 3]}, "a position is [x, y, z], three numbers"),
    ({"A": [1, 2, 10 ** 400]}, "marker A: position"),
    ('{"A": [1, NaN, 3]}', "the number NaN is not finite"),
    ('{"A": [1, 1e999, 3]}', "marker A: position [1, inf, 3] is not finite"),
    ('{"A": {"vertex": 1, "offset": Infinity}}', "the number Infinity is not finite"),
    ({"A": {"vertex": 1, "offset": -0.5}}, "marker A: offset -0.5 is not a finite distance ≥ 0"),
    ({"A": {"vertex": 1, "offset": True}}, "marker A: offset is a distance (a number ≥ 0), not true"),
    ({"A": {"vertex": True}}, "marker A: a vertex index is a whole number ≥ 0 without a decimal point, not true"),
    ({"A": {"vertex": [1, 2, 3]}}, "marker A: a vertex index is a whole number"),
    ({"A": {"position": 3}}, "marker A: a position is [x, y, z], three numbers, not a whole number 3"),
    ({"A": {"vertex": 1, "position": [1, 2, 3]}}, "not an object with vertex and position"),
    ({"A": {"offset": 0.1}}, "not an object with neither vertex nor position"),
    ({"A": {"vertex": 1, "normal": [0, 0, 1]}}, "not an object with the key 'normal'"),
    ('{"LKNE": 1, "LKNE": 2}', "the label 'LKNE' is given twice"),
    ({"LKNE": 1, "Derrick: l kne": 2}, "the labels 'LKNE' and 'Derrick: l kne' are one marker, LKNE"),
    ({"A": 1, "Derrick: ": 2}, "the label 'Derrick: ' names no marker"),
])
def test_refusals(tmp_path, document, needle):
    refusal(layout_file(tmp_path, document), needle)


def test_unreadable_files(tmp_path):
    refusal(tmp_path / "absent.json", "no such marker layout file")
    refusal(tmp_path, "cannot read the marker layout")
    path = tmp_path / "latin.json"
    path.write_bytes(b'{"caf\xe9": 1}')
    refusal(path, "not UTF-8 text")
    refusal(layout_file(tmp_path, "[" * 100000, "deep.json"), "JSON nested too deeply")


def test_write_then_read_round_trips_exactly(tmp_path):
    rng = np.random.default_rng(3)
    labels = ("Derrick:LKNE", "RKNE", "C7", "CLAV", "Ümlaut", "T10")
    vertices = np.array([7, -1, 0, -1, 123456789, -1])
    positions = np.full((6, 3), np.nan)
    positions[[1, 3, 5]] = [[0.1, 1 / 3, -2e-300], rng.normal(size=3), [-0.0, 1e17, 5.0]]
    offsets = np.array([0.0, 0.013, 1 / 7, 0.0, 2.0, 0.0])
    path = tmp_path / "layout.json"
    write_marker_layout(path, MarkerLayout("unused", labels, vertices, positions, offsets))
    back = read_marker_layout(path)
    assert back.path == str(path) and back.labels == labels
    assert back.vertices.dtype == np.int64 and np.array_equal(back.vertices, vertices)
    assert np.array_equal(back.positions, positions, equal_nan=True) and np.array_equal(back.offsets, offsets)
    document = json.loads(path.read_text(encoding="utf-8"))
    assert document["Derrick:LKNE"] == 7 and type(document["Derrick:LKNE"]) is int
    assert document["CLAV"] == positions[3].tolist() and document["C7"] == {"vertex": 0, "offset": 1 / 7}
    assert document["RKNE"] == {"position": [0.1, 1 / 3, -2e-300], "offset": 0.013}
    assert document["Ümlaut"] == {"vertex": 123456789, "offset": 2.0}
    assert [p.name for p in tmp_path.iterdir()] == ["layout.json"]  # no temporary left beside it


@pytest.mark.parametrize("vertices,positions,offsets,needle", [
    ([1, -1], [[np.nan] * 3, [np.nan, 0, 0]], [0, 0], "marker B has neither a vertex nor a finite position"),
    ([1, 2], [[np.nan] * 3] * 2, [0, -1], "marker B: offset -1.0 is not a finite distance ≥ 0"),
    ([1, 2, 3], [[np.nan] * 3] * 2, [0, 0], "needs vertices (2,)"),
])
def test_write_refuses_an_invalid_layout(tmp_path, vertices, positions, offsets, needle):
    path = tmp_path / "layout.json"
    with pytest.raises(FormatError, match="not written") as caught:
        write_marker_layout(path, MarkerLayout("x", ("A", "B"), np.array(vertices), np.array(positions, float),
                                               np.array(offsets, float)))
    assert needle in str(caught.value) and not path.exists()


def take(labels, frames=4):
    points = np.arange(frames * len(labels) * 3, dtype=float).reshape(frames, len(labels), 3)
    return MarkerTake("take.c3d", tuple(labels), points, 50.0, 0.0, "m", "POINT:UNITS")


def layout(labels):
    count = len(labels)
    return MarkerLayout("layout.json", tuple(labels), np.arange(count), np.full((count, 3), np.nan), np.zeros(count))


def test_matching_drops_subject_prefixes_spaces_and_case():
    recorded = take(["Derrick:C7", "Derrick:l kne", "Derrick:EXTRA", "Derrick:RKNE", "Derrick:clav"])
    matched = match_markers(recorded, layout(["LKNE", "r kne", "Other:C7", "CLAV"]))
    assert matched.take_labels == ("Derrick:l kne", "Derrick:RKNE", "Derrick:C7", "Derrick:clav")
    assert matched.points.shape == (4, 4, 3)
    assert np.array_equal(matched.points, recorded.points[:, [1, 3, 0, 4]])
    assert matched.missing == () and matched.unmatched == ("Derrick:EXTRA",)


def test_missing_markers_need_allow_missing():
    recorded = take(["S:C7", "S:LKNE", "S:RKNE"])
    wanted = layout(["C7", "LKNE", "T10", "RKNE", "CLAV"])
    with pytest.raises(FormatError) as caught:
        match_markers(recorded, wanted)
    assert str(caught.value) == ("take.c3d: lacks markers T10, CLAV named by layout.json (give --allow-missing to "
                                 "play without them)")
    matched = match_markers(recorded, wanted, allow_missing=True)
    assert matched.missing == ("T10", "CLAV") and matched.unmatched == ()
    assert matched.take_labels == ("S:C7", "S:LKNE", "", "S:RKNE", "")
    assert np.isnan(matched.points[:, [2, 4]]).all()
    assert np.array_equal(matched.points[:, [0, 1, 3]], recorded.points)


@pytest.mark.parametrize("allow_missing", [False, True])
def test_fewer_than_three_markers_are_refused_whatever_allow_missing(allow_missing):
    recorded = take(["S:C7", "S:LKNE", "S:X1", "S:X2"])
    with pytest.raises(FormatError) as caught:
        match_markers(recorded, layout(["C7", "LKNE", "RKNE", "CLAV"]), allow_missing=allow_missing)
    assert str(caught.value) == ("take.c3d: fewer than 3 markers of layout.json found in the take: only C7, LKNE; "
                                 "the take's markers are S:C7, S:LKNE, S:X1, S:X2")
    with pytest.raises(FormatError, match=r"in the take: none; the take's markers are M0, M1, .*, M7, … \(9 in all"):
        match_markers(take([f"M{i}" for i in range(9)]), layout(["A", "B", "C"]), allow_missing=allow_missing)
