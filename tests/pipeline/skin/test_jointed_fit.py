"""The skeleton-constrained fit (Le & Deng 2014 §5): forward kinematics against plain LBS, exact
recovery of an exactly jointed skin, joints held to rounding."""

import numpy as np
import pytest

from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.inputs.examples import walker
from skinsynth.pipeline.mesh.geometry import bounding_box_diagonal, points_inside
from skinsynth.pipeline.rig.rotations import rotation_exp
from skinsynth.pipeline.skin.joints import Skeleton, find_skeleton
from skinsynth.pipeline.skin.jointed_fit import chain_coefficients, fit_jointed, world_transforms


def _held(rotations, translations, skeleton):
    """Largest distance between where a jointed bone and its parent put its joint."""
    worst = 0.0
    for b in np.flatnonzero(skeleton.jointed):
        p, q = skeleton.parents[b], skeleton.joints[b]
        gap = (np.einsum("fxy,y->fx", rotations[:, b] - rotations[:, p], q) + translations[:, b]
               - translations[:, p])
        worst = max(worst, float(np.abs(gap).max()))
    return worst


def test_the_chain_coefficients_are_linear_blend_skinning_of_the_forward_kinematics():
    rng = np.random.default_rng(0)
    bones, count, frames = 6, 40, 5
    parents, jointed = np.array([-1, 0, 1, 0, 3, 0]), np.array([False, True, True, True, True, False])
    joints, rest = rng.normal(size=(bones, 3)), rng.normal(size=(count, 3))
    weights = rng.random((count, bones))
    weights /= weights.sum(axis=1, keepdims=True)
    R = rotation_exp(rng.normal(size=(frames, bones, 3)))
    T = rng.normal(size=(frames, 2, 3))  # the root's and the free bone's translations
    s, a = chain_coefficients(rest, weights, parents, jointed, joints)
    model = np.einsum("va,fax->fvx", s, T) + np.einsum("fkxy,vky->fvx", R, a)
    world_R, world_t = world_transforms(R, T, parents, jointed, joints)
    skinned = np.einsum("vk,fkxy,vy->fvx", weights, world_R, rest) + np.einsum("vk,fkx->fvx", weights, world_t)
    assert np.abs(model - skinned).max() < 1e-12
    assert _held(world_R, world_t, Skeleton(parents, jointed, joints, np.zeros(bones))) < 1e-12


@pytest.fixture(scope="module")
def jointed_walker():
    vertices, faces, rig = walker(rig=True)
    order = np.argsort(-rig.weights, axis=1, kind="stable")[:, :4]
    return vertices, faces, rig, order, np.take_along_axis(rig.weights, order, axis=1)


def test_an_exactly_jointed_skin_is_recovered_from_disturbed_bones(jointed_walker):
    vertices, faces, rig, indices, weights = jointed_walker
    skeleton = find_skeleton(rig.rest, faces, indices, weights, rig.rotations, rig.translations, root=0)
    disturbed = rotation_exp(np.random.default_rng(2).normal(scale=0.05, size=rig.rotations.shape[:2] + (3,)))
    fit, fitted = fit_jointed(vertices, rig.rest, indices, weights, disturbed @ rig.rotations, skeleton,
                              faces=faces, iterations=60, tolerance=0.0)
    skinned = lbs_reference(rig.rest, fit.bone_indices, fit.bone_weights, fit.rotations, fit.translations)
    diagonal = bounding_box_diagonal(rig.rest)
    assert np.sqrt(np.mean(np.sum((skinned - vertices) ** 2, axis=2))) / diagonal < 1e-5
    assert _held(fit.rotations, fit.translations, fitted) < 1e-10 * diagonal
    assert np.abs(fitted.joints[1:] - rig.joints[1:]).max() < 1e-3 * diagonal
    assert fitted.parents.tolist() == rig.parents.tolist()


def test_the_jointed_fit_holds_its_joints_inside_the_body_and_never_worsens_with_joints_fixed(jointed_walker):
    vertices, faces, rig, indices, weights = jointed_walker
    noisy = vertices + np.random.default_rng(3).normal(scale=2e-3, size=vertices.shape)
    skeleton = find_skeleton(rig.rest, faces, indices, weights, rig.rotations, rig.translations, root=0)
    fit, fitted = fit_jointed(noisy, rig.rest, indices, weights, rig.rotations, skeleton, faces=faces, iterations=8,
                              tolerance=0.0)
    assert points_inside(fitted.joints[fitted.jointed], rig.rest, faces).all()
    assert _held(fit.rotations, fit.translations, fitted) < 1e-10
    frozen, _ = fit_jointed(noisy, rig.rest, indices, weights, rig.rotations, skeleton, iterations=8, tolerance=0.0,
                            move_joints=False)
    assert np.all(np.diff(frozen.error_history) <= 1e-12 * frozen.error_history[0])


def test_the_rig_normal_equations_are_the_gauss_newton_system_formed_vertex_by_vertex():
    """H = Σ_i J_iᵀ J_i, g = Σ_i J_iᵀ e_i with J_i = [−[y_ik]× per bone | s_ia I per anchor] and e_i the
    residual, from the chain coefficients directly; against the sums' compiled system."""
    from skinsynth.pipeline.skin.bone_transforms import Trajectories
    from skinsynth.pipeline.skin.jointed_fit import _Products
    from skinsynth.pipeline.skin.rig_normal_equations import normal_equations

    rng = np.random.default_rng(1)
    bones, count, frames = 6, 50, 4
    parents, jointed = np.array([-1, 0, 1, 0, 3, 0]), np.array([False, True, True, True, True, False])
    joints, rest = rng.normal(size=(bones, 3)), rng.normal(size=(count, 3))
    weights = rng.random((count, bones)) * (rng.random((count, bones)) < 0.6)
    weights[np.arange(count), rng.integers(0, bones, count)] += 0.5
    weights /= weights.sum(axis=1, keepdims=True)
    vertices = rng.normal(size=(frames, count, 3))
    R, T = rotation_exp(rng.normal(size=(frames, bones, 3))), rng.normal(size=(frames, 2, 3))
    sums = _Products(Trajectories(vertices, rest), np.tile(np.arange(bones), (count, 1)), weights, parents,
                     jointed).sums(joints)
    n = 3 * (bones + 2)
    H, g = np.empty((frames, n, n)), np.empty((frames, n))
    normal_equations(*(np.ascontiguousarray(x) for x in (R, sums.gram_flat, sums.anchor_cross, sums.anchor_gram,
                                                         sums.cross, sums.anchor_vertices, T)), H, g)
    s, a = chain_coefficients(rest, weights, parents, jointed, joints)
    y = np.einsum("fkxy,vky->fvkx", R, a)  # (F, V, B, 3)
    residual = vertices - np.einsum("va,fax->fvx", s, T) - y.sum(axis=2)
    skew = np.zeros(y.shape + (3,))
    skew[..., 0, 1], skew[..., 0, 2], skew[..., 1, 2] = -y[..., 2], y[..., 1], -y[..., 0]
    skew -= np.swapaxes(skew, -1, -2)
    J = np.concatenate([-skew.transpose(0, 1, 3, 2, 4).reshape(frames, count, 3, 3 * bones),
                        np.einsum("va,xw->vxaw", s, np.eye(3)).reshape(1, count, 3, 6).repeat(frames, 0)], axis=3)
    expected_H = np.einsum("fvxi,fvxj->fij", J, J)
    expected_g = np.einsum("fvxi,fvx->fi", J, residual)
    scale = np.abs(expected_H).max()
    assert np.abs(H - expected_H).max() < 1e-11 * scale
    assert np.abs(g - expected_g).max() < 1e-11 * np.abs(expected_g).max()
