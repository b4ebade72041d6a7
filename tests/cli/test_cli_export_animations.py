"""export of any animation of any file (issue 23, part 1): a synthesis's animations by index or
range, a played file's characters, read one at a time; the same points synthesize and play write."""

import json

import h5py
import numpy as np
import pytest

from skinsynth.formats.usd import read_points_cache, read_skel_points

from cli_helpers import assert_ok, assert_user_error, cli


@pytest.fixture(scope="module")
def files(stage_files, tmp_path_factory):
    """A synthesis of 10 animations with its --usd caches, and a play .h5 of 3 characters."""
    stages = stage_files(frames=40, bones=4, iterations=6, cycles=2, graph=(), controls=("--count", 4), puppet=())
    root = stages.copy_to(tmp_path_factory.mktemp("export"))
    assert_ok(cli("synthesize", root / "graph.h5", "-o", root / "bones.h5", "-n", 10, "-m", 30, "--seed", 2,
                  "--usd", root / "usd", "-q"))
    assert_ok(cli("play", root / "puppet.h5", "-c", root / "bar.npz", "--instances", 3, "-o", root / "crowd.h5",
                  "-q"))
    return root


def test_an_animation_of_a_synthesis_is_the_one_synthesize_wrote(files, tmp_path):
    assert_ok(cli("export", files / "bones.h5", "--animation", 7, "-o", tmp_path / "a.usdc", "--as", "points", "-q"))
    exported, _, _ = read_points_cache(tmp_path / "a.usdc")
    written, _, _ = read_points_cache(files / "usd" / "animation_0007.usdc")
    assert exported.shape[:1] == (30,) and np.array_equal(exported, written)


def test_an_animation_of_a_synthesis_as_a_usdskel_rig_plays_the_same_points(files, tmp_path):
    assert_ok(cli("export", files / "bones.h5", "--animation", 3, "-o", tmp_path / "a.usda", "-q"))  # skel: default
    played = read_skel_points(tmp_path / "a.usda")  # skinned by UsdSkel itself
    written, _, _ = read_points_cache(files / "usd" / "animation_0003.usdc")
    diagonal = np.linalg.norm(np.ptp(written[0], axis=0))
    assert played.shape == written.shape and np.abs(played - written).max() < 1e-5 * diagonal


def test_a_usdskel_rig_with_root_motion_plays_the_same_points(files, tmp_path):
    """--root-motion: the root joint carries the ground motion and the bones are divided by it."""
    from pxr import Usd, UsdSkel

    assert_ok(cli("export", files / "bones.h5", "--animation", 5, "-o", tmp_path / "a.usda", "--root-motion", "-q"))
    played = read_skel_points(tmp_path / "a.usda")
    written, _, _ = read_points_cache(files / "usd" / "animation_0005.usdc")
    diagonal = np.linalg.norm(np.ptp(written[0], axis=0))
    assert np.abs(played - written).max() < 1e-5 * diagonal
    stage = Usd.Stage.Open(str(tmp_path / "a.usda"))
    animation = UsdSkel.Animation(next(p for p in stage.Traverse() if p.IsA(UsdSkel.Animation)))
    travel = np.array([animation.GetTranslationsAttr().Get(f)[0] for f in range(30)])
    assert np.abs(travel[:, 1]).max() < 1e-6 and np.abs(travel).max() > 0  # Y up: on the ground, moving


def test_indices_and_ranges_choose_the_animations_of_a_folder_in_order(files, tmp_path):
    done = assert_ok(cli("export", files / "bones.h5", "--animation", "2:5", "--animation", 8, "--animation", 3,
                         "-o", f"{tmp_path / 'vat'}/", "--json"))
    summary = json.loads(done.stdout)
    assert summary["animations"] == [2, 3, 4, 8]
    clips = [clip["name"] for clip in json.loads((tmp_path / "vat" / "vat.json").read_text())["animations"]]
    assert clips == ["animation_0002", "animation_0003", "animation_0004", "animation_0008"]


def test_a_character_of_a_played_file_is_its_vertices(files, tmp_path):
    assert_ok(cli("export", files / "crowd.h5", "--animation", 1, "-o", tmp_path / "c.usdc", "-q"))  # points: default
    exported, _, _ = read_points_cache(tmp_path / "c.usdc")
    with h5py.File(files / "crowd.h5") as f:
        played = f["vertices"][1]
    assert np.abs(exported - played).max() == 0.0


@pytest.mark.parametrize("args, needles", [
    (["bones.h5", "--animation", 10, "-o", "{out}/a.usdc"], ["--animation 10", "animations 0..9"]),
    (["bones.h5", "--animation", "4:2", "-o", "{out}/v/"], ["--animation 4:2", "animations 0..9"]),
    (["bones.h5", "--animation", "x", "-o", "{out}/a.usdc"], ["expected N or A:B"]),
    (["bones.h5", "-o", "{out}/a.usdc"], ["10 animations chosen", "folder"]),
    (["bones.h5", "--animation", "0:2", "-o", "{out}/a.exr"], ["2 animations chosen", "folder"]),
    (["crowd.h5", "--animation", 0, "-o", "{out}/a.usdc", "--as", "skel"], ["--as skel needs a skeleton"]),
    (["crowd.h5", "--animation", 3, "-o", "{out}/a.usdc"], ["characters 0..2"]),
], ids=["out of range", "empty range", "not a number", "several to one file", "several to one exr",
        "skel of vertices", "character out of range"])
def test_bad_choices_are_one_line_and_write_nothing(files, tmp_path, args, needles):
    args = [str(files / a) if a in ("bones.h5", "crowd.h5") else
            (a.replace("{out}", str(tmp_path)) if isinstance(a, str) else a) for a in args]
    assert_user_error(cli("export", *args), *needles, folder=tmp_path)


def test_a_folder_of_many_animations_checks_each_texture_not_their_sum(files, tmp_path):
    """Each animation of a folder is its own texture: 10 × 30 frames at one texel a row is 10
    textures of 2,460 rows, not one of 24,600 (over the 16,384 engines load)."""
    assert_ok(cli("export", files / "bones.h5", "-o", f"{tmp_path / 'vat'}/", "--max-width", 1, "-q"))
    assert len([n for n in (tmp_path / "vat").iterdir() if n.name.endswith("_normals.exr")]) == 10
