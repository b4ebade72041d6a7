"""A puppet trained for linear blend skinning (train-kcca --skinning linear, issue 23 part 5): its
correctives invert each vertex's linear-blend map, its cross-validation scores what LBS plays, and
every later command (evaluate, play, preview) plays it linearly unless told otherwise."""

import numpy as np

from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.puppet.correctives import (LINEAR_RIDGE, Model, blend_operator, cross_validated_errors,
                                                   linear_vertex_maps, rest_offsets)
from skinsynth.pipeline.puppet.puppet import predict_vertices, train_puppet
from skinsynth.pipeline.rig.rotations import dual_quaternion_to_rigid

from rigs import random_skin
from puppet_cases import CONTROLS, bulging_tube, random_dual_quaternions


def _lbs(rest, idx, w, dq, offsets=None):
    rotations, translations = dual_quaternion_to_rigid(dq)
    return lbs_reference(rest, idx, w, rotations, translations, offsets)


def test_linear_rest_offsets_make_lbs_reproduce_any_target():
    rng = np.random.default_rng(0)
    rest, idx, w = random_skin(rng, 300, 6, 4)
    dq = random_dual_quaternions(rng, 5, 6)
    targets = rng.normal(size=(5, 300, 3))
    offsets = rest_offsets(rest, idx, w, dq, targets, skinning="linear")
    maps = linear_vertex_maps(idx, w, dq)[0]
    smallest = np.linalg.svd(maps, compute_uv=False)[..., -1]
    error = np.linalg.norm(_lbs(rest, idx, w, dq, offsets) - targets, axis=-1)
    residual = np.linalg.norm(targets - _lbs(rest, idx, w, dq), axis=-1)
    # the ridge ε biases the solve by about ε/σ_min² of the residual
    assert np.all(error <= 2 * LINEAR_RIDGE / smallest ** 2 * residual + 1e-12)
    assert np.median(error / residual) < 1e-5


def test_linear_vertex_maps_are_the_lbs_of_a_point():
    rng = np.random.default_rng(1)
    rest, idx, w = random_skin(rng, 50, 5, 3)
    dq = random_dual_quaternions(rng, 3, 5)
    maps, shifts = linear_vertex_maps(idx, w, dq)
    assert np.abs(np.einsum("fvij,vj->fvi", maps, rest) + shifts - _lbs(rest, idx, w, dq)).max() < 1e-12


def test_a_collapsed_vertex_map_gives_a_bounded_offset():
    """Two bones half a turn apart, weights ½ each: A = 0 along two axes (the candy wrapper); no
    offset can reach the target there, and the regularised inverse keeps the offset finite."""
    rest = np.zeros((1, 3))
    idx, w = np.array([[0, 1]]), np.array([[0.5, 0.5]])
    dq = np.zeros((1, 2, 8))
    dq[0, 0, 0] = 1.0  # identity
    dq[0, 1, 1] = 1.0  # half a turn about x
    offsets = rest_offsets(rest, idx, w, dq, np.array([[[0.0, 1.0, 1.0]]]), skinning="linear")
    assert np.all(np.isfinite(offsets)) and np.abs(offsets).max() < 1e-12


def test_linear_cross_validated_errors_are_the_posed_errors_brute_force():
    """cross_validated_errors under linear skinning: each model's RMS equals fitting the fold's
    correctives, adding them to the rest pose and skinning the held-out rows with LBS."""
    rng = np.random.default_rng(2)
    n, verts = 10, 40
    rest, idx, w = random_skin(rng, verts, 4, 3)
    x = rng.normal(size=(n, 3))
    kernel = np.exp(-0.5 * np.sum((x[:, None] - x[None]) ** 2, axis=-1))
    targets = rng.normal(size=(n, verts, 3))
    folds = [np.arange(0, n, 2), np.arange(1, n, 2)]
    predictions = [random_dual_quaternions(rng, n, 4) for _ in folds]
    errors = cross_validated_errors(kernel, x, folds, predictions, targets, rest, idx, w, ridges=(1e-3,),
                                    skinning="linear")
    for model in (Model(np.inf), Model(1e-3)):
        total = 0.0
        for test, d in zip(folds, predictions):
            train = np.setdiff1d(np.arange(n), test)
            offsets = rest_offsets(rest, idx, w, d, targets, skinning="linear")
            shift = np.zeros((len(test), verts, 3))
            if np.isfinite(model.ridge):
                a, _ = blend_operator(kernel[np.ix_(train, train)], model.ridge)
                shift = np.einsum("tj,jvc->tvc", kernel[np.ix_(test, train)] @ a.T, offsets[train])
            total += np.sum((_lbs(rest, idx, w, d[test], shift) - targets[test]) ** 2)
        assert abs(errors[model] - np.sqrt(total / (n * verts))) < 1e-9 * errors[model]


def _train(data, train, correctives, skinning):
    return train_puppet(data["vertices"], data["rest"], data["faces"], data["bone_indices"], data["bone_weights"],
                        data["rotations"], data["translations"], CONTROLS, train, global_motion="world",
                        correctives=correctives, skinning=skinning)


def test_a_linear_puppet_with_a_tiny_ridge_reproduces_its_examples_under_lbs():
    data = bulging_tube()
    train = np.arange(0, 40, 2)
    puppet = _train(data, train, 1e-9, "linear")
    assert puppet.skinning == "linear"
    predicted = predict_vertices(puppet, data["vertices"][train][:, CONTROLS])  # the puppet's own: linear
    assert np.abs(predicted - predict_vertices(puppet, data["vertices"][train][:, CONTROLS], skinning="linear")).max() == 0
    # RMS 3.0e-5 (the interpolation's conditioning at ridge 1e-9; the dual-quaternion puppet's 1.5e-6)
    rms = np.sqrt(np.mean(np.sum((predicted - data["vertices"][train]) ** 2, axis=-1)))
    assert rms < 1e-5 * np.ptp(data["rest"], axis=0).max()


def test_linear_correctives_beat_dual_quaternion_correctives_played_linearly():
    """Correctives fitted for DQS and played with LBS miss; fitted for LBS, they do not."""
    data = bulging_tube()
    train, test = np.arange(0, 40, 2), np.arange(1, 40, 2)
    linear, dual = _train(data, train, "auto", "linear"), _train(data, train, "auto", "dual-quaternion")
    controls = data["vertices"][test][:, CONTROLS]

    def rms(puppet, skinning):
        return np.sqrt(np.mean(np.sum((predict_vertices(puppet, controls, skinning=skinning)
                                       - data["vertices"][test]) ** 2, axis=-1)))

    assert rms(linear, "linear") < rms(dual, "linear")
