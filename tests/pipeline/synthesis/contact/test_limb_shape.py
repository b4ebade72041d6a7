"""A limb's turn kept to the shapes the capture shows (issue 62:
:mod:`skinsynth.pipeline.synthesis.contact.limb_shape`): on a generated leg with exact joints and a
skin blended at its joints, the seams are the edges a turn can strain, and a turn that would strain
them past the capture's envelope is cut, in the compiled plant loop, while one within it is kept."""

import numpy as np

from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.synthesis.contact.limb_shape import limb_seams, seam_tears
from skinsynth.pipeline.mesh.shape import ShapeEnvelope, edge_strain

from test_limb_reach import _leg_pose, _reach, _sole

#: Rings of four vertices up the leg: (height, {bone: weight}); bones 0 body, 1 thigh, 2 shin, 3 foot.
RINGS = ((1.1, {0: 1.0}), (1.0, {0: 0.5, 1: 0.5}), (0.75, {1: 1.0}), (0.55, {1: 1.0}), (0.5, {1: 0.5, 2: 0.5}),
         (0.45, {2: 1.0}), (0.25, {2: 1.0}), (0.08, {2: 0.5, 3: 0.5}), (0.03, {3: 1.0}))
#: The rings blended from two bones (at the hip, knee and ankle).
BLENDED = (1, 4, 7)
BONE_JOINT = np.array([-1, 0, 1, 2])  # each bone's last joint: the body none, thigh hip, shin knee, foot ankle
LIMB = np.array([[0, 1, 2]])


def _leg_skin():
    """rest (V, 3), bone_indices, bone_weights (V, 2), edges (E, 2): each ring's four sides and the
    edges from each of its vertices to the same one of the next ring."""
    corners = np.array([[0.04, 0.0, 0.04], [-0.04, 0.0, 0.04], [-0.04, 0.0, -0.04], [0.04, 0.0, -0.04]])
    rest, indices, weights, edges = [], [], [], []
    for r, (height, carried) in enumerate(RINGS):
        for c in range(4):
            rest.append(corners[c] + [0.0, height, 0.0])
            bones = sorted(carried)
            indices.append((bones + bones)[:2])
            weights.append(([carried[b] for b in bones] + [0.0])[:2])
            edges.append((4 * r + c, 4 * r + (c + 1) % 4))
            if r + 1 < len(RINGS):
                edges.append((4 * r + c, 4 * (r + 1) + c))
    return np.array(rest), np.array(indices, np.int64), np.array(weights), np.array(edges, np.int64)


def _envelope(F, t, skin, margin=0.02):
    """The capture's envelope when it shows only the pose F, t (every frame the same)."""
    rest, indices, weights, edges = skin
    lengths = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)
    strain = edge_strain(lbs_reference(rest, indices, weights, F[0].astype(np.float64), t[0].astype(np.float64))[:1], edges, lengths)[0]
    return ShapeEnvelope(edges=edges, rest_lengths=lengths, envelope=strain, margin=margin)


def test_the_seams_are_the_edges_at_the_limbs_blended_joints():
    skin = _leg_skin()
    rest, indices, weights, edges = skin
    F, t = _leg_pose(1)
    seams = limb_seams(LIMB, BONE_JOINT, indices, weights, _envelope(F, t, skin))
    ring = edges // 4
    expected = np.flatnonzero(np.isin(ring, BLENDED).any(axis=1))  # every edge touching a blended ring
    found = seams.vertices[0][seams.edges[0][seams.edges[0, :, 0] >= 0]]
    assert {tuple(e) for e in found} == {tuple(e) for e in edges[expected]}
    assert seams.budget[0] == np.floor(1e-3 * expected.size)
    few = limb_seams(LIMB, BONE_JOINT, indices, weights, _envelope(F, t, skin), most=9)  # at most 9, evenly spaced
    kept = few.vertices[0][few.edges[0][few.edges[0, :, 0] >= 0]]
    np.testing.assert_array_equal(kept, edges[expected[np.linspace(0, expected.size - 1, 9).round().astype(int)]])
    # each seam measured against its own envelope plus the margin; the rest lengths kept
    where = {tuple(e): i for i, e in enumerate(edges)}
    places = [where[tuple(e)] for e in found]
    np.testing.assert_allclose(seams.lengths[0, :len(places)],
                               np.linalg.norm(rest[edges[places, 0]] - rest[edges[places, 1]], axis=1))
    # a turn of the whole limb about the hip strains no edge below it: only the hip's ring can tear
    turn = np.array([[[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]] * 3)  # 90° about x, at every joint's map
    hip = F[0, 0, 0].astype(np.float64) @ np.array([0.0, 1.0, 0.0]) + t[0, 0, 0]
    g = np.repeat((hip - turn[0] @ hip)[None], 3, axis=0)
    # each seam's maps: the hip's ring the body's and the hip's (bits 0, 1), the knee's the hip's and the knee's, …
    masks = dict(zip(map(tuple, found), seams.masks[0, :len(found)]))
    for e in edges[expected]:
        rings = set(np.asarray(e) // 4)
        spanned = {1: 0b11, 4: 0b110, 7: 0b1100}[next(r for r in rings if r in BLENDED)]
        assert masks[tuple(e)] == spanned, (e, masks[tuple(e)])
    S, E = seams.vertices.shape[1], seams.edges.shape[1]
    sides = np.array([0b11, 0b110, 0b1100])  # the bits a seam spanning the hip, knee, ankle has

    def torn(unseen):
        return seam_tears(F.astype(np.float64), t.astype(np.float64), 0, 0, turn, g, BONE_JOINT, rest, indices, weights,
                          seams.vertices[0], seams.edges[0], seams.lengths[0], seams.one[0], seams.allowance[0],
                          seams.masks[0], sides, unseen, np.empty((S, 3)), np.empty((S, 3)), np.empty(E), False)

    touching_hip = np.isin(ring[expected], [1]).any(axis=1).sum()
    assert 0 < torn(0b1110) <= touching_hip
    assert torn(0b10) == torn(0b1110)  # only the hip's seams can tear: measuring them alone finds the same
    assert torn(0b1100) == 0 and torn(0) == 0  # the knee's and ankle's seams are not strained


def test_a_turn_that_would_tear_the_knee_is_cut_and_one_within_the_envelope_is_kept():
    """The foot raised by a third of the leg: the knee must bend a radian further than the capture
    ever shows, which creases its blended ring. Allowed to tear (a budget of every seam), the leg
    reaches and the seams are strained past the envelope; kept to it, the turn is cut, no seam is
    past it, and the foot misses its target (it slides a little, the body stays whole). A small
    shift that strains nothing past the envelope is made in full."""
    skin = _leg_skin()
    rest, indices, weights, edges = skin
    frames = 20
    F0, t0 = _leg_pose(frames)
    envelope = _envelope(F0, t0, skin)
    raise_foot = np.broadcast_to([0.0, 0.3, 0.1], (frames, 3))
    allowed = limb_seams(LIMB, BONE_JOINT, indices, weights, envelope, tear=1.0)
    kept = limb_seams(LIMB, BONE_JOINT, indices, weights, envelope, tear=0.0)

    def past(F, t):
        strain = edge_strain(lbs_reference(rest, indices, weights, F[0].astype(np.float64), t[0].astype(np.float64)), edges, envelope.rest_lengths)
        return (strain > envelope.envelope + envelope.margin + 1e-5).sum(axis=1)

    before = _sole(F0, t0)
    F, t = F0.copy(), t0.copy()
    _, cut = _reach(F, t, raise_foot, skin=(rest, indices, weights, allowed))
    assert cut.sum() == 0 and past(F, t).min() > 4  # torn: the check is not vacuous
    np.testing.assert_allclose(_sole(F, t)[-1] - before[-1], raise_foot[-1], atol=0.02)

    F, t = F0.copy(), t0.copy()
    _, cut = _reach(F, t, raise_foot, skin=(rest, indices, weights, kept))
    assert cut.sum() == frames and past(F, t).max() == 0  # cut at every frame; never past the envelope
    miss = np.linalg.norm(_sole(F, t)[-1] - before[-1] - raise_foot[-1])
    assert miss > 0.05  # the foot slides rather than the knee tearing

    F, t = F0.copy(), t0.copy()
    small = np.broadcast_to([0.0, 0.0, 0.004], (frames, 3))
    _, cut = _reach(F, t, small, skin=(rest, indices, weights, kept))
    assert cut.sum() == 0 and past(F, t).max() == 0
    np.testing.assert_allclose(_sole(F, t)[-1] - before[-1], small[-1], atol=4e-4)
