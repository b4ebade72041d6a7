"""pipeline.puppet.marker_filter: the zero-phase Butterworth's response against its closed form
and on sinusoids, its ends on moving markers, runs filtered on their own (a run too short for the
filter kept raw), the noise it keeps and removes against the response's integral and against
known white noise, a take too slow for the cut-off kept raw, and the cut-off a take chooses
(``--filter auto``) against the best one on motion of known bandwidth and noise."""

import numpy as np
import pytest

from skinsynth.pipeline.puppet.marker_filter import (BODY_CUTOFF, PASSES_CORRECTION, can_filter, choose_cutoff, lowpass,
                                                     lowpass_response, lowpass_runs, noise_gains, removed_noise,
                                                     shortest_run)
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
    for cutoff in (BODY_CUTOFF, "auto"):  # too slow for 10 Hz; too slow to tell noise from motion
        slow = drive_from_markers(shapes, rate=15.0, fps=15.0, reference=rest, training=shapes, take_up="Y",
                                  puppet_up="Y", cutoff=cutoff)
        assert slow.cutoff is None and np.array_equal(slow.controls, raw.controls)
    # 20 samples at 60 Hz: shorter than the filter's reach (24), so nothing is filtered, and it says so
    short = drive_from_markers(shapes, rate=60.0, fps=60.0, reference=rest, training=shapes, take_up="Y",
                               puppet_up="Y", cutoff=BODY_CUTOFF)
    assert short.cutoff is None and np.array_equal(short.controls, raw.controls)
    whole = rest + 0.1 * rng.normal(size=(60, 6, 3))
    longer = whole.copy()
    longer[20:50, 2] = np.nan  # marker 2 seen for 20 samples, then 10: both runs kept raw
    filtered = drive_from_markers(longer, rate=60.0, fps=60.0, reference=rest, training=whole, take_up="Y",
                                  puppet_up="Y", max_gap=0, cutoff=BODY_CUTOFF)
    unfiltered = drive_from_markers(longer, rate=60.0, fps=60.0, reference=rest, training=whole, take_up="Y",
                                    puppet_up="Y", max_gap=0, cutoff=None)
    assert filtered.cutoff == BODY_CUTOFF and filtered.kept_raw == 30
    assert not np.allclose(filtered.controls, unfiltered.controls)


def _moving(samples, rate, seed):
    """A marker's smooth motion (samples, 3): a few sinusoids of 0.3–3 Hz, 0.05–0.1 m, random phase."""
    rng = np.random.default_rng(seed)
    t = np.arange(samples)[:, None] / rate
    frequencies, amplitudes = rng.uniform(0.3, 3.0, (3, 3)), rng.uniform(0.05, 0.1, (3, 3))
    phases = rng.uniform(0, 6, (3, 3))
    return sum(amplitudes[k] * np.sin(2 * np.pi * frequencies[k] * t + phases[k]) for k in range(3))


def test_a_moving_end_keeps_no_more_than_its_noise():
    """The odd reflection carries a line on past the end (a line comes through within 2 % of one
    sample's step), so a marker in mid-motion at a run's end is off by about its noise;
    Gustafsson's ends (used before) bent it by centimetres."""
    rate, noise = 100.0, 0.001
    rng = np.random.default_rng(5)
    ends = []
    for seed in range(40):
        motion = _moving(300, rate, seed)
        filtered = lowpass(motion + noise * rng.normal(size=motion.shape), rate, BODY_CUTOFF)
        ends.append(filtered[[0, -1]] - motion[[0, -1]])
    assert np.sqrt(np.mean(np.square(ends))) < 1.5 * noise  # raw: 1 × noise
    line = np.outer(np.arange(50.0), [0.01, -0.02, 0.005]) + 3.0
    assert np.abs(lowpass(line, rate, BODY_CUTOFF) - line).max() < 0.02 * 0.02


def test_a_run_too_short_for_the_filter_is_kept_raw():
    """A marker seen for 3 samples between two gaps stays where it was seen (Gustafsson's ends put
    such a run near the origin: metres off on a real take)."""
    rate = 100.0
    assert shortest_run(rate, BODY_CUTOFF) == 40
    points = np.full((200, 1, 3), np.nan)
    points[:, 0] = _moving(200, rate, 1) + np.array([2.0, 1.0, -3.0])
    holed = points.copy()
    holed[60:100] = np.nan
    holed[103:150] = np.nan  # an island of 3 samples, 100–102
    out = lowpass_runs(holed, rate, BODY_CUTOFF)
    np.testing.assert_array_equal(out[100:103], holed[100:103])
    assert np.abs(out[:60] - points[:60]).max() < 0.01 and np.abs(out[150:] - points[150:]).max() < 0.01
    short = 0.01 * np.random.default_rng(2).normal(size=(39, 3))
    np.testing.assert_array_equal(lowpass(short, rate, BODY_CUTOFF), short)


@pytest.mark.parametrize("rate", [50.0, 100.0, 240.0])
def test_the_noise_kept_inside_a_run_is_the_responses_integral(rate):
    """White noise of variance 1 comes out of a linear filter with variance ∫|H(f)|² df / (rate / 2)
    over 0..rate/2; H real (zero phase), so what is removed has ∫(1 − H)²."""
    frequencies = np.linspace(0.0, rate / 2, 20001)
    response = lowpass_response(rate, BODY_CUTOFF, frequencies)
    kept, removed = noise_gains(rate, BODY_CUTOFF, 500, 1001)
    assert kept == pytest.approx(np.trapezoid(response ** 2, frequencies) / (rate / 2), rel=2e-3)
    assert removed == pytest.approx(np.trapezoid((1 - response) ** 2, frequencies) / (rate / 2), rel=2e-3)
    assert noise_gains(rate, BODY_CUTOFF, 0, 1001)[0] == pytest.approx(1.0, abs=0.01)  # the end: all its noise
    assert noise_gains(rate, BODY_CUTOFF, 5, 10) == (1.0, 0.0)  # too short to filter


def test_the_noise_removed_measures_the_takes_noise():
    rate, sigma = 100.0, 0.002
    rng = np.random.default_rng(6)
    motion = np.stack([_moving(3000, rate, seed) for seed in range(4)], axis=1)  # (T, 4, 3)
    raw = motion + sigma * np.array([1.0, 1.0, 2.0, 0.5])[None, :, None] * rng.normal(size=motion.shape)
    raw[500:700, 1] = np.nan
    interpolated = np.zeros(raw.shape[:2], dtype=bool)
    variances = removed_noise(raw, lowpass_runs(raw, rate, BODY_CUTOFF), rate, BODY_CUTOFF, exclude=interpolated)
    np.testing.assert_allclose(np.sqrt(variances), sigma * np.array([1.0, 1.0, 2.0, 0.5]), rtol=0.05)


def test_a_take_is_filtered_where_it_can_be_and_says_what_was_kept_raw():
    """filter_take: long runs filtered and their noise read, a short run kept raw and counted; a take
    too slow for the cut-off or with no run long enough kept raw with no cut-off reported."""
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.puppet.marker_filter import filter_take

    rate, sigma = 100.0, 0.002
    motion = np.stack([_moving(600, rate, seed) for seed in range(2)], axis=1)  # (T, 2, 3)
    raw = motion + sigma * np.random.default_rng(4).normal(size=motion.shape)
    raw[300:310, 1] = np.nan
    raw[320:600, 1] = np.nan  # marker 1: a run of 300, then one of 10 (too short for 40 samples' reach)
    took = filter_take(raw, rate, BODY_CUTOFF)
    assert took.cutoff == BODY_CUTOFF and took.kept_raw == 10
    np.testing.assert_array_equal(took.points[310:320, 1], raw[310:320, 1])
    assert np.sqrt(np.mean((took.points[100:200] - motion[100:200]) ** 2)) < 0.7 * sigma  # raw: 1, filtered 0.46
    np.testing.assert_allclose(np.sqrt(took.variances), sigma, rtol=0.15)
    for slow in (filter_take(raw, 15.0, BODY_CUTOFF), filter_take(raw[:30], rate, BODY_CUTOFF),
                 filter_take(raw, rate, None)):
        assert slow.cutoff is None and slow.kept_raw == 0 and slow.variances is None
        assert np.array_equal(slow.points, raw[:len(slow.points)], equal_nan=True)
    with pytest.raises(OptionError, match="positive cut-off"):
        filter_take(raw, rate, -2.0)


def test_the_noise_left_in_a_weighted_sum_of_filtered_samples_is_what_white_noise_shows():
    """combined_noise_gain: one sample of weight 1 is noise_gains' share; a mean over 50 samples
    and a difference of two halves' means against the variance measured over 4000 noise draws."""
    from skinsynth.pipeline.puppet.marker_filter import combined_noise_gain

    rate, length, first = 100.0, 300, 120
    assert combined_noise_gain(rate, BODY_CUTOFF, 150, [1.0], length) == pytest.approx(
        noise_gains(rate, BODY_CUTOFF, 150, length)[0], rel=1e-9)
    sums = np.stack([np.full(50, 1 / 50), np.r_[np.full(25, 1 / 25), np.full(25, -1 / 25)]])
    predicted = combined_noise_gain(rate, BODY_CUTOFF, first, sums, length)
    draws = lowpass(np.random.default_rng(8).normal(size=(length, 4000)), rate, BODY_CUTOFF)
    measured = np.var(sums @ draws[first:first + 50], axis=1)
    np.testing.assert_allclose(predicted, measured, rtol=0.1)  # 4000 draws: the variance to about 2 %
    np.testing.assert_allclose(combined_noise_gain(rate, None, first, sums, length), [1 / 50, 2 / 25])


def _band_limited(band, noise, seed, samples=1000, rate=100.0):
    """(noisy, motion) (samples, 2, 3) at ``rate``: two markers moving by 8 sinusoids per coordinate
    of 0.2–``band`` Hz (0.05 m / (1 + f)), plus white noise of ``noise`` metres per coordinate."""
    rng = np.random.default_rng(seed)
    time = np.arange(samples) / rate
    frequencies = rng.uniform(0.2, band, size=(8, 6))
    phases = rng.uniform(0.0, 2 * np.pi, size=(8, 6))
    motion = np.sum(0.05 / (1 + frequencies) * np.sin(2 * np.pi * frequencies * time[:, None, None] + phases),
                    axis=1).reshape(samples, 2, 3)
    return motion + noise * rng.normal(size=motion.shape), motion


@pytest.mark.parametrize("band, noise", [(2.0, 0.001), (5.0, 0.001), (8.0, 0.001), (5.0, 0.003), (10.0, 0.0005)])
def test_the_chosen_cut_off_passes_the_motion_and_stops_the_noise(band, noise):
    """Issue 66: ``--filter auto`` on trajectories of known bandwidth and noise. Against the error
    of every cut-off of the grid (brute force, the motion known): the chosen one is above the
    motion's band (it passes the motion), its error within 10 % of the best one's (measured: the
    best or its neighbour), and under 0.7 of the raw noise (it stops the noise)."""
    noisy, motion = _band_limited(band, noise, seed=int(band * 10 + noise * 1e4))
    inside = slice(100, -100)  # the ends: the filter's reflection, alike for every cut-off

    def error(cutoff):
        return float(np.sqrt(np.mean((lowpass_runs(noisy, 100.0, cutoff) - motion)[inside] ** 2)))

    grid = np.arange(2.0, 40.5, 0.5)
    best = min(error(c) for c in grid)
    chosen = choose_cutoff(noisy, 100.0)
    assert chosen > band
    assert error(chosen) <= 1.1 * best
    assert error(chosen) < 0.7 * noise


def test_a_clean_take_is_left_all_but_raw_and_a_slow_one_raw():
    """No noise: the cut-off chosen is far above the motion (5 Hz: over 20 Hz), and the take
    comes through within 1e-5 m (0.05 m of motion); a take sampled below about 42 Hz cannot tell noise from a body's
    motion and is kept raw (None)."""
    clean, motion = _band_limited(5.0, 0.0, seed=9)
    chosen = choose_cutoff(clean, 100.0)
    assert chosen > 20.0
    assert np.abs(lowpass_runs(clean, 100.0, chosen) - motion)[100:-100].max() < 1e-5
    assert choose_cutoff(clean[::3], 100.0 / 3) is None
    assert choose_cutoff(clean[::2], 50.0) is not None
