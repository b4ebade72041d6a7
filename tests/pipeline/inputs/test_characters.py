"""The generated characters with known skeletons (issue 65's truth): their skin is exact LBS of
their true rig, every joint holds, the ground and the flight are as documented, the chain names
cover every bone."""

import numpy as np
import pytest

from skinsynth.pipeline.inputs.characters import (CHARACTERS, HUMANOID_MOTIONS, QUADRUPED_MOTIONS, body_weights,
                                                  character, humanoid_body)


@pytest.fixture(scope="module", params=[("humanoid", 1.0), ("humanoid", 0.8), ("quadruped", 1.0), ("quadruped", 1.3)],
                ids=lambda p: f"{p[0]}-{p[1]}")
def made(request):
    kind, limbs = request.param
    return (kind, limbs, *character(kind, frames_per_motion=24, limbs=limbs))


def test_the_vertices_are_exactly_the_true_rigs_linear_blend_skin(made):
    _, _, vertices, faces, rig = made
    skinned = (np.einsum("vb,fbij,vj->fvi", rig.weights, rig.rotations, rig.rest)
               + np.einsum("vb,fbi->fvi", rig.weights, rig.translations))
    assert np.abs(skinned - vertices).max() < 1e-12
    assert rig.weights.min() >= 0.0 and np.allclose(rig.weights.sum(axis=1), 1.0)
    assert faces.min() == 0 and faces.max() == rig.rest.shape[0] - 1
    np.testing.assert_allclose(np.linalg.det(rig.rotations), 1.0, atol=1e-12)


def test_every_joint_holds_in_every_frame_and_turns_in_some(made):
    """Each bone and its parent carry their joint to one place in every frame (the truth a joint
    finder must meet), and every joint bends by at least 0.2 rad somewhere (a joint that never turns
    is anywhere on its pair: module notes)."""
    _, _, vertices, _, rig = made
    body = rig.body
    child = np.flatnonzero(body.parents >= 0)
    parent = body.parents[child]
    at = lambda bones: (np.einsum("fbij,bj->fbi", rig.rotations[:, bones], body.joints[child])  # noqa: E731
                        + rig.translations[:, bones])
    assert np.abs(at(child) - at(parent)).max() < 1e-12
    relative = np.einsum("fbji,fbjk->fbik", rig.rotations[:, parent], rig.rotations[:, child])
    bend = np.arccos(np.clip((np.trace(relative, axis1=2, axis2=3) - 1.0) / 2.0, -1.0, 1.0))
    assert bend.max(axis=0).min() > 0.2


def test_the_lowest_point_is_on_the_ground_but_in_a_jumps_flight(made):
    kind, _, vertices, _, rig = made
    lowest = vertices[..., 1].min(axis=1)
    np.testing.assert_allclose(lowest[rig.ground], 0.0, atol=1e-12)
    if kind == "humanoid":  # the jump's middle third: up to 0.45 above the ground
        assert (~rig.ground).sum() >= 6 and lowest[~rig.ground].min() > 0.0 and lowest.max() == pytest.approx(0.45, abs=0.02)
    else:
        assert rig.ground.all()


def test_the_left_is_at_plus_x_the_figure_faces_plus_z_and_the_limbs_scale():
    """The rest poses: the humanoid facing +z (its toes ahead of its ankles), its left at +x; the
    quadruped's head at +z; ``limbs`` lengthens the legs and not the trunk."""
    for kind, (build, _, names) in CHARACTERS.items():
        body = build()
        assert set(names) == set(body.names) and len(set(names.values())) == len(names)
        for name, at in zip(body.names, body.joints):
            if name.endswith("_l") and name.split("_")[0] not in ("tail",):
                assert at[0] > 0.0 and body.joints[body.index(name[:-1] + "r")][0] == -at[0]
    human = humanoid_body()
    assert human.ends[human.index("foot_l"), 2] > human.joints[human.index("foot_l"), 2]
    quadruped = CHARACTERS["quadruped"][0]()
    assert quadruped.ends[quadruped.index("head"), 2] > quadruped.joints[quadruped.index("tail_01"), 2]
    long = humanoid_body(limbs=1.3)
    leg = lambda b: np.linalg.norm(b.ends[b.index("shin_l")] - b.joints[b.index("thigh_l")])  # noqa: E731
    trunk = lambda b: np.linalg.norm(b.ends[b.index("chest")] - b.joints[b.index("spine")])  # noqa: E731
    assert leg(long) == pytest.approx(1.3 * leg(human)) and trunk(long) == pytest.approx(trunk(human))


def test_each_motion_is_its_own_and_the_default_plays_them_all():
    one, _, rig = character("humanoid", motions=["raise"], frames_per_motion=12)
    every, _, _ = character("humanoid", frames_per_motion=12)
    assert len(one) == 12 and len(every) == 12 * len(HUMANOID_MOTIONS)
    np.testing.assert_allclose(every[12:24], one, atol=1e-12)  # the second motion is "raise"
    four, _, _ = character("quadruped", frames_per_motion=12)
    assert len(four) == 12 * len(QUADRUPED_MOTIONS)


def test_neighbouring_bones_share_skin_at_their_joint_and_no_other_pair_does():
    """Half and half at the joint (the parent's weight rising to ½ along each tube's first
    ``blend``, the continuing child's along its parent's last), and no weight on two bones that do
    not meet."""
    body = humanoid_body()
    rest, _, weights = body_weights(body)
    shared = (weights[:, :, None] > 0) & (weights[:, None, :] > 0)
    pairs = {(a, b) for a, b in zip(*np.nonzero(shared.any(axis=0))) if a < b}
    tree = {tuple(sorted((b, int(p)))) for b, p in enumerate(body.parents) if p >= 0}
    assert pairs <= tree
    knee = body.joints[body.index("shin_l")]
    at_knee = np.linalg.norm(rest - knee, axis=1) < 0.08
    thigh, shin = body.index("thigh_l"), body.index("shin_l")
    assert np.abs(weights[at_knee][:, [thigh, shin]].sum(axis=1) - 1.0).max() < 1e-12
    halves = np.isclose(weights[at_knee, thigh], 0.5) & np.isclose(weights[at_knee, shin], 0.5)
    assert halves.sum() >= 20  # the two rings at the knee (10 vertices round each)
