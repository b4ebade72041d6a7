"""pipeline.skeleton against closed forms: joint matrices times inverse binds give back the LBS
bone transforms exactly; influences and quantised weights keep their sums."""

import numpy as np
import pytest

from skinsynth.pipeline.rotations import quaternion_to_matrix
from skinsynth.pipeline.skeleton import (float_weights, four_influences, gltf_clip, gltf_rig, inverse_bind_matrices,
                                         joint_locals, quantized_weights)


def random_rotations(rng, shape):
    q = rng.normal(size=shape + (4,))
    return quaternion_to_matrix(q / np.linalg.norm(q, axis=-1, keepdims=True))


def xyzw_to_matrix(q):
    return quaternion_to_matrix(np.concatenate([q[..., 3:], q[..., :3]], axis=-1))


def test_joint_world_times_inverse_bind_is_the_bone_transform():
    rng = np.random.default_rng(0)
    rotations, translations, centres = random_rotations(rng, (7, 5)), rng.normal(size=(7, 5, 3)), rng.normal(size=(5, 3))
    quaternions, locals_ = joint_locals(rotations, translations, centres)
    joint = np.tile(np.eye(4), (7, 5, 1, 1))
    joint[..., :3, :3], joint[..., :3, 3] = xyzw_to_matrix(quaternions), locals_
    skinning = joint @ inverse_bind_matrices(centres)[1:]
    np.testing.assert_allclose(skinning[..., :3, :3], rotations, atol=1e-12)
    np.testing.assert_allclose(skinning[..., :3, 3], translations, atol=1e-12)
    assert (np.sum(quaternions[1:] * quaternions[:-1], axis=-1) >= 0).all()  # one hemisphere per bone


def test_a_moving_root_times_the_bones_locals_is_their_world():
    rng = np.random.default_rng(1)
    rotations, translations, centres = random_rotations(rng, (6, 3)), rng.normal(size=(6, 3, 3)), rng.normal(size=(3, 3))
    root_r, root_t = random_rotations(rng, (6,)), rng.normal(size=(6, 3))
    quaternions, locals_ = joint_locals(rotations, translations, centres, root_r, root_t)
    world_r = np.einsum("fij,fbjk->fbik", root_r, xyzw_to_matrix(quaternions))
    world_t = np.einsum("fij,fbj->fbi", root_r, locals_) + root_t[:, None]
    np.testing.assert_allclose(world_r, rotations, atol=1e-12)
    np.testing.assert_allclose(world_t, np.einsum("fbij,bj->fbi", rotations, centres) + translations, atol=1e-12)


def test_four_influences_are_the_heaviest_shifted_past_the_root_and_sum_to_one():
    indices = np.array([[3, 1, 0, 2, 4], [0, 1, 2, 3, 4]])
    weights = np.array([[0.1, 0.4, 0.0, 0.3, 0.2], [0.5, 0.5, 0.0, 0.0, 0.0]])
    joints, out = four_influences(indices, weights)
    np.testing.assert_array_equal(joints, [[2, 3, 5, 4], [1, 2, 0, 0]])
    np.testing.assert_allclose(out, [[0.4, 0.3, 0.2, 0.1], [0.5, 0.5, 0.0, 0.0]])
    with pytest.raises(ValueError, match="glTF carries 4"):
        four_influences(indices, np.full((2, 5), 0.2))
    joints, out = four_influences(np.array([[2, 0]]), np.array([[0.25, 0.75]]))  # fewer slots: padded
    np.testing.assert_array_equal(joints, [[1, 3, 0, 0]])
    np.testing.assert_allclose(out, [[0.75, 0.25, 0, 0]])


@pytest.mark.parametrize("bits", [8, 16])
def test_quantised_weights_sum_exactly_and_stay_within_a_level(bits):
    rng = np.random.default_rng(bits)
    weights = np.sort(rng.dirichlet(np.ones(4), size=2000), axis=1)[:, ::-1]
    levels = quantized_weights(weights, bits)
    top = (1 << bits) - 1
    assert (levels.astype(np.int64).sum(axis=1) == top).all()
    assert np.abs(levels / top - weights).max() <= 2.5 / top
    assert np.abs(float_weights(weights).astype(np.float64).sum(axis=1) - 1.0).max() < 2e-7


def test_a_z_up_rig_in_centimetres_becomes_y_up_metres():
    rng = np.random.default_rng(2)
    rest = rng.normal(size=(20, 3))
    faces = np.array([[0, 1, 2], [2, 3, 4]])
    indices, weights = np.zeros((20, 1), int), np.ones((20, 1))
    rig = gltf_rig(rest, faces, indices, weights, np.zeros((1, 3)), up_axis="Z", meters_per_unit=0.01)
    np.testing.assert_allclose(rig["positions"], 0.01 * np.stack([rest[:, 0], rest[:, 2], -rest[:, 1]], axis=1))
    rotations, translations = random_rotations(rng, (3, 1)), rng.normal(size=(3, 1, 3))
    clip = gltf_clip("c", rotations, translations, np.zeros((1, 3)), 24.0, up_axis="Z", meters_per_unit=0.01)
    posed = np.einsum("fij,vj->fvi", xyzw_to_matrix(clip["rotations"][:, 0]), rig["positions"]) \
        + clip["translations"][:, 0, None]
    truth = np.einsum("fij,vj->fvi", rotations[:, 0], rest) + translations[:, 0, None]
    np.testing.assert_allclose(posed, 0.01 * np.stack([truth[..., 0], truth[..., 2], -truth[..., 1]], -1), atol=1e-12)
    np.testing.assert_allclose(clip["times"], [0, 1 / 24, 2 / 24])


def test_bone_texels_rotate_as_the_shader_formula_says():
    """rotate(q, r) = r + 2 q.xyz × (q.xyz × r + q.w r) with texel 0, plus texel 1, is R r + t."""
    from skinsynth.pipeline.skeleton import bone_texels, texture_influences

    rng = np.random.default_rng(3)
    rotations, translations = random_rotations(rng, (5, 4)), rng.normal(size=(5, 4, 3))
    texels = bone_texels(rotations, translations)
    r = rng.normal(size=3)
    xyz, w = texels[..., 0, :3], texels[..., 0, 3:]
    shader = r + 2.0 * np.cross(xyz, np.cross(xyz, r) + w * r) + texels[..., 1, :3]
    np.testing.assert_allclose(shader, rotations @ r + translations, atol=1e-12)
    assert (texels[..., 1, 3] == 1.0).all()
    bones, weights = texture_influences(np.array([[2, 0, 1]]), np.array([[0.2, 0.5, 0.3]]))
    np.testing.assert_array_equal(bones, [[0, 1, 2, 0]])
    np.testing.assert_allclose(weights, [[0.5, 0.3, 0.2, 0.0]])
