"""Figures for people: per-frame error curves of several methods, as a PNG.

Drawn with matplotlib's object API on an Agg canvas (no pyplot, no global backend switch, safe
in worker processes without a display) and written atomically.
"""

import os

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .atomic import atomic_output


def write_error_plot(path, frames, errors, title, ylabel):
    """Write a PNG of per-frame errors: one line per method, its mean error in the legend.

    frames (T,): test frame indices (the x axis); errors: {method name: (T,) errors}; title and
    ylabel are shown as given. Raises ValueError for a path not ending in ``.png``, no methods,
    or error arrays whose length differs from ``frames``.
    """
    path = os.fspath(path)
    if not path.lower().endswith(".png"):
        raise ValueError(f"{path}: error plots are written as PNG; the path must end in .png")
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

    figure = Figure(figsize=(9.0, 5.0), dpi=120, layout="constrained")
    FigureCanvasAgg(figure)
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
    with atomic_output(path) as tmp:
        figure.savefig(tmp, format="png")
