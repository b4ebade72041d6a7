"""The fit that keeps the capture's ground contacts (issue 64): pipeline/skin/contact_fit.py against
brute force, closed forms and the generated walker."""

import numpy as np
import pytest

from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.inputs.examples import synthetic_lbs, walker
from skinsynth.pipeline.mesh.contact_measures import character_height, clip_ground
from skinsynth.pipeline.skin.bone_transforms import Trajectories
from skinsynth.pipeline.skin.contact_fit import (NEAR_SHARE, contact_sums, contact_weight, keep_contacts,
                                                 near_ground, playback_feet, weighted_sweep)
from skinsynth.pipeline.skin.skin_fit import fit_skin
from skinsynth.pipeline.skin.transform_sweep import sparse_weighted_sums, sweep_bone_transforms


@pytest.fixture(scope="module")
def model():
    truth = synthetic_lbs(bones=5, frames=12, max_influences=3, rings=16, segments=8, seed=2)
    rng = np.random.default_rng(0)
    near = rng.random(truth["vertices"].shape[:2]) < 0.1
    transforms = np.concatenate([truth["rotations"], truth["translations"][..., None]], axis=-1)
    noisy = truth["vertices"] + rng.normal(scale=0.02, size=truth["vertices"].shape)  # no exact fit
    return truth, near, transforms, noisy


def dense_weights(truth):
    count = truth["rest"].shape[0]
    W = np.zeros((count, truth["rotations"].shape[1]))
    np.put_along_axis(W, truth["bone_indices"].astype(np.int64), truth["bone_weights"], axis=1)
    return W


def weighted_error(transforms, vertices, rest, W, omega):
    u = np.concatenate([rest, np.ones((rest.shape[0], 1))], axis=1)
    fitted = np.einsum("vb,fbij,vj->fvi", W, transforms, u)
    return float(np.sum(omega * np.sum((fitted - vertices) ** 2, axis=-1)))


def test_contact_sums_are_the_brute_force_weighted_sums(model):
    truth, near, _, noisy = model
    bones, weight = truth["rotations"].shape[1], 7.0
    W = dense_weights(truth)
    u = np.concatenate([truth["rest"], np.ones((W.shape[0], 1))], axis=1)
    p, q = sparse_weighted_sums(truth["bone_indices"], truth["bone_weights"], Trajectories(noisy, truth["rest"]), bones)
    extra_p, extra_q, slot = contact_sums(truth["bone_indices"], truth["bone_weights"], noisy, truth["rest"], near,
                                          weight, bones)
    omega = 1.0 + weight * near  # (F, V)
    P = np.einsum("fv,vj,fva,vc->jfac", omega, W, noisy, u)
    Q = np.einsum("fv,vj,vk,vc,vd->fjkcd", omega, W, W, u, u)
    assert np.allclose(p + extra_p, P, rtol=1e-12, atol=1e-10)
    linked = np.flatnonzero(slot >= 0)
    full = np.broadcast_to(q, Q.shape).copy()
    full[:, linked[:, None], linked[None, :]] += extra_q
    assert np.allclose(full, Q, rtol=1e-12, atol=1e-10)


def test_without_near_pairs_the_sweep_is_the_compiled_sweep(model):
    truth, _, transforms, noisy = model
    bones = transforms.shape[1]
    p, q = sparse_weighted_sums(truth["bone_indices"], truth["bone_weights"], Trajectories(noisy, truth["rest"]), bones)
    none = np.zeros(noisy.shape[:2], bool)
    extra_p, extra_q, slot = contact_sums(truth["bone_indices"], truth["bone_weights"], noisy, truth["rest"], none,
                                          5.0, bones)
    assert not extra_p.any() and extra_q.size == 0 and (slot < 0).all()
    start = transforms + np.random.default_rng(1).normal(scale=0.05, size=transforms.shape)
    assert np.allclose(weighted_sweep(start, p, q, extra_q, slot), sweep_bone_transforms(start, p, q), atol=1e-12)


def test_each_bone_update_minimises_the_weighted_error(model):
    # Gauss-Seidel over exact per-bone minimisers: the weighted error never rises, and a second
    # sweep from the first's result changes it by less than the first did.
    truth, near, transforms, noisy = model
    bones, weight = transforms.shape[1], 20.0
    p, q = sparse_weighted_sums(truth["bone_indices"], truth["bone_weights"], Trajectories(noisy, truth["rest"]), bones)
    extra_p, extra_q, slot = contact_sums(truth["bone_indices"], truth["bone_weights"], noisy, truth["rest"], near,
                                          weight, bones)
    W, omega = dense_weights(truth), 1.0 + weight * near
    start = transforms.copy()
    start[..., 3] += 0.1
    errors = [weighted_error(start, noisy, truth["rest"], W, omega)]
    T = start
    for _ in range(3):
        T = weighted_sweep(T, p + extra_p, q, extra_q, slot)
        errors.append(weighted_error(T, noisy, truth["rest"], W, omega))
    assert errors[1] < 0.5 * errors[0] and np.all(np.diff(errors) <= 1e-9 * errors[0])
    assert np.allclose(T[..., :3] @ np.swapaxes(T[..., :3], -1, -2), np.eye(3), atol=1e-9)


def test_exact_lbs_data_stays_exact_under_the_weighting():
    truth = synthetic_lbs(bones=6, frames=30, max_influences=4, width=0.35, seed=1)
    vertices = truth["vertices"]
    fit = fit_skin(vertices, bones=6, max_influences=4, iterations=40, tolerance=1e-6)
    near = np.random.default_rng(3).random(vertices.shape[:2]) < 0.05  # any weighting: the exact fit is its optimum
    kept = keep_contacts(fit, vertices, near)
    played = lbs_reference(kept.rest_vertices, kept.bone_indices, kept.bone_weights, kept.rotations, kept.translations)
    diagonal = np.linalg.norm(np.ptp(vertices[0], axis=0))
    assert np.sqrt(np.mean(np.sum((played - vertices) ** 2, axis=-1))) / diagonal < 1e-4
    assert np.all(kept.bone_weights >= 0.0) and np.allclose(kept.bone_weights.sum(axis=1), 1.0, atol=1e-12)
    assert kept.iterations == fit.iterations + 3 and len(kept.error_history) == len(fit.error_history) + 3


def test_contact_weight_keeps_the_near_pairs_to_their_share():
    assert contact_weight(0.01, 20.0) == 20.0  # the samba's 1 %: the full weight
    for s in (0.033, 0.077, 0.15):
        w = contact_weight(s, 20.0)
        assert 0.0 < w < 20.0
        assert s * (1 + w) / (s * (1 + w) + 1 - s) == pytest.approx(NEAR_SHARE, rel=1e-12)
    assert contact_weight(0.25, 20.0) == 0.0 and contact_weight(0.0, 20.0) == 0.0


def test_near_ground_per_clip_and_none_without_a_ground():
    vertices = np.zeros((4, 3, 3))
    vertices[:, :, 1] = [[0.0, 0.5, 3.0]] * 2 + [[10.0, 10.05, 13.0]] * 2  # two clips, grounds 0 and 10
    near = near_ground(vertices, [0, 2, 4], [0.0, 10.0], 1, height=3.0, band=0.02)
    assert near.tolist() == [[True, False, False]] * 2 + [[True, True, False]] * 2
    assert not near_ground(vertices, [0, 2, 4], [np.nan, np.nan], 1, 3.0).any()


def test_the_walker_fitted_with_too_few_bones_slides_less_with_its_contacts_weighed():
    # Six bones for the planted walker's ten parts: its feet share bones with its shins, and the
    # plain fit's playback slides where the capture stands still (0.24 % of the height at the 95th
    # percentile); weighed toward the ground the fit slides 0.59× as much (0.14 %) at 1.01× the
    # error (the RMSE goal 1.05×; the slide checked at 0.8×, far from either figure).
    vertices, faces = walker(planted=True)
    height = character_height(vertices[0], 1)
    starts = [0, vertices.shape[0]]
    near = near_ground(vertices, starts, [clip_ground(vertices, 1)], 1, height)
    plain = fit_skin(vertices, bones=6, seed=0)
    kept = keep_contacts(plain, vertices, near)
    before, after = playback_feet(plain, vertices, starts, 1), playback_feet(kept, vertices, starts, 1)
    assert after["playback"]["slide_p95"] < 0.8 * before["playback"]["slide_p95"]
    rmse = [np.sqrt(np.mean(np.sum((lbs_reference(f.rest_vertices, f.bone_indices, f.bone_weights, f.rotations,
                                                  f.translations) - vertices) ** 2, axis=-1))) for f in (plain, kept)]
    assert rmse[1] < 1.05 * rmse[0]
    assert before["capture"] == after["capture"]
