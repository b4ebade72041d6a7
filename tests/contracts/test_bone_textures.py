"""Bone-animation textures (issue 23): decoded as a vertex shader would (texel -> bone rotation and
translation -> linear blend skinning of the rest mesh's four influences), every clip of the folder
is the animation itself: within 1e-5 of the diagonal in float, 1e-3 in half."""

import json

import h5py
import numpy as np
import pytest

from skinsynth.formats.bone_textures import read_bone_texture
from skinsynth.formats.model import read_model
from skinsynth.formats.skin_file import read_skin
from skinsynth.gpu import lbs

from cli_helpers import assert_ok, assert_user_error, cli
from glb_reading import glb_primitive


@pytest.fixture(scope="module")
def files(stage_files, tmp_path_factory):
    stages = stage_files(frames=40, bones=4, iterations=6, cycles=2, graph=())
    root = stages.copy_to(tmp_path_factory.mktemp("bones"))
    assert_ok(cli("synthesize", root / "graph.h5", "-o", root / "b.h5", "-n", 5, "-m", 30, "--seed", 8, "-q"))
    return root


def shader_decode(folder, clip, frame):
    """What a vertex shader computes for ``frame`` of clip number ``clip`` (bones.json's layout)."""
    layout = json.loads((folder / "bones.json").read_text())
    image = read_bone_texture(folder / "bones.exr").astype(np.float64)
    attributes = glb_primitive(folder / "rest.glb")[0]
    rest = attributes["POSITION"].astype(np.float64)
    bones = np.concatenate([attributes["TEXCOORD_1"], attributes["TEXCOORD_2"]], axis=1).astype(int)
    weights = np.concatenate([attributes["TEXCOORD_3"], attributes["TEXCOORD_4"]], axis=1).astype(np.float64)
    g = layout["clips"][clip]["first"] + frame
    assert g <= layout["clips"][clip]["last"]
    per_row, count = layout["frames_per_row"], 2 * layout["bones"]
    x0, y = (g % per_row) * count, g // per_row
    q = image[y, x0 + 2 * bones]  # (V, 4, 4): each influence's rotation texel
    t = image[y, x0 + 2 * bones + 1][..., :3]
    xyz, w = q[..., :3], q[..., 3:]
    r = rest[:, None, :]
    rotated = r + 2.0 * np.cross(xyz, np.cross(xyz, r) + w * r)
    return np.einsum("vk,vkc->vc", weights, rotated + t)


@pytest.mark.parametrize("half, tolerance", [(False, 1e-5), (True, 1e-3)], ids=["float", "half"])
def test_every_clip_decodes_to_its_animation(files, tmp_path, half, tolerance):
    folder = tmp_path / "bones"
    extra = ["--half"] if half else []
    done = assert_ok(cli("export", files / "b.h5", "--animation", 1, "--animation", "3:5", "-o", f"{folder}/",
                         "--as", "bones", "--json", *extra))
    summary = json.loads(done.stdout)
    assert summary["texel_bytes_per_animation"] < summary["vat_texel_bytes_per_animation"]
    layout = json.loads((folder / "bones.json").read_text())
    assert [c["name"] for c in layout["clips"]] == ["animation_0001", "animation_0003", "animation_0004"]
    assert [(c["first"], c["last"]) for c in layout["clips"]] == [(0, 29), (30, 59), (60, 89)]  # inclusive
    skin = read_skin(files / "b.h5", read_model(files / "b.h5", groups=("mesh", "examples", "skin")))
    diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    with h5py.File(files / "b.h5") as f:
        for clip, animation in enumerate((1, 3, 4)):
            truth = lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights,
                        f["synthesis/bone_matrices"][animation].astype(np.float64),
                        f["synthesis/bone_translations"][animation].astype(np.float64), device="cpu")
            for frame in (0, 14, 29):  # first, middle, last (the clip's inclusive end)
                error = np.abs(shader_decode(folder, clip, frame) - truth[frame]).max() / diagonal
                assert error <= tolerance, (clip, frame, error)


def test_many_frames_wrap_to_more_rows(files, tmp_path):
    folder = tmp_path / "narrow"
    assert_ok(cli("export", files / "b.h5", "-o", f"{folder}/", "--as", "bones", "--max-width", 40, "-q"))
    layout = json.loads((folder / "bones.json").read_text())
    assert layout["frames_per_row"] == 5 and layout["width"] == 40 and layout["height"] == 30  # 150 frames
    skin = read_skin(files / "b.h5", read_model(files / "b.h5", groups=("mesh", "examples", "skin")))
    with h5py.File(files / "b.h5") as f:
        truth = lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, f["synthesis/bone_matrices"][4].astype(
            np.float64), f["synthesis/bone_translations"][4].astype(np.float64), device="cpu")
    diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    assert np.abs(shader_decode(folder, 4, 29) - truth[29]).max() <= 1e-5 * diagonal


@pytest.mark.parametrize("args, needles", [
    (["-o", "{out}/b.usdc", "--as", "bones"], ["--as bones writes a folder"]),
    (["-o", "{out}/b/", "--as", "bones", "--max-width", 1], ["takes 8 texels, more than --max-width 1"]),
], ids=["not a folder", "too wide"])
def test_bad_bone_texture_requests_are_one_line(files, tmp_path, args, needles):
    args = [a.replace("{out}", str(tmp_path)) if isinstance(a, str) else a for a in args]
    assert_user_error(cli("export", files / "b.h5", *args), *needles, folder=tmp_path)


def played_puppet(stage_files, *options):
    """The test bar's stage files with a puppet trained with ``options`` (read only)."""
    return stage_files(frames=40, bones=4, iterations=6, cycles=2, controls=("--count", 4), puppet=options)


def test_play_as_bones_decodes_to_what_play_computes(stage_files, tmp_path):
    """play -o DIR/ --as bones: each character a clip of one texture, decoded as a shader would,
    is play's own linear skinning (its .h5 vertices, the characters in place: --spacing 0)."""
    from skinsynth.formats.meshseq import read_played_characters

    stages = played_puppet(stage_files, "--skinning", "linear", "--correctives", "off")
    args = ["play", stages / "puppet.h5", "-c", stages / "bar.npz", "--instances", 2, "--spacing", 0, "-q"]
    folder = tmp_path / "bones"
    assert_ok(cli(*args, "-o", f"{folder}/", "--as", "bones"))
    assert_ok(cli(*args, "-o", tmp_path / "played.h5"))
    names, vertices, _, _ = read_played_characters(tmp_path / "played.h5")
    layout = json.loads((folder / "bones.json").read_text())
    assert [c["name"] for c in layout["clips"]] == list(names) == ["character_000", "character_001"]
    assert [(c["first"], c["last"]) for c in layout["clips"]] == [(0, 39), (40, 79)]
    diagonal = np.linalg.norm(np.ptp(vertices[0, 0], axis=0))
    for clip in range(2):
        for frame in (0, 20, 39):
            error = np.abs(shader_decode(folder, clip, frame) - vertices[clip, frame]).max() / diagonal
            assert error <= 1e-5, (clip, frame, error)


def test_what_bone_textures_cannot_carry_is_refused_in_one_line(stage_files, tmp_path):
    """Pose-space correctives move vertices (bone textures carry bones), dual quaternions are not
    what a shader's linear decode plays, and bone textures are a folder: one line each."""
    corrected = played_puppet(stage_files, "--skinning", "linear", "--correctives", "1e-3")
    plain = played_puppet(stage_files, "--skinning", "linear", "--correctives", "off")
    out = tmp_path / "out"
    out.mkdir()
    assert_user_error(cli("play", corrected / "puppet.h5", "-c", corrected / "bar.npz", "-o", f"{out}/b/", "--as",
                          "bones"), "correctives", "train-kcca --correctives off", "without --as bones", folder=out)
    assert_user_error(cli("play", plain / "puppet.h5", "-c", plain / "bar.npz", "-o", f"{out}/b/", "--as", "bones",
                          "--skinning", "dual-quaternion"), "bone textures skin linearly", "--skinning linear",
                      folder=out)
    assert_user_error(cli("play", plain / "puppet.h5", "-c", plain / "bar.npz", "-o", out / "b.usdc", "--as",
                          "bones"), "--as bones writes a folder", f"-o {out / 'b'}/", folder=out)


def test_the_rest_mesh_carries_the_input_uvs_split_at_seams(tmp_path):
    """An input with UVs (issue 23): rest.glb's TEXCOORD_0 is each corner's (u, 1 − v), its seam
    vertices copies with their original's influences (the decode still plays every vertex), and
    rest.obj keeps its vertices unsplit with a vt per corner; without UVs TEXCOORD_0 is zero."""
    from skinsynth.formats.meshseq import read_mesh_sequence
    from skinsynth.pipeline.mesh.uv_seams import split_uv_seams
    from uv_meshes import uv_bar, write_obj_frames

    write_obj_frames(tmp_path / "frames", *uv_bar())
    assert_ok(cli("fit-skin", tmp_path / "frames", "-o", tmp_path / "skin.h5", "--bones", 4, "--iterations", 4, "-q"))
    folder = tmp_path / "bones"
    assert_ok(cli("export", tmp_path / "skin.h5", "-o", f"{folder}/", "--as", "bones", "-q"))
    skin = read_skin(tmp_path / "skin.h5")
    vertex_map, split_faces, _ = split_uv_seams(skin.faces, skin.face_uvs, len(skin.rest_vertices))
    attributes = glb_primitive(folder / "rest.glb")[0]
    assert len(attributes["POSITION"]) == len(vertex_map) > len(skin.rest_vertices)
    np.testing.assert_array_equal(attributes["POSITION"], skin.rest_vertices[vertex_map].astype(np.float32))
    flipped = np.stack([skin.face_uvs[..., 0], 1.0 - skin.face_uvs[..., 1]], axis=-1).astype(np.float32)
    np.testing.assert_array_equal(attributes["TEXCOORD_0"][split_faces], flipped)
    truth = lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations, skin.translations,
                device="cpu")[:, vertex_map]
    diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    for frame in (0, 20, 39):
        assert np.abs(shader_decode(folder, 0, frame) - truth[frame]).max() <= 1e-5 * diagonal
    assert "material UVs" in json.loads((folder / "bones.json").read_text())["rest_mesh"]["uv"]
    # rest.obj: the V vertices in order, each corner's UV as written (OBJ's v up)
    (tmp_path / "again").mkdir()
    for f in range(2):
        (tmp_path / "again" / f"{f}.obj").write_text((folder / "rest.obj").read_text())
    again = read_mesh_sequence(str(tmp_path / "again"))
    np.testing.assert_allclose(again.vertices[0], skin.rest_vertices, rtol=1e-8)
    np.testing.assert_array_equal(again.faces, skin.faces)
    np.testing.assert_allclose(again.face_uvs, skin.face_uvs, rtol=1e-8, atol=1e-12)


def test_without_uvs_the_rest_mesh_has_zero_texcoord_0(files, tmp_path):
    folder = tmp_path / "plain"
    assert_ok(cli("export", files / "b.h5", "--animation", 0, "-o", f"{folder}/", "--as", "bones", "-q"))
    attributes = glb_primitive(folder / "rest.glb")[0]
    skin = read_skin(files / "b.h5", read_model(files / "b.h5", groups=("mesh", "examples", "skin")))
    assert len(attributes["POSITION"]) == len(skin.rest_vertices) and not attributes["TEXCOORD_0"].any()
    assert json.loads((folder / "bones.json").read_text())["rest_mesh"]["uv"] == "TEXCOORD_0 (zero: no material UVs)"
    assert "vt" not in (folder / "rest.obj").read_text()
