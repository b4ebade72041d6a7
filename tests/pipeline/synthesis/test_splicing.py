import numpy as np
import pytest

from skinsynth.pipeline.inputs.examples import bending_bar
from skinsynth.pipeline.synthesis.graph import build_graph
from skinsynth.pipeline.rig.rotations import rotation_exp
from skinsynth.pipeline.skin.skin_fit import fit_skin
from skinsynth.pipeline.synthesis.splicing import blend_series, seam_windows, splice, walk_sources
from skinsynth.pipeline.synthesis.transitions import bone_centroids, candidate_transitions
from splice_cases import chain_clip, rigid_fits, second_differences, skin, splice_clip, walk, wrap_clip


@pytest.fixture(scope="module")
def loop_clip():
    return chain_clip(frames=60, period=20.0)  # three identical 20-frame cycles


@pytest.fixture(scope="module")
def drifting_loop_clip():
    return chain_clip(frames=60, period=20.0, drift=1.0)


@pytest.fixture(scope="module")
def real_clip():
    return chain_clip(frames=120, period=20.0, second=33.0)  # no frame repeats


@pytest.fixture(scope="module")
def drifting_real_clip():
    return chain_clip(frames=120, period=20.0, second=33.0, drift=1.0)


def free_frames(sources, window):
    animation, frame = seam_windows(np.atleast_2d(sources), window).frames()[:2]
    mask = np.zeros(np.atleast_2d(sources).shape, bool)
    mask[animation, frame] = True
    return mask


def test_seam_windows_are_clipped_at_neighbours_and_ends():
    # Seams at k = 3, 10, 12, 30 of a 40-frame walk, window 4 (a whole window spans 2·4 + 2 frames).
    sources = walk((50, 53), (7, 14), (20, 22), (60, 78), (5, 15))
    assert sources.size == 40
    w = seam_windows(sources[None], 4)
    assert w.seam.tolist() == [3, 10, 12, 30]
    # first seam: left clipped at frame 0; gap 7 ≤ 8 to the next seam: shared fixed frame 3 + 3
    # gap 2: shared fixed frame 10 + 1; gap 18: both half-windows whole; last seam: whole.
    assert w.left.tolist() == [0, 6, 11, 25]
    assert w.right.tolist() == [6, 11, 16, 34]
    animation, frame, owner, first, last = w.frames()
    assert np.unique(frame).size == frame.size  # no frame blended twice
    assert not np.isin(frame, np.concatenate([w.left, w.right])).any()  # fixed frames are not free
    assert w.counts.tolist() == [5, 4, 4, 8]
    # A seam at k = 1 and one at M − 1: their windows lie on one side only.
    edge = walk((30, 31), (10, 20), (40, 41))
    w = seam_windows(edge[None], 4)
    assert w.seam.tolist() == [1, 11] and w.left.tolist() == [0, 6] and w.right.tolist() == [5, 11]
    # window 0: nothing is blended.
    assert seam_windows(sources[None], 0).counts.sum() == 0


def test_walk_validation():
    # A seam onto frame 0 is the wrap, the transition (6, −1): accepted.
    assert walk_sources([[5, 6, 0, 1]], 10).tolist() == [[5, 6, 0, 1]]
    with pytest.raises(ValueError, match="lie in"):
        walk_sources([[5, 6, -1, 0]], 10)
    with pytest.raises(ValueError, match="lie in"):
        walk_sources([[5, 6, 7, 10]], 10)
    assert walk_sources([0, 1, 2, 7], 10).shape == (1, 4)


@pytest.mark.parametrize("spread", [False, True])
def test_poisson_blend_solves_zhengs_discrete_equation(spread):
    # Rotations about one fixed axis commute, so the blend of U = Rz(θ) must be Zheng's scalar
    # Poisson blend of θ: θ̃(m−1) − 2θ̃(m) + θ̃(m+1) = g(source[m]) (the input's own second
    # difference there, plus the seam's velocity jump spread evenly), θ̃ = θ(source) at the
    # window's two fixed frames; the linear coordinates likewise, with no rotation in sight.
    rng = np.random.default_rng(4)
    frames = 120
    theta = np.cumsum(np.cumsum(rng.normal(0.0, 0.02, (frames, 2)), axis=0), axis=0)  # angles near π too
    theta += np.array([3.0, -0.5])
    U = rotation_exp(np.concatenate([np.zeros((frames, 2, 2)), theta[..., None]], axis=-1))
    S = rng.normal(size=(frames, 2, 4)).cumsum(axis=0)
    sources = np.stack([walk((10, 40), (71, 101)), walk((30, 35), (50, 53), (80, 102), (11, 41))])
    windows = seam_windows(sources, 6)
    animation, frame, R, lin = blend_series(U, S, sources, windows, spread_velocity=spread)
    angle = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    for s in range(windows.seam.size):
        a, left, right, k = windows.animation[s], windows.left[s], windows.right[s], windows.seam[s]
        inside = (animation == a) & (frame > left) & (frame < right)
        for series, blended in ((theta, angle[inside]), (S, lin[inside])):
            ends = series[sources[a, [left, right]]]
            out = np.concatenate([ends[:1], blended, ends[1:]])
            if series is theta:  # angles of rotations: modulo 2π, on one branch along the window
                out = np.unwrap(out, axis=0)
            src = sources[a, left + 1:right]
            g = series[src - 1] - 2 * series[src] + series[src + 1]
            residual = out[:-2] - 2 * out[1:-1] + out[2:] - g
            if spread:
                i, j = sources[a, k - 1], sources[a, k] - 1
                residual -= ((series[j + 1] - series[j]) - (series[i + 1] - series[i])) / (right - left + 1)
            assert np.abs(residual).max() < 1e-9


@pytest.mark.parametrize("clip_name", ["real_clip", "drifting_real_clip"])
def test_walk_without_seams_reproduces_the_input(clip_name, request):
    clip = request.getfixturevalue(clip_name)
    sources = np.stack([np.arange(5, 65), np.arange(50, 110)])
    F, t = splice_clip(clip, sources)
    bones = clip["component"].bones
    assert F.shape == (2, 60, len(bones), 3, 3) and t.shape == (2, 60, len(bones), 3) and F.dtype == np.float64
    assert np.abs(F - clip["rotations"][sources][:, :, bones]).max() < 1e-10
    assert np.abs(t - clip["translations"][sources][:, :, bones]).max() < 1e-10


def test_away_from_seams_each_segment_is_the_input_moved_rigidly(drifting_real_clip):
    clip = drifting_real_clip
    window = 5
    # Three transitions (any (i, j) will do here), segments long enough to have frames outside
    # the windows.
    sources = walk((3, 25), (61, 80), (11, 30), (90, 110))
    F, t = splice_clip(clip, sources[None], window=window)
    out = skin(clip, F[0], t[0])
    reference = skin(clip, clip["rotations"], clip["translations"])[sources]
    blended = free_frames(sources, window)[0]
    seams = np.flatnonzero(sources[1:] != sources[:-1] + 1) + 1
    assert seams.size == 3 and blended.sum() == 3 * 2 * window
    segment = np.searchsorted(seams, np.arange(sources.size), side="right")
    for s in range(seams.size + 1):
        frames = np.flatnonzero((segment == s) & ~blended)
        rot, trans, moved = rigid_fits(out[frames], reference[frames])
        assert np.abs(moved - reference[frames]).max() < 1e-9  # input mesh, rigidly moved ...
        assert np.abs(rot - rot[0]).max() < 1e-9 and np.abs(trans - trans[0]).max() < 1e-9  # ... one per segment
        if s == 0:
            assert np.abs(rot[0] - np.eye(3)).max() < 1e-12 and np.abs(trans[0]).max() < 1e-12


def test_exact_loop_transitions_are_seamless(loop_clip):
    clip = loop_clip
    # Frames f and f + 20 are the same pose: i → j = i ∓ 20 continues the input exactly.
    sources = walk((5, 45), (25, 55), (35, 51), (11, 30))
    F, t = splice_clip(clip, sources[None])
    bones = clip["component"].bones
    assert np.abs(F[0] - clip["rotations"][sources][:, bones]).max() < 1e-8
    assert np.abs(t[0] - clip["translations"][sources][:, bones]).max() < 1e-8


def test_exact_loop_with_drift_continues_the_input_rigidly(drifting_loop_clip):
    # Poses repeat in the reference bone's frame but the whole mesh drifts: the output is the
    # input, each segment moved by the rigid transform that matches it up (eq. 7), windows included.
    clip = drifting_loop_clip
    sources = walk((5, 45), (25, 55), (35, 51))
    F, t = splice_clip(clip, sources[None])
    out = skin(clip, F[0], t[0])
    reference = skin(clip, clip["rotations"], clip["translations"])[sources]
    seams = np.flatnonzero(sources[1:] != sources[:-1] + 1) + 1
    segment = np.searchsorted(seams, np.arange(sources.size), side="right")
    for s in range(seams.size + 1):
        frames = np.flatnonzero(segment == s)
        rot, trans, moved = rigid_fits(out[frames], reference[frames])
        assert np.abs(moved - reference[frames]).max() < 1e-8
        assert np.abs(rot - rot[0]).max() < 1e-8
    # No jump at the seams: the output is as smooth as the input.
    assert second_differences(out).max() < 1.01 * second_differences(
        skin(clip, clip["rotations"], clip["translations"])).max()


def test_real_transitions_have_continuous_velocity(real_clip):
    clip = real_clip
    transitions = clip["component"].transitions
    frames, half, window = clip["rotations"].shape[0], 20, 8
    base = second_differences(skin(clip, clip["rotations"], clip["translations"])).max()
    # The 12 best candidate transitions (i, j), then the same with j moved on by 3 frames (poor
    # transitions): each in a walk of 20 frames up to i and 20 from j + 1.
    for shift in (0, 3):
        local_minima, _ = candidate_transitions(transitions.D, transitions.threshold)
        chosen = [(i, j + shift) for i, j in local_minima if i >= half - 1 and j + shift + half < frames][:12]
        assert len(chosen) == 12
        sources = np.stack([walk((i - half + 1, i + 1), (j + 1, j + half + 1)) for i, j in chosen])
        worst = {}
        for w in (0, window):
            F, t = splice_clip(clip, sources, window=w)
            worst[w] = np.array([second_differences(skin(clip, F[a], t[a]))[half - w - 2:half + w].max()
                                 for a in range(len(chosen))])
        # Every blended transition is as smooth as the input's own motion (max over the whole
        # window, seam included) ...
        assert worst[window].max() < 1.5 * base
        if shift:
            # ... even where splicing without blending (eq. 7 alone, window 0) jumps visibly.
            assert worst[0].min() > 2.0 * base


def test_reference_bone_stays_rigid_and_batches_equal_single_walks(drifting_real_clip):
    clip = drifting_real_clip
    sources = np.stack([walk((10, 40), (71, 101)),
                        walk((30, 31), (50, 53), (80, 102), (11, 45)),  # seams at k = 1, 4, 26
                        walk((60, 119), (3, 4))])  # a seam at the last frame
    F, t = splice_clip(clip, sources, window=6)
    at = clip["component"].bones.index(clip["component"].transitions.reference)
    ref = F[:, :, at]
    assert np.abs(np.swapaxes(ref, -1, -2) @ ref - np.eye(3)).max() < 1e-12
    assert np.abs(np.linalg.det(ref) - 1.0).max() < 1e-12
    for a in range(3):
        F1, t1 = splice_clip(clip, sources[a:a + 1], window=6)
        assert np.abs(F1[0] - F[a]).max() < 1e-12 and np.abs(t1[0] - t[a]).max() < 1e-12
    # Memory knobs and dtype change nothing beyond rounding.
    F2, t2 = splice_clip(clip, sources, window=6, block_frames=7, animation_block=1)
    assert np.abs(F2 - F).max() < 1e-12 and np.abs(t2 - t).max() < 1e-12
    F3, t3 = splice_clip(clip, sources, window=6, dtype=np.float32)
    assert F3.dtype == np.float32 and t3.dtype == np.float32
    assert np.abs(F3 - F).max() < 1e-5 and np.abs(t3 - t).max() < 1e-5


def test_anchored_solve_equals_plain_eq9_on_a_full_rank_operator(real_clip):
    component = real_clip["component"]
    assert component.operator.rank() == 12 * len(component.transitions.local_bones)
    sources = np.stack([walk((10, 40), (71, 101)), walk((30, 35), (50, 53), (80, 102), (11, 41))])
    anchored = splice_clip(real_clip, sources, anchored=True, blend="key-vertices")
    plain = splice_clip(real_clip, sources, anchored=False, blend="key-vertices")
    assert np.abs(anchored[0] - plain[0]).max() < 1e-7 and np.abs(anchored[1] - plain[1]).max() < 1e-7


def test_anchored_solve_keeps_what_a_rank_deficient_operator_cannot_see():
    # Hard weights (one influence): the key vertices do not determine every bone direction
    # (rank G < 12 B'). Plain eq. 9 zeroes those directions inside the windows; the anchored
    # solve keeps the source's, so an exact loop stays exact.
    clip = chain_clip(frames=60, period=20.0, max_influences=1)
    component = clip["component"]
    assert component.operator.rank() < 12 * len(component.transitions.local_bones)
    sources = walk((5, 45), (25, 55))
    bones = component.bones
    F, t = splice_clip(clip, sources[None], blend="key-vertices")
    assert np.abs(F[0] - clip["rotations"][sources][:, bones]).max() < 1e-8
    assert np.abs(t[0] - clip["translations"][sources][:, bones]).max() < 1e-8
    F, t = splice_clip(clip, sources[None], anchored=False, blend="key-vertices")
    assert np.abs(t[0] - clip["translations"][sources][:, bones]).max() > 1e-2


def test_fitted_bending_bar_loop():
    # The fitted-skin path: a two-cycle bending bar (frames f and f + 20 identical), 4 bones.
    vertices, faces = bending_bar(frames=40, rings=12, segments=8, cycles=2)
    fit = fit_skin(vertices, 4, iterations=10)
    graph = build_graph(fit.rest_vertices, faces, fit.bone_indices, fit.bone_weights, fit.rotations,
                        fit.translations, single_component=True)
    sources = walk((2, 32), (12, 37))  # 31 → j = 11, the same pose
    F, t = splice(graph.components[0], fit.rotations, fit.translations, sources[None])
    assert np.abs(F[0] - fit.rotations[sources]).max() < 1e-8
    assert np.abs(t[0] - fit.translations[sources]).max() < 1e-8


@pytest.mark.parametrize("blend", ["bones", "key-vertices"])
def test_each_distinct_window_is_solved_once_and_matches_a_per_window_solve(drifting_real_clip, blend):
    from skinsynth.pipeline.synthesis.deformation_gradients import rotation_times_strain
    from skinsynth.pipeline.synthesis.splicing import distinct_windows, gradient_series, reference_alignment
    from skinsynth.pipeline.synthesis.transitions import local_frame_positions

    clip, window = drifting_real_clip, 4
    component = clip["component"]
    # The first two walks take the same three transitions with long segments (identical windows);
    # the third has short segments (clipped windows) and one long-segment transition of the others.
    sources = np.stack([walk((3, 25), (61, 80), (11, 30), (90, 110)), walk((10, 25), (61, 80), (11, 30), (90, 117)),
                        walk((5, 25), (61, 66), (100, 104), (40, 80), (11, 22))])
    windows = seam_windows(sources, window)
    _, unique, inverse = distinct_windows(sources, windows)
    assert windows.seam.size == 10 and unique.seam.size == 6 and inverse.max() == 5
    F, t = splice_clip(clip, sources, window=window, blend=blend)
    # Brute force: every window blended and solved on its own, then eq. 10.
    F_in, t_in, local = local_frame_positions(clip["rotations"], clip["translations"], component.transitions.reference,
                                              component.bones)
    if blend == "bones":
        pivots = bone_centroids(clip["rest"], clip["bone_indices"], clip["bone_weights"], clip["rotations"].shape[1])
        pivots = pivots[local]
        animation, frame, rot, lin = blend_series(F_in, np.einsum("fbij,bj->fbi", F_in, pivots) + t_in, sources,
                                                  windows)
        F_local, t_local = rot, lin - np.einsum("lbij,bj->lbi", rot, pivots)
    else:  # eq. 9, anchored
        U, S = gradient_series(component.strain)
        animation, frame, rot, lin = blend_series(U, S, sources, windows)
        src = sources[animation, frame]
        D = rotation_times_strain(rot, lin) - rotation_times_strain(U, S)[src]
        dF, dt = component.operator.solve(D + component.operator.constant.reshape(-1, 3, 3))
        F_local, t_local = F_in[src] + dF, t_in[src] + dt
    R_ref, t_ref = reference_alignment(clip["rotations"][:, component.transitions.reference],
                                       clip["translations"][:, component.transitions.reference], sources)
    at = np.searchsorted(component.bones, local)
    expected_F = R_ref[animation, frame][:, None] @ F_local
    expected_t = np.einsum("lab,lkb->lka", R_ref[animation, frame], t_local) + t_ref[animation, frame][:, None]
    assert np.abs(F[animation[:, None], frame[:, None], at] - expected_F).max() < 1e-12
    assert np.abs(t[animation[:, None], frame[:, None], at] - expected_t).max() < 1e-12


# ---------------------------------------------------------------------------- the wrap: seams (i, −1)


@pytest.mark.parametrize("up", [None, np.array([0.0, 1.0, 0.0])])
def test_a_seam_onto_frame_0_continues_a_periodic_clip_exactly(up):
    from skinsynth.pipeline.synthesis.splicing import splice_local

    clip = wrap_clip()
    frames = clip["rotations"].shape[0]
    # The graph finds the loop itself: after the last frame, continue at frame 0.
    assert [frames - 1, -1] in clip["component"].transitions.pairs.tolist()
    # Walks round the clip: seams (F−1, −1) at every lap, windows of 8 frames on each side.
    starts = np.array([5, 20, 31])
    sources = (starts[:, None] + np.arange(80)) % frames
    pivots = bone_centroids(clip["rest"], clip["bone_indices"], clip["bone_weights"], clip["rotations"].shape[1])
    spliced = splice_local(clip["component"], clip["rotations"], clip["translations"], sources, window=8,
                           pivots=pivots, up=up)
    F, t = spliced.world()
    bones = clip["component"].bones
    for a, start in enumerate(starts):
        R_true, t_true = clip["pose"](start + np.arange(80))  # the world the clip was cut from
        assert np.abs(F[a] - R_true[:, bones]).max() < 1e-9
        assert np.abs(t[a] - t_true[:, bones]).max() < 1e-9
    # Not a trivial case: the seams were blended, and the reference bone moved on at each lap.
    assert seam_windows(sources, 8).counts.sum() > 0
    R0, t0 = clip["pose"](starts[:1] + frames)
    assert np.abs(t0 - clip["translations"][starts[0]]).max() > 0.1


def test_a_poor_wrap_is_blended_like_any_transition():
    # A clip not at constant velocity at its wrap (the bend's acceleration is largest at frame 0):
    # across the seam (F−1, −1) the mesh's acceleration stays within 1.5 × the clip's own largest.
    vertices, faces = bending_bar(frames=40, rings=12, segments=8, cycles=1)
    fit = fit_skin(vertices, 4, iterations=10)
    graph = build_graph(fit.rest_vertices, faces, fit.bone_indices, fit.bone_weights, fit.rotations,
                        fit.translations, single_component=True)
    assert [39, -1] in graph.components[0].transitions.pairs.tolist()
    clip = dict(rest=fit.rest_vertices, bone_indices=fit.bone_indices, bone_weights=fit.bone_weights)
    sources = (np.arange(100) + 10) % 40  # seams at k = 30 and 70
    F, t = splice(graph.components[0], fit.rotations, fit.translations, sources[None],
                  pivots=bone_centroids(fit.rest_vertices, fit.bone_indices, fit.bone_weights, 4))
    out = second_differences(skin(clip, F[0], t[0]))
    base = second_differences(skin(clip, fit.rotations, fit.translations)).max()
    assert out.max() < 1.5 * base
    # Away from the windows each segment is the input, moved by one rigid transform (eq. 7).
    away = ~free_frames(sources, 8)[0]
    mesh, reference = skin(clip, F[0], t[0]), skin(clip, fit.rotations, fit.translations)[sources]
    segment = np.searchsorted([30, 70], np.arange(100), side="right")
    for s in range(3):
        frames = np.flatnonzero((segment == s) & away)
        rot, _, moved = rigid_fits(mesh[frames], reference[frames])
        assert frames.size >= 20 and np.abs(moved - reference[frames]).max() < 1e-9
        assert np.abs(rot - rot[0]).max() < 1e-9


def test_seam_guidance_extrapolates_frame_minus_1_as_frame_0_going_backwards():
    from skinsynth.pipeline.synthesis.splicing import seam_guidance
    from skinsynth.pipeline.rig.rotations import rotation_log

    rng = np.random.default_rng(8)
    frames = 20
    U = rotation_exp(rng.normal(scale=0.8, size=(frames, 3, 3)))  # 3 items
    S = rng.normal(size=(frames, 3, 6))
    # Seams onto frame 0 from frame 10 (a near-repeat across the ends) and from the last frame.
    sources = np.stack([walk((4, 11), (0, 9)), walk((12, 20), (0, 8))])
    windows = seam_windows(sources, 3)
    assert windows.seam.tolist() == [7, 8]
    h_left, h_right, jump = seam_guidance(U, S, sources, windows, np.arange(2))
    T = lambda x: np.swapaxes(x, -1, -2)  # noqa: E731
    U_before, S_before = U[0] @ T(U[1]) @ U[0], 2 * S[0] - S[1]  # U(−1), S(−1)
    U_after, S_after = U[19] @ T(U[18]) @ U[19], 2 * S[19] - S[18]  # U(F), for i = F − 1
    for w, (i, U_next, S_next) in enumerate([(10, U[11], S[11]), (19, U_after, S_after)]):
        assert np.allclose(h_right[w], np.concatenate([rotation_log(U_before @ T(U[i])),
                                                       S_before - S[i]], axis=-1), atol=1e-12)
        assert np.allclose(h_left[w], np.concatenate([rotation_log(U_next @ T(U[0])),
                                                      S_next - S[0]], axis=-1), atol=1e-12)
        step_right = np.concatenate([rotation_log(U[0] @ T(U_before)), S[0] - S_before], -1)
        step_left = np.concatenate([rotation_log(U_next @ T(U[i])), S_next - S[i]], -1)
        assert np.allclose(jump[w], step_right - step_left, atol=1e-12)
