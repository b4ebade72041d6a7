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


def test_evaluate_measures_over_the_rest_diagonal_as_fit_skin_and_preview_do(files):
    """Issue 68: one error normaliser. evaluate's figures are RMS vertex distances over the rest
    bounding-box diagonal (fit-skin's RMSE and preview's colours use it): RBF's held-out error
    recomputed here from its own prediction, over the diagonal, is the figure printed; the text
    says the unit once."""
    from skinsynth.formats.puppet_file import read_puppet
    from skinsynth.pipeline.mesh.geometry import bounding_box_diagonal
    from skinsynth.pipeline.puppet import puppet_from_record
    from skinsynth.pipeline.puppet.baselines import fit_rbf, predict_rbf

    result = json.loads(assert_ok(cli("evaluate", files / "puppet.h5", "--json")).stdout)
    record, test_frames, skin = read_puppet(files / "puppet.h5")
    puppet = puppet_from_record(record)
    examples = np.asarray(skin.examples, np.float64)
    rbf = fit_rbf(examples[puppet.train_frames], puppet.control_indices, puppet.reference_controls,
                  global_motion=puppet.global_motion)
    predicted = predict_rbf(rbf, examples[test_frames][:, puppet.control_indices])
    rms = np.sqrt(np.mean(np.sum((predicted - examples[test_frames]) ** 2, axis=-1)))
    assert result["rbf"] == pytest.approx(rms / bounding_box_diagonal(puppet.rest_vertices), rel=1e-9)
    assert result["error_over"] == "rest bounding-box diagonal"
    text = assert_ok(cli("evaluate", files / "puppet.h5")).stdout
    assert text.count("over the rest bounding-box diagonal") == 1


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


@pytest.mark.parametrize("skinning", ["dual-quaternion", "linear"])
@pytest.mark.parametrize("correctives", ["off", "1e-4", "tail"])
def test_the_documented_numpy_recipe_reproduces_predict_vertices(files, tmp_path, correctives, skinning):
    """docs/format.md's third-party implementation (h5py and numpy only), run as written, on a
    puppet without correctives, with them, and with a power and an affine tail written in, for
    either skinning."""
    import pathlib
    import re

    from skinsynth.formats.puppet_file import read_puppet

    from skinsynth.pipeline.puppet import puppet_from_record
    from skinsynth.pipeline.puppet.puppet import predict_vertices

    path = tmp_path / "puppet.h5"
    assert_ok(cli("train-kcca", files / "controls.h5", "-o", path, "-q", "--correctives",
                  "1e-4" if correctives == "tail" else correctives, "--skinning", skinning))
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
    assert (puppet.correctives is None) == (correctives == "off") and puppet.skinning == skinning
    controls = skin.examples[:, puppet.control_indices]
    expected = predict_vertices(puppet, controls)
    got = np.stack([namespace["evaluate"](c) for c in controls])
    assert np.abs(got - expected).max() < 1e-9 * np.ptp(skin.rest_vertices, axis=0).max()


def test_a_linear_puppet_is_evaluated_and_played_linearly_by_default(files, tmp_path):
    """train-kcca --skinning linear is recorded; evaluate and play use it unless told otherwise;
    a dual-quaternion puppet to glTF is one line naming --skinning linear."""
    from skinsynth.formats.meshseq import read_played_characters
    from skinsynth.formats.puppet_file import read_puppet
    from skinsynth.pipeline.puppet import predict_vertices, puppet_from_record

    linear = tmp_path / "linear.h5"
    summary = json.loads(assert_ok(cli("train-kcca", files / "controls.h5", "-o", linear, "--skinning", "linear",
                                       "--correctives", "off", "--json")).stdout)
    assert summary["skinning"] == "linear"
    with h5py.File(linear) as f:
        assert f["training"].attrs["skinning"] == "linear"
    evaluated = json.loads(assert_ok(cli("evaluate", linear, "--json")).stdout)
    assert evaluated["skinning"] == "linear"
    dual = json.loads(assert_ok(cli("evaluate", linear, "--json", "--skinning", "dual-quaternion")).stdout)
    assert dual["skinning"] == "dual-quaternion" and dual["kcca"] != evaluated["kcca"]
    assert json.loads(assert_ok(cli("evaluate", files / "puppet.h5", "--json")).stdout)["skinning"] == "linear"  # default

    record, _, skin = read_puppet(str(linear))
    puppet = puppet_from_record(record)
    np.save(tmp_path / "c.npy", skin.examples[:, puppet.control_indices])
    played = json.loads(assert_ok(cli("play", linear, "-c", tmp_path / "c.npy", "-o", tmp_path / "p.h5",
                                      "--json")).stdout)
    assert played["skinning"] == "linear"
    vertices = read_played_characters(str(tmp_path / "p.h5"))[1][0]  # (F, V, 3)
    expected = predict_vertices(puppet, skin.examples[:, puppet.control_indices], skinning="linear")
    assert np.abs(vertices - expected).max() < 1e-5 * np.ptp(skin.rest_vertices, axis=0).max()
    assert_ok(cli("play", linear, "-c", tmp_path / "c.npy", "-o", tmp_path / "p.glb", "-q"))
    assert_ok(cli("train-kcca", files / "controls.h5", "-o", tmp_path / "dual.h5", "--skinning", "dual-quaternion",
                  "-q"))
    assert json.loads(assert_ok(cli("evaluate", tmp_path / "dual.h5", "--json")).stdout)["skinning"] == "dual-quaternion"
    before = sorted(p.name for p in tmp_path.iterdir())
    assert_user_error(cli("play", tmp_path / "dual.h5", "-c", tmp_path / "c.npy", "-o", tmp_path / "d.glb"),
                      "d.glb", "train-kcca --skinning linear", folder=tmp_path, keep=before)


def test_a_puppet_written_before_skinning_was_recorded_is_dual_quaternion(files, tmp_path):
    import shutil

    from skinsynth.formats.puppet_file import read_puppet

    old = tmp_path / "old.h5"
    shutil.copy(files / "puppet.h5", old)
    with h5py.File(old, "r+") as f:
        del f["training"].attrs["skinning"]
    assert read_puppet(str(old))[0].skinning == "dual-quaternion"
    with h5py.File(old, "r+") as f:
        f["training"].attrs["skinning"] = "cubic"
    assert_user_error(cli("evaluate", old), "old.h5", "/training/@skinning", "'cubic'")
