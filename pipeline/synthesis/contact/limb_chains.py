"""The joints a plant's correction turns: each contact patch's limb, from the foot up to where the
limb meets the body, and the range each of those joints shows in the input (issue 62).

A correction that moves bones as a skeleton moves keeps the body whole: the foot's subtree turns
about the ankle, the shin's about the knee, the thigh's about the hip, and what lies on the body's
side of each joint does not move. Two bones on either side of a turning joint then carry the
joint's point to the same place, so the skin between them bends as the rig itself bends it, where
a shift of one bone against its neighbour shears it (the corrections before this one tore the
dancer's torso in 69 % of its synthesized frames).

**The tree** is the skin's joint tree, rooted where the body balances
(:mod:`skinsynth.pipeline.rig.joint_tree`): a jointed skin's own, or a free fit's, found from its
joints as ``fit-skin --skeleton`` finds them.

**A limb** is the chain of joints from a patch's bone towards the body while the part beyond the
joint (the foot's side, :func:`limb_side`) carries at most :data:`LIMB_SHARE` of the skin and no
other limb's patch: two legs joined by a skirt (the samba's: 122 units of skin between one thigh and
the other leg) turn at the knee and the ankle, not at a hip that would take the other leg along, nor
at one cut through the skirt (which tore it in 2 % of the samba's frames). A human leg is 14–17 % of
the dancer's and the samba's skin, a horse's 5–8 %; the next joint up takes in the trunk or the
other leg (47 % on the dancer), so a third separates limbs from the body for people and animals
alike.

**A foot** is a patch at the far end of its limb: its rest centroid at least :data:`FOOT_REACH` of
the limb's reach from the limb's top joint. Feet lie at 0.93–0.97 of it (the dancer's, the samba's,
the crane's, the walker's, the horse's hooves); a patch on the body itself lies nearer (a horse lying
on its side: its flank, its neck at 0.40–0.76, where turning the part that carries it tore the body
in 2 % of the frames of its collapse). A patch that is no foot gets no limb, and is held by the
root's shift alone.
"""

from dataclasses import dataclass

import numpy as np

from ...rig.joint_tree import in_tree, is_below, tree_depth

#: Largest share of the skin the part beyond a limb's joint may carry (module notes: a limb).
LIMB_SHARE = 1.0 / 3.0
#: How far from its limb's top joint a patch's rest centroid must lie, as a share of the limb's reach
#: (its farthest vertex), to be a foot the limb turns to hold (module notes: a foot).
FOOT_REACH = 0.85
#: Most input frames whose joint poses :attr:`JointRange.seen` keeps (evenly spaced past them): what
#: a limb's turn is compared with before its skin is checked (:mod:`.limb_shape`).
SEEN_FRAMES = 512


@dataclass
class JointRange:
    """The turns each of K joints shows in the input (module notes). mean (K, 3, 3) Q̄; axes
    (K, 3, 3) the principal axes of log(Q̄ᵀ Q) as columns; spread (K, 3) its standard deviation
    along each, radians; low, high (K, 3) its least and largest coordinate along each; seen (K, S, 3)
    its coordinates in S of the input's frames (every frame up to :data:`SEEN_FRAMES`, evenly
    spaced past them): the poses the input shows it in, not only their ranges."""

    mean: np.ndarray
    axes: np.ndarray
    spread: np.ndarray
    low: np.ndarray
    high: np.ndarray
    seen: np.ndarray = None


@dataclass
class LimbChains:
    """The joints the plants turn (module notes). K joints, each named by its limb-side bone:
    bone (K,) that bone, body (K,) its parent (the body side), point (K, 3) the joint's rest
    position, parent (K,) the next joint towards the body on the same chain (−1: the chain's top),
    parents before children; reach (K,) how far the limb beyond it extends from the joint (the
    farthest rest vertex it carries, weighted); ranges (a :class:`JointRange` of the K joints).
    bone_joint (B,): the last joint of a chain whose limb side holds each bone (−1: none, it moves
    with the body); patch_joint (P,): each patch's last joint (−1: no limb); limb_bones (P,) lists:
    the bones each patch's limb moves."""

    bone: np.ndarray
    body: np.ndarray
    point: np.ndarray
    parent: np.ndarray
    reach: np.ndarray
    ranges: JointRange
    bone_joint: np.ndarray
    patch_joint: np.ndarray
    limb_bones: list

    @property
    def joints(self):
        return self.bone.size


def limb_chains(parents, mass, anchors, pairs, contact, limb_share=LIMB_SHARE):
    """The chains of a tree rooted at the body (parents (B,); mass (B,) the bones'
    weight sums) for patches carried by ``anchors`` (P,) bones: from each anchor up, every joint
    whose limb side carries at most ``limb_share`` of the skin and no other anchor (module notes),
    its limb side cut from the body where the bones share least skin (:func:`limb_side`; pairs
    (N, 2), contact (N,): the bones that meet and the skin they share). Returns (bone (K,), body (K,), parent (K,),
    moved (K, B) bool: each joint's limb side), joints nearest the body first."""
    parents = np.asarray(parents, dtype=np.int64)
    mass = np.asarray(mass, dtype=np.float64)
    inside = in_tree(parents)
    root = int(np.flatnonzero(inside & (parents < 0))[0])
    total = float(mass[inside].sum())
    paths = []
    for anchor in np.asarray(anchors, dtype=np.int64):
        path, bone = [], int(anchor)
        while bone >= 0 and inside[bone] and parents[bone] >= 0:
            path.append(bone)
            bone = int(parents[bone])
        paths.append(path)  # the joints' limb-side bones, from the foot up
    moved = {}  # bone → its joint's limb side, the deepest first so each side holds those below it
    stopped = set()
    anchors = [int(a) for a in np.asarray(anchors, dtype=np.int64) if a >= 0]
    for bone in sorted({b for path in paths for b in path}, key=lambda b: -tree_depth(parents, b)):
        below = [side for b, side in moved.items() if is_below(parents, b, bone)]
        others = [a for a in anchors if not is_below(parents, a, bone)]  # another limb's feet
        side = limb_side(bone, int(parents[bone]), root, below, pairs, contact, parents.size)
        if mass[side].sum() > limb_share * total or np.isin(others, side).any():
            stopped.add(bone)
        else:
            moved[bone] = side
    order = []
    for path in paths:  # each path's joints up to the first whose limb side is too heavy
        for bone in path:
            if bone in stopped:
                break
            if bone not in order:
                order.append(bone)
    order.sort(key=lambda b: (tree_depth(parents, b), b))
    slot = {bone: k for k, bone in enumerate(order)}
    bone_ids = np.array(order, dtype=np.int64)
    parent = np.full(len(order), -1, dtype=np.int64)
    for k, bone in enumerate(order):  # the next joint of the chain towards the body
        up = int(parents[bone])
        while up >= 0 and up not in slot:
            up = int(parents[up])
        parent[k] = slot.get(up, -1)
    sides = np.zeros((len(order), parents.size), dtype=bool)
    for k, bone in enumerate(order):
        sides[k, moved[bone]] = True
    return bone_ids, parents[bone_ids], parent, sides


def limb_side(bone, body, root, below, pairs, contact, bones):
    """(n,) the bones a joint between ``body`` and ``bone`` turns: those on ``bone``'s side of the
    cut through the least shared skin (pairs (N, 2), contact (N,)) that separates ``bone`` and the
    limb sides ``below`` it (lists of bones) from ``body`` and the ``root``. Two bones that split
    one limb between them (the dancer's calf, front and back: 209 units of skin shared, against 66
    with the thigh) turn together, where the tree hangs one from the thigh beside the other."""
    import networkx as nx

    graph = nx.DiGraph()
    graph.add_nodes_from(range(bones))
    for (j, k), c in zip(np.asarray(pairs, dtype=np.int64), np.asarray(contact, dtype=np.float64)):
        graph.add_edge(int(j), int(k), capacity=float(c))
        graph.add_edge(int(k), int(j), capacity=float(c))
    for b in {int(bone), *(int(x) for side in below for x in side)}:
        graph.add_edge("limb", b)  # no capacity: never cut
    for b in {int(body), int(root)}:
        graph.add_edge(b, "body")
    _, (limb, _) = nx.minimum_cut(graph, "limb", "body")
    return np.array(sorted(b for b in limb if b != "limb"), dtype=np.int64)


def parent_top(parent, k):
    """The top of joint k's chain (parent (K,): the next joint towards the body, −1 at a top)."""
    while parent[k] >= 0:
        k = int(parent[k])
    return k


def joint_ranges(rotations, body, bone):
    """The :class:`JointRange` of the joints between bones ``body`` (K,) and ``bone`` (K,), over
    the fit's rotations (F, B, 3, 3) (module notes)."""
    from ...rig.rotations import polar_rotation, rotation_log

    R = np.asarray(rotations, dtype=np.float64)
    relative = np.einsum("fkyx,fkyz->fkxz", R[:, body], R[:, bone])  # R_pᵀ R_b (F, K, 3, 3)
    mean = polar_rotation(relative.sum(axis=0)) if len(body) else np.zeros((0, 3, 3))
    logs = rotation_log(np.einsum("kyx,fkyz->fkxz", mean, relative))  # (F, K, 3)
    covariance = np.einsum("fki,fkj->kij", logs, logs) / max(R.shape[0], 1)
    values, axes = np.linalg.eigh(covariance)  # ascending
    coordinates = np.einsum("kij,fki->fkj", axes, logs)
    frames = np.unique(np.linspace(0, max(R.shape[0] - 1, 0), min(R.shape[0], SEEN_FRAMES)).round().astype(np.int64))
    return JointRange(mean=mean, axes=axes, spread=np.sqrt(np.maximum(values, 0.0)),
                      low=coordinates.min(axis=0), high=coordinates.max(axis=0),
                      seen=np.ascontiguousarray(coordinates[frames].transpose(1, 0, 2)))


def plant_chains(tree, anchors, centres, rotations, rest, bone_indices, bone_weights, limb_share=LIMB_SHARE,
                 foot_reach=FOOT_REACH):
    """The :class:`LimbChains` of a skin's joint tree (a :class:`~skinsynth.pipeline.rig.joint_tree.JointTree`,
    rooted where the body balances) for the patches carried by ``anchors`` (P,), their rest centroids
    ``centres`` (P, 3): each foot's limb (:func:`limb_chains`; a patch whose centroid lies nearer its
    limb's top joint than ``foot_reach`` of the limb's reach is no foot, and gets none: module
    notes), its joints' reach (the farthest rest vertex (V, 3) whose heaviest bone they turn, at
    least a hundredth of the rest diagonal) and their ranges over the fit's rotations (F, B, 3, 3)."""
    anchors = np.asarray(anchors, dtype=np.int64)
    chains = _chains(tree, anchors, rest, bone_indices, bone_weights, limb_share)
    feet = np.array([k >= 0 and np.linalg.norm(np.asarray(c) - chains.point[parent_top(chains.parent, k)])
                     >= foot_reach * chains.reach[parent_top(chains.parent, k)]
                     for k, c in zip(chains.patch_joint, centres)], dtype=bool)
    if not feet.all():  # again, for the feet alone: another patch is no foot a limb must leave behind
        chains = _chains(tree, np.where(feet, anchors, -1), rest, bone_indices, bone_weights, limb_share)
    chains.ranges = joint_ranges(rotations, chains.body, chains.bone)
    return chains


def _chains(tree, anchors, rest, bone_indices, bone_weights, limb_share):
    """:func:`plant_chains` for ``anchors`` (−1: a patch with no limb), its ranges left empty."""
    from ...mesh.geometry import bounding_box_diagonal

    rest = np.asarray(rest, dtype=np.float64)
    bones = tree.parents.size
    bone, body, parent, sides = limb_chains(tree.parents, tree.mass, anchors, tree.pairs, tree.contact, limb_share)
    bone_joint = np.full(bones, -1, dtype=np.int64)
    for k in range(bone.size):  # parents first: a bone's last joint is the deepest whose side holds it
        bone_joint[sides[k]] = k
    patch_joint = np.array([bone_joint[a] if a >= 0 else -1 for a in anchors], dtype=np.int64)
    point = tree.joints[bone].reshape(-1, 3)
    heaviest = np.asarray(bone_indices)[np.arange(rest.shape[0]), np.argmax(np.asarray(bone_weights), axis=1)]
    floor = 0.01 * bounding_box_diagonal(rest)
    reach = np.array([max(floor, float(np.linalg.norm(rest[sides[k][heaviest]] - point[k], axis=1).max(initial=0.0)))
                      for k in range(bone.size)])
    limb_bones = [np.flatnonzero(sides[parent_top(parent, k)]) if k >= 0 else np.zeros(0, np.int64) for k in patch_joint]
    return LimbChains(bone=bone, body=body, point=point, parent=parent, reach=reach, ranges=None,
                      bone_joint=bone_joint, patch_joint=patch_joint, limb_bones=limb_bones)
