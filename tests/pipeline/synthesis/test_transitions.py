import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skinsynth.pipeline.errors import OptionError
from skinsynth.pipeline.inputs.examples import synthetic_lbs
from skinsynth.pipeline.rig.rotations import rotation_exp, rotation_log
from skinsynth.pipeline.synthesis.transitions import (bone_coordinate_matrix, candidate_transitions, find_transitions,
                                            local_frame_positions, pairwise_squared_distances,
                                            reduced_coordinates, reference_bone, reference_motion,
                                            select_transitions, transition_costs, transition_threshold)


def periodic_motion(period, bones=5, seed=0):
    """Bone motions that are a smooth periodic function of time (two harmonics, random phases)."""
    rng = np.random.default_rng(seed)
    phase = 2.0 * np.pi * np.arange(period)[:, None, None] / period  # (P, 1, 1)
    a1, a2 = rng.uniform(-0.6, 0.6, size=(2, bones, 3))
    p1, p2 = rng.uniform(0.0, 2.0 * np.pi, size=(2, bones, 3))
    rotations = rotation_exp(a1 * np.sin(phase + p1) + a2 * np.sin(2.0 * phase + p2))
    b1, b2 = rng.normal(scale=0.4, size=(2, bones, 3))
    q1, q2 = rng.uniform(0.0, 2.0 * np.pi, size=(2, bones, 3))
    translations = b1 * np.sin(phase + q1) + b2 * np.cos(2.0 * phase + q2)
    return rotations, translations


@pytest.fixture
def model():
    """Weights of a 5-bone tube and a clip of P = 24 frames played twice (frames k and k+P equal)."""
    lbs = synthetic_lbs(bones=5, frames=2, max_influences=3, rings=30, segments=8)
    rotations, translations = periodic_motion(24, bones=5)
    return dict(bone_indices=lbs["bone_indices"], bone_weights=lbs["bone_weights"], period=24,
                rotations=np.concatenate([rotations, rotations]),
                translations=np.concatenate([translations, translations]))


def rigidly_moved(rotations, translations, q, c):
    """Every bone after the rigid transform (Q, c) of the whole mesh: (Q R, Q t + c), since Σ w = 1."""
    return q @ rotations, (q @ translations[..., None])[..., 0] + c


def test_reference_bone_largest_weight_sum_ties_lowest_and_subset():
    idx = np.array([[0, 1], [1, 2], [2, 0], [3, 2]])
    w = np.array([[0.5, 0.5], [0.5, 0.5], [0.5, 0.5], [1.0, 0.0]])
    # sums: bone 0: 1.0, bone 1: 1.0, bone 2: 1.0, bone 3: 1.0 -> a four-way tie: lowest id.
    assert reference_bone(idx, w, 4) == 0
    assert reference_bone(idx, w, 4, subset=[3, 2]) == 2
    w2 = np.array([[0.2, 0.8], [0.5, 0.5], [0.5, 0.5], [1.0, 0.0]])
    assert reference_bone(idx, w2, 4) == 1  # 1.3
    assert reference_bone(idx, w2, 4, subset=[0, 3]) == 3  # bone 3: 1.0 beats bone 0: 0.7
    with pytest.raises(OptionError):
        reference_bone(idx, w, 4, subset=[5])


def test_local_frame_positions_match_eq2_brute_force(model):
    rot, tra = model["rotations"][:5], model["translations"][:5]
    r_local, t_local, ids = local_frame_positions(rot, tra, 2, bones_subset=[4, 0, 2, 3])
    assert ids == [0, 3, 4]
    assert r_local.shape == (5, 3, 3, 3) and t_local.shape == (5, 3, 3)
    for f in range(5):
        for k, b in enumerate(ids):
            assert np.allclose(r_local[f, k], rot[f, 2].T @ rot[f, b], atol=1e-14)
            assert np.allclose(t_local[f, k], rot[f, 2].T @ (tra[f, b] - tra[f, 2]), atol=1e-14)
    with pytest.raises(OptionError):
        local_frame_positions(rot, tra, 1, bones_subset=[0, 2])


def test_reference_motion_eq6_and_first_frame(model):
    rot, tra = model["rotations"], model["translations"]
    r = reference_motion(rot, tra, 1)
    assert r.shape == (rot.shape[0], 6)
    for i in (1, 7, 30):
        assert np.allclose(r[i, :3], rot[i, 1].T @ (tra[i - 1, 1] - tra[i, 1]), atol=1e-14)
        assert np.allclose(r[i, 3:], rotation_log(rot[i, 1].T @ rot[i - 1, 1]), atol=1e-12)
    assert np.array_equal(r[0], r[1])  # r_0 := r_1


def test_reduced_coordinates_reconstruct_to_truncation_error(model):
    r_local, t_local, ids = local_frame_positions(model["rotations"], model["translations"], 0)
    a = bone_coordinate_matrix(r_local, t_local)
    assert a.shape == (6 * len(ids), model["rotations"].shape[0])
    assert np.allclose(a[6:9, 3], t_local[3, 1]) and np.allclose(a[9:12, 3], rotation_log(r_local[3, 1]))
    full = np.linalg.svd(a, compute_uv=False)
    for threshold in (0.005, 0.05, 0.3):
        q, basis, singular = reduced_coordinates(r_local, t_local, threshold)
        rank = int(np.sum(full >= threshold * full[0]))
        assert q.shape == (a.shape[1], rank) and basis.shape == (a.shape[0], rank)
        assert np.allclose(singular, full[:rank])
        assert np.allclose(basis.T @ basis, np.eye(rank), atol=1e-12)
        error = np.sum((a - basis @ q.T) ** 2)
        assert error == pytest.approx(np.sum(full[rank:] ** 2), rel=1e-8, abs=1e-20)
    assert rank < a.shape[0]  # the largest threshold really truncates
    q, basis, _ = reduced_coordinates(r_local, t_local, 0.0)
    assert np.allclose(basis @ q.T, a, atol=1e-12)


def test_transition_costs_eq5_brute_force_and_weights():
    rng = np.random.default_rng(4)
    q, r = rng.normal(size=(9, 4)), rng.normal(size=(9, 6))
    D, alpha, beta = transition_costs(q, r)
    qdot = np.diff(q, axis=0, prepend=q[:1] * 0.0)
    qdot[0] = qdot[1]
    sq = lambda x: np.max(np.sum(x * x, axis=1))  # noqa: E731
    assert alpha == pytest.approx(sq(q) / sq(qdot)) and beta == pytest.approx(sq(q) / sq(r))
    brute = np.array([[np.sum((q[i] - q[j]) ** 2) + alpha * np.sum((qdot[i] - qdot[j]) ** 2)
                       + beta * np.sum((r[i] - r[j]) ** 2) for j in range(9)] for i in range(9)])
    assert np.allclose(D, brute, atol=1e-12)
    assert np.array_equal(D, D.T) and np.all(np.diag(D) == 0.0)
    # Given weights are used as they are; zero denominators are guarded.
    assert transition_costs(q, r, alpha=2.0, beta=0.0)[1:] == (2.0, 0.0)
    D0, a0, b0 = transition_costs(np.zeros((5, 0)), np.zeros((5, 6)))
    assert np.all(D0 == 0.0) and (a0, b0) == (1.0, 1.0)
    # No non-reference bones: the r term alone, normalised to a unit maximum.
    D1, _, b1 = transition_costs(np.zeros((9, 0)), r)
    assert np.allclose(D1, pairwise_squared_distances(r) / sq(r))


def test_exact_loop_played_twice_gives_matching_frame_transitions(model):
    p = model["period"]
    tr = find_transitions(model["rotations"], model["translations"], model["bone_indices"],
                          model["bone_weights"])
    frames = 2 * p
    assert tr.D.shape == (frames, frames) and tr.q.shape[0] == frames
    assert tr.reference in range(5) and tr.local_bones == [b for b in range(5) if b != tr.reference]
    steps = tr.steps
    assert tr.threshold == pytest.approx(3.0 * np.median(steps))
    # D(i, i+P) ≈ 0 for every i ≥ 1 (frame 0 has no true predecessor: q̇_0 := q̇_1).
    loop = np.array([tr.D[i, i + p] for i in range(1, p)])
    assert np.max(loop) < 1e-10 * np.median(steps)
    found = {tuple(pair) for pair in tr.pairs.tolist()}
    # (p − 1, 2p − 1) would continue past the clip's last frame: no walk can take it.
    expected = {(i, i + p) for i in range(1, p - 1)} | {(i + p, i) for i in range(1, p)}
    assert expected <= found
    # They are the cheapest candidates, and sorted first.
    assert {tuple(pair) for pair in tr.pairs[:len(expected)].tolist()} == expected
    assert np.all(np.diff(tr.costs) >= 0.0)
    assert np.all(np.abs(tr.pairs[:, 0] - tr.pairs[:, 1]) >= 2) and np.all(tr.pairs[:, 0] >= 1)
    # j ≥ 1, or the virtual frame −1: the clip's last frame runs into its first, so the wrap
    # (2P − 1, −1), "after the last frame continue at frame 0", is a candidate too.
    assert np.all((tr.pairs[:, 1] >= 1) | (tr.pairs[:, 1] == -1)) and (frames - 1, -1) in found


def test_fixed_rigid_motion_of_the_whole_clip_leaves_D_unchanged(model):
    base = find_transitions(model["rotations"], model["translations"], model["bone_indices"],
                            model["bone_weights"])
    q = Rotation.random(random_state=7).as_matrix()
    c = np.array([3.0, -1.0, 2.5])
    rot, tra = rigidly_moved(model["rotations"], model["translations"], q, c)
    moved = find_transitions(rot, tra, model["bone_indices"], model["bone_weights"])
    assert np.max(np.abs(moved.D - base.D)) < 1e-9
    assert (moved.alpha, moved.beta) == pytest.approx((base.alpha, base.beta), rel=1e-9)
    assert np.allclose(moved.r, base.r, atol=1e-12)
    # Same candidates (the order of the ≈ 0 loop costs is round-off).
    assert set(map(tuple, moved.pairs.tolist())) == set(map(tuple, base.pairs.tolist()))


def test_eq2_removes_a_rigid_motion_that_varies_per_frame(model):
    rot, tra = model["rotations"], model["translations"]
    frames = rot.shape[0]
    q = Rotation.random(frames, random_state=8).as_matrix()[:, None]  # (F, 1, 3, 3)
    c = np.random.default_rng(9).normal(scale=5.0, size=(frames, 1, 3))
    rot2, tra2 = rigidly_moved(rot, tra, q, c)
    ref = reference_bone(model["bone_indices"], model["bone_weights"], 5)
    r_local, t_local, _ = local_frame_positions(rot, tra, ref)
    r_local2, t_local2, _ = local_frame_positions(rot2, tra2, ref)
    assert np.allclose(r_local2, r_local, atol=1e-12) and np.allclose(t_local2, t_local, atol=1e-12)
    qa = reduced_coordinates(r_local, t_local)[0]
    qb = reduced_coordinates(r_local2, t_local2)[0]
    assert np.max(np.abs(pairwise_squared_distances(qa) - pairwise_squared_distances(qb))) < 1e-9
    # The reference bone's own motion r (eq. 6) does see a per-frame rigid motion.
    assert not np.allclose(reference_motion(rot2, tra2, ref), reference_motion(rot, tra, ref), atol=1e-3)


def bowls(frames, centres, depth=9.5, width=2.0):
    """A synthetic symmetric cost matrix: |i − j| (capped at 10) minus Gaussian valleys."""
    i, j = np.indices((frames, frames))
    d = np.minimum(np.abs(i - j), 10).astype(float)
    for ci, cj in centres:
        for a, b in ((ci, cj), (cj, ci)):
            d -= depth * np.exp(-((i - a) ** 2 + (j - b) ** 2) / (2.0 * width ** 2))
    return d


def test_local_minimum_filtering_returns_one_pair_per_valley():
    d = bowls(40, [(10, 25), (5, 33)])
    pairs, costs = candidate_transitions(d, threshold=3.0, min_gap=2)
    assert sorted(map(tuple, pairs.tolist())) == [(5, 33), (10, 25), (25, 10), (33, 5)]
    assert np.allclose(costs, 0.5, atol=1e-3)
    # Without the filter each valley holds many pairs below the threshold ...
    below = (d < 3.0) & (np.abs(np.subtract.outer(np.arange(40), np.arange(40))) >= 2)
    assert below.sum() > 4 * 5
    # ... and the near-diagonal pairs (D(i, i±2) = 2 < 3) are on the slope of D(i, i) = 0, not minima.
    assert np.all(np.abs(pairs[:, 0] - pairs[:, 1]) > 2)


def test_candidate_transitions_gap_first_frame_and_threshold():
    d = bowls(40, [(0, 20), (12, 24), (8, 30)])
    pairs, _ = candidate_transitions(d, threshold=3.0, min_gap=2)
    found = set(map(tuple, pairs.tolist()))
    assert (8, 30) in found and (30, 8) in found
    assert not any(0 in p for p in found)  # frame 0 has no velocity of its own
    assert (12, 24) in found
    assert (12, 24) not in set(map(tuple, candidate_transitions(d, 3.0, min_gap=13)[0].tolist()))
    assert len(candidate_transitions(d, threshold=0.4)[0]) == 0  # the valleys bottom out at ≈ 0.5
    cost = d[8, 30]
    assert (8, 30) not in set(map(tuple, candidate_transitions(d, threshold=cost)[0].tolist()))  # D < T_c, strict
    assert (8, 30) in set(map(tuple, candidate_transitions(d, threshold=np.nextafter(cost, 1.0))[0].tolist()))
    empty_pairs, empty_costs = candidate_transitions(np.zeros((0, 0)), 1.0)
    assert empty_pairs.shape == (0, 2) and empty_costs.shape == (0,)


def test_threshold_rules(model):
    tr = find_transitions(model["rotations"], model["translations"], model["bone_indices"],
                          model["bone_weights"])
    steps = np.array([tr.D[i, i - 1] for i in range(1, tr.D.shape[0])])
    assert transition_threshold(tr.D) == pytest.approx(3.0 * np.median(steps))
    assert transition_threshold(tr.D, 2.0, "median-step") == pytest.approx(2.0 * np.median(steps))
    zheng = transition_threshold(tr.D, 40.0, "max-step")
    assert zheng == pytest.approx(40.0 * np.max(steps))
    literal = find_transitions(model["rotations"], model["translations"], model["bone_indices"],
                               model["bone_weights"], threshold_scale=40.0, threshold_reference="max-step")
    assert literal.threshold == pytest.approx(zheng)
    # Zheng's literal rule admits far more of the frame pairs than the default.
    assert np.mean(tr.D < zheng) > 3 * np.mean(tr.D < tr.threshold)
    assert len(literal.pairs) >= len(tr.pairs)
    with pytest.raises(OptionError):
        transition_threshold(tr.D, reference="mean-step")
    with pytest.raises(OptionError):
        transition_threshold(np.zeros((1, 1)))


def test_bones_subset_restricts_reference_and_coordinates(model):
    tr = find_transitions(model["rotations"], model["translations"], model["bone_indices"],
                          model["bone_weights"], bones_subset=[3, 4])
    assert tr.bones == [3, 4] and tr.reference in (3, 4) and len(tr.local_bones) == 1
    assert tr.basis.shape[0] == 6 and tr.q.shape[1] <= 6
    # One bone alone: no q, the reference motion term still ranks frames.
    single = find_transitions(model["rotations"], model["translations"], model["bone_indices"],
                              model["bone_weights"], bones_subset=[2])
    assert single.q.shape == (48, 0) and single.D.max() > 0.0
    p = model["period"]
    assert single.D[5, 5 + p] < 1e-10


# ---------------------------------------------------------------------------- the wrap: frame −1


def test_start_costs_are_eq5_against_the_virtual_frame_before_the_start():
    # Brute force: append frame −1 (the clip continued backwards at its first velocity) to every
    # series and evaluate eq. 5 (and the posture term) between frame i and it, term by term.
    from skinsynth.pipeline.synthesis.transitions import padded_costs, posture_costs, start_costs

    rng = np.random.default_rng(11)
    frames = 12
    q, r, posture = rng.normal(size=(frames, 4)), rng.normal(size=(frames, 6)), rng.normal(size=(frames, 4))
    r[0] = r[1]  # as reference_motion makes it: r_0 := r_1
    D, alpha, beta = transition_costs(q, r)
    D, gamma = posture_costs(D, q, posture, 0.7)
    start = start_costs(q, r, alpha, beta, posture, gamma)
    q_virtual = q[0] - (q[1] - q[0])
    qdot = np.diff(q, axis=0, prepend=q[:1] * 0.0)
    qdot[0] = qdot[1]
    qdot_virtual = q[1] - q[0]  # q̇₋₁ = q̇_0 = q̇_1: constant velocity
    r_virtual = r[1]  # r₋₁ = r_0 = r_1
    posture_virtual = 2.0 * posture[0] - posture[1]
    brute = np.array([np.sum((q[i] - q_virtual) ** 2) + alpha * np.sum((qdot[i] - qdot_virtual) ** 2)
                      + beta * np.sum((r[i] - r_virtual) ** 2) + gamma * np.sum((posture[i] - posture_virtual) ** 2)
                      for i in range(frames)])
    assert np.allclose(start, brute, rtol=1e-12, atol=1e-12)
    # D(0, −1) is a playback step at the first velocity: no velocity or r term.
    step = np.sum((q[1] - q[0]) ** 2) + gamma * np.sum((posture[1] - posture[0]) ** 2)
    assert start[0] == pytest.approx(step, rel=1e-12)
    padded = padded_costs(D, start)
    assert padded.shape == (frames, frames + 1)
    assert np.array_equal(padded[:, 0], start) and np.array_equal(padded[:, 1:], D)


def brute_candidates(D, start, threshold, min_gap):
    """Local minima (3×3, ≤ with the 1e-9 × max|D| tolerance) of [D(·, −1) | D] below the threshold,
    |i − j| ≥ min_gap, i ≥ 1, j ≥ 1 or j = −1: one cell at a time."""
    frames = D.shape[0]
    padded = np.concatenate([start[:, None], D], axis=1)
    tolerance = 1e-9 * np.abs(D).max()
    out = set()
    for i in range(frames):
        for c in range(frames + 1):
            j = c - 1
            if not (padded[i, c] < threshold and abs(i - j) >= min_gap and i >= 1 and (j >= 1 or j == -1)):
                continue
            near = padded[max(i - 1, 0):i + 2, max(c - 1, 0):c + 2]
            if padded[i, c] <= near.min() + tolerance:
                out.add((i, j))
    return out


def test_candidates_in_the_padded_matrix_match_brute_force():
    rng = np.random.default_rng(3)
    frames = 30
    # A cost-like matrix with valleys, one of them on the virtual column (after 27, continue at 0).
    d = bowls(frames, [(10, 20), (4, 25)])
    start = np.minimum(np.abs(np.arange(frames) + 1.0), 10.0) + rng.uniform(0.0, 0.05, frames)
    start -= 9.5 * np.exp(-((np.arange(frames) - 27.0) ** 2) / 8.0)
    for threshold, min_gap in ((3.0, 2), (np.inf, 2), (3.0, 6), (0.1, 2)):
        pairs, costs = candidate_transitions(d, threshold, min_gap, start=start)
        assert set(map(tuple, pairs.tolist())) == brute_candidates(d, start, threshold, min_gap)
        padded = np.concatenate([start[:, None], d], axis=1)
        assert np.array_equal(costs, padded[pairs[:, 0], pairs[:, 1] + 1])
        assert np.all(np.diff(costs) >= 0.0)
    found = set(map(tuple, candidate_transitions(d, 3.0, 2, start=start)[0].tolist()))
    assert (27, -1) in found
    # The column never changes the pairs (i, j ≥ 1): without it, the same ones less the wrap.
    plain = set(map(tuple, candidate_transitions(d, 3.0, 2)[0].tolist()))
    assert plain == {p for p in found if p[1] != -1}


def test_one_cycle_clip_gets_its_wrap_and_a_clip_played_twice_keeps_its_transitions(model):
    p = model["period"]
    args = (model["bone_indices"], model["bone_weights"])
    # One cycle: frame P would be frame 0 again. Without the virtual frame nothing returns.
    one = find_transitions(model["rotations"][:p], model["translations"][:p], *args)
    assert one.start.shape == (p,)
    assert (p - 1, -1) in set(map(tuple, one.pairs.tolist()))
    assert one.share == 1.0
    from skinsynth.pipeline.synthesis.transitions import select_transitions

    # Without it no cheap transition returns; the coverage rule admits dearer ones, and not all frames.
    pairs, costs, admitted, share = select_transitions(one.D, one.threshold, 2, 0, 0.95)
    assert admitted == len(pairs) and np.all(costs >= one.threshold) and share < 1.0
    assert one.admitted == 0 and one.costs[0] < one.threshold
    # Two cycles: the wrap is added, every other pair is unchanged.
    two = find_transitions(model["rotations"], model["translations"], *args)
    kept = select_transitions(two.D, two.threshold, 2, 0, 0.95)[0]
    assert {tuple(x) for x in two.pairs.tolist() if x[1] != -1} == set(map(tuple, kept.tolist()))


def test_coverage_admits_a_candidate_the_spacing_rule_dropped_where_it_reaches_frames_off_the_part():
    # Issue 63: the gallop at 12 fps (two 12-frame strides) kept (15, 3), dropped its neighbour
    # (13, 1) as "the same choice", and frames 0–3 only led into the part. Costs: a periodic
    # valley D(i, i ± 12), flat to within the candidates' tolerance (every pair on it a local
    # minimum), cheapest at frames 3 and 7 of each stride, so that the spacing rule (3 frames)
    # keeps (15, 3) and (19, 7) and drops every pair that enters frames 1–3.
    frames, period = 24, 12
    i = np.arange(frames)
    phase = 2.0 * np.pi * (i[:, None] - i[None, :]) / period
    bump = 1e-11 * np.minimum(np.abs((i % period) - 3), np.abs((i % period) - 7)).astype(float)
    D = 1.0 - np.cos(phase) + bump[:, None] + bump[None, :]
    np.fill_diagonal(D, 0.0)
    from skinsynth.pipeline.synthesis.motion_graph import recurrent_frames

    pairs, costs, admitted, share = select_transitions(D, threshold=0.5, min_gap=2, spacing=3, coverage=0.95)
    kept_first = [tuple(p) for p in pairs[:4]]
    assert {(3, 15), (15, 3)} <= set(kept_first)  # the cheapest, kept by the spacing rule
    on_part = recurrent_frames(frames, pairs)
    # every frame a transition can enter (j ≥ 1: frame j + 1 ≥ 2) lies on the part
    assert on_part[2:].all() and share >= 22 / 24 - 1e-12
    assert admitted == 0  # the one added lies below T_c: no admission above it
