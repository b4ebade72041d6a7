"""Figures for people, as PNGs: per-frame error curves, transition-cost matrices, bone graphs,
contact timelines.

Drawn with matplotlib's object API on an Agg canvas (no pyplot, no global backend switch, safe
in worker processes without a display) and written atomically.
"""

import os

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from .atomic import atomic_output


def series_rms(values):
    """The RMS over frames of per-frame errors (T,), NaNs left out (NaN if none is finite): for
    per-frame RMS errors over one vertex count, the overall RMS (issue 68: the legend said the mean
    of the per-frame RMS, 0.01224, where evaluate printed the overall 0.01455)."""
    values = np.asarray(values, dtype=np.float64)
    return float(np.sqrt(np.nanmean(values ** 2))) if np.any(np.isfinite(values)) else float("nan")


def write_error_plot(path, frames, errors, title, ylabel):
    """Write a PNG of per-frame errors: one line per method, its RMS over the frames in the legend
    (:func:`series_rms`: the figure evaluate prints).

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
        axes.plot(frames, values, marker=marker, markersize=3.5, linewidth=1.4,
                  label=f"{name} (RMS {series_rms(values):.4g})")
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


def write_cost_matrix_plot(path, costs, pairs, threshold, title, start=None):
    """The transition-cost matrix D (F, F) as an image, candidate transitions pairs (M, 2) marked.

    Colour is log10(D / threshold) so the threshold sits at 0 whatever the clip's scale; (i, j)
    is row i (the frame left), column j (the frame entered). ``start`` (F,): D(i, −1), the column
    of the virtual frame −1 before the clip's start (a pair (i, −1): after i, continue at frame
    0), drawn at j = −1 left of a white line; None draws D alone (pairs (i, −1) still marked)."""
    figure = _new_figure(path, (7.0, 6.0))
    axes = figure.add_subplot()
    tiny = max(float(threshold) * 1e-6, np.finfo(float).tiny)
    costs = np.asarray(costs, dtype=np.float64)
    frames = costs.shape[0]
    first = 0
    if start is not None:
        costs, first = np.concatenate([np.asarray(start, dtype=np.float64).reshape(frames, 1), costs], axis=1), -1
    shown = np.log10(np.maximum(costs, tiny) / max(float(threshold), tiny))
    image = axes.imshow(shown, cmap="viridis", origin="upper", interpolation="nearest", vmin=-3, vmax=3,
                        extent=(first - 0.5, frames - 0.5, frames - 0.5, -0.5))
    figure.colorbar(image, ax=axes, label="log10(D / threshold)")
    if start is not None:
        axes.axvline(-0.5, color="white", linewidth=0.8)
    if len(pairs):
        axes.scatter(pairs[:, 1], pairs[:, 0], s=18, facecolors="none", edgecolors="red", linewidths=1.2,
                     label=f"{len(pairs)} candidate transitions")
        axes.legend(loc="upper right", fontsize=8)
    axes.set_xlabel("frame j (entered)" if start is None else "frame j (entered; −1: before the start, continue at 0)")
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


def write_contact_timeline_plot(path, planted, sizes, title, clip_starts=None, clip_names=None):
    """The input's ground contacts on a timeline: one row per patch (its vertex count in the
    label), a dark cell at each frame where it is planted. planted (F, P) bool; sizes (P,);
    ``clip_starts`` (C + 1,) global first frames of the clips and the frame count, drawn as
    vertical lines with ``clip_names`` when there are several."""
    planted = np.asarray(planted, dtype=bool)
    frames, patches = planted.shape
    figure = _new_figure(path, (9.0, 1.6 + 0.28 * max(patches, 1)))
    axes = figure.add_subplot()
    axes.imshow(planted.T.astype(np.float64), cmap="Greys", vmin=0.0, vmax=1.0, aspect="auto",
                interpolation="nearest", extent=(-0.5, frames - 0.5, patches - 0.5, -0.5))
    axes.set_yticks(np.arange(patches))
    axes.set_yticklabels([f"patch {p} ({int(n)} v)" for p, n in enumerate(sizes)], fontsize=7)
    if clip_starts is not None and len(clip_starts) > 2:
        for c, start in enumerate(clip_starts[:-1]):
            if c:
                axes.axvline(start - 0.5, color="red", linewidth=1.0)
            if clip_names is not None:
                axes.annotate(str(clip_names[c]), (start, -0.5), textcoords="offset points", xytext=(2, 4),
                              fontsize=7, color="red", annotation_clip=False)
    axes.set_xlabel("input frame")
    axes.set_title(title, pad=14.0)  # room for the clip names above the first row
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    keys = [Patch(facecolor="black", edgecolor="grey", label="planted on the ground"),
            Patch(facecolor="white", edgecolor="grey", label="off the ground")]
    if clip_starts is not None and len(clip_starts) > 2:
        keys.append(Line2D([], [], color="red", linewidth=1.0, label="clip boundary"))
    axes.legend(handles=keys, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
    _save(figure, path)


def write_synthesis_plot(path, sources, accel_ratio, title, limit=1.5, seams=None, clip_starts=None):
    """One synthesized animation: where each component's frames come from, and how hard it moves.

    sources (C, M) int: the input-clip frame each of C bone components plays at each of M output
    frames; a seam of component c is an output frame k >= 1 with sources[c, k] != sources[c, k-1] + 1,
    or, given, where ``seams`` (C, M) bool says (the caller's rule: with several input clips a step
    from one clip's last frame onto the next one's first is a seam too; this module applies no
    rule of its own beyond the one-clip default). ``clip_starts`` (C + 1,) global first frames of
    the input's clips and its frame count, when it holds several: drawn as faint horizontal lines.
    accel_ratio (M,): per output frame the largest vertex acceleration over the input clip's largest,
    NaN where undefined (the first and last frame). Top panel: the source frame per output frame, one
    step line per component, seams as dots. Bottom panel: accel_ratio against 1 (the input's largest)
    and ``limit`` (frames above it in red), every seam of any component as a faint vertical line.
    Raises ValueError for a path not ending in ``.png``, sources not a non-empty 2-D array, or
    accel_ratio not of shape (M,), or seams not of the shape of sources.
    """
    sources = np.asarray(sources)
    if sources.ndim != 2 or sources.size == 0:
        raise ValueError(f"sources must be a non-empty (C, M) array, got shape {sources.shape}")
    if not np.issubdtype(sources.dtype, np.integer):
        raise ValueError(f"sources must hold integer frame indices, got dtype {sources.dtype}")
    accel_ratio = np.asarray(accel_ratio, dtype=np.float64)
    count, length = sources.shape
    if accel_ratio.shape != (length,):
        raise ValueError(f"accel_ratio has shape {accel_ratio.shape}, sources has {length} output frames")
    limit = float(limit)

    frames = np.arange(length)
    if seams is None:
        seams = np.zeros(sources.shape, dtype=bool)
        seams[:, 1:] = sources[:, 1:] != sources[:, :-1] + 1
    else:
        seams = np.asarray(seams, dtype=bool)
        if seams.shape != sources.shape:
            raise ValueError(f"seams has shape {seams.shape}, sources {sources.shape}")

    figure = _new_figure(path, (10.0, 6.0))
    top, bottom = figure.subplots(2, 1, sharex=True)
    for c in range(count):
        (line,) = top.step(frames, sources[c], where="post", linewidth=1.4, label=f"component {c}")
        top.scatter(frames[seams[c]], sources[c, seams[c]], s=18, color=line.get_color(), zorder=3)
    if clip_starts is not None and len(clip_starts) > 2:  # where each input clip begins
        top.hlines(np.asarray(clip_starts[1:-1]) - 0.5, 0, max(length - 1, 1), colors="0.8", linewidths=0.8,
                   linestyles="dotted", zorder=0)
    top.set_title(title)
    top.set_ylabel("input frame")
    top.yaxis.set_major_locator(MaxNLocator(integer=True))
    top.grid(True, alpha=0.3)
    if count > 1:
        top.legend(loc="best", fontsize=8, ncols=min(count, 4))

    any_seam = frames[seams.any(axis=0)]
    if any_seam.size:
        bottom.vlines(any_seam, 0.0, 1.0, transform=bottom.get_xaxis_transform(), colors="0.85", linewidths=0.8,
                      zorder=0, label=f"seam ({any_seam.size} frames)")
    bottom.plot(frames, accel_ratio, linewidth=1.4, color="tab:blue", label="max acceleration")
    bottom.axhline(1.0, color="0.35", linewidth=1.0, label="input's largest")
    bottom.axhline(limit, color="tab:orange", linestyle="--", linewidth=1.2, label=f"limit {limit:g}×")
    over = np.zeros(length, dtype=bool)
    np.greater(accel_ratio, limit, out=over, where=~np.isnan(accel_ratio))
    if over.any():
        bottom.plot(frames[over], accel_ratio[over], linestyle="none", marker="o", markersize=4.5, color="red",
                    zorder=3, label=f"above limit ({int(over.sum())} frames)")
    bottom.set_ylim(bottom=0.0)
    bottom.set_xlabel("output frame")
    bottom.set_ylabel("max acceleration / input's")
    bottom.grid(True, alpha=0.3)
    bottom.legend(loc="best", fontsize=8)
    _save(figure, path)


def write_synthesis_plots(folder, plots, clip_starts=None, inputs=(), outputs=()):
    """Write ``plots`` (one per animation, in order: each with sources (C, M), accel_ratio (M,),
    title and seams (C, M) bool or None, as :func:`write_synthesis_plot` takes them) as
    ``animation_NNNN.png`` in the folder ``folder``, atomically
    (:func:`~.output_folder.atomic_folder`, refused where it could cost the user a file: ``inputs``,
    ``outputs``); ``clip_starts`` as :func:`write_synthesis_plot`'s. Returns the paths written."""
    from .output_folder import atomic_folder

    written = []
    with atomic_folder(folder, inputs=inputs, outputs=outputs) as tmp:
        for a, plot in enumerate(plots):
            name = f"animation_{a:04d}.png"
            write_synthesis_plot(os.path.join(tmp, name), plot.sources, plot.accel_ratio, plot.title, seams=plot.seams,
                                 clip_starts=clip_starts)
            written.append(os.path.join(folder, name))
    return written


def write_graph_plots(folder, analysis, positions, drawn, inputs=(), outputs=()):
    """build-graph's folder of PNGs, written atomically (:func:`~.output_folder.atomic_folder`,
    refused where it could cost the user a file: ``inputs``, ``outputs``): each component's
    transition-cost matrix with its transitions ``drawn`` [(n, 2) per component, where the matrix
    shows them: a transition into a clip's start at its virtual column], the bone graph at
    ``positions`` (B, 2) and, when the input has ground contacts, their timeline (contacts.png:
    patches × frames). ``analysis``: the graph as build-graph found it (``pipeline.synthesis``'s
    GraphAnalysis: components with their bones and transitions, weights, kept_edges, cut_nodes,
    contacts, clips)."""
    from .output_folder import atomic_folder

    with atomic_folder(folder, inputs=inputs, outputs=outputs) as tmp:
        for number, (component, shown) in enumerate(zip(analysis.components, drawn)):
            t = component.transitions
            write_cost_matrix_plot(os.path.join(tmp, f"costs_component_{number:03d}.png"), t.D, shown,
                                   t.threshold, f"component {number}: {len(component.bones)} bones, "
                                   f"{len(t.pairs)} transitions (T_c = {t.threshold:.3g})", start=t.start)
        write_bone_graph_plot(os.path.join(tmp, "bone_graph.png"), positions, analysis.weights,
                              analysis.kept_edges, [c.bones for c in analysis.components], analysis.cut_nodes,
                              f"bone graph: {len(analysis.components)} component(s), "
                              f"{len(analysis.cut_nodes)} cut node(s)")
        contacts, clips = analysis.contacts, analysis.clips
        if contacts is not None and contacts.count:
            write_contact_timeline_plot(os.path.join(tmp, "contacts.png"), contacts.planted, np.diff(contacts.offsets),
                                        f"ground contacts: {contacts.count} patch(es), "
                                        f"{contacts.planted.any(axis=1).mean():.0%} of the frames in contact",
                                        clip_starts=clips.starts, clip_names=clips.names)
