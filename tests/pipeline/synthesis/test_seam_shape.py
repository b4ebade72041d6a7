"""Transitions whose splice tears the body (issue 62, :mod:`skinsynth.pipeline.synthesis.seam_shape`):
which are refused, by hand."""

import numpy as np

from skinsynth.pipeline.synthesis.seam_shape import refused_ways


def test_a_tearing_transition_is_refused_unless_it_is_the_least_tearing_only_way_between_two_clips():
    most = 10
    worst = np.array([3, 40, 25, 30, 12, 50, 0, 11])
    clip_from = np.array([0, 0, 0, 0, 1, 1, 1, 1])
    clip_to = np.array([0, 0, 1, 1, 0, 0, 0, 1])
    refused = refused_ways(worst, most, clip_from, clip_to)
    # within clip 0: the one past most is refused; 0 → 1: both ways tear, the lesser (25) stays;
    # 1 → 0: one way (0) does not tear, so both tearing ways go; within clip 1: refused past most
    np.testing.assert_array_equal(refused, [False, True, False, True, True, True, False, True])
    assert not refused_ways(np.array([5, 20]), most, np.array([0, 1]), np.array([1, 0])).any()  # each the only way
    np.testing.assert_array_equal(refused_ways(np.array([20, 20]), most, np.array([0, 0]), np.array([1, 1])),
                                  [False, True])  # the first of equals
