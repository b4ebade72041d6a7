"""How well feet stay planted: the measures of issue 35 part 4, for an input and for an output.

Every figure is a share of the character's **height** H (the rest pose's extent along the up
axis), so captures of any scale compare; docs/contact.md states the same definitions for users.

- **Ground** (:func:`clip_ground`): per input clip, the 5th percentile of its per-frame lowest
  heights along the up axis. Not the lowest of them: one frame whose hoof dips through the floor
  (a capture's or a fit's error) would lower it; not the median: a gallop or a jump has many
  frames with every foot in the air. Anything that walks, dances or lies on a floor has its
  lowest point on that floor in most frames, so a low percentile finds it and ignores the rare
  dip. An output frame is measured against the ground of the input clip its first component's
  source frame comes from (one clip: one ground).
- **Contact vertices** of the step m → m+1: the vertices within ``band`` (1 %) of H above the
  ground (or anywhere below it) at both frames m and m+1, where frame m plays on to m+1 (in an
  input of several clips, no step joins one clip's last frame to the next one's first:
  :meth:`~skinsynth.pipeline.inputs.clips.Clips.plays_on`). A step with none is not a contact step.
- **Slide** of a contact step: the median, over its contact vertices, of their horizontal
  displacement (the up component removed) from m to m+1, over H (the median: one vertex of a
  heel that lifts does not make a planted foot slide). Reported: its median and 95th percentile
  over the contact steps, and the share of contact steps whose slide exceeds ``limit`` (0.5 %).
- **Float** and **penetration** of a contact step: the height of the lowest contact vertex at
  frame m minus the ground, over H: float is its positive part (the patch hovers), penetration
  its negative part (the patch is under the floor). Reported: median, 95th percentile, largest.
- **Worst acceleration**: the largest ‖x(m+1) − 2 x(m) + x(m−1)‖ over every vertex and frame of
  the output, over the input's largest (the input's measured inside each clip).

Pure numpy, vectorised over frames and vertices; a long animation is measured in blocks of
frames (:func:`measure_frames`), so its vertices never need to be in memory at once.
"""

from dataclasses import dataclass

import numpy as np

#: Contact band: share of the height above the ground.
BAND = 0.01
#: A contact step slides when its slide exceeds this share of the height.
LIMIT = 0.005
#: Percentile of the per-frame lowest heights that is a clip's ground.
GROUND_PERCENTILE = 5.0


def character_height(rest, up_axis=1):
    """H: the rest pose's extent along ``up_axis`` (1.0 for a flat rest pose)."""
    return float(np.ptp(np.asarray(rest)[:, up_axis])) or 1.0


def clip_ground(vertices, up_axis=1):
    """The ground of one clip, vertices (M, V, 3): the 5th percentile of its per-frame lowest
    heights (module notes)."""
    return float(np.percentile(np.asarray(vertices)[..., up_axis].min(axis=-1), GROUND_PERCENTILE))


@dataclass
class Steps:
    """Raw per-step figures of one or more animations, to be joined and summarised
    (:func:`summary`): ``slide``, ``offset`` (lowest contact vertex minus ground) over the height,
    one per contact step; ``steps`` all steps measured; ``accel`` the largest acceleration seen
    (NaN: none, under 3 frames); ``limited`` (one per contact step) bool: the step starts or ends
    at a frame where the plants could not hold a foot (:func:`limits_summary`)."""

    slide: np.ndarray
    offset: np.ndarray
    steps: int
    accel: float
    limited: np.ndarray = None

    @staticmethod
    def join(parts):
        parts = list(parts)
        return Steps(np.concatenate([p.slide for p in parts] + [np.zeros(0)]),
                     np.concatenate([p.offset for p in parts] + [np.zeros(0)]),
                     int(sum(p.steps for p in parts)), _largest([p.accel for p in parts]),
                     np.concatenate([np.zeros(p.slide.size, bool) if p.limited is None else p.limited
                                     for p in parts] + [np.zeros(0, bool)]))


def _largest(values):
    """The largest finite of ``values`` (any shape) as a float; NaN where none is."""
    values = np.asarray(values, dtype=np.float64).ravel()
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else float("nan")


def _blocks(first, end, block):
    """(start, stop) of the blocks measuring frames first … end − 1: ``block`` steps each, two
    frames of overlap, so every step and every second difference is counted once."""
    for start in range(first, max(end - 1, first + 1), block):
        yield start, min(start + block + 2, end)


def contact_steps(vertices, ground, height, up_axis=1, band=BAND, plays_on=None, steps=None, limited=None):
    """The :class:`Steps` of vertices (M, V, 3): ``ground`` a float or (M,) per frame;
    ``plays_on`` (M,) bool (frame m is followed by m+1; None: every frame but the last).
    ``steps``: count only the steps m → m+1 and the second differences centred on m+1 for
    m < steps (None: all; :func:`measure_frames`' blocks). ``limited`` (M,) bool or None: the
    frames where the plants could not hold a foot (a step is limited where either end is)."""
    rows, slide, offset, counted, accel = _step_table(vertices, ground, height, up_axis, band, plays_on, steps)
    marked = None
    if limited is not None:
        limited = np.asarray(limited, dtype=bool)
        marked = limited[rows] | limited[rows + 1]
    return Steps(slide, offset, int(counted[:-1].sum()), _largest(accel), marked)


def _step_table(vertices, ground, height, up_axis=1, band=BAND, plays_on=None, steps=None):
    """:func:`contact_steps`' figures step by step: (rows (n,) the contact steps m → m+1, their
    slide (n,) and offset (n,) over the height, counted (M,) the steps counted, accel (M,) the
    largest second difference centred on each frame, NaN where none is counted)."""
    x = np.asarray(vertices, dtype=np.float64)
    M = x.shape[0]
    plays = np.ones(M, bool) if plays_on is None else np.asarray(plays_on, dtype=bool).copy()
    plays[-1:] = False
    counted = plays.copy()
    if steps is not None:
        counted[steps:] = False
    ground = np.broadcast_to(np.asarray(ground, dtype=np.float64), (M,))
    above = x[..., up_axis] - ground[:, None]  # (M, V)
    near = above <= band * height
    contact = near[:-1] & near[1:] & counted[:-1, None]  # (M−1, V)
    # only the contact pairs (a few % of the vertices): their steps, grouped by step (rows sorted)
    r, v = np.nonzero(contact)
    step = x[r + 1, v] - x[r, v]
    step[:, up_axis] = 0.0
    moved = np.sqrt(np.einsum("ij,ij->i", step, step))
    rows, slide, offset = np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    if r.size:
        rows, starts, counts = np.unique(r, return_index=True, return_counts=True)
        ordered = moved[np.lexsort((moved, r))]  # by step, then by distance
        slide = 0.5 * (ordered[starts + (counts - 1) // 2] + ordered[starts + counts // 2]) / height
        offset = np.minimum.reduceat(above[r, v], starts) / height
    # second differences whose three frames play on one into the next
    accel = np.full(M, np.nan)
    centred = np.flatnonzero(plays[:-2] & plays[1:-1] & counted[:-2]) if M >= 3 else np.zeros(0, np.int64)
    if centred.size:
        second = np.subtract(x[2:], x[1:-1])
        second -= x[1:-1]
        second += x[:-2]
        accel[centred + 1] = np.sqrt(np.einsum("mvi,mvi->mv", second, second).max(axis=1)[centred])
    return rows, slide, offset, counted, accel


def measure_frames(frames, count, ground, height, up_axis=1, band=BAND, plays_on=None, block=64, limited=None):
    """:func:`contact_steps` of a long animation given as ``frames(start, stop)`` -> vertices
    (stop − start, V, 3) of ``count`` frames, in blocks of ``block`` frames (two frames of
    overlap, so every step and every second difference is counted once). ``ground``: a float or
    (count,); ``plays_on``, ``limited`` (count,) or None."""
    ground = np.broadcast_to(np.asarray(ground, dtype=np.float64), (count,))
    plays = np.ones(count, bool) if plays_on is None else np.asarray(plays_on, dtype=bool)
    parts = []
    for start, stop in _blocks(0, count, block):
        # steps start .. start+block−1, second differences centred on start+1 .. start+block
        parts.append(contact_steps(frames(start, stop), ground[start:stop], height, up_axis, band,
                                   plays[start:stop], steps=block,
                                   limited=None if limited is None else limited[start:stop]))
    return Steps.join(parts)


def summary(measured, limit=LIMIT):
    """The reported figures (module notes) of :class:`Steps`: a dict of plain floats."""
    slide, offset = measured.slide, measured.offset
    out = {"steps": int(measured.steps), "contact_steps": int(slide.size)}
    if slide.size:
        float_, sink = np.maximum(offset, 0.0), np.maximum(-offset, 0.0)
        out.update(slide_median=float(np.median(slide)), slide_p95=float(np.percentile(slide, 95)),
                   sliding_share=float(np.mean(slide > limit)),
                   float_median=float(np.median(float_)), float_p95=float(np.percentile(float_, 95)),
                   float_max=float(float_.max()), penetration_median=float(np.median(sink)),
                   penetration_p95=float(np.percentile(sink, 95)), penetration_max=float(sink.max()))
    out["largest_accel"] = measured.accel
    return out


#: The flags of where the plants could not hold a foot (:attr:`.synthesis.Synthesis.limited`): a
#: limb held at the edge of its joints' range; a limb's turn cut to keep the skin whole.
LIMB_HELD, LIMB_CUT = 1, 2


def limits_summary(measured, limited, limit=LIMIT):
    """Where the plants could not hold a foot, and how much it slid there (issue 62: a limb held at
    the edge of its joints' range, or its turn cut to keep the skin whole, lets its foot slide a
    little): ``measured`` the output's :class:`Steps` (with ``limited``), limited (A, M) uint8 the
    measured animations' flags (:attr:`.synthesis.Synthesis.limited`: :data:`LIMB_HELD`,
    :data:`LIMB_CUT`). A dict:
    held_frames, cut_frames (shares of the frames), contact_steps (the share of the contact steps
    at such frames) and their slide_median, slide_p95, sliding_share (absent where none is)."""
    limited = np.asarray(limited)
    out = {"held_frames": float(np.mean(limited & LIMB_HELD > 0)) if limited.size else 0.0,
           "cut_frames": float(np.mean(limited & LIMB_CUT > 0)) if limited.size else 0.0}
    at = measured.slide[measured.limited] if measured.limited is not None else np.zeros(0)
    out["contact_steps"] = float(at.size / max(measured.slide.size, 1))
    if at.size:
        out.update(slide_median=float(np.median(at)), slide_p95=float(np.percentile(at, 95)),
                   sliding_share=float(np.mean(at > limit)))
    return out


#: An input figure at most this (a share of the height, or of the largest acceleration's units) is
#: rounding, not motion: no ratio is taken over it (the planted walker's slide p95 is 6e-17).
RATIO_FLOOR = 1e-9


def ratios(output, input_):
    """Output over input of the slide figures and the largest acceleration (None where the
    input's is missing, or 0 up to rounding: at most :data:`RATIO_FLOOR`)."""
    out = {}
    for key in ("slide_median", "slide_p95", "sliding_share", "largest_accel"):
        a, b = output.get(key), input_.get(key)
        out[key] = (float(a / b) if a is not None and b is not None and np.isfinite(a) and np.isfinite(b)
                    and b > RATIO_FLOOR else None)
    return out


@dataclass
class InputSteps:
    """An input's figures step by step (:func:`input_steps`): per input frame f, the slide and
    offset of the step f → f+1 (NaN where it is no contact step, or crosses into the next clip) and
    the largest second difference centred on f (NaN at a clip's ends); ``grounds`` (C,) each clip's."""

    slide: np.ndarray
    offset: np.ndarray
    accel: np.ndarray
    grounds: np.ndarray


def input_steps(vertices, starts, height, up_axis=1, block=64, grounds=None):
    """The :class:`InputSteps` of an input of one or more clips, vertices (F, V, 3), clip c being
    frames starts[c] … starts[c+1] − 1; no step or second difference crosses from one clip into the
    next; measured in blocks of ``block`` frames. ``grounds`` (C,): each clip's ground (None: its
    own, :func:`clip_ground`; a fit's playback is measured on its capture's)."""
    vertices = np.asarray(vertices)
    starts = np.asarray(starts, dtype=np.int64)
    F = vertices.shape[0]
    slide, offset, accel = np.full(F, np.nan), np.full(F, np.nan), np.full(F, np.nan)
    grounds = (np.array([clip_ground(vertices[a:b], up_axis) for a, b in zip(starts[:-1], starts[1:])])
               if grounds is None else np.asarray(grounds, dtype=np.float64))
    for a, b, g in zip(starts[:-1], starts[1:], grounds):
        for start, stop in _blocks(a, b, block):
            rows, s, o, _, acc = _step_table(vertices[start:stop], g, height, up_axis, BAND, None, block)
            slide[start + rows], offset[start + rows] = s, o
            inside = np.isfinite(acc)
            accel[start + np.flatnonzero(inside)] = acc[inside]
    return InputSteps(slide, offset, accel, grounds)


def measure_input(vertices, starts, height, up_axis=1, block=64):
    """An input of one or more clips, vertices (F, V, 3), clip c being frames starts[c] …
    starts[c+1] − 1 (:attr:`~skinsynth.pipeline.inputs.clips.Clips.starts`): (its :class:`Steps`, each
    clip's ground (C,)). No step or second difference crosses from one clip into the next."""
    table = input_steps(vertices, starts, height, up_axis, block)
    return steps_of_input(table, starts), table.grounds


def steps_of_input(table, starts):
    """The :class:`Steps` of the whole input from its :class:`InputSteps` (every step inside a clip)."""
    counts = np.diff(np.asarray(starts, dtype=np.int64))
    at = np.flatnonzero(np.isfinite(table.slide))
    return Steps(table.slide[at], table.offset[at], int(np.maximum(counts - 1, 0).sum()), _largest(table.accel))


def played_input(table, sources, starts):
    """The :class:`Steps` of the input frames themselves played along walks: ``table`` the input's
    :class:`InputSteps`, sources (A, M) the input frame of each output frame, starts the clips'
    starts (C + 1,). A step counts only where the walk plays on (source m + 1 = source m + 1 within a
    clip), not across a seam; so each counted step is the input's own step at its source frame,
    gathered (the same figures as measuring the played frames again). Why: a capture's feet slide
    more in some of its frames than in others (the samba's 0.17 % of the height a step in frames
    25–125, 0.03 % in frames 125–175), so the whole clip's figure is a fair reference only for walks
    that play every frame equally; this one is, for any walk, what the input did at the frames it
    plays."""
    from ..inputs.clips import Clips

    counts = np.diff(np.asarray(starts, dtype=np.int64))
    clips = Clips(tuple(range(counts.size)), tuple(counts))  # the names play no part
    sources = np.asarray(sources, dtype=np.int64)
    slides, offsets, steps, accel = [], [], 0, []
    for src in sources:
        plays = np.zeros(src.size, bool)
        plays[:-1] = clips.continues(src)
        stepping = src[:-1][plays[:-1]]
        steps += stepping.size
        contact = stepping[np.isfinite(table.slide[stepping])]
        slides.append(table.slide[contact])
        offsets.append(table.offset[contact])
        centred = src[1:-1][plays[:-2] & plays[1:-1]] if src.size >= 3 else np.zeros(0, np.int64)
        accel.append(table.accel[centred])
    return Steps(np.concatenate(slides + [np.zeros(0)]), np.concatenate(offsets + [np.zeros(0)]), steps,
                 _largest(np.concatenate(accel + [np.zeros(0)])))


def significant(value, digits=6):
    """``value`` (a figure, or a dict or list of them) for a report: floats to ``digits``
    significant digits, a non-finite one as None."""
    if isinstance(value, dict):
        return {k: significant(v, digits) for k, v in value.items()}
    if isinstance(value, list):
        return [significant(v, digits) for v in value]
    if isinstance(value, float):
        return float(f"{value:.{digits}g}") if np.isfinite(value) else None
    return value


def feet_report(figures, count):
    """The report of the feet figures of the input and the first ``count`` animations
    (:func:`~skinsynth.pipeline.synthesis.skinned.measure_feet`'s, with the ``seconds`` they took):
    (the --json "contact" object, one text line; definitions in docs/contact.md)."""
    figures = significant(figures)
    figures["seconds"] = round(figures["seconds"], 3)
    contact = {"animations": count, "definitions": "docs/contact.md", **figures}
    i, o, r = figures["input"], figures["output"], figures["ratios"]
    fit = figures.get("fit") or {}

    def share(side, key):
        return f"{side[key]:.2%}" if side.get(key) is not None else "n/a"

    accel = f"{r['largest_accel']:.2f}×" if r.get("largest_accel") is not None else "n/a"
    limits = ""
    if "limits" in figures:
        held = figures["limits"]
        limits = (f"; limbs held at their joints' range in {held['held_frames']:.1%} of the frames, turns cut to "
                  f"keep the skin in {held['cut_frames']:.1%}, {held['contact_steps']:.1%} of the contact steps "
                  f"there" + (f" (slide median {share(held, 'slide_median')}, 95th percentile "
                              f"{share(held, 'slide_p95')})" if held.get("slide_median") is not None else ""))
    def against(key):
        return f"{share(i, key)}" + (f", the fit's playback {share(fit, key)}" if fit else "")

    line = (f"feet (first {count} animations against the input, shares of the height; docs/contact.md): slide "
            f"median {share(o, 'slide_median')} (input {against('slide_median')}), 95th percentile "
            f"{share(o, 'slide_p95')} ({against('slide_p95')}), steps sliding over 0.5 % {share(o, 'sliding_share')} "
            f"({against('sliding_share')}); float p95 {share(o, 'float_p95')} ({share(i, 'float_p95')}), "
            f"penetration p95 {share(o, 'penetration_p95')} ({share(i, 'penetration_p95')}); "
            f"worst acceleration {accel} the input's{limits}")
    return contact, line
