"""select-controls → train-kcca → evaluate from the command line, and their bad inputs."""

import json

import h5py
import numpy as np
import pytest

from cli_helpers import assert_folder_holds, assert_ok, assert_user_error, cli


@pytest.fixture(scope="module")
def files(stage_files):
    return stage_files(frames=24, bones=4, iterations=8, controls=("--count", 6), puppet=()).folder


def test_pipeline_and_evaluate_json(files, tmp_path):
    result = json.loads(assert_ok(cli("evaluate", files / "puppet.h5", "--json", "--plot", tmp_path / "e.png")).stdout)
    for key in ("kcca", "kcca_no_translation_solver", "pca_blendshape", "rbf", "test_frames", "global_motion"):
        assert key in result
    assert result["test_frames"] == [f for f in range(24) if f % 4]
    assert all(0.0 <= result[k] < 0.05 for k in ("kcca", "pca_blendshape", "rbf"))
    assert (tmp_path / "e.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    from skinsynth.pipeline.puppet.poisson import PRIOR_GRID

    assert result["translation_prior"] in PRIOR_GRID  # cross-validated by default
    text = assert_ok(cli("evaluate", files / "puppet.h5")).stdout
    assert "control-frame" in text and "kcca" in text
    summary = json.loads(assert_ok(cli("inspect", files / "puppet.h5", "--json")).stdout)
    assert summary["stage"] == "puppet" and [p["stage"] for p in summary["provenance"]] == ["skin", "controls", "puppet"]


def test_translation_prior_given_is_stored_and_used(files, tmp_path):
    assert_ok(cli("train-kcca", files / "controls.h5", "-o", tmp_path / "p5.h5", "--translation-prior", "5", "-q"))
    with h5py.File(tmp_path / "p5.h5") as f:
        assert f["poisson"].attrs["prior"] == 5.0 and "user" in f["poisson"].attrs["prior_reason"]
    result = json.loads(assert_ok(cli("evaluate", tmp_path / "p5.h5", "--json")).stdout)
    assert result["translation_prior"] == 5.0


def test_train_kcca_is_deterministic(files, tmp_path):
    assert_ok(cli("train-kcca", files / "controls.h5", "-o", tmp_path / "again.h5", "-q"))
    with h5py.File(files / "puppet.h5") as a, h5py.File(tmp_path / "again.h5") as b:
        for name in ("kcca/predictor", "kcca/bias", "poisson/rotation_operator", "poisson/control_operator"):
            assert a[name][()].tobytes() == b[name][()].tobytes()


@pytest.mark.parametrize("args,needles", [
    (["--kernel", "cubic"], ["--kernel", "cubic"]),
    (["--train-frames", "first:3"], ["3 training frames"]),
    (["--train-frames", "every:0"], ["--train-frames"]),
    (["--regularization", "lots"], ["--regularization"]),
    (["--bases", "0"], ["--bases"]),
    (["--beta", "0"], ["--beta"]),
    (["--translation-prior", "strong"], ["--translation-prior"]),
    (["--translation-prior", "-1"], ["--translation-prior"]),
], ids=["kernel", "too-few-frames", "bad-spec", "regularization", "bases", "beta", "prior-word", "prior-negative"])
def test_train_kcca_bad_options(files, tmp_path, args, needles):
    assert_user_error(cli("train-kcca", files / "controls.h5", "-o", tmp_path / "p.h5", *args), *needles,
                      folder=tmp_path)


def test_train_kcca_refuses_a_skin_file(files, tmp_path):
    assert_user_error(cli("train-kcca", files / "skin.h5", "-o", tmp_path / "p.h5"), "skin.h5", "'skin'",
                      "select-controls", folder=tmp_path)


def test_evaluate_refuses_other_stages_and_all_training(files, tmp_path):
    assert_user_error(cli("evaluate", files / "controls.h5"), "controls.h5", "train-kcca")
    assert_ok(cli("train-kcca", files / "controls.h5", "-o", tmp_path / "all.h5", "--train-frames", "all", "-q"))
    assert_user_error(cli("evaluate", tmp_path / "all.h5"), "no held-out frames")
    assert_user_error(cli("evaluate", files / "puppet.h5", "--plot", tmp_path / "e.pdf"), ".png")
    assert_folder_holds(tmp_path, ["all.h5"])


def test_evaluate_extrapolates_with_the_puppets_own_options(files, tmp_path):
    """--extrapolate retrains with train-kcca's recorded options on the first frames and tests on
    the rest: the same as training that split by hand."""
    out = json.loads(assert_ok(cli("evaluate", files / "puppet.h5", "--json", "--extrapolate", 0.75)).stdout)
    beyond = out["extrapolation"]
    assert beyond["train_frames"] == 18 and beyond["test_frames"] == list(range(18, 24))
    assert_ok(cli("train-kcca", files / "controls.h5", "-o", tmp_path / "first.h5", "--train-frames", "first:18", "-q"))
    by_hand = json.loads(assert_ok(cli("evaluate", tmp_path / "first.h5", "--json")).stdout)
    for key in ("kcca", "kcca_no_translation_solver", "pca_blendshape", "rbf"):
        assert beyond[key] == pytest.approx(by_hand[key], rel=1e-9)
    text = assert_ok(cli("evaluate", files / "puppet.h5", "--extrapolate", 0.75)).stdout
    assert "extrapolation: trained on frames 0..17, tested on the 6 after" in text
    for bad in (0.0, 1.0, 0.1):
        assert_user_error(cli("evaluate", files / "puppet.h5", "--extrapolate", bad), "--extrapolate")


@pytest.mark.parametrize("correctives", ["off", "1e-4", "tail"])
def test_the_documented_numpy_recipe_reproduces_predict_vertices(files, tmp_path, correctives):
    """docs/format.md's third-party implementation (h5py and numpy only), run as written, on a
    puppet without correctives, with them, and with a power and an affine tail written in."""
    import pathlib
    import re

    from skinsynth.formats.puppet_file import read_puppet

    from skinsynth.pipeline.puppet import puppet_from_record
    from skinsynth.pipeline.puppet.puppet import predict_vertices

    path = tmp_path / "puppet.h5"
    assert_ok(cli("train-kcca", files / "controls.h5", "-o", path, "-q", "--correctives",
                  "1e-4" if correctives == "tail" else correctives))
    if correctives == "tail":
        rng = np.random.default_rng(0)
        with h5py.File(path, "r+") as f:
            n_p, d = f["kcca/training_controls"].shape
            f["correctives"].attrs["power"] = 4.0
            f["correctives"].create_dataset("tail", data=rng.normal(size=(n_p, 4)))
            f["correctives"].create_dataset("axes", data=np.linalg.qr(rng.normal(size=(d, 3)))[0].T)
    text = (pathlib.Path(__file__).parents[2] / "docs" / "format.md").read_text()
    section = text[text.index("## Evaluating a puppet in numpy"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1).replace("bar.puppet.h5", str(path))
    namespace = {}
    exec(compile(code, "docs/format.md", "exec"), namespace)
    record, test_frames, skin = read_puppet(str(path))
    puppet = puppet_from_record(record)
    assert (puppet.correctives is None) == (correctives == "off")
    controls = skin.examples[:, puppet.control_indices]
    expected = predict_vertices(puppet, controls)
    got = np.stack([namespace["evaluate"](c) for c in controls])
    assert np.abs(got - expected).max() < 1e-9 * np.ptp(skin.rest_vertices, axis=0).max()
