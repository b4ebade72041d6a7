"""The skin a limb's turn strains, and the check that keeps it within what the capture shows
(issue 62).

A limb turned at its joints (:mod:`.limb_reach`) keeps every bone length, but the skin at a joint
is blended from the bones on both sides of it, and a turn the input never shows there can stretch
it as the rig never did: each joint within the range the input shows along each of its axes is
not the same as the combination the input shows (a horse's collapse splays its legs, and its
gallop's hips turned by 48° within those ranges tore the skin at the hip in 1 % of its frames).

So, at each frame, a limb's solution (:mod:`.limb_reach`: the turns that reach its targets) is
checked before its joints follow it: the edges the turn can strain (its **seams**,
:func:`limb_seams`: an edge whose two ends the turn does not carry as one rigid piece) are measured
against the capture's shape envelope (:mod:`..shape`: each edge's largest strain in the capture and
its fit, plus the margin). An edge the turn strains past that and past what the uncorrected frame
already has is a tear; where one limb's turn tears more than :data:`LIMB_TEAR` of its seams, the
turn is halved (every joint's, about its own point) up to :data:`HALVINGS` times, then let go:
the foot misses its target by what the turn no longer makes. The joints follow what is kept with
their bounded acceleration, so a cut turn is let go smoothly, over a few frames; cutting what they
apply instead popped (the dancer's worst acceleration rose from 1.39 to 2.1 times the input's).

Why :data:`LIMB_TEAR` is a thousandth of a limb's checked seams (one edge of 1,024): a seam a hair
past its envelope (a turn of a degree at a joint the capture holds at its extreme) should not cut a
plant; a limb's seams are at most a third of the mesh's edges (the samba's legs 9,120 and 9,814 of
its 29,907; the dancer's 5,527 and 4,284 of 21,177), so four limbs at that share stay far under what
breaks a frame (:data:`...mesh.shape.BROKEN_SHARE`, 0.5 %), with room for a splice's own strain. Measured
at 20 × 600, seed 3 (``benchmarks/synthesize.py``), every seam checked: on the horse's clips (its
gallop's hips turned by 48° after a plant of its collapse) 1.05 % of the frames were broken with no
check, 0.32 % with no seam allowed, 0.22 % with a thousandth, 0.40–0.51 % with 0.0025; the dancer,
the crane, the cow and the walker: no frame broken with or without it.

**The cost.** Checking every seam skins thousands of vertices a limb a frame: the samba's
``synthesize -n 100 -m 600`` took 26 s instead of 3. So only the seams spanning a joint the turn
leaves in a pose the input never shows are measured (:attr:`LimbSeams.masks`): a joint within
:data:`.limb_reach.RANGE_MARGIN` of a pose the input shows it in (:attr:`.limb_chains.JointRange.seen`)
or of its own uncorrected pose bends its skin as the capture or its fit bent it; a frame with no
such joint is not checked at all. And at most :data:`SEAM_EDGES` seams a limb are, evenly spaced
over them, so the share torn is kept: 5.6 s (2.9 s with ``--no-shape-check``, 2.8 s with
``--no-contact``); the horse's clips 0.40 % broken (0.22 % with every seam), the dancer's figures
the same. The 384 most blended seams instead missed the horse's hips (0.51 %) and cut the dancer's
turns ten times as often.
"""

from dataclasses import dataclass

import numba
import numpy as np

#: The share of a limb's checked seams its turn may strain past the capture's envelope before the
#: turn is cut (module notes).
LIMB_TEAR = 0.001
#: How many times a tearing turn is halved before it is let go (module notes).
HALVINGS = 3
#: Most seams checked per limb, evenly spaced over its seams (module notes, the cost).
SEAM_EDGES = 1024


@dataclass
class LimbSeams:
    """The edges each of L limbs' turns can strain (:func:`limb_seams`), padded with −1: vertices
    (L, S) their ends' ids; edges (L, E, 2) each edge's ends as places in its limb's ``vertices``;
    lengths (L, E) rest lengths (a zero one replaced by the mean edge's, with one (L, E) 0 there,
    as :func:`...mesh.shape.edge_strain` measures it); allowance (L, E) the envelope plus its margin;
    masks (L, E) the maps each edge's ends are carried by (bit 0 the body, bit i + 1 the limb's
    joint i): an edge spans joint i when it has both i's bit and its parent's (or the body's);
    budget (L,): how many of them each limb's turn may tear (``tear`` of its seams, rounded down)."""

    vertices: np.ndarray
    edges: np.ndarray
    lengths: np.ndarray
    one: np.ndarray
    allowance: np.ndarray
    budget: int
    masks: np.ndarray = None


def limb_seams(limb_joints, bone_joint, bone_indices, bone_weights, envelope, tear=LIMB_TEAR, most=SEAM_EDGES):
    """The :class:`LimbSeams` of limbs (limb_joints (L, n), −1 padded, as
    :meth:`.planting.PlantRig.limbs`) whose joints carry bones as bone_joint (B,) says (each bone's
    last joint, −1: none); bone_indices, bone_weights (V, K) the skin; envelope: the capture's
    :class:`...mesh.shape.ShapeEnvelope` (edges, rest_lengths, envelope, margin). A vertex moves with one
    joint's map when every bone weighing on it has that last joint in the limb (or none: the body);
    an edge is a seam when its ends are not carried by the same map. Of a limb's seams at most
    ``most`` are kept, evenly spaced in edge order (:data:`SEAM_EDGES`). tear: the share of the kept
    seams a turn may tear (:data:`LIMB_TEAR`)."""
    indices = np.asarray(bone_indices, dtype=np.int64)
    carried = np.asarray(bone_weights) > 0.0
    edges = np.asarray(envelope.edges, dtype=np.int64)
    rest = np.asarray(envelope.rest_lengths, dtype=np.float64)
    floor = max(float(rest.mean()) if rest.size else 1.0, 1e-300)
    allowance = np.asarray(envelope.envelope, dtype=np.float64) + float(envelope.margin)
    chosen, carried_by = [], []
    for joints in np.asarray(limb_joints, dtype=np.int64):
        mine = np.isin(bone_joint, joints[joints >= 0])
        maps = np.where(mine, bone_joint, -1)[indices]  # (V, K) each weight's map (−1: the body)
        place = np.full(max(int(np.max(bone_joint, initial=-1)) + 2, 1), 0, np.int64)  # a joint's bit: 1 + its place
        for i, k in enumerate(joints[joints >= 0]):
            place[k + 1] = i + 1
        bits = np.where(carried, np.left_shift(1, place[maps + 1]), 0)
        carried_by.append(np.bitwise_or.reduce(bits, axis=1))  # (V,) each vertex's maps
        first = maps[np.arange(len(maps)), np.argmax(carried, axis=1)]
        pure = np.all(~carried | (maps == first[:, None]), axis=1)
        carrier = np.where(pure, first, -2)  # −2: blended from several maps
        ends = carrier[edges]
        seams = np.flatnonzero((ends[:, 0] == -2) | (ends[:, 0] != ends[:, 1]))
        if seams.size > most:  # evenly spaced over the limb's seams, so the share torn is kept
            seams = seams[np.unique(np.linspace(0, seams.size - 1, most).round().astype(np.int64))]
        chosen.append(seams)
    count = max([1] + [s.size for s in chosen])
    L = len(chosen)
    vertices = np.full((L, 2 * count), -1, np.int64)
    local = np.full((L, count, 2), -1, np.int64)
    lengths, one, allow = np.ones((L, count)), np.zeros((L, count)), np.zeros((L, count))
    masks = np.zeros((L, count), np.int64)
    for l, seams in enumerate(chosen):
        masks[l, :seams.size] = carried_by[l][edges[seams, 0]] | carried_by[l][edges[seams, 1]]
        ids, places = np.unique(edges[seams], return_inverse=True)
        vertices[l, :ids.size] = ids
        local[l, :seams.size] = places.reshape(-1, 2)
        lengths[l, :seams.size] = np.where(rest[seams] > 0.0, rest[seams], floor)
        one[l, :seams.size] = (rest[seams] > 0.0).astype(np.float64)
        allow[l, :seams.size] = allowance[seams]
    return LimbSeams(vertices=vertices, edges=local, lengths=lengths, one=one, allowance=allow, masks=masks,
                     budget=np.floor(tear * np.array([s.size for s in chosen], dtype=np.float64)).astype(np.int64))


def no_seams(count):
    """The :class:`LimbSeams` of ``count`` limbs with nothing to check (no envelope): no seams."""
    none = np.full((count, 1), -1, np.int64)
    return LimbSeams(vertices=none, edges=np.repeat(none[..., None], 2, axis=2), lengths=np.ones(none.shape),
                     one=np.zeros(none.shape), allowance=np.zeros(none.shape), budget=np.zeros(count, np.int64),
                     masks=np.zeros(none.shape, np.int64))


@numba.njit(cache=True, nogil=True)
def _skin_vertex(F, t, a, m, v, rest, bone_indices, bone_weights, maps, A, g, turned, out):
    """out (3,): vertex v skinned by the frame's bones, each bone's part moved by its map's turn
    (maps (B,) the bone's place in A (n, 3, 3), g (n, 3), −1: none) where ``turned``."""
    for d in range(3):
        out[d] = 0.0
    for k in range(bone_indices.shape[1]):
        w = bone_weights[v, k]
        if w <= 0.0:
            continue
        bone = bone_indices[v, k]
        x0 = F[a, m, bone, 0, 0] * rest[v, 0] + F[a, m, bone, 0, 1] * rest[v, 1] + F[a, m, bone, 0, 2] * rest[v, 2] + t[a, m, bone, 0]
        x1 = F[a, m, bone, 1, 0] * rest[v, 0] + F[a, m, bone, 1, 1] * rest[v, 1] + F[a, m, bone, 1, 2] * rest[v, 2] + t[a, m, bone, 1]
        x2 = F[a, m, bone, 2, 0] * rest[v, 0] + F[a, m, bone, 2, 1] * rest[v, 1] + F[a, m, bone, 2, 2] * rest[v, 2] + t[a, m, bone, 2]
        i = maps[bone]
        if turned and i >= 0:
            y0 = A[i, 0, 0] * x0 + A[i, 0, 1] * x1 + A[i, 0, 2] * x2 + g[i, 0]
            y1 = A[i, 1, 0] * x0 + A[i, 1, 1] * x1 + A[i, 1, 2] * x2 + g[i, 1]
            y2 = A[i, 2, 0] * x0 + A[i, 2, 1] * x1 + A[i, 2, 2] * x2 + g[i, 2]
            x0, x1, x2 = y0, y1, y2
        out[0] += w * x0
        out[1] += w * x1
        out[2] += w * x2


@numba.njit(cache=True, nogil=True)
def _strain(points, a, b, length, one):
    x = points[a, 0] - points[b, 0]
    y = points[a, 1] - points[b, 1]
    z = points[a, 2] - points[b, 2]
    return abs(np.sqrt(x * x + y * y + z * z) / length - one)


@numba.njit(cache=True, nogil=True)
def seam_tears(F, t, a, m, A, g, maps, rest, bone_indices, bone_weights, vertices, edges, lengths, one, allowance,
               masks, sides, unseen, before, after, strain0, measured):
    """How many of a limb's seams (one limb's rows of :class:`LimbSeams`) its turn (A (n, 3, 3),
    g (n, 3), each joint's map; maps (B,) each bone's joint in it, −1: none) tears at frame m of
    animation a (F (A, M, B, 3, 3), t (A, M, B, 3) the frame as it is, not turned): strained past
    its allowance and past the frame's own strain. Only the seams spanning a joint of ``unseen``
    (bit i + 1: joint i; masks (E,) each seam's, sides (n,) the bits a seam spanning joint i has:
    its own and its parent's or the body's) are measured: a joint the turn leaves in a pose the
    input shows bends its skin as the capture does. before, after (S, 3), strain0 (E,): workspace;
    ``measured``: a second call at the same frame, whose own positions and strains found so far
    stay in before and strain0. Vertices are skinned only for the seams measured, and the frame's
    own only for those the turn strains past their allowance (NaN marks what is not yet known)."""
    S = 0
    while S < vertices.shape[0] and vertices[S] >= 0:
        S += 1
    E = 0
    while E < edges.shape[0] and edges[E, 0] >= 0:
        E += 1
    if not measured:
        for s in range(S):
            before[s, 0] = np.nan
        for e in range(E):
            strain0[e] = np.nan
    for s in range(S):
        after[s, 0] = np.nan
    torn = 0
    for e in range(E):
        spans = False
        for i in range(sides.shape[0]):
            if (unseen >> (i + 1)) & 1 and (masks[e] & sides[i]) == sides[i]:
                spans = True
                break
        if not spans:
            continue
        for end in range(2):
            s = edges[e, end]
            if np.isnan(after[s, 0]):
                _skin_vertex(F, t, a, m, vertices[s], rest, bone_indices, bone_weights, maps, A, g, True, after[s])
        strain = _strain(after, edges[e, 0], edges[e, 1], lengths[e], one[e])
        if strain <= allowance[e]:
            continue
        if np.isnan(strain0[e]):
            for end in range(2):
                s = edges[e, end]
                if np.isnan(before[s, 0]):
                    _skin_vertex(F, t, a, m, vertices[s], rest, bone_indices, bone_weights, maps, A, g, False,
                                 before[s])
            strain0[e] = _strain(before, edges[e, 0], edges[e, 1], lengths[e], one[e])
        if strain > strain0[e]:
            torn += 1
    return torn
