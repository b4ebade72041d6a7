"""The merged rig keeps the input's support (issue 25, part 2): pipeline.synthesis.contact against
brute force (LBS of every vertex) and its properties (the band holds at every frame, nothing moves
where nothing leaves it, the shift is vertical and smooth)."""

import numpy as np
import pytest

from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.rig.rotations import rotation_exp
from skinsynth.pipeline.rig.influence import dense_weights
from skinsynth.pipeline.synthesis.contact.ground import (contact_offsets,
                                                  ground_excess, height_operator, keep_contact, lowest_heights, lowest_range,
                                                  support, support_lowest)

from rigs import random_skin


def _animation(rng, frames, bones, scale=0.3):
    return rotation_exp(rng.normal(scale=scale, size=(frames, bones, 3))), rng.normal(size=(frames, bones, 3))


def _smooth_animation(rng, frames, bones):
    """A cycle: each bone turning and moving sinusoidally (frames, bones, 3, 3), (frames, bones, 3)."""
    phase = 2 * np.pi * np.arange(frames)[:, None, None] / frames
    axes, offsets, sway = rng.normal(scale=0.3, size=(bones, 3)), rng.normal(size=(bones, 3)), rng.normal(size=(bones, 3))
    return rotation_exp(axes * np.sin(phase)), offsets + 0.2 * sway * np.cos(phase)


@pytest.mark.parametrize("up_axis", [1, 2])
def test_heights_by_the_operator_are_the_lbs_heights(up_axis):
    rng = np.random.default_rng(0)
    rest, idx, w = random_skin(rng, 60, 5, 3)  # padding slots: index −1, weight 0
    F, t = _animation(rng, 7, 5)
    heights = np.concatenate([F[..., up_axis, :], t[..., up_axis, None]], -1).reshape(7, -1) \
        @ height_operator(rest, dense_weights(idx, w, 5))
    assert np.allclose(heights, lbs_reference(rest, idx, w, F, t)[..., up_axis], atol=1e-12)


def test_the_band_given_is_the_input_frames_own_range_widened_by_the_slack():
    rng = np.random.default_rng(4)
    rest, idx, w = random_skin(rng, 100, 4, 2)
    F, t = _animation(rng, 6, 4)
    frames = lbs_reference(rest, idx, w, F, t) + rng.normal(scale=0.01, size=(6, 100, 3))  # the input: fit + error
    low, high = lowest_range(frames, 1)
    assert (low, high) == (frames[..., 1].min(), frames[..., 1].min(axis=1).max())
    found = support(rest, idx, w, F, t, up_axis=1, slack=0.01, ground=(low, high))
    assert found.lo == pytest.approx(low - 0.01 * found.height) and found.hi == pytest.approx(high + 0.01 * found.height)


def test_the_band_is_the_inputs_range_of_lowest_points_and_its_lowest_vertices_are_supports():
    rng = np.random.default_rng(1)
    rest, idx, w = random_skin(rng, 300, 6, 3)
    F, t = _animation(rng, 9, 6)
    found = support(rest, idx, w, F, t, up_axis=1, slack=0.0, spread=10)
    lowest = lbs_reference(rest, idx, w, F, t)[..., 1].min(axis=1)
    assert found.lo == pytest.approx(lowest.min()) and found.hi == pytest.approx(lowest.max())
    # every input frame's lowest vertex is a support: the input itself is measured exactly
    assert np.allclose(support_lowest(F[None], t[None], found)[0], lowest, atol=1e-12)
    assert len(found.vertices) < rest.shape[0]


@pytest.mark.parametrize("seed", range(5))
def test_offsets_put_every_frame_in_the_band_and_are_zero_far_from_where_it_leaves(seed):
    rng = np.random.default_rng(seed)
    lowest = np.cumsum(rng.normal(scale=0.05, size=(4, 400)), axis=1)  # wanders out and back
    lo, hi, radius = -0.3, 0.2, 6
    delta = contact_offsets(lowest, lo, hi, radius=radius)
    corrected = lowest + delta
    assert np.all(corrected >= lo - 1e-12) and np.all(corrected <= hi + 1e-12)
    outside = (lowest < lo) | (lowest > hi)
    assert outside.any()
    reach = 3 * 2 * radius  # 3 rounds, each spreading 2·radius frames further
    near = np.zeros_like(outside)
    for shift in range(-reach, reach + 1):
        near[:, max(0, shift):400 + min(0, shift)] |= outside[:, max(0, -shift):400 - max(0, shift)]
    assert np.all(delta[~near] == 0.0) and (~near).any()


def test_a_dip_through_the_floor_is_lifted_smoothly_where_the_band_leaves_room():
    frames = np.arange(200)
    lowest = (-0.5 * np.exp(-((frames - 100) / 6.0) ** 2))[None]  # a foot pushed 0.4 through the floor
    delta = contact_offsets(lowest, -0.1, 0.6, radius=8)[0]
    corrected = lowest[0] + delta
    assert corrected.min() == pytest.approx(-0.1) and np.all(delta >= 0.0)  # lifted just enough, never pushed down
    # spread over the window: smoother than the dip itself
    assert np.max(np.abs(np.diff(delta, 2))) < 0.5 * np.max(np.abs(np.diff(lowest[0], 2)))
    violating = np.flatnonzero(lowest[0] < -0.1)
    moved = np.flatnonzero(delta)
    assert moved[0] >= violating[0] - 16 and moved[-1] <= violating[-1] + 16


def test_keep_contact_moves_only_the_up_translation_and_only_where_needed():
    rng = np.random.default_rng(2)
    rest, idx, w = random_skin(rng, 200, 4, 2)
    F, t = _smooth_animation(rng, 120, 4)
    found = support(rest, idx, w, F, t, up_axis=1)
    # the input itself stays in its band: nothing changes, bit for bit
    F1, t1 = F[None].astype(np.float32), t[None].astype(np.float32)
    kept = t1.copy()
    assert not keep_contact(F1, t1, found).any() and np.array_equal(t1, kept)
    # the whole character sunk by a quarter of its height over frames 60..69: raised back
    sunk = t1.copy()
    sunk[0, 60:70, :, 1] -= 0.25 * found.height
    before = sunk.copy()
    delta = keep_contact(F1, sunk, found)
    assert np.array_equal(sunk[..., [0, 2]], before[..., [0, 2]])  # no sideways motion
    lowest = lbs_reference(rest, idx, w, F1[0].astype(np.float64), sunk[0].astype(np.float64))[..., 1].min(axis=1)
    assert lowest.min() >= found.lo - 1e-5 * found.height
    assert delta[0, 60:70].min() > 0.0
    reach = 3 * 2 * 8  # each of the 3 rounds spreads a correction 2·radius frames further (the module notes)
    assert np.all(delta[0, :60 - reach] == 0.0) and np.all(delta[0, 70 + reach:] == 0.0)


def test_measures_of_ground_on_closed_forms():
    rng = np.random.default_rng(3)
    body = rng.normal(size=(50, 3))
    speed = np.array([0.02, 0.0, 0.01])
    walking = body[None] + np.arange(20)[:, None, None] * speed  # rigid, constant velocity, on the ground
    assert np.allclose(lowest_heights(walking), body[:, 1].min())
    below, above = ground_excess(np.array([-0.2, 0.5]), np.array([0.0, 0.4]), height=2.0)
    assert (below, above) == pytest.approx((0.1, 0.05))


def test_the_band_of_lowest_points_spans_every_clip():
    rng = np.random.default_rng(5)
    body = rng.normal(size=(50, 3))
    walk = body[None] + np.arange(12)[:, None, None] * np.array([0.02, 0.0, 0.01])
    both = np.concatenate([walk, walk[:8] + np.array([5.0, -0.7, -3.0])])  # a second take, 0.7 lower
    assert lowest_range(both) == pytest.approx((body[:, 1].min() - 0.7, body[:, 1].min()))


def test_ground_floored_raises_only_the_lower_end():
    """The band's floor with ground contacts: the lowest clip ground less the tolerance, never
    lowered, never above the band's upper end."""
    from skinsynth.pipeline.synthesis.contact.ground import Support, ground_floored

    found = Support(vertices=np.arange(3), bones=np.arange(2), operator=np.zeros((8, 3)), lo=-0.05, hi=0.1,
                    height=2.0, up_axis=1)
    assert ground_floored(found, [0.0, 0.02], tolerance=0.01).lo == pytest.approx(-0.02)
    assert ground_floored(found, [-0.2], tolerance=0.01).lo == -0.05  # the input's own range already higher
    assert ground_floored(found, [0.5], tolerance=0.01).lo == 0.1  # never above the upper end
    assert ground_floored(found, [0.0], tolerance=0.01).hi == 0.1


def test_support_without_drops_the_vertices_and_keeps_the_others_heights():
    """support_without: the remaining vertices' lowest heights are those of the full support's
    columns for them (bones only they needed dropped); removing every vertex leaves none."""
    from skinsynth.pipeline.synthesis.contact.ground import support, support_lowest, support_without

    rng = np.random.default_rng(2)
    V, B, frames = 40, 5, 6
    rest = rng.normal(size=(V, 3))
    indices = np.stack([rng.permutation(B)[:2] for _ in range(V)])
    weights = np.full((V, 2), 0.5)
    rotations = np.stack([[rotation_exp(rng.normal(scale=0.3, size=3)) for _ in range(B)] for _ in range(frames)])
    translations = rng.normal(scale=0.1, size=(frames, B, 3))
    found = support(rest, indices, weights, rotations, translations, band=1.0, most=V)
    dropped = found.vertices[::2]
    kept = support_without(found, dropped)
    np.testing.assert_array_equal(kept.vertices, found.vertices[1::2])
    assert (kept.lo, kept.hi) == (found.lo, found.hi)
    F, t = rotations[None].astype(np.float32), translations[None].astype(np.float32)
    heights = lbs_reference(rest, indices, weights, rotations, translations)[..., 1]
    np.testing.assert_allclose(support_lowest(F, t, kept)[0], heights[:, kept.vertices].min(axis=1), atol=1e-5)
    assert support_without(found, found.vertices).vertices.size == 0
