"""The puppet's baselines: PCA blendshapes and direct RBF regression, and the error plot."""

import os

import numpy as np
import pytest

from skinsynth.formats.plots import write_error_plot
from skinsynth.pipeline.puppet.alignment import apply_frames
from skinsynth.pipeline.puppet.baselines import (
    fit_pca_blendshape,
    fit_rbf,
    predict_pca_blendshape,
    predict_rbf,
)
from skinsynth.pipeline.errors import OptionError
from skinsynth.pipeline.inputs.examples import bending_bar
from skinsynth.pipeline.rig.rotations import rotation_exp

CONTROLS = np.array([3, 17, 29, 41, 55])


def _rigid_motions(rng, count):
    rotations = rotation_exp(rng.normal(scale=1.0, size=(count, 3)))
    translations = rng.normal(scale=3.0, size=(count, 3))
    return rotations, translations


def _rigid_basis(points):
    """(3n, 6) orthonormal basis of the infinitesimal rigid motions of points (n, 3)."""
    centred = points - points.mean(axis=0)
    columns = []
    for axis in np.eye(3):
        columns.append(np.tile(axis, len(points)))  # translation
        columns.append(np.cross(axis, centred).ravel())  # rotation about the centroid
    q, _ = np.linalg.qr(np.stack(columns, axis=1))
    return q


@pytest.fixture
def subspace():
    """Frames mean + Σ_i w_i B_i with 4 random bases, 60 vertices, controls CONTROLS.

    The bases' control rows are made orthogonal to the rigid motions of the rest controls, so
    every frame's control points are already optimally aligned with the rest ones (Procrustes
    gives the identity): the data lie in the 4-D subspace both in the world and in place, and
    the 3·5 − 6 = 9 non-rigid control coordinates determine the 4 weights.
    """
    rng = np.random.default_rng(7)
    k, vertex_count = 4, 60
    rest = rng.normal(size=(vertex_count, 3))
    bases = rng.normal(scale=0.1, size=(k, vertex_count, 3))
    rigid = _rigid_basis(rest[CONTROLS])
    control_rows = bases[:, CONTROLS].reshape(k, -1)
    bases[:, CONTROLS] = (control_rows - (control_rows @ rigid) @ rigid.T).reshape(k, -1, 3)
    weights = rng.normal(size=(26, k))
    weights[0] = 0.0  # frame 0 is the rest pose
    frames = rest + np.einsum("fk,kvc->fvc", weights, bases)
    return frames[:18], frames[18:], rest[CONTROLS], k


def test_pca_blendshape_is_exact_on_a_linear_subspace(subspace):
    train, test, reference, k = subspace
    model = fit_pca_blendshape(train, CONTROLS, reference, components=k, global_motion="world", ridge=1e-12)
    assert model.bases.shape == (k, 60, 3) and model.mean.shape == (60, 3)
    predicted = predict_pca_blendshape(model, test[:, CONTROLS])
    np.testing.assert_allclose(predicted, test, rtol=0, atol=1e-9)

    # The default ridge (1e-6 of s_max²) biases the weights only slightly on well-posed data.
    default = fit_pca_blendshape(train, CONTROLS, reference, components=k, global_motion="world")
    assert np.abs(predict_pca_blendshape(default, test[:, CONTROLS]) - test).max() < 1e-5


def test_pca_blendshape_control_frame_undoes_rigid_motion(subspace):
    train, test, reference, k = subspace
    rng = np.random.default_rng(11)
    moved_train = apply_frames(*_rigid_motions(rng, len(train)), train)
    moved_test = apply_frames(*_rigid_motions(rng, len(test)), test)

    model = fit_pca_blendshape(moved_train, CONTROLS, reference, components=k, ridge=1e-12)
    predicted = predict_pca_blendshape(model, moved_test[:, CONTROLS])
    np.testing.assert_allclose(predicted, moved_test, rtol=0, atol=1e-9)

    # In world space the same data need many more components and still cannot be matched.
    world = fit_pca_blendshape(moved_train, CONTROLS, reference, components=k, global_motion="world")
    assert np.abs(predict_pca_blendshape(world, moved_test[:, CONTROLS]) - moved_test).max() > 0.1


def test_pca_blendshape_cross_validation_finds_the_true_dimension(subspace):
    train, test, reference, k = subspace
    for global_motion in ("world", "control-frame"):
        model = fit_pca_blendshape(train, CONTROLS, reference, global_motion=global_motion)
        errors = model.cv_errors
        assert model.components == k, errors
        # Candidates run to min(n_p − 1, 2·3n_c) = min(17, 30); the gap at k is many decades.
        assert errors.shape == (17,)
        assert errors[k - 2] > 1e4 * errors[k - 1]
        np.testing.assert_allclose(predict_pca_blendshape(model, test[:, CONTROLS]), test, atol=1e-5)


def test_pca_blendshape_refuses_impossible_options(subspace):
    train, _, reference, _ = subspace
    with pytest.raises(OptionError):
        fit_pca_blendshape(train, CONTROLS, reference, components=len(train))
    with pytest.raises(OptionError):
        fit_pca_blendshape(train, CONTROLS, reference, global_motion="sideways")
    with pytest.raises(OptionError):
        fit_pca_blendshape(train[:2], CONTROLS, reference)  # too few frames to cross-validate


def test_rbf_interpolates_training_frames(subspace):
    train, _, reference, _ = subspace
    rng = np.random.default_rng(5)
    moved = apply_frames(*_rigid_motions(rng, len(train)), train)
    for global_motion, frames in (("world", train), ("control-frame", moved)):
        model = fit_rbf(frames, CONTROLS, reference, global_motion=global_motion)
        np.testing.assert_allclose(predict_rbf(model, frames[:, CONTROLS]), frames, rtol=0, atol=1e-8)


def _bar_split():
    vertices, _ = bending_bar(frames=40, rings=12, segments=8)
    train = np.arange(0, 40, 4)
    test = np.setdiff1d(np.arange(40), train)
    controls = np.array([0, 34, 68, 94])  # one vertex on each of rings 0, 4, 8, 11
    return vertices, train, test, controls


def _rms(a, b):
    return np.sqrt(np.mean(np.sum((a - b) ** 2, axis=-1)))


def test_baselines_generalise_on_the_bending_bar():
    vertices, train, test, controls = _bar_split()
    reference = vertices[0, controls]
    # The deformation to be predicted: held-out frames' RMS displacement from rest (≈ 0.94 on a
    # bar 4 long).
    deformation = _rms(vertices[test], vertices[0])
    rbf = fit_rbf(vertices[train], controls, reference)
    rbf_error = _rms(predict_rbf(rbf, vertices[test][:, controls]), vertices[test])
    pca = fit_pca_blendshape(vertices[train], controls, reference)
    pca_error = _rms(predict_pca_blendshape(pca, vertices[test][:, controls]), vertices[test])
    # Measured (control-frame): RBF 0.0021 (0.22 % of the deformation), PCA with CV-chosen k = 8
    # 0.0049 (0.5 %). The family is one smooth parameter, sampled every 4th frame, so both
    # should interpolate it closely; the bounds leave ~4x headroom for BLAS/LAPACK differences
    # while still failing for any real breakage (predicting the rest pose scores 100 %).
    assert rbf_error < 0.01 * deformation
    assert pca_error < 0.02 * deformation


def test_rbf_survives_a_periodic_clip_that_repeats_its_poses():
    """Training on two copies of a cycle (each pose twice, up to file rounding, as the horse
    gallop holds them) must predict as well as training on one copy."""
    vertices, train, test, controls = _bar_split()
    reference = vertices[0, controls]
    rounding = np.random.default_rng(0).normal(scale=1e-5, size=vertices[train].shape)
    twice = np.concatenate([vertices[train], vertices[train] + rounding])
    once = predict_rbf(fit_rbf(vertices[train], controls, reference), vertices[test][:, controls])
    repeated = predict_rbf(fit_rbf(twice, controls, reference), vertices[test][:, controls])
    assert _rms(repeated, once) < 1e-3 * _rms(vertices[test], vertices[0])


def test_baselines_are_equivariant_under_rigid_motion_in_control_frame_mode():
    vertices, train, test, controls = _bar_split()
    reference = vertices[0, controls]
    moved = apply_frames(*_rigid_motions(np.random.default_rng(2), len(test)), vertices[test])
    for fit, predict in ((fit_rbf, predict_rbf), (fit_pca_blendshape, predict_pca_blendshape)):
        model = fit(vertices[train], controls, reference)
        still = predict(model, vertices[test][:, controls])
        in_motion = predict(model, moved[:, controls])
        # Same frames moved rigidly: the errors against the moved truth are the same.
        np.testing.assert_allclose(
            np.linalg.norm(in_motion - moved, axis=-1), np.linalg.norm(still - vertices[test], axis=-1), atol=1e-9
        )


def test_error_plot_writes_a_png(tmp_path):
    frames = np.arange(1, 40, 2)
    errors = {"puppet": np.linspace(0.01, 0.02, frames.size), "PCA blendshape": np.full(frames.size, 0.03)}
    path = tmp_path / "errors.png"
    write_error_plot(path, frames, errors, "Held-out error", "vertex RMS error")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(data) > 10_000
    assert os.listdir(tmp_path) == ["errors.png"]


def test_the_plots_legend_is_the_overall_rms_evaluate_prints():
    # issue 68: the legend gave the mean of the per-frame RMS, below the overall RMS evaluate prints
    from skinsynth.formats.plots import series_rms
    from skinsynth.pipeline.puppet.evaluation import relative_errors

    rng = np.random.default_rng(0)
    truth = rng.normal(size=(12, 50, 3))
    predicted = truth + rng.normal(scale=np.linspace(0.01, 0.2, 12)[:, None, None], size=truth.shape)
    per_frame, overall = relative_errors(predicted, truth, 2.0)
    assert series_rms(per_frame) == pytest.approx(overall, rel=1e-12)
    assert np.mean(per_frame) < 0.95 * overall  # what the legend said before: far from it


def test_error_plot_refuses_bad_requests(tmp_path):
    with pytest.raises(ValueError, match="png"):
        write_error_plot(tmp_path / "errors.pdf", [0, 1], {"a": [1.0, 2.0]}, "t", "y")
    with pytest.raises(ValueError):
        write_error_plot(tmp_path / "errors.png", [0, 1], {"a": [1.0, 2.0, 3.0]}, "t", "y")
    assert os.listdir(tmp_path) == []


def test_pca_cross_validation_matches_refitting_fold_by_fold():
    vertices, train, _, controls = _bar_split()
    frames, reference = vertices[train], vertices[0, controls]
    model = fit_pca_blendshape(frames, controls, reference)
    for k in range(1, len(frames) - 1):  # a fold of n_p − 1 frames supports up to n_p − 2 components
        squared = 0.0
        for j in range(len(frames)):
            fold = fit_pca_blendshape(np.delete(frames, j, axis=0), controls, reference, components=k)
            squared += np.sum((predict_pca_blendshape(fold, frames[j : j + 1, controls]) - frames[j]) ** 2)
        assert model.cv_errors[k - 1] == pytest.approx(np.sqrt(squared / frames[:, :, 0].size), rel=1e-6)
