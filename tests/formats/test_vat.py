"""Engine-ready vertex animation (formats.vat_bundle): decoded as a shader would, from the rest
mesh's UVs and the texture's texels, it gives back the animation skinsynth computed."""

import json

import numpy as np
import OpenEXR
import pytest
import trimesh

from skinsynth.formats.errors import FormatError
from skinsynth.formats.scene import Scene
from skinsynth.formats.vat_bundle import check_texture_size, write_vat_folder
from skinsynth.pipeline.mesh.geometry import vertex_normals
from skinsynth.pipeline.inputs.examples import bending_bar

from cli_helpers import assert_ok, assert_user_error, cli


def shader_decode(folder, name, mesh_file):
    """What a VAT vertex shader does, in numpy: per vertex its UV, per frame v_f = v − f·rows/height,
    the texel under (u, v_f) with point sampling (v bottom-up), position = rest + texel."""
    sidecar = json.loads((folder / "vat.json").read_text())
    with OpenEXR.File(str(folder / f"{name}.exr")) as exr:
        image = np.array(exr.channels()["RGB"].pixels, dtype=np.float64)  # (height, width, 3), row 0 on top
    mesh = trimesh.load(str(folder / mesh_file), process=False, force="mesh")
    uv, rest = np.asarray(mesh.visual.uv, dtype=np.float64), np.asarray(mesh.vertices)
    width, height, rows = sidecar["width"], sidecar["height"], sidecar["rows_per_frame"]
    frames = []
    for f in range(sidecar["frame_count"]):
        v = uv[:, 1] - f * rows / height
        column = np.floor(uv[:, 0] * width).astype(int)
        row = np.floor((1.0 - v) * height).astype(int)
        frames.append(rest + image[row, column])
    return np.stack(frames)


@pytest.mark.parametrize("half,tolerance", [(False, 1e-6), (True, 1e-3)])
@pytest.mark.parametrize("mesh_file", ["rest.obj", "rest.glb"])
def test_a_shader_decode_gives_back_the_animation(tmp_path, half, tolerance, mesh_file):
    vertices, faces = bending_bar(frames=7, rings=12, segments=8)
    folder = tmp_path / "vat"
    write_vat_folder(folder, vertices[0], faces, [("walk", vertices, vertex_normals(vertices, faces))], 24.0, Scene(), max_width=20, half=half)
    decoded = shader_decode(folder, "walk", mesh_file)
    diagonal = np.linalg.norm(np.ptp(vertices[0], axis=0))
    assert np.abs(decoded - vertices).max() < tolerance * diagonal
    sidecar = json.loads((folder / "vat.json").read_text())
    assert (sidecar["width"], sidecar["rows_per_frame"], sidecar["frame_count"]) == (20, 5, 7)
    assert sidecar["encoding"]["type"] == ("half" if half else "float32")


def test_normals_texture_holds_unit_normals_of_each_frame(tmp_path):
    vertices, faces = bending_bar(frames=3, rings=6, segments=6)
    normals = vertex_normals(vertices, faces)
    assert np.allclose(np.linalg.norm(normals, axis=-1), 1.0)
    # brute force: each vertex sums the (area-weighted) cross products of its faces
    reference = np.zeros_like(vertices[2])
    for a, b, c in faces:
        n = np.cross(vertices[2][b] - vertices[2][a], vertices[2][c] - vertices[2][a])
        reference[[a, b, c]] += n
    reference /= np.linalg.norm(reference, axis=1, keepdims=True)
    assert np.abs(normals[2] - reference).max() < 1e-12
    write_vat_folder(tmp_path / "n", vertices[0], faces, [("a", vertices, normals)], 24.0, Scene())
    with OpenEXR.File(str(tmp_path / "n" / "a_normals.exr")) as exr:
        image = np.array(exr.channels()["RGB"].pixels)
    assert np.allclose(image.reshape(3, -1, 3)[:, :len(vertices[0])], normals, atol=1e-6)


def test_textures_past_what_engines_load_are_refused_with_a_clear_message():
    with pytest.raises(FormatError, match="16384"):
        check_texture_size("big", 10_000, 17_000, 8192)
    assert check_texture_size("ok", 10_000, 100, 8192) == (8192, 2, 200)


def test_export_and_play_write_the_folder(stage_files, tmp_path):
    stages = stage_files(frames=24, bones=4, iterations=6, controls=("--count", 6), puppet=())
    assert_ok(cli("export", stages / "skin.h5", "-o", f"{tmp_path / 'skin_vat'}/", "--half"))
    names = sorted(p.name for p in (tmp_path / "skin_vat").iterdir())
    assert names == [".skinsynth-folder.json", "animation.exr", "animation_normals.exr", "rest.glb", "rest.obj", "vat.json"]
    assert_ok(cli("play", stages / "puppet.h5", "-c", stages / "bar.npz", "-o", f"{tmp_path / 'crowd'}/",
                  "--instances", 2, "--max-width", 50))
    sidecar = json.loads((tmp_path / "crowd" / "vat.json").read_text())
    assert [a["name"] for a in sidecar["animations"]] == ["character_000", "character_001"]
    assert sidecar["width"] == 50
    assert_user_error(cli("play", stages / "puppet.h5", "-c", stages / "bar.npz", "-o", f"{tmp_path / 'x'}/",
                          "--max-width", 0), "--max-width")
