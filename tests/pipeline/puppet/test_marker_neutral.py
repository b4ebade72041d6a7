"""pipeline.puppet.marker_neutral: the neutral residual's James–Stein shrinkage against its closed
form and its two limits (noise alone, real offsets), and the choice of a quiet neutral frame."""

import numpy as np
import pytest

from skinsynth.pipeline.puppet.marker_filter import BODY_CUTOFF, lowpass_runs, removed_noise
from skinsynth.pipeline.puppet.marker_neutral import (choose_neutral_frame, closest_to_rest, frame_gains, held_start,
                                                     shrink_neutral_residual)


def test_the_shrinkage_is_james_steins_on_the_standardised_residual():
    residual = np.array([[1.0, 2.0, 0.0], [0.0, -1.0, 3.0], [2.0, 2.0, 2.0], [1.0, 0.0, 1.0], [np.nan] * 3])
    variances = np.array([0.5, 0.5, 2.0, 1.0, 0.5])
    shrunk, kept = shrink_neutral_residual(residual, variances)
    z2 = 5 / 0.5 + 10 / 0.5 + 12 / 2.0 + 2 / 1.0  # four markers seen: p = 12 − 7 = 5
    assert kept == pytest.approx(1.0 - 3.0 / z2, abs=1e-15)
    np.testing.assert_allclose(shrunk[:4], kept * residual[:4], atol=1e-15)
    assert np.isnan(shrunk[4]).all()
    assert shrink_neutral_residual(residual[:3], variances[:3])[1] == 1.0  # 3 markers: p = 2, nothing to gain


def test_noise_goes_and_real_offsets_stay():
    """A residual of pure noise (after the similarity's 7 fitted coordinates) is shrunk nearly to
    nothing and its error falls; a performer's offsets, far above the noise, are kept to within it."""
    rng = np.random.default_rng(3)
    markers, sigma = 16, 0.001
    errors_raw, errors_shrunk, kept = [], [], []
    for _ in range(200):
        noise = sigma * rng.normal(size=(markers, 3))
        shrunk, share = shrink_neutral_residual(noise, np.full(markers, sigma ** 2))
        errors_raw.append(np.sum(noise ** 2))
        errors_shrunk.append(np.sum(shrunk ** 2))
        kept.append(share)
    # |z|² of pure noise is χ² with 48 degrees of freedom (median 47.3): the share kept 1 − 39 / 47.3 ≈ 0.18
    assert np.mean(errors_shrunk) < 0.2 * np.mean(errors_raw) and abs(np.median(kept) - (1 - 39 / 47.33)) < 0.1
    offsets = 0.02 * rng.normal(size=(markers, 3))  # 2 cm: markers placed off the character's vertices
    noisy = offsets + sigma * rng.normal(size=(markers, 3))
    shrunk, share = shrink_neutral_residual(noisy, np.full(markers, sigma ** 2))
    assert share > 0.99 and np.abs(shrunk - noisy).max() < sigma


def test_a_noisy_take_starting_at_rest_is_aligned_inside_its_first_run():
    """A performer holding the rest pose at the take's start: the first sample ties with the next
    ones, but the filter leaves it all its raw noise (an end) and the next but one a fifth: the
    quieter is taken; a clean take keeps the first."""
    rate = 100.0
    rng = np.random.default_rng(4)
    rest = rng.normal(size=(10, 3))
    still = np.concatenate([np.zeros(30), np.linspace(0.0, 1.0, 170) ** 2])  # at rest for 0.3 s, then away
    poses = rest + still[:, None, None] * rng.normal(size=(1, 10, 3))
    present = np.ones(10, dtype=bool)
    noisy = poses + 0.002 * rng.normal(size=poses.shape)
    filtered = lowpass_runs(noisy, rate, BODY_CUTOFF)
    variances = removed_noise(noisy, filtered, rate, BODY_CUTOFF)

    def gains(frame):
        return frame_gains(filtered, rate, BODY_CUTOFF, frame)

    assert gains(0) == pytest.approx(np.ones(10), abs=0.01) and gains(2).max() < 0.3
    chosen = closest_to_rest(filtered, rest, present, noise=3 * 0.002 ** 2, gains=gains, variances=variances,
                             within=5)
    assert 1 <= chosen <= 5 and gains(chosen).max() < 0.4
    assert closest_to_rest(filtered, rest, present, noise=3 * 0.002 ** 2) == 0  # without the filter's gains
    clean = lowpass_runs(poses, rate, BODY_CUTOFF)
    assert closest_to_rest(clean, rest, present, noise=1e-12, gains=lambda f: frame_gains(clean, rate, BODY_CUTOFF, f),
                           variances=removed_noise(poses, clean, rate, BODY_CUTOFF), within=5) == 0


def test_a_performer_moving_in_the_rest_pose_is_aligned_at_the_first_tie():
    """Walking in the rest pose, every early frame ties on shape, but aligning at a later one would
    move the whole take by the walk between them: the first is kept."""
    rate = 100.0
    rng = np.random.default_rng(7)
    rest = rng.normal(size=(10, 3))
    walk = np.outer(np.arange(200) / rate, [1.0, 0.0, 0.3])  # 1 m/s, the shape unchanged
    poses = rest[None] + walk[:, None]
    noisy = poses + 0.002 * rng.normal(size=poses.shape)
    filtered = lowpass_runs(noisy, rate, BODY_CUTOFF)
    variances = removed_noise(noisy, filtered, rate, BODY_CUTOFF)
    chosen = closest_to_rest(filtered, rest, np.ones(10, dtype=bool), noise=3 * 0.002 ** 2,
                             gains=lambda f: frame_gains(filtered, rate, BODY_CUTOFF, f), variances=variances, within=5)
    assert chosen == 0


def _held_then_moving(seconds_still, rate=100.0, seed=7, markers=16, sigma=0.002):
    """A body's markers (T, M, 3): still at rest for ``seconds_still``, then a smooth move away (a
    turn and a walk), 2 s in all; the clean poses, the noisy ones and the rest pose."""
    rng = np.random.default_rng(seed)
    rest = rng.normal(scale=0.3, size=(markers, 3))
    times = np.arange(int(2.0 * rate)) / rate
    moving = np.clip(times - seconds_still, 0.0, None)
    angle = 0.8 * moving ** 2
    turn = np.stack([np.stack([np.cos(angle), -np.sin(angle), 0 * angle], -1),
                     np.stack([np.sin(angle), np.cos(angle), 0 * angle], -1),
                     np.stack([0 * angle, 0 * angle, 1 + 0 * angle], -1)], axis=1)  # (T, 3, 3)
    clean = np.einsum("tab,mb->tma", turn, rest) + (0.5 * moving)[:, None, None] * np.array([1.0, 0.0, 0.0])
    return clean, clean + sigma * rng.normal(size=clean.shape), rest


def _neutral(noisy, rate=100.0, frame=2):
    from skinsynth.pipeline.puppet.marker_filter import filter_take
    from skinsynth.pipeline.puppet.marker_neutral import neutral_pose, still_window

    took = filter_take(noisy, rate, BODY_CUTOFF)
    present = np.ones(noisy.shape[1], dtype=bool)
    one_sample = 3.0 * took.variances * frame_gains(took.points, rate, BODY_CUTOFF, frame)  # (M,)
    window = still_window(took.points, frame, present, one_sample, rate)
    return window, neutral_pose(took.points, frame, present, took.variances, rate, BODY_CUTOFF)


def test_a_pose_held_is_read_over_the_frames_it_is_held():
    """A second at rest, then away: the still window is that second (a few samples of the slow
    start of the move at most), its mean the pose to a fraction of one frame's noise, with the noise
    it leaves as the filter's rows say; a take moving from its first frame is read at the frame."""
    errors_mean, errors_frame = [], []
    for seed in range(5):
        clean, noisy, rest = _held_then_moving(1.0, seed=seed)
        window, (pose, gains, used) = _neutral(noisy)
        assert window[0] <= 2 and 95 <= window[1] <= 110 and used == window  # frame 0 keeps its raw noise
        errors_mean.append(np.sqrt(np.mean((pose - rest) ** 2)))
        errors_frame.append(np.sqrt(np.mean((lowpass_runs(noisy, 100.0, BODY_CUTOFF)[2] - rest) ** 2)))
        assert gains.max() < 0.05  # a mean over a hundred samples: about 1 / 100 of one's variance
    assert np.mean(errors_mean) < 0.3 * np.mean(errors_frame)  # measured 0.2
    clean, noisy, rest = _held_then_moving(0.0, seed=1)
    window, (pose, gains, used) = _neutral(noisy)
    assert window[1] - window[0] < 25 and used == (2, 2)  # moving: a few frames look still, not a pose held
    np.testing.assert_array_equal(pose, lowpass_runs(noisy, 100.0, BODY_CUTOFF)[2])


def test_a_held_calibration_pose_aligns_the_take_better_than_one_frame(monkeypatch):
    """drive_from_markers on takes starting in a held rest pose: the map recovered from the held
    second's mean is nearer the truth than the one from the neutral frame alone (five draws)."""
    import skinsynth.pipeline.puppet.marker_neutral as marker_neutral
    from skinsynth.pipeline.puppet.markers import drive_from_markers

    errors, default = {}, marker_neutral.STILL_SHORTEST
    for shortest in (default, np.inf):
        monkeypatch.setattr(marker_neutral, "STILL_SHORTEST", shortest)
        errors[shortest] = []
        for seed in range(5):
            clean, noisy, rest = _held_then_moving(1.0, seed=seed)
            drive = drive_from_markers(noisy, 100.0, 100.0, rest, clean[::10], take_up="Y", puppet_up="Y")
            first, last = drive.neutral["frames"]
            assert (last - first >= 95) == (shortest == default)  # the held second, or the frame alone
            carried = drive.scale * clean @ drive.rotation.T + drive.translation  # truth: the identity
            errors[shortest].append(np.sqrt(np.mean((carried - clean) ** 2)))
    assert np.mean(errors[default]) < 0.5 * np.mean(errors[np.inf]), errors


def test_a_marker_lost_while_the_pose_is_held_is_read_over_the_frames_it_is_seen():
    """Two markers lost for 30 samples each inside the held second (neither beside the neutral
    frame): the window still spans the second, each marker is its mean over the samples it has
    (measured 0.96x the gapless means' error, 0.22x the frame's), and its noise is that mean's (the
    two runs filtered apart add up): more than with all its samples."""
    clean, noisy, rest = _held_then_moving(1.0, seed=3)
    holed = noisy.copy()
    holed[30:60, 4] = np.nan
    holed[50:80, 9] = np.nan
    (whole_window, (whole, whole_gains, _)), (window, (pose, gains, used)) = _neutral(noisy), _neutral(holed)
    assert used == window and window[0] <= 2 and window[1] >= 95
    assert np.sqrt(np.mean((pose - rest) ** 2)) < 1.5 * np.sqrt(np.mean((whole - rest) ** 2))
    assert gains[4] > 1.2 * whole_gains[4] and gains[9] > 1.2 * whole_gains[9]  # 70 samples, not 100: 1.4x
    assert gains.max() < 0.05


def _calibration_then_motion(rate=50.0, held=1.2, seed=0):
    """A take (T, 8, 3) in metres: a standing pose (not the rest pose) held for ``held`` seconds
    with a slow sway of 1.5 cm, then 4 s of motion swinging from it through the rest pose (at 0.36 s
    into the motion, and again later); and the rest pose (8, 3)."""
    rng = np.random.default_rng(seed)
    rest = rng.normal(size=(8, 3)) * 0.4 + [0.0, 1.0, 0.0]
    calibration = rest + 0.15 * rng.normal(size=(8, 3))
    time = np.arange(int((held + 4.0) * rate)) / rate
    sway = 0.015 * np.sin(2 * np.pi * 0.4 * time)[:, None, None] * np.array([1.0, 0.0, 0.0])
    after = np.maximum(time - held, 0.0)[:, None, None]
    return rest + np.cos(2 * np.pi * 0.7 * after) * (calibration - rest) + sway, rest


def test_a_take_beginning_in_a_held_pose_is_aligned_there():
    """Issue 66: real takes begin in the performer's calibration pose, and the shared serve was
    aligned mid-serve (frame 810, the pose nearest the puppet's rest pose over the whole take):
    a take that begins in a held pose (every marker within 3 % of the body's size, a standing
    sway, for a second or more) is aligned in it, though a later frame of the motion comes
    nearer the rest pose; one that begins in motion, or holds still too briefly, is aligned where
    it comes nearest the rest pose, as before."""
    points, rest = _calibration_then_motion()
    present = np.ones(8, bool)
    first, stop = held_start(points, present, 50.0)
    assert first == 0 and 60 <= stop <= 70  # 1.2 s held, then the swing leaves it
    everywhere = closest_to_rest(points, rest, present)
    assert everywhere > 80  # the motion passes nearer the rest pose
    chosen = choose_neutral_frame(points, rest, present, 0.0, 50.0, None, None)
    assert chosen < stop  # in it
    brief, _ = _calibration_then_motion(held=0.7)
    assert held_start(brief, present, 50.0) is None
    assert choose_neutral_frame(brief, rest, present, 0.0, 50.0, None, None) == closest_to_rest(brief, rest, present)
    assert held_start(points[80:], present, 50.0) is None  # in motion from its first frame
    late = points.copy()
    late[:10, 3] = np.nan  # a marker seen only from frame 10: the held pose counted from there
    assert held_start(late, present, 50.0)[0] == 10
