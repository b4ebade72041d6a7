"""How far control poses go from the examples a model was trained on: each frame's RMS distance
over the control points to the nearest training example, in a unit of the character's size (the
largest side of its rest box), and the scale that says "inside what was trained". ``play --json``
and the ``view`` page report it; a puppet of a jointed skin blends towards its skeleton by it
(``pipeline.puppet.jointed_play``)."""

import numpy as np


def extrapolation_distances(controls, training, unit):
    """(distances (N,), nearest (N,)) of controls (N, n_c, 3) from training (n_p, n_c, 3), both
    in place: each frame's RMS distance over the control points to the nearest training example,
    divided by ``unit`` (``evaluate``'s: the largest side of the rest bounding box), and that
    example's row (the first of equally near ones); vectorised over frames in blocks of bounded
    memory (``play --json`` reports a whole take)."""
    block = max(1, (32 << 20) // (8 * max(np.size(training), 1)))
    distances, nearest = np.empty(len(controls)), np.empty(len(controls), dtype=np.int64)
    for start in range(0, len(controls), block):
        gaps = pose_distances(controls[start:start + block], training, unit)  # (block, n_p)
        nearest[start:start + block] = np.argmin(gaps, axis=1)
        distances[start:start + block] = gaps[np.arange(len(gaps)), nearest[start:start + block]]
    return distances, nearest


def pose_distances(controls, training, unit):
    """(N, n_p): every frame's RMS distance over the control points, controls (N, n_c, 3), to
    every training example (n_p, n_c, 3), divided by ``unit``."""
    flat = np.asarray(controls, dtype=np.float64).reshape(len(controls), -1)
    train = np.asarray(training, dtype=np.float64).reshape(len(training), -1)
    gaps = np.sum((train[None] - flat[:, None]) ** 2, axis=2)
    return np.sqrt(gaps / np.asarray(training).shape[1]) / unit


def extrapolation_scale(training, unit, same=1e-6):
    """The default colour scale of the indicator: the largest distance from a training example
    (n_p, n_c, 3) to its nearest other pose, in the unit of :func:`extrapolation`. Controls that
    close to an example are no farther from it than the examples are from each other: inside what
    was trained (the choice of threshold; ``view --extrapolation-scale`` overrides it). Examples
    closer than ``same`` (in that unit) are one pose (a periodic capture repeats its poses); with
    a single pose there is no neighbour: 0.05, 5 % of the largest side."""
    training = np.asarray(training, dtype=float)
    flat = training.reshape(len(training), -1)
    gaps = np.sqrt(np.sum((flat[:, None, :] - flat[None, :, :]) ** 2, axis=2) / training.shape[1]) / unit
    gaps[gaps <= same] = np.inf  # itself, and repeats of its pose
    nearest = gaps.min(axis=1)
    nearest = nearest[np.isfinite(nearest)]
    return float(nearest.max()) if len(nearest) else 0.05


def extrapolation_report(names, trajectories, training, unit):
    """How far each trajectory (named by ``names``) goes from what a puppet was trained on, per
    frame (``play``'s report of the ``view`` page's indicator): trajectories [(F, n_c, 3)] and
    training (n_p, n_c, 3) controls in place, distances as :func:`extrapolation_distances`'s, against
    :func:`extrapolation_scale` -> (summary entries, text lines)."""
    scale = extrapolation_scale(training, unit)
    entries, lines = [], []
    for name, trajectory in zip(names, trajectories):
        distances, _ = extrapolation_distances(trajectory, training, unit)
        worst = int(np.argmax(distances))
        entries.append({"controls": str(name), "per_frame": [round(float(d), 6) for d in distances],
                        "mean": float(distances.mean()), "worst": float(distances[worst]), "worst_frame": worst,
                        "scale": scale, "frames_beyond_scale": int(np.sum(distances > scale))})
        lines.append(f"extrapolation of {name}: mean {distances.mean():.3g}, worst {distances[worst]:.3g} at frame "
                     f"{worst}; {int(np.sum(distances > scale))} of {len(distances)} frames beyond {scale:.3g}, the "
                     "largest gap between training poses (distance to the nearest training pose, RMS over the "
                     "controls, the rest box's largest side = 1)")
    return entries, lines
