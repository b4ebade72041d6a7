"""The joint tree of a skin: which bone hangs from which, at which joint, rooted where the body balances.

A jointed skin (``fit-skin --skeleton``) brings its own tree. A free fit has none, so one is found
as ``fit-skin --skeleton`` finds it (:mod:`.bone_joints`): the bones that meet (share skin or a mesh
edge), each pair's joint (the point the two bones carry most nearly to the same place over the
input frames), and the spanning tree of the pairs whose joints drift least, those that barely share
skin last (:func:`free_fit_tree`, :func:`.bone_joints.spanning_cost`).
Bones no pair joins to the tree (a prop) stay out of it.

**The body** is where the tree balances: the bone whose removal leaves no part heavier than half
the skin (:func:`balance_bone`; weight sums, so a bone's share of the skin). It does not depend on
which bone the tree was rooted at, nor on the bone count: a human's balance is in the trunk and a
horse's in its barrel, wherever the fit put its heaviest bone (the held-out jumping person's
heaviest bone is a shin). :func:`skin_joint_tree` roots the tree there.

What uses it: a synthesis's plants turn limbs at these joints
(:mod:`skinsynth.pipeline.synthesis.contact.limb_chains`).
"""

from dataclasses import dataclass

import numpy as np

from .influence import weight_sums


@dataclass
class JointTree:
    """A skin's joint tree (module notes): parents (B,) int64, −1 at the root and at the bones left out;
    joints (B, 3) each bone's joint with its parent, at rest; pairs (N, 2) the bones that meet and
    contact (N,) the skin each pair shares (:func:`.bone_joints.bone_neighbours`); mass (B,) the
    bones' weight sums."""

    parents: np.ndarray
    joints: np.ndarray
    pairs: np.ndarray
    contact: np.ndarray
    mass: np.ndarray

    @property
    def root(self):
        return int(np.flatnonzero(in_tree(self.parents) & (self.parents < 0))[0])


def skin_joint_tree(rest, faces, bone_indices, bone_weights, rotations, translations, skeleton=None):
    """The :class:`JointTree` of a skin (rest (V, 3), faces, weights (V, K), the fit's rotations
    (F, B, 3, 3) and translations (F, B, 3)): a jointed skin's own (``skeleton``: its (parents,
    joints)), or a free fit's (:func:`free_fit_tree`), rooted where it balances (:func:`balance_bone`)."""
    from ..mesh.geometry import bounding_box_diagonal
    from .bone_joints import JOINT_SPREAD, bone_neighbours, joint_positions, spanning_cost

    rest = np.asarray(rest, dtype=np.float64)
    bones = np.asarray(rotations).shape[1]
    pairs, centres, contact = bone_neighbours(rest, faces, bone_indices, bone_weights, bones)
    mass = weight_sums(bone_indices, bone_weights, bones)
    if skeleton is None:
        points, drift = joint_positions(rotations, translations, pairs, centres, JOINT_SPREAD * bounding_box_diagonal(rest))
        parents, joints = free_fit_tree(pairs, points, spanning_cost(pairs, drift, contact, mass), bones)
    else:
        parents, joints = (np.asarray(a) for a in skeleton)
    parents, joints = rooted_at(parents, joints, balance_bone(parents, mass))
    return JointTree(parents=parents, joints=joints, pairs=pairs, contact=contact, mass=mass)


def free_fit_tree(pairs, points, drift, bones):
    """(parents (B,) with −1 at the root and at bones left out, joints (B, 3) each bone's joint with
    its parent) of a free fit's ``bones``: the spanning tree of the bones that meet (pairs (N, 2),
    their joints, points (N, 3): :mod:`.bone_joints`) whose joints drift least (drift (N,), or any
    cost: :func:`.bone_joints.spanning_cost`), rooted
    at its largest part's lowest bone (:func:`rooted_at` moves it). A bone no pair reaches has
    parent −1 besides the root."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree

    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    drift = np.asarray(drift, dtype=np.float64)
    # +1 keeps a zero drift an edge (scipy reads 0 as none); ties go as scipy orders them (deterministic)
    graph = coo_matrix((drift / max(float(drift.max(initial=0.0)), 1e-300) + 1.0, (pairs[:, 0], pairs[:, 1])),
                       shape=(bones, bones)).tocsr()
    forest = minimum_spanning_tree(graph)
    forest = forest + forest.T
    _, labels = connected_components(forest, directed=False)
    sizes = np.bincount(labels)
    root = int(np.flatnonzero(labels == np.argmax(sizes))[0])  # the largest part's lowest bone
    order, predecessors = breadth_first_order(forest, root, directed=False, return_predecessors=True)
    parents = np.full(bones, -1, dtype=np.int64)
    parents[order[1:]] = predecessors[order[1:]]
    joints = np.zeros((bones, 3))
    key = {(int(a), int(b)): p for p, (a, b) in enumerate(pairs)}
    for b in order[1:]:
        joints[b] = points[key[(min(b, int(parents[b])), max(b, int(parents[b])))]]
    return parents, joints


def balance_bone(parents, mass):
    """The bone where a tree (parents (B,), −1 at its root; other −1s are bones outside it) balances:
    the one whose removal leaves the heaviest remaining part lightest (mass (B,)); ties to the lower
    id."""
    parents = np.asarray(parents, dtype=np.int64)
    mass = np.asarray(mass, dtype=np.float64)
    inside = in_tree(parents)
    below = subtree_mass(parents, np.where(inside, mass, 0.0))
    total = below[inside & (parents < 0)].sum()
    heaviest = np.where(inside, total - below, np.inf)  # the part on the root's side
    for b in np.flatnonzero(inside & (parents >= 0)):  # and each child's part
        heaviest[parents[b]] = max(heaviest[parents[b]], below[b])
    return int(np.argmin(heaviest))


def rooted_at(parents, joints, root, *also):
    """The same tree (parents (B,), joints (B, 3): each bone's joint with its parent) rooted at
    ``root``: the parents on the way from the old root to it reversed, each joint staying with its
    pair of bones, as does each array of ``also`` (B, …: any other value a bone holds for its joint
    with its parent: fixed or sliding, its drift), returned after the joints. ``root`` keeps its own
    entries. Bones outside the tree (−1, not the root) stay outside."""
    parents = np.asarray(parents, dtype=np.int64).copy()
    joints = np.asarray(joints, dtype=np.float64).copy()
    also = [np.array(a, copy=True) for a in also]
    path = [int(root)]
    while parents[path[-1]] >= 0:
        path.append(int(parents[path[-1]]))
    for child, parent in zip(path[:-1][::-1], path[1:][::-1]):  # from the old root down: flip each edge
        parents[parent], joints[parent] = child, joints[child]
        for a in also:
            a[parent] = a[child]
    parents[root] = -1
    return (parents, joints, *also)


def in_tree(parents):
    """(B,) bool: the bones of the tree (the root, the one −1 with children or the only bone, and
    its descendants); a −1 with no children besides it is a bone left out."""
    parents = np.asarray(parents, dtype=np.int64)
    tops = np.flatnonzero(parents < 0)
    counts = np.bincount(parents[parents >= 0], minlength=parents.size)
    root = tops[np.argmax(counts[tops])] if tops.size else -1
    inside = np.zeros(parents.size, dtype=bool)
    for b in range(parents.size):
        at = b
        while parents[at] >= 0:
            at = int(parents[at])
        inside[b] = at == root
    return inside


def subtree_mass(parents, mass):
    """(B,): each bone's mass with its descendants'."""
    below = np.asarray(mass, dtype=np.float64).copy()
    order = np.argsort([-tree_depth(parents, b) for b in range(parents.size)], kind="stable")  # deepest first
    for b in order:
        if parents[b] >= 0:
            below[parents[b]] += below[b]
    return below


def tree_depth(parent, k):
    """How many parents up from bone k (parent (B,), −1 at the top) the top is."""
    depth = 0
    while parent[k] >= 0:
        k, depth = int(parent[k]), depth + 1
    return depth


def is_below(parents, bone, top):
    """Whether ``bone`` is ``top`` or one of its descendants."""
    while bone >= 0:
        if bone == top:
            return True
        bone = int(parents[bone])
    return False
