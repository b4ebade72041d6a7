"""The jointed rig's inverse kinematics (pipeline/rig/inverse_kinematics.py) against closed forms:
its Jacobian against finite differences, a pose that skinned points reach recovered exactly, the
prior alone keeping the start, and every jointed bone on its joint."""

import numpy as np

from skinsynth.pipeline.rig.inverse_kinematics import JointedRig, solve_pose
from skinsynth.pipeline.rig.rotations import rotation_exp
from skinsynth.pipeline.rig.skeleton import slide_offsets

#: A tree of six bones: the root, a chain of two under it with a loose (free) third, a branch of two.
PARENTS = np.array([-1, 0, 1, 0, 3, 1])
JOINTED = np.array([False, True, False, True, True, False])


def _rig(points, seed=0):
    rng = np.random.default_rng(seed)
    joints = rng.normal(size=(6, 3))
    rest = rng.normal(size=(points, 3))
    bones = rng.integers(0, 6, size=(points, 2))
    weights = rng.dirichlet([1.0, 1.0], size=points)
    return JointedRig(PARENTS, JOINTED, joints, rest, bones, weights), rng


def _pose(rig, rng, frames=2, spread=1.0):
    rotations = rotation_exp(rng.normal(size=(frames, 6, 3)) * spread)
    return rotations, rig.forward(rotations, rng.normal(size=(frames, 3)), rng.normal(size=(frames, len(rig.loose), 3)))


def test_the_jacobian_is_the_points_derivative():
    rig, rng = _rig(7)
    rotations, translations = _pose(rig, rng)
    slides, root = rig.slides(rotations, translations), translations[:, rig.root]
    jacobian, start = rig.jacobian(rotations, slides), rig.skinned_points(rotations, translations)
    step, numeric = 1e-6, np.zeros_like(jacobian)
    for column in range(jacobian.shape[2]):
        d = np.zeros(jacobian.shape[2])
        d[column] = step
        d = d.reshape(-1, 3)
        turned = np.einsum("fbxy,fbyz->fbxz", rotation_exp(np.broadcast_to(d[:6], (2, 6, 3))), rotations)
        moved = rig.skinned_points(turned, rig.forward(turned, root + d[6], slides + d[7:]))
        numeric[:, :, column] = ((moved - start) / step).reshape(2, -1)
    assert np.abs(numeric - jacobian).max() < 1e-4


def test_reachable_targets_are_reached_exactly_and_the_joints_hold():
    rig, rng = _rig(40)
    start_r, start_t = _pose(rig, rng)
    truth_r, truth_t = _pose(rig, rng, spread=0.3)
    targets = rig.skinned_points(truth_r, truth_t)
    rotations, translations = solve_pose(rig, start_r, start_t, targets, prior_weight=1e-6, iterations=15)
    assert np.abs(rig.skinned_points(rotations, translations) - targets).max() < 1e-8
    assert np.abs(rotations - truth_r).max() < 1e-8 and np.abs(translations - truth_t).max() < 1e-8
    jointed = np.flatnonzero(JOINTED)  # every jointed bone's slide is zero: on its joint
    assert np.abs(slide_offsets(rotations, translations, PARENTS, rig.joints, jointed)).max() < 1e-10


def test_targets_where_the_points_are_keep_the_start_and_the_prior_holds_what_they_cannot_say():
    rig, rng = _rig(3)  # three points cannot fix six bones: the prior decides
    rotations, translations = _pose(rig, rng)
    targets = rig.skinned_points(rotations, translations)
    solved_r, solved_t = solve_pose(rig, rotations, translations, targets)
    assert np.abs(solved_r - rotations).max() < 1e-9 and np.abs(solved_t - translations).max() < 1e-9
    # pulled away, the prior stays: a heavier prior leaves the pose nearer the start
    moved = targets + np.array([0.3, -0.2, 0.1])
    near = [np.abs(solve_pose(rig, rotations, translations, moved, prior_weight=w)[0] - rotations).max()
            for w in (0.3, 3.0)]
    assert near[1] < 0.5 * near[0]
