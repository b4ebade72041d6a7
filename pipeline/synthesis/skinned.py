"""Synthesized animations as vertices, skinned on demand for the caches synthesize writes, the
pictures it draws of them and the feet it measures."""

import time
from dataclasses import dataclass

import numpy as np

from skinsynth.gpu import lbs


class SkinnedAnimations:
    """Each synthesized animation's vertices (M, V, 3), skinned by the warp LBS kernel only when
    asked for (a crowd of 10⁶ never has to fit in memory): ``skin`` has rest_vertices (V, 3),
    bone_indices and bone_weights (V, K); F (A, M, B, 3, 3) and t (A, M, B, 3) the bone motions;
    offsets (A, 3) each animation's placement.

    Asked in order (as the writers do), it skins the next ``threads`` animations in worker
    threads while the current one is written (CPU only: a CPU kernel launch runs in its calling
    thread, outside the GIL, so two threads skin about twice as fast on two cores); as a context
    manager it closes those threads on leaving."""

    def __init__(self, skin, F, t, offsets, device, threads=1):
        self.skin, self.F, self.t, self.offsets, self.device = skin, F, t, offsets, device
        self.threads = threads if str(device).startswith("cpu") else 1
        self._pool, self._pending = None, {}

    def __len__(self):
        return self.F.shape[0]

    def _skin(self, a):
        s = self.skin
        return lbs(s.rest_vertices, s.bone_indices, s.bone_weights, self.F[a], self.t[a], device=self.device) \
            + self.offsets[a]

    def __getitem__(self, a):
        if self.threads <= 1:
            return self._skin(a)
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(self.threads)
        for stale in [b for b in self._pending if b < a]:
            self._pending.pop(stale).cancel()
        for b in range(a, min(len(self), a + self.threads + 1)):
            if b not in self._pending:
                self._pending[b] = self._pool.submit(self._skin, b)
        return self._pending.pop(a).result()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        if self._pool is not None:
            for future in self._pending.values():
                future.cancel()
            self._pool.shutdown()
            self._pool, self._pending = None, {}


def measure_feet(skin, F, t, sources, starts, count, up_axis=1, device="cpu", block=64, limited=None):
    """The feet figures (:mod:`..mesh.contact_measures`, docs/contact.md) of the input and of the first
    ``count`` synthesized animations, their vertices skinned in blocks of ``block`` frames:
    ``skin`` has examples (Fi, V, 3), rest_vertices, bone_indices, bone_weights; F (A, M, B, 3, 3),
    t (A, M, B, 3), sources (C, A, M); ``starts`` the input's clip starts (C + 1,). An output frame
    is measured against the ground of the clip its first component plays. Returns a dict: height,
    ground (per clip), input, output (:func:`~..mesh.contact_measures.summary`), ratios, and ``played``
    with ``ratios_played``: the input frames themselves replayed along the first component's walks
    (steps across a seam left out), the reference for what synthesis adds where a walk dwells on
    part of a clip (:func:`~..mesh.contact_measures.played_input`), and ``fit`` with ``ratios_fit``:
    the fit's own playback of the input (its bones over the input's frames, measured on the
    input's grounds; issue 64: synthesis cannot plant what the rig cannot hold, so its feet are
    judged against the capture and against the rig's replay of it). limited (A, M) uint8 or None
    (:attr:`.synthesis.Synthesis.limited`): where the plants could not hold a foot, reported as
    ``limits`` (:func:`~..mesh.contact_measures.limits_summary`) where any animation has plants."""
    from ..mesh.contact_measures import (Steps, character_height, input_steps, limits_summary, measure_frames,
                                   played_input, ratios, steps_of_input, summary)

    height = character_height(skin.rest_vertices, up_axis)
    table = input_steps(skin.examples, starts, height, up_axis, block=block)  # the input's, step by step
    measured_in, grounds = steps_of_input(table, starts), table.grounds
    playback = np.concatenate([lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations[s:s + block],
                                   skin.translations[s:s + block], device=device)
                               for s in range(0, skin.rotations.shape[0], block)])
    fit = summary(steps_of_input(input_steps(playback, starts, height, up_axis, block=block, grounds=grounds), starts))
    clip_of = np.clip(np.searchsorted(np.asarray(starts), np.asarray(sources[0, :count]), side="right") - 1,
                      0, len(grounds) - 1)
    parts = []
    for a in range(count):
        Fa, ta = np.asarray(F[a]), np.asarray(t[a])  # one animation's bones (a cluster's: read from its shard)

        def frames(s, e, Fa=Fa, ta=ta):
            return lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, Fa[s:e], ta[s:e], device=device)

        parts.append(measure_frames(frames, Fa.shape[0], grounds[clip_of[a]], height, up_axis, block=block,
                                    limited=None if limited is None else np.asarray(limited[a]) > 0))
    measured = Steps.join(parts)
    figures_in, figures_out = summary(measured_in), summary(measured)
    played = summary(played_input(table, sources[0, :count], starts))
    figures = {"height": height, "ground": [float(g) for g in grounds], "input": figures_in, "output": figures_out,
               "ratios": ratios(figures_out, figures_in), "played": played, "ratios_played": ratios(figures_out, played),
               "fit": fit, "ratios_fit": ratios(figures_out, fit)}
    if limited is not None:
        figures["limits"] = limits_summary(measured, np.asarray(limited[:count]))
    return figures


def capture_envelope(skin, skinning, block=64):
    """The :class:`..mesh.shape.ShapeEnvelope` of a skin's capture: its frames (examples (Fi, V, 3), faces)
    and the fit's playback of them (rest_vertices, bone_indices, bone_weights, rotations and
    translations), skinned in blocks of ``block`` frames by ``skinning`` (rest, indices, weights,
    rotations, translations) -> vertices (:func:`skinsynth.gpu.lbs`, or its numpy reference)."""
    from ..mesh.shape import shape_envelope

    fit = skin.rotations.shape[0]

    def playback():
        for s in range(0, fit, block):
            yield skinning(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations[s:s + block],
                           skin.translations[s:s + block])

    return shape_envelope(skin.examples, skin.faces, playback(), block)


def measure_shape(skin, F, t, count, device="cpu", block=64, envelope=None):
    """The shape figures (:mod:`.shape`: edges strained far past anything the capture or its fit shows)
    of the first ``count`` synthesized animations, skinned in blocks of ``block`` frames: ``skin`` has
    examples (Fi, V, 3), faces, rest_vertices, bone_indices, bone_weights, rotations and translations
    (the fit, whose playback of the capture the envelope takes in); F (A, M, B, 3, 3), t (A, M, B, 3).
    Returns a dict: frames measured, broken_frames and broken_share (frames with more than
    :data:`..mesh.shape.BROKEN_SHARE` of their edges beyond), worst_frame (the largest share of one frame's
    edges beyond), margin and broken_edge_share (the definitions' constants). envelope: the
    capture's, where the synthesis already made it (:func:`.synthesis.skin_envelope`), or None."""
    if envelope is None:
        envelope = capture_envelope(skin, lambda *bones: lbs(*bones, device=device), block)
    shares = []
    for a in range(count):
        Fa, ta = np.asarray(F[a]), np.asarray(t[a])
        for s in range(0, Fa.shape[0], block):
            shares.append(envelope.beyond_share(lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights,
                                                    Fa[s:s + block], ta[s:s + block], device=device)))
    shares = np.concatenate(shares) if shares else np.zeros(0)
    broken = int(np.count_nonzero(shares > envelope.broken_share))
    return {"frames": int(shares.size), "broken_frames": broken, "broken_share": broken / max(shares.size, 1),
            "worst_frame": float(shares.max(initial=0.0)), "margin": envelope.margin,
            "broken_edge_share": envelope.broken_share}


def report_measures(skin, F, t, sources, count, up_axis=1, device="cpu", limited=None, envelope=None):
    """``synthesize --measure-feet``: the feet (:func:`measure_feet`; the input's clips are the
    skin's clip_names and clip_frames) and the shape (:func:`measure_shape`) of the first ``count``
    animations, each timed and reported: {"contact": (its --json object, one text line), "shape": …}
    (:func:`~..mesh.contact_measures.feet_report`, :func:`shape_report`); limited, envelope: as
    :func:`measure_feet` and :func:`measure_shape` take them."""
    from ..inputs.clips import Clips
    from ..mesh.contact_measures import feet_report

    starts = Clips(skin.clip_names, skin.clip_frames).starts
    started = time.perf_counter()
    figures = measure_feet(skin, F, t, sources, starts, count, up_axis, device, limited=limited)
    figures["seconds"] = time.perf_counter() - started
    started = time.perf_counter()
    shape = measure_shape(skin, F, t, count, device, envelope=envelope)
    shape["seconds"] = time.perf_counter() - started
    return {"contact": feet_report(figures, count), "shape": shape_report(shape, count)}


@dataclass
class AccelerationPlot:
    """What ``synthesize --plot`` draws of one animation (``formats.plots.write_synthesis_plot``):
    sources (C, M) the input frame each component plays at each output frame; accel_ratio (M,)
    each frame's largest vertex acceleration over the input's largest; title; seams (C, M) bool,
    or None for the one-clip rule (a frame that does not play on from the one before)."""

    sources: np.ndarray
    accel_ratio: np.ndarray
    title: str
    seams: np.ndarray | None


def acceleration_plots(skin, F, t, sources, count, device, clips=None):
    """The :class:`AccelerationPlot` of each of the first ``count`` animations, one at a time, its
    vertices baked with the skin's own weights: ``skin`` has examples (Fi, V, 3), rest_vertices,
    bone_indices, bone_weights; F (A, M, B, 3, 3), t (A, M, B, 3), sources (C, A, M). ``clips``:
    the input's several clips (None: one): seams by the clip-aware rule, and the input's largest
    acceleration measured inside each clip (never across the step from one clip's last frame to
    the next one's first)."""
    from ..mesh.geometry import frame_accelerations, largest_acceleration

    largest = largest_acceleration(skin.examples, None if clips is None else clips.starts)
    for a in range(count):
        vertices = lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, F[a], t[a], device=device)
        ratio = frame_accelerations(vertices) / largest
        mask = None if clips is None else clips.seams(sources[:, a])  # (C, M)
        seams = int(np.sum(sources[:, a, 1:] != sources[:, a, :-1] + 1)) if mask is None else int(mask.sum())
        # no acceleration in an animation under 3 frames
        peak = f"{np.max(ratio[1:-1]):.2f}× the input's" if len(ratio) > 2 else "none (under 3 frames)"
        yield AccelerationPlot(sources[:, a], ratio, f"animation {a}: {seams} seams, largest acceleration {peak}",
                               mask)


def shape_report(figures, count):
    """The report of :func:`measure_shape`'s figures of the
    first ``count`` animations (with the ``seconds`` they took): (the --json "shape" object, one text
    line; definitions in docs/contact.md)."""
    shape = {"animations": count, "definitions": "docs/contact.md", **figures,
             "broken_share": round(figures["broken_share"], 6), "worst_frame": round(figures["worst_frame"], 6),
             "seconds": round(figures["seconds"], 3)}
    line = (f"shape (first {count} animations against the capture; docs/contact.md): {figures['broken_frames']} of "
            f"{figures['frames']} frames broken ({figures['broken_share']:.2%}; more than "
            f"{figures['broken_edge_share']:.1%} of their edges strained {figures['margin']:g} of their length past "
            f"the capture's and its fit's), worst frame {figures['worst_frame']:.2%} of its edges")
    return shape, line
