"""Contact with the ground across components: keep the merged rig's support (issue #25, part 2).

The problem. Multi-component synthesis (:mod:`.assembly`) walks each bone component on its own
motion graph and merges them through their cut nodes. When the legs are components of their
own, the merge combines leg poses that never occur together: both legs mid-swing (both feet in
the air, the body floating), or both planted while the pelvis is at its lowest (a foot pushed
through the floor). Measured on a held-out dancer cut into 4 components: the lowest vertex went
6–7 % of the body's height below the input's lowest point and 4–6 % above the highest lowest
point the input ever has. Ground alignment (:mod:`.splicing`, ``up``) keeps each component's
reference bone on the ground; it cannot see the combination.

The method: a vertical root correction, after the merge. Per output frame the lowest height
ℓ(m) along the up axis of a fixed set of support vertices (:func:`support`) is compared with the
input's own range of lowest heights [lo, hi] (min and max over the input frames of their lowest
height, widened by ``slack``); the whole character (every bone's translation) is moved by a
vertical δ(m) that is zero wherever ℓ lies in the band and, where it leaves it, the smallest
smooth shift that brings it back (:func:`contact_offsets`: the violation dilated over ``radius``
frames, then smoothed with a raised-cosine kernel whose support fits inside the dilation, so the
band holds exactly at every violating frame; where that lift carries a neighbour out of the band
on the other side, a further round corrects it (at most ``rounds``, so δ is zero farther than
rounds × 2·radius frames from any violation), and a last clip makes it exact where an upward and
a downward need meet). Why this and not a merge that chooses among each component's candidate
segments those that keep support: the candidates are whole walks (hundreds to thousands of
frames), so a combination that keeps support at every frame of a 3,000-frame animation rarely
exists among the few a merge tries, while a vertical shift always exists (the band is never
empty), costs one small matrix product per batch, leaves the walks, seams and the eq. 12–14
merge untouched, and moves no vertex sideways (no foot sliding added). It is the same kind of
fix as the ground alignment (the root placed, the posture kept). Where nothing leaves the band
δ is exactly zero and the bones are not touched, so outputs that never leave the band stay
byte-identical.

What it costs. Where the band is narrow and the feet fast, holding it forces the shift to
follow the lowest foot frame by frame. The walker example (legs as components of their own; its
input keeps the lowest point at exactly 0, and at 24 fps a swinging foot moves about 5 cm a
frame) had its largest vertex acceleration go from 1.21× to 1.78× the input's (50 animations ×
600 frames, benchmarks/synthesize.py; single-component 1.11× either way): the merge had combined leg poses whose lowest point jumps by
up to 7 cm between frames, and a 1 % band is 1.7 cm. On the shared captures, where the merged
lowest point seldom leaves the band, it changes nothing measurable (benchmarks/synthesize.py).
``synthesize --no-contact`` keeps the merge as it is.

Heights are exact LBS of the support vertices (:func:`height_operator`): the height of vertex v
is linear in the up row of each bone's (F_b, t_b), so the heights of all frames are one matrix
product P (frames, 4B) · Q (4B, S) — no skinning of the whole mesh.

Support vertices: those that come within ``band`` of the input frame's lowest point in some
input frame (the feet, hooves, whatever carries the body; at most ``most`` of them, evenly
spaced among them by index, neighbours on a sole having nearly one height), and, with
``spread``, an evenly spaced subset of all vertices (so that a part that never touches the
ground in the input, but would in a new combination, is not missed by more than the subset's
spacing; off by default: each such vertex brings its bones into the product, and on the shared
captures and the walker the feet alone held every measured frame within 1 %). The input's own lowest
vertex of every frame is always in the set, so an output frame that plays an input pose
unchanged has exactly that frame's lowest height. The set's size is the correction's cost (one
product of a batch's 150,000 frames by it): about 270 on the elephant, where all the
near-ground ones within 1 % of the height were 2,200 and cost it 1.7 s of a 4 s run.

Measuring (shared by the benchmark and the tests): :func:`lowest_heights` and :func:`ground_excess`
(how far the lowest point leaves the input's range, over the height). How well the feet stay
planted (slide, float, penetration of the contact vertices) is :mod:`...mesh.contact_measures`.
"""

from dataclasses import dataclass

import numpy as np

from ...rig.influence import dense_weights

#: Frames over which a correction is dilated and then smoothed (each side).
RADIUS = 8
#: Band of support vertices (share of the height above an input frame's lowest point).
SUPPORT_BAND = 0.003
#: Most near-ground support vertices kept (besides each input frame's lowest).
MOST_NEAR = 256
#: Allowed excursion beyond the input's range before anything is corrected (share of the height):
#: the 0.1 % dips a splice makes are left alone (outputs stay byte-identical), far inside 1 %.
SLACK = 0.002
#: Evenly spaced vertices added to the support set (0: none; each brings its bones into the product).
SPREAD = 0


#: With ground contacts (:mod:`.planting`), the band's lower end is raised to the clips' ground less
#: this share of the height where the input's own lowest point dips further (a hoof through the
#: floor at an impact: the horse's gallop 0.56 % of the height, two frames): the floor is then the
#: ground found on the input, not its worst frame (:func:`ground_floored`).
GROUND_TOLERANCE = 0.0025


@dataclass
class Support:
    """vertices (S,) ids; bones (b,) the bones that move them; operator (4b, S)
    (:func:`height_operator` over those bones); lo, hi: the allowed band of
    lowest heights (the input's range widened by the slack); height: the rest pose's extent along
    up; up_axis."""

    vertices: np.ndarray
    bones: np.ndarray
    operator: np.ndarray
    lo: float
    hi: float
    height: float
    up_axis: int


def height_operator(rest, weights):
    """Q (4B, V): the height of vertex v is Σ_b w_vb (F_b[up]·x_v + t_b[up]) = P · Q[:, v], with
    P = :func:`bone_rows` (the up rows of every bone). rest (V, 3), weights (V, B) dense."""
    homogeneous = np.concatenate([np.asarray(rest, dtype=np.float64), np.ones((rest.shape[0], 1))], axis=1)
    return (weights[:, :, None] * homogeneous[:, None, :]).reshape(rest.shape[0], -1).T.copy()


def bone_rows(F, t, up_axis):
    """(..., B, 3, 3), (..., B, 3) -> (..., 4B) float64: each bone's up row of F, then of t."""
    rows = np.concatenate([F[..., up_axis, :], t[..., up_axis, None]], axis=-1).astype(np.float64)
    return rows.reshape(rows.shape[:-2] + (-1,))


def lowest_range(vertices, up_axis=1):
    """(lowest, highest) of the per-frame lowest point along ``up_axis`` of vertices (F, V, 3):
    the input's own range of lowest points, the band :func:`support` keeps. With several clips
    (issue 26) F is every clip's frames: the band spans them all (the order of frames does not
    matter here)."""
    lowest = lowest_heights(vertices, up_axis)
    return float(lowest.min()), float(lowest.max())


def support(rest, bone_indices, bone_weights, rotations, translations, up_axis=1, band=SUPPORT_BAND, slack=SLACK,
            spread=SPREAD, ground=None, most=MOST_NEAR):
    """The :class:`Support` of an input clip (its LBS fit: rest (V, 3), weights (V, K), rotations
    (F, B, 3, 3), translations (F, B, 3); several clips: all their frames, in any order): support
    vertices, their height operator and the band.

    ``ground``: the input frames' own (lowest, highest) lowest point (:func:`lowest_range`), the
    range to keep; None: the fit's playback of them. They differ by the fit's error at the lowest
    vertices: 1.2 % of the height on the shared horse collapse, whose fit sinks 3 cm into the
    floor where the input lies on it, so the input's own range is the default of ``synthesize``."""
    rest = np.asarray(rest, dtype=np.float64)
    dense = dense_weights(bone_indices, bone_weights, rotations.shape[1])
    rows = bone_rows(rotations, translations, up_axis)  # (F, 4B)
    heights = rows @ height_operator(rest, dense)  # (F, V)
    lowest = heights.min(axis=1)
    height = float(np.ptp(rest[:, up_axis])) or 1.0
    near = np.flatnonzero((heights <= lowest[:, None] + band * height).any(axis=0))
    near = near[np.linspace(0, len(near) - 1, min(most, len(near))).astype(np.int64)]
    even = np.linspace(0, rest.shape[0] - 1, min(spread, rest.shape[0])).astype(np.int64)
    vertices = np.union1d(np.union1d(near, even), np.argmin(heights, axis=1))
    low, high = (float(lowest.min()), float(lowest.max())) if ground is None else ground
    bones = np.flatnonzero(dense[vertices].any(axis=0))  # the feet's bones: the product's other side
    return Support(vertices=vertices, bones=bones, operator=height_operator(rest[vertices], dense[vertices][:, bones]),
                   lo=low - slack * height, hi=high + slack * height, height=height, up_axis=int(up_axis))


def ground_floored(found, grounds, tolerance=GROUND_TOLERANCE):
    """``found`` (a :class:`Support`) with its band's lower end no lower than the lowest of the
    clips' grounds (C,) less ``tolerance`` × its height (:data:`GROUND_TOLERANCE`)."""
    import dataclasses

    floor = float(np.min(grounds)) - tolerance * found.height
    return dataclasses.replace(found, lo=max(found.lo, min(floor, found.hi)))


def support_without(found, vertices):
    """``found`` (a :class:`Support`) less the given vertex ids (their columns and the bones only
    they needed): the support the plants' own lowest points (their patches' sample vertices) do
    not already cover (:func:`.synthesis.make_batch`); its band is ``found``'s."""
    import dataclasses

    keep = ~np.isin(found.vertices, vertices)
    B, S = found.bones.size, int(keep.sum())
    operator = found.operator[:, keep].reshape(B, 4, S)  # each bone's up row of F (3), then of t (1)
    needed = np.abs(operator).sum(axis=(1, 2)) > 0.0
    return dataclasses.replace(found, vertices=found.vertices[keep], bones=found.bones[needed],
                               operator=operator[needed].reshape(4 * int(needed.sum()), S))


def support_lowest(F, t, found, block_bytes=1 << 22):
    """Lowest height of the support vertices per frame: F (A, M, B, 3, 3), t (A, M, B, 3) -> (A, M)
    float64 (blocks of animations, one float32 matrix product each: a batch of 250 animations ×
    600 frames is 150,000 × 4b by 4b × S, b the bones that move the supports; float32 halves its
    time against float64, and its 1e-7 relative error is far inside the band's slack). Blocks of
    4 MB of heights, not more: the product's output then stays in the cache for the minimum (the
    samba's 250-animation batch: 0.08 s, against 0.19 s in one 64 MB block; the same numbers)."""
    A, M = F.shape[:2]
    out = np.empty((A, M))
    operator = found.operator.astype(np.float32)
    step = max(1, block_bytes // max(1, 4 * M * operator.shape[1]))
    up = found.up_axis
    for a in range(0, A, step):
        # bone_rows' layout (each bone's up row of F, then of t), gathered in the bones' own float32
        # (bone_rows widens to float64, which this product narrowed again: the same numbers, twice the copies)
        rows = np.concatenate([F[a:a + step, :, found.bones, up, :], t[a:a + step, :, found.bones, up, None]], axis=-1)
        rows = rows.reshape(rows.shape[:2] + (-1,)).astype(np.float32, copy=False)
        out[a:a + step] = (rows @ operator).min(axis=-1)
    return out


def raised_cosine(radius):
    """The raised-cosine kernel (2·radius + 1,), normalised, that :func:`_raise` smooths with."""
    kernel = 1.0 - np.cos(2.0 * np.pi * (np.arange(2 * radius + 1) + 1.0) / (2 * radius + 2))
    return kernel / kernel.sum()


def _raise(need, radius):
    """Smooth s ≥ need (A, M) ≥ 0, zero farther than 2·radius from any need: dilated over
    ±radius, then averaged with a raised-cosine kernel of the same support."""
    from scipy.ndimage import convolve1d, maximum_filter1d

    if radius == 0:
        return need
    kernel = raised_cosine(radius)
    return convolve1d(maximum_filter1d(need, 2 * radius + 1, axis=1, mode="nearest"), kernel, axis=1, mode="nearest")


def contact_offsets(lowest, lo, hi, radius=RADIUS, rounds=3):
    """δ (A, M): the vertical shift that puts lowest (A, M) + δ inside [lo, hi] at every frame,
    zero wherever lowest already lies there and farther than ``rounds`` × 2·radius frames from
    where it does not; smooth where the band leaves room (module notes). All animations at once."""
    lowest = np.asarray(lowest, dtype=np.float64)
    delta = np.zeros_like(lowest)
    for _ in range(rounds):
        now = lowest + delta
        up, down = np.maximum(lo - now, 0.0), np.maximum(now - hi, 0.0)
        if not (up.any() or down.any()):
            return delta
        delta = delta + _raise(up, radius) - _raise(down, radius)
    return np.clip(delta, lo - lowest, hi - lowest)


def keep_contact(F, t, found, radius=RADIUS, lowest=None):
    """Move each frame of F (A, M, B, 3, 3), t (A, M, B, 3) vertically so that its support keeps
    the input's range (:func:`contact_offsets`); t is changed in place, and only at the frames
    whose shift is not zero. lowest: None, or (A, M) the lowest points of vertices found already
    (the plants' patches, :func:`.planting.plant_feet`), taken with ``found``'s. Returns δ (A, M)."""
    if lowest is None:
        lowest = support_lowest(F, t, found)
    elif found.vertices.size:
        lowest = np.minimum(lowest, support_lowest(F, t, found))
    delta = contact_offsets(lowest, found.lo, found.hi, radius)
    rows, frames = np.nonzero(delta)
    if rows.size:
        t[rows, frames, :, found.up_axis] += delta[rows, frames, None].astype(t.dtype)
    return delta


# --- measuring ---------------------------------------------------------------------------------


def lowest_heights(vertices, up_axis=1):
    """vertices (..., M, V, 3) -> (..., M): the lowest height per frame."""
    return np.asarray(vertices)[..., up_axis].min(axis=-1)


def ground_excess(lowest, lowest_input, height):
    """(below, above): how far lowest (any shape) goes below min(lowest_input) and above
    max(lowest_input), each ≥ 0, as shares of ``height``."""
    lowest, lowest_input = np.asarray(lowest), np.asarray(lowest_input)
    below = max(0.0, float(lowest_input.min() - lowest.min())) / height
    above = max(0.0, float(lowest.max() - lowest_input.max())) / height
    return below, above
