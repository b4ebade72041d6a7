"""glTF of an input with material UVs (issue 23): the .glb carries them as TEXCOORD_0 in glTF's
convention (u, 1 − v), its vertices split at UV seams (each copy its original's position, normal
and influences), the Khronos validator finds nothing, and three.js plays it to skinsynth's LBS at
every vertex, the copies included. Inputs without UVs are test_gltf.py's."""


import numpy as np
import pytest

from skinsynth.formats.model import read_model
from skinsynth.formats.skin_file import read_skin
from skinsynth.gpu import lbs
from skinsynth.pipeline.mesh.uv_seams import split_uv_seams

from cli_helpers import assert_ok, cli
from glb_reading import glb_primitive
from gltf_clients import in_gltf_axes, skip_without_clients, three_positions, validate
from uv_meshes import uv_bar, write_obj_frames

skip_without_clients()


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("gltf_uvs")
    write_obj_frames(root / "frames", *uv_bar())
    assert_ok(cli("fit-skin", root / "frames", "-o", root / "skin.h5", "--bones", 4, "--iterations", 6, "-q"))
    assert_ok(cli("fit-skin", root / "frames", "-o", root / "zup.h5", "--bones", 4, "--iterations", 4,
                  "--up-axis", "Z", "--meters-per-unit", 0.01, "-q"))
    assert_ok(cli("build-graph", root / "skin.h5", "-o", root / "graph.h5", "-q"))
    return root


@pytest.mark.parametrize("source", ["skin.h5", "zup.h5"])
def test_a_glb_with_uvs_is_valid_and_three_js_plays_every_split_vertex(files, tmp_path, source):
    out = tmp_path / "uv.glb"
    assert_ok(cli("export", files / source, "-o", out, "-q"))
    report = validate(out)
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]

    skin = read_skin(files / source, read_model(files / source, groups=("mesh", "examples", "skin")))
    vertex_map, _, _ = split_uv_seams(skin.faces, skin.face_uvs, len(skin.rest_vertices))
    count = len(skin.rest_vertices)
    assert len(vertex_map) > count  # the bar's seam and caps split vertices
    attributes, indices = glb_primitive(out)
    assert len(attributes["POSITION"]) == len(vertex_map)
    np.testing.assert_array_equal(attributes["POSITION"],
                                  in_gltf_axes(skin.rest_vertices, skin.scene)[vertex_map].astype(np.float32))
    np.testing.assert_array_equal(attributes["NORMAL"][count:], attributes["NORMAL"][vertex_map[count:]])
    np.testing.assert_array_equal(attributes["JOINTS_0"][count:], attributes["JOINTS_0"][vertex_map[count:]])
    np.testing.assert_array_equal(attributes["WEIGHTS_0"][count:], attributes["WEIGHTS_0"][vertex_map[count:]])
    np.testing.assert_array_equal(vertex_map[indices], skin.faces)  # each corner's vertex
    flipped = np.stack([skin.face_uvs[..., 0], 1.0 - skin.face_uvs[..., 1]], axis=-1).astype(np.float32)
    np.testing.assert_array_equal(attributes["TEXCOORD_0"][indices], flipped)  # each corner's UV, v down

    frames = [0, len(skin.rotations) // 2, len(skin.rotations) - 1]
    played, _ = three_positions(out, skin.fps, frames, tmp_path)
    truth = in_gltf_axes(lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations,
                             skin.translations, device="cpu")[frames], skin.scene)[:, vertex_map]
    diagonal = np.linalg.norm(np.ptp(in_gltf_axes(skin.rest_vertices, skin.scene), axis=0))
    assert played.shape == (1, 3, len(vertex_map), 3)
    assert np.abs(played[0] - truth).max() <= 1e-5 * diagonal


def test_synthesize_gltf_carries_the_uvs_too(files, tmp_path):
    assert_ok(cli("synthesize", files / "graph.h5", "-o", tmp_path / "b.h5", "-n", 2, "-m", 20, "--seed", 2,
                  "--gltf", tmp_path / "run.glb", "-q"))
    skin = read_skin(files / "skin.h5")
    attributes, indices = glb_primitive(tmp_path / "run.glb")
    flipped = np.stack([skin.face_uvs[..., 0], 1.0 - skin.face_uvs[..., 1]], axis=-1).astype(np.float32)
    np.testing.assert_array_equal(attributes["TEXCOORD_0"][indices], flipped)
    report = validate(tmp_path / "run.glb")
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]
