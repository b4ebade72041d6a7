"""fit_bones_to_rig: bone transforms of new frames on a given rig (Dem Bones' bones-only solve)."""

import numpy as np

from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.inputs.examples import synthetic_lbs
from skinsynth.pipeline.mesh.geometry import bounding_box_diagonal
from skinsynth.pipeline.skin.skin_fit import fit_bones_to_rig, fit_skin


def test_exact_lbs_frames_on_their_own_rig_are_recovered():
    truth = synthetic_lbs(bones=6, frames=20, seed=3)
    fit = fit_bones_to_rig(truth["vertices"], truth["rest"], truth["bone_indices"], truth["bone_weights"], 6,
                           iterations=200, tolerance=0.0, patience=5)
    recon = lbs_reference(fit.rest_vertices, fit.bone_indices, fit.bone_weights, fit.rotations, fit.translations)
    error = np.sqrt(np.mean(np.sum((recon - truth["vertices"]) ** 2, axis=2)))
    assert error / bounding_box_diagonal(truth["rest"]) < 1e-5
    assert np.abs(fit.rotations - truth["rotations"]).max() < 1e-4
    assert np.abs(fit.translations - truth["translations"]).max() < 1e-4
    # the rig is kept exactly
    assert np.array_equal(fit.bone_weights, truth["bone_weights"]) and np.array_equal(fit.rest_vertices, truth["rest"])


def test_the_error_never_rises_and_matches_a_reconstruction():
    truth = synthetic_lbs(bones=5, frames=12, seed=1)
    noisy = truth["vertices"] + np.random.default_rng(0).normal(scale=0.01, size=truth["vertices"].shape)
    fit = fit_bones_to_rig(noisy, truth["rest"], truth["bone_indices"], truth["bone_weights"], 5,
                           iterations=30, tolerance=0.0, joint_steps=0)
    assert np.all(np.diff(fit.error_history) <= 1e-12 * fit.error_history[0])
    recon = lbs_reference(fit.rest_vertices, fit.bone_indices, fit.bone_weights, fit.rotations, fit.translations)
    assert np.isclose(np.sqrt(np.mean(np.sum((recon - noisy) ** 2, axis=2))), fit.rmse, rtol=1e-8)


def test_a_take_on_the_rig_of_a_joint_fit_reproduces_that_fit():
    """Frames of the joint fit's own clip, solved again on its rig, are reconstructed at least as well."""
    truth = synthetic_lbs(bones=4, frames=16, seed=5)
    joint = fit_skin(truth["vertices"], 4, iterations=15)
    again = fit_bones_to_rig(truth["vertices"][8:], joint.rest_vertices, joint.bone_indices, joint.bone_weights, 4)
    mine = lbs_reference(joint.rest_vertices, joint.bone_indices, joint.bone_weights, joint.rotations[8:],
                         joint.translations[8:])
    theirs = np.sqrt(np.mean(np.sum((mine - truth["vertices"][8:]) ** 2, axis=2)))
    assert again.rmse <= theirs * (1 + 1e-6)
