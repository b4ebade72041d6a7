"""pipeline.puppet.marker_filter: the zero-phase Butterworth's response against its closed form
and on sinusoids, runs filtered on their own, and a take too slow for the cut-off kept raw."""

import numpy as np

from skinsynth.pipeline.puppet.marker_filter import (BODY_CUTOFF, PASSES_CORRECTION, can_filter, lowpass,
                                                     lowpass_response, lowpass_runs)
from skinsynth.pipeline.puppet.markers import drive_from_markers


def test_the_response_is_half_power_at_the_cut_off_after_both_passes():
    rate, cutoff = 100.0, 10.0
    frequencies = np.array([0.5, cutoff, 40.0])
    response = lowpass_response(rate, cutoff, frequencies)
    # two passes of a 2nd-order Butterworth at cutoff / C: amplitude (1 + (f C / cutoff)^4)^-1 (the bilinear
    # transform's warp aside), so 1/√2 (−3 dB) at the cut-off by Winter's correction C
    assert abs(1.0 / (1.0 + PASSES_CORRECTION ** 4) - 2 ** -0.5) < 1e-12
    assert abs(response[1] - 2 ** -0.5) < 0.03
    assert response[0] > 0.9999 and response[2] < 1e-3


def test_sinusoids_pass_or_stop_with_no_lag():
    rate = 100.0
    t = np.arange(1000) / rate
    slow, fast = np.sin(2 * np.pi * 1.0 * t), np.sin(2 * np.pi * 35.0 * t)
    middle = slice(100, 900)
    kept = lowpass(slow + fast, rate, BODY_CUTOFF)
    assert np.abs(kept[middle] - slow[middle]).max() < 0.01  # the 1 Hz motion in place (zero phase), 35 Hz gone
    assert np.abs(kept - slow)[10:-10].max() < 0.01  # the ends too, but for a transient of 0.1 s


def test_each_run_of_seen_samples_is_filtered_on_its_own():
    rng = np.random.default_rng(2)
    points = np.cumsum(rng.normal(size=(200, 3, 3)), axis=0)
    holed = points.copy()
    holed[80:95, 1] = np.nan
    out = lowpass_runs(holed, 100.0, 8.0)
    assert np.isnan(out[80:95, 1]).all() and not np.isnan(out[:80, 1]).any() and not np.isnan(out[95:, 1]).any()
    np.testing.assert_allclose(out[:80, 1], lowpass(points[:80, 1], 100.0, 8.0), atol=1e-12)
    np.testing.assert_allclose(out[95:, 1], lowpass(points[95:, 1], 100.0, 8.0), atol=1e-12)
    np.testing.assert_allclose(out[:, 0], lowpass(points[:, 0], 100.0, 8.0), atol=1e-12)


def test_a_take_too_slow_for_the_cut_off_is_kept_raw():
    assert not can_filter(15.0, BODY_CUTOFF) and can_filter(30.0, BODY_CUTOFF)
    rng = np.random.default_rng(4)
    rest = rng.normal(size=(6, 3))
    shapes = rest + 0.1 * rng.normal(size=(20, 6, 3))
    raw = drive_from_markers(shapes, rate=15.0, fps=15.0, reference=rest, training=shapes, take_up="Y", puppet_up="Y",
                             cutoff=None)
    slow = drive_from_markers(shapes, rate=15.0, fps=15.0, reference=rest, training=shapes, take_up="Y",
                              puppet_up="Y")
    assert slow.cutoff is None and np.array_equal(slow.controls, raw.controls)
    filtered = drive_from_markers(shapes, rate=60.0, fps=60.0, reference=rest, training=shapes, take_up="Y",
                                  puppet_up="Y")
    assert filtered.cutoff == BODY_CUTOFF and not np.allclose(filtered.controls, raw.controls)
