"""select-controls, train-kcca and evaluate on a skin file of several clips (issue 26): --clips
chooses the frames, sampling runs within each clip, evaluate --hold-out-clip trains on the other
clips and tests on the held-out one, and a one-clip file reads as before."""

import json

import h5py
import numpy as np
import pytest

from skinsynth.formats.puppet_file import read_puppet
from skinsynth.formats.skin_file import read_skin
from skinsynth.formats.meshseq import write_array_sequence
from skinsynth.pipeline.inputs.examples import bending_bar
from skinsynth.pipeline.puppet import evaluate_puppet, puppet_from_record, select_controls

from cli_helpers import assert_folder_holds, assert_ok, assert_user_error, cli

#: Frames of the two clips: "bend" (a bend-and-twist cycle) and "curl" (the other way, twisting more).
BEND, CURL = 18, 14


@pytest.fixture(scope="module")
def two_clips(tmp_path_factory):
    """skin.h5 of the clips bend (frames 0–17) and curl (18–31) of one bar, controls.h5 (defaults)
    and puppet.h5 (defaults), and the clips' own vertices."""
    folder = tmp_path_factory.mktemp("puppet_clips")
    bend, faces = bending_bar(frames=BEND, rings=10, segments=8)
    curl, _ = bending_bar(frames=CURL, rings=10, segments=8, bend=-1.2, twist=1.5)
    write_array_sequence(folder / "bend.npz", bend, faces, 24.0)
    write_array_sequence(folder / "curl.npz", curl, faces, 24.0)
    assert_ok(cli("fit-skin", f"bend={folder / 'bend.npz'}", f"curl={folder / 'curl.npz'}", "-o", folder / "skin.h5",
                  "--bones", 4, "--iterations", 8, "-q"))
    assert_ok(cli("select-controls", folder / "skin.h5", "-o", folder / "controls.h5", "--count", 6, "-q"))
    assert_ok(cli("train-kcca", folder / "controls.h5", "-o", folder / "puppet.h5", "-q"))
    return folder, {"bend": bend, "curl": curl}


def test_every_clip_by_default_sampled_within_each(two_clips):
    folder, _ = two_clips
    with h5py.File(folder / "controls.h5") as f:
        assert list(f["controls"].attrs["clips"]) == ["bend", "curl"]
    with h5py.File(folder / "puppet.h5") as f:
        training = f["training"]
        assert list(training.attrs["clips"]) == ["bend", "curl"]
        # every:4 from each clip's first frame: 0, 4 … 16, then 18, 22, 26, 30 (not 20, 24, 28)
        assert training["train_frames"][()].tolist() == [0, 4, 8, 12, 16, 18, 22, 26, 30]
        assert training["test_frames"][()].tolist() == [f for f in range(BEND + CURL)
                                                        if f not in (0, 4, 8, 12, 16, 18, 22, 26, 30)]


def test_clips_chooses_the_frames_of_controls_and_training(two_clips, tmp_path):
    folder, clips = two_clips
    out = json.loads(assert_ok(cli("select-controls", folder / "skin.h5", "-o", tmp_path / "c.h5", "--count", 6,
                                   "--clips", "bend", "--json")).stdout)
    assert out["clips"] == ["bend"] and out["frames"] == BEND
    # the same controls as chosen from the bend clip's own vertices, the other clip unseen
    skin = read_skin(str(folder / "skin.h5"))
    alone = select_controls(clips["bend"], skin.rest_vertices, count=6)
    with h5py.File(tmp_path / "c.h5") as f:
        assert f["controls/vertex_indices"][()].tolist() == alone.indices.tolist()
        assert list(f["controls"].attrs["clips"]) == ["bend"]
    summary = json.loads(assert_ok(cli("train-kcca", tmp_path / "c.h5", "-o", tmp_path / "p.h5", "--clips", "bend",
                                       "--json")).stdout)
    assert summary["clips"] == ["bend"] and summary["train_frames"] == 5 and summary["test_frames"] == BEND - 5
    record, test_frames, _ = read_puppet(str(tmp_path / "p.h5"))
    assert record.train_frames.tolist() == [0, 4, 8, 12, 16] and record.training_clips == ("bend",)
    assert test_frames.tolist() == [f for f in range(BEND) if f % 4]  # curl's frames: neither
    # the curl alone: global ids from its first frame
    assert_ok(cli("train-kcca", tmp_path / "c.h5", "-o", tmp_path / "q.h5", "--clips", "curl", "-q"))
    record, test_frames, _ = read_puppet(str(tmp_path / "q.h5"))
    assert record.train_frames.tolist() == [18, 22, 26, 30] and test_frames.tolist() == [
        f for f in range(BEND, BEND + CURL) if (f - BEND) % 4]


def test_hold_out_clip_trains_on_the_others_and_tests_the_clip(two_clips, tmp_path):
    folder, _ = two_clips
    out = json.loads(assert_ok(cli("evaluate", folder / "puppet.h5", "--hold-out-clip", "curl", "--json")).stdout)
    unseen = out["clip_hold_out"]
    assert unseen["train_clips"] == ["bend"] and unseen["test_clips"] == ["curl"]
    assert unseen["train_frames"] == list(range(BEND))  # what the retrained puppet holds
    assert unseen["test_frames"] == list(range(BEND, BEND + CURL))
    assert out["clips"] == ["bend", "curl"]
    # the same numbers as a puppet trained by hand on every bend frame and tested on the curl's
    assert_ok(cli("train-kcca", folder / "controls.h5", "-o", tmp_path / "bend.h5", "--clips", "bend",
                  "--train-frames", "all", "-q"))
    record, _, skin = read_puppet(str(tmp_path / "bend.h5"))
    assert record.train_frames.tolist() == list(range(BEND))
    by_hand = evaluate_puppet(puppet_from_record(record), skin.examples, np.arange(BEND, BEND + CURL))
    for method in ("kcca", "kcca_no_translation_solver", "pca_blendshape", "rbf"):
        assert np.isclose(unseen[method], by_hand.overall[method], rtol=1e-9, atol=0.0), method
    text = assert_ok(cli("evaluate", folder / "puppet.h5", "--hold-out-clip", "bend")).stdout
    assert "clip hold-out: trained on curl (14 frames), tested on bend (18 frames)" in text
    assert text.count("pca_blendshape") == 2 and text.count("rbf") == 2


@pytest.mark.parametrize("command,args,needles", [
    ("select-controls", ("--clips", "gallop"), ["--clips", "'gallop'", "bend, curl"]),
    ("train-kcca", ("--clips", "bend,gallop"), ["--clips", "'gallop'", "bend, curl"]),
    ("train-kcca", ("--clips", "curl", "--train-frames", "0,20"), ["--train-frames", "frame 0", "'bend'"]),
], ids=["select-controls", "train-kcca", "train-kcca-list"])
def test_unknown_clip_is_one_line(two_clips, tmp_path, command, args, needles):
    folder, _ = two_clips
    source = folder / ("skin.h5" if command == "select-controls" else "controls.h5")
    assert_user_error(cli(command, source, "-o", tmp_path / "out.h5", *args), *needles, folder=tmp_path)


def test_evaluate_refuses_an_unknown_or_the_only_clip(two_clips, tmp_path):
    folder, _ = two_clips
    assert_user_error(cli("evaluate", folder / "puppet.h5", "--hold-out-clip", "gallop"), "--hold-out-clip",
                      "'gallop'", "bend, curl")
    assert_user_error(cli("evaluate", folder / "puppet.h5", "--hold-out-clip", "bend,curl"), "--hold-out-clip",
                      "no clip to train on")
    assert_ok(cli("train-kcca", folder / "controls.h5", "-o", tmp_path / "bend.h5", "--clips", "bend", "-q"))
    assert_user_error(cli("evaluate", tmp_path / "bend.h5", "--hold-out-clip", "bend"), "no clip to train on",
                      "trained on bend")
    assert_folder_holds(tmp_path, ["bend.h5"])


def test_a_one_clip_file_trains_as_before(stage_files):
    """A one-clip file: every:4 over all frames as parse_frame_spec gave it, and its clip recorded."""
    files = stage_files(frames=24, bones=4, iterations=8, controls=("--count", 6), puppet=())
    record, test_frames, skin = read_puppet(str(files / "puppet.h5"))
    assert record.train_frames.tolist() == list(range(0, 24, 4)) and test_frames.tolist() == [
        f for f in range(24) if f % 4]
    assert record.training_clips == skin.clip_names and len(skin.clip_names) == 1


@pytest.mark.slow
def test_horse_trained_on_the_gallop_tested_on_the_collapse(horse_clips, tmp_path):
    """The real two-clip horse (22 bones): evaluate --hold-out-clip collapse trains on the gallop's
    48 frames and reports KCCA and the baselines on the collapse's 53. The puppet is trained on the
    gallop alone (--clips gallop: what the hold-out retrains, whatever the puppet's clips) at the
    width and prior cross-validation picks on it (1σ, 1), correctives off, so the retraining
    cross-validates nothing (the defaults' own choices are tested in test_real_data.py). Measured:
    KCCA 0.167 (0.153 with every choice cross-validated), PCA blendshapes 0.250, RBF 2.89 of the
    rest diagonal (0.201, 0.184, 0.301, 3.47 of the largest side, 1.20 times shorter)."""
    _, skin, _ = horse_clips
    assert_ok(cli("select-controls", skin, "-o", tmp_path / "controls.h5", "-q"))
    assert_ok(cli("train-kcca", tmp_path / "controls.h5", "-o", tmp_path / "puppet.h5", "--clips", "gallop",
                  "--kernel-width", 1, "--translation-prior", 1, "--correctives", "off", "-q"))
    out = json.loads(assert_ok(cli("evaluate", tmp_path / "puppet.h5", "--hold-out-clip", "collapse",
                                   "--json")).stdout)
    unseen = out["clip_hold_out"]
    assert unseen["train_clips"] == ["gallop"] and unseen["test_clips"] == ["collapse"]
    assert unseen["train_frames"] == list(range(48)) and unseen["test_frames"] == list(range(48, 101))
    for method in ("kcca", "kcca_no_translation_solver", "pca_blendshape", "rbf"):
        assert 0.0 < unseen[method] < np.inf, method
    assert unseen["kcca"] < unseen["pca_blendshape"] < unseen["rbf"]
