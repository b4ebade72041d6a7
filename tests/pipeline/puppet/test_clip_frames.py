"""Training and held-out frames of several clips (issue 26): train-kcca's --train-frames within
each clip, --clips, and evaluate's whole-clip hold-out, against frames enumerated by hand."""

import numpy as np
import pytest

from skinsynth.pipeline.inputs.clips import Clips
from skinsynth.pipeline.errors import OptionError
from skinsynth.pipeline.puppet.evaluation import clip_hold_out_split
from skinsynth.pipeline.puppet.puppet import clip_training_frames, parse_frame_spec

#: Three clips: frames 0–9 (a), 10–16 (b), 17–29 (c).
CLIPS = Clips(("a", "b", "c"), (10, 7, 13))


def _by_hand(spec, names):
    """Global training frames of ``spec`` sampled within each named clip, written out frame by frame."""
    frames, first = [], 0
    for name, count in zip(CLIPS.names, CLIPS.frames):
        if name in names:
            for local in range(count):
                if (spec == "all" or (spec.startswith("every:") and local % int(spec[6:]) == 0)
                        or (spec.startswith("first:") and local < int(spec[6:]))):
                    frames.append(first + local)
        first += count
    return frames


@pytest.mark.parametrize("spec", ["every:4", "every:3", "first:8", "all"])
@pytest.mark.parametrize("names", [None, "a,b,c", "b", "c,a", ("a", "c")])
def test_sampling_runs_within_each_chosen_clip(spec, names):
    chosen = CLIPS.names if names is None else [n for n in CLIPS.names
                                                 if n in (names.split(",") if isinstance(names, str) else names)]
    train, held_out, used = clip_training_frames(spec, CLIPS, names)
    assert used == tuple(chosen)
    assert train.tolist() == _by_hand(spec, chosen)
    in_chosen = [f for f in range(CLIPS.total) if CLIPS.names[int(CLIPS.clip_of(f))] in chosen]
    assert held_out.tolist() == [f for f in in_chosen if f not in train.tolist()]
    assert train.dtype == held_out.dtype == np.int64


@pytest.mark.parametrize("spec", ["every:4", "first:5", "all", "0,2,5-7", "every:1"])
def test_one_clip_is_the_plain_frame_spec(spec):
    train, held_out, used = clip_training_frames(spec, Clips.single(24, "bar"), None)
    expected = parse_frame_spec(spec, 24)
    assert train.tobytes() == expected.astype(np.int64).tobytes()
    assert held_out.tolist() == np.setdiff1d(np.arange(24), expected).tolist() and used == ("bar",)


def test_a_frame_list_names_global_frames_inside_the_chosen_clips():
    train, held_out, _ = clip_training_frames("10,12-14", CLIPS, "b")
    assert train.tolist() == [10, 12, 13, 14] and held_out.tolist() == [11, 15, 16]
    with pytest.raises(OptionError, match=r"frame 3 \(a:3\) is in clip 'a', not one of --clips b"):
        clip_training_frames("3,10", CLIPS, "b")


def test_an_unknown_clip_names_the_option_and_the_clips():
    with pytest.raises(OptionError, match="--clips: no clip named 'gallop'; the clips are a, b, c"):
        clip_training_frames("every:4", CLIPS, "a,gallop")


def test_clip_hold_out_trains_on_the_other_clips_only():
    train, test, train_names, test_names = clip_hold_out_split(CLIPS, ("b",))
    assert test.tolist() == list(range(10, 17)) and train.tolist() == list(range(10)) + list(range(17, 30))
    assert train_names == ("a", "c") and test_names == ("b",)
    # repeatable and comma lists; the puppet's own clips bound the training side
    train, test, train_names, test_names = clip_hold_out_split(CLIPS, ("c", "a"), training_clips=("a", "b", "c"))
    assert train.tolist() == list(range(10, 17)) and test.tolist() == list(range(10)) + list(range(17, 30))
    train, test, train_names, _ = clip_hold_out_split(CLIPS, ["b"], training_clips=("b", "c"))
    assert train_names == ("c",) and train.tolist() == list(range(17, 30))
    assert not np.intersect1d(train, test).size


def test_clip_hold_out_refuses_unknown_names_and_nothing_left_to_train():
    with pytest.raises(OptionError, match="--hold-out-clip: no clip named 'x'; the clips are a, b, c"):
        clip_hold_out_split(CLIPS, ("x",))
    with pytest.raises(OptionError, match="leaves no clip to train on"):
        clip_hold_out_split(CLIPS, ("a,b,c",))
    with pytest.raises(OptionError, match="leaves no clip to train on"):
        clip_hold_out_split(CLIPS, ("b",), training_clips=("b",))
