"""pipeline/inputs/clips.py against brute-force enumeration of the frames of a few clips."""

import numpy as np
import pytest

from skinsynth.pipeline.inputs.clips import Clips
from skinsynth.pipeline.errors import OptionError

CLIPS = Clips(("gallop", "collapse", "poses"), (5, 3, 4))


def brute_table(clips):
    """(clip, local frame) of every global frame, by walking the clips one frame at a time."""
    return [(c, f) for c, n in enumerate(clips.frames) for f in range(n)]


def test_frames_map_to_their_clip_and_back():
    table = brute_table(CLIPS)
    assert CLIPS.total == len(table) == 12
    assert CLIPS.clip_of(np.arange(12)).tolist() == [c for c, _ in table]
    for frame, (c, f) in enumerate(table):
        assert CLIPS.frame(f"{CLIPS.names[c]}:{f}") == frame
        assert CLIPS.frame(f"{CLIPS.names[c]}:{f - CLIPS.frames[c]}") == frame  # negative: from the end
        assert CLIPS.label(frame) == f"{CLIPS.names[c]}:{f}"
        assert CLIPS.first_frames()[frame] == (f == 0)
        assert CLIPS.last_frames()[frame] == (f == CLIPS.frames[c] - 1)
    assert CLIPS.frame("7") == 7 and Clips.single(9).label(4) == "4"


def test_playback_and_transitions_stay_inside_clips():
    table = brute_table(CLIPS)
    plays = [k + 1 < len(table) and table[k + 1][0] == table[k][0] for k in range(len(table))]
    assert CLIPS.plays_on().tolist() == plays
    # j = -(c+1) continues at clip c's first frame; j >= 0 continues at j + 1, in its clip
    assert CLIPS.targets([-1, -2, -3]).tolist() == [0, 5, 8]
    assert CLIPS.targets([0, 6]).tolist() == [1, 7]
    for target in range(12):
        j = int(CLIPS.transition_j(target))
        assert int(CLIPS.targets(j)) == target and CLIPS.valid_j(j)
    assert not CLIPS.valid_j(4) and not CLIPS.valid_j(-4) and CLIPS.valid_j(3)  # 4 ends the gallop


def test_seams_mark_every_jump_and_every_clip_entry():
    sources = np.array([[3, 4, 5, 6, 0, 1, 2, 8, 9]])  # gallop 3-4, into collapse 0-1 by playback's index, ...
    expected = [False, False, True, False, True, False, False, True, False]
    assert CLIPS.seams(sources)[0].tolist() == expected
    # the brute-force rule: a seam wherever the next source is not the same clip's next frame
    table = brute_table(CLIPS)
    row = sources[0]
    brute = [False] + [not (table[b][0] == table[a][0] and table[b][1] == table[a][1] + 1)
                       for a, b in zip(row[:-1], row[1:])]
    assert brute == expected


def test_select_and_bad_names():
    assert CLIPS.select("collapse,gallop").tolist() == [0, 1, 2, 3, 4, 5, 6, 7]
    assert CLIPS.select(None).tolist() == list(range(12))
    assert CLIPS.subset(["poses", "gallop"]) == Clips(("gallop", "poses"), (5, 4))
    with pytest.raises(OptionError, match="no clip named 'trot'.*gallop, collapse, poses"):
        CLIPS.frame("trot:3", "--start")
    with pytest.raises(OptionError, match="frames 0..2"):
        CLIPS.frame("collapse:3")
    with pytest.raises(OptionError, match="CLIP:FRAME"):
        CLIPS.frame("gallop:x")
    for names, frames in ((("a", "a"), (2, 2)), (("a:b",), (2,)), (("a",), (0,)), (("a", "b"), (2,))):
        with pytest.raises(ValueError):
            Clips(names, frames)
