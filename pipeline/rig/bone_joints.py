"""Where two bones of a free fit meet, and the joint they turn about (Le & Deng 2014, §4): the floor
under ``fit-skin --skeleton``'s hierarchy (:mod:`skinsynth.pipeline.skin.joints`) and the limbs a
synthesis's plants turn (:mod:`skinsynth.pipeline.synthesis.contact.limb_chains`).

A free fit moves every bone on its own: ``x ↦ R_j(f) x + t_j(f)`` from the rest pose. Two bones that
meet at a joint carry the joint's rest point p to the same place in every frame, so the joint is the
point that moves least relative to both bones:

    p_jk = argmin_p  Σ_f ‖(R_j(f) − R_k(f)) p + t_j(f) − t_k(f)‖² / F  +  (p − c_jk)ᵀ Q (p − c_jk)

(least squares, one 3×3 solve per pair). The data term A = Σ_f D_fᵀ D_f / F alone leaves a hinge's
axis free (the rotation differences have rank 2) and a pair that never bends free in every
direction, so a pull Q towards ``c_jk``, the centre of the region where the two bones meet, picks
the point on that axis nearest it (Le & Deng pull the joint towards the bones' shared vertices too).
The pull is a prior with the data's own noise, not a fixed share: with σ² the mean squared drift of
the data's own answer (a ridge of 1e-9) and s a priori how far a joint lies from where its bones
meet (``spread``, default 5 % of the rest diagonal),

    Q = σ²/s² · ((I − A/λ_max) + JOINT_FLOOR · I)

so it acts along the directions the pair bends in much less than its main bend (a hinge's axis: 0.3 %
of it on the horse's legs), little across them, and not at all on exact data: the walker's true
bones give its true joints to 1e-15 (an isotropic pull of 1 % of the bend moved its ankles by 0.4 %
of its height). The floor places the joint of two bones that hardly bend at all (a torso that moves
as one) at ``c_jk``.

Which bones meet (:func:`bone_neighbours`): those whose dominated vertices share a mesh edge, or that
share weight (Σ_i min(w_ij, w_ik) at least :data:`MIN_SHARE` of the lighter bone's: the skin blends
them; the walker's limbs are tubes of their own, tied to the torso by weights alone). ``c_jk`` is the
centroid of that region: the shared vertices weighted by min(w_ij, w_ik), each boundary edge's
midpoint by ½. The joint's **drift** (:func:`joint_drift`) is its RMS distance apart over the
frames, ‖(R_j − R_k) p + t_j − t_k‖: zero for bones that truly hinge there.

**Which joints a tree keeps** (:func:`spanning_cost`): the spanning tree over the joints' drift
prefers, before any drift, the pairs that share at least :data:`MIN_JOINT_SHARE` of the lighter
bone's skin. A free fit gives a few vertices small weights of far bones, so bones that merely brush
become neighbours, and two such bones can hold a joint by chance: a generated humanoid's two thighs
swing about one hip axis, so a point on it drifts as little between them (0.11 % of the diagonal)
as at either hip; Zheng's dancer's chest bone held to an upper arm (0.38 % of the diagonal, 0.39 %
of the lighter's skin shared) better than to the spine below it. The tree then ran thigh → thigh →
pelvis, spine → arm. A joint is where two bones *blend*: on every capture the joints of the trees
kept share 1.3–50 % of the lighter bone's skin (the walker's weak ties 1.3–2.5 %, by design the
least), the chance pairs that displaced them 0.1–0.8 %. Only where the shared pairs leave a part
unjoined does a brushing pair join it (by drift, as before): a character whose limbs are tied by
nothing but weak skin keeps its tree.
"""

import numpy as np

from ..mesh.geometry import mesh_edges
from .influence import weight_sums

#: How far a joint may lie from where its two bones meet, a priori, as a share of the rest
#: diagonal (module notes: the pull).
JOINT_SPREAD = 0.05
#: Shared weight that makes two bones neighbours without a mesh edge between their regions, as a
#: share of the lighter bone's total weight (module notes).
MIN_SHARE = 0.001
#: The pull in every direction, as a share of the pull along a hinge's axis: what places the
#: joint of two bones that never bend (module notes).
JOINT_FLOOR = 0.01
#: Largest drift (RMS over frames, share of the rest diagonal) of a joint that holds: ``fit-skin
#: --skeleton``'s fixed joints, and the joints a synthesis's plants turn a limb at. A soft body's
#: bones drift 3–6 % of its diagonal apart at the points they share best (the elastic cow), a
#: dancer's 0.03–0.5 %.
MAX_JOINT_DRIFT = 0.02
#: Skin two bones share (Σ_i min(w_ij, w_ik), a share of the lighter bone's Σ_i w_ij) below which
#: their joint joins a tree only where no pair sharing more does (module notes: which joints a tree keeps).
MIN_JOINT_SHARE = 0.01


def bone_neighbours(rest, faces, bone_indices, bone_weights, bones, min_share=None):
    """Bones that meet, where and how much: (pairs (P, 2) int64 with j < k, centres (P, 3), contact
    (P,): the skin they share, Σ_i min(w_ij, w_ik) plus ½ per mesh edge between their regions).

    rest (V, 3), faces (T, 3), bone_indices (V, K), bone_weights (V, K). Module notes: a mesh
    edge between vertices that the two bones dominate, or shared weight Σ_i min(w_ij, w_ik) of at
    least ``min_share`` (default :data:`MIN_SHARE`) of the lighter bone's Σ_i w_ij."""
    min_share = MIN_SHARE if min_share is None else min_share
    rest = np.asarray(rest, dtype=np.float64)
    indices, weights = np.asarray(bone_indices, dtype=np.int64), np.asarray(bone_weights, dtype=np.float64)
    mass = np.zeros((bones, bones))
    moment = np.zeros((bones, bones, 3))
    slots = indices.shape[1]
    for a in range(slots):  # K(K−1)/2 slot pairs, each over every vertex at once
        for b in range(a + 1, slots):
            share = np.minimum(weights[:, a], weights[:, b])
            use = (share > 0.0) & (indices[:, a] != indices[:, b])
            j, k = np.minimum(indices[use, a], indices[use, b]), np.maximum(indices[use, a], indices[use, b])
            np.add.at(mass, (j, k), share[use])
            np.add.at(moment, (j, k), share[use, None] * rest[use])
    dominant = indices[np.arange(len(indices)), np.argmax(weights, axis=1)]
    edges = mesh_edges(np.asarray(faces, dtype=np.int64))
    edges = edges[dominant[edges[:, 0]] != dominant[edges[:, 1]]]
    j, k = np.minimum(dominant[edges[:, 0]], dominant[edges[:, 1]]), np.maximum(dominant[edges[:, 0]], dominant[edges[:, 1]])
    totals = weight_sums(indices, weights, bones)
    shared = mass > min_share * np.minimum(totals[:, None], totals[None, :])
    np.add.at(mass, (j, k), 0.5)
    np.add.at(moment, (j, k), 0.25 * (rest[edges[:, 0]] + rest[edges[:, 1]]))
    touching = np.zeros((bones, bones), dtype=bool)
    touching[j, k] = True
    j, k = np.nonzero(np.triu(shared | touching, 1))
    return np.stack([j, k], axis=1).astype(np.int64), moment[j, k] / mass[j, k, None], mass[j, k]


def joint_positions(rotations, translations, pairs, centres, spread, floor=JOINT_FLOOR):
    """Each pair's joint in the rest pose and its drift: (joints (P, 3), drift (P,)).

    rotations (F, B, 3, 3), translations (F, B, 3): the free bones; pairs (P, 2); centres (P, 3)
    where each pair meets; spread: how far from its meeting centre a joint may be a priori, in
    the mesh's units (module notes: the pull). drift: RMS over the frames of the joint's two
    images' distance, in the mesh's units."""
    R, t = np.asarray(rotations, dtype=np.float64), np.asarray(translations, dtype=np.float64)
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    centres = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
    D = R[:, pairs[:, 0]] - R[:, pairs[:, 1]]  # (F, P, 3, 3)
    d = t[:, pairs[:, 0]] - t[:, pairs[:, 1]]  # (F, P, 3)
    frames = R.shape[0]
    normal = np.einsum("fpij,fpik->pjk", D, D) / frames
    right = -np.einsum("fpij,fpi->pj", D, d) / frames
    largest = np.linalg.eigvalsh(normal)[:, -1] if len(pairs) else np.zeros(0)

    def solve(pull):
        return np.linalg.solve(normal + pull, (right[..., None] + pull @ centres[..., None]))[..., 0]

    eye = np.eye(3)
    # The data's own answer (a ridge of 1e-9 of the bend), its residual drift is the noise σ.
    least = solve((1e-9 * largest + 1e-300)[:, None, None] * eye)
    noise = joint_drift(R, t, pairs, least) ** 2
    weak = eye - normal / np.maximum(largest, 1e-300)[:, None, None]  # 1 along a hinge's axis, 0 across it
    pull = (noise / spread ** 2)[:, None, None] * (weak + floor * eye) + 1e-12 * eye
    joints = solve(pull)
    return joints, joint_drift(R, t, pairs, joints)


def joint_drift(rotations, translations, pairs, joints):
    """drift (P,): RMS over the frames of ‖(R_j − R_k) p + t_j − t_k‖ for each pair (j, k) of
    ``pairs`` (P, 2) and its joint p (``joints`` (P, 3)), in the mesh's units."""
    R, t = np.asarray(rotations, dtype=np.float64), np.asarray(translations, dtype=np.float64)
    gap = (np.einsum("fpij,pj->fpi", R[:, pairs[:, 0]] - R[:, pairs[:, 1]], joints)
           + t[:, pairs[:, 0]] - t[:, pairs[:, 1]])
    return np.sqrt(np.mean(np.sum(gap ** 2, axis=2), axis=0))


def spanning_cost(pairs, drift, contact, mass, min_share=MIN_JOINT_SHARE):
    """cost (P,): the order in which a spanning tree takes the pairs (P, 2) (module notes): their
    ``drift`` (P,), every pair sharing less than ``min_share`` of the lighter bone's ``mass`` (B,)
    (``contact`` (P,): :func:`bone_neighbours`) after every pair sharing more. Kruskal's algorithm
    over it takes the sharing pairs' tree first and joins what they leave apart by the others."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    drift = np.asarray(drift, dtype=np.float64)
    mass = np.asarray(mass, dtype=np.float64)
    lighter = np.minimum(mass[pairs[:, 0]], mass[pairs[:, 1]])
    brushing = np.asarray(contact, dtype=np.float64) < min_share * lighter
    return drift + brushing * (float(drift.max(initial=0.0)) + 1.0)
