"""Motion-capture takes made from a mesh's own control vertices, with a known truth (issue 37's
must-show): a take at ``factor`` × the capture's rate, in millimetres, Z up, under a known
similarity, with noise and gaps. Used by the marker tests and ``benchmarks/markers.py``."""

import numpy as np

#: (x, y, z) -> (z, x, y): a Y-up capture's up axis becomes the take's Z.
Y_TO_Z = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def rotation_about(axis, angle):
    """Rodrigues: the rotation (3, 3) by ``angle`` radians about ``axis`` (3,)."""
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


def denser(frames, factor, smooth=False):
    """frames (F, n, 3) at some rate -> (⌊factor (F − 1)⌋ + 1, n, 3) at factor × it, linear between
    frames; with a whole factor sample factor·f is frame f exactly (100 Hz from 24 fps: 25/6).
    ``smooth``: through the frames by a shape-preserving cubic (PCHIP: smooth as a performer's
    markers are, no overshoot where the take holds still and then moves) instead of a line, which
    turns sharply at every frame (24 times a second), what no marker does and a filter reads as
    noise."""
    times = np.arange(int(np.floor((len(frames) - 1) * factor + 1e-9)) + 1) / factor
    if smooth:
        from scipy.interpolate import PchipInterpolator

        return PchipInterpolator(np.arange(len(frames)), frames, axis=0)(times)
    low = np.minimum(np.floor(times).astype(int), len(frames) - 1)
    high = np.minimum(low + 1, len(frames) - 1)
    mix = (times - low)[:, None, None]
    return (1 - mix) * frames[low] + mix * frames[high]


def gap_mask(samples, markers, share, longest, seed, keep_first=True):
    """(samples, markers) bool: about ``share`` of the samples missing, in gaps of 1..longest
    frames at random markers and starts (seeded); the first sample kept when keep_first (the
    neutral frame must see every marker)."""
    rng = np.random.default_rng(seed)
    mask = np.zeros((samples, markers), dtype=bool)
    while mask.mean() < share:
        length = int(rng.integers(1, longest + 1))
        start = int(rng.integers(1 if keep_first else 0, max(samples - length, 2)))
        mask[start:start + length, int(rng.integers(markers))] = True
    return mask


def take_points(frames, factor, scale, rotation, shift_mm, noise=0.0, missing=0.0, longest=30, seed=0,
                keep_first=True, smooth=False):
    """A take (T, n, 3) in millimetres, Z up, of a Y-up capture's control positions frames
    (F, n, 3) in metres: ``1000 (scale · rotation @ Y_TO_Z @ x) + shift_mm`` at factor × the
    capture's rate, plus Gaussian noise of ``noise`` metres per coordinate, and ``missing`` of
    the samples NaN in gaps of 1..longest take frames (the first sample kept whole when
    ``keep_first``); ``smooth``: between frames as :func:`denser` says."""
    rng = np.random.default_rng(seed + 1)
    dense = denser(np.asarray(frames, dtype=float), factor, smooth)
    points = 1000.0 * scale * dense @ (rotation @ Y_TO_Z).T + shift_mm
    points += 1000.0 * noise * rng.normal(size=points.shape)
    if missing > 0:
        points[gap_mask(len(points), points.shape[1], missing, longest, seed, keep_first)] = np.nan
    return points


def take_map(scale, rotation, shift_mm):
    """The map the puppet should recover, from the take's metres to the capture's: (scale,
    rotation (3, 3), translation (3,)) of ``x ↦ scale · rotation @ x + translation``."""
    forward = scale * rotation @ Y_TO_Z
    inverse = np.linalg.inv(forward)
    return 1.0 / scale, inverse * scale, -inverse @ (np.asarray(shift_mm) / 1000.0)
