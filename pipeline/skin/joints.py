"""Joints and a bone hierarchy found from a free rigid-bone fit (Le & Deng 2014, §4).

Which bones of a free fit (:mod:`.skin_fit`) meet, and the joint each pair turns about (the point
it carries most nearly to one place over the frames, pulled towards where the two bones meet), are
the floor's: :mod:`skinsynth.pipeline.rig.bone_joints` (its module notes: the pull,
:data:`~skinsynth.pipeline.rig.bone_joints.JOINT_FLOOR`, :data:`~skinsynth.pipeline.rig.bone_joints.MIN_SHARE`).

A joint found outside the mesh (where ``c_jk`` is: the shared region is a patch of skin on a
curved body) is moved into it (:func:`inside_mesh`, inside meaning a winding number of at least
½: :func:`..geometry.points_inside`): along the segment to the first of ``c_jk``, the midpoint of
the two bones' centroids and each centroid that is inside, to a quarter of the way past the skin,
before its drift is measured. So every joint lies in the body, as a rig's joints do.

A joint's **drift** is its RMS distance apart over the frames, ‖(R_j − R_k) p + t_j − t_k‖: zero
for bones that truly hinge there. The hierarchy
(:func:`skeleton_tree`) is the minimum spanning forest of the neighbour graph weighted by
drift, keeping only pairs whose drift is at most ``max_drift`` (rigid neighbours), the pairs that
barely share skin taken only where the others leave a part unjoined
(:func:`~skinsynth.pipeline.rig.bone_joints.spanning_cost`: two bones that brush can hold a
joint by chance, as two thighs swinging about one hip axis do), rooted at
the bone that carries the most weight; the fitted skeleton is then hung from the body's centre
(:func:`hung_from_centre`: a biped's hips, where its legs part, else the tree's centre by skin
weight, :func:`~skinsynth.pipeline.rig.joint_tree.balance_bone`; issue 65), which turns the tree
round and moves nothing. A group of bones with no rigid neighbour path to the root joins the tree at its neighbour all the same: through the pair between it and
the tree that shares the most skin, by a **sliding joint** (a horse's shoulder has no bony joint;
a skirt panel slides on the hip). A sliding bone keeps a translation of its own, so the fit is as
free as before, but it hangs from the bone it is attached to, not from the root, and its travel relative
to that parent at the joint is measured and bounded (:func:`~skinsynth.pipeline.rig.skeleton.slide_offsets`,
``fit-skin``'s ``slide_low``/``slide_high``): a pose or a synthesis keeps it within what the data
showed. Only a group with no neighbour in the tree at all (a prop, cloth apart from the body)
hangs from the root *free*: its own translation, unbounded.

**At most a fifth of the bones slide** (:data:`MAX_SLIDING_SHARE`, ``--max-sliding-share``): where
more joints drift past ``max_drift``, those that drift most slide and the others hold fixed on the
same joint, so a soft capture still gets a skeleton that turns at its joints. Measured (RMSE over
the free fit's, share of fixed joints, ``benchmarks/skeleton.py``'s bones): samba 1.07 → 1.33
(43 → 81 %), crane 1.19 → 1.25 (67 → 81 %), horse collapse 1.13 → 1.20 (63 → 84 %); the horse
gallop (3 sliding of 21) and the elephant (1 of 19) are within it and unchanged. The summary names
the joints held fixed past ``max_drift``. A character whose sliding parts are more than a fifth of
its bones needs a larger share: the walker with sliding shoulders slides 2 of its 9 (0.25).
"""

from dataclasses import dataclass

import numpy as np

from ..rig.bone_joints import (JOINT_SPREAD, MAX_JOINT_DRIFT, bone_neighbours, joint_drift,  # noqa: F401 (re-exported)
                               joint_positions, spanning_cost)
from ..rig.chain_labels import biped_hips
from ..rig.influence import most_influential_bone, weight_sums
from ..rig.joint_tree import balance_bone, is_below, rooted_at
from ..rig.skeleton import depth_first

#: Largest share of the bones (the root aside) that may slide: a rig an animator poses and a
#: retargeter maps turns at its joints, and issue 44 asks at least 80 % of them fixed (module notes).
MAX_SLIDING_SHARE = 0.2


def sliding_bound(share, bones):
    """How many of ``bones`` bones may slide at ``share`` (module notes): ⌊share · (B − 1)⌋, the root
    aside (a hair over, so that 0.2 of 11 bones is 2, not 1.999…)."""
    return int(np.floor(share * (bones - 1) + 1e-9))


@dataclass
class Skeleton:
    """A tree over the B bones of a skin.

    parents (B,) int64: each bone's parent, −1 for the root (exactly one); jointed (B,) bool: the
    bone rotates about its joint with its parent (False for the root, the sliding bones and the
    free ones, which keep their own translation); joints (B, 3): each bone's joint in the rest
    pose (its own weighted rest centroid where it has none); drift (B,): each joint's drift over
    the rest diagonal on the fit it was found from (0 where there is no joint); sliding (B,) bool
    or None (none): the bone slides on its joint with its parent (module notes); names: [str]
    (B,) the bones' joint names where a given skeleton has them, else None; root: the root bone.
    """

    parents: np.ndarray
    jointed: np.ndarray
    joints: np.ndarray
    drift: np.ndarray
    sliding: np.ndarray = None
    names: list = None

    @property
    def root(self):
        return int(np.flatnonzero(self.parents < 0)[0])

    @property
    def bones(self):
        return self.parents.size

    def order(self):
        """Bone ids (B,), every parent before its children (depth first from the root)."""
        return depth_first(self.parents)


#: Depths (shares of the mesh's diagonal) under the skin nearest a point where :func:`inside_mesh`
#: looks for a way in when none of the point's anchors is inside (a thin, curved limb: both bones'
#: centroids outside it).
SKIN_DEPTHS = (0.005, 0.01, 0.02, 0.04)


def inside_mesh(points, anchors, vertices, faces, steps=12):
    """points (P, 3) moved into the closed mesh (vertices, faces) where outside: along the segment to
    the first inside one of each point's ``anchors`` (P, N, 3), to where it last crosses the skin
    (:func:`..mesh.crossing.last_crossings`, one pass over the triangles), then a quarter of the
    rest of the way on. Where that point is not inside even so (a mesh with holes, whose winding
    number changes off the skin too) or no crossing is found, the segment is bisected to the skin
    instead (``steps`` halvings: the skin to 2.4e-4 of the segment at 12; each halving tests every
    such point against every triangle). Last come points under the skin nearest the point,
    :data:`SKIN_DEPTHS` deep along its vertex normal (either way: the mesh's orientation is not
    assumed), for a point none of whose anchors is inside (on the horse's clips, a sliding joint
    between two thin, curved leg bones whose centroids both lie outside the leg). A point with no
    inside anchor even so stays. Returns (points (P, 3), moved (P,) bool)."""
    from ..mesh.crossing import last_crossings
    from ..mesh.geometry import inside_test
    from ..mesh.winding import triangle_corners

    points = np.array(points, dtype=np.float64)
    vertices = np.asarray(vertices, dtype=np.float64)
    corners = triangle_corners(vertices, faces)
    points_inside = inside_test(corners)
    outside = np.flatnonzero(~points_inside(points))
    moved = np.zeros(len(points), dtype=bool)
    if outside.size == 0:
        return points, moved
    target = np.full((outside.size, 3), np.nan)  # each outside point's first inside anchor
    for candidates in (lambda rows: np.asarray(anchors, dtype=np.float64)[outside[rows]],
                       lambda rows: _under_skin(points[outside[rows]], vertices, faces)):
        rows = np.flatnonzero(np.isnan(target[:, 0]))  # the skin's way in only where no anchor is inside
        if rows.size == 0:
            break
        near = candidates(rows)  # (n, N, 3)
        for column in range(near.shape[1]):  # in order, each tested only while none before it was inside
            left = np.flatnonzero(np.isnan(target[rows, 0]))
            if left.size == 0:
                break
            inside = left[points_inside(near[left, column])]
            target[rows[inside]] = near[inside, column]
    found = ~np.isnan(target[:, 0])
    outside, target = outside[found], target[found]
    start = points[outside]

    def placed(rows, fraction):  # past the skin at ``fraction`` of the way in, a quarter of the rest on
        return start[rows] + (fraction + 0.25 * (1.0 - fraction))[:, None] * (target[rows] - start[rows])

    every = np.arange(outside.size)
    high = last_crossings(start, target, corners)  # outside before it, inside after
    astray = np.flatnonzero((high < 0.0) | ~points_inside(placed(every, high)))
    if astray.size:  # bisected: outside at low, inside at high
        low, high[astray] = np.zeros(astray.size), 1.0
        for _ in range(steps):
            middle = 0.5 * (low + high[astray])
            now = points_inside(start[astray] + middle[:, None] * (target[astray] - start[astray]))
            high[astray], low = np.where(now, middle, high[astray]), np.where(now, low, middle)
    points[outside] = placed(every, high)
    moved[outside] = True
    return points, moved


def _under_skin(points, vertices, faces):
    """(n, 8, 3): for each of ``points`` (n, 3), the points :data:`SKIN_DEPTHS` under the skin at
    its nearest vertex, along that vertex's normal one way, then the other (the mesh's orientation
    not assumed)."""
    from scipy.spatial import cKDTree

    from ..mesh.geometry import bounding_box_diagonal, vertex_normals

    nearest = cKDTree(vertices).query(points)[1]
    normals = vertex_normals(vertices[None], faces)[0][nearest]  # (n, 3)
    depths = np.asarray(SKIN_DEPTHS) * bounding_box_diagonal(vertices)
    under = (vertices[nearest][:, None, None, :]
             - np.array([1.0, -1.0])[None, None, :, None] * depths[None, :, None, None] * normals[:, None, None, :])
    return under.reshape(len(points), -1, 3)


def skeleton_tree(bones, pairs, drift, weight_totals, root=None, max_drift=np.inf, contact=None, max_sliding=None,
                  cost=None):
    """The hierarchy: (parents (B,) int64, jointed (B,) bool, joint_pair (B,) int64, sliding (B,) bool).

    pairs (P, 2), drift (P,): the neighbour pairs and their joints' drift; weight_totals (B,):
    each bone's Σ weights (the root, unless ``root`` is given, is the largest). Pairs with drift
    above ``max_drift`` are not fixed joints: the minimum spanning forest of the others, taken in
    the order of ``cost`` (P,) (default: their drift; :func:`find_skeleton` puts the pairs that
    barely share skin last, :func:`~skinsynth.pipeline.rig.bone_joints.spanning_cost`), makes
    groups of bones held by fixed joints (ties between equal costs go to the lower pair index;
    scipy's spanning tree is deterministic). The root's group is the tree's trunk; every other
    group joins the tree through its pair with a bone already in it that shares the most skin
    (``contact`` (P,), :func:`bone_neighbours`; the least drift on a tie, and alone without
    ``contact``), that pair's bone in the group becoming the group's top, *sliding* on its joint
    with its neighbour (module notes: a scapula, a skirt panel). Contact, not drift, picks where a
    sliding bone hangs: past the fixed joints' drift, drift no longer says which neighbour a bone
    belongs to (a walker's arm sliding 10 cm on its chest drifts less against the pelvis it only
    brushes, which turns against the chest: 2.6–3.1 % against 3.5–3.7 % of the diagonal), while the
    skin it shares does (ten and two times the pelvis's there); a group with no neighbour in the tree at all (a prop, or
    cloth apart from the body) hangs from the root *free* (its largest bone on top), and groups
    may join it in turn. ``max_sliding``: at most this many sliding bones, those whose joints drift
    most; the others hold fixed on the same joint (None: no bound; module notes). joint_pair[b]: the
    pair whose joint holds bone b to its parent, fixed or sliding, −1 where none."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree

    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    drift = np.asarray(drift, dtype=np.float64)
    totals = np.asarray(weight_totals, dtype=np.float64)
    rigid = np.flatnonzero(drift <= max_drift)
    cost = drift if cost is None else np.asarray(cost, dtype=np.float64)
    # +1 keeps zero-drift joints as edges (scipy reads a 0 as no edge); the order is unchanged.
    graph = coo_matrix((cost[rigid] / max(float(cost.max(initial=0.0)), 1e-300) + 1.0,
                        (pairs[rigid, 0], pairs[rigid, 1])), shape=(bones, bones)).tocsr()
    forest = minimum_spanning_tree(graph)
    forest = forest + forest.T
    root = int(np.argmax(totals)) if root is None else int(root)
    parents = np.full(bones, -1, dtype=np.int64)
    jointed = np.zeros(bones, dtype=bool)
    sliding = np.zeros(bones, dtype=bool)
    joint_pair = np.full(bones, -1, dtype=np.int64)
    _, labels = connected_components(forest, directed=False)
    placed = np.zeros(bones, dtype=bool)

    def hang(top):
        """Place top's group below top (already given its parent), through its fixed joints."""
        order, predecessors = breadth_first_order(forest, top, directed=False, return_predecessors=True)
        below = order[1:]
        parents[below] = predecessors[below]
        jointed[below] = True
        placed[order] = True

    hang(root)
    key = {(int(a), int(b)): p for p, (a, b) in enumerate(pairs)}
    while not placed.all():
        crossing = np.flatnonzero(placed[pairs[:, 0]] != placed[pairs[:, 1]])
        if crossing.size:  # the pair into the tree sharing the most skin, then the least drift, the lower index
            share = np.zeros(crossing.size) if contact is None else -np.asarray(contact, dtype=np.float64)[crossing]
            pair = int(crossing[np.lexsort((crossing, drift[crossing], share))[0]])
            a, b = pairs[pair]
            inside, top = (int(a), int(b)) if placed[a] else (int(b), int(a))
            parents[top], sliding[top] = inside, True
        else:  # no neighbour in the tree: free from the root
            members = np.flatnonzero(~placed)
            top = int(members[np.argmax(totals[members])])
            parents[top] = root
        hang(top)
    for b in np.flatnonzero(jointed | sliding):
        joint_pair[b] = key[(min(b, int(parents[b])), max(b, int(parents[b])))]
    slid = np.flatnonzero(sliding)
    if max_sliding is not None and slid.size > max_sliding:  # the least drifting held fixed, ties to the lower id
        held = slid[np.lexsort((slid, drift[joint_pair[slid]]))[:slid.size - max_sliding]]
        jointed[held], sliding[held] = True, False
    return parents, jointed, joint_pair, sliding


def find_skeleton(rest, faces, bone_indices, bone_weights, rotations, translations, root=None,
                  max_drift=MAX_JOINT_DRIFT, spread=JOINT_SPREAD, diagonal=None, max_sliding_share=MAX_SLIDING_SHARE,
                  frames=None, up_axis=1):
    """A :class:`Skeleton` for a free fit: neighbours, joints, drift, tree (module notes).

    rest (V, 3), faces (T, 3), bone_indices / bone_weights (V, K), rotations (F, B, 3, 3),
    translations (F, B, 3). ``max_drift`` is a share of ``diagonal`` (default: the rest pose's
    bounding-box diagonal); ``root``: the root bone, default the one carrying the most weight;
    ``max_sliding_share``: at most ⌊share · (B − 1)⌋ bones slide (module notes; None: any number);
    ``frames`` (F, V, 3), the input's, with ``up_axis`` up: a biped's limbs that hang down from its
    head are hung from its spine instead (:func:`limbs_off_the_head`; None: the tree as spanned)."""
    from ..mesh.geometry import bounding_box_diagonal
    from ..rig.influence import bone_centroids

    bones = np.asarray(rotations).shape[1]
    diagonal = bounding_box_diagonal(rest) if diagonal is None else float(diagonal)
    totals = weight_sums(bone_indices, bone_weights, bones)
    if root is None:
        root = most_influential_bone(bone_indices, bone_weights, bones)
    pairs, centres, contact = bone_neighbours(rest, faces, bone_indices, bone_weights, bones)
    joints, _ = joint_positions(rotations, translations, pairs, centres, spread * diagonal)
    points = bone_centroids(rest, bone_indices, bone_weights, bones)
    ends = points[pairs]  # (P, 2, 3): each pair's two bone centroids
    joints, _ = inside_mesh(joints, np.concatenate([centres[:, None], ends.mean(axis=1, keepdims=True), ends], axis=1),
                            rest, faces)
    drift = joint_drift(rotations, translations, pairs, joints) / diagonal
    most = None if max_sliding_share is None else sliding_bound(max_sliding_share, bones)
    parents, jointed, joint_pair, sliding = skeleton_tree(bones, pairs, drift, totals, root, max_drift, contact, most,
                                                          spanning_cost(pairs, drift, contact, totals))
    if frames is not None:  # a biped's head is the top of its spine: nothing hangs down from it
        parents, jointed, joint_pair, sliding = limbs_off_the_head(
            parents, jointed, joint_pair, sliding, pairs, drift, joints, max_drift, rest, bone_indices, bone_weights,
            frames, up_axis)
    parents, joint_pair = through_the_bone_between(parents, jointed, joint_pair, pairs, drift, max_drift, points)
    held = jointed | sliding
    points[held] = joints[joint_pair[held]]
    bone_drift = np.where(held, drift[np.maximum(joint_pair, 0)], 0.0)
    return Skeleton(parents=parents, jointed=jointed, joints=points, drift=bone_drift, sliding=sliding)


def limbs_off_the_head(parents, jointed, joint_pair, sliding, pairs, drift, joints, max_drift, rest, bone_indices,
                       bone_weights, frames, up_axis=1):
    """The tree (parents, jointed, joint_pair, sliding: :func:`skeleton_tree`'s; pairs (P, 2), their
    drift (P,) and joints (P, 3)) with every limb that hangs down from a biped's head hung from the
    spine below it instead (issue 65: limbs join the trunk). The spine: the path from the hips
    (:func:`~skinsynth.pipeline.rig.chain_labels.biped_hips`, the feet found on ``frames``, from the
    tree rooted at its centre) to the head, the bone the topmost vertex of the rest pose holds most
    (a standing human's crown; hands raised above it are a leaf, from which nothing hangs). A child
    of the head whose limb is centred below the head's own joint with the spine hangs there by the
    spanning tree's chance, not by the body's build: the crane's shoulder drifts a little less
    against the head (1.6 % of the diagonal) than against the chest (2.0 %), all of it soft, and its
    arm hung from the head, the neck left unnamed. It moves to its neighbour on the spine below the
    head whose joint drifts least (fixed within ``max_drift``, else sliding). Nothing changes where
    the tree has no biped's legs, where nothing hangs down from the head (or the head has no joint),
    or where such a limb meets no bone of the spine."""
    from ..rig.influence import bone_centroids

    bones = parents.size
    centres = bone_centroids(rest, bone_indices, bone_weights, bones)
    held = np.flatnonzero(joint_pair >= 0)
    points = centres.copy()
    points[held] = joints[joint_pair[held]]
    centred = rooted_at(parents, points, balance_bone(parents, weight_sums(bone_indices, bone_weights, bones)))
    hips = biped_hips(*centred, rest, bone_indices, bone_weights, up_axis, frames)
    if hips is None:
        return parents, jointed, joint_pair, sliding
    root = int(np.flatnonzero(parents < 0)[0])
    tree, _, fixed, pair_of, slides = rooted_at(parents, points, int(hips), jointed, joint_pair, sliding)
    top = int(np.argmax(rest[:, up_axis]))
    head = int(np.asarray(bone_indices)[top][np.argmax(np.asarray(bone_weights)[top])])
    spine = [head]
    while tree[spine[-1]] >= 0:
        spine.append(int(tree[spine[-1]]))
    key = {(int(a), int(b)): p for p, (a, b) in enumerate(pairs)}
    if len(spine) < 2 or (min(head, spine[1]), max(head, spine[1])) not in key:  # no spine, or a free head
        return parents, jointed, joint_pair, sliding
    neck = joints[key[(min(head, spine[1]), max(head, spine[1]))]][up_axis]
    moved = False
    for child in np.flatnonzero(tree == head):
        limb = [b for b in range(bones) if is_below(tree, b, int(child))]
        options = [key[(min(child, b), max(child, b))] for b in spine[1:] if (min(child, b), max(child, b)) in key]
        if centres[limb, up_axis].mean() < neck and options:  # hung, in the tree from the hips, on the spine
            pair = min(options, key=lambda p: (drift[p], p))
            tree[child] = pairs[pair][0] if pairs[pair][1] == child else pairs[pair][1]
            pair_of[child], fixed[child], slides[child] = pair, drift[pair] <= max_drift, drift[pair] > max_drift
            moved = True
    if not moved:
        return parents, jointed, joint_pair, sliding
    parents, _, jointed, joint_pair, sliding = rooted_at(tree, points, root, fixed, pair_of, slides)  # back
    jointed[root], joint_pair[root], sliding[root] = False, -1, False
    return parents, jointed, joint_pair, sliding


#: Where a bone's skin must be centred, along the way from its parent's centroid to its sibling's, to be
#: the bone between them (:func:`through_the_bone_between`): past the first and before the last fifth of the
#: way, and at most a quarter of its length off it.
BETWEEN_SPAN = (0.2, 0.8)
BETWEEN_OFF = 0.25


def through_the_bone_between(parents, jointed, joint_pair, pairs, drift, max_drift, centres):
    """(parents, joint_pair): the tree (:func:`skeleton_tree`'s; pairs (P, 2) and their drift (P,)) with each
    chain passing through the bone between (issue 65: every bone's parent). Where bone h hangs from p by a
    fixed joint and a sibling n (another child of p, a leaf) has its skin centred on the way from p's
    skin to h's (``centres`` (B, 3); :data:`BETWEEN_SPAN`, :data:`BETWEEN_OFF`) and meets h with a joint
    that holds (drift within ``max_drift``), n is the link between them the spanning tree skipped: h
    hangs from n instead. A bone's skin lies between its parent's and its child's along a chain; a
    leaf beside a link, its skin in the link's middle, is that link's middle bone: the generated
    humanoid's neck, left a leaf of the chest beside the chest → head link (the neck barely turns
    against the head: the two joints drift alike, and the tree took the chest's), its spine beside
    pelvis → chest. Repeated until nothing moves (a bone at most once per round). Of the shared
    captures only the cloth sheet's tree has such a leaf (its error 1.29× → 1.30× the free fit's)."""
    parents, joint_pair = np.array(parents, copy=True), np.array(joint_pair, copy=True)
    centres = np.asarray(centres, dtype=np.float64)
    key = {(int(a), int(b)): p for p, (a, b) in enumerate(np.asarray(pairs, dtype=np.int64).reshape(-1, 2))}
    for _ in range(parents.size):
        moved = False
        for bone in np.flatnonzero(np.asarray(jointed, dtype=bool) & (parents >= 0)):
            parent = parents[bone]
            way = centres[bone] - centres[parent]
            length = float(np.linalg.norm(way))
            best = None
            for other in np.flatnonzero(parents == parent):
                pair = key.get((min(other, bone), max(other, bone)))
                if other == bone or pair is None or (parents == other).any() or not drift[pair] <= max_drift:
                    continue
                along = float((centres[other] - centres[parent]) @ way) / max(length * length, 1e-300)
                off = float(np.linalg.norm(centres[other] - centres[parent] - along * way))
                if BETWEEN_SPAN[0] < along < BETWEEN_SPAN[1] and off < BETWEEN_OFF * length and \
                        (best is None or off < best[0]):
                    best = (off, other, pair)
            if best is not None:
                parents[bone], joint_pair[bone] = best[1], best[2]
                moved = True
        if not moved:
            break
    return parents, joint_pair


def hung_from_centre(skeleton, drift, rest, bone_indices, bone_weights, frames=None, up_axis=1):
    """(skeleton, drift (B,)): the found ``skeleton`` (and its joints' ``drift``) hung from the body's
    centre (module notes): a biped's hips, where its two legs part
    (:func:`~skinsynth.pipeline.rig.chain_labels.biped_hips`, the feet found on the input's
    ``frames`` (F, V, 3) with ``up_axis`` up), else the tree's centre by skin weight, the bone whose
    removal leaves no part with more than half the skin
    (:func:`~skinsynth.pipeline.rig.joint_tree.balance_bone`, where the plants' limbs root the tree
    too): a standing human's legs are each about a sixth of its skin and its upper body about half,
    so its centre lies in the trunk; a quadruped's is its trunk; a limb's end only where it carries
    more than half the skin, as no character's does. Only the tree's direction
    changes: every joint, bone and transform stays, each joint's kind (fixed, sliding) and drift
    moving with it along the turned path (a sliding joint's travel is measured afterwards on the tree
    as it is stored). Where the path crosses a free bone (no joint: it hangs from the root alone) the
    skeleton is returned as it is."""
    from ..rig.influence import bone_centroids

    centre = balance_bone(skeleton.parents, weight_sums(bone_indices, bone_weights, skeleton.bones))
    hips = biped_hips(*rooted_at(skeleton.parents, skeleton.joints, centre), rest, bone_indices, bone_weights, up_axis,
                      frames)
    root = centre if hips is None else int(hips)
    path = [root]
    while skeleton.parents[path[-1]] >= 0:
        path.append(int(skeleton.parents[path[-1]]))
    sliding = np.zeros(skeleton.bones, bool) if skeleton.sliding is None else np.asarray(skeleton.sliding, bool)
    if root == skeleton.root or not (np.asarray(skeleton.jointed) | sliding)[path[:-1]].all():
        return skeleton, drift
    parents, joints, jointed, slides, bone_drift, moved = rooted_at(skeleton.parents, skeleton.joints, root,
                                                                    skeleton.jointed, sliding, skeleton.drift, drift)
    jointed[root] = slides[root] = False
    joints[root] = bone_centroids(rest, bone_indices, bone_weights, skeleton.bones)[root]
    bone_drift[root] = moved[root] = 0.0
    return Skeleton(parents=parents, jointed=jointed, joints=joints, drift=bone_drift,
                    sliding=None if skeleton.sliding is None else slides, names=skeleton.names), moved


def free_skin_skeleton(rest, faces, bone_indices, bone_weights, rotations, translations, frames, up_axis=1):
    """The skeleton a free skin's bones keep best, for ``play`` to pose it beyond its examples
    (:mod:`skinsynth.pipeline.puppet.jointed_play`): :func:`find_skeleton` of its bones (rest (V,
    3), faces (T, 3), bone_indices / bone_weights (V, K), rotations (F, B, 3, 3), translations
    (F, B, 3)), hung from the body's centre (:func:`hung_from_centre`; frames (F, V, 3) its
    examples, ``up_axis`` up), as ``fit-skin --skeleton`` finds it before it refits the bones on
    it: {"parents" (B,), "jointed" (B,) (a sliding bone is loose), "joints" (B, 3)}."""
    found = find_skeleton(rest, faces, bone_indices, bone_weights, rotations, translations, frames=frames,
                          up_axis=up_axis)
    found, _ = hung_from_centre(found, found.drift, rest, bone_indices, bone_weights, frames, up_axis)
    return {"parents": np.asarray(found.parents), "jointed": np.asarray(found.jointed, bool),
            "joints": np.asarray(found.joints, np.float64)}


def given_skeleton(names, parents, positions, free):
    """A :class:`Skeleton` from a rig the user brings (a UsdSkel ``Skeleton``: joint ``names``
    (J,) as paths, ``parents`` (J,) −1 at the top, bind ``positions`` (J, 3), ``free`` (J,) bool):
    (skeleton, kept (B,) the joints that are bones). Every joint is a bone turning about its
    position, except: the top joint when it is skinsynth's own ``root`` above one bone (the
    exporter's root joint, which carries no vertex: docs/skeleton.md), and the ``free`` joints,
    which hang from their parent with translations of their own. ValueError for several top
    joints."""
    parents = np.asarray(parents, dtype=np.int64)
    positions = np.asarray(positions, dtype=np.float64)
    free = np.asarray(free, dtype=bool)
    tops = np.flatnonzero(parents < 0)
    if tops.size != 1:
        raise ValueError(f"the skeleton has {tops.size} top joints; a rig has one")
    top = int(tops[0])
    kept = np.arange(parents.size)
    if str(names[top]).split("/")[-1] == "root" and np.count_nonzero(parents == top) == 1 and parents.size > 1:
        kept = kept[kept != top]
    index = np.full(parents.size, -1, dtype=np.int64)
    index[kept] = np.arange(kept.size)
    bone_parents = np.where(parents[kept] >= 0, index[np.maximum(parents[kept], 0)], -1)
    jointed = (bone_parents >= 0) & ~free[kept]
    return Skeleton(parents=bone_parents, jointed=jointed, joints=positions[kept], drift=np.zeros(kept.size),
                    names=[str(names[k]).split("/")[-1] for k in kept]), kept
