"""pipeline.skeleton against closed forms: joint matrices times inverse binds give back the LBS
bone transforms exactly; influences and quantised weights keep their sums."""

import numpy as np
import pytest

from skinsynth.pipeline.rig.rotations import quaternion_to_matrix
from skinsynth.pipeline.rig.skeleton import (float_weights, four_influences, gltf_clip, gltf_rig, inverse_bind_matrices,
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
    from skinsynth.pipeline.rig.skeleton import bone_texels, texture_influences

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


# -- a skeleton's tree (fit-skin --skeleton): names, parent-local joints, a glTF rig of it ------------------

#: A tree of 10 bones: the root 0 with three children (a chain 1-2-3; a free bone 4 with a child 5;
#: 6-7, which branches into 8 and 9).
TREE = np.array([-1, 0, 1, 2, 0, 4, 0, 6, 7, 7])
TREE_JOINTED = np.array([False, True, True, True, False, True, True, True, True, True])


def test_joint_names_follow_the_chains_in_depth_first_order():
    from skinsynth.pipeline.rig.skeleton import depth_first, joint_names

    assert joint_names(TREE, TREE_JOINTED) == [
        "chain_00_joint_00", "chain_01_joint_00", "chain_01_joint_01", "chain_01_joint_02",
        "chain_02_joint_00",  # a free bone starts a chain
        "chain_03_joint_00",  # and its child another
        "chain_04_joint_00", "chain_04_joint_01", "chain_05_joint_00", "chain_06_joint_00"]
    assert joint_names(np.array([-1, 0, 1])) == ["chain_00_joint_00", "chain_00_joint_01", "chain_00_joint_02"]
    # the root bone need not be bone 0; children in ascending id, each subtree whole before the next
    assert joint_names(np.array([1, -1, 1, 0])) == ["chain_01_joint_00", "chain_00_joint_00", "chain_02_joint_00",
                                                    "chain_01_joint_01"]
    np.testing.assert_array_equal(depth_first(TREE), [0, 1, 2, 3, 4, 5, 6, 7, 8, 9])
    np.testing.assert_array_equal(depth_first(np.array([1, -1, 1, 0])), [1, 0, 3, 2])
    with pytest.raises(ValueError, match="exactly one root"):
        depth_first(np.array([-1, -1]))
    with pytest.raises(ValueError, match="not a tree"):
        depth_first(np.array([-1, 2, 1]))


def _compose_down(parents, local_r, local_t, root_r, root_t):
    """World matrices (F, B, 4, 4) of a tree's joints from their parent-local transforms."""
    from skinsynth.pipeline.rig.skeleton import depth_first

    frames, bones = local_r.shape[:2]
    local = np.tile(np.eye(4), (frames, bones, 1, 1))
    local[..., :3, :3], local[..., :3, 3] = local_r, local_t
    root = np.tile(np.eye(4), (frames, 1, 1))
    root[:, :3, :3], root[:, :3, 3] = root_r, root_t
    world = np.empty_like(local)
    for bone in depth_first(parents):
        world[:, bone] = (root if parents[bone] < 0 else world[:, parents[bone]]) @ local[:, bone]
    return world


@pytest.mark.parametrize("moving_root", [False, True], ids=["fixed root", "moving root"])
def test_tree_locals_composed_down_the_tree_are_the_joints_world_matrices(moving_root):
    from skinsynth.pipeline.rig.skeleton import tree_local_transforms, tree_locals

    rng = np.random.default_rng(4)
    frames, bones = 6, len(TREE)
    rotations, translations = random_rotations(rng, (frames, bones)), rng.normal(size=(frames, bones, 3))
    centres = rng.normal(size=(bones, 3))
    root_r, root_t = (random_rotations(rng, (frames,)), rng.normal(size=(frames, 3))) if moving_root else \
        (np.tile(np.eye(3), (frames, 1, 1)), np.zeros((frames, 3)))
    root = (root_r, root_t) if moving_root else (None, None)
    local_r, local_t = tree_local_transforms(rotations, translations, centres, TREE, *root)
    world = _compose_down(TREE, local_r, local_t, root_r, root_t)
    np.testing.assert_allclose(world[..., :3, :3], rotations, atol=1e-12)
    np.testing.assert_allclose(world[..., :3, 3], np.einsum("fbij,bj->fbi", rotations, centres) + translations,
                               atol=1e-12)
    quaternions, same_t = tree_locals(rotations, translations, centres, TREE, *root)
    np.testing.assert_allclose(xyzw_to_matrix(quaternions), local_r, atol=1e-12)
    np.testing.assert_array_equal(same_t, local_t)
    assert (np.sum(quaternions[1:] * quaternions[:-1], axis=-1) >= 0).all()
    flat = np.full(bones, -1)  # every bone under the root: the one-root rig's locals
    flat_q, flat_t = tree_locals(rotations, translations, centres, flat, *root)
    want_q, want_t = joint_locals(rotations, translations, centres, *root)
    np.testing.assert_allclose(flat_q, want_q, atol=1e-12)
    np.testing.assert_allclose(flat_t, want_t, atol=1e-12)


def test_a_jointed_bones_local_translation_is_its_constant_bone_vector():
    """The walker's true rig: every joint holds, so each jointed bone's translation local to its
    parent is c_j − c_p in every frame (its length constant); the rest locals compose to the joints."""
    from skinsynth.pipeline.inputs.examples import walker
    from skinsynth.pipeline.rig.skeleton import rest_locals, tree_local_transforms

    _, _, rig = walker(frames=12, cycles=1, rings=8, segments=6, rig=True)
    local_r, local_t = tree_local_transforms(rig.rotations, rig.translations, rig.joints, rig.parents)
    jointed = rig.parents >= 0
    bone_vectors = rig.joints[jointed] - rig.joints[rig.parents[jointed]]
    assert np.abs(local_t[:, jointed] - bone_vectors).max() <= 1e-9
    np.testing.assert_allclose(rest_locals(rig.joints, rig.parents)[jointed], bone_vectors)
    np.testing.assert_allclose(rest_locals(rig.joints, rig.parents)[~jointed], rig.joints[~jointed])
    assert np.ptp(local_t[:, ~jointed], axis=0).max() > 1e-3  # the root bone moves (the walker bobs)


@pytest.mark.parametrize("up_axis, meters_per_unit, moving_root", [("Y", 1.0, False), ("Z", 0.01, True)])
def test_a_gltf_rig_of_a_tree_skins_as_the_lbs(up_axis, meters_per_unit, moving_root):
    """An engine's skinning of the tree rig (locals composed down the joints' parents, times the
    inverse binds) is the LBS, in glTF's axes and units; the nodes' rest translations compose to
    the joints."""
    from skinsynth.pipeline.inputs.examples import walker
    from skinsynth.pipeline.rig.skeleton import _converted

    _, faces, rig = walker(frames=12, cycles=1, rings=8, segments=6, rig=True)
    indices = np.tile(np.arange(10), (len(rig.rest), 1))
    built = gltf_rig(rig.rest, faces, indices, rig.weights, rig.joints, up_axis=up_axis,
                     meters_per_unit=meters_per_unit, parents=rig.parents)
    assert built["joint_names"][0] == "root" and built["parents"][0] == -1
    np.testing.assert_array_equal(built["parents"][1:], rig.parents + 1)
    joints = _converted(up_axis, meters_per_unit, rig.joints)
    rest_world = _compose_down(built["parents"][1:] - 1, np.tile(np.eye(3), (1, 10, 1, 1)),
                               built["bind_translations"][None, 1:], np.eye(3)[None], np.zeros((1, 3)))
    np.testing.assert_allclose(rest_world[0, :, :3, 3], joints, atol=1e-12)
    ground = (rig.rest, indices, rig.weights) if moving_root else None
    clip = gltf_clip("walk", rig.rotations, rig.translations, rig.joints, 24.0, up_axis=up_axis,
                     meters_per_unit=meters_per_unit, ground=ground, parents=rig.parents)
    root_r = xyzw_to_matrix(clip["root_rotations"]) if moving_root else np.tile(np.eye(3), (12, 1, 1))
    root_t = clip["root_translations"] if moving_root else np.zeros((12, 3))
    world = _compose_down(rig.parents, xyzw_to_matrix(clip["rotations"]), clip["translations"], root_r, root_t)
    skinning = world @ built["inverse_binds"][1:]
    posed = np.einsum("fvk,fvkij,vj->fvi", np.broadcast_to(built["weights"], (12,) + built["weights"].shape),
                      skinning[:, built["joints"] - 1][..., :3, :3], built["positions"]) + \
        np.einsum("vk,fvki->fvi", built["weights"], skinning[:, built["joints"] - 1][..., :3, 3])
    truth = np.einsum("vk,fvki->fvi", rig.weights,
                      np.einsum("fkij,vj->fvki", rig.rotations, rig.rest) + rig.translations[:, None])
    truth = _converted(up_axis, meters_per_unit, truth)
    diagonal = np.linalg.norm(np.ptp(built["positions"], axis=0))
    assert np.abs(posed - truth).max() <= 1e-7 * diagonal  # the weights are float32; the rest exact


def test_two_bone_inverse_kinematics_brings_each_foot_to_its_target_and_keeps_the_joints():
    from skinsynth.pipeline.rig.rotations import rotation_exp
    from skinsynth.pipeline.rig.skeleton import hold_joints, reach_with_legs

    rng = np.random.default_rng(4)
    parents, jointed = np.array([-1, 0, 1, 2]), np.array([False, True, True, True])  # body, thigh, shin, foot
    joints = np.array([[0.0, 1.2, 0.0], [0.1, 1.0, 0.0], [0.1, 0.55, 0.02], [0.1, 0.1, 0.0]])
    frames = 30
    R = rotation_exp(rng.normal(scale=0.4, size=(frames, 4, 3)))
    t = np.zeros((frames, 4, 3))
    t[:, 0] = rng.normal(scale=0.2, size=(frames, 3))
    hold_joints(R, t, parents, jointed, joints)
    hip = np.einsum("fxy,y->fx", R[:, 1], joints[1]) + t[:, 1]
    direction = rng.normal(size=(frames, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    reach = np.linalg.norm(joints[2] - joints[1]) + np.linalg.norm(joints[3] - joints[2])
    length = np.where(np.arange(frames) < 20, rng.uniform(0.3, 0.9, frames) * reach, 1.5 * reach)  # last 10: too far
    targets = (hip + length[:, None] * direction)[:, None]
    foot_turn = R[:, 3].copy()
    reach_with_legs(R, t, parents, jointed, joints, [3], targets)
    ankle = np.einsum("fxy,y->fx", R[:, 3], joints[3]) + t[:, 3]
    assert np.abs(ankle[:20] - targets[:20, 0]).max() < 1e-9
    # out of reach: the straight leg points at the target
    assert np.allclose(ankle[20:], hip[20:] + reach * direction[20:], atol=1e-6)
    assert np.array_equal(R[:, 3], foot_turn)
    for bone in (1, 2, 3):
        gap = (np.einsum("fxy,y->fx", R[:, bone] - R[:, parents[bone]], joints[bone]) + t[:, bone]
               - t[:, parents[bone]])
        assert np.abs(gap).max() < 1e-12
    assert np.allclose(np.einsum("fbxy,fbzy->fbxz", R[:, 1:3], R[:, 1:3]), np.eye(3), atol=1e-12)


def test_a_sliding_bone_is_kept_within_its_travel_and_left_alone_inside_it():
    """hold_joints with slides against the closed form: a bone that slides by a known offset s (in its
    parent's frame) on its joint; inside [low, high] nothing moves (bit for bit), beyond it the slide
    is clipped per axis and the bone keeps its turn; slide_offsets gives s back."""
    from skinsynth.pipeline.rig.skeleton import hold_joints, slide_offsets

    rng = np.random.default_rng(8)
    frames = 40
    parents, jointed = np.array([-1, 0, 1]), np.array([False, False, True])  # body, a sliding shoulder, a leg
    sliding = np.array([False, True, False])
    joints = np.array([[0.0, 1.0, 0.0], [0.3, 0.9, 0.1], [0.3, 0.5, 0.1]])
    R = random_rotations(rng, (frames, 3))
    t = rng.normal(size=(frames, 3, 3))
    s = rng.uniform(-0.1, 0.1, size=(frames, 3))
    s[:10] *= 4.0  # the first ten beyond the travel on some axis
    # the shoulder placed so that it slides by s: R_1 q + t_1 = R_0 (q + s) + t_0
    t[:, 1] = np.einsum("fxy,fy->fx", R[:, 0], joints[1] + s) + t[:, 0] - np.einsum("fxy,y->fx", R[:, 1], joints[1])
    hold_joints(R, t, parents, jointed, joints)  # the leg on its joint
    np.testing.assert_allclose(slide_offsets(R, t, parents, joints, [1])[:, 0], s, atol=1e-12)
    low, high = np.zeros((3, 3)), np.zeros((3, 3))
    low[1], high[1] = -0.1, 0.1
    before_R, before_t = R.copy(), t.copy()
    hold_joints(R, t, parents, jointed, joints, (sliding, low, high))
    inside = np.all(np.abs(s) <= 0.1, axis=1)
    assert inside[10:].all() and not inside[:10].all()
    assert np.array_equal(t[inside], before_t[inside]) and np.array_equal(R, before_R)
    np.testing.assert_allclose(slide_offsets(R, t, parents, joints, [1])[:, 0], np.clip(s, -0.1, 0.1), atol=1e-12)
    gap = np.einsum("fxy,y->fx", R[:, 2] - R[:, 1], joints[2]) + t[:, 2] - t[:, 1]  # the leg followed it
    assert np.abs(gap).max() < 1e-12
