"""Figures for people, as PNGs: per-frame error curves, transition-cost matrices, bone graphs.

Drawn with matplotlib's object API on an Agg canvas (no pyplot, no global backend switch, safe
in worker processes without a display) and written atomically.
"""

import os

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .atomic import atomic_output


def write_error_plot(path, frames, errors, title, ylabel):
    """Write a PNG of per-frame errors: one line per method, its mean error in the legend.

    frames (T,): test frame indices (the x axis); errors: {method name: (T,) errors}; title and
    ylabel are shown as given. Raises ValueError for a path not ending in ``.png``, no methods,
    or error arrays whose length differs from ``frames``.
    """
    frames = np.asarray(frames)
    if frames.ndim != 1 or frames.size == 0:
        raise ValueError("frames must be a non-empty 1-D array")
    if not errors:
        raise ValueError("no methods to plot")
    series = {}
    for name, values in errors.items():
        values = np.asarray(values, dtype=np.float64)
        if values.shape != frames.shape:
            raise ValueError(f"errors[{name!r}] has shape {values.shape}, frames has {frames.shape}")
        series[name] = values

    figure = _new_figure(path, (9.0, 5.0))
    axes = figure.add_subplot()
    marker = "o" if frames.size <= 60 else None
    for name, values in series.items():
        mean = np.nanmean(values) if np.any(np.isfinite(values)) else np.nan
        axes.plot(frames, values, marker=marker, markersize=3.5, linewidth=1.4, label=f"{name} (mean {mean:.4g})")
    axes.set_title(title)
    axes.set_xlabel("test frame")
    axes.set_ylabel(ylabel)
    axes.set_ylim(bottom=0.0)
    axes.grid(True, alpha=0.3)
    axes.legend(loc="best", frameon=True)
    _save(figure, path)


def _new_figure(path, size):
    path = os.fspath(path)
    if not path.lower().endswith(".png"):
        raise ValueError(f"{path}: plots are written as PNG; the path must end in .png")
    figure = Figure(figsize=size, dpi=120, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def _save(figure, path):
    with atomic_output(path) as tmp:
        figure.savefig(tmp, format="png")


def write_cost_matrix_plot(path, costs, pairs, threshold, title):
    """The transition-cost matrix D (F, F) as an image, candidate transitions pairs (M, 2) marked.

    Colour is log10(D / threshold) so the threshold sits at 0 whatever the clip's scale; (i, j)
    is row i (the frame left), column j (the frame entered)."""
    figure = _new_figure(path, (7.0, 6.0))
    axes = figure.add_subplot()
    tiny = max(float(threshold) * 1e-6, np.finfo(float).tiny)
    shown = np.log10(np.maximum(costs, tiny) / max(float(threshold), tiny))
    image = axes.imshow(shown, cmap="viridis", origin="upper", interpolation="nearest", vmin=-3, vmax=3)
    figure.colorbar(image, ax=axes, label="log10(D / threshold)")
    if len(pairs):
        axes.scatter(pairs[:, 1], pairs[:, 0], s=18, facecolors="none", edgecolors="red", linewidths=1.2,
                     label=f"{len(pairs)} candidate transitions")
        axes.legend(loc="upper right", fontsize=8)
    axes.set_xlabel("frame j (entered)")
    axes.set_ylabel("frame i (left)")
    axes.set_title(title)
    _save(figure, path)


def write_bone_graph_plot(path, positions, weights, edges, components, cut_nodes, title):
    """The bone graph: bones at positions (B, 2), kept edges (E, 2) drawn with width ∝ weight,
    nodes coloured by component (a bone shared by components takes the first), cut nodes ringed."""
    figure = _new_figure(path, (8.0, 6.0))
    axes = figure.add_subplot()
    top = max(float(weights.max()), np.finfo(float).tiny)
    for i, j in edges:
        axes.plot(positions[[i, j], 0], positions[[i, j], 1], color="0.55", linewidth=0.5 + 3.0 * weights[i, j] / top,
                  zorder=1)
    palette = colormaps["tab10"]
    owner = np.full(len(positions), -1)
    for number, members in enumerate(components):
        members = np.asarray(members)
        owner[members[owner[members] < 0]] = number
    for number in range(len(components)):
        chosen = owner == number
        axes.scatter(positions[chosen, 0], positions[chosen, 1], s=60, color=palette(number % 10), zorder=2,
                     label=f"component {number} ({len(components[number])} bones)")
    if len(cut_nodes):
        cut = np.asarray(cut_nodes)
        axes.scatter(positions[cut, 0], positions[cut, 1], s=180, facecolors="none", edgecolors="red", linewidths=1.8,
                     zorder=3, label="cut node")
    for b, (x, y) in enumerate(positions):
        axes.annotate(str(b), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    axes.set_aspect("equal", adjustable="datalim")
    axes.set_title(title)
    axes.legend(loc="best", fontsize=8)
    _save(figure, path)
