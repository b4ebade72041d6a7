"""One test per cause of pops, drift and trapped walks found on the real captures (issue 10),
each on a small case that reproduced it."""

import numpy as np
import pytest

from skinsynth.pipeline.synthesis.motion_graph import (MotionGraph, constrained_walks, random_walks, recurrent_frames,
                                                       walk_statistics)
from skinsynth.pipeline.rig.rotations import heading_and_posture, rotation_exp, rotation_log
from skinsynth.pipeline.synthesis.splicing import blend_series, reference_alignment, seam_windows
from skinsynth.pipeline.synthesis.transitions import select_transitions
from splice_cases import chain_clip, second_differences, skin, splice_clip, walk


def step_angles(R):
    """Angle of each one-frame step of a rotation series (..., M, 3, 3) -> (..., M − 1)."""
    return np.linalg.norm(rotation_log(R[..., 1:, :, :] @ np.swapaxes(R[..., :-1, :, :], -1, -2)), axis=-1)


def test_blend_is_smooth_where_rotations_cross_half_a_turn():
    # Cause: key-vertex rotations near π (the samba reached 3.14 rad) flip their axis-angle
    # vectors; blending those vectors made garbage inside windows. The blend works on relative
    # rotations now: a seam between two nearby states of a rotation turning through π is smooth.
    frames = 80
    axis = np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8])
    angle = np.pi - 0.4 + 0.01 * np.arange(frames)  # crosses π at frame 40
    U = rotation_exp((angle[:, None] * axis)[:, None])  # (F, 1, 3, 3)
    S = np.zeros((frames, 1, 0))
    sources = walk((20, 45), (36, 60))[None]  # i = 44, j = 35: a jump of 0.09 rad across π
    windows = seam_windows(sources, 4)
    animation, frame, R, _ = blend_series(U, S, sources, windows)
    out = U[sources[0]].copy()
    out[frame, 0] = R[:, 0]
    steps = step_angles(out[:, 0])
    assert steps.max() < 0.03  # the input steps by 0.01; the 0.09 jump is spread over 9 frames
    assert np.abs(np.diff(steps, n=1)).max() < 0.02


def test_splicing_does_not_depend_on_where_the_mesh_sits():
    # Cause: bones blended about the world origin (rotation by log, translation linearly) moved
    # vertices far from the origin by lever arm × angle² (the samba's poorly fitted bone 12 turned
    # 0.8 rad in a frame: 2.5× the input's acceleration, growing with the window). Blended about
    # their rest centroids, the output is the same wherever the clip is placed.
    clip = chain_clip(frames=120, period=20.0, second=33.0)
    offset = np.array([40.0, -25.0, 10.0])
    moved = dict(clip, rest=clip["rest"] + offset,
                 translations=clip["translations"] + offset - clip["rotations"] @ offset)
    sources = np.stack([walk((10, 40), (74, 105)), walk((30, 60), (14, 45))])
    F, t = splice_clip(clip, sources, window=6)
    F2, t2 = splice_clip(moved, sources, window=6)
    assert np.abs(F2 - F).max() < 1e-9
    shifted = skin(moved, F2[0], t2[0]) - offset
    assert np.abs(shifted - skin(clip, F[0], t[0])).max() < 1e-8
    # About the origin instead, the far-away copy is rougher than the near one.
    F3, t3 = splice_clip(moved, sources, window=6, pivots=np.zeros((clip["rotations"].shape[1], 3)))
    assert second_differences(skin(moved, F3[0], t3[0])).max() > 1.2 * second_differences(skin(clip, F[0], t[0])).max()


def test_a_seam_from_the_clips_last_frame_keeps_its_velocity():
    # Cause: with no frame after the clip's last, the blend assumed the walk went on as j does,
    # which put the whole velocity change at the seam (1.8× the input's acceleration here).
    clip = chain_clip(frames=120, period=20.0, second=33.0)
    base = second_differences(skin(clip, clip["rotations"], clip["translations"])).max()
    sources = walk((100, 120), (86, 106))[None]  # i = 119, the last frame; j = 85
    for window in (4, 8):
        F, t = splice_clip(clip, sources, window=window)
        assert second_differences(skin(clip, F[0], t[0])).max() < 1.2 * base


def bobbing_reference(frames=200, seed=0):
    """A reference bone that walks and turns on the ground while it bobs and rocks (F, 3, 3), (F, 3)."""
    rng = np.random.default_rng(seed)
    f = np.arange(frames)
    yaw = 0.01 * f + 0.2 * np.sin(f / 9.0)
    tilt = 0.15 * np.sin(f / 5.0 + rng.uniform(0, 6)) + 0.05 * np.sin(f / 3.1)
    R = rotation_exp(np.stack([tilt, yaw, 0.5 * tilt], axis=1))
    t = np.stack([0.03 * f, 0.1 * np.sin(f / 4.0) + 0.02 * np.sin(f / 2.3), 0.02 * f], axis=1)
    return R, t


def test_heading_and_posture_split_a_pose_and_the_posture_ignores_ground_motion():
    R, t = bobbing_reference()
    up, pivot = np.array([0.0, 1.0, 0.0]), np.array([0.2, 1.0, -0.3])
    H_R, H_t, P_R, P_t = heading_and_posture(R, t, pivot, up)
    assert np.abs(H_R @ P_R - R).max() < 1e-12
    assert np.abs(np.einsum("fij,fj->fi", H_R, P_t) + H_t - t).max() < 1e-12
    assert np.abs(H_R @ up - up).max() < 1e-12 and np.abs(H_t @ up).max() < 1e-12  # a turn about up, a ground shift
    # A turn about up and a ground shift of the whole clip leaves the posture as it was.
    turn = rotation_exp(np.array([0.0, 2.0, 0.0]))
    shift = np.array([3.0, 0.0, -1.0])
    _, _, P_R2, P_t2 = heading_and_posture(turn @ R, t @ turn.T + shift, pivot, up)
    assert np.abs(P_R2 - P_R).max() < 1e-12 and np.abs(P_t2 - P_t).max() < 1e-10


def test_ground_alignment_keeps_long_walks_on_the_ground():
    # Cause: eq. 7 moves each segment by a full rigid transform, so height and tilt errors add
    # up seam after seam (the horse gallop ended 0.7 of its height off the ground after 3,000
    # frames and turned over). Aligned by a turn about up and a ground shift, every output frame's
    # height and tilt stay in the input's range (up to what the blend mixes inside a window).
    R, t = bobbing_reference()
    up, pivot = np.array([0.0, 1.0, 0.0]), np.zeros(3)
    graph = MotionGraph(200, [(i, j) for i in range(30, 190, 23) for j in range(12, 190, 31) if abs(i - j) > 8])
    sources = random_walks(graph, 6, 3000, np.random.default_rng(1), min_segment=6)
    height_in = t[:, 1]
    tilt_in = np.degrees(np.arccos(np.clip((R @ up) @ up, -1, 1)))
    R_g, t_g = reference_alignment(R, t, sources, up=up, pivot=pivot, window=4)
    tilt_g = np.degrees(np.arccos(np.clip((R_g @ up) @ up, -1, 1)))
    margin = 0.05 * np.ptp(height_in)
    assert height_in.min() - margin <= t_g[..., 1].min() and t_g[..., 1].max() <= height_in.max() + margin
    assert tilt_g.max() <= tilt_in.max() + 1.0
    R_f, t_f = reference_alignment(R, t, sources)  # Zheng's eq. 7
    assert np.ptp(t_f[..., 1]) > 5 * np.ptp(height_in)
    # Away from windows each segment is the input turned about up and shifted on the ground.
    lone = walk((10, 60), (31, 90))[None]
    R_l, t_l = reference_alignment(R, t, lone, up=up, pivot=pivot, window=4)
    assert np.abs(R_l[0, :45] - R[10:55]).max() < 1e-12
    turn = R_l[0, 60:] @ np.swapaxes(R[41:90], -1, -2)  # the second segment past its window
    assert np.abs(turn - turn[0]).max() < 1e-9 and np.abs(turn[0] @ up - up).max() < 1e-9
    assert np.abs(t_l[0, 60:, 1] - t[41:90, 1]).max() < 1e-9


def test_transitions_are_spread_out_and_admitted_until_walks_reach_the_clip():
    # Cause: every local minimum below T_c was a transition (96 on the horse's exact loop, 68 on
    # a 3-bone samba leg; walks seamed every ~6 frames), and a cloth with none below T_c could
    # not be synthesised at all.
    frames = 60
    i, j = np.indices((frames, frames))
    D = 1.0 + 0.001 * (i + j)
    D[np.abs(i - j) == 20] = 0.0  # an exact loop of period 20: a flat valley
    pairs, costs, admitted, share = select_transitions(D, threshold=0.5, spacing=5, coverage=0.0)
    loop = pairs[np.abs(pairs[:, 0] - pairs[:, 1]) == 20]
    assert len(pairs) == len(loop) and admitted == 0
    for a in range(len(loop)):  # no two within 5 frames of each other in both i and j
        near = (np.abs(loop[:, 0] - loop[a, 0]) <= 5) & (np.abs(loop[:, 1] - loop[a, 1]) <= 5)
        assert near.sum() == 1
    assert 8 <= len(loop) <= 16
    # No pair below T_c: the cheapest ones that join the clip into one cycle are admitted.
    D2 = 5.0 + np.abs(np.subtract.outer(np.arange(frames), np.arange(frames)) % 7)
    pairs, costs, admitted, share = select_transitions(D2, threshold=1.0, spacing=3, coverage=0.9)
    assert admitted == len(pairs) > 0 and share >= 0.9
    assert recurrent_frames(frames, pairs).mean() == pytest.approx(share)
    # ... but never past admit_scale × T_c.
    pairs, _, admitted, share = select_transitions(D2, threshold=1.0, spacing=3, coverage=0.9, admit_scale=4.0)
    assert len(pairs) == 0 and share < 0.1


def test_recurrent_frames_and_walk_statistics_on_a_known_graph():
    # 0..9 with 8 → 3 (continue at 4): frames 4..8 form the cycle; 9 is a dead end, 0..3 transient.
    assert np.flatnonzero(recurrent_frames(10, [(8, 3)])).tolist() == [4, 5, 6, 7, 8]
    sources = np.array([[[4, 5, 6, 7, 8, 4, 5, 6, 7, 8], [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]]])
    stats = walk_statistics(sources, 10)
    assert stats["transitions"] == [1] and stats["coverage"] == [1.0]
    assert stats["mean_segment_frames"] == [20 / 3] and stats["shortest_segment"] == [10]


def trap_graph():
    """40 frames: an early loop 5..15 (15 → 5), playback on into a late loop 25..35 (35 → 25), and
    a way back 27 → 3 that leaves two frames after the late loop's only way in."""
    return 40, [(15, 4), (35, 24), (27, 2)]


def test_a_way_back_a_strict_walk_cannot_take_is_not_recurrent():
    # Cause: on the samba's arm the way back from the late frames left two frames after the only
    # way in; the frame graph counted the whole clip as one part, walks of min_segment frames
    # stayed in the late part (a median 32 % of the frames played).
    frames, pairs = trap_graph()
    assert np.flatnonzero(recurrent_frames(frames, pairs)).tolist() == list(range(3, 36))
    assert np.flatnonzero(recurrent_frames(frames, pairs, segment=4)).tolist() == list(range(3, 28))
    assert np.flatnonzero(recurrent_frames(frames, pairs, segment=3)).tolist() == list(range(3, 36))


def test_walks_enter_a_trap_only_as_their_ending():
    frames, pairs = trap_graph()
    graph = MotionGraph(frames, pairs)
    trapped = graph.trapped(False, 4).reshape(frames, 4)
    assert np.flatnonzero(trapped.any(axis=1)).tolist() == list(range(25, 36))
    assert not trapped[3:25].any() and trapped[28:36, -1].all()
    ending = 12
    sources = random_walks(graph, 300, 200, np.random.default_rng(3), min_segment=4, fresh=ending)
    late = sources >= 28  # the trap's own frames and the dead end after it
    assert not late[:, :-(ending + 1)].any()  # entered with at most ``ending`` steps left
    assert late[:, -(ending + 1):].any(axis=1).mean() > 0.1  # its frames are still played, as endings (0.2)
    assert set(np.unique(sources[:, 0])) <= set(range(0, 28))
    # Without loop avoidance (fresh = 0) the walks are as they were: most end up in the trap.
    legacy = random_walks(graph, 300, 200, np.random.default_rng(3), min_segment=4)
    assert (legacy[:, 100] >= 25).mean() > 0.5
    # A target inside a trap (of the frame graph too, here) is still reached, and the walk goes on from it.
    sealed = MotionGraph(frames, [(15, 2), (35, 24)])
    assert sealed.trapped(False, 1)[25:36].all()
    targeted = constrained_walks(sealed, 4, 200, [(30, 10)], np.random.default_rng(0), min_segment=4, fresh=ending)
    assert (targeted[:, 10] == 30).all() and (targeted[:, 11:] >= 25).all()
