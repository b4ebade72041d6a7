"""Transitions whose splice would tear the body, refused before any walk takes them (issue 62).

A transition (i, j) passes Zheng's cost threshold (eq. 5–6) on the reduced coordinates of the bones
in the reference bone's frame. The truncated coordinates can miss a limb: the horse's gallop holds
transitions between phases half a cycle apart (frame 33, phase 9, to frame 21), cheaper by eq. 6 than
a frame's own step, whose splice blends legs that swing apart through relative turns no input frame
shows (31° at a hock, at the seam), and the skin between its bones tears there in every animation
that takes one (1.3 % of the frames of twenty gallops of 600 frames; :mod:`.shape`). The cost does
not see it; the shape measure does.

So each transition is spliced once on its own (:func:`transition_walks`: the frames before i and
after it, the window's length and one more on each side), with the synthesis's own options, the
component's bones skinned on the vertices they carry alone, and the walk's frames measured against
the capture's edges (:class:`..mesh.shape.ShapeEnvelope`): a transition is *tearing* when any of those
frames has more edges beyond than a broken frame of the whole mesh has
(:data:`..mesh.shape.BROKEN_SHARE` of all its edges). A synthesis walks the others
(:func:`.synthesis.prepare_synthesis`), unless refusing them would leave a component fewer than
:data:`KEEP_PLAYABLE` of the frames it could play for ever from: it then keeps its transitions,
and says so. A transition between clips is a clip's way in or out (a gallop into its collapse): a
tearing one is refused where another way from the one clip into the other does not tear, and where
every way tears the one that tears least is kept, so the clips stay joined (the horse's clips: 0.40 %
of the frames broken, each at one of its two only ways between clips, one each way, which stay). ``synthesize --no-shape-check`` walks every transition, as before.
"""

import numpy as np

#: A component keeps its tearing transitions when refusing them would leave its walks fewer than
#: this share of the frames they could play for ever from (as :data:`.contact.planting.KEEP_USABLE`).
KEEP_PLAYABLE = 0.9
#: A vertex belongs to a component's own region when at least this share of its weight is on the
#: component's bones (its other bones come from other components' walks in a merge).
OWN_WEIGHT = 0.999


def transition_walks(pairs, window, clips):
    """The walk each transition is spliced on: (walks [(sources (L,), seam)], one per pair (T, 2)):
    up to ``window`` + 2 frames of i's clip ending at i, then the frame played after the seam
    (``clips.targets(j)``) and up to ``window`` + 1 frames after it in its clip."""
    walks = []
    targets = clips.targets(np.asarray(pairs, dtype=np.int64).reshape(-1, 2)[:, 1])
    starts = clips.starts
    for (i, _), target in zip(np.asarray(pairs, dtype=np.int64).reshape(-1, 2), targets):
        clip_i = np.searchsorted(starts, i, side="right") - 1
        clip_t = np.searchsorted(starts, target, side="right") - 1
        first = max(int(starts[clip_i]), int(i) - window - 1)
        last = min(int(starts[clip_t + 1]) - 1, int(target) + window + 1)
        walks.append((np.concatenate([np.arange(first, i + 1), np.arange(target, last + 1)]), int(i) + 1 - first))
    return walks


def tearing_transitions(component, skin, envelope, request, pivots, lbs):
    """(T,) bool: which of a component's transitions (``component.transitions.pairs``) tear the body
    when spliced (module notes). skin: rest_vertices, bone_indices, bone_weights (V, K), rotations
    (F, B, 3, 3), translations (F, B, 3); envelope: the capture's :class:`..mesh.shape.ShapeEnvelope`;
    request: the synthesis's (window, blend, alignment, spread velocity, clips: the splice it runs); pivots (B, 3) the bones' blend pivots; lbs: linear blend skinning, (rest, indices, weights,
    F, t) -> vertices (:func:`skinsynth.gpu.lbs`)."""
    from ..inputs.clips import Clips
    from .splicing import splice_local

    pairs = np.asarray(component.transitions.pairs, dtype=np.int64).reshape(-1, 2)
    tearing = np.zeros(len(pairs), dtype=bool)
    if not len(pairs):
        return tearing
    frames = skin.rotations.shape[0]
    clips = request.clips or Clips.single(frames)
    bones = np.asarray(component.bones, dtype=np.int64)
    weights = np.asarray(skin.bone_weights, dtype=np.float64)
    own = (np.isin(skin.bone_indices, bones) * weights).sum(axis=1) >= OWN_WEIGHT * weights.sum(axis=1)
    region = np.flatnonzero(own)
    edges = envelope.edges
    inside = own[edges[:, 0]] & own[edges[:, 1]]
    if not inside.any():
        return tearing
    local = np.full(own.size, -1, np.int64)
    local[region] = np.arange(region.size)
    sub = type(envelope)(edges=local[edges[inside]], rest_lengths=envelope.rest_lengths[inside],
                         envelope=envelope.envelope[inside], margin=envelope.margin)
    most = envelope.broken_share * len(edges)  # a broken frame's count of edges beyond, of the whole mesh
    up = None if request.alignment == "full" else np.eye(3)[request.up_axis]
    worst = np.zeros(len(pairs))  # each transition's largest count of edges beyond in one frame
    walks = transition_walks(pairs, request.window, clips)
    for length in sorted({len(w) for w, _ in walks}):  # walks of one length spliced together
        rows = [n for n, (w, _) in enumerate(walks) if len(w) == length]
        sources = np.stack([walks[n][0] for n in rows])
        F, t = splice_local(component, skin.rotations, skin.translations, sources, window=request.window,
                            spread_velocity=request.spread_velocity, blend=request.blend, pivots=pivots, up=up,
                            clips=request.clips).world()
        F_all = np.broadcast_to(np.eye(3), sources.shape + (skin.rotations.shape[1], 3, 3)).copy()
        t_all = np.zeros(sources.shape + (skin.rotations.shape[1], 3))
        F_all[:, :, bones], t_all[:, :, bones] = F, t
        vertices = lbs(skin.rest_vertices[region], skin.bone_indices[region], skin.bone_weights[region],
                       F_all.reshape((-1,) + F_all.shape[2:]), t_all.reshape((-1,) + t_all.shape[2:]))
        beyond = sub.beyond(vertices).sum(axis=1).reshape(sources.shape)
        worst[rows] = beyond.max(axis=1)
    return refused_ways(worst, most, clips.clip_of(pairs[:, 0]), clips.clip_of(clips.targets(pairs[:, 1])))


def refused_ways(worst, most, clip_from, clip_to):
    """(T,) bool: the transitions refused, each with ``worst`` (T,) its largest count of edges beyond
    in one frame of its splice and clip_from, clip_to (T,) the clips it leaves and enters: those
    past ``most``, but of the ways from one clip into another (clip_from ≠ clip_to) that all tear,
    the one that tears least (the first of equals) is kept, so the clips stay joined (module notes)."""
    worst = np.asarray(worst)
    clip_from, clip_to = np.asarray(clip_from), np.asarray(clip_to)
    tearing = worst > most
    for a, b in sorted({(int(x), int(y)) for x, y in zip(clip_from, clip_to) if x != y}):
        ways = np.flatnonzero((clip_from == a) & (clip_to == b))
        if tearing[ways].all():
            tearing[ways[np.argmin(worst[ways])]] = False
    return tearing
