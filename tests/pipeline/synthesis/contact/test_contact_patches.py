"""Ground contacts found on the input (issue 35, part 1): pipeline.synthesis.contact_patches on
generated blocks whose plants are known in closed form (hysteresis, shortest plant, clip ends)."""

import numpy as np
import pytest
import trimesh

from skinsynth.pipeline.inputs.clips import Clips
from skinsynth.pipeline.errors import OptionError
from skinsynth.pipeline.synthesis.contact.patches import find_contacts, runs

FPS = 10.0


def block():
    """A unit cube (height 1) standing on y = 0, each face subdivided (its sole faces the ground)."""
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    vertices, faces = trimesh.remesh.subdivide(box.vertices, box.faces)
    return vertices - [0.0, vertices[:, 1].min(), 0.0], np.asarray(faces, dtype=np.int64)


#: Heights of the block's sole, frame by frame (H = 1; defaults: enter within 0.02, leave beyond 0.03).
LIFT = {10: 0.025,  # still within the release band: stays planted (hysteresis)
        11: 0.2, 12: 0.3, 13: 0.2,
        14: 0.0, 15: 0.0,  # a touch of 2 frames (0.2 s): shorter than a 0.3 s plant
        16: 0.2, 17: 0.1,
        18: 0.025,  # within the release band but not the entry band: not planted yet
        19: 0.01}  # enters


def rest_lift_rest(frames=40, slide_from=30, slide_speed=4.0):
    """The block resting (0–10), lifting (11–18), resting again (19–29), then sliding sideways at
    slide_speed heights per second (30–39): (frames, V, 3)."""
    rest, faces = block()
    heights = np.array([LIFT.get(f, 0.0) for f in range(frames)])
    slide = np.maximum(np.arange(frames) - slide_from, 0) * slide_speed / FPS
    moves = np.zeros((frames, 1, 3))
    moves[:, 0, 1], moves[:, 0, 0] = heights, slide
    return rest[None] + moves, faces


def test_rest_lift_rest_gives_the_plants_of_the_hysteresis_and_the_shortest_plant():
    vertices, faces = rest_lift_rest()
    found = find_contacts(vertices, faces, FPS, up_axis=1, min_duration=0.3)
    assert found.count == 1  # the sole, one connected patch
    sole = np.flatnonzero(vertices[0, :, 1] == 0.0)
    # The sole's vertices (a corner whose faces mostly stand up does not face the ground).
    assert np.isin(found.patch(0), sole).all() and found.patch(0).size >= sole.size - 2
    assert found.plants() == [(0, 0, 10), (0, 19, 29)]
    assert found.height == pytest.approx(1.0) and found.ground == pytest.approx([0.0])
    # Without a shortest plant the two-frame touch is one.
    assert find_contacts(vertices, faces, FPS, up_axis=1, min_duration=0.0).plants() == \
        [(0, 0, 10), (0, 14, 15), (0, 19, 29)]
    # Without hysteresis (release 1): frame 10 (0.025 above the ground) is already off it.
    assert find_contacts(vertices, faces, FPS, up_axis=1, release=1.0, min_duration=0.3).plants() == \
        [(0, 0, 9), (0, 19, 29)]


def test_the_ground_is_the_clips_own_and_its_belt_is_no_motion():
    vertices, faces = rest_lift_rest(slide_from=40)  # no slide
    shifted = vertices + [0.0, -3.7, 0.0]  # a ground far from y = 0
    assert find_contacts(shifted, faces, FPS).plants() == find_contacts(vertices, faces, FPS).plants()
    belt = vertices + (np.arange(40) * 0.5)[:, None, None] * [0.0, 0.0, 1.0]  # a treadmill: the whole block drifts
    assert find_contacts(belt, faces, FPS).plants() == find_contacts(vertices, faces, FPS).plants()


def test_frames_across_a_clips_end_are_never_motion():
    rest, faces = block()
    vertices = np.repeat(rest[None], 20, axis=0)
    vertices[10:, :, 0] += 5.0  # clip b rests 5 heights away from where clip a ends
    clips = Clips(("a", "b"), (10, 10))
    found = find_contacts(vertices, faces, FPS, clips=clips)
    assert found.count == 1 and found.planted.all()
    assert found.plants(clips) == [(0, 0, 9), (0, 10, 19)]  # two plants: none crosses the clip's end
    one = find_contacts(vertices, faces, FPS)  # read as one clip, the jump is motion
    assert not one.planted[9:11].any() and one.planted[:9].all() and one.planted[11:].all()


def test_a_block_that_never_rests_has_no_contact():
    rest, faces = block()
    t = np.arange(48) / FPS
    drift = np.stack([2.0 * np.cos(t), 0.3 * np.sin(3 * t), 2.0 * np.sin(t)], axis=1)  # 2 heights/s around a circle
    found = find_contacts(rest[None] + drift[:, None], faces, FPS)
    assert found.count == 0 and found.planted.shape == (48, 0) and found.vertices.size == 0


def test_runs_split_at_clip_starts():
    clips = Clips(("a", "b"), (3, 3))
    assert runs(np.array([0, 1, 1, 1, 1, 0], bool), clips) == [(1, 2), (3, 4)]


@pytest.mark.parametrize("option", [dict(height=0.0), dict(speed=-1.0), dict(release=0.5), dict(min_duration=-0.1),
                                    dict(height=np.inf), dict(min_support=-0.1), dict(min_support=1.5)])
def test_options_out_of_range(option):
    vertices, faces = rest_lift_rest()
    with pytest.raises(OptionError):
        find_contacts(vertices, faces, FPS, **option)


def resting_for(frames_on_ground, frames=100):
    """The block held 0.5 heights up, lowered onto the ground for frames_on_ground frames in the
    middle of the frames (like a hem at the bottom of its swing, or a foot planted): (frames, V, 3)."""
    rest, faces = block()
    heights = np.full(frames, 0.5)
    first = (frames - frames_on_ground) // 2
    heights[first:first + frames_on_ground] = 0.0
    return rest[None] + heights[:, None, None] * [0.0, 1.0, 0.0], faces


def test_a_ground_touched_in_few_frames_bears_no_weight():
    # 8 % of the frames on the ground (a pause at the lowest, as the vellum sheet's hem): no contact at
    # the default share (0.12), though the block lies flat on its ground for 0.8 s
    vertices, faces = resting_for(8)
    assert find_contacts(vertices, faces, FPS).count == 0
    # ... found when the share asked is lower, as one plant of those 8 frames
    assert find_contacts(vertices, faces, FPS, min_support=0.04).plants() == [(0, 46, 53)]


def test_a_ground_touched_in_many_frames_is_kept():
    vertices, faces = resting_for(30)  # 30 %: well above the default share
    found = find_contacts(vertices, faces, FPS)
    assert found.plants() == [(0, 35, 64)] and found.options["min_support"] == 0.12
    assert find_contacts(vertices, faces, FPS, min_support=0.5).count == 0  # fewer frames than asked


def test_the_share_is_each_clips_own():
    brief, faces = resting_for(8)  # clip a: a pause at the lowest (8 %)
    long, _ = resting_for(30)  # clip b: resting 30 % of its frames
    clips = Clips(("a", "b"), (100, 100))
    found = find_contacts(np.concatenate([brief, long]), faces, FPS, clips=clips)
    assert found.plants(clips) == [(0, 135, 164)]  # clip b's plant only
