"""fit-skin on several clips of one mesh (one rig), and --rig (a new take on an existing rig)."""

import json

import h5py
import numpy as np
import pytest

from skinsynth.formats.skin_file import read_skin
from skinsynth.pipeline.inputs.examples import synthetic_lbs

from cli_helpers import assert_ok, assert_user_error, cli


@pytest.fixture(scope="module")
def clips(tmp_path_factory):
    """clip_walk.npz (frames 0–13) and clip_turn.npz (14–23) of one exact LBS animation, their
    concatenation as one file, and a third take (frames 24–31) for --rig."""
    folder = tmp_path_factory.mktemp("clips")
    truth = synthetic_lbs(bones=5, frames=32, seed=7, rings=24, segments=8)
    parts = {"clip_walk": slice(0, 14), "clip_turn": slice(14, 24), "both": slice(0, 24), "take": slice(24, 32)}
    for name, part in parts.items():
        np.savez(folder / f"{name}.npz", vertices=truth["vertices"][part], faces=truth["faces"], fps=24.0)
    return folder, truth


def test_several_clips_get_one_rig_and_a_clip_table(clips):
    folder, _ = clips
    out = folder / "joint.h5"
    result = assert_ok(cli("fit-skin", folder / "clip_walk.npz", folder / "clip_turn.npz", "-o", out, "--bones", 5,
                           "--json"))
    summary = json.loads(result.stdout)
    assert [(c["name"], c["frames"]) for c in summary["clips"]] == [("walk", 14), ("turn", 10)]
    skin = read_skin(str(out))
    assert skin.clip_names == ("walk", "turn") and skin.clip_frames == (14, 10)
    with h5py.File(out) as f:
        assert f["examples/clip_frames"][()].tolist() == [14, 10]
    # one fit over every frame: the same numbers as fitting the frames as one file
    alone = folder / "alone.h5"
    assert_ok(cli("fit-skin", folder / "both.npz", "-o", alone, "--bones", 5, "-q"))
    one = read_skin(str(alone))
    assert one.clip_names == ("both",) and one.clip_frames == (24,)
    for name in ("rotations", "translations", "bone_weights", "bone_indices", "rest_vertices"):
        assert np.array_equal(getattr(skin, name), getattr(one, name)), name
    # per-clip errors are those of the frames of each clip
    with h5py.File(out) as f:
        frame_rmse = f["skin/frame_rmse"][()]
    assert np.isclose(summary["clips"][1]["rmse"], np.sqrt(np.mean(frame_rmse[14:] ** 2)))


def test_names_given_as_name_equals_input_and_rest_frame_by_clip(clips):
    folder, truth = clips
    out = folder / "named.h5"
    assert_ok(cli("fit-skin", f"run={folder / 'clip_walk.npz'}", f"fall={folder / 'clip_turn.npz'}", "-o", out,
                  "--bones", 5, "--rest-frame", "fall:2", "-q"))
    skin = read_skin(str(out))
    assert skin.clip_names == ("run", "fall") and skin.rest_frame == 16
    assert np.array_equal(skin.rest_vertices, truth["vertices"][16])


def test_a_new_take_on_a_rig_keeps_the_rig_and_solves_its_bones(clips):
    folder, truth = clips
    rig = folder / "rig.h5"
    assert_ok(cli("fit-skin", folder / "clip_walk.npz", folder / "clip_turn.npz", "-o", rig, "--bones", 5, "-q"))
    out = folder / "take.h5"
    summary = json.loads(assert_ok(cli("fit-skin", folder / "take.npz", "--rig", rig, "-o", out, "--json")).stdout)
    base, take = read_skin(str(rig)), read_skin(str(out))
    for name in ("rest_vertices", "bone_indices", "bone_weights", "bone_rest_frames", "faces"):
        assert np.array_equal(getattr(base, name), getattr(take, name)), name
    assert take.rotations.shape == (8, 5, 3, 3) and take.clip_names == ("take",)
    # the data is exact LBS of the same bones, so the rig fits the new take about as well as its own clips
    assert summary["rmse_over_diagonal"] < 5 * base.rmse_over_diagonal + 1e-6
    full = folder / "take_full.h5"
    assert_ok(cli("fit-skin", folder / "take.npz", "-o", full, "--bones", 5, "-q"))
    assert np.isfinite(read_skin(str(full)).rmse)


@pytest.mark.parametrize("problem", ["vertices", "faces", "fps"])
def test_clips_of_different_meshes_are_refused_in_one_line(clips, tmp_path, problem):
    folder, truth = clips
    vertices, faces, fps = truth["vertices"][:6], truth["faces"].copy(), 24.0
    if problem == "vertices":
        vertices = vertices[:, :-1]
        faces = faces[(faces < vertices.shape[1]).all(axis=1)]
    elif problem == "faces":
        faces[3] = faces[3, ::-1]
    else:
        fps = 30.0
    np.savez(tmp_path / "other.npz", vertices=vertices, faces=faces, fps=fps)
    needle = {"vertices": "vertices", "faces": "face 3", "fps": "30 fps"}[problem]
    assert_user_error(cli("fit-skin", folder / "clip_walk.npz", tmp_path / "other.npz", "-o", tmp_path / "x.h5",
                          "--bones", 3), "other.npz", needle, folder=tmp_path, keep=["other.npz"])


def test_bad_rig_and_names_are_refused_in_one_line(clips, tmp_path):
    folder, truth = clips
    rig = folder / "rig2.h5"
    assert_ok(cli("fit-skin", folder / "clip_walk.npz", "-o", rig, "--bones", 5, "-q"))
    np.savez(tmp_path / "small.npz", vertices=truth["vertices"][:4, :-8], faces=truth["faces"][:10], fps=24.0)
    keep = ["small.npz"]
    assert_user_error(cli("fit-skin", tmp_path / "small.npz", "--rig", rig, "-o", tmp_path / "x.h5"),
                      "rig2.h5", "vertices", folder=tmp_path, keep=keep)
    assert_user_error(cli("fit-skin", folder / "take.npz", "--rig", rig, "--bones", 4, "-o", tmp_path / "x.h5"),
                      "--bones 4", folder=tmp_path, keep=keep)
    assert_user_error(cli("fit-skin", folder / "take.npz", "-o", tmp_path / "x.h5"), "--bones", folder=tmp_path,
                      keep=keep)
    assert_user_error(cli("fit-skin", folder / "take.npz", "--rig", rig, "--seed", 3, "-o", tmp_path / "x.h5"),
                      "--seed", "--rig", folder=tmp_path, keep=keep)
    assert_user_error(cli("fit-skin", f"a={folder / 'clip_walk.npz'}", f"a={folder / 'clip_turn.npz'}", "-o",
                          tmp_path / "x.h5", "--bones", 3), "named 'a'", folder=tmp_path, keep=keep)
    assert_user_error(cli("fit-skin", folder / "clip_walk.npz", folder / "clip_turn.npz", "-o", tmp_path / "x.h5",
                          "--bones", 3, "--rest-frame", "trot:1"), "no clip named 'trot'", "walk, turn",
                      folder=tmp_path, keep=keep)
