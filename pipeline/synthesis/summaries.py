"""What build-graph and synthesize report of their results: each a summary (the --json object)
and the text lines a person reads, built from the result alone."""

import numpy as np


def synthesis_summary(output, result, components, frames, min_segment, jobs, seconds, written, feet=None,
                      cluster=None):
    """synthesize's summary of ``result`` (a :class:`~.synthesis.Synthesis`), written to
    ``output`` with the other files ``written`` (``output`` first), made of ``components`` with
    segments of at least ``min_segment`` frames by ``jobs`` processes in ``seconds``: (summary,
    lines). With several clips it counts, per component, the frames played from each clip and
    the transitions taken from each clip to each. ``feet``: the feet measures' report
    (:func:`~.skinned.report_feet`), ``cluster`` a cluster run's (:func:`cluster_summary`), or
    None."""
    stats = result.statistics
    summary = {"animations": int(result.F.shape[0]), "frames": int(frames), "seconds": round(seconds, 3),
               "distinct": result.distinct, "transitions_used": int(np.sum(result.seams_used)),
               "components": len(components), "min_segment": int(min_segment), "jobs": int(jobs),
               "graph_transitions": [int(len(c.transitions.pairs)) for c in components],
               "transitions_used_per_component": stats["transitions"],
               "mean_segment_frames": [round(m, 2) for m in stats["mean_segment_frames"]],
               "shortest_segment": stats["shortest_segment"],
               "coverage": [round(c, 4) for c in stats["coverage"]],
               "rejected": result.rejected, "outputs": written}
    lines = [f"wrote {output}: {summary['animations']} animations × {frames} frames from {len(components)} "
             f"component(s), {result.distinct} distinct, {summary['transitions_used']} transitions used; "
             f"{seconds:.1f} s" + (f"; replaced {result.rejected}" if any(result.rejected.values()) else ""),
             f"segments: mean {', '.join(f'{m:.1f}' for m in stats['mean_segment_frames'])} frames, shortest "
             f"{', '.join(map(str, stats['shortest_segment']))} (≥ {min_segment} asked); input frames played: "
             f"{', '.join(f'{c:.0%}' for c in stats['coverage'])} (per component)"]
    if "coverage_per_clip" in stats:  # several clips: what each clip gave, and the way between them
        summary["coverage_per_clip"] = [{name: round(share, 4) for name, share in shares.items()}
                                        for shares in stats["coverage_per_clip"]]
        summary["transitions_between"] = [{pair: int(n) for pair, n in used.items()}
                                          for used in stats["transitions_between"]]
        for c, (shares, used) in enumerate(zip(stats["coverage_per_clip"], stats["transitions_between"])):
            played = ", ".join(f"{name} {share:.0%}" for name, share in shares.items())
            taken = ", ".join(f"{pair.replace('->', '→')} {n}" for pair, n in used.items() if n) or "none"
            lines.append(f"component {c}: frames played per clip {played}; transitions {taken}")
    if feet is not None:
        summary["contact"], line = feet
        lines.append(line)
    if cluster is not None:
        summary["cluster"], cluster_lines = cluster
        lines += cluster_lines
    if len(written) > 1:
        lines.append(f"also wrote: {', '.join(written[1:]) if len(written) < 6 else written[1] + ' …'}")
    return summary, lines


def cluster_summary(address, workers, dashboard, remote, folder, old_shards_kept=False):
    """synthesize --cluster's report of a run on the cluster at ``address`` (``workers``, its
    ``dashboard`` URL or None) through ``remote`` (a :class:`~skinsynth.pipeline.runtime.execution.Remote`:
    tasks, reused batches, retries), its shards in ``folder``; ``old_shards_kept``: the old
    output's unused shards could not be removed yet: (summary["cluster"], lines)."""
    lines = ["the old output's shards are kept: something still reads it (the next run removes them)"] \
        if old_shards_kept else []
    summary = {"address": address, "workers": workers, "tasks": remote.tasks, "reused_batches": remote.reused,
               "retries": remote.retries, "dashboard": dashboard, "shards": folder}
    lines.append(f"cluster {address}: {workers} workers, {remote.tasks} tasks, {remote.retries} re-run after a "
                 f"lost worker, {remote.reused} batches reused; shards in {folder}")
    return summary, lines
