"""What build-graph and synthesize report of their results: each a summary (the --json object)
and the text lines a person reads, built from the result alone."""

import numpy as np


def synthesis_summary(output, result, components, frames, min_segment, jobs, seconds, written, measures=None,
                      cluster=None):
    """synthesize's summary of ``result`` (a :class:`~.synthesis.Synthesis`), written to
    ``output`` with the other files ``written`` (``output`` first), made of ``components`` with
    segments of at least ``min_segment`` frames by ``jobs`` processes in ``seconds``: (summary,
    lines). With several clips it counts, per component, the frames played from each clip and
    the transitions taken from each clip to each. ``measures``: the feet's and the shape's reports
    (:func:`~.skinned.report_measures`), ``cluster`` a cluster run's (:func:`cluster_summary`), or
    None."""
    stats = result.statistics
    held = stats.get("distinct_poses", stats["distinct_frames"]) != stats["distinct_frames"]
    summary = {"animations": int(result.F.shape[0]), "frames": int(frames), "seconds": round(seconds, 3),
               "distinct": result.distinct, "transitions_used": int(np.sum(result.seams_used)),
               "components": len(components), "min_segment": int(min_segment), "jobs": int(jobs),
               "graph_transitions": [int(len(c.transitions.pairs)) for c in components],
               "transitions_used_per_component": stats["transitions"],
               "mean_segment_frames": [round(m, 2) for m in stats["mean_segment_frames"]],
               "shortest_segment": stats["shortest_segment"],
               "coverage": [round(c, 4) for c in stats["coverage"]],
               "distinct_frames": stats["distinct_frames"], "distinct_poses": stats["distinct_poses"],
               "stuck": stats["stuck"],
               "rejected": result.rejected, "outputs": written}
    lines = [f"wrote {output}: {summary['animations']} animations × {frames} frames from {len(components)} "
             f"component(s), {result.distinct} distinct, {summary['transitions_used']} transitions used; "
             f"{seconds:.1f} s" + (f"; replaced {result.rejected}" if any(result.rejected.values()) else ""),
             f"segments: mean {', '.join(f'{m:.1f}' for m in stats['mean_segment_frames'])} frames, shortest "
             f"{', '.join(map(str, stats['shortest_segment']))} (≥ {min_segment} asked); input frames played: "
             f"{', '.join(f'{c:.0%}' for c in stats['coverage'])} (per component)",
             ("distinct poses per animation (a held pose once): " if held else "distinct input frames per animation: ")
             + ", ".join(f"median {np.median(d):.0f} (least {min(d)})"
                         for d in stats["distinct_poses" if held else "distinct_frames"] if d)
             + " (per component); stuck in a loop: " + ", ".join(map(str, stats["stuck"]))]
    refused = [getattr(c, "shape_refused", 0) for c in components]
    kept_all = [k for k, c in enumerate(components) if getattr(c, "shape_kept_all", False)]
    summary["shape_refused_transitions"] = refused
    if any(refused) or kept_all:
        lines.append(f"transitions refused for tearing the body (docs/contact.md): {', '.join(map(str, refused))} "
                     "(per component)" + (f"; component(s) {', '.join(map(str, kept_all))} kept all theirs, "
                                          "refusing them would leave too few walks" if kept_all else ""))
    if "coverage_per_clip" in stats:  # several clips: what each clip gave, and the way between them
        summary["coverage_per_clip"] = [{name: round(share, 4) for name, share in shares.items()}
                                        for shares in stats["coverage_per_clip"]]
        summary["transitions_between"] = [{pair: int(n) for pair, n in used.items()}
                                          for used in stats["transitions_between"]]
        for c, (shares, used) in enumerate(zip(stats["coverage_per_clip"], stats["transitions_between"])):
            played = ", ".join(f"{name} {share:.0%}" for name, share in shares.items())
            taken = ", ".join(f"{pair.replace('->', '→')} {n}" for pair, n in used.items() if n) or "none"
            lines.append(f"component {c}: frames played per clip {played}; transitions {taken}")
    for key, (figures, line) in (measures or {}).items():
        summary[key] = figures
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


def graph_summary(output, analysis, seconds):
    """build-graph's summary of ``analysis`` (a :class:`~.graph.GraphAnalysis`, made in ``seconds``),
    written to ``output``: (summary, lines). ``transitions_between`` ({"a->b": count}, a
    component's, and over all components at the top) counts transitions by the clip they leave and
    the clip they enter; the text names them only when there are several clips."""
    clips, refused = analysis.clips, analysis.refused
    min_segment, up_axis = analysis.options["min_segment"], "XYZ"[analysis.options["up_axis"]]
    lines = [f"wrote {output}: {len(analysis.components)} component(s), cut nodes {analysis.cut_nodes}, "
             f"{analysis.transition_count} transitions, segments ≥ {min_segment} frames; {seconds:.1f} s"]
    components = []
    held = analysis.held if analysis.held is not None and len(analysis.held.runs) else None
    between = analysis.transitions_between()
    for number, component in enumerate(analysis.components):
        t = component.transitions
        extra = f", {t.admitted} above T_c for coverage" if t.admitted else ""
        lines.append(f"  component {number}: bones {component.bones} (reference {t.reference}), "
                     f"{len(t.pairs)} transitions{extra}, {t.share:.0%} of the {'moving ' if held else ''}frames on "
                     f"one strongly connected part, {len(component.key)} key vertices, {t.q.shape[1]} reduced "
                     "coordinates")
        if len(clips) > 1:
            lines.append("    " + _transitions_by_direction(between[number], clips))
        one_way, lead_in = _off_part(t, clips, min_segment, held)
        if one_way:
            lines.append(f"    frames {_ranges(one_way, clips)} are reached one way only (a one-time event and what "
                         "follows it: no transition leads back), so a walk plays them at most once, in its last 2 s")
        if lead_in:
            lines.append(f"    frames {_ranges(lead_in, clips)} only lead into the strongly connected part (nothing "
                         "returns to them): a walk plays them only where it starts on them, once")
        components.append({"bones": list(component.bones), "reference": int(t.reference),
                           "transitions": len(t.pairs), "admitted": int(t.admitted), "share": float(t.share),
                           "key_vertices": len(component.key), "reduced_coordinates": int(t.q.shape[1]),
                           "transitions_between": between[number], "one_way_frames": one_way,
                           "lead_in_frames": lead_in})
    total = {key: sum(counts[key] for counts in between) for key in between[0]} if between else {}
    if len(clips) > 1:
        every = f"; all components: {_transitions_by_direction(total, clips)}" if len(between) > 1 else ""
        lines.insert(1, f"  clips {', '.join(f'{n} ({f} frames)' for n, f in zip(clips.names, clips.frames))}{every}")
    summary = {"output": output, "components": components, "cut_nodes": list(analysis.cut_nodes),
               "transitions": int(analysis.transition_count), "min_segment": int(min_segment), "up_axis": up_axis,
               "seconds": round(seconds, 3), "clips": list(clips.names), "transitions_between": total,
               "walk_clips": list(analysis.options.get("walk_clips") or clips.names)}
    if held is not None:  # issue 63: each held pose one place in the graph
        runs = held.runs.tolist()
        summary["held_poses"] = {"runs": runs, "shown_frames": int(held.keep) + 1,
                                 "moving_frames": int(held.moving.sum())}
        lines.insert(1, f"  held poses (one place each, shown {held.keep + 1} frames): " + ", ".join(
            f"{clips.label(a)}–{clips.label(b)}" for a, b in runs[:8]) + (f" and {len(runs) - 8} more" if len(runs) > 8 else "")
            + f"; {summary['held_poses']['moving_frames']} moving frames of {held.frames}")
    contacts = analysis.contacts
    if contacts is not None:
        share = float(contacts.planted.any(axis=1).mean()) if contacts.count else 0.0
        summary["contacts"] = {"patches": contacts.count, "plants": len(contacts.plants(clips)),
                               "share_of_frames": round(share, 4)}
        lines.append(f"  ground contacts: {contacts.count} patch(es), {summary['contacts']['plants']} plant(s), "
                     f"{share:.0%} of the frames" if contacts.count else "  ground contacts: none (no ground found)")
        if refused is not None:
            summary["contacts"]["refused_transitions"] = [n for n, _ in refused]
            summary["contacts"]["kept_for_walks"] = [bool(k) for _, k in refused]
            kept = [str(c) for c, (_, k) in enumerate(refused) if k]
            lines.append(f"  transitions refused for a contact jump (a planted patch to a swinging one): "
                         f"{sum(n for n, _ in refused)}" + (f"; component(s) {', '.join(kept)} kept theirs (refusing "
                                                              f"them left too few frames to walk)" if kept else ""))
    left_out = [n for n in clips.names if n not in summary["walk_clips"]]
    if left_out:
        lines.insert(2, f"  walks play {', '.join(summary['walk_clips'])}; left out (--clips): {', '.join(left_out)}")
    return summary, lines


def _off_part(transitions, clips, segment, held):
    """([frames reached one way only], [frames that only lead in]) of a component's
    :class:`~.transitions.Transitions`, moving frames only (:func:`.motion_graph.frames_off_part`)."""
    from .motion_graph import frames_off_part

    frames = transitions.D.shape[0]
    hidden = None if held is None else held.hidden
    _, after, before = frames_off_part(frames, transitions.pairs, clips if len(clips) > 1 else None, segment, hidden)
    moving = np.ones(frames, bool) if held is None else held.moving
    return np.flatnonzero(after & moving).tolist(), np.flatnonzero(before & moving).tolist()


def _ranges(frames, clips):
    """'3–9, 40' of sorted frame ids (as the clips name them), at most 6 ranges."""
    frames = np.asarray(frames, np.int64)
    cuts = np.flatnonzero(np.diff(frames) != 1) + 1
    runs = [(int(r[0]), int(r[-1])) for r in np.split(frames, cuts)]
    text = ", ".join(clips.label(a) if a == b else f"{clips.label(a)}–{clips.label(b)}" for a, b in runs[:6])
    return text + (f" and {len(runs) - 6} more" if len(runs) > 6 else "")


def _transitions_by_direction(counts, clips):
    """'within gallop 15, collapse 0; between gallop→collapse 3, collapse→gallop 1' from {"a->b": n}."""
    within = ", ".join(f"{a} {counts[f'{a}->{a}']}" for a in clips.names)
    across = ", ".join(f"{a}→{b} {counts[f'{a}->{b}']}" for a in clips.names for b in clips.names if a != b)
    return f"transitions within {within}; between {across}"
