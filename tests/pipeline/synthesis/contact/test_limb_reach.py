"""A planted foot moved by its limb's joints (issue 62: :mod:`skinsynth.pipeline.synthesis.contact.limb_reach`):
on a generated leg with exact joints, a reachable target is reached, bone lengths and joints are
kept to rounding, a hinge stays a hinge within its range, and no correction pops."""

import numpy as np

from skinsynth.pipeline.rig.rotations import rotation_exp, rotation_log
from skinsynth.pipeline.synthesis.contact.limb_reach import (COLD_STEPS, PRIOR, RANGE_MARGIN, STIFF, WARM_STEPS,
                                                          _track, _unseen_joints, reach_animations)
from skinsynth.pipeline.synthesis.contact.limb_shape import HALVINGS, no_seams

#: The leg's rest joints: hip, knee, ankle; its sole's centre in front of the ankle.
HIP, KNEE, ANKLE, SOLE = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.5, 0.0]), np.array([0.0, 0.08, 0.0]), \
    np.array([0.0, 0.0, 0.12])


def _leg_pose(frames, hip_turn=0.2, bend=0.6):
    """Bones (1, M, 4, 3, 3), (1, M, 4, 3) float32 of a body (0), thigh (1), shin (2) and foot (3) with
    exact joints: the thigh turned forward by ``hip_turn``, the knee bent by ``bend`` (about x), the
    body standing still; every frame the same."""
    R = np.broadcast_to(np.eye(3), (4, 3, 3)).copy()
    R[1] = rotation_exp(np.array([-hip_turn, 0.0, 0.0]))
    R[2] = R[1] @ rotation_exp(np.array([bend, 0.0, 0.0]))
    R[3] = R[2] @ rotation_exp(np.array([-bend + hip_turn, 0.0, 0.0]))  # the foot level again
    t = np.zeros((4, 3))
    for bone, parent, joint in ((1, 0, HIP), (2, 1, KNEE), (3, 2, ANKLE)):
        t[bone] = R[parent] @ joint + t[parent] - R[bone] @ joint
    F = np.broadcast_to(R, (1, frames, 4, 3, 3)).astype(np.float32).copy()
    return F, np.broadcast_to(t, (1, frames, 4, 3)).astype(np.float32).copy()


def _ranges(hinge):
    """(mean, axes, frame, weight, low, high) of the three joints: free in every direction, or
    (hinge) the knee a hinge about x bending from 0 to 2 rad, its other axes fixed."""
    K = 3
    mean = np.broadcast_to(np.eye(3), (K, 3, 3)).copy()
    axes = np.broadcast_to(np.eye(3)[:, [1, 2, 0]], (K, 3, 3)).copy()  # columns ascending: x last
    low, high = np.full((K, 3), -3.0), np.full((K, 3), 3.0)
    spread = np.ones((K, 3))
    if hinge:
        mean[1] = rotation_exp(np.array([1.0, 0.0, 0.0]))  # the mean bend
        low[1], high[1] = [0.0, 0.0, -1.0], [0.0, 0.0, 1.0]
        spread[1] = [0.0, 0.0, 0.6]
    largest = spread.max(axis=1, keepdims=True)
    weight = largest / np.maximum(spread, STIFF * largest)
    frame = np.einsum("kxu,kvx->kuv", axes, mean)
    return mean, axes, frame, weight, low, high


def _reach(F, t, correction, turn=None, hinge=False, limit=np.inf, skin=None):
    """The leg's foot (its sole's centre) moved by ``correction`` (M, 3) and turned by ``turn`` (M, 3)
    (axis-angle) through its hip, knee and ankle, in place; skin: None, or (rest (V, 3),
    bone_indices, bone_weights (V, K), its :class:`LimbSeams`) whose seams a turn may not tear.
    Returns (A, M) counts of the joints held at their range and of the turns cut."""
    M = F.shape[1]
    sole = np.einsum("mij,j->mi", F[0, :, 3].astype(np.float64), SOLE) + t[0, :, 3]
    pivot = sole[None, None].copy()
    corr = np.asarray(correction, dtype=np.float64)[None, None].copy()
    turned = np.zeros_like(corr) if turn is None else np.asarray(turn, dtype=np.float64)[None, None].copy()
    mean, axes, frame, weight, low, high = _ranges(hinge)
    held, cut = np.zeros((1, M), np.int64), np.zeros((1, M), np.int64)
    rest, indices, weights, seams = skin or (np.zeros((1, 3)), np.zeros((1, 1), np.int64), np.zeros((1, 1)),
                                             no_seams(1))
    reach_animations(F, t, pivot, corr, turned, np.zeros((1, M, 3)), np.array([[0, 1, 2]]), np.array([[0]]),
                     np.array([1, 2, 3]), np.array([0, 1, 2]), np.stack([HIP, KNEE, ANKLE]), np.array([-1, 0, 1]),
                     np.array([1.05, 0.55, 0.15]), mean, axes, frame, weight, low, high, np.zeros((3, 0, 3)),
                     float(RANGE_MARGIN),
                     float(PRIOR), np.array([0.05]), np.array([2]), np.array([-1, 0, 1, 2]), np.array([3]),
                     SOLE[None, None].copy(), np.ones((1, 1)), int(WARM_STEPS), int(COLD_STEPS), float(limit), rest,
                     indices, weights, seams.vertices, seams.edges, seams.lengths, seams.one, seams.allowance,
                     seams.masks, seams.budget, int(HALVINGS), held, cut)
    return held, cut


def _sole(F, t):
    return np.einsum("mij,j->mi", F[0, :, 3].astype(np.float64), SOLE) + t[0, :, 3]


def _joint_gaps(F, t):
    """(M, 3): how far apart each joint's two bones carry it (0 on an exact rig)."""
    F, t = F[0].astype(np.float64), t[0].astype(np.float64)
    return np.stack([np.linalg.norm(np.einsum("mij,j->mi", F[:, p] - F[:, b], q) + t[:, p] - t[:, b], axis=1)
                     for b, p, q in ((1, 0, HIP), (2, 1, KNEE), (3, 2, ANKLE))], axis=1)


def test_a_reachable_target_is_reached_and_the_leg_keeps_its_joints_and_lengths():
    F, t = _leg_pose(40)
    before = _sole(F, t)
    shift = np.array([0.06, 0.03, -0.05])
    held, cut = _reach(F, t, np.broadcast_to(shift, (40, 3)))
    miss = np.linalg.norm(_sole(F, t) - before - shift, axis=1)
    assert miss[-1] < 0.02 * np.linalg.norm(shift)  # the prior's share: a few per cent at most
    assert _joint_gaps(F, t).max() < 1e-6  # every joint held (float32 bones)
    hip = F[0, :, 1].astype(np.float64) @ HIP + t[0, :, 1]
    knee = F[0, :, 1].astype(np.float64) @ KNEE + t[0, :, 1]
    ankle = F[0, :, 2].astype(np.float64) @ ANKLE + t[0, :, 2]
    np.testing.assert_allclose(np.linalg.norm(knee - hip, axis=1), 0.5, atol=1e-6)  # lengths kept
    np.testing.assert_allclose(np.linalg.norm(ankle - knee, axis=1), 0.42, atol=1e-6)
    np.testing.assert_array_equal(F[0, :, 0], np.broadcast_to(np.eye(3), (40, 3, 3)))  # the body never moves
    assert held.sum() == 0 and cut.sum() == 0


def test_a_turn_of_the_foot_is_made_at_the_ankle():
    F, t = _leg_pose(30)
    foot = F[0, 0, 3].astype(np.float64)
    _reach(F, t, np.zeros((30, 3)), turn=np.broadcast_to([0.0, 0.3, 0.0], (30, 3)))
    turned = rotation_log(F[0, -1, 3].astype(np.float64) @ foot.T)
    np.testing.assert_allclose(turned, [0.0, 0.3, 0.0], atol=0.01)
    assert _joint_gaps(F, t).max() < 1e-6


def test_a_hinge_stays_a_hinge_within_its_range():
    """A target out to the side (x), which a free knee reaches partly by bending sideways: the hinged
    knee keeps its axis (the hip takes the turn)."""
    F, t = _leg_pose(30)
    before = _sole(F, t)
    shift = np.broadcast_to([0.4, 0.0, 0.0], (30, 3))
    free_F, free_t = F.copy(), t.copy()
    _reach(free_F, free_t, shift)
    _reach(F, t, shift, hinge=True)
    relative = rotation_log(np.einsum("mji,mjk->mik", F[0, :, 1].astype(np.float64), F[0, :, 2].astype(np.float64)))
    assert np.abs(relative[:, 1:]).max() < RANGE_MARGIN + np.radians(1.0)  # no turn off the hinge past the margin
    free_relative = rotation_log(np.einsum("mji,mjk->mik", free_F[0, :, 1].astype(np.float64),
                                           free_F[0, :, 2].astype(np.float64)))
    assert np.abs(free_relative[:, 1:]).max() > 2 * RANGE_MARGIN  # unhinged, the knee bends sideways
    assert _joint_gaps(F, t).max() < 1e-6
    assert np.linalg.norm(_sole(F, t)[-1] - before[-1] - shift[-1]) < 0.05 * 0.4


def test_a_jump_of_the_target_adds_no_more_than_the_limit():
    """A target that jumps by a tenth of the leg at frame 10: the foot follows with accelerations
    within the joints' limits (each joint's acceleration at its reach at most ``limit``), and ends
    where the target is."""
    frames, limit = 60, 2e-3
    F, t = _leg_pose(frames)
    before = _sole(F, t)
    shift = np.zeros((frames, 3))
    shift[10:] = [0.0, 0.05, 0.08]
    _reach(F, t, shift, limit=limit)
    sole = _sole(F, t) - before
    acceleration = np.linalg.norm(sole[2:] - 2 * sole[1:-1] + sole[:-2], axis=1)
    assert acceleration.max() <= 3 * limit * 1.01  # three joints, each within the limit at its reach
    unlimited_F, unlimited_t = _leg_pose(frames)
    _reach(unlimited_F, unlimited_t, shift)
    free = _sole(unlimited_F, unlimited_t) - before
    assert np.linalg.norm(free[2:] - 2 * free[1:-1] + free[:-2], axis=1).max() > 5 * acceleration.max()
    np.testing.assert_allclose(sole[-1], free[-1], atol=1e-4)


def test_track_follows_without_overshoot_or_pops():
    most = 0.05
    last, velocity = np.zeros(3), np.zeros(3)
    path = []
    for _ in range(40):
        before = velocity.copy()
        _track(np.array([1.0, 0.0, 0.0]), last, velocity, most)
        assert np.linalg.norm(velocity - before) <= most * (1 + 1e-12)
        path.append(last[0])
    assert max(path) <= 1.0 + 1e-12 and path[-1] == 1.0  # there, never past it
    last, velocity = np.zeros(3), np.zeros(3)
    for k in range(20):  # a goal moving slower than the limit allows is followed exactly
        goal = np.array([0.0, 0.001 * k * k, 0.0])
        _track(goal, last, velocity, most)
        np.testing.assert_allclose(last, goal, atol=1e-15)



def test_a_pose_the_input_shows_or_the_frame_had_is_seen():
    """:func:`_unseen_joints`: a joint within the margin of a pose the input shows (or of its own
    uncorrected pose) bends its skin as the capture does; the others are named, by bit (i + 1)."""
    eye = np.broadcast_to(np.eye(3), (2, 3, 3)).copy()  # body-side and limb-side bones at rest, mean and axes I
    seen = np.zeros((2, 3, 3))
    seen[:, 1] = [0.5, 0.0, 0.0]
    seen[:, 2] = [0.0, 0.0, -0.8]
    z0 = np.array([[0.0, 0.3, 0.0], [0.0, 0.0, 0.0]])

    def unseen(turns):
        rho = np.stack([rotation_exp(np.asarray(x, dtype=np.float64)) for x in turns])
        return _unseen_joints(np.array([0, 1]), rho, eye, eye, eye, eye, seen, z0, float(RANGE_MARGIN), np.empty(3),
                              np.empty((3, 3)), np.empty((3, 3)), np.empty(3))

    small = 0.5 * RANGE_MARGIN
    assert unseen([[0.5 + small, 0.0, 0.0], [0.0, 0.0, -0.8 + small]]) == 0  # both near a seen pose
    assert unseen([[0.0, 0.3 + small, 0.0], [small, 0.0, 0.0]]) == 0  # near their own, uncorrected
    assert unseen([[0.5 + 3 * RANGE_MARGIN, 0.0, 0.0], [0.0, 0.0, 0.0]]) == 0b10  # the first beyond both
    assert unseen([[0.5, 0.0, 0.0], [0.0, 0.4, 0.0]]) == 0b100  # the second
    assert unseen([[1.5, 0.0, 0.0], [0.0, 0.4, 0.0]]) == 0b110  # both
