"""Marker trajectories low-pass filtered as motion-capture tools do, before anything reads them.

An optical take carries the system's noise at its own rate (100–240 Hz), far above anything a
body does; resampled to the puppet's rate by picking samples, that noise goes straight through
to the puppet (and aliases below the new Nyquist frequency), and the neutral frame's noise
offsets every frame of a ``delta`` retargeting. Vicon Nexus, Qualisys and the biomechanics
literature (Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed., §3.4) low-pass
every coordinate with a Butterworth filter run forward and backward: zero phase lag, so no event
moves in time.

Here: a second-order Butterworth run forward and backward (:func:`scipy.signal.filtfilt`), its
cut-off raised by Winter's correction so that after both passes the response is −3 dB at the
cut-off asked for (:func:`lowpass_response`). The ends use Gustafsson's initial conditions
(``method="gust"``), not a padding: an odd reflection (scipy's default) pins each end to its
raw, noisy sample, and a take's first frame is often its neutral one (measured on issue 45's
held-out samba take with noise of 0.1 % of the height: vertex error 1.21× the clean controls'
with the padding, 1.12× with Gustafsson's ends).
"""

import numpy as np

#: The default cut-off, Hz: the fastest body motions (sport, dance) have energy to about 10 Hz
#: (Winter §3.4.4; walking is filtered at 6 Hz), and a puppet playing at 24–30 fps shows nothing
#: above 12–15 Hz. Measured on issue 45's held-out takes (``benchmarks/markers.py --only
#: held_out``): 6 Hz cut the crane's kicks (its worst clean frame 1.65× the clean controls'),
#: 10 Hz 1.21×; the noise take's error 1.12× at 10 Hz, 1.21× unfiltered (samba).
BODY_CUTOFF = 10.0
#: Order of each pass (two passes: a fourth-order, zero-phase response).
ORDER = 2
#: Winter's correction for two passes of a second-order Butterworth, (√2 − 1)^(1/4): the −3 dB
#: point of the pair lies at this share of each pass's cut-off.
PASSES_CORRECTION = (np.sqrt(2.0) - 1.0) ** 0.25


def cutoff_option(text):
    """``play --filter``'s value: a cut-off in Hz (float), or None for "none"; OptionError else."""
    from ..errors import OptionError

    try:
        return None if str(text).strip().lower() == "none" else float(text)
    except ValueError:
        raise OptionError(f"--filter takes a cut-off in Hz or none (got {text})") from None


def _coefficients(rate, cutoff):
    from scipy.signal import butter

    return butter(ORDER, cutoff / PASSES_CORRECTION, btype="low", fs=rate)


def can_filter(rate, cutoff):
    """Whether a take sampled at ``rate`` Hz can be low-passed at ``cutoff`` Hz (each pass's
    corrected cut-off below the take's Nyquist frequency)."""
    return cutoff / PASSES_CORRECTION < 0.5 * rate


def lowpass(values, rate, cutoff):
    """values (T, ...) sampled at ``rate`` Hz, low-passed along time at ``cutoff`` Hz (−3 dB there
    after both passes, zero phase, Gustafsson's ends); a copy unchanged where :func:`can_filter`
    is false or there are fewer than 3 samples."""
    from scipy.signal import filtfilt

    values = np.asarray(values, dtype=np.float64)
    if len(values) < 3 or not can_filter(rate, cutoff):
        return values.copy()
    b, a = _coefficients(rate, cutoff)
    return filtfilt(b, a, values, axis=0, method="gust")


def lowpass_runs(points, rate, cutoff):
    """points (T, M, 3) with NaN where a marker is missing, each marker's runs of seen samples
    low-passed on their own (:func:`lowpass`; never across a gap); the NaN stay."""
    from .marker_gaps import runs

    points = np.array(points, dtype=np.float64)
    seen = ~np.isnan(points).any(axis=2)
    for marker in range(points.shape[1]):  # markers, never vertices
        for start, end in zip(*runs(seen[:, marker])):
            points[start:end, marker] = lowpass(points[start:end, marker], rate, cutoff)
    return points


def lowpass_response(rate, cutoff, frequencies):
    """|H(f)| of :func:`lowpass` (both passes) at ``frequencies`` (Hz)."""
    from scipy.signal import freqz

    _, response = freqz(*_coefficients(rate, cutoff), worN=np.asarray(frequencies, dtype=np.float64), fs=rate)
    return np.abs(response) ** 2
