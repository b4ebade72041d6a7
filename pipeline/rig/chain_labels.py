"""Chains named by what they are: a skeleton's legs, arms, neck, tail and spine, from the
geometry alone (issue 44: what Blender's, Unreal's and Godot's retargeters map by name and side).

Nothing comes from a template; everything from the tree, the rest pose, the skin and the frames:

1. **Feet**: the bones whose skin comes within :data:`FOOT_BAND` of the height of each frame's
   lowest point in at least :data:`FOOT_FRAMES` of the frames the body stands in (a gallop's rest
   frame has two hooves in the air; a hand that touches the floor once is not a foot) and that have
   no such bone below them in the tree: a leaf, or a foot a bone still hangs from (Zheng's dancer,
   27 bones: the spanning tree over the joints' drift hung a calf bone from one foot, and with
   leaves only one foot was found and nothing named). **The frames it stands in** are those at
   least :data:`UPRIGHT` (two thirds) of its tallest frame's height: lying, collapsed or tucked,
   a body touches the floor with its side, its belly or its knees, which says nothing of its feet
   (the horse collapse touches it with 13 of its 20 bones over its 53 frames; counted there, every
   leaf was a foot). Standing, a human is its full height (arms raised, taller: 1.25× it, so
   standing with them down is 0.8 of the tallest and still counts), a horse grazing 0.8 of it, a
   deep squat or a horse on its knees under two thirds; every shared capture that stands
   throughout has all its frames at 0.88 or more of its tallest, so nothing changes for them.
   Leaves whose paths meet below :data:`FOOT_SPAN` of the height are one foot (a toe and a heel
   bone), the one farthest from the root along the tree kept. Two feet make a biped, four a
   quadruped; any other count, two legs on one side (or two front legs on one side: a sheet
   draped on the ground, a horse lying down), a leg whose top stands less than :data:`LEG_HEIGHT`
   of the height above its foot at rest, legs whose
   bones mostly slide (fewer than half on fixed joints: a soft body, whose parts slide on each
   other, has no legs; the simulated cow was named a biped), or legs with no thickness (their
   skin's smallest spread under :data:`LIMB_THICKNESS` of its largest: a sheet cut like a figure;
   every leg of every shared capture and generated character is 0.13–0.26, the cloth sheet's 0),
   and no chain is named (:func:`chain_labels` returns None): nothing is named rather than named
   wrong.
2. **Across** (left–right): two legs, the horizontal line between the tops of their chains;
   four, across the body's length (the rest pose's largest horizontal spread: a quadruped is
   longer than wide, and its legs, mid-gallop, may spread any way). **Forward** is horizontal
   and across it, its sign: a biped's toes point forward (a sole lies ahead of the ankle above
   it, :func:`_toes_ahead`); a quadruped carries more skin past its legs' tops at its head's end
   (head and neck) than at its tail's (the vertices beyond the front legs' tops against those
   beyond the hind legs'; by reach instead, the 99th percentile ahead against the 1st behind, a
   galloping horse's tail outreached its head, and its hind legs were named its forelegs), each
   vertex weighed by the skin it stands for (a third of its triangles' area, where the faces are
   given) and by how high it is held (its mean height over the frames above each frame's lowest
   point): a head and neck are held up from the shoulders, a tail hangs. Neither alone holds on
   every body: by vertices, the generated quadruped (a tail tessellated as finely as its neck,
   one ring count per length whatever the girth) had as many past its hind legs as past its
   forelegs (855 against 847); by area, the galloping horse's rump and tail outweigh its head and
   neck (0.82 against 0.68), though held at 0.43 of the height against 0.70. **Left** is
   up × forward (a figure facing +z with y up has its left at +x): one rule for every
   character, so a mirrored character swaps its labels.
3. **Ends**: a biped's arms are, on each side, the leaf farthest from the root along the tree
   that is in no leg and whose branch off the legs' paths rises above the hips (not a bone on a
   thigh, nor a skirt panel hanging from the hips; with the root at the hips the branch's first
   bone, a spine bone, may be centred lower than the pelvis); its head the highest limb above the
   shoulders near the centre line, within :data:`CENTRE_BAND` (a fifth) of the width (the span
   across the hips, arms included) of the legs' middle: a head sits between the shoulders, but
   not on the line between the feet when the body leans or the head tilts (Zheng's dancer's head
   stood 0.13 of the width aside, was taken for no end, and its chest bone was named an arm).
   A quadruped's head is the end farthest ahead past its front legs, its tail the one farthest
   behind past its hind legs, off the body (no leg's): a quadruped's head is where it is going,
   wherever its neck turns (within a tenth of the width of the legs' middle, the rule before, the
   generated quadruped's head turned aside at rest and its tail behind a trunk bent sideways were
   neither named).
4. **Chains**: from each end up to the first bone that also carries another end (where the limb
   branches off the body), the bones numbered from the body outwards: ``leg_l_01`` the thigh
   (``leg_front_l_01``… on four legs), ``arm_r_02``, ``neck_01`` (its last bone the head),
   ``tail_01``. Between the root (``body``) and where the neck branches (without a head, where
   the arms do), ``spine_01``…; between the root and where the legs branch (a root in the
   chest), ``hips_01``… (on four legs, ``spine_01``… to where each pair branches). Every other bone (a
   side branch: a skirt panel, a bone on the belly) keeps its place name from
   :func:`.skeleton.joint_names`.
"""

import numpy as np

#: How close to each frame's lowest point (share of the height) a foot's skin comes.
FOOT_BAND = 0.05
#: Share of the frames in which a foot's skin comes that close to the ground.
FOOT_FRAMES = 0.1
#: Frames whose height (along up) is below this share of the tallest frame's are not standing
#: (lying, collapsed, tucked): their ground contacts say nothing of the feet (module notes, 1.).
UPRIGHT = 2.0 / 3.0
#: Grounded leaves whose paths meet in a bone this low (share of the height, its centroid above
#: the lowest point) are one foot (a toe and a heel bone meet in the foot or the shin; two legs
#: meet at the hips, near half the height; a knee is at about a quarter).
FOOT_SPAN = 0.2
#: How far (share of the height) a leg's top stands above its foot's lowest point at rest.
LEG_HEIGHT = 0.2
#: A leg's skin is a limb's, round its bones: its smallest spread (standard deviation at rest) at
#: least this share of its largest (module notes, 1.).
LIMB_THICKNESS = 0.05
#: Share of the width (across) within which an end counts as on the centre line.
CENTRE_BAND = 0.2


def _paths(parents):
    """[[root, …, b]] for every bone b."""
    paths = [None] * len(parents)

    def path(b):
        if paths[b] is None:
            paths[b] = [b] if parents[b] < 0 else path(parents[b]) + [b]
        return paths[b]

    for b in range(len(parents)):
        path(b)
    return paths


def _reach(paths, joints, centres):
    """(B,): each bone's distance from the root along the tree: its joints' steps plus its centroid's."""
    return np.array([sum(np.linalg.norm(joints[c] - joints[p]) for p, c in zip(path[1:-1], path[2:]))
                     + np.linalg.norm(centres[path[-1]] - joints[path[-1]]) for path in paths])


def trunk_names(names, paths, stops):
    """``names`` (B,) with the trunk named: for each (stop, label) of ``stops``, the bones from the
    root (excluded) to ``stop`` (where limbs branch) not yet named (``chain_…``) become
    ``label_01``, ``label_02``… numbered by depth, ties by id, over all the label's stops at once
    (a quadruped's front and hind legs may branch off two trunk bones at one depth: numbered along
    each path, both would be ``spine_02``). paths: [[root, …, b]] per bone."""
    names = list(names)
    for label in dict.fromkeys(label for _, label in stops):
        trunk = {b for stop, name in stops if name == label for b in paths[stop][1:] if names[b].startswith("chain_")}
        for k, b in enumerate(sorted(trunk, key=lambda b: (len(paths[b]), b))):
            names[b] = f"{label}_{k + 1:02d}"
    return names


def chain_tops(names):
    """{chain: its first bone (B index)} of bone names (:func:`chain_labels`'), by chain name."""
    return dict(sorted((name[:-3], b) for b, name in enumerate(names or ())
                       if name.endswith("_01") and not name.startswith("chain_")))


def named_chains(names):
    """{chain: bones} of bone names (:func:`chain_labels`'), chains sorted by name: ``leg_l_03``
    counts towards ``leg_l``; the root (``body``) and the unnamed (``chain_…``) count nowhere."""
    chains = {}
    for name in names or ():
        stem, _, number = name.rpartition("_")
        if stem and number.isdigit() and not name.startswith("chain_"):
            chains[stem] = chains.get(stem, 0) + 1
    return dict(sorted(chains.items()))


def _toes_ahead(leg, forward, up_axis, height):
    """How far (along ``forward``) a leg's sole lies ahead of its ankle: the centroid of its skin
    ``leg`` (N, 3) within :data:`FOOT_BAND` of the height of its own lowest point, less that of
    its skin from 2 to 3 bands up (the ankle and the shin above the heel). A foot reaches forward
    from the ankle, so the sign says which way the figure faces, whatever the bones."""
    above = leg[:, up_axis] - leg[:, up_axis].min()
    sole, ankle = leg[above < FOOT_BAND * height], leg[(above > 2 * FOOT_BAND * height) & (above < 3 * FOOT_BAND * height)]
    if not (len(sole) and len(ankle)):
        return 0.0
    return float((sole.mean(axis=0) - ankle.mean(axis=0)) @ forward)


def _round(points):
    """Whether skin ``points`` (N, 3) has a limb's thickness (:data:`LIMB_THICKNESS`), not a sheet's."""
    spread = np.sqrt(np.maximum(np.linalg.eigvalsh(np.cov(points.T)), 0.0)) if len(points) > 3 else np.zeros(3)
    return spread[0] >= LIMB_THICKNESS * spread[-1]


def _context(parents, joints, rest, bone_indices, bone_weights, up_axis, frames):
    """What finding the feet needs of a tree as rooted: (centres (B, 3), owner (V,), height, paths,
    leaves, reach (B,), grounded(bone), junction(end, others))."""
    from .influence import bone_centroids, dense_weights

    bones = parents.size
    centres = bone_centroids(rest, bone_indices, bone_weights, bones)
    owner = np.argmax(dense_weights(bone_indices, bone_weights, bones), axis=1)
    height = float(np.ptp(rest[:, up_axis])) or 1.0
    paths = _paths(parents)
    leaves = [b for b in range(bones) if not (parents == b).any() and parents[b] >= 0]
    poses = rest[None] if frames is None else np.asarray(frames, dtype=np.float64)
    tall = np.ptp(poses[..., up_axis], axis=1)
    poses = poses[tall >= UPRIGHT * tall.max()]  # the frames it stands in
    floor = poses[..., up_axis].min(axis=1)  # (F,)

    def grounded(bone):
        mine = owner == bone
        return parents[bone] >= 0 and mine.any() and \
            np.mean(poses[:, mine, up_axis].min(axis=1) - floor < FOOT_BAND * height) >= FOOT_FRAMES

    def junction(end, others):
        """The position on end's path of its deepest bone on another's path (where they part)."""
        return max(k for k, b in enumerate(paths[end][:-1]) if any(b in paths[o] for o in others if o != end))

    return centres, owner, height, paths, leaves, _reach(paths, joints, centres), grounded, junction


def _feet(grounded, reach, paths, centres, low, height, up_axis, junction):
    """The feet (module notes, 1.): the grounded bones with no grounded bone below them, the
    farthest from the root first, one per group whose paths meet below :data:`FOOT_SPAN` of the
    height."""
    on_ground = [b for b in range(len(paths)) if grounded(b)]
    lowest = [b for b in on_ground if not any(b in paths[d][:-1] for d in on_ground)]
    feet = []
    for end in sorted(lowest, key=lambda b: -reach[b]):
        if all(centres[paths[end][junction(end, [f])], up_axis] - low > FOOT_SPAN * height for f in feet):
            feet.append(end)
    return feet


def biped_hips(parents, joints, rest, bone_indices, bone_weights, up_axis=1, frames=None):
    """The bone where a biped's two legs part (its hips, where a retargeter starts a human), or
    None where the tree has not exactly two feet (module notes, 1.: a quadruped, a bar, a cloth).
    Found from the tree as rooted (``parents``): from a root in the trunk (the tree's centre,
    :func:`.joint_tree.balance_bone`) both legs go down through the hips."""
    parents = np.asarray(parents, dtype=np.int64)
    rest = np.asarray(rest, np.float64)
    centres, _, height, paths, _, reach, grounded, junction = _context(
        parents, np.asarray(joints, np.float64), rest, bone_indices, bone_weights, up_axis, frames)
    feet = _feet(grounded, reach, paths, centres, rest[:, up_axis].min(), height, up_axis, junction)
    return _meeting(paths, feet) if len(feet) == 2 else None


def _meeting(paths, group):
    """The deepest bone on every path of the ``group`` of bones: where their limbs branch."""
    return max(set.intersection(*(set(paths[e]) for e in group)), key=lambda k: len(paths[k]))


def chain_labels(parents, joints, rest, bone_indices, bone_weights, up_axis=1, frames=None, jointed=None, faces=None):
    """[str] (B,) each bone's name (module notes), or None where it finds no character's legs.

    parents (B,) (−1 the root); joints (B, 3) rest joints; rest (V, 3); bone_indices /
    bone_weights (V, K); up_axis 0, 1 or 2; frames (F, V, 3) the input's (None: the rest pose);
    jointed (B,) as :func:`.skeleton.joint_names` takes it, for the bones no chain names; faces
    (T, 3) the mesh's, by whose area a quadruped's skin past its legs is weighed (None: by vertex)."""
    from .skeleton import joint_names

    parents = np.asarray(parents, dtype=np.int64)
    joints, rest = np.asarray(joints, np.float64), np.asarray(rest, np.float64)
    bones = parents.size
    up = np.eye(3)[up_axis]
    centres, owner, height, paths, leaves, reach, grounded, junction = _context(
        parents, joints, rest, bone_indices, bone_weights, up_axis, frames)
    root = int(np.flatnonzero(parents < 0)[0])

    def top(end, others):
        """The first bone of end's chain: the one below where its path parts from the others'."""
        return paths[end][junction(end, others) + 1]

    feet = _feet(grounded, reach, paths, centres, rest[:, up_axis].min(), height, up_axis, junction)
    if len(feet) not in (2, 4):
        return None
    quadruped = len(feet) == 4

    hips = np.array([joints[top(f, feet)] for f in feet])
    middle = hips.mean(axis=0)
    flat = (hips if not quadruped else rest) - (middle if not quadruped else rest.mean(axis=0))
    flat -= np.outer(flat @ up, up)
    along = np.linalg.eigh(flat.T @ flat)[1][:, -1]  # two hips: the line between them; a quadruped: its length
    across = along if not quadruped else np.cross(up, along)
    across /= np.linalg.norm(across)
    forward = np.cross(across, up)
    width = float(np.ptp(rest @ across)) or 1.0
    if quadruped:  # more of the skin lies past the legs at the head's end than at the tail's
        from ..mesh.geometry import vertex_areas

        poses = rest[None] if frames is None else np.asarray(frames, dtype=np.float64)
        raised = np.mean(poses[..., up_axis] - poses[..., up_axis].min(axis=1, keepdims=True), axis=0)  # (V,)
        skin = (np.ones(len(rest)) if faces is None else vertex_areas(rest, faces)) * raised
        ahead, hips_ahead = (rest - middle) @ forward, (hips - middle) @ forward
        sign = np.sign(skin[ahead > hips_ahead.max()].sum() - skin[ahead < hips_ahead.min()].sum())
    else:
        sign = np.sign(sum(_toes_ahead(rest[np.isin(owner, paths[f][paths[f].index(top(f, feet)):])], forward,
                                       up_axis, height) for f in feet))
    forward = forward * (sign or 1.0)
    left = np.cross(up, forward)

    def side(b):
        return "_l" if (centres[b] - middle) @ left > 0 else "_r"

    ends = {}  # end bone: label
    in_legs = set()
    for f in feet:
        where = "" if not quadruped else ("_front" if (joints[top(f, feet)] - middle) @ forward > 0 else "_back")
        ends[f] = "leg" + where + side(f)
    legs_stand = all(joints[top(f, feet)][up_axis] - rest[owner == f, up_axis].min(initial=np.inf) > LEG_HEIGHT * height
                     for f in feet)
    legs = [paths[f][paths[f].index(top(f, feet)):] for f in feet]
    for leg in legs:
        in_legs.update(leg)
    turning = jointed is None or all(np.mean(np.asarray(jointed)[leg]) >= 0.5 for leg in legs)
    if len(set(ends.values())) < len(feet) or not legs_stand or not turning \
            or not _round(rest[np.isin(owner, list(in_legs))]):
        return None  # two legs on one side, a leg not standing under the body, sliding or flat "legs"
    hips_bone = parents[top(feet[0], feet)] if len(feet) == 2 else None
    # ends off the body: not in a leg, and on a biped leaving the legs' paths by a bone above the hips
    rest_leaves = [b for b in leaves if b not in feet and not in_legs.intersection(paths[b])
                   and (hips_bone is None or max(centres[k, up_axis] for k in paths[b][paths[b].index(top(b, feet)):])
                        > centres[hips_bone, up_axis])]
    if quadruped:
        front = max((joints[top(f, feet)] - middle) @ forward for f in feet)
        head = max((b for b in rest_leaves if (centres[b] - middle) @ forward > front),
                   key=lambda b: (centres[b] - middle) @ forward, default=None)
        behind = min((joints[top(f, feet)] - middle) @ forward for f in feet)
        tail = min((b for b in rest_leaves if (centres[b] - middle) @ forward < behind),
                   key=lambda b: (centres[b] - middle) @ forward, default=None)
        if tail is not None:
            ends[tail] = "tail"
    else:
        for label in ("_l", "_r"):
            arm = max((b for b in rest_leaves if side(b) == label), key=lambda b: reach[b], default=None)
            if arm is not None:
                ends[arm] = "arm" + label
        shoulders = [joints[top(e, list(ends) + feet)] for e in ends if ends[e].startswith("arm")]
        floor_of_head = max((s[up_axis] for s in shoulders), default=centres[root, up_axis])

        def crown(b):  # the highest bone of b's limb, from where it leaves the body
            return max(paths[b][paths[b].index(top(b, list(ends) + feet)):], key=lambda k: centres[k, up_axis])

        heads = [b for b in rest_leaves if b not in ends and centres[crown(b), up_axis] > floor_of_head
                 and abs((centres[crown(b)] - middle) @ across) < CENTRE_BAND * width]
        head = max(heads, key=lambda b: centres[crown(b), up_axis], default=None)
    if head is not None:
        ends[head] = "neck"
    names = list(joint_names(parents, jointed))
    names[root] = "body"
    taken = {}
    for end, label in sorted(ends.items()):
        count = taken[label] = taken.get(label, 0) + 1
        stem = label if count == 1 else f"{label}_{count}"
        chain = paths[end][paths[end].index(top(end, list(ends))):]
        for k, b in enumerate(chain):
            names[b] = f"{stem}_{k + 1:02d}"
    arms = [e for e, label in ends.items() if label.startswith("arm")]
    upper = [parents[top(head, list(ends))]] if head is not None else [_meeting(paths, arms)] if len(arms) == 2 else []
    pairs = [[f for f in feet if ends[f].startswith(end)] for end in ("leg_front", "leg_back")] if quadruped else [feet]
    stops = [(bone, "spine") for bone in upper] + [(_meeting(paths, pair), "spine" if quadruped else "hips")
                                                        for pair in pairs]
    names = trunk_names(names, paths, stops)
    return names if len(set(names)) == bones else None  # distinct, as every export needs (never seen otherwise)
