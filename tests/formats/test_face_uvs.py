"""Material UVs through the stage files (issue 23): fit-skin keeps an input's corner UVs as
``/mesh/face_uvs`` exactly, every later stage carries them, a file without UVs has no such dataset,
and a damaged one is one error line."""

import h5py
import numpy as np
import pytest

from skinsynth.formats.model import read_model
from skinsynth.formats.skin_file import read_skin

from cli_helpers import assert_ok, assert_user_error, cli
from uv_meshes import distinct_uvs, uv_bar, write_obj_frames, write_usd_sequence


@pytest.fixture(scope="module")
def bar():
    return uv_bar()


@pytest.fixture(scope="module")
def uv_skin(bar, tmp_path_factory):
    """fit-skin of the bar's OBJ frames (with vt): the folder and the skin file."""
    root = tmp_path_factory.mktemp("uv_skin")
    vertices, faces, _ = bar
    write_obj_frames(root / "frames", *bar)
    assert_ok(cli("fit-skin", root / "frames", "-o", root / "skin.h5", "--bones", 4, "--iterations", 4, "-q"))
    return root


def mesh_group(path):
    with h5py.File(path) as f:
        return {name: f["mesh"][name][()] for name in f["mesh"]}


def test_fit_skin_keeps_the_obj_corner_uvs_exactly(bar, uv_skin):
    vertices, faces, face_uvs = bar
    assert len(np.unique(np.c_[faces.reshape(-1, 1), face_uvs.reshape(-1, 2)], axis=0)) > vertices.shape[1]  # seams
    mesh = mesh_group(uv_skin / "skin.h5")
    assert list(mesh) == ["rest_vertices", "faces", "face_uvs"]
    np.testing.assert_array_equal(mesh["faces"], faces)
    assert mesh["face_uvs"].dtype == np.float64
    np.testing.assert_array_equal(mesh["face_uvs"], face_uvs)
    skin = read_skin(uv_skin / "skin.h5")
    np.testing.assert_array_equal(skin.face_uvs, face_uvs)
    np.testing.assert_array_equal(skin.rest_vertices, vertices[0])  # vertex count and order kept


@pytest.mark.parametrize("interpolation", ["faceVarying indexed", "vertex"])
def test_fit_skin_keeps_usd_st(bar, tmp_path, interpolation):
    vertices, faces, face_uvs = bar
    if interpolation == "vertex":  # one UV a vertex (no seam): v along the bar, u from the height
        per_vertex = np.stack([vertices[0, :, 1] + 0.5, vertices[0, :, 0] / 4.0], axis=1)
        path = write_usd_sequence(tmp_path / "bar.usda", vertices, faces, per_vertex, "vertex")
        expected = per_vertex.astype(np.float32).astype(np.float64)[faces]
    else:
        uvs, index = distinct_uvs(face_uvs)
        path = write_usd_sequence(tmp_path / "bar.usdc", vertices, faces, uvs, "faceVarying", indices=index)
        expected = uvs.astype(np.float32).astype(np.float64)[index]
    assert_ok(cli("fit-skin", path, "-o", tmp_path / "skin.h5", "--bones", 4, "--iterations", 3, "-q"))
    np.testing.assert_array_equal(read_skin(tmp_path / "skin.h5").face_uvs, expected)


def test_a_file_without_uvs_has_no_face_uvs(stage_files):
    stages = stage_files(frames=40, bones=4, iterations=6, cycles=2)
    assert list(mesh_group(stages / "skin.h5")) == ["rest_vertices", "faces"]
    assert read_skin(stages / "skin.h5").face_uvs is None


def test_every_later_stage_carries_the_uvs(bar, uv_skin, tmp_path):
    face_uvs = bar[2]
    skin, controls, puppet = uv_skin / "skin.h5", tmp_path / "controls.h5", tmp_path / "puppet.h5"
    graph, synthesis = tmp_path / "graph.h5", tmp_path / "bones.h5"
    assert_ok(cli("select-controls", skin, "-o", controls, "--count", 4, "-q"))
    assert_ok(cli("train-kcca", controls, "-o", puppet, "--correctives", "off", "-q"))
    assert_ok(cli("build-graph", skin, "-o", graph, "-q"))
    assert_ok(cli("synthesize", graph, "-o", synthesis, "-n", 2, "-m", 20, "--seed", 1, "-q"))
    for path in (controls, puppet, graph, synthesis):
        np.testing.assert_array_equal(mesh_group(path)["face_uvs"], face_uvs, err_msg=str(path))
        groups = read_model(path, groups=("mesh", "examples", "skin"))
        np.testing.assert_array_equal(read_skin(path, groups).face_uvs, face_uvs, err_msg=str(path))


@pytest.mark.parametrize("damage, words", [
    ("shape", ["/mesh/face_uvs has shape", "(T, 3, 2)"]),
    ("nan", ["/mesh/face_uvs holds NaN or inf"]),
    ("kind", ["/mesh/face_uvs must hold float values"]),
])
def test_a_damaged_face_uvs_is_one_error_line(uv_skin, tmp_path, damage, words):
    bad = tmp_path / "bad.h5"
    bad.write_bytes((uv_skin / "skin.h5").read_bytes())
    with h5py.File(bad, "r+") as f:
        good = f["mesh/face_uvs"][()]
        del f["mesh/face_uvs"]
        if damage == "shape":
            f["mesh/face_uvs"] = good[:-1]
        elif damage == "nan":
            good[3, 1, 0] = np.nan
            f["mesh/face_uvs"] = good
        else:
            f["mesh/face_uvs"] = good.astype(np.int64)
    out = tmp_path / "out"
    out.mkdir()
    assert_user_error(cli("export", bad, "-o", out / "x.glb"), "bad.h5", *words, folder=out)
    assert_user_error(cli("inspect", bad), "bad.h5", *words)
