"""Markers to controls (pipeline/puppet/markers.py, its gaps pipeline/puppet/marker_gaps.py)
against closed-form truth."""

import numpy as np
import pytest

from skinsynth.pipeline.errors import OptionError
from skinsynth.pipeline.puppet.marker_gaps import fill_from_training, fill_short_gaps, training_subspace
from skinsynth.pipeline.puppet.markers import (drive_from_markers, resample_uniform, similarity_transform,
                                               stabilize_markers, up_axis_rotation)
from skinsynth.pipeline.rig.rotations import rotation_exp


def _rotation(seed):
    return rotation_exp(np.random.default_rng(seed).normal(size=3))


def _poses(frames=60, markers=10, rank=4, seed=0):
    """Controls (frames, markers, 3) on a rank-`rank` subspace around a rest shape, plus a slow
    rigid drift, and the rest shape (markers, 3)."""
    rng = np.random.default_rng(seed)
    rest = rng.normal(size=(markers, 3))
    bases = rng.normal(size=(rank, markers, 3)) * 0.1
    time = np.linspace(0, 2 * np.pi, frames)
    amplitudes = np.stack([np.sin((j + 1) * time + j) for j in range(rank)], axis=1)
    amplitudes[0] = 0.0  # frame 0 is the rest pose
    shapes = rest + np.einsum("fk,kma->fma", amplitudes, bases)
    return shapes, rest


def test_similarity_recovers_scale_rotation_translation():
    rng = np.random.default_rng(1)
    source = rng.normal(size=(12, 3))
    rotation, scale, shift = _rotation(2), 3.7, np.array([0.4, -2.0, 9.0])
    s, r, t = similarity_transform(source, scale * source @ rotation.T + shift)
    assert abs(s - scale) < 1e-12 and np.abs(r - rotation).max() < 1e-12 and np.abs(t - shift).max() < 1e-11


def test_similarity_never_reflects():
    rng = np.random.default_rng(3)
    source = rng.normal(size=(8, 3))
    mirrored = source * np.array([-1.0, 1.0, 1.0])
    _, rotation, _ = similarity_transform(source, mirrored)
    assert np.linalg.det(rotation) == pytest.approx(1.0)


def test_up_axis_rotation_is_proper_and_turns_up():
    turn = up_axis_rotation("Z", "Y")
    assert np.linalg.det(turn) == pytest.approx(1.0)
    assert np.allclose(turn @ [0, 0, 1], [0, 1, 0])
    assert np.allclose(up_axis_rotation("Y", "Y"), np.eye(3))
    assert np.allclose(up_axis_rotation("Y", "Z") @ turn, np.eye(3))


def test_short_gaps_bridge_quadratic_motion_exactly_and_leave_long_and_edge_gaps():
    time = np.arange(40, dtype=float) / 100.0
    points = np.stack([np.stack([time, 2 * time ** 2, -time + time ** 2], axis=1)] * 3, axis=1)  # (40, 3, 3)
    holed = points.copy()
    holed[5:9, 0] = np.nan  # 4 frames: filled
    holed[10:25, 1] = np.nan  # 15 frames: too long
    holed[:3, 2] = np.nan  # at the start: no frame before it
    for cutoff in (4.0, 10.0, None):  # a stiff spline, a loose one, a raw take's: a parabola goes through unbent
        filled, mask = fill_short_gaps(holed, 10, 100.0, cutoff)
        assert np.abs(filled[5:9, 0] - points[5:9, 0]).max() < 1e-9 and mask[5:9, 0].all()
    assert np.isnan(filled[10:25, 1]).all() and np.isnan(filled[:3, 2]).all()
    assert mask.sum() == 4


def test_resample_keeps_samples_on_frames_and_interpolates_between():
    rate, fps = 120.0, 24.0
    values = np.random.default_rng(4).normal(size=(121, 5, 3))
    out = resample_uniform(values, rate, fps)
    assert out.shape[0] == 25 and np.array_equal(out, values[::5])
    line = np.arange(11, dtype=float)[:, None] * np.array([1.0, -3.0])  # 50 Hz linear
    resampled = resample_uniform(line, 50.0, 24.0)
    assert np.allclose(resampled, (np.arange(len(resampled)) * 50 / 24)[:, None] * np.array([1.0, -3.0]))


def test_stabilize_removes_a_rigid_head_motion_exactly():
    shapes, _ = _poses(frames=20)
    rotations = np.stack([rotation_exp(np.array([0.0, 0.03 * f, 0.01 * f])) for f in range(20)])
    moved = np.einsum("fab,fmb->fma", rotations, shapes) + np.arange(20)[:, None, None] * 0.1
    head = [0, 1, 2, 3]
    shapes[:, head] = shapes[0, head]  # the head markers are rigid in the truth
    moved = np.einsum("fab,fmb->fma", rotations, shapes) + np.arange(20)[:, None, None] * 0.1
    steady = stabilize_markers(moved, head, neutral=0)
    truth = np.einsum("ab,fmb->fma", rotations[0], shapes)
    assert np.abs(steady - truth).max() < 1e-10


def test_training_fill_recovers_markers_of_a_subspace_pose_under_rigid_motion():
    shapes, rest = _poses(frames=80, markers=12, rank=3)
    training = shapes[:60]
    test = shapes[60:].copy()
    turned = np.einsum("ab,fmb->fma", _rotation(5), test) + np.array([3.0, 0.0, -1.0])
    holed = turned.copy()
    holed[:, [2, 7]] = np.nan  # two markers lost for every test frame
    holed[5, [0, 3, 4]] = np.nan  # another pattern in one frame
    filled, mask, held = fill_from_training(holed, training, min_markers=3, ridge=0.0)
    assert len(held) == 0 and mask.sum() == 2 * len(test) + 3
    assert np.abs(filled - turned).max() < 1e-9
    ridged, _, _ = fill_from_training(holed, training, min_markers=3)  # the default ridge: shrinks a little
    motion = np.abs(turned - turned.mean(axis=0)).max()
    assert np.abs(ridged - turned).max() < 0.02 * motion


def test_training_fill_holds_frames_with_too_few_markers():
    shapes, _ = _poses(frames=10, markers=6)
    holed = shapes.copy()
    holed[4:6, :4] = np.nan  # 2 of 6 seen
    holed[0, :5] = np.nan  # the first frame too: held from the first good one
    filled, _, held = fill_from_training(holed, shapes, min_markers=3)
    assert held.tolist() == [0, 4, 5]
    assert np.array_equal(filled[4], filled[3]) and np.array_equal(filled[5], filled[3])
    assert np.array_equal(filled[0], filled[1])
    with pytest.raises(OptionError, match="no frame"):
        fill_from_training(np.full((3, 6, 3), np.nan), shapes, min_markers=3)


def test_subspace_keeps_enough_variance():
    shapes, _ = _poses(frames=50, rank=3)
    mean, bases, variances = training_subspace(shapes)
    assert len(variances) <= 3 and np.allclose(np.einsum("kma,jma->kj", bases, bases), np.eye(len(variances)))


def _take(shapes, scale, rotation, shift, units=1.0):
    """Markers in a Z-up take (metres / units) seeing Y-up controls shapes (F, n, 3)."""
    z_up = shapes @ up_axis_rotation("Y", "Z").T
    return (scale * z_up @ rotation.T + shift) * units


def test_drive_recovers_the_transform_and_the_controls_exactly_without_noise():
    shapes, rest = _poses(frames=121, markers=10, rank=3)
    rotation, scale, shift = _rotation(7), 1.8, np.array([0.5, 2.0, 0.1])
    take = _take(shapes, scale, rotation, shift)
    holed = take.copy()
    holed[30:34, 2] = np.nan  # short: interpolated
    holed[50:90, 5] = np.nan  # long: from the training subspace
    drive = drive_from_markers(holed, rate=120.0, fps=24.0, reference=rest, training=shapes, take_up="Z",
                               puppet_up="Y", cutoff=None)  # raw: a low-pass moves every sample a little
    truth = np.linalg.inv(scale * rotation @ up_axis_rotation("Y", "Z"))
    assert abs(drive.scale - np.cbrt(np.linalg.det(truth))) < 1e-9
    assert np.abs(drive.scale * drive.rotation - truth).max() < 1e-9
    assert np.abs(drive.translation + truth @ shift).max() < 1e-9
    assert drive.neutral_frame == 0 and drive.controls.shape == (25, 10, 3)
    kept = [f for f in range(25) if not 30 <= 5 * f < 34 and not 50 <= 5 * f < 90]
    assert np.abs(drive.controls[kept] - shapes[::5][kept]).max() < 1e-9
    assert drive.interpolated[2].tolist() == [30, 31, 32, 33] and drive.subspace[5].tolist() == list(range(50, 90))
    assert np.abs(drive.controls - shapes[::5]).max() < 0.05  # filled frames: near, through the subspace


def test_drive_absolute_places_controls_on_the_aligned_markers():
    shapes, rest = _poses(frames=30, markers=8)
    performer = shapes * np.array([1.2, 0.9, 1.0])  # other proportions
    take = _take(performer, 1.0, _rotation(9), np.zeros(3), units=1.0)
    delta = drive_from_markers(take, 30.0, 30.0, rest, shapes, retarget="delta", cutoff=None)
    absolute = drive_from_markers(take, 30.0, 30.0, rest, shapes, retarget="absolute")
    assert np.abs(delta.controls[0] - rest).max() < 1e-12  # the rest shape is the character's own
    # filtered, the neutral frame's residual (the performer's proportions) is far above what the filter
    # removed: kept almost whole (James–Stein), the rest shape the character's to a fraction of a percent
    filtered = drive_from_markers(take, 30.0, 30.0, rest, shapes, retarget="delta")
    assert filtered.neutral["kept"] > 0.95 and filtered.neutral["residual"] > 10 * filtered.neutral["noise"]
    assert np.abs(filtered.controls[0] - rest).max() < 0.01 * np.ptp(rest)
    assert np.abs(absolute.controls - absolute.markers).max() < 1e-12
    assert np.abs(absolute.controls[0] - rest).max() > 1e-3


def test_drive_refuses_what_the_take_cannot_give():
    shapes, rest = _poses(frames=20, markers=6)
    take = _take(shapes, 1.0, np.eye(3), np.zeros(3))
    with pytest.raises(OptionError, match="retarget"):
        drive_from_markers(take, 20.0, 20.0, rest, shapes, retarget="nearest")
    with pytest.raises(OptionError, match="outside"):
        drive_from_markers(take, 20.0, 20.0, rest, shapes, neutral_frame=20)
    holed = take.copy()
    holed[:12, 0] = np.nan  # marker 0 seen from frame 12 on, marker 1 only before it: no frame sees both
    holed[12:, 1] = np.nan
    with pytest.raises(OptionError, match="every marker it has"):
        drive_from_markers(holed, 20.0, 20.0, rest, shapes, max_gap=0)
    with pytest.raises(OptionError, match="lacks markers 0"):
        drive_from_markers(holed, 20.0, 20.0, rest, shapes, neutral_frame=3, max_gap=0)
    line = take.copy()
    line[:, 3:] = np.nan  # three markers left ...
    line[:, 2] = 2.0 * line[:, 1] - line[:, 0]  # ... on a line
    with pytest.raises(OptionError, match="do not span a plane"):
        drive_from_markers(line, 20.0, 20.0, rest, shapes)
    with pytest.raises(OptionError, match="stabilize"):
        drive_from_markers(take, 20.0, 20.0, rest, shapes, stabilize=[0, 1])


def test_frame_ranges_name_runs_of_consecutive_frames():
    from skinsynth.pipeline.puppet.markers import frame_ranges

    assert frame_ranges([]) == ""
    assert frame_ranges([3]) == "3"
    assert frame_ranges([0, 1, 2, 7, 9, 10]) == "0–2, 7, 9–10"


def test_a_layouts_markers_are_ordered_by_the_controls_and_a_mismatch_is_refused():
    from skinsynth.pipeline.puppet.markers import layout_order

    rest = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    positions = np.full((3, 3), np.nan)
    positions[1] = [0.1, 0.9, 0.0]  # given by its rest position: the nearest vertex, 2
    order = layout_order([3, -1, 0], positions, rest, [0, 2, 3])
    assert order.tolist() == [2, 1, 0]
    with pytest.raises(ValueError, match="two markers sit on one vertex"):
        layout_order([0, 0, 2], np.full((3, 3), np.nan), rest, [0, 2, 3])
    with pytest.raises(ValueError, match=r"vertices \[1\] are not controls, controls \[3\] have no marker"):
        layout_order([0, 1, 2], np.full((3, 3), np.nan), rest, [0, 2, 3])


def test_the_neutral_frame_is_the_one_a_similarity_brings_nearest_the_rest_pose():
    from skinsynth.pipeline.puppet.marker_neutral import closest_to_rest, sample_noise

    rng = np.random.default_rng(8)
    rest = rng.normal(size=(7, 3))
    poses = rest + 0.3 * rng.normal(size=(40, 7, 3))  # deformed frames
    poses[23] = 2.5 * rest @ _rotation(3).T + np.array([1.0, -4.0, 2.0])  # the rest pose, moved and scaled
    present = np.ones(7, dtype=bool)
    assert closest_to_rest(poses, rest, present) == 23
    poses[30] = poses[23]  # a cyclic take comes back to it: the first
    assert closest_to_rest(poses, rest, present) == 23
    holed = poses.copy()
    holed[:, 4] = np.nan  # a marker the take lacks: the others decide
    present[4] = False
    assert closest_to_rest(holed, rest, present) == 23
    holed[23, 1] = np.nan  # frame 23 no longer sees all it has
    assert closest_to_rest(holed, rest, present) == 30
    # white noise of σ per coordinate on a slow straight path: 3σ² per sample
    line = np.linspace(0.0, 1.0, 4000)[:, None, None] * np.ones((1, 5, 3))
    noisy = line + 0.01 * rng.normal(size=line.shape)
    assert abs(sample_noise(noisy) / (3 * 0.01 ** 2) - 1.0) < 0.1
    # noise no larger than the take's own makes near-rest neighbours ties: the first is taken
    near = np.repeat(rest[None], 5, axis=0) + 0.001 * rng.normal(size=(5, 7, 3))
    near[3] = rest
    assert closest_to_rest(near, rest, np.ones(7, dtype=bool), noise=3 * 0.001 ** 2) == 0
    assert closest_to_rest(near, rest, np.ones(7, dtype=bool)) == 3


def test_filled_runs_are_joined_to_their_seen_ends():
    """A run filled with the right motion but off by a drift linear in time comes back exactly:
    the line between the jumps at its two seen ends is that drift."""
    from skinsynth.pipeline.puppet.marker_gaps import join_filled_runs

    frames = np.arange(60, dtype=float)
    truth = np.zeros((60, 2, 3))
    truth[:, 0] = np.array([0.3, -1.0, 2.0]) + np.outer(frames, [0.01, 0.02, -0.005])
    truth[:, 1] = 5.0
    filled = np.zeros((60, 2), dtype=bool)
    filled[20:35, 0] = True  # inside the take
    filled[50:, 1] = True  # at its end: one seen side
    guessed = truth.copy()
    guessed[20:35, 0] = truth[19, 0] + np.array([0.5, 0.1, 0.0])  # held still and off: the drift is linear
    guessed[50:, 1] = 4.0
    joined = join_filled_runs(guessed, filled)
    np.testing.assert_allclose(joined, truth, atol=1e-12)
    assert np.array_equal(join_filled_runs(guessed, np.zeros_like(filled)), guessed)


def test_the_fill_uncertainty_is_the_priors_spread_where_nothing_seen_informs_it():
    """Markers 3–5 move along one direction with the training poses, 0–2 never do: a frame that
    sees marker 3 determines the motion (its fill nearly certain); one that sees only 0–2 knows
    nothing of it, and its fill's expected error is the training poses' own spread of 3–5."""
    from skinsynth.pipeline.puppet.marker_gaps import fill_uncertainty

    rng = np.random.default_rng(6)
    base = rng.normal(size=(6, 3))
    direction = np.zeros((6, 3))
    direction[3:] = rng.normal(size=(3, 3))
    training = base + rng.uniform(-1.0, 1.0, size=(200, 1, 1)) * direction
    missing = np.zeros((3, 6), dtype=bool)
    missing[0, 4:] = True  # sees 0–3
    missing[1, 3:] = True  # sees 0–2 only
    uncertainty = fill_uncertainty(missing, training)
    spread = np.sqrt(np.mean(np.sum((training[:, 3:] - training[:, 3:].mean(axis=0)) ** 2, axis=2)))
    assert uncertainty[2] == 0.0
    assert abs(uncertainty[1] / spread - 1.0) < 1e-6
    assert uncertainty[0] < 0.05 * spread  # 1.9 %: the fit's assumed noise (ridge · v_0) is all that is left


def test_a_rigid_cluster_with_a_marker_missing_recovers_it():
    """Issue 45: four markers riding one bone, one of them missing for a while, the cluster's three
    others carry it exactly (to 1e-6); a marker over a joint (two bones) is no cluster's."""
    from skinsynth.pipeline.puppet.marker_gaps import fill_rigid_clusters, rigid_clusters

    rng = np.random.default_rng(9)
    local = rng.normal(size=(6, 3))
    turns = rotation_exp(rng.normal(size=(80, 3)) * np.linspace(0.0, 1.5, 80)[:, None])
    markers = np.einsum("tab,mb->tma", turns, local) + rng.normal(size=(80, 1, 3))
    bones = rigid_clusters(np.array([[2, 0]] * 4 + [[2, 1], [3, 0]]),
                           np.array([[1.0, 0.0]] * 3 + [[0.95, 0.05], [0.6, 0.4], [1.0, 0.0]]))
    assert bones.tolist() == [2, 2, 2, 2, -1, 3]
    holed = markers.copy()
    holed[30:60, 1] = np.nan  # in the cluster: three others seen
    holed[40:50, 4] = np.nan  # over a joint: left for the subspace
    holed[10:20, 0] = np.nan
    holed[10:20, 2] = np.nan  # two others seen only: left too
    filled, rigid = fill_rigid_clusters(holed, bones, neutral=0)
    assert rigid[30:60, 1].all() and rigid.sum() == 30
    np.testing.assert_allclose(filled[30:60, 1], markers[30:60, 1], atol=1e-6)
    assert np.isnan(filled[40:50, 4]).all() and np.isnan(filled[10:20, [0, 2]]).all()


def test_the_jump_at_a_seen_end_is_the_fills_own_error_there():
    """Where the fill is right (a take on the training poses' subspace), the jump measured at the
    seen sample beside the run, that sample less the fill of it from the others, is ~0 and the run
    stays right; the old jump, the seen sample less the run's first filled one, counted the
    frame's motion between them as error and moved the whole run by it."""
    from skinsynth.pipeline.puppet.marker_gaps import join_filled_runs

    shapes, _ = _poses(frames=80, markers=10, rank=3)
    holed = shapes.copy()
    holed[20:40, 5] = np.nan
    filled, by_subspace, _ = fill_from_training(holed, shapes, 3)
    assert np.abs(filled - shapes).max() < 1e-4  # the fill itself: right
    measured = join_filled_runs(filled, by_subspace, holed, shapes)
    assert np.abs(measured - shapes).max() < 1e-4
    motion = np.abs(shapes[20, 5] - shapes[19, 5]).max()
    assert motion > 1e-3 and np.abs(join_filled_runs(filled, by_subspace) - shapes).max() > 0.5 * motion
