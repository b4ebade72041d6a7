"""The planted walker turning on one foot (issue 64, part 2): a generated pivot with its truth.

A real dancer's feet do not only rest or step: they turn on the spot, about the ball of the foot
(Zheng 2013's dancer, ``geomvideo_dance``: 44 % of its contact steps move more than 0.5 % of the
height, a foot turning about its ball). Such a foot is planted (it bears the weight, its sole on
the floor) and yet its contact vertices move, on arcs about one point that does not. A plant that
held the patch still, or kept its orientation, would tear the turn; one that let it go would let
the pivot slide. :func:`pivot_walker` makes that case with its closed-form truth: the pivot's
vertex, which the input keeps exactly still while the rest of the sole sweeps round it.
"""

from typing import NamedTuple

import numpy as np

from .examples import (WALKER_ANKLE_Y, WALKER_CLEARANCE, WALKER_HIP_X, WALKER_HIP_Y, WALKER_KNEE_Y, WALKER_PARTS,
                       WalkerRig, _rotation, _two_link, walker)

#: Within one pivot (its share ``u`` in [0, 1)): both feet rest until ``_REST``; the left
#: (pivot) foot steps in place until ``_STEP``; then the body turns on the left foot's ball while
#: the right foot swings round and sets down. The turn runs between ``_TURN_HOLD`` and
#: ``1 − _TURN_HOLD`` of that swing, so the swinging foot is well clear of the floor (3.5 % of the
#: height) before it moves sideways, and after it.
_REST, _STEP, _TURN_HOLD = 0.2, 0.4, 0.2
_SWAY = 0.03  # the pelvis over the supporting foot, metres

#: Seconds a pivot takes (``skinsynth example walker --pivot``: ``frames_per_pivot`` from ``--fps``).
PIVOT_SECONDS = 2.0


class PivotTruth(NamedTuple):
    """What :func:`pivot_walker` does, feet in the order (left, right).

    - ``planted`` (F, 2) bool: the foot rests on the floor (its sole on y = 0).
    - ``turning`` (F,) bool: the body turns on the left foot's ball in this frame's step to the
      next (the left foot planted, its sole sweeping round the ball).
    - ``ball_vertices`` (2,) int: each foot's pivot vertex, the lowest of its sole near the ball.
    - ``balls`` (F, 2, 3): their world positions; the left one stays exactly still through every
      turn (and every rest), the right one while that foot rests.
    - ``heading`` (F,) radians: the figure's turn about +y.
    """
    planted: np.ndarray
    turning: np.ndarray
    ball_vertices: np.ndarray
    balls: np.ndarray
    heading: np.ndarray


def _ease(x):
    """0 → 1 with zero speed at both ends (a cycloid, as the walker's swing)."""
    x = np.clip(x, 0.0, 1.0)
    return x - np.sin(2.0 * np.pi * x) / (2.0 * np.pi)


def pivot_walker(pivots=4, frames_per_pivot=48, turn=np.pi, rings=24, segments=10, rig=False):
    """The planted walker (``walker(planted=True)``'s mesh and skin) standing and turning ``turn``
    radians (default 180°) about the ball of its left foot, ``pivots`` times, one every
    ``frames_per_pivot`` frames (2 s at 24 fps by default; the turn itself takes 0.7 s).

    Each pivot: both feet rest (a fifth of it); the left foot steps in place, lifted and set down
    where it stood (the body swayed over the right foot), so the pivot foot's plants begin and end
    as a dancer's do; then the body turns about the vertical through the left foot's ball vertex
    (swayed over the left foot) while the right foot lifts, swings round and sets down. The left
    foot stays flat on the floor through the turn: its ball vertex stays exactly where it is and
    the rest of its sole sweeps arcs round it (its heel up to 3 % of the height a frame). The legs are
    two links posed by analytic inverse kinematics in the figure's own frame (knees forward), the
    feet level, the arms a little out. With ``turn`` = 180°, two pivots make a whole turn and
    bring the figure back to where it started: the default four repeat exactly, which gives a
    motion graph exact transitions.

    Returns (vertices (F, V, 3), faces (T, 3), :class:`PivotTruth`[, :class:`.examples.WalkerRig`
    with ``rig=True``]), metres, Y up, F = ``pivots × frames_per_pivot``.
    """
    if pivots < 1 or frames_per_pivot < 12:
        raise ValueError("a pivot walker needs at least one pivot of at least 12 frames")
    _, faces, base = walker(frames=2, cycles=1, rings=rings, segments=segments, planted=True, rig=True)
    rest, weights, joints = base.rest, base.weights, base.joints
    joint = dict(zip(WALKER_PARTS, joints))
    parents = {part: (None if p < 0 else WALKER_PARTS[p]) for part, p in zip(WALKER_PARTS, base.parents)}
    balls = []
    for side in ("l", "r"):  # the lowest vertex of the sole wholly the foot's, nearest the ball
        foot = np.flatnonzero(weights[:, WALKER_PARTS.index(f"foot_{side}")] == 1.0)
        low = foot[rest[foot, 1] <= rest[foot, 1].min() + 1e-9]
        x = WALKER_HIP_X if side == "l" else -WALKER_HIP_X
        balls.append(int(low[np.argmin(np.hypot(rest[low, 0] - x, rest[low, 2] - 0.14))]))
    ball_fig = rest[balls[0]].copy()  # the left ball in the figure's frame (the left foot rests where it stood)

    frames = pivots * frames_per_pivot
    u = (np.arange(frames) % frames_per_pivot) / frames_per_pivot
    k = np.arange(frames) // frames_per_pivot
    step = np.clip((u - _REST) / (_STEP - _REST), 0.0, 1.0)
    swing = np.clip((u - _STEP) / (1.0 - _STEP), 0.0, 1.0)
    progress = _ease((swing - _TURN_HOLD) / (1.0 - 2.0 * _TURN_HOLD))
    heading = turn * (k + progress)
    lift_left = WALKER_CLEARANCE * np.sin(np.pi * step) ** 2
    lift_right = WALKER_CLEARANCE * np.sin(np.pi * swing) ** 2
    sway = _SWAY * (np.sin(np.pi * swing) ** 2 - np.sin(np.pi * step) ** 2)  # +x: over the left foot

    # The pose in the figure's own frame: rotations and joint positions per part.
    leg = WALKER_HIP_Y - WALKER_ANKLE_Y
    pelvis = np.stack([sway, np.full(frames, WALKER_ANKLE_Y + 0.96 * leg), np.zeros(frames)], axis=-1)
    eye = np.broadcast_to(np.eye(3), (frames, 3, 3))
    rot = {"pelvis": eye, "chest": eye, "foot_l": eye, "foot_r": eye,
           "arm_l": np.broadcast_to(_rotation(2, 0.1), (frames, 3, 3)),
           "arm_r": np.broadcast_to(_rotation(2, -0.1), (frames, 3, 3))}
    for side, x, lift in (("l", WALKER_HIP_X, lift_left), ("r", -WALKER_HIP_X, lift_right)):
        hip = pelvis + np.array([x, 0.0, 0.0])
        ankle = np.stack([np.full(frames, x), WALKER_ANKLE_Y + lift, np.zeros(frames)], axis=-1)
        rot[f"thigh_{side}"], rot[f"shin_{side}"] = _two_link(hip, ankle, WALKER_HIP_Y - WALKER_KNEE_Y,
                                                              WALKER_KNEE_Y - WALKER_ANKLE_Y)
    pos = {}
    for part in WALKER_PARTS:  # parents first
        parent = parents[part]
        pos[part] = pelvis if parent is None else pos[parent] + np.einsum("fab,b->fa", rot[parent],
                                                                         joint[part] - joint[parent])

    # Into the world: turned by the heading about the left ball, which stays where it first stood.
    yaw = _rotation(1, heading)
    shift = ball_fig - np.einsum("fab,b->fa", yaw, ball_fig)  # Y(ψ) b + shift = b
    rotations = np.stack([yaw @ rot[part] for part in WALKER_PARTS], axis=1)
    positions = np.stack([np.einsum("fab,fb->fa", yaw, pos[part]) + shift for part in WALKER_PARTS], axis=1)
    translations = positions - np.einsum("fkab,kb->fka", rotations, joints)
    vertices = np.zeros((frames,) + rest.shape)
    for k in range(len(WALKER_PARTS)):  # linear blend skinning, part by part (the walker's peak memory)
        used = weights[:, k] > 0.0
        vertices[:, used] += weights[used, k][None, :, None] * (
            np.einsum("fab,vb->fva", rotations[:, k], rest[used]) + translations[:, k, None])

    planted = np.stack([lift_left < 1e-12, lift_right < 1e-12], axis=1)
    turning = np.append(np.abs(np.diff(heading)) > 1e-12, False)  # a pivot's last frame is still
    truth = PivotTruth(planted=planted, turning=turning, ball_vertices=np.array(balls), balls=vertices[:, balls],
                       heading=heading)
    if not rig:
        return vertices, faces, truth
    parent_ids = np.array([-1 if parents[p] is None else WALKER_PARTS.index(parents[p]) for p in WALKER_PARTS])
    return vertices, faces, truth, WalkerRig(rest=rest, parents=parent_ids, joints=joints, weights=weights,
                                             rotations=rotations, translations=translations)
