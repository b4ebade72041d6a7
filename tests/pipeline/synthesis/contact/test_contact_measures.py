"""The feet measures (issue 35 part 4) on closed forms: pipeline/mesh/contact_measures.py."""

import numpy as np
import pytest

from skinsynth.pipeline.inputs.clips import Clips
from skinsynth.pipeline.mesh.contact_measures import (BAND, Steps, character_height, clip_ground, contact_steps,
                                                           input_steps, limits_summary, measure_frames, measure_input,
                                                           played_input, ratios, summary)


def block(frames=30, velocity=(0.0, 0.0, 0.0), lift=0.0):
    """A 1 × 2 × 1 box of vertices (H = 2) whose sole lies at height ``lift``, moving rigidly by
    ``velocity`` per frame: (frames, V, 3)."""
    grid = np.stack(np.meshgrid(np.linspace(0, 1, 5), np.linspace(0, 2, 9), np.linspace(0, 1, 5),
                                indexing="ij"), axis=-1).reshape(-1, 3)
    return grid[None] + np.arange(frames)[:, None, None] * np.asarray(velocity) + np.array([0.0, lift, 0.0])


def test_a_block_sliding_on_the_ground_slides_at_its_speed_over_the_height():
    x = block(velocity=(0.03, 0.0, 0.04))  # 0.05 a frame; H = 2
    H = character_height(x[0])
    assert H == 2.0 and clip_ground(x) == 0.0
    got = summary(contact_steps(x, 0.0, H))
    assert got["steps"] == got["contact_steps"] == 29
    assert got["slide_median"] == pytest.approx(0.025) and got["slide_p95"] == pytest.approx(0.025)
    assert got["sliding_share"] == 1.0
    assert got["float_max"] == 0.0 and got["penetration_max"] == 0.0
    assert got["largest_accel"] == pytest.approx(0.0, abs=1e-12)  # constant velocity


def test_a_block_resting_still_does_not_slide():
    got = summary(contact_steps(block(), 0.0, 2.0))
    assert got["contact_steps"] == 29
    assert (got["slide_median"], got["slide_p95"], got["sliding_share"]) == (0.0, 0.0, 0.0)


def test_a_lifted_block_floats_by_its_lift_and_a_sunk_one_penetrates():
    lifted = summary(contact_steps(block(lift=0.01), 0.0, 2.0))  # 0.5 % of the height, inside the 1 % band
    assert lifted["float_median"] == pytest.approx(0.005) and lifted["float_max"] == pytest.approx(0.005)
    assert lifted["penetration_max"] == 0.0
    sunk = summary(contact_steps(block(lift=-0.03), 0.0, 2.0))
    assert sunk["penetration_median"] == pytest.approx(0.015) and sunk["float_max"] == 0.0
    # above the band: no contact at all
    assert summary(contact_steps(block(lift=2.5 * BAND * 2.0), 0.0, 2.0))["contact_steps"] == 0


def test_contact_needs_two_consecutive_frames_near_the_ground():
    x = block(frames=6)
    x[[1, 3, 4], :, 1] += 1.0  # frames 0, 2 and 5 rest, each alone: no step rests at both ends
    got = contact_steps(x, 0.0, 2.0)
    assert got.slide.size == 0
    x[4, :, 1] -= 1.0  # now frames 4 and 5 both rest: the one step 4 → 5
    assert contact_steps(x, 0.0, 2.0).slide.size == 1


def test_ground_is_a_low_percentile_not_one_dip():
    x = block(frames=100, lift=0.0)
    x[:, :, 1] += np.linspace(0, 0.5, 100)[:, None] ** 2  # rises slowly away from the floor
    x[7, :, 1] -= 0.4  # one frame through the floor
    ground = clip_ground(x)
    assert -0.01 < ground < 0.01


def test_blocks_count_every_step_once():
    rng = np.random.default_rng(4)
    x = block(frames=50, velocity=(0.01, 0.0, 0.0)) + rng.normal(scale=0.002, size=(50, 225, 3))
    whole = contact_steps(x, 0.0, 2.0)
    blocks = measure_frames(lambda s, e: x[s:e], 50, 0.0, 2.0, block=7)
    assert blocks.steps == whole.steps == 49
    assert np.allclose(blocks.slide, whole.slide) and np.allclose(blocks.offset, whole.offset)
    assert blocks.accel == pytest.approx(whole.accel)


def test_the_slide_where_the_plants_could_not_hold_a_foot_is_told_apart():
    """Issue 62: where a limb is held at its range (flag 1) or its turn cut (flag 2) the foot may
    slide; the report says in which share of the frames and how much it slid there. A block resting
    still for 20 frames, then sliding 0.02 a frame (H = 2) while flagged: the flagged steps are the
    sliding ones (a step is flagged where either end is), counted the same in blocks of frames."""
    x = np.concatenate([block(frames=20), block(frames=20, velocity=(0.02, 0.0, 0.0))[1:]])  # slides from frame 19
    limited = np.zeros(39, np.uint8)
    limited[20:30] = 1
    limited[30:] = 2
    for measured in (contact_steps(x, 0.0, 2.0, limited=limited > 0),
                     measure_frames(lambda s, e: x[s:e], 39, 0.0, 2.0, block=7, limited=limited > 0)):
        got = limits_summary(measured, limited[None])
        assert got["held_frames"] == pytest.approx(10 / 39) and got["cut_frames"] == pytest.approx(9 / 39)
        assert got["contact_steps"] == pytest.approx(19 / 38)  # steps 19→20 … 37→38
        assert got["slide_median"] == pytest.approx(0.01) and got["sliding_share"] == 1.0
    unflagged = limits_summary(contact_steps(x, 0.0, 2.0, limited=np.zeros(39, bool)), np.zeros((1, 39), np.uint8))
    assert unflagged == {"held_frames": 0.0, "cut_frames": 0.0, "contact_steps": 0.0}


def test_the_step_from_one_clip_to_the_next_is_not_motion():
    walk = block(frames=12, velocity=(0.02, 0.0, 0.0))
    elsewhere = block(frames=8, velocity=(0.02, 0.0, 0.0)) + np.array([5.0, 0.0, -3.0])  # another take, 6 units away
    clips = Clips(("walk", "elsewhere"), (12, 8))
    both = np.concatenate([walk, elsewhere])
    assert contact_steps(both, 0.0, 2.0).slide.max() > 1.0  # read as one clip, the cut is a huge slide
    measured, grounds = measure_input(both, clips.starts, 2.0, block=5)
    assert measured.steps == 18 and np.allclose(grounds, 0.0)
    assert np.allclose(measured.slide, 0.01) and measured.accel == pytest.approx(0.0, abs=1e-12)
    same = contact_steps(both, 0.0, 2.0, plays_on=clips.plays_on())
    assert np.allclose(same.slide, 0.01)


def test_the_input_played_along_walks_is_the_input_at_the_frames_played():
    """A clip that rests for 10 frames and then slides 0.04 a frame (H = 2): a walk that loops on
    the resting frames plays no slide, one that loops on the sliding frames plays 0.02 of the
    height at every step, and the steps across its seams (a jump of 0.36) are not counted; the
    whole clip played in order is the input's own measure."""
    rest_then_slide = np.concatenate([block(frames=10), block(frames=10, velocity=(0.04, 0.0, 0.0))])
    starts = np.array([0, 20])
    still = np.tile(np.arange(0, 8), 5)[None]  # frames 0–7 again and again
    sliding = np.tile(np.arange(10, 20), 4)[None]
    table = input_steps(rest_then_slide, starts, 2.0)
    assert played_input(table, still, starts).slide.max() == 0.0
    moving = played_input(table, sliding, starts)
    assert moving.slide.size == 36 and np.allclose(moving.slide, 0.02)  # 9 steps a loop, the 3 seams not
    whole = played_input(table, np.arange(20)[None], starts)
    own, _ = measure_input(rest_then_slide, starts, 2.0)
    assert np.array_equal(whole.slide, own.slide) and whole.steps == own.steps and whole.accel == own.accel


def test_the_played_input_gathered_is_the_played_frames_measured_again():
    """Brute force: the played frames themselves stacked and measured (steps across seams and
    clips left out) give the same figures as the input's steps gathered, on two clips of a wobbling
    block and random walks with seams."""
    rng = np.random.default_rng(4)
    clip_a = block(frames=30, velocity=(0.01, 0.0, 0.0)) + rng.normal(0.0, 0.003, (30, 1, 3)) * [1.0, 0.0, 1.0]
    clip_b = block(frames=25, lift=0.2)
    clip_b = clip_b + rng.normal(0.0, 0.004, clip_b.shape)
    examples = np.concatenate([clip_a, clip_b])
    clips = Clips(("a", "b"), (30, 25))
    table = input_steps(examples, clips.starts, 2.0, block=7)
    walks = np.stack([np.concatenate([np.arange(s, s + 20) for s in rng.integers(0, 35, 4)]) for _ in range(3)])
    gathered = played_input(table, walks, clips.starts)
    again = []
    for src in walks:
        plays = np.zeros(src.size, bool)
        plays[:-1] = clips.continues(src)
        ground = table.grounds[np.searchsorted(clips.starts, src, side="right") - 1]
        again.append(measure_frames(lambda s, e, src=src: examples[src[s:e]], src.size, ground, 2.0, plays_on=plays,
                                    block=9))
    again = Steps.join(again)
    assert gathered.steps == again.steps and gathered.slide.size == again.slide.size > 20
    np.testing.assert_array_equal(np.sort(gathered.slide), np.sort(again.slide))
    np.testing.assert_array_equal(np.sort(gathered.offset), np.sort(again.offset))
    assert gathered.accel == again.accel


def test_each_clip_has_its_own_ground():
    low, high = block(frames=10), block(frames=10, lift=0.7)
    measured, grounds = measure_input(np.concatenate([low, high]), Clips(("a", "b"), (10, 10)).starts, 2.0)
    assert grounds == pytest.approx([0.0, 0.7]) and measured.slide.size == 18


def test_summary_and_ratios():
    out = summary(Steps(np.array([0.0, 0.01]), np.array([0.0, -0.002]), 4, 3.0))
    base = summary(Steps(np.array([0.0, 0.006]), np.array([0.001, 0.0]), 4, 2.0))
    r = ratios(out, base)
    assert r["largest_accel"] == 1.5 and r["sliding_share"] == 1.0
    assert r["slide_median"] == pytest.approx(5.0 / 3.0)
    assert summary(Steps(np.zeros(0), np.zeros(0), 3, float("nan")))["contact_steps"] == 0
    assert ratios({"slide_median": 1.0}, {"slide_median": 0.0})["slide_median"] is None
    # an input still up to rounding (the planted walker's p95: 6e-17 of its height) gives no ratio
    assert ratios({"slide_p95": 0.17}, {"slide_p95": 5.6e-17})["slide_p95"] is None


def test_the_feet_report_rounds_its_figures_and_says_n_a_where_a_figure_is_missing():
    from skinsynth.pipeline.mesh.contact_measures import feet_report

    side = {"steps": 10, "contact_steps": 0, "largest_accel": 0.123456789}
    figures = {"height": 2.0, "ground": [0.0], "input": dict(side), "seconds": 1.23456,
               "output": {**side, "slide_median": 0.0123456789, "float_p95": float("nan")},
               "ratios": {"slide_median": None, "largest_accel": 1.0}}
    contact, line = feet_report(figures, 3)
    assert contact["animations"] == 3 and contact["definitions"] == "docs/contact.md"
    assert contact["seconds"] == 1.235 and contact["output"]["slide_median"] == 0.0123457
    assert contact["output"]["float_p95"] is None and contact["input"]["largest_accel"] == 0.123457
    assert line.startswith("feet (first 3 animations against the input")
    assert "slide median 1.23% (input n/a)" in line and "worst acceleration 1.00× the input's" in line
    assert "float p95 n/a (n/a)" in line and "\n" not in line
