"""Marker trajectories low-pass filtered as motion-capture tools do, before anything reads them.

An optical take carries the system's noise at its own rate (100–240 Hz), far above anything a
body does; resampled to the puppet's rate by picking samples, that noise goes straight through
to the puppet (and aliases below the new Nyquist frequency), and the neutral frame's noise
offsets every frame of a ``delta`` retargeting. Vicon Nexus, Qualisys and the biomechanics
literature (Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed., §3.4) low-pass
every coordinate with a Butterworth filter run forward and backward: zero phase lag, so no event
moves in time.

The cut-off is the take's own (``--filter auto``, the default; :func:`choose_cutoff`): a fast
dancer's hands need more bandwidth than a slow form's pelvis, and a clean take needs none cut,
so one figure for every take either blurs the fast or passes the noise of the slow (10 Hz, the
default before, played the clean held-out takes of Zheng's dancer and of the cow at 1.10× and
1.05× the clean controls' error; docs/mocap.md).

Here: a second-order Butterworth run forward and backward (:func:`scipy.signal.filtfilt`), its
cut-off raised by Winter's correction so that after both passes the response is −3 dB at the
cut-off asked for (:func:`lowpass_response`). The ends are padded by an odd reflection (scipy's
default): a marker moving in a straight line comes through (within 2 % of a sample's step), and
its end sample keeps its raw noise but little more. Gustafsson's initial conditions
(``method="gust"``), used before, filter the end's noise more but bend a moving end: on
band-limited motion (0.1 m at 3 Hz, 1 mm of noise, 100 Hz) the first sample 9 mm off against the
reflection's 1 mm, and a run of 3 samples metres off (a marker seen for 3 frames between two gaps
moved to the origin). A run shorter than the filter's reach (:data:`REACH` cut-off periods,
:func:`shortest_run`) is kept raw: there its ends' transients outweigh the noise removed (measured
on that motion at 50–480 Hz: 4 periods 1.0–1.5× the raw error, 6 periods 0.8–1.0×, 12 periods
0.75–0.8×). The neutral frame's noise, which a ``delta`` retargeting adds to every frame, is
handled where it is used (:func:`.marker_neutral.shrink_neutral_residual`,
:func:`.marker_neutral.closest_to_rest`) from the noise the filter removed
(:func:`removed_noise`).
"""

import functools
from typing import NamedTuple

import numpy as np

#: A body's bandwidth, Hz, where a take gives none: the smoothing spline over a raw take's gaps
#: (``--filter none``, :func:`.marker_gaps.fill_short_gaps`). The fastest body motions (sport,
#: dance) have energy to about 10 Hz (Winter §3.4.4; walking is filtered at 6 Hz), and a puppet
#: playing at 24–30 fps shows nothing above 12–15 Hz. It was the default cut-off before
#: ``--filter auto``; measured on issue 45's held-out takes (``benchmarks/markers.py --only
#: held_out``, with Gustafsson's ends then): 6 Hz cut the crane's kicks (its worst clean frame
#: 1.65× the clean controls'), 10 Hz 1.21×; the noise take's error 1.12× at 10 Hz, 1.21×
#: unfiltered (samba). With the reflection's ends, 7 and 8 Hz gave the noise takes nothing over
#: 10 Hz (crane 1.106× both, five draws) and cost the crane's noise-and-gaps take (1.22×, 1.20×).
BODY_CUTOFF = 10.0
#: How far the filter's response to one sample reaches, in periods of the cut-off (``rate /
#: cutoff`` samples): 4 (a window that wide gives an endless take's noise gain to 1e-4 at 30–1000
#: Hz). Runs shorter are kept raw (:func:`shortest_run`); :func:`noise_gains` looks no further
#: (at most :data:`MAX_REACH` samples).
REACH = 4.0
MAX_REACH = 500
#: Order of each pass (two passes: a fourth-order, zero-phase response).
ORDER = 2
#: Winter's correction for two passes of a second-order Butterworth, (√2 − 1)^(1/4): the −3 dB
#: point of the pair lies at this share of each pass's cut-off.
PASSES_CORRECTION = (np.sqrt(2.0) - 1.0) ** 0.25


#: ``--filter auto``: the cut-off chosen from the take itself (:func:`choose_cutoff`), the default.
AUTO = "auto"
#: :func:`choose_cutoff` tries cut-offs from this (Hz) in steps of :data:`CUTOFF_STEP` to the highest
#: the take's rate allows: no body motion is filtered below 2 Hz (walking: 6 Hz, Winter §3.4.4).
LOWEST_CUTOFF = 2.0
CUTOFF_STEP = 0.5
#: The noise is read where only noise is left above the cut-off: over the cut-offs from this share
#: of the highest tried up (Winter's straight, noise-only section of the residual). A body's motion
#: has its energy below about 10 Hz (Winter §3.4.4), under 0.6 of the highest cut-off of any take
#: sampled at 50 Hz or more (at 100 Hz: 24–40 Hz).
NOISE_SECTION = 0.6


def residual_curve(points, rate, cutoffs):
    """Winter's residual R(fc) (C,) of points (T, M, 3) (NaN where missing) for each of ``cutoffs``
    (C,) Hz: the RMS, per coordinate, of each seen sample less its low-passed value
    (:func:`lowpass_runs`), over the samples of runs long enough to be filtered at fc (NaN where
    no run is)."""
    raw = np.asarray(points, dtype=np.float64)
    seen = ~np.isnan(raw).any(axis=2)
    residual = np.full(len(cutoffs), np.nan)
    for k, cutoff in enumerate(cutoffs):  # cut-offs, never samples
        used = seen & ~unfiltered_samples(seen, rate, cutoff)
        if used.any():
            squared = np.sum((raw - lowpass_runs(raw, rate, cutoff)) ** 2, axis=2)
            residual[k] = np.sqrt(np.mean(squared[used]) / 3.0)
    return residual


def choose_cutoff(points, rate):
    """The cut-off (Hz) that filters a take's markers points (T, M, 3) (NaN where missing), sampled
    at ``rate`` Hz, best: the one whose filtered samples lie nearest the motion, by Stein's
    unbiased estimate of that error (Mallows' C_p for a linear filter), from Winter's residual
    analysis (§3.4.4.3). The residual R(fc) (:func:`residual_curve`) is the motion the filter cuts
    plus the noise it removes; where fc is high enough that only noise lies above it, R²(fc) is the
    noise variance σ² times the share of white noise the filter removes (:func:`noise_gains`), which
    gives σ (the median over the top :data:`NOISE_SECTION` of the cut-offs; Winter draws a line
    there instead, which bends away from R near the Nyquist frequency and read the noise 1.5× too
    high on generated motion). The error of filtering at fc against the motion is then
    R²(fc) − σ² + 2σ² s(fc), s the filter's weight on the sample itself: the fc minimising it is
    taken. On generated motion of known bandwidth (2–10 Hz at 100 Hz, noise 0.2–3 mm) it took the
    best cut-off of the grid or its neighbour, where Winter's crossing (R = σ) took one 1.5–3 Hz
    lower, cutting motion (tests/pipeline/puppet/test_marker_filter.py); on a clean take it takes a
    high cut-off that leaves the take all but raw. None where the take is too short or too slow for
    :data:`LOWEST_CUTOFF`, or sampled too slowly to tell its noise from a body's motion (its noise
    section would start below :data:`BODY_CUTOFF`: under about 42 Hz; a real optical take runs at
    50–480 Hz): it is kept raw."""
    top = np.floor(0.5 * rate * PASSES_CORRECTION / CUTOFF_STEP) * CUTOFF_STEP
    while top >= LOWEST_CUTOFF and not can_filter(rate, top):
        top -= CUTOFF_STEP
    cutoffs = np.arange(LOWEST_CUTOFF, top + 0.5 * CUTOFF_STEP, CUTOFF_STEP)
    if NOISE_SECTION * top < BODY_CUTOFF:
        return None
    coarse = cutoffs[::2]  # every other cut-off first, then the two beside the best (the risk is smooth)
    residual = residual_curve(points, rate, coarse)
    known = np.isfinite(residual)
    gains = _interior_gains(rate, coarse)
    section = known & (coarse >= NOISE_SECTION * top) & (gains[:, 1] > 0.05)
    if not section.any():
        return None
    variance = float(np.median(residual[section] ** 2 / gains[section, 1]))

    def risk(residual, gains):
        itself = 0.5 * (1.0 + gains[:, 0] - gains[:, 1])  # the filter's weight on the sample: (1 + kept − removed) / 2
        return np.where(np.isfinite(residual), residual ** 2 - variance + 2.0 * variance * itself, np.inf)

    best = float(coarse[int(np.argmin(risk(residual, gains)))])
    beside = np.array([c for c in (best - CUTOFF_STEP, best + CUTOFF_STEP) if cutoffs[0] <= c <= cutoffs[-1]])
    tried = np.concatenate([[best], beside])
    residual = np.concatenate([[residual[int(np.argmin(np.abs(coarse - best)))]], residual_curve(points, rate, beside)])
    return float(tried[int(np.argmin(risk(residual, _interior_gains(rate, tried))))])


def _interior_gains(rate, cutoffs):
    """(C, 2): the white noise an interior sample keeps and has removed at each of ``cutoffs``
    (:func:`noise_gains`)."""
    return np.array([noise_gains(rate, float(c), shortest_run(rate, c), 2 * shortest_run(rate, c) + 1)
                     for c in cutoffs]).reshape(-1, 2)


class FilteredTake(NamedTuple):
    """What :func:`filter_take` made of a take: points (T, M, 3), NaN where missing; cutoff (Hz),
    None where the take was kept raw; kept_raw: seen samples left raw in runs too short for the
    filter; variances (M,): each marker's noise per coordinate (:func:`removed_noise`), None for a
    raw take."""

    points: np.ndarray
    cutoff: float
    kept_raw: int
    variances: np.ndarray


def filter_take(points, rate, cutoff, exclude=None):
    """A take's markers points (T, M, 3) (NaN where missing) low-passed at ``cutoff`` Hz (``--filter
    auto`` chooses it first, :func:`choose_cutoff`), None for none (:func:`lowpass_runs`), with what
    :func:`removed_noise` reads of their noise (exclude (T, M):
    samples that measured nothing, interpolated ones). Kept raw, reported with cutoff None, where
    the take is too slow for the filter (:func:`can_filter`) or no run of samples is long enough
    (:func:`unfiltered_samples`). -> :class:`FilteredTake`; OptionError for a cut-off ≤ 0."""
    from ..errors import OptionError

    raw = np.asarray(points, dtype=np.float64)
    if cutoff is None:
        return FilteredTake(raw, None, 0, None)
    if not (np.isfinite(cutoff) and cutoff > 0):
        raise OptionError(f"--filter must be a positive cut-off in Hz, auto or none (got {cutoff:g})")
    if not can_filter(rate, cutoff):
        return FilteredTake(raw, None, 0, None)
    seen = ~np.isnan(raw).any(axis=2)
    kept_raw = int(unfiltered_samples(seen, rate, cutoff).sum())
    if kept_raw == int(seen.sum()):  # no run long enough: the take is raw
        return FilteredTake(raw, None, 0, None)
    cutoff = float(cutoff)
    filtered = lowpass_runs(raw, rate, cutoff)
    return FilteredTake(filtered, cutoff, kept_raw, removed_noise(raw, filtered, rate, cutoff, exclude=exclude))


def cutoff_option(text):
    """``play --filter``'s value: a cut-off in Hz (float), :data:`AUTO` for "auto", or None for
    "none"; OptionError else."""
    from ..errors import OptionError

    if str(text).strip().lower() == AUTO:
        return AUTO
    try:
        return None if str(text).strip().lower() == "none" else float(text)
    except ValueError:
        raise OptionError(f"--filter takes a cut-off in Hz, auto or none (got {text})") from None


@functools.lru_cache(maxsize=256)
def _coefficients(rate, cutoff):
    """The Butterworth's (b, a) at ``cutoff`` Hz of ``rate`` Hz (cached: :func:`choose_cutoff` asks each
    one of every marker's runs)."""
    from scipy.signal import butter

    return butter(ORDER, cutoff / PASSES_CORRECTION, btype="low", fs=rate)


def can_filter(rate, cutoff):
    """Whether a take sampled at ``rate`` Hz can be low-passed at ``cutoff`` Hz (each pass's
    corrected cut-off below the take's Nyquist frequency)."""
    return cutoff / PASSES_CORRECTION < 0.5 * rate


def shortest_run(rate, cutoff):
    """The fewest samples :func:`lowpass` filters at ``rate`` Hz and ``cutoff`` Hz: the filter's
    reach, :data:`REACH` periods of the cut-off (40 samples at 10 Hz of 100 Hz)."""
    return int(np.ceil(REACH * rate / cutoff))


def lowpass(values, rate, cutoff):
    """values (T, ...) sampled at ``rate`` Hz, low-passed along time at ``cutoff`` Hz (−3 dB there
    after both passes, zero phase, ends padded by an odd reflection); a copy unchanged where
    :func:`can_filter` is false or there are fewer than :func:`shortest_run` samples."""
    from scipy.signal import filtfilt

    values = np.asarray(values, dtype=np.float64)
    if not can_filter(rate, cutoff) or len(values) < shortest_run(rate, cutoff):
        return values.copy()
    b, a = _coefficients(rate, cutoff)
    return filtfilt(b, a, values, axis=0, padtype="odd")


def lowpass_runs(points, rate, cutoff):
    """points (T, M, 3) with NaN where a marker is missing, each marker's runs of seen samples
    low-passed on their own (:func:`lowpass`; never across a gap); the NaN stay."""
    from .marker_gaps import runs

    points = np.array(points, dtype=np.float64)
    seen = ~np.isnan(points).any(axis=2)
    whole = seen.all(axis=0)  # the markers seen throughout: one run each, filtered together
    if whole.any():
        points[:, whole] = lowpass(points[:, whole], rate, cutoff)
    for marker in np.flatnonzero(~whole):  # markers, never vertices
        for start, end in zip(*runs(seen[:, marker])):
            points[start:end, marker] = lowpass(points[start:end, marker], rate, cutoff)
    return points


@functools.lru_cache(maxsize=4096)
def noise_gains(rate, cutoff, position, length):
    """What :func:`lowpass` does to white noise of variance 1 at sample ``position`` of a run of
    ``length`` samples: (kept, removed), the variance of the filtered sample and of the raw minus
    the filtered one. The filter is linear, so its row for that sample is the filtered
    identity's: an interior sample keeps 0.21 of the variance at 10 Hz of 100 Hz, a run's end all
    of it (the reflection), a run too short to filter all of it."""
    reach = min(shortest_run(rate, cutoff), MAX_REACH)
    start, end = max(0, int(position) - reach), min(int(length), int(position) + reach + 1)
    row = lowpass(np.eye(end - start), rate, cutoff)[position - start]
    kept = float(row @ row)
    return kept, 1.0 - 2.0 * float(row[position - start]) + kept


def combined_noise_gain(rate, cutoff, first, weights, length):
    """What :func:`lowpass` leaves of white noise of variance 1 in Σ_k weights_k · filtered[first + k],
    a weighted sum of consecutive samples of a run of ``length`` (cutoff None: a raw run): the
    filtered identity's rows there, weighted, squared and summed (for one sample and weight 1,
    :func:`noise_gains`' kept share). weights (K,) -> a float; (W, K), several sums -> (W,)."""
    weights = np.asarray(weights, dtype=np.float64)
    if cutoff is None:
        return np.sum(weights ** 2, axis=-1)
    reach = min(shortest_run(rate, cutoff), MAX_REACH)
    start, end = max(0, int(first) - reach), min(int(length), int(first) + weights.shape[-1] + reach)
    rows = lowpass(np.eye(end - start), rate, cutoff)[first - start:first - start + weights.shape[-1]]
    combined = weights @ rows
    return np.sum(combined ** 2, axis=-1)


def removed_noise(raw, filtered, rate, cutoff, exclude=None):
    """Each marker's measurement noise variance per coordinate (M,), from what :func:`lowpass_runs`
    removed: raw, filtered (T, M, 3) NaN where missing; exclude (T, M) bool: samples that carry no
    measurement (interpolated). The filter's own assumption — what lies above the cut-off is noise
    — estimated on the samples at least the filter's reach from their run's ends (every filtered
    one where a marker has fewer than 10), divided by the share of white noise the filter removes
    there (:func:`noise_gains`). 0 where a marker has no filtered sample to estimate it from."""
    from .marker_gaps import runs

    seen = ~np.isnan(raw).any(axis=2) & ~np.isnan(filtered).any(axis=2)
    if exclude is not None:
        seen &= ~exclude
    shortest = shortest_run(rate, cutoff)
    reach = min(shortest, MAX_REACH)
    _, removed = noise_gains(rate, cutoff, reach, 2 * reach + 1)
    squared = np.sum((raw - filtered) ** 2, axis=2) / 3.0  # (T, M) per coordinate
    variances = np.zeros(raw.shape[1])
    for marker in range(raw.shape[1]):  # markers, never vertices
        interior, filtered_run = np.zeros((2, len(raw)), dtype=bool)
        for start, end in zip(*runs(~np.isnan(filtered[:, marker]).any(axis=1))):  # the runs the filter took
            interior[start + reach:end - reach] = True
            filtered_run[start:end] = end - start >= shortest
        use = seen[:, marker] & interior
        if use.sum() < 10:
            use = seen[:, marker] & filtered_run
        if use.any():
            variances[marker] = float(np.mean(squared[use, marker])) / removed
    return variances


def unfiltered_samples(seen, rate, cutoff):
    """(T, M) bool: the seen samples (``seen`` (T, M)) that :func:`lowpass_runs` keeps raw, in runs
    shorter than :func:`shortest_run`."""
    from .marker_gaps import runs

    short = np.zeros_like(seen, dtype=bool)
    shortest = shortest_run(rate, cutoff)
    for marker in range(seen.shape[1]):  # markers, never vertices
        for start, end in zip(*runs(seen[:, marker])):
            short[start:end, marker] = end - start < shortest
    return short


def lowpass_response(rate, cutoff, frequencies):
    """|H(f)| of :func:`lowpass` (both passes) at ``frequencies`` (Hz)."""
    from scipy.signal import freqz

    _, response = freqz(*_coefficients(rate, cutoff), worN=np.asarray(frequencies, dtype=np.float64), fs=rate)
    return np.abs(response) ** 2
