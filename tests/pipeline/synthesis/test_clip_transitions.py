"""Transitions and the motion graph over several clips of one character (issue 26), against
brute force and constructed truths: a clip that copies frames of another, eq. 5–6 per clip,
block-wise local minima, and the one-clip results unchanged."""

import json

import h5py
import numpy as np
import pytest
from scipy.ndimage import minimum_filter

from skinsynth.pipeline.inputs.clips import Clips
from skinsynth.pipeline.inputs.examples import synthetic_lbs
from skinsynth.pipeline.rig.rotations import rotation_exp, rotation_log
from skinsynth.pipeline.synthesis.motion_graph import (MotionGraph, constrained_walks, random_walks, recurrent_frames,
                                                       seams, transitions_between, walk_statistics)
from skinsynth.pipeline.synthesis.transitions import (candidate_transitions, find_transitions, posture_costs,
                                                      reference_motion, transition_costs, velocities, virtual_costs)


def drifting_motion(frames, bones=5, seed=0):
    """Bone motions that never repeat: angles and offsets drift steadily, plus a wiggle."""
    rng = np.random.default_rng(seed)
    time = np.arange(frames)[:, None, None] / frames  # (F, 1, 1)
    drift, wiggle, phase = rng.uniform(-1.0, 1.0, size=(3, bones, 3))
    rotations = rotation_exp(drift * time + 0.2 * wiggle * np.sin(9.0 * time + 6.0 * phase))
    translations = rng.normal(scale=0.5, size=(bones, 3)) * time + 0.1 * np.cos(7.0 * time + phase)
    return rotations, translations


@pytest.fixture
def copied():
    """Clip A: 40 frames of a drifting motion; clip B: A's frames 10..30 copied exactly (21 frames)."""
    lbs = synthetic_lbs(bones=5, frames=2, max_influences=3, rings=30, segments=8)
    rotations, translations = drifting_motion(40)
    return dict(bone_indices=lbs["bone_indices"], bone_weights=lbs["bone_weights"],
                rotations=np.concatenate([rotations, rotations[10:31]]),
                translations=np.concatenate([translations, translations[10:31]]),
                clips=Clips(("a", "b"), (40, 21)))


def entered_clip(clips, pairs):
    """The clip each transition (i, j) enters, from the conventions' own targets."""
    return clips.clip_of(clips.targets(pairs[:, 1]))


# ------------------------------------------------------------------- (a) a clip that copies another


def test_transitions_join_the_clips_where_their_frames_coincide(copied):
    clips = copied["clips"]
    result = find_transitions(copied["rotations"], copied["translations"], copied["bone_indices"],
                              copied["bone_weights"], spacing=3, clips=clips)
    pairs, costs = result.pairs, result.costs
    left, entered = clips.clip_of(pairs[:, 0]), entered_clip(clips, pairs)
    cheap = costs < result.threshold
    # B's frame m is A's frame 10 + m: after A's frame k, B's frame k − 9 is A's k + 1 (and back).
    a_to_b = cheap & (left == 0) & (entered == 1)
    b_to_a = cheap & (left == 1) & (entered == 0)
    assert a_to_b.any() and b_to_a.any()
    for i, j in pairs[a_to_b]:
        assert j == i - 10 + 40  # j = B's copy of A's frame i: B plays A's i + 1 next
    for i, j in pairs[b_to_a]:
        assert j == i - 40 + 10  # j = A's copy of B's frame i
    assert np.all(costs[a_to_b | b_to_a] < 1e-9 * result.D.max())
    # A drifts without repeating: nothing cheap inside a clip.
    assert not (cheap & (left == entered)).any()


def test_no_edge_from_one_clips_end_to_the_next_clips_start_unless_a_transition_says_so(copied):
    clips = copied["clips"]
    result = find_transitions(copied["rotations"], copied["translations"], copied["bone_indices"],
                              copied["bone_weights"], spacing=3, clips=clips)
    last_a, first_b = 39, 40
    chosen = (last_a, -2) in set(map(tuple, result.pairs.tolist()))
    graph = MotionGraph(clips.total, result.pairs, clips=clips)
    assert bool(graph.has_edges(last_a, first_b)) == chosen
    others = result.pairs[~((result.pairs[:, 0] == last_a) & (result.pairs[:, 1] == -2))]
    assert not MotionGraph(clips.total, others, clips=clips).has_edges(last_a, first_b)
    with_it = MotionGraph(clips.total, np.concatenate([others, [[last_a, -2]]]), clips=clips)
    assert with_it.has_edges(last_a, first_b)


# ------------------------------------------------- (b) eq. 5–6 within each clip, brute force


def eq6(rotations, translations, i, reference):
    """r_i of Zheng eq. 6 from frames i − 1 and i of the reference bone."""
    r_i, r_prev = rotations[i, reference], rotations[i - 1, reference]
    return np.concatenate([r_i.T @ (translations[i - 1, reference] - translations[i, reference]),
                           rotation_log(r_i.T @ r_prev)])


def test_reference_motion_and_velocities_take_each_clips_own_first_step(copied):
    clips = Clips(("a", "b", "c"), (25, 1, 35))  # a clip of one frame has no step
    rot, tra = copied["rotations"], copied["translations"]
    r = reference_motion(rot, tra, 2, clips)
    q = np.random.default_rng(4).normal(size=(clips.total, 3))
    qdot = velocities(q, clips)
    for c, (first, count) in enumerate(zip(clips.starts[:-1], clips.frames)):
        for local in range(count):
            f = first + local
            step = f + 1 if local == 0 else f  # a clip's first frame: its own first step
            if count == 1:
                assert np.array_equal(r[f], np.zeros(6)) and np.array_equal(qdot[f], np.zeros(3))
                continue
            assert np.allclose(r[f], eq6(rot, tra, step, 2), atol=1e-12)
            assert np.allclose(qdot[f], q[step] - q[step - 1], atol=1e-15)
    # Each clip alone gives the same rows.
    for first, end in zip(clips.starts[:-1], clips.starts[1:]):
        assert np.array_equal(r[first:end], reference_motion(rot[first:end], tra[first:end], 2))


def test_virtual_columns_are_eq5_against_each_clips_frame_before_its_start():
    rng = np.random.default_rng(7)
    clips = Clips(("a", "b", "c"), (9, 7, 1))
    frames = clips.total
    q, r, posture = rng.normal(size=(frames, 4)), rng.normal(size=(frames, 6)), rng.normal(size=(frames, 4))
    for first in clips.starts[:-1]:
        r[first] = r[first + 1] if first + 1 < frames and not clips.first_frames()[first + 1] else 0.0
    D, alpha, beta = transition_costs(q, r, clips=clips)
    D, gamma = posture_costs(D, q, posture, 0.7)
    virtual = virtual_costs(q, r, alpha, beta, posture, gamma, clips)
    assert virtual.shape == (frames, 3)
    qdot = np.zeros_like(q)
    for first, end in zip(clips.starts[:-1], clips.starts[1:]):
        if end - first >= 2:
            qdot[first + 1:end] = np.diff(q[first:end], axis=0)
            qdot[first] = qdot[first + 1]
    for c, first in enumerate(clips.starts[:-1]):
        if clips.frames[c] < 2:
            assert np.all(np.isinf(virtual[:, c]))
            continue
        s = int(first)
        brute = [np.sum((q[i] - (2 * q[s] - q[s + 1])) ** 2) + alpha * np.sum((qdot[i] - (q[s + 1] - q[s])) ** 2)
                 + beta * np.sum((r[i] - r[s]) ** 2) + gamma * np.sum((posture[i] - (2 * posture[s] - posture[s + 1])) ** 2)
                 for i in range(frames)]
        assert np.allclose(virtual[:, c], brute, rtol=1e-12, atol=1e-12)
    # D's velocity term is within clips: D(i, j) by eq. 5 with the clip-wise q̇.
    i, j = 9, 3  # b's first frame against a frame of a
    expected = np.sum((q[i] - q[j]) ** 2) + alpha * np.sum((qdot[i] - qdot[j]) ** 2) + beta * np.sum((r[i] - r[j]) ** 2) \
        + gamma * np.sum((posture[i] - posture[j]) ** 2)
    assert D[i, j] == pytest.approx(expected, rel=1e-10)


def brute_block_candidates(D, virtual, clips, threshold, min_gap):
    """Local minima searched one (clip of i, clip entered) block at a time: the block alone, its
    clip's virtual column before it, the 3×3 test at the block's edges as at a matrix's edges."""
    tolerance = 1e-9 * np.abs(D).max()
    starts, out = clips.starts, set()
    first = clips.first_frames()
    for a in range(len(clips)):
        rows = np.arange(starts[a], starts[a + 1])
        for c in range(len(clips)):
            columns = np.concatenate([[-(c + 1)], np.arange(starts[c], starts[c + 1])])
            block = np.concatenate([virtual[rows, c][:, None], D[np.ix_(rows, columns[1:])]], axis=1)
            low = minimum_filter(block, size=3, mode="constant", cval=np.inf)
            for x, i in enumerate(rows):
                for y, j in enumerate(columns):
                    before = j if j >= 0 else starts[c] - 1
                    if a == c and abs(i - before) < min_gap:
                        continue
                    if first[i] or (j >= 0 and first[j]) or not block[x, y] < threshold:
                        continue
                    if block[x, y] <= low[x, y] + tolerance:
                        out.add((int(i), int(j)))
    return out


def test_candidates_are_local_minima_of_each_clip_block():
    rng = np.random.default_rng(5)
    clips = Clips(("a", "b", "c"), (14, 11, 9))
    frames = clips.total
    i, j = np.indices((frames, frames))
    D = np.minimum(np.abs(i - j), 10).astype(float) + rng.uniform(0.0, 0.3, (frames, frames))
    # valleys across the clip boundaries: a minimum that would sit just across one must not count there
    for ci, cj in ((12, 26), (24, 3), (5, 30), (30, 13), (13, 14)):
        D -= 9.0 * np.exp(-((i - ci) ** 2 + (j - cj) ** 2) / 3.0)
    virtual = 5.0 + rng.uniform(0.0, 3.0, (frames, 3))
    virtual[20, 2] = 0.1  # after b's frame 20 continue at c's start
    for threshold, min_gap in ((4.0, 2), (np.inf, 2), (4.0, 5)):
        pairs, costs = candidate_transitions(D, threshold, min_gap, start=virtual, clips=clips)
        assert set(map(tuple, pairs.tolist())) == brute_block_candidates(D, virtual, clips, threshold, min_gap)
        assert np.all(np.diff(costs) >= 0.0)
    found = set(map(tuple, candidate_transitions(D, 4.0, 2, start=virtual, clips=clips)[0].tolist()))
    assert (20, -3) in found


# ------------------------------------------------------- (c) one clip: the same numbers as before


def test_one_clip_gives_exactly_the_results_of_no_clips(copied):
    args = (copied["rotations"][:40], copied["translations"][:40], copied["bone_indices"], copied["bone_weights"])
    pivots = np.random.default_rng(1).normal(size=(5, 3))
    for extra in (dict(), dict(up=np.eye(3)[1], pivots=pivots, scale=2.0, spacing=3)):
        plain = find_transitions(*args, **extra)
        single = find_transitions(*args, clips=Clips.single(40), **extra)
        for name in ("q", "r", "D", "pairs", "costs", "start", "basis", "singular"):
            assert np.array_equal(getattr(plain, name), getattr(single, name)), name
        assert (plain.threshold, plain.alpha, plain.beta, plain.admitted, plain.share) == \
            (single.threshold, single.alpha, single.beta, single.admitted, single.share)
        assert np.array_equal(plain.virtual, single.virtual) and np.array_equal(plain.start, plain.virtual[:, 0])
    pairs = np.array([[30, 5], [39, -1], [20, 2], [12, 39]])
    a, b = MotionGraph(40, pairs), MotionGraph(40, pairs, clips=Clips.single(40))
    assert np.array_equal(a.transitions, b.transitions) and np.array_equal(a.indices, b.indices)
    walks = [random_walks(g, 20, 60, np.random.default_rng(3), min_segment=3) for g in (a, b)]
    assert np.array_equal(*walks)
    assert np.array_equal(recurrent_frames(40, pairs), recurrent_frames(40, pairs, Clips.single(40)))
    for (k1, p1), (k2, p2) in zip(seams(walks[0]), seams(walks[0], Clips.single(40))):
        assert np.array_equal(k1, k2) and np.array_equal(p1, p2)
    stats = walk_statistics(walks[0][None], 40, Clips.single(40))
    plain_stats = walk_statistics(walks[0][None], 40)
    assert all(stats[key] == plain_stats[key] for key in plain_stats)


# ------------------------------------------------------------------ (d) the graph over clips


CLIPS = Clips(("walk", "fall", "pose"), (12, 10, 6))  # frames 0–11, 12–21, 22–27


def test_playback_stays_inside_clips_and_virtual_frames_enter_each_clip():
    f = np.arange(CLIPS.total - 1)
    looping = MotionGraph(CLIPS.total, [(10, 2)], clips=CLIPS)  # a loop 3–10 inside the walk, no other move
    assert np.array_equal(looping.has_edges(f, f + 1), CLIPS.plays_on()[:-1])  # never 11 → 12 nor 21 → 22
    graph = MotionGraph(CLIPS.total, [(11, -2), (20, -1), (27, 3)], clips=CLIPS)
    assert graph.has_edges(11, 12)  # (11, −2): continue at the fall's first frame
    assert graph.has_edges(20, 0) and graph.has_edges(27, 4)
    assert not graph.has_edges(21, 22)
    # 21, the fall's last frame, plays on nowhere and leaves by no transition: a dead end; the
    # pose clip is entered by nothing but leaves by (27, 3), so a walk started there goes on
    assert not graph.usable[21] and graph.usable[:21].all() and graph.usable[22:].all()
    assert np.array_equal(CLIPS.targets(graph.transitions[:, 1]), [12, 0, 4])  # sorted by (i, frame entered)


def test_pairs_the_clips_refuse_are_dropped_or_refused():
    from skinsynth.pipeline.errors import OptionError

    graph = MotionGraph(CLIPS.total, [(11, -2), (20, -1), (5, 11), (8, 21), (15, 27)], clips=CLIPS)
    assert graph.transitions.tolist() == [[11, -2], [20, -1]]  # 11, 21, 27 end their clips: dropped
    with pytest.raises(OptionError, match="−3"):
        MotionGraph(CLIPS.total, [(11, -4)], clips=CLIPS)
    with pytest.raises(ValueError):
        MotionGraph(20, [], clips=CLIPS)


def test_walks_over_clips_stay_on_edges():
    pairs = [(11, -2), (20, -1), (9, 14), (18, 3), (25, 6), (16, -3), (7, 23)]
    graph = MotionGraph(CLIPS.total, pairs, clips=CLIPS)
    walks = random_walks(graph, 200, 90, np.random.default_rng(0), min_segment=3)
    assert graph.has_edges(walks[:, :-1], walks[:, 1:]).all()
    targets = constrained_walks(graph, 20, 60, [(CLIPS.frame("fall:0"), 20), (CLIPS.frame("pose:1"), 45)],
                                np.random.default_rng(1), min_segment=3)
    assert graph.has_edges(targets[:, :-1], targets[:, 1:]).all()
    assert np.all(targets[:, 20] == 12) and np.all(targets[:, 45] == 23)
    # seams are the conventions' seams; their transitions are edges of the graph
    for row, (k, used) in zip(walks, seams(walks, CLIPS)):
        assert np.array_equal(k, np.flatnonzero(CLIPS.seams(row)))
        assert np.array_equal(CLIPS.targets(used[:, 1]), row[k])
        assert set(map(tuple, used.tolist())) <= set(map(tuple, graph.transitions.tolist()))


def test_walk_statistics_per_clip_on_a_known_walk():
    # walk 0–11, then (11, −2) into the fall 12–15, (15 → 3) back: (15, 2); component 2 stays in the walk
    first = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 3, 4]
    second = [4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21]  # 11 → 12 crosses by a seam
    sources = np.array([[first], [second]])
    stats = walk_statistics(sources, CLIPS.total, CLIPS)
    assert stats["transitions"] == [2, 1]
    assert stats["transitions_between"][0]["walk->fall"] == 1 and stats["transitions_between"][0]["fall->walk"] == 1
    assert stats["transitions_between"][1]["walk->fall"] == 1
    assert sum(stats["transitions_between"][1].values()) == 1
    assert stats["coverage_per_clip"][0] == {"walk": 1.0, "fall": 0.4, "pose": 0.0}
    assert stats["coverage_per_clip"][1] == {"walk": 8 / 12, "fall": 1.0, "pose": 0.0}
    assert transitions_between([(11, -2), (20, -1), (25, 6), (3, 8)], CLIPS) == {
        "walk->walk": 1, "walk->fall": 1, "walk->pose": 0, "fall->walk": 1, "fall->fall": 0, "fall->pose": 0,
        "pose->walk": 1, "pose->fall": 0, "pose->pose": 0}


def test_recurrent_frames_follow_the_clip_aware_edges():
    # 11 → 12 is no edge: with (20, −1) alone nothing returns (every part one frame), with
    # (11, −2) too one cycle 0–20
    assert recurrent_frames(CLIPS.total, [(20, -1)], CLIPS).sum() == 1
    both = recurrent_frames(CLIPS.total, [(11, -2), (20, -1)], CLIPS)
    assert np.flatnonzero(both).tolist() == list(range(21))


# --------------------------------------------------------------- (e) the real gallop and collapse


@pytest.mark.slow
def test_real_gallop_and_collapse(horse_clips, tmp_path):
    from cli_helpers import assert_ok, cli

    _, skin, _ = horse_clips

    def build(name, *options):
        summary = json.loads(assert_ok(cli("build-graph", skin, "-o", tmp_path / name, "--json",
                                           *options)).stdout)
        with h5py.File(tmp_path / name) as f:
            clips = Clips(tuple(f["examples"].attrs["clip_names"]), tuple(f["examples/clip_frames"][()]))
            parts = [f["graph"][k] for k in sorted(f["graph"]) if k.startswith("component_")]
            found = [(p["transitions"][()], p["transition_costs"][()], p.attrs["threshold"]) for p in parts]
        return summary, clips, found

    summary, clips, found = build("default.h5")
    assert clips.names == ("gallop", "collapse") and summary["clips"] == ["gallop", "collapse"]
    for component, (pairs, _, _) in zip(summary["components"], found):
        # the summary counts what the file holds, by the clip left and the clip entered
        left, entered = clips.clip_of(pairs[:, 0]), clips.clip_of(clips.targets(pairs[:, 1]))
        for a, name_a in enumerate(clips.names):
            for b, name_b in enumerate(clips.names):
                assert component["transitions_between"][f"{name_a}->{name_b}"] == int(((left == a) & (entered == b)).sum())
        assert component["transitions_between"]["gallop->gallop"] > 0  # the gallop is one cycle twice
        assert clips.valid_j(pairs[:, 1]).all()
    # Each clip has its own T_c (the gallop's steps are ~100x the collapse's), and every clip gets
    # a way in and a way out (the cheapest crossing below 10 of its T_c): both directions appear,
    # each judged by the threshold of its pair of clips.
    between = summary["transitions_between"]
    assert between["gallop->collapse"] > 0 and between["collapse->gallop"] > 0
    with h5py.File(tmp_path / "default.h5") as f:
        thresholds = [f["graph"][k]["clip_thresholds"][()] for k in sorted(f["graph"]) if k.startswith("component_")]
    for (pairs, costs, pooled), limit in zip(found, thresholds):
        left, entered = clips.clip_of(pairs[:, 0]), clips.clip_of(clips.targets(pairs[:, 1]))
        assert limit[0, 1] == limit[1, 0] == limit.max()  # a crossing may cost a step of the faster clip
        assert np.all(costs < 10 * limit[left, entered])


def test_clip_thresholds_take_each_clips_own_steps_and_the_larger_for_a_crossing():
    from skinsynth.pipeline.synthesis.transitions import clip_thresholds, transition_threshold

    clips = Clips(("fast", "slow", "still"), (5, 4, 1))
    rng = np.random.default_rng(0)
    D = rng.random((10, 10)) * 100
    steps = {"fast": [D[i, i - 1] for i in range(1, 5)], "slow": [D[i, i - 1] for i in range(6, 9)]}
    fast, slow = 3 * np.median(steps["fast"]), 3 * np.median(steps["slow"])
    pooled = 3 * np.median(steps["fast"] + steps["slow"])  # a one-frame clip has no step: the pooled one
    expected = np.array([[fast, max(fast, slow), fast], [max(fast, slow), slow, slow], [fast, slow, pooled]])
    assert np.allclose(clip_thresholds(D, 3.0, "median-step", clips), expected)
    assert np.isclose(pooled, transition_threshold(D, 3.0, "median-step", clips))
    one = Clips.single(10)
    assert clip_thresholds(D, 3.0, "max-step", one)[0, 0] == transition_threshold(D, 3.0, "max-step", one)


def test_every_clip_gets_a_way_in_and_out_when_only_the_pair_would_help():
    """Two clips whose crossings cost more than T_c: the coverage rule, which admits one
    transition at a time only if it enlarges the strongly connected part, cannot join them (a way
    in alone or a way out alone enlarges nothing); the clip links do, the cheapest each way."""
    from skinsynth.pipeline.synthesis.transitions import select_transitions

    clips = Clips(("a", "b"), (8, 8))
    D = np.full((16, 16), 50.0)
    idx = np.arange(1, 16)
    D[idx, idx - 1] = 1.0  # playback steps: T_c = 3
    D[7, 8 + 2] = 9.0   # a:7 enters b after b:2 (plays b:3), 3 T_c
    D[8 + 6, 3] = 12.0  # b:6 enters a after a:3 (plays a:4), 4 T_c
    D[8 + 5, 2] = 40.0  # a dearer way back
    np.fill_diagonal(D, 0.0)
    D = np.minimum(D, D.T)
    start = np.full((16, 2), 50.0)
    start[7, 0] = 2.0  # a:7 loops to a's start: a is a cycle of its own
    pairs, costs, admitted, share = select_transitions(D, np.full((2, 2), 3.0), min_gap=2, start=start,
                                                      clips=clips, coverage=0.95)
    crossing = clips.clip_of(pairs[:, 0]) != clips.clip_of(clips.targets(pairs[:, 1]))
    assert sorted(map(tuple, pairs[crossing].tolist())) == [(7, 10), (14, 3)]
    assert admitted == 2


def test_an_analysis_made_again_as_one_component_keeps_the_clips_and_the_walk_clips():
    """synthesize --single-component on a graph of several components analyses the rig again: it
    must read the frames as the same clips, with the same clips left out of the walks."""
    from types import SimpleNamespace

    from skinsynth.pipeline.inputs.examples import synthetic_lbs
    from skinsynth.pipeline.synthesis.synthesis import synthesis_components

    truth = synthetic_lbs(bones=4, frames=30, seed=2, rings=16, segments=6)
    skin = SimpleNamespace(rest_vertices=truth["rest"], faces=truth["faces"], bone_indices=truth["bone_indices"],
                           bone_weights=truth["bone_weights"], rotations=truth["rotations"],
                           translations=truth["translations"])
    clips = Clips(("a", "b"), (18, 12))
    components = synthesis_components(skin, [None, None], single_component=True, clips=clips, walk_clips=["a"])
    assert len(components) == 1 and components[0].transitions.clips == clips
    pairs = components[0].transitions.pairs
    assert np.all((pairs[:, 0] < 18) & (clips.targets(pairs[:, 1]) < 18))  # b is left out of the walks
