"""Several clips of one mesh in what inspect, export and preview write (issue 26): inspect lists
the file's clip table; export --clip gives one clip's frames exactly, a .glb one animation per
clip, a USD stage its clips' time codes; preview names frames CLIP:FRAME and marks a jump into
another clip as a seam."""

import json
import os
import shutil
import subprocess

import h5py
import numpy as np
import pytest
from PIL import Image

from skinsynth.formats.skin_file import read_skin
from skinsynth.formats.usd import read_clips, read_points_cache, read_skel_points
from skinsynth.pipeline.inputs.examples import synthetic_lbs

from cli_helpers import assert_ok, assert_user_error, cli
from glb_reading import glb_accessor, glb_document

JS = os.path.join(os.path.dirname(__file__), os.pardir, "contracts", "js")
START = 101  # the scene's first time code, set in the skin file: every export counts from it


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """walk.npz (14 frames) and turn.npz (10) of one exact LBS animation fitted as two clips
    (two.h5, its scene starting at frame START), and walk alone (one.h5)."""
    folder = tmp_path_factory.mktemp("clips_outputs")
    truth = synthetic_lbs(bones=4, frames=24, seed=3, rings=16, segments=6)
    for name, part in {"walk": slice(0, 14), "turn": slice(14, 24)}.items():
        np.savez(folder / f"{name}.npz", vertices=truth["vertices"][part], faces=truth["faces"], fps=24.0)
    assert_ok(cli("fit-skin", folder / "walk.npz", folder / "turn.npz", "-o", folder / "two.h5", "--bones", 4,
                  "--iterations", 6, "-q"))
    with h5py.File(folder / "two.h5", "r+") as f:
        f["examples"].attrs["start_frame"] = float(START)
    assert_ok(cli("fit-skin", folder / "walk.npz", "-o", folder / "one.h5", "--bones", 4, "--iterations", 6, "-q"))
    return folder


def stored_table(path):
    """[{name, frames, first, last}] read straight from /examples, first and last by counting."""
    with h5py.File(path) as f:
        counts = f["examples/clip_frames"][()].tolist()
        names = [str(n) for n in f["examples"].attrs["clip_names"]]
    firsts = np.concatenate([[0], np.cumsum(counts)[:-1]]).tolist()
    return [{"name": n, "frames": c, "first": a, "last": a + c - 1} for n, c, a in zip(names, counts, firsts)]


def skin_of(path):
    return read_skin(str(path))


def reconstruction(skin, frames):
    """(M, V, 3): the skin's LBS of the global frames ``frames``, written out here (v = Σ w (R r + t))."""
    rotations, translations = skin.rotations[frames], skin.translations[frames]
    moved = np.einsum("fvkij,vj->fvki", rotations[:, skin.bone_indices], skin.rest_vertices) \
        + translations[:, skin.bone_indices]
    return np.einsum("vk,fvki->fvi", skin.bone_weights, moved)


# ---------------------------------------------------------------- inspect


def test_inspect_lists_the_clip_table_the_file_holds(files):
    summary = json.loads(assert_ok(cli("inspect", files / "two.h5", "--json")).stdout)
    assert summary["clips"] == stored_table(files / "two.h5")
    assert [c["name"] for c in summary["clips"]] == ["walk", "turn"]
    text = assert_ok(cli("inspect", files / "two.h5")).stdout
    assert "  walk: 14 frames (0–13)" in text and "  turn: 10 frames (14–23)" in text


RECIPE = dict(frames=24, bones=4, iterations=8, cycles=2, controls=("--count", 6), puppet=(),
              graph=("--min-segment", 4), synthesis=("-n", 1, "-m", 30, "--device", "cpu"))


def test_inspect_lists_the_clips_of_every_stage_file(files, stage_files, tmp_path):
    stages = stage_files(**RECIPE)
    for name in ("skin.h5", "controls.h5", "puppet.h5", "graph.h5", "bones.h5"):
        summary = json.loads(assert_ok(cli("inspect", stages / name, "--json")).stdout)
        assert summary["clips"] == stored_table(stages / name) == [
            {"name": "bar", "frames": 24, "first": 0, "last": 23}], name
    # a later stage of a two-clip skin: its own C (control candidates) is no clip count
    assert_ok(cli("select-controls", files / "two.h5", "-o", tmp_path / "controls.h5", "--count", 6, "-q"))
    summary = json.loads(assert_ok(cli("inspect", tmp_path / "controls.h5", "--json")).stdout)
    assert summary["clips"] == stored_table(files / "two.h5")


def test_inspect_of_a_file_without_a_clip_table_names_one_clip_after_its_source(files, tmp_path):
    old = tmp_path / "old.h5"
    shutil.copy(files / "one.h5", old)
    with h5py.File(old, "r+") as f:
        del f["examples/clip_frames"]
        del f["examples"].attrs["clip_names"]
    summary = json.loads(assert_ok(cli("inspect", old, "--json")).stdout)
    assert summary["clips"] == [{"name": "walk", "frames": 14, "first": 0, "last": 13}]


# ---------------------------------------------------------------- export


@pytest.mark.parametrize("kind", ["skel", "points"])
def test_export_of_one_clip_is_exactly_its_frames_from_the_start_frame(files, tmp_path, kind):
    out = tmp_path / "turn.usda"
    summary = json.loads(assert_ok(cli("export", files / "two.h5", "--clip", "turn", "-o", out, "--as", kind,
                                       "--json")).stdout)
    assert summary["frames"] == 10 and summary["clips"] == ["turn"]
    skin = skin_of(files / "two.h5")
    truth = reconstruction(skin, np.arange(14, 24))
    played = read_skel_points(out) if kind == "skel" else read_points_cache(out)[0]
    diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    assert played.shape == truth.shape and np.abs(played - truth).max() < 1e-5 * diagonal
    from pxr import Usd

    stage = Usd.Stage.Open(str(out))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (START, START + 9)
    assert read_clips(out) == []  # one clip: no clip metadata


def test_a_usd_stage_of_several_clips_names_each_clips_time_codes(files, tmp_path):
    for kind in ("skel", "points"):
        out = tmp_path / f"{kind}.usdc"
        assert_ok(cli("export", files / "two.h5", "-o", out, "--as", kind, "-q"))
        assert read_clips(out) == [("walk", START, START + 13), ("turn", START + 14, START + 23)]
    assert_ok(cli("export", files / "one.h5", "-o", tmp_path / "one.usda", "-q"))
    assert read_clips(tmp_path / "one.usda") == []
    assert "customLayerData" not in (tmp_path / "one.usda").read_text()


def animations_of(path):
    """{name: [(times (F,), [channel outputs])]} of a .glb's animations."""
    document, binary = glb_document(path)
    out = {}
    for animation in document["animations"]:
        samplers = animation["samplers"]
        out[animation["name"]] = (glb_accessor(document, binary, samplers[0]["input"])[:, 0],
                                  [glb_accessor(document, binary, s["output"]) for s in samplers])
    return out


def test_a_glb_of_several_clips_has_one_animation_per_clip(files, tmp_path):
    out = tmp_path / "two.glb"
    summary = json.loads(assert_ok(cli("export", files / "two.h5", "-o", out, "--json")).stdout)
    animations = animations_of(out)
    assert list(animations) == ["walk", "turn"] == summary["names"]
    for name, frames in (("walk", 14), ("turn", 10)):
        times, outputs = animations[name]
        assert np.allclose(times, np.arange(frames) / 24.0)
        assert all(len(keys) == frames for keys in outputs)
        # each is the animation of that clip exported alone
        alone = tmp_path / f"{name}.glb"
        assert_ok(cli("export", files / "two.h5", "--clip", name, "-o", alone, "-q"))
        (single, (times_alone, outputs_alone)), = animations_of(alone).items()
        assert single == name and np.array_equal(times, times_alone)
        assert all(np.array_equal(a, b) for a, b in zip(outputs, outputs_alone))
    one = animations_of(_export(files / "one.h5", tmp_path / "one.glb"))
    assert list(one) == ["animation"]  # one clip: as before clips
    if shutil.which("node") and os.path.isdir(os.path.join(JS, "node_modules", "gltf-validator")):
        done = subprocess.run(["node", os.path.join(JS, "gltf_validate.mjs"), str(out)], capture_output=True,
                              text=True, timeout=120)
        report = json.loads(done.stdout)
        assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]


def test_texture_folders_of_several_clips_hold_one_animation_per_clip(files, tmp_path):
    from skinsynth.formats.exr import read_vat

    skin = skin_of(files / "two.h5")
    assert_ok(cli("export", files / "two.h5", "-o", f"{tmp_path / 'vat'}/", "-q"))
    for name, frames in (("walk", np.arange(14)), ("turn", np.arange(14, 24))):
        offsets, _ = read_vat(tmp_path / "vat" / f"{name}.exr")  # float32 offsets from the rest pose
        expected = reconstruction(skin, frames) - skin.rest_vertices
        assert offsets.shape == expected.shape
        np.testing.assert_allclose(offsets, expected, atol=1e-5 * np.ptp(skin.rest_vertices))
    assert_ok(cli("export", files / "two.h5", "-o", f"{tmp_path / 'bones'}/", "--as", "bones", "-q"))
    with open(tmp_path / "bones" / "bones.json") as handle:
        table = json.load(handle)["clips"]
    assert [(c["name"], c["first"], c["last"]) for c in table] == [("walk", 0, 13), ("turn", 14, 23)]


def _export(path, out, *options):
    assert_ok(cli("export", path, "-o", out, "-q", *options))
    return out


@pytest.mark.parametrize("command, output", [("export", "x.usda"), ("export", "x.glb"), ("preview", "x.gif")])
def test_an_unknown_clip_is_one_line_naming_the_option_and_the_clips(files, tmp_path, command, output):
    assert_user_error(cli(command, files / "two.h5", "--clip", "trot", "-o", tmp_path / output),
                      "--clip", "'trot'", "walk, turn", folder=tmp_path)


def test_clip_of_a_file_without_clips_is_one_line(files, tmp_path):
    assert_user_error(cli("export", files / "turn.npz", "--clip", "turn", "-o", tmp_path / "x.usda"), "turn.npz",
                      folder=tmp_path)
    assert_user_error(cli("preview", files / "turn.npz", "--clip", "turn", "-o", tmp_path / "x.gif"), "--clip",
                      "turn.npz", folder=tmp_path)


# ---------------------------------------------------------------- preview


def test_preview_of_one_clip_shows_its_frames(files, tmp_path):
    out = tmp_path / "turn.gif"
    summary = json.loads(assert_ok(cli("preview", files / "two.h5", "--clip", "turn", "-o", out, "--size", "96x64",
                                       "--compare", "--json")).stdout)
    assert summary["frames"] == 10 and summary["panels"] == 2


def test_frames_are_named_clip_colon_frame_when_there_are_several_clips():
    from skinsynth.pipeline.inputs.clips import Clips
    from skinsynth.pipeline.view import frame_captions, walk_captions

    clips = Clips(("walk", "turn"), (14, 10))
    assert frame_captions(clips, [0, 13, 14, 23]) == ["frame walk:0", "frame walk:13", "frame turn:0", "frame turn:9"]
    assert frame_captions(Clips.single(24), [3]) == ["frame 3"]
    captions, seams = walk_captions(clips, np.array([[12, 13, 14, 15, 3], [0, 1, 2, 3, 4]]))
    assert seams.tolist() == [False, False, True, False, True]
    assert captions[2] == "frame 2 · input turn:0, walk:2 · seam"


@pytest.fixture(scope="module")
def synthesis(stage_files, tmp_path_factory):
    """A synthesis file (one clip), and the same file with its clip table cut in two inside a
    run that animation 0 plays straight on: there the two-clip file has a seam the other does not."""
    root = stage_files(**RECIPE).copy_to(tmp_path_factory.mktemp("clips_preview"))
    with h5py.File(root / "bones.h5") as f:
        sources = f["synthesis/sources"][()][:, 0]  # (C, M): animation 0
        frames = f["examples/vertices"].shape[0]
    # the clips part at a frame that component 0 reaches by playing on from the one before
    steps = np.flatnonzero(sources[0, 1:] == sources[0, :-1] + 1) + 1
    cut = int(sources[0, steps[len(steps) // 2]])
    split = root / "split.h5"
    shutil.copy(root / "bones.h5", split)
    with h5py.File(split, "r+") as f:
        del f["examples/clip_frames"]
        f["examples/clip_frames"] = np.array([cut, frames - cut], dtype=np.int64)
        f["examples"].attrs["clip_names"] = ["early", "late"]
    return root, sources, cut


def red_caption_frames(path):
    with Image.open(path) as gif:
        reddish = []
        for m in range(gif.n_frames):
            gif.seek(m)
            corner = np.asarray(gif.convert("RGB"))[:30, :160].astype(int)
            reddish.append(bool(np.any((corner[..., 0] > 150) & (corner[..., 1] < 80) & (corner[..., 2] < 80))))
    return np.flatnonzero(reddish).tolist()


def test_preview_marks_a_jump_into_another_clip_as_a_seam(synthesis, tmp_path):
    root, sources, cut = synthesis
    jumps = np.any(sources[:, 1:] != sources[:, :-1] + 1, axis=0)
    into_late = np.any(sources[:, 1:] == cut, axis=0)  # plays the late clip's first frame after early's last
    for name, seams in (("bones.h5", jumps), ("split.h5", jumps | into_late)):
        out = tmp_path / f"{name}.gif"
        assert_ok(cli("preview", root / name, "-o", out, "--size", "240x120", "-q"))
        assert red_caption_frames(out) == (np.flatnonzero(seams) + 1).tolist(), name
    assert into_late.any() and not np.array_equal(jumps, jumps | into_late)
    assert_user_error(cli("preview", root / "split.h5", "--clip", "late", "-o", tmp_path / "x.gif"), "--clip",
                      "synthesis", folder=tmp_path, keep=["bones.h5.gif", "split.h5.gif"])
