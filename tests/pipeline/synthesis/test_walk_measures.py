"""Walks that explore the clip (issue 48): the per-animation measures against brute force, and
the spread rule that puts transitions between the repeats of a cyclic motion whose repeats differ."""

import numpy as np
import pytest

from skinsynth.pipeline.synthesis.motion_graph import MotionGraph, random_walks, walk_statistics
from skinsynth.pipeline.synthesis.transitions import (select_transitions, transition_costs, transition_threshold,
                                                      virtual_costs)
from skinsynth.pipeline.synthesis.walk_measures import distinct_frames, stuck_loops, stuck_walks


def brute_stuck(walk, fps, longest=2.0, repeats=3):
    """A walk is stuck where some stretch of P frames (2 ≤ P < longest·fps) is played more than
    ``repeats`` times in a row: walk[m:m+P] repeated (repeats + 1) times from m."""
    walk = list(walk)
    for period in range(2, int(np.ceil(longest * fps))):
        for m in range(len(walk) - (repeats + 1) * period + 1):
            piece = walk[m:m + period]
            if all(walk[m + r * period:m + (r + 1) * period] == piece for r in range(repeats + 1)):
                return True
    return False


def test_distinct_frames_and_stuck_walks_match_brute_force():
    rng = np.random.default_rng(3)
    walks = []
    for _ in range(40):  # pieces of playback, some loops replayed 2–6 times, periods 2–30 frames
        pieces = []
        while sum(len(p) for p in pieces) < 120:
            start, period = int(rng.integers(0, 200)), int(rng.integers(2, 31))
            pieces.append(np.tile(np.arange(start, start + period), int(rng.integers(1, 7))))
        walks.append(np.concatenate(pieces)[:120])
    walks = np.stack(walks)
    assert distinct_frames(walks).tolist() == [len(set(w.tolist())) for w in walks]
    fps = 10.0  # loops shorter than 20 frames count
    expected = [brute_stuck(w, fps) for w in walks]
    assert 5 < sum(expected) < 35  # both kinds present
    assert stuck_walks(walks, fps).tolist() == expected


def test_a_loop_counts_as_stuck_only_when_short_and_repeated_more_than_three_times():
    ramp = np.arange(100)
    loop = np.arange(320, 330)  # 10 frames
    walk = lambda times: np.concatenate([ramp, np.tile(loop, times), ramp + 500])  # noqa: E731
    assert stuck_loops(walk(4)[None], 24.0)[0] == 40 and not stuck_walks(walk(3)[None], 24.0)[0]
    assert not stuck_walks(walk(4)[None], 5.0)[0]  # 10 frames at 5 fps is 2 s: not shorter than 2 s
    assert stuck_walks(np.tile(loop, 4)[None], 5.1)[0]
    stats = walk_statistics(walk(5)[None, None], 1000, fps=24.0)
    assert stats["distinct_frames"] == [[210]] and stats["stuck"] == [1]


def cyclic_clip(frames=400, cycles=4, tempo=0.6):
    """Reduced coordinates of a motion that repeats ``cycles`` times and speeds up from 1 − tempo
    to 1 + tempo times its mean (as ``example walker --tempo``): q (F, 4), r (F, 6), the phase."""
    f = np.arange(frames, dtype=np.float64)
    phase = 2 * np.pi * cycles * (f - tempo * frames / np.pi * np.sin(np.pi * f / frames)) / frames
    q = np.stack([np.sin(phase), np.cos(phase), 0.5 * np.sin(2 * phase), 0.3 * np.cos(3 * phase)], axis=1)
    r = np.zeros((frames, 6))
    r[1:, 0] = np.diff(phase)  # the body's speed: the reference bone's step
    r[0] = r[1]
    return q, r, phase


@pytest.mark.parametrize("tempo", [0.5, 0.6])
def test_every_repeat_of_a_cyclic_motion_gets_a_way_across_where_repeats_differ(tempo):
    # Cause (issue 48, a held-out walking bird): T_c = 3 median steps admitted transitions only
    # where the clip's repeats were alike (its fast end), so walks reaching the end stayed there.
    q, r, phase = cyclic_clip(tempo=tempo)
    D, alpha, beta = transition_costs(q, r)
    start = virtual_costs(q, r, alpha, beta)
    threshold = transition_threshold(D)
    cycle = np.floor(phase / (2 * np.pi)).astype(int)

    def departures(spread):
        pairs, _, _, _ = select_transitions(D, threshold, spacing=6, coverage=0.95, start=start, spread=spread)
        return pairs, np.bincount(cycle[pairs[:, 0]], minlength=cycle.max() + 1)

    before, per_cycle_before = departures(0)
    assert (per_cycle_before == 0).any()  # the fault this rule fixes
    pairs, per_cycle = departures(48)  # build-graph's: 4 × --min-segment (12 at 24 fps)
    assert (per_cycle >= 1).all()
    assert set(map(tuple, before.tolist())) <= set(map(tuple, pairs.tolist()))  # only additions
    # the transitions join like phases: a repeat into another, not across the cycle
    jump = np.angle(np.exp(1j * (phase[pairs[:, 0]] - phase[np.maximum(pairs[:, 1], 0)])))
    assert np.abs(jump).max() < 0.6
    # walks on them explore: none stuck, each plays most of the clip
    graph = MotionGraph(len(q), pairs)
    walks = random_walks(graph, 50, 600, np.random.default_rng(0), min_segment=12, transition_probability=0.1,
                         fresh=48)
    assert not stuck_walks(walks, 24.0).any()
    assert np.median(distinct_frames(walks)) >= 0.5 * graph.usable_count


def test_walks_leave_a_loop_they_replay_where_a_short_clip_has_one_way_back():
    # Cause (issue 48): on the 48-frame horse gallop the last frame's one way back is a cycle
    # earlier, and walks left that cycle by a 10 % draw at three of its frames: 15 of 16 walks of
    # 600 frames replayed it more than three times in a row. The graph is the gallop's own.
    pairs = [[12, 36], [36, 12], [1, 25], [25, 1], [47, 23], [19, 43], [6, 17], [17, 6], [30, 41], [41, 30],
             [20, 33], [33, 20], [9, 44], [44, 9], [12, 24], [24, 12], [1, 5]]
    graph = MotionGraph(48, pairs)

    def walks(fresh):
        return random_walks(graph, 64, 600, np.random.default_rng(5), transition_probability=0.1, min_segment=12,
                            fresh=fresh)

    before, after = walks(0), walks(48)
    assert stuck_walks(before, 24.0).mean() > 0.8  # 0.91–0.98 over seeds 0–5
    assert stuck_walks(after, 24.0).mean() < 0.15  # 0–0.05
    assert np.median(distinct_frames(after)) >= 0.5 * graph.usable_count  # 38–46 of 48
    # still walks of the graph: every step plays on or takes one of its transitions
    allowed = {(i, i + 1) for i in range(47)} | {(i, j + 1) for i, j in pairs}
    steps = set(zip(after[:, :-1].ravel().tolist(), after[:, 1:].ravel().tolist()))
    assert steps <= allowed
    # a walk leaving a loop may cut a segment short, never under half of min_segment
    assert walk_statistics(after[None], 48)["shortest_segment"][0] >= 6


def test_a_clip_shorter_than_two_seconds_played_whole_is_not_stuck():
    """Issue 63: a 30-frame clip (1.25 s at 24 fps) played end to end ten times is the clip looping;
    the same loop inside a longer clip is a walk caught in a part of it."""
    whole = np.tile(np.arange(30), 10)[None]
    assert stuck_walks(whole, 24.0)[0] and not stuck_walks(whole, 24.0, clip_frames=30)[0]
    assert stuck_walks(whole, 24.0, clip_frames=31)[0]
    assert walk_statistics(whole[None], 30, fps=24.0)["stuck"] == [0]
    assert walk_statistics(whole[None], 200, fps=24.0)["stuck"] == [1]
