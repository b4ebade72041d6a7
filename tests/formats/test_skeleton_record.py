"""/skin/skeleton's sliding bones (formats.validation.check_skeleton, formats.skin_file): all three
datasets or none, never on a jointed bone or the root, low ≤ high; written only where a bone slides."""

import numpy as np
import pytest

from skinsynth.formats.skin_file import skeleton_group
from skinsynth.formats.validation import FormatError, check_skeleton


def _group(**change):
    group = skeleton_group(parents=[-1, 0, 1], jointed=[False, False, True], joints=np.zeros((3, 3)),
                           drift=[0.0, 0.05, 0.01], root=0, free_rmse=1.0, max_drift=0.02,
                           sliding=[False, True, False], slide_low=np.full((3, 3), -0.1), slide_high=np.full((3, 3), 0.1))
    group.update(change)
    return group


def test_a_sound_sliding_record_passes_and_none_is_written_without_sliding():
    check_skeleton("rig.h5", _group(), {"B": 3})
    plain = skeleton_group(parents=[-1, 0], jointed=[False, True], joints=np.zeros((2, 3)), drift=[0.0, 0.0], root=0,
                           free_rmse=1.0, max_drift=0.02, sliding=[False, False], slide_low=np.zeros((2, 3)),
                           slide_high=np.zeros((2, 3)))
    assert not {"sliding", "slide_low", "slide_high"} & set(plain)


@pytest.mark.parametrize("change, message", [
    ({"sliding": np.array([False, True, True])}, "bone 2, which is jointed"),
    ({"sliding": np.array([True, True, False])}, "bone 0, which is the root"),
    ({"slide_low": np.full((3, 3), 0.2)}, "slide_low exceeds slide_high"),
], ids=["jointed", "root", "bounds"])
def test_an_inconsistent_sliding_record_is_refused(change, message):
    with pytest.raises(FormatError, match=message):
        check_skeleton("rig.h5", _group(**change), {"B": 3})


def test_a_sliding_record_needs_all_three_datasets():
    group = _group()
    del group["slide_high"]
    with pytest.raises(FormatError, match="without slide_high"):
        check_skeleton("rig.h5", group, {"B": 3})
