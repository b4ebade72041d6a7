"""Held poses and a threshold that does not depend on sampling (issue 63): generated cyclic clips,
sampled at several frame rates and padded with stills, give the same graph up to resampling."""

import numpy as np
import pytest

from skinsynth.pipeline.inputs.clips import Clips
from skinsynth.pipeline.synthesis.held_poses import HeldPoses, find_held_poses
from skinsynth.pipeline.synthesis.motion_graph import (MotionGraph, default_min_segment, frames_off_part, recurrent_frames,
                                                       walk_statistics)
from skinsynth.pipeline.synthesis.summaries import _ranges
from skinsynth.pipeline.synthesis.synthesis import timed_walk_options
from skinsynth.pipeline.synthesis.transitions import find_transitions, select_held
from skinsynth.pipeline.rig.rotations import rotation_exp

BONES = 6
PIVOTS = np.stack([np.zeros(BONES), np.arange(BONES, dtype=float), np.zeros(BONES)], axis=1)


def chain(times, period=1.0, seed=0):
    """A bone chain whose joints swing with ``period`` seconds at ``times`` (F,) seconds, its root
    travelling on a circle: rotations (F, B, 3, 3), translations (F, B, 3) (each bone about its
    pivot, the chain's pivots carried down it). Two harmonics, so strides are alike but not equal."""
    rng = np.random.default_rng(seed)
    amplitude, phase, axis = rng.uniform(0.2, 0.6, BONES), rng.uniform(0, 2 * np.pi, BONES), rng.normal(size=(BONES, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    angle = amplitude * (np.sin(2 * np.pi * times[:, None] / period + phase)
                         + 0.15 * np.sin(2 * np.pi * times[:, None] / (2.7 * period)))
    local = rotation_exp(angle[..., None] * axis)  # (F, B, 3, 3)
    frames = times.size
    rotations = np.empty((frames, BONES, 3, 3))
    translations = np.empty((frames, BONES, 3))
    root = np.stack([np.cos(0.3 * times), np.zeros(frames), np.sin(0.3 * times)], axis=1) * 3.0
    for b in range(BONES):  # a loop over bones
        if b == 0:
            rotations[:, 0] = local[:, 0]
            translations[:, 0] = root + PIVOTS[0] - np.einsum("fij,j->fi", local[:, 0], PIVOTS[0])
        else:
            rotations[:, b] = rotations[:, b - 1] @ local[:, b]
            joint = np.einsum("fij,j->fi", rotations[:, b - 1], PIVOTS[b]) + translations[:, b - 1]
            translations[:, b] = joint - np.einsum("fij,j->fi", rotations[:, b], PIVOTS[b])
    return rotations, translations


def skin():
    """One vertex per bone, bone 0 the heaviest (the reference): bone_indices, bone_weights (B, 2)."""
    indices = np.stack([np.arange(BONES), (np.arange(BONES) + 1) % BONES], axis=1)
    weights = np.tile([0.8, 0.2], (BONES, 1))
    weights[0] = [1.0, 0.0]
    return indices, weights


def graph_of(rotations, translations, fps):
    """find_transitions at build-graph's defaults for a clip at ``fps``: (Transitions, HeldPoses)."""
    segment = default_min_segment(fps)
    held = find_held_poses(rotations, translations, PIVOTS, float(BONES), segment)
    indices, weights = skin()
    found = find_transitions(rotations, translations, indices, weights, spacing=max(1, segment // 2), coverage=0.95,
                             spread=4 * segment, segment=segment, held=held, fps=fps)
    return found, held


def with_stills(rotations, translations, fps, before=3.0, inside=2.0):
    """The clip with ``before`` s held in its first pose and ``inside`` s held at its middle frame."""
    middle = rotations.shape[0] // 2
    order = np.concatenate([np.zeros(int(before * fps), int), np.arange(middle),
                            np.full(int(inside * fps), middle), np.arange(middle, rotations.shape[0])])
    return rotations[order], translations[order]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_graph_holds_under_resampling_and_stills(seed):
    """The property of issue 63: sampled at 12, 24 or 48 fps, or with 3 s and 2 s of stills, the same
    motion keeps its strongly connected share (of the moving frames) within 5 % of the 24 fps
    clip's, and its threshold within a factor of 1.5 (the steps themselves change 16-fold)."""
    seconds = 6.0
    shares, thresholds = {}, {}
    for fps in (12, 24, 48):
        rotations, translations = chain(np.arange(int(seconds * fps)) / fps, seed=seed)
        found, held = graph_of(rotations, translations, fps)
        assert not len(held.runs)
        shares[fps], thresholds[fps] = found.share, found.threshold
    rotations, translations = with_stills(*chain(np.arange(int(seconds * 24)) / 24, seed=seed), 24)
    found, held = graph_of(rotations, translations, 24)
    assert len(held.runs) == 2
    shares["stills"], thresholds["stills"] = found.share, found.threshold
    for key in (12, 48, "stills"):
        assert abs(shares[key] - shares[24]) <= 0.05, (key, shares)
        assert 1 / 1.5 < thresholds[key] / thresholds[24] < 1.5, (key, thresholds)
    assert shares[24] > 0.9


def test_held_runs_are_found_in_any_unit_and_never_cross_a_clip():
    rotations, translations = with_stills(*chain(np.arange(96) / 24.0), 24)
    held = find_held_poses(rotations, translations, PIVOTS, float(BONES), 12)
    # the 72 still frames and the clip's first frame (the same pose); the 48 and the middle frame
    assert held.runs.tolist() == [[0, 72], [120, 168]]
    scaled = find_held_poses(rotations, 100.0 * translations, 100.0 * PIVOTS, 100.0 * BONES, 12)  # centimetres
    assert scaled.runs.tolist() == held.runs.tolist()
    split = find_held_poses(rotations, translations, PIVOTS, float(BONES), 12, clips=Clips(("a", "b"), (40, 177)))
    assert split.runs.tolist() == [[0, 39], [40, 72], [120, 168]]
    # a pose held for less than min_frames is no run, nor is a clip that always moves
    assert not len(find_held_poses(*chain(np.arange(96) / 24.0), PIVOTS, float(BONES), 12).runs)
    short = find_held_poses(rotations[60:], translations[60:], PIVOTS, float(BONES), 14)
    assert short.runs.tolist() == [[60, 108]]


def test_a_held_pose_is_one_place():
    """Walks show a held pose for ``keep`` frames, go on from its last by its skip, never show the
    frames between, and count it once; no transition leaves or enters a hidden frame."""
    rotations, translations = with_stills(*chain(np.arange(144) / 24.0), 24)
    found, held = graph_of(rotations, translations, 24)
    hidden = held.hidden
    assert hidden.sum() == (72 - 12) + (48 - 12)
    pairs = found.pairs
    for skip in held.skips:
        assert (pairs == skip).all(axis=1).any()
    layout = Clips.single(rotations.shape[0])
    assert not hidden[pairs[:, 0]].any() and not hidden[layout.targets(pairs[:, 1])].any()
    MotionGraph(rotations.shape[0], pairs, forbidden=hidden)  # walks exist without the hidden frames
    shown = np.flatnonzero(~hidden)[:50]  # the first still's 12 frames, its skip, its last frame and on
    assert shown[11] == held.skips[0][0] == 11 and shown[12] == held.skips[0][1] + 1 == 72
    stats = walk_statistics(shown[None, None], rotations.shape[0], fps=24.0, held=held)
    assert stats["distinct_frames"][0][0] == np.unique(shown).size
    assert stats["distinct_poses"][0][0] == np.unique(held.representative[shown]).size < np.unique(shown).size


def test_without_runs_select_held_is_select_transitions():
    rotations, translations = chain(np.arange(120) / 24.0)
    plain, _ = graph_of(rotations, translations, 24)
    again = select_held(plain.D, plain.threshold, 2, 6, 0.95, start=plain.virtual, spread=48, segment=12,
                        held=HeldPoses(np.zeros((0, 2), np.int64), 12, 120))
    assert np.array_equal(again[0], plain.pairs) and np.array_equal(again[1], plain.costs)
    assert recurrent_frames(120, plain.pairs, segment=12, hidden=np.zeros(120, bool)).mean() == plain.share


def test_frames_off_the_part_are_told_apart():
    """A lead-in (0–9), a loop (10–19: 19 → 10) and what a one-way event leads to (20–29, playback
    from 19 only), by hand; with a segment of 4 the loop still holds (a seam at 10, 10 frames on)."""
    for segment in (1, 4):
        on, after, before = frames_off_part(30, [[19, 9]], segment=segment)
        assert np.flatnonzero(on).tolist() == list(range(10, 20))
        assert np.flatnonzero(after).tolist() == list(range(20, 30))
        assert np.flatnonzero(before).tolist() == list(range(10))
    # a second way back from 25 makes 20–25 part of it; 26–29 stay one-way; hidden frames are off it
    on, after, _ = frames_off_part(30, [[19, 9], [25, 9]], segment=1)
    assert np.flatnonzero(on).tolist() == list(range(10, 26)) and np.flatnonzero(after).tolist() == list(range(26, 30))
    hidden = np.zeros(30, bool)
    hidden[22:24] = True
    on, after, before = frames_off_part(30, [[19, 9], [25, 9]], segment=1, hidden=hidden)
    assert not (on | after | before)[22:24].any() and np.flatnonzero(on).tolist() == list(range(10, 20))
    assert _ranges([3, 4, 5, 9, 12, 13], Clips.single(30)) == "3–5, 9, 12–13"
    assert _ranges([3, 4, 31], Clips(("a", "b"), (30, 10))) == "a:3–a:4, b:1"


def test_walks_blend_and_branch_in_time():
    """At 24 fps the walk options are exactly the old defaults; at another rate the same blend time
    (capped) and the same chance of a transition per second."""
    assert timed_walk_options(24.0) == {"window": 4, "transition_probability": 0.1}
    assert timed_walk_options(12.0)["window"] == 2 and timed_walk_options(48.0)["window"] == 8
    assert timed_walk_options(96.0)["window"] == 12 and timed_walk_options(1.0)["window"] == 1
    for fps in (12.0, 30.0, 48.0, 96.0):
        stay = (1.0 - timed_walk_options(fps)["transition_probability"]) ** fps  # no transition in a second
        assert stay == pytest.approx(0.9 ** 24, rel=1e-12)
