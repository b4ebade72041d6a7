"""Splicing walks over several clips of one mesh (issue 26; pipeline/inputs/clips.py conventions).

Independent truths: a periodic world cut into two clips (the second recorded elsewhere on the
ground) whose exact continuation is known, so walks that cross from one clip into the other —
by the virtual frame before a clip (j = −(c + 1)) or by a frame j ≥ 0 — must reproduce it
exactly; away from windows a segment is its input moved rigidly (eq. 7); one clip given as
``Clips.single`` is today's code bit for bit.
"""

import numpy as np
import pytest

from skinsynth.pipeline.inputs.clips import Clips
from skinsynth.pipeline.rig.rotations import rotation_exp
from skinsynth.pipeline.synthesis.graph import build_graph
from skinsynth.pipeline.synthesis.splicing import (blend_series, reference_alignment, seam_guidance, seam_windows,
                                                  splice, splice_local, walk_seams)
from skinsynth.pipeline.synthesis.transitions import bone_centroids
from splice_cases import chain_clip, rigid_fits, skin, walk, wrap_clip

UP = np.array([0.0, 1.0, 0.0])


def moved(R, t, turn, shift):
    """Poses R (F, B, 3, 3), t (F, B, 3) carried by the rigid motion x ↦ turn x + shift."""
    return turn @ R, np.einsum("ij,fbj->fbi", turn, t) + shift


@pytest.fixture(scope="module")
def two_clips():
    """Clip a: one cycle of wrap_clip's world (frames 0 … 31); clip b: the same cycle recorded
    elsewhere (turned about the up axis and shifted on the ground), global frames 32 … 63."""
    clip = wrap_clip()
    frames = clip["rotations"].shape[0]
    turn, shift = rotation_exp(np.array([0.0, 1.1, 0.0])), np.array([2.0, 0.0, -1.5])
    R_b, t_b = moved(clip["rotations"], clip["translations"], turn, shift)
    R, t = np.concatenate([clip["rotations"], R_b]), np.concatenate([clip["translations"], t_b])
    graph = build_graph(clip["rest"], clip["faces"], clip["bone_indices"], clip["bone_weights"], R, t,
                        single_component=True)
    pivots = bone_centroids(clip["rest"], clip["bone_indices"], clip["bone_weights"], R.shape[1])
    return dict(clip, rotations=R, translations=t, component=graph.components[0], pivots=pivots, cycle=frames,
                clips=Clips(("a", "b"), (frames, frames)))


def crossing_walks(cycle):
    """Two 80-frame walks and the world frame each starts at (their exact continuation)."""
    a, b = 0, cycle  # global first frames of the clips
    first = walk((a + 5, a + cycle), (b, b + cycle), (a, a + 21))  # a's last → b's first (j = −2), wrap to a (j = −1)
    second = walk((a + 10, a + 21), (b + 21, b + cycle), (b, b + cycle), (a, a + 26))  # j = b:20 ≥ 0, j = −2, j = −1
    return np.stack([first, second]), np.array([5, 10])


@pytest.mark.parametrize("up", [None, UP])
def test_walks_across_clips_continue_the_world_exactly(two_clips, up):
    sources, world_start = crossing_walks(two_clips["cycle"])
    clips = two_clips["clips"]
    animation, k = walk_seams(sources, clips)
    assert list(zip(animation, k)) == [(0, 27), (0, 59), (1, 11), (1, 22), (1, 54)]
    j = clips.transition_j(sources[animation, k])
    assert j.tolist() == [-2, -1, 52, -2, -1]  # into b's start, a's start, b:20 → b:21, b's own wrap, a's start
    spliced = splice_local(two_clips["component"], two_clips["rotations"], two_clips["translations"], sources,
                           window=8, pivots=two_clips["pivots"], up=up, clips=clips)
    F, t = spliced.world()
    bones = two_clips["component"].bones
    for a, start in enumerate(world_start):
        R_true, t_true = two_clips["pose"](start + np.arange(sources.shape[1]))
        assert np.abs(F[a] - R_true[:, bones]).max() < 1e-9
        assert np.abs(t[a] - t_true[:, bones]).max() < 1e-9
    assert seam_windows(sources, 8, clips).counts.sum() > 0  # not a trivial case: the seams were blended


def test_playing_a_clips_last_frame_then_the_next_clips_first_is_a_seam(two_clips):
    # 31 → 32 are consecutive numbers, but a's last frame is not followed by b's first in playback.
    sources = walk((10, 32), (32, 60))[None]
    clips = two_clips["clips"]
    assert walk_seams(sources, clips)[1].tolist() == [22]
    assert walk_seams(sources)[1].tolist() == []  # the one-clip rule sees playback
    windows = seam_windows(sources, 4, clips)
    assert (windows.left.tolist(), windows.right.tolist()) == ([17], [26])  # blended on both sides
    args = (two_clips["component"], two_clips["rotations"], two_clips["translations"], sources)
    F, t = splice(*args, window=4, pivots=two_clips["pivots"], clips=clips)
    R_true, t_true = two_clips["pose"](10 + np.arange(sources.shape[1]))
    bones = two_clips["component"].bones
    assert np.abs(t[0] - t_true[:, bones]).max() < 1e-9  # b is carried onto a's end: the world goes on
    # Read as one clip, frame 32 is played where b was recorded: the character jumps by b's offset.
    F_one, t_one = splice(*args, window=4, pivots=two_clips["pivots"])
    assert np.abs(t_one[0, 22:] - t_true[22:, bones]).max() > 1.0


@pytest.mark.parametrize("blend", ["bones", "key-vertices"])
def test_away_from_windows_segments_across_clips_are_their_input_moved_rigidly(blend):
    full = chain_clip(frames=120, period=20.0, second=33.0, drift=1.0)
    clips = Clips(("first", "second"), (70, 50))
    window = 5
    # a:3 … a:69 (a's last) → b:0 (j = −2); b:20 → a:12 (j = 11 ≥ 0); a:39 → b:31 (j = 100 ≥ 0).
    sources = walk((3, 70), (70, 91), (12, 40), (101, 120))
    k = walk_seams(sources[None], clips)[1]
    assert k.tolist() == [67, 88, 116] and clips.transition_j(sources[k]).tolist() == [-2, 11, 100]
    F, t = splice(full["component"], full["rotations"], full["translations"], sources[None], window=window,
                  pivots=bone_centroids(full["rest"], full["bone_indices"], full["bone_weights"], 6), clips=clips,
                  blend=blend)
    out = skin(full, F[0], t[0])
    reference = skin(full, full["rotations"], full["translations"])[sources]
    animation, frame = seam_windows(sources[None], window, clips).frames()[:2]
    blended = np.zeros(sources.size, bool)
    blended[frame] = True
    assert blended.sum() == 3 * 2 * window
    segment = np.searchsorted(k, np.arange(sources.size), side="right")
    for s in range(k.size + 1):
        frames = np.flatnonzero((segment == s) & ~blended)
        rot, trans, fitted = rigid_fits(out[frames], reference[frames])
        assert np.abs(fitted - reference[frames]).max() < 1e-9  # the input mesh, rigidly moved ...
        assert np.abs(rot - rot[0]).max() < 1e-9 and np.abs(trans - trans[0]).max() < 1e-9  # ... one per segment


def test_seam_guidance_reads_neither_across_a_clip_end_nor_before_a_clip_start():
    from skinsynth.pipeline.rig.rotations import rotation_log

    rng = np.random.default_rng(4)
    clips = Clips(("a", "one", "b"), (12, 1, 8))  # frames 0–11, 12, 13–20
    U = rotation_exp(rng.normal(scale=0.8, size=(clips.total, 2, 3)))
    S = rng.normal(size=(clips.total, 2, 6))
    T = lambda x: np.swapaxes(x, -1, -2)  # noqa: E731
    # a's last → b's first (j = −3); the one-frame clip → b:4 (j = 16); a:6 → the one-frame clip (j = −2).
    sources = np.stack([walk((6, 12), (13, 19)), walk((9, 12), (12, 13), (17, 21), (13, 17)),
                        walk((2, 7), (12, 13), (13, 19))])
    windows = seam_windows(sources, 2, clips)
    assert list(zip(windows.animation, windows.seam)) == [(0, 6), (1, 3), (1, 4), (1, 8), (2, 5), (2, 6)]
    h_left, h_right, jump = seam_guidance(U, S, sources, windows, np.arange(6), clips)

    def difference(Up, Sp, Uq, Sq):
        return np.concatenate([rotation_log(Up @ T(Uq)), Sp - Sq], axis=-1)

    after = {11: (U[11] @ T(U[10]) @ U[11], 2 * S[11] - S[10]), 12: (U[12], S[12]),  # a's last, the one-frame clip
             20: (U[20] @ T(U[19]) @ U[20], 2 * S[20] - S[19]), 6: (U[7], S[7])}
    before = {13: (U[13] @ T(U[14]) @ U[13], 2 * S[13] - S[14]), 12: (U[12], S[12]),  # b's start, the one-frame clip
              17: (U[16], S[16])}
    for w, (a, k) in enumerate(zip(windows.animation, windows.seam)):
        i, target = sources[a, k - 1], sources[a, k]
        U_next, S_next = after[i]
        U_j, S_j = before[target]
        assert np.allclose(h_left[w], difference(U_next, S_next, U[target], S[target]), atol=1e-12)
        assert np.allclose(h_right[w], difference(U_j, S_j, U[i], S[i]), atol=1e-12)
        assert np.allclose(jump[w], difference(U[target], S[target], U_j, S_j)
                           - difference(U_next, S_next, U[i], S[i]), atol=1e-12)


@pytest.mark.parametrize("blend", ["bones", "key-vertices"])
@pytest.mark.parametrize("up", [None, UP])
def test_one_clip_given_as_clips_is_todays_splice_bit_for_bit(up, blend):
    clip = wrap_clip()
    frames = clip["rotations"].shape[0]
    starts = np.array([5, 20, 31])
    sources = np.concatenate([(starts[:, None] + np.arange(50)) % frames,  # wraps (j = −1)
                              np.stack([walk((3, 20), (7, 30), (1, 15))[:50]] * 3)], axis=1)
    pivots = bone_centroids(clip["rest"], clip["bone_indices"], clip["bone_weights"], clip["rotations"].shape[1])
    args = (clip["component"], clip["rotations"], clip["translations"], sources)
    kwargs = dict(window=6, pivots=pivots, up=up, blend=blend, damped_bones=[1], damping=1e-3)
    plain = splice_local(*args, **kwargs)
    single = splice_local(*args, clips=Clips.single(frames), **kwargs)
    for name in ("rotation", "translation", "F", "t"):
        assert np.array_equal(getattr(plain, name), getattr(single, name)), name
    assert np.array_equal(seam_windows(sources, 6).left, seam_windows(sources, 6, Clips.single(frames)).left)
    R, t = clip["rotations"][:, 0], clip["translations"][:, 0]
    for a, b in zip(reference_alignment(R, t, sources, up=up, pivot=pivots[0], window=6),
                    reference_alignment(R, t, sources, up=up, pivot=pivots[0], window=6, clips=Clips.single(frames))):
        assert np.array_equal(a, b)
    U, S = rotation_exp(clip["translations"][:, :, :]), clip["translations"].repeat(2, axis=-1)
    windows = seam_windows(sources, 6)
    for a, b in zip(blend_series(U, S, sources, windows),
                    blend_series(U, S, sources, windows, clips=Clips.single(frames))):
        assert np.array_equal(a, b)


def test_clips_must_hold_the_inputs_frames(two_clips):
    with pytest.raises(ValueError, match="the clips hold 40 frames, the input 64"):
        splice(two_clips["component"], two_clips["rotations"], two_clips["translations"], np.arange(10)[None],
               clips=Clips(("a", "b"), (20, 20)))
