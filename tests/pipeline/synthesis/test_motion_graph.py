import time

import numpy as np
import pytest

from skinsynth.pipeline.errors import OptionError
from skinsynth.pipeline.synthesis.motion_graph import (MotionGraph, constrained_walks, diversity_filter, overlap,
                                             random_walks, seams)


def rich_transitions(frames=48, count=20, seed=0):
    """A loop back from the last frame plus random candidate-like pairs (i, j ≥ 1, |i − j| ≥ 2)."""
    rng = np.random.default_rng(seed)
    pairs = [(frames - 1, 0)]
    while len(pairs) < count:
        i, j = rng.integers(1, frames - 1, size=2)
        if abs(i - j) >= 2 and (i, j) not in pairs:
            pairs.append((int(i), int(j)))
    return np.array(pairs)


def assert_walks_on_graph(graph, sources, usable_only=False):
    assert graph.has_edges(sources[:, :-1], sources[:, 1:], usable_only=usable_only).all()


# ---------------------------------------------------------------------------- graph and pruning


def test_backward_transition_from_last_frame_keeps_all_frames():
    graph = MotionGraph(20, [(19, 3)])  # 19 → 4: frames 0..19 all reach the cycle 4..19
    assert graph.usable.all() and graph.usable_count == 20
    assert not graph.dead_ends.any()
    assert list(graph.successors(19)) == [4]
    assert list(graph.successors(5)) == [6]


def test_frames_after_the_last_transition_source_are_dead_ends():
    graph = MotionGraph(20, [(17, 3)])  # 17 → 4; 18 → 19 has no way back
    assert graph.usable_count == 18
    assert graph.dead_ends[18:].all() and graph.usable[:18].all()
    assert list(graph.successors(17)) == [4]  # playback 17 → 18 is not in the usable subgraph
    assert "2 dead ends" in graph.describe()


def test_transition_into_dead_end_region_is_pruned():
    # cycle 6..20 via (20, 5); (10, 24) jumps to 25..29, which runs off the clip's end
    graph = MotionGraph(30, [(20, 5), (10, 24)])
    assert graph.usable[:21].all() and not graph.usable[21:].any()
    assert list(graph.successors(10)) == [11]
    assert graph.has_edges(10, 25) and not graph.has_edges(10, 25, usable_only=True)


def test_no_transition_raises_clear_error():
    with pytest.raises(OptionError, match="no repeated states.*--threshold-scale"):
        MotionGraph(30, np.zeros((0, 2), int))
    with pytest.raises(OptionError, match="no transition leads back"):
        MotionGraph(30, [(5, 20), (8, 25)])  # forward jumps only: every walk ends at frame 29


def test_forbidden_frames_can_break_every_cycle():
    with pytest.raises(OptionError, match="1 forbidden"):
        MotionGraph(20, [(19, 3)], forbidden=np.arange(20) == 10)


def test_edges_follow_the_walk_semantics():
    graph = MotionGraph(10, [(9, 2), (6, 2), (6, 2), (4, 4), (5, 9)])
    # (9, 2): 9 → 3; (6, 2): 6 → 3 (duplicate dropped); (4, 4) is playback; (5, 9): j + 1 = 10 is past the end
    assert graph.transitions.tolist() == [[6, 2], [9, 2]]
    assert graph.has_edges([0, 8, 9, 6, 6, 9], [1, 9, 3, 3, 7, 0]).tolist() == [True, True, True, True, True, False]
    assert not graph.has_edges(9, 10) and not graph.has_edges(5, 10)


def test_the_wrap_is_the_edge_i_to_0():
    # (19, −1): after 19, continue at frame 0, the loop of a one-cycle clip; nothing else returns.
    graph = MotionGraph(20, [(19, -1)])
    assert graph.usable.all() and graph.transitions.tolist() == [[19, -1]]
    assert list(graph.successors(19)) == [0] and list(graph.successors(0)) == [1]
    assert graph.has_edges([19, 19, 18, 5], [0, 1, 0, 6]).tolist() == [True, False, False, True]
    with pytest.raises(OptionError, match="no transition leads back"):
        MotionGraph(20, np.zeros((0, 2), int))
    # A near-repeat across the ends: after 17, continue at 0; 18 and 19 become a dead-end tail.
    tail = MotionGraph(20, [(17, -1), (12, 3)])
    assert list(tail.successors(17)) == [0] and tail.dead_ends[18:].all() and tail.usable[:18].all()
    assert tail.has_edges(17, 0) and tail.has_edges(17, 18) and not tail.has_edges(12, 0)
    # Frame 0 forbidden: the wrap has nowhere to land and is dropped.
    forbidden = np.zeros(20, bool)
    forbidden[0] = True
    assert MotionGraph(20, [(19, -1), (19, 5)], forbidden=forbidden).transitions.tolist() == [[19, 5]]
    # Walks reach frame 0 only through the wrap, and play the clip in order around it.
    sources = random_walks(graph, 50, 100, np.random.default_rng(0), min_segment=4)
    assert_walks_on_graph(graph, sources, usable_only=True)
    assert np.array_equal(sources, (sources[:, :1] + np.arange(100)) % 20)
    for k, pairs in seams(sources):
        assert pairs.tolist() == [[19, -1]] * len(k)
    walks = constrained_walks(graph, 5, 60, [(0, 30), (19, 49)], np.random.default_rng(1), min_segment=4)
    assert (walks[:, 30] == 0).all() and (walks[:, 49] == 19).all()
    assert_walks_on_graph(graph, walks)
    with pytest.raises(OptionError, match="j in −1"):
        MotionGraph(20, [(19, -2)])
    with pytest.raises(OptionError, match="i in 0"):
        MotionGraph(20, [(-1, 5)])


# ---------------------------------------------------------------------------- random walks


def test_random_walks_are_walks_of_the_usable_graph():
    graph = MotionGraph(48, rich_transitions())
    rng = np.random.default_rng(1)
    sources = random_walks(graph, 200, 300, rng)
    assert sources.shape == (200, 300)
    assert graph.usable[sources].all()
    assert_walks_on_graph(graph, sources, usable_only=True)
    assert len(np.unique(sources[:, 0])) > 20  # starts spread over the usable frames
    assert sum(len(k) for k, _ in seams(sources)) > 200 * 10


def test_random_walks_enter_dead_ends_only_to_end_there():
    # 10 → 25 leads into frames that can only play off the end; 20 → 6 closes the cycle
    graph = MotionGraph(30, [(20, 5), (10, 24), (15, 2)])
    sources = random_walks(graph, 300, 200, np.random.default_rng(2), start=0, transition_probability=0.9,
                           min_segment=1)
    assert_walks_on_graph(graph, sources)
    assert (sources[:, 0] == 0).all()
    dead = graph.dead_ends[sources]
    # Once in a dead end a walk plays on to its last frame, which it reaches exactly there.
    entered = dead.argmax(axis=1)
    for walk, at, any_dead in zip(sources, entered, dead.any(axis=1)):
        if any_dead:
            assert graph.dead_ends[walk[at:]].all() and (np.diff(walk[at:]) == 1).all()
    assert dead[:, -1].any()  # some walks do end in the tail: those frames are played
    assert not dead[:, :150].any()  # a 5-frame tail is only entered near the walk's end


def test_random_walks_avoid_forbidden_frames():
    forbidden = np.zeros(48, bool)
    forbidden[[12, 13, 30]] = True
    transitions = np.concatenate([rich_transitions(), [[11, 14], [29, 31], [40, 5]]])
    graph = MotionGraph(48, transitions, forbidden=forbidden)
    sources = random_walks(graph, 300, 300, np.random.default_rng(3))
    assert not forbidden[sources].any()
    assert_walks_on_graph(graph, sources)


def test_random_walks_respect_min_segment_after_the_first_segment():
    graph = MotionGraph(48, rich_transitions())
    sources = random_walks(graph, 300, 300, np.random.default_rng(4), transition_probability=1.0, min_segment=5)
    for k, _ in seams(sources):
        if len(k) > 1:
            assert np.diff(k).min() >= 5
    # with probability 1 the walks transition as soon as allowed: many seams
    assert np.mean([len(k) for k, _ in seams(sources)]) > 20


def test_random_walks_are_deterministic_per_seed():
    graph = MotionGraph(48, rich_transitions())
    a = random_walks(graph, 50, 200, np.random.default_rng(7))
    b = random_walks(graph, 50, 200, np.random.default_rng(7))
    c = random_walks(graph, 50, 200, np.random.default_rng(8))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_random_walks_reject_unusable_start():
    graph = MotionGraph(20, [(17, 3)])
    with pytest.raises(OptionError, match="start frame 19 is a dead end"):
        random_walks(graph, 3, 10, np.random.default_rng(0), start=19)


# ---------------------------------------------------------------------------- constrained walks


def test_targets_land_exactly():
    graph = MotionGraph(48, rich_transitions())
    targets = [(20, 100), (5, 180), (33, 181 + 40)]
    sources = constrained_walks(graph, 100, 400, targets, np.random.default_rng(5), start=10, end=40)
    assert sources.shape == (100, 400)
    for f, t in targets + [(10, 0), (40, 399)]:
        assert (sources[:, t] == f).all(), (f, t)
    assert_walks_on_graph(graph, sources)
    assert len({tuple(row) for row in sources}) > 90  # still diverse between the targets


def test_targets_with_free_start_and_end():
    graph = MotionGraph(48, rich_transitions())
    sources = constrained_walks(graph, 100, 200, [(30, 50), (31, 51)], np.random.default_rng(6))
    assert (sources[:, 50] == 30).all() and (sources[:, 51] == 31).all()
    assert_walks_on_graph(graph, sources)
    assert len(np.unique(sources[:, 0])) > 5 and len(np.unique(sources[:, -1])) > 5


def test_constrained_walks_are_deterministic_and_avoid_forbidden():
    forbidden = np.zeros(48, bool)
    forbidden[[12, 13]] = True
    graph = MotionGraph(48, np.concatenate([rich_transitions(), [[11, 14]]]), forbidden=forbidden)
    kwargs = dict(targets=[(25, 120)], start=2, end=44)
    a = constrained_walks(graph, 50, 240, rng=np.random.default_rng(9), **kwargs)
    b = constrained_walks(graph, 50, 240, rng=np.random.default_rng(9), **kwargs)
    np.testing.assert_array_equal(a, b)
    assert not forbidden[a].any()
    assert_walks_on_graph(graph, a)
    with pytest.raises(OptionError, match="input frame 12 at output time 50 is a forbidden frame"):
        constrained_walks(graph, 5, 100, [(12, 50)], np.random.default_rng(0))


def test_end_target_may_be_a_dead_end_frame():
    graph = MotionGraph(20, [(17, 3)])  # 18, 19 are dead ends
    sources = constrained_walks(graph, 20, 62, [], np.random.default_rng(0), start=0, end=19)  # 19 + 3 × 14
    assert (sources[:, -1] == 19).all() and (sources[:, 0] == 0).all()
    assert_walks_on_graph(graph, sources)
    with pytest.raises(OptionError, match="dead end"):
        constrained_walks(graph, 20, 60, [], np.random.default_rng(0), end=19, usable_only=True)


def test_min_segment_is_met_when_possible_in_constrained_walks():
    graph = MotionGraph(48, rich_transitions())
    sources = constrained_walks(graph, 100, 300, [(20, 150)], np.random.default_rng(10), start=1, end=40,
                                transition_probability=0.8, min_segment=4)
    for k, _ in seams(sources):
        assert len(k) == 0 or (np.diff(np.concatenate([[0], k])) >= 4).all()


def test_unreachable_target_names_frame_and_time():
    graph = MotionGraph(20, [(19, 4)])  # one loop 5..19 of 15 frames; frame 10 is 10 steps from 0
    with pytest.raises(OptionError, match=r"input frame 10 cannot be reached at output time 3 from input frame 0 "
                                          r"at output time 0.*output times 10, 25, 40"):
        constrained_walks(graph, 4, 50, [(10, 3)], np.random.default_rng(0), start=0)
    with pytest.raises(OptionError, match="input frame 0 cannot be reached at output time 5 from any start frame"):
        constrained_walks(graph, 4, 50, [(0, 5)], np.random.default_rng(0))
    # the same frame 10 steps later works
    sources = constrained_walks(graph, 4, 50, [(10, 10)], np.random.default_rng(0), start=0)
    assert (sources[:, :11] == np.arange(11)).all()


def test_conflicting_targets_raise():
    graph = MotionGraph(48, rich_transitions())
    with pytest.raises(OptionError, match="output time 0 is targeted at two input frames"):
        constrained_walks(graph, 4, 50, [(3, 0)], np.random.default_rng(0), start=5)
    with pytest.raises(OptionError, match="outside 0..49"):
        constrained_walks(graph, 4, 50, [(3, 50)], np.random.default_rng(0))


# ---------------------------------------------------------------------------- overlap, diversity, seams


def test_overlap():
    assert overlap([1, 2, 3, 4], [1, 2, 9, 4]) == 0.75
    assert overlap([1, 2], [3, 4]) == 0.0


@pytest.mark.parametrize("min_difference", [0.0, 0.3, 0.5, 0.8, 1.0])
def test_diversity_filter_matches_brute_force(min_difference):
    rng = np.random.default_rng(11)
    base = rng.integers(0, 3, size=(6, 40))
    sources = base[rng.integers(0, 6, size=150)]
    flip = rng.random(sources.shape) < 0.3
    sources = np.where(flip, rng.integers(0, 3, size=sources.shape), sources)
    expected = np.zeros(len(sources), bool)
    for n in range(len(sources)):
        expected[n] = all(overlap(sources[n], sources[k]) <= 1.0 - min_difference
                          for k in range(n) if expected[k])
    for block_elements in (1 << 24, 2000):  # one block, and many small blocks
        np.testing.assert_array_equal(diversity_filter(sources, min_difference, block_elements), expected)


@pytest.mark.parametrize("min_difference", [0.3, 0.5])
def test_diversity_filter_resumes_from_rows_already_kept(min_difference):
    """kept_before=K (the first K rows a kept set): the same mask as filtering everything again."""
    rng = np.random.default_rng(12)
    base = rng.integers(0, 3, size=(6, 40))
    sources = np.where(rng.random((300, 40)) < 0.3, rng.integers(0, 3, size=(300, 40)),
                       base[rng.integers(0, 6, size=300)])
    first = sources[:150][diversity_filter(sources[:150], min_difference)]
    joint = np.concatenate([first, sources[150:]])
    np.testing.assert_array_equal(diversity_filter(joint, min_difference, kept_before=len(first)),
                                  diversity_filter(joint, min_difference))


def test_seams_lists_transitions_used():
    k, pairs = seams([3, 4, 5, 10, 11, 2, 3])
    assert k.tolist() == [3, 5]
    assert pairs.tolist() == [[5, 9], [11, 1]]
    per_walk = seams(np.array([[0, 1, 2], [5, 2, 3]]))
    assert per_walk[0][0].size == 0 and per_walk[1][1].tolist() == [[5, 1]]
    assert seams([8, 9, 0, 1])[1].tolist() == [[9, -1]]  # a seam onto frame 0: the wrap (9, −1)


def test_random_walk_speed():
    graph = MotionGraph(48, rich_transitions())
    rng = np.random.default_rng(0)
    random_walks(graph, 10, 600, rng)  # warm-up
    began = time.perf_counter()
    sources = random_walks(graph, 1000, 600, rng)
    elapsed = time.perf_counter() - began
    assert sources.shape == (1000, 600)
    print(f"\n1000 random walks x 600 frames on a 48-frame clip with {len(graph.transitions)} transitions: "
          f"{elapsed * 1e3:.1f} ms")


@pytest.mark.parametrize("seed", range(6))
def test_targets_taken_from_a_walk_are_met_with_full_segments(seed):
    """Targets read off a walk whose segments are all ≥ min_segment are feasible with full segments."""
    rng = np.random.default_rng(100 + seed)
    frames = int(rng.integers(20, 60))
    graph = MotionGraph(frames, rich_transitions(frames, int(rng.integers(5, 25)), seed))
    reference = random_walks(graph, 50, 150, rng, min_segment=3)
    full = [row for row in reference if (np.diff(np.concatenate([[0], seams(row)[0]])) >= 3).all()]
    assert full
    times = np.sort(rng.choice(np.arange(1, 150), size=5, replace=False))
    targets = [(int(full[0][t]), int(t)) for t in times]
    sources = constrained_walks(graph, 40, 150, targets, rng, start=int(full[0][0]), min_segment=3,
                                usable_only=bool(seed % 2))
    for f, t in targets:
        assert (sources[:, t] == f).all()
    assert (sources[:, 0] == full[0][0]).all()
    assert_walks_on_graph(graph, sources, usable_only=bool(seed % 2))
    for k, _ in seams(sources):
        assert (np.diff(np.concatenate([[0], k])) >= 3).all()
