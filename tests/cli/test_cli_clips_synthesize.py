"""synthesize over several clips of one mesh (issue 26): frames named CLIP:FRAME in --start, --end
and --target, the summary per clip, the clip table carried into the synthesis file, unknown clips
refused in one line; and the shared horse gallop + collapse (slow)."""

import json

import h5py
import numpy as np
import pytest

from skinsynth.formats.meshseq import write_array_sequence
from skinsynth.formats.skin_file import read_skin
from skinsynth.pipeline.inputs.clips import Clips
from skinsynth.pipeline.inputs.examples import bending_bar

from cli_helpers import assert_ok, assert_user_error, cli

CYCLE = 20  # frames per clip: each clip is one bend-and-twist cycle of the bar


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """a.npz and b.npz, the two cycles of a bending bar, fitted as two clips of one rig
    (skin.h5) and analysed (graph.h5)."""
    folder = tmp_path_factory.mktemp("clips_synthesize")
    vertices, faces = bending_bar(frames=2 * CYCLE, rings=10, segments=8, cycles=2)
    write_array_sequence(folder / "a.npz", vertices[:CYCLE], faces, 24.0)
    write_array_sequence(folder / "b.npz", vertices[CYCLE:], faces, 24.0)
    assert_ok(cli("fit-skin", folder / "a.npz", folder / "b.npz", "-o", folder / "skin.h5", "--bones", 4,
                  "--iterations", 10, "-q"))
    assert_ok(cli("build-graph", folder / "skin.h5", "-o", folder / "graph.h5", "--min-segment", 4, "-q"))
    return folder


def sources_of(path):
    with h5py.File(path) as f:
        return f["synthesis/sources"][()], f["synthesis/seams"][()]


def test_start_and_end_name_frames_of_clips(files, tmp_path):
    out = tmp_path / "s.h5"
    report = json.loads(assert_ok(cli("synthesize", files / "graph.h5", "-o", out, "-n", 3, "-m", 60,
                                      "--start", "a:0", "--end", f"b:{CYCLE - 1}", "--json")).stdout)
    sources, seams = sources_of(out)
    assert np.all(sources[:, :, 0] == 0) and np.all(sources[:, :, -1] == 2 * CYCLE - 1)  # a's first, b's last
    # The file maps its global frames back to clips: the clip table is carried forward.
    skin = read_skin(str(out))
    clips = Clips(skin.clip_names, skin.clip_frames)
    assert clips == Clips(("a", "b"), (CYCLE, CYCLE))
    # Seams counted by the clip-aware rule (a's last frame then b's first is one).
    assert seams.tolist() == clips.seams(sources).sum(axis=(0, 2)).tolist()
    assert report["transitions_used"] == int(seams.sum())
    # The summary per clip: coverage of each clip, transitions taken from each clip to each.
    assert [sorted(shares) for shares in report["coverage_per_clip"]] == [["a", "b"]] * report["components"]
    for shares, component in zip(report["coverage_per_clip"], sources):
        played = np.unique(component)
        assert shares["a"] == pytest.approx(np.mean(np.isin(np.arange(CYCLE), played)), abs=1e-4)
        assert shares["b"] == pytest.approx(np.mean(np.isin(np.arange(CYCLE, 2 * CYCLE), played)), abs=1e-4)
    for used, total in zip(report["transitions_between"], report["transitions_used_per_component"]):
        assert sorted(used) == ["a->a", "a->b", "b->a", "b->b"] and sum(used.values()) == total
    # Every walk starts in a and ends in b: each went from a to b at least once.
    assert all(used["a->b"] >= 3 for used in report["transitions_between"])
    # The plain global numbers (the options' old names) are the same request: the same animations.
    assert_ok(cli("synthesize", files / "graph.h5", "-o", tmp_path / "plain.h5", "-n", 3, "-m", 60,
                  "--start-frame", 0, "--end-frame", 2 * CYCLE - 1, "-q"))
    assert np.array_equal(sources_of(tmp_path / "plain.h5")[0], sources)
    text = assert_ok(cli("synthesize", files / "graph.h5", "-o", tmp_path / "t.h5", "-n", 2, "-m", 60,
                         "--start", "a:0", "--end", "b:-1")).stdout
    assert "frames played per clip a " in text and "a→b" in text


def test_targets_name_frames_of_clips_and_plots_mark_seams_by_clip(files, tmp_path):
    out = tmp_path / "s.h5"
    assert_ok(cli("synthesize", files / "graph.h5", "-o", out, "-n", 2, "-m", 50, "--target", "b:5@20",
                  "--target", "3@38", "--plot", tmp_path / "plots", "--plot-count", 1, "--device", "cpu", "-q"))
    sources, _ = sources_of(out)
    assert np.all(sources[:, :, 20] == CYCLE + 5) and np.all(sources[:, :, 38] == 3)
    assert sorted(p.name for p in (tmp_path / "plots").iterdir() if p.suffix == ".png") == ["animation_0000.png"]


@pytest.mark.parametrize("option, value, needles", [
    ("--start", "c:0", ("--start", "'c'", "a, b")),
    ("--end", "gallop:3", ("--end", "a, b")),
    ("--target", "c:1@4", ("--target", "a, b")),
    ("--start", f"b:{CYCLE}", ("--start", "'b' has frames 0..19")),
    ("--end-frame", 2 * CYCLE, ("--end", "outside the 40 frames")),
])
def test_an_unknown_clip_or_frame_is_one_line_naming_the_option(files, tmp_path, option, value, needles):
    assert_user_error(cli("synthesize", files / "graph.h5", "-o", tmp_path / "s.h5", "-n", 2, "-m", 30, option, value),
                      *needles, folder=tmp_path)


@pytest.mark.slow
def test_the_horse_gallops_then_collapses(horse_clips, tmp_path):
    _, skin, _ = horse_clips
    assert_ok(cli("build-graph", skin, "-o", tmp_path / "graph.h5", "-q"))
    report = json.loads(assert_ok(cli("synthesize", tmp_path / "graph.h5", "-o", tmp_path / "s.h5", "-n", 4,
                                      "-m", 240, "--start", "gallop:0", "--end", "collapse:52", "--json")).stdout)
    sources, _ = sources_of(tmp_path / "s.h5")
    assert np.all(sources[:, :, 0] == 0) and np.all(sources[:, :, -1] == 48 + 52)
    assert all(used["gallop->collapse"] >= 4 for used in report["transitions_between"])
    assert all(set(shares) == {"gallop", "collapse"} for shares in report["coverage_per_clip"])
