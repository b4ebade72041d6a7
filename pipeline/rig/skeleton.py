"""A fitted rig as an engine skeleton: one root joint with every rigid bone under it, the bones'
per-frame transforms as joint-local rotation and translation (scale 1), bind matrices, and the
vertex influences a skinned-mesh format carries (glTF 2.0: four per vertex, heaviest first).

Skinning identity (LBS, the model ``fit-skin`` fits): vertex v_i(f) = Σ_j w_ij (R_j(f) r_i + t_j(f))
for rest positions r_i. An engine skins with joint world matrices J_j(f) times inverse bind
matrices B_j⁻¹. With each bone's bind transform a translation to its rest centre c_j,
J_j(f) = [R_j(f) | R_j(f) c_j + t_j(f)] makes J_j(f) B_j⁻¹ = [R_j(f) | t_j(f)] exactly. The root's
bind is the identity; its world transform P(f) (identity, or the ground motion with root motion)
is divided out of every bone: local_j(f) = P(f)⁻¹ J_j(f).

A rig with a skeleton (``fit-skin --skeleton``: each bone's ``parents`` bone, −1 for the root
bone; its ``joints``, the rest positions c_j it turns about) is exported as a tree instead
(:func:`tree_locals`, :func:`joint_names`): the root bone under the root joint, every other bone
under its parent bone, each joint at c_j with the same inverse bind (a translation by −c_j) and
the same world matrix J_j(f), now local to its parent: local_j(f) = J_p(f)⁻¹ J_j(f) (the root
bone's p the root joint, P(f)). For a jointed bone, R_j c_j + t_j = R_p c_j + t_p makes its local
translation the constant c_j − c_p: bones of constant length, as an animator's skeleton has.
"""

import numpy as np

from .influence import bone_centroids, most_influential_bone
from .rotations import align_hemispheres, heading_and_posture, matrix_to_quaternion, rotation_exp

#: Influences per vertex a glTF skin carries in JOINTS_0/WEIGHTS_0 (engines read no more).
GLTF_INFLUENCES = 4


def _xyzw(rotations):
    """Unit quaternions (..., 4) as (x, y, z, w), glTF's and shaders' order, of rotations
    (F, ..., 3, 3), each sequence along the first axis on one hemisphere (interpolation between
    frames takes the short way)."""
    wxyz = align_hemispheres(matrix_to_quaternion(np.asarray(rotations, dtype=np.float64)), axis=0)
    return np.concatenate([wxyz[..., 1:], wxyz[..., :1]], axis=-1)


def bone_world(rotations, translations, centres):
    """Joint world transforms of the bones: rotations (F, B, 3, 3) unchanged, positions (F, B, 3)
    R_j c_j + t_j for bone centres (B, 3)."""
    positions = np.einsum("fbij,bj->fbi", rotations, centres) + translations
    return np.asarray(rotations, dtype=np.float64), positions


def joint_locals(rotations, translations, centres, root_rotations=None, root_translations=None):
    """Each bone's transform local to the root joint, per frame.

    rotations (F, B, 3, 3), translations (F, B, 3): the LBS bone transforms; centres (B, 3); the
    root's world transform per frame (root_rotations (F, 3, 3), root_translations (F, 3)), None
    for a fixed root at the origin. Returns (quaternions (F, B, 4) as (x, y, z, w), each bone's
    sequence on one hemisphere so that interpolation takes the short way, and translations
    (F, B, 3))."""
    world_r, world_t = bone_world(rotations, translations, centres)
    if root_rotations is not None:
        inverse = np.swapaxes(root_rotations, -1, -2)
        world_r = np.einsum("fij,fbjk->fbik", inverse, world_r)
        world_t = np.einsum("fij,fbj->fbi", inverse, world_t - root_translations[:, None, :])
    return _xyzw(world_r), world_t


def depth_first(parents):
    """The bones of a tree (parents (B,), −1 for the one root bone) in depth-first order, each
    bone's children in ascending id: (B,) int64, parents always before their children.
    ValueError unless ``parents`` is one tree (one root, every bone reaching it)."""
    parents = np.asarray(parents, dtype=np.int64)
    roots = np.flatnonzero(parents < 0)
    if roots.size != 1:
        raise ValueError(f"a skeleton has exactly one root bone (parent -1), not {roots.size}")
    children = _children(parents)
    order, stack = [], [int(roots[0])]
    while stack:
        bone = stack.pop()
        order.append(bone)
        stack.extend(reversed(children[bone]))
    if len(order) != len(parents):
        raise ValueError("the skeleton's parents are not a tree: some bone never reaches the root (a cycle)")
    return np.array(order, dtype=np.int64)


def _children(parents):
    """Each bone's children, ascending: [list] (B,)."""
    children = [[] for _ in range(len(parents))]
    for bone, parent in enumerate(parents):
        if parent >= 0:
            children[parent].append(bone)
    return children


def joint_names(parents, jointed=None):
    """The joint name of each bone of a tree (parents (B,), −1 for the root bone), saying where it
    is: ``chain_CC_joint_JJ``, the JJ-th joint of chain CC. A chain is a maximal path down the
    tree through bones of exactly one child: the root bone starts chain 00; the children of a
    branch (a bone with several children, or a free bone) each start a new chain, and so does a
    free bone itself (``jointed`` (B,) False: it hangs from its parent without a joint, so it
    continues no chain; None: every bone but the root is jointed). Chains are numbered in
    depth-first order, children in ascending bone id. Returns [str] (B,), by bone id."""
    parents = np.asarray(parents, dtype=np.int64)
    jointed = parents >= 0 if jointed is None else np.asarray(jointed, dtype=bool)
    free = ~jointed & (parents >= 0)
    children = _children(parents)
    names, chains = [None] * len(parents), 0
    for bone in depth_first(parents):
        parent = parents[bone]
        if parent >= 0 and len(children[parent]) == 1 and not free[parent] and not free[bone]:
            chain, joint = names[parent]
            names[bone] = (chain, joint + 1)
        else:
            names[bone], chains = (chains, 0), chains + 1
    return [f"chain_{chain:02d}_joint_{joint:02d}" for chain, joint in names]


def bone_names(skeleton):
    """[str] (B,): a read /skin/skeleton's bone names, its chains' (``@names``,
    :mod:`.chain_labels`) where it has them, else :func:`joint_names` of its tree."""
    return list(skeleton["names"]) if skeleton.get("names") is not None else joint_names(skeleton["parents"],
                                                                                          skeleton["jointed"])


def hold_joints(rotations, translations, parents, jointed, joints, slides=None):
    """Put every jointed bone back on its joint, in place: t_j = t_p + (R_p − R_j) q_j, parents
    first, so each joint goes where its parent takes it and its bone keeps its turn (R_j, any
    3×3). rotations (..., B, 3, 3), translations (..., B, 3) (any leading axes: frames,
    animations); parents (B,), jointed (B,), joints (B, 3) as ``fit-skin --skeleton`` stores them.
    slides: None, or (sliding (B,) bool, low (B, 3), high (B, 3)): each sliding bone's slide
    (:func:`slide_offsets`) is kept within [low, high] (per axis of its parent's frame): where it
    is beyond, t_j = t_p + R_p (q_j + s) − R_j q_j with s clipped; where it is within, the bone is
    left as it is, bit for bit. The root and the free bones keep their translations."""
    joints = np.asarray(joints, dtype=np.float64)
    sliding = np.zeros(len(parents), bool) if slides is None else np.asarray(slides[0], dtype=bool)
    for bone in depth_first(parents):
        parent = parents[bone]
        if jointed[bone]:
            translations[..., bone, :] = translations[..., parent, :] + np.einsum(
                "...xy,y->...x", rotations[..., parent, :, :] - rotations[..., bone, :, :], joints[bone])
        elif sliding[bone]:
            slide = slide_offsets(rotations, translations, parents, joints, [bone])[..., 0, :]
            held = np.clip(slide, slides[1][bone], slides[2][bone])
            beyond = np.any(held != slide, axis=-1)
            if beyond.any():
                R_p, R_j = rotations[..., parent, :, :][beyond], rotations[..., bone, :, :][beyond]
                translations[..., bone, :][beyond] = translations[..., parent, :][beyond] + np.einsum(
                    "nxy,ny->nx", R_p, joints[bone] + held[beyond]) - np.einsum("nxy,y->nx", R_j, joints[bone])
    return translations


def slide_offsets(rotations, translations, parents, joints, bones):
    """(..., k, 3): how far each of ``bones`` (k,) slides on its joint q_j with its parent p: where
    the bone carries the joint less where the parent does, in the parent's frame,
    s_j = R_p⁻¹ ((R_j − R_p) q_j + t_j − t_p) (R_p any invertible 3×3: a spliced bone inside a
    blend window is affine). 0 for a joint that holds. rotations (..., B, 3, 3), translations
    (..., B, 3); parents (B,); joints (B, 3)."""
    bones = np.asarray(bones, dtype=np.int64)
    up = np.asarray(parents, dtype=np.int64)[bones]
    q = np.asarray(joints, dtype=np.float64)[bones]
    R_j, R_p = rotations[..., bones, :, :].astype(np.float64), rotations[..., up, :, :].astype(np.float64)
    gap = np.einsum("...kxy,ky->...kx", R_j - R_p, q) + translations[..., bones, :] - translations[..., up, :]
    return np.linalg.solve(R_p, gap[..., None])[..., 0]


def held_rig(skeleton):
    """(parents, jointed, joints, slides) of a skin's /skin/skeleton as read (``skin.skeleton``):
    the arguments :func:`hold_joints` takes after the bones; slides None when no bone slides."""
    sliding = skeleton["sliding"]
    slides = (sliding, skeleton["slide_low"], skeleton["slide_high"]) if sliding.any() else None
    return skeleton["parents"], skeleton["jointed"], skeleton["joints"], slides


def _turn_between(a, b):
    """The smallest rotations (..., 3, 3) taking directions a (..., 3) to b (..., 3): about a × b by
    the angle between them (a half turn about a perpendicular where they oppose)."""
    a = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-300)
    b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-300)
    axis = np.cross(a, b)
    sine, cosine = np.linalg.norm(axis, axis=-1), np.einsum("...x,...x->...", a, b)
    opposed = (sine < 1e-9) & (cosine < 0.0)
    if opposed.any():  # any axis perpendicular to a
        other = np.where(np.abs(a[..., :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
        axis = np.where(opposed[..., None], np.cross(a, other), axis)
    axis = axis / np.maximum(np.linalg.norm(axis, axis=-1, keepdims=True), 1e-300)
    return rotation_exp(axis * np.arctan2(sine, cosine)[..., None])


def reach_with_legs(rotations, translations, parents, jointed, joints, feet, targets, slides=None):
    """Two-bone inverse kinematics, in place: each of ``feet`` (bone ids) has its joint brought to
    ``targets`` (..., len(feet), 3) by turning its parent (the shin) and grandparent (the thigh)
    about their joints, the leg bending in the plane it bends in already; the foot keeps its world
    rotation, and everything below follows (:func:`hold_joints` after). Out of reach, the leg
    straightens (or folds) towards the target. A foot whose shin or thigh is not jointed is left
    alone. rotations (..., B, 3, 3), translations (..., B, 3): a jointed rig's bones (joints
    holding); slides: :func:`hold_joints`'. Returns the translations."""
    joints = np.asarray(joints, dtype=np.float64)
    for n, foot in enumerate(feet):
        shin = parents[foot]
        thigh = parents[shin] if shin >= 0 else -1
        if thigh < 0 or not (jointed[foot] and jointed[shin] and jointed[thigh]):
            continue
        target = np.asarray(targets[..., n, :], dtype=np.float64)
        R_t, R_s = rotations[..., thigh, :, :].astype(np.float64), rotations[..., shin, :, :].astype(np.float64)
        hip = np.einsum("...xy,y->...x", R_t, joints[thigh]) + translations[..., thigh, :]
        upper, lower = joints[shin] - joints[thigh], joints[foot] - joints[shin]
        l1, l2 = np.linalg.norm(upper), np.linalg.norm(lower)
        knee = hip + np.einsum("...xy,y->...x", R_t, upper)
        ankle = knee + np.einsum("...xy,y->...x", R_s, lower)
        to_target = target - hip
        distance = np.clip(np.linalg.norm(to_target, axis=-1), abs(l1 - l2) + 1e-9 * (l1 + l2),
                           (1.0 - 1e-9) * (l1 + l2))
        u = to_target / np.maximum(np.linalg.norm(to_target, axis=-1, keepdims=True), 1e-300)
        bend = (knee - hip) - np.einsum("...x,...x->...", knee - hip, u)[..., None] * u  # the knee's side
        fallback = np.cross(u, np.where(np.abs(u[..., :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])))
        bend = np.where(np.linalg.norm(bend, axis=-1, keepdims=True) > 1e-9 * l1, bend, fallback)
        w = bend / np.linalg.norm(bend, axis=-1, keepdims=True)
        cosine = np.clip((l1 * l1 + distance * distance - l2 * l2) / (2.0 * l1 * distance), -1.0, 1.0)
        wanted_knee = hip + l1 * (cosine[..., None] * u + np.sqrt(1.0 - cosine * cosine)[..., None] * w)
        turn = _turn_between(knee - hip, wanted_knee - hip)
        R_t, R_s = turn @ R_t, turn @ R_s
        ankle = wanted_knee + np.einsum("...xy,y->...x", R_s, lower)
        R_s = _turn_between(ankle - wanted_knee, hip + distance[..., None] * u - wanted_knee) @ R_s
        rotations[..., thigh, :, :], rotations[..., shin, :, :] = R_t, R_s
    return hold_joints(rotations, translations, parents, jointed, joints, slides)


def rest_locals(centres, parents):
    """Each joint's rest translation local to its parent joint (B, 3): c_j − c_p, the root bone's
    c_j (its parent, the root joint, at the origin). centres (B, 3), parents (B,)."""
    centres = np.asarray(centres, dtype=np.float64)
    parents = np.asarray(parents, dtype=np.int64)
    return centres - np.where((parents >= 0)[:, None], centres[np.maximum(parents, 0)], 0.0)


def tree_local_transforms(rotations, translations, centres, parents, root_rotations=None, root_translations=None):
    """Each bone's joint transform local to its parent joint, per frame, as matrices: local_j =
    J_p⁻¹ J_j with J_j = [R_j | R_j c_j + t_j] (module notes), the root bone's parent the root
    joint (root_rotations (F, 3, 3), root_translations (F, 3): its world transform; None for the
    origin). rotations (F, B, 3, 3), translations (F, B, 3): the LBS bone transforms; centres
    (B, 3) the joints' rest positions; parents (B,). Returns (rotations (F, B, 3, 3),
    translations (F, B, 3)). Exact for any bone transforms; a jointed bone's translation is
    c_j − c_p in every frame (to rounding) when its joint holds."""
    world_r, world_t = bone_world(rotations, translations, centres)
    parents = np.asarray(parents, dtype=np.int64)
    top = parents < 0
    parent_r, parent_t = world_r[:, np.maximum(parents, 0)], world_t[:, np.maximum(parents, 0)]
    if root_rotations is None:
        parent_r[:, top], parent_t[:, top] = np.eye(3), 0.0
    else:
        parent_r[:, top] = np.asarray(root_rotations, dtype=np.float64)[:, None]
        parent_t[:, top] = np.asarray(root_translations, dtype=np.float64)[:, None]
    local_r = np.einsum("fbji,fbjk->fbik", parent_r, world_r)
    local_t = np.einsum("fbji,fbj->fbi", parent_r, world_t - parent_t)
    return local_r, local_t


def tree_locals(rotations, translations, centres, parents, root_rotations=None, root_translations=None):
    """:func:`tree_local_transforms` as glTF animates joints: (quaternions (F, B, 4) (x, y, z, w),
    each bone's sequence on one hemisphere, translations (F, B, 3))."""
    local_r, local_t = tree_local_transforms(rotations, translations, centres, parents, root_rotations,
                                             root_translations)
    return _xyzw(local_r), local_t


def joint_tree_arrays(skeleton, rotations, translations, root_motion=None):
    """A skin's /skin/skeleton (``skin.skeleton``: parents, jointed, joints) as a joint tree for one
    or several animations, rotations (..., B, 3, 3) and translations (..., B, 3), under a root joint
    moving by ``root_motion`` ((rotations (F, 3, 3), translations (F, 3)), or None: fixed):
    {parents, names (:func:`bone_names`), rest (:func:`rest_locals`), rotations and translations
    local to each parent joint (:func:`tree_local_transforms`, the inputs' shapes), free (B,) the
    unjointed bones below the root bone}, as ``formats.usd.JointTree`` holds them (its
    ``bind_centers`` are then ``skeleton["joints"]``)."""
    parents, joints = skeleton["parents"], skeleton["joints"]
    rotations, translations = np.asarray(rotations, np.float64), np.asarray(translations, np.float64)
    local_r, local_t = tree_local_transforms(rotations.reshape(-1, *rotations.shape[-3:]),
                                             translations.reshape(-1, *translations.shape[-2:]), joints, parents,
                                             *(root_motion or (None, None)))
    return dict(parents=parents, names=bone_names(skeleton), rest=rest_locals(joints, parents),
                rotations=local_r.reshape(rotations.shape), translations=local_t.reshape(translations.shape),
                free=~np.asarray(skeleton["jointed"], dtype=bool) & (np.asarray(parents) >= 0))


def joint_parents(parents=None, bones=None):
    """The parent joint of each joint of an exported rig, (B + 1,) int64: −1 for joint 0, the
    root; bone j is joint j + 1, under joint parents[j] + 1, the root bone under the root. None
    (a rig without a skeleton, ``bones`` of them): every bone under the root."""
    if parents is None:
        return np.concatenate([[-1], np.zeros(bones, dtype=np.int64)])
    return np.concatenate([[-1], np.asarray(parents, dtype=np.int64) + 1])


def inverse_bind_matrices(centres):
    """(B + 1, 4, 4): the root's (identity) then each bone's, a translation by −c_j."""
    matrices = np.tile(np.eye(4), (len(centres) + 1, 1, 1))
    matrices[1:, :3, 3] = -np.asarray(centres, dtype=np.float64)
    return matrices


def four_influences(bone_indices, bone_weights):
    """(joints (V, 4), weights (V, 4)) for a skin of at most :data:`GLTF_INFLUENCES` influences:
    bone indices shifted by one (joint 0 is the root, which carries no vertex), heaviest first,
    unused slots joint 0 with weight 0, rows summing to 1. ValueError for wider skins."""
    count, width = bone_indices.shape
    if width > GLTF_INFLUENCES:
        heavy = int(np.count_nonzero(bone_weights > 0.0, axis=1).max())
        if heavy > GLTF_INFLUENCES:
            raise ValueError(f"the skin has up to {heavy} influences per vertex, and glTF carries "
                             f"{GLTF_INFLUENCES}: fit it again with --max-influences {GLTF_INFLUENCES}")
    order = np.argsort(-bone_weights, axis=1, kind="stable")[:, :GLTF_INFLUENCES]
    weights = np.take_along_axis(bone_weights, order, axis=1)
    joints = np.take_along_axis(bone_indices, order, axis=1).astype(np.int64) + 1
    joints[weights <= 0.0] = 0
    weights = np.where(weights > 0.0, weights, 0.0)
    if weights.shape[1] < GLTF_INFLUENCES:
        pad = GLTF_INFLUENCES - weights.shape[1]
        weights = np.pad(weights, ((0, 0), (0, pad)))
        joints = np.pad(joints, ((0, 0), (0, pad)))
    return joints, weights / weights.sum(axis=1, keepdims=True)


def quantized_weights(weights, bits):
    """weights (V, 4) as unsigned normalised integers of ``bits`` (8 or 16) whose rows sum to
    exactly 2^bits − 1 (what glTF asks of normalised weights): rounded, then the rounding's
    remainder given to the heaviest slot (the first). Returns uint8 or uint16 (V, 4)."""
    top = (1 << bits) - 1
    levels = np.rint(np.asarray(weights, dtype=np.float64) * top).astype(np.int64)
    levels[:, 0] += top - levels.sum(axis=1)
    return levels.astype(np.uint8 if bits == 8 else np.uint16)


def float_weights(weights):
    """weights (V, 4) float32 whose rows sum to 1 as closely as float32 holds (the remainder of
    the rounding to float32 given to the heaviest slot)."""
    out = np.asarray(weights, dtype=np.float32).copy()
    out[:, 0] += (1.0 - out.astype(np.float64).sum(axis=1)).astype(np.float32)
    return out


def to_gltf_axes(up_axis, meters_per_unit):
    """(rotation (3, 3), scale): what takes a scene of ``up_axis`` ("Y"/"Z") and units of
    ``meters_per_unit`` to glTF's, Y up in metres (Z up: x, y, z → x, z, −y)."""
    rotation = np.eye(3) if up_axis == "Y" else np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
    return rotation, float(meters_per_unit)


def _converted(up_axis, meters_per_unit, points):
    rotation, scale = to_gltf_axes(up_axis, meters_per_unit)
    return scale * (np.asarray(points, dtype=np.float64) @ rotation.T)


def gltf_rig(rest_vertices, faces, bone_indices, bone_weights, centres, up_axis="Y", meters_per_unit=1.0,
             quantize=None, face_uvs=None, morph_targets=None, parents=None, jointed=None, names=None):
    """What a glTF skin needs of a fitted rig, in glTF's axes and metres (:func:`to_gltf_axes`):
    {positions, normals (V, 3), faces, joints (V, 4), weights (V, 4) (float32, or ``quantize`` 8
    or 16 bits), inverse_binds (B + 1, 4, 4), bind_translations (B + 1, 3), joint_names}: joint 0
    the root ("root"), joint j + 1 bone j ("bone_NNN"). rest_vertices (V, 3); bone_indices and
    bone_weights (V, K); centres (B, 3) the bones' rest centres. ValueError for more than four
    influences per vertex.

    ``face_uvs`` (T, 3, 2), the material UVs per face corner (v up), adds ``uvs`` (V', 2) in
    glTF's convention (u, 1 − v) and splits the vertices at UV seams
    (:func:`.uv_seams.split_uv_seams`: the V originals first, then the copies); every per-vertex
    array then has V' rows, a copy's position, normal (the unsplit mesh's, so shading stays
    smooth across a seam), joints and weights its original's. The joints and binds are unchanged.

    ``morph_targets`` (k, V, 3), rest-pose displacements in the rig's axes and units (a puppet's
    correctives, :mod:`.morph_targets`), adds ``morph_targets`` (k, V', 3) in glTF's: they turn
    and scale as positions do (no translation), and a copy at a seam takes its original's.

    ``parents`` (B,), a skeleton's tree (−1 for the root bone; ``centres`` then its joints), makes
    the joints that tree (module notes): ``parents`` (B + 1,) each joint's parent joint
    (:func:`joint_parents`), ``bind_translations`` local to it (:func:`rest_locals`) and the
    bones named ``names`` (B,) or by :func:`joint_names` (``jointed`` (B,) marks the free bones); the inverse
    binds are the same translations by −c_j."""
    from ..mesh.geometry import vertex_normals

    positions = _converted(up_axis, meters_per_unit, rest_vertices)
    normals = vertex_normals(positions[None], faces)[0]
    normals[np.linalg.norm(normals, axis=1) == 0.0] = (0.0, 1.0, 0.0)  # glTF normals are unit vectors
    joints, weights = four_influences(np.asarray(bone_indices), np.asarray(bone_weights, dtype=np.float64))
    weights = float_weights(weights) if quantize is None else quantized_weights(weights, quantize)
    joints[weights == 0] = 0  # a slot whose weight rounded to nothing names no joint
    bone_centres = _converted(up_axis, meters_per_unit, centres)
    rig = {"positions": positions, "normals": normals, "faces": np.asarray(faces), "joints": joints,
           "weights": weights, "inverse_binds": inverse_bind_matrices(bone_centres),
           "bind_translations": np.vstack([np.zeros((1, 3)), bone_centres]),
           "joint_names": ["root"] + [f"bone_{j:03d}" for j in range(len(centres))]}
    if parents is not None:
        rig.update(parents=joint_parents(parents), joint_names=["root"] + (list(names) if names is not None
                                                                           else joint_names(parents, jointed)),
                   bind_translations=np.vstack([np.zeros((1, 3)), rest_locals(bone_centres, parents)]))
    if morph_targets is not None:
        rig["morph_targets"] = _converted(up_axis, meters_per_unit, morph_targets)
    if face_uvs is not None:
        from ..mesh.uv_seams import gltf_texcoords, split_uv_seams

        vertex_map, split_faces, uvs = split_uv_seams(faces, face_uvs, len(positions))
        rig.update({name: rig[name][vertex_map] for name in ("positions", "normals", "joints", "weights")},
                   faces=split_faces, uvs=gltf_texcoords(uvs))
        if morph_targets is not None:
            rig["morph_targets"] = rig["morph_targets"][:, vertex_map]
    return rig


def ground_motion(rotations, translations, rest, bone_indices, bone_weights, up):
    """The root's world transform under ``--root-motion``: the character's ground motion as
    synthesize's ground alignment defines it (:func:`.rotations.heading_and_posture`), the turn
    about ``up`` (3,) and the ground-plane shift of the most influential bone about its rest
    centroid. rotations (F, B, 3, 3), translations (F, B, 3), rest (V, 3), bone_indices and
    bone_weights (V, K) -> (rotations (F, 3, 3), translations (F, 3))."""
    bones = rotations.shape[1]
    bone = most_influential_bone(bone_indices, bone_weights, bones)
    pivot = bone_centroids(rest, bone_indices, bone_weights, bones)[bone]
    turn, shift, _, _ = heading_and_posture(rotations[:, bone], translations[:, bone], pivot, up)
    return turn, shift


def gltf_clip(name, rotations, translations, centres, fps, up_axis="Y", meters_per_unit=1.0, ground=None,
              parents=None):
    """One glTF animation clip of an LBS animation: rotations (F, B, 3, 3), translations (F, B, 3)
    in the rig's axes and units, as :func:`gltf_rig`; {name, times (F,) seconds at ``fps``,
    rotations (F, B, 4) (x, y, z, w), translations (F, B, 3)} local to the root. ``ground``: the
    rig's (rest (V, 3), bone_indices, bone_weights) to give the root the ground motion
    (:func:`ground_motion`, Y up) and ``root_rotations`` (F, 4), ``root_translations`` (F, 3);
    None for a root fixed at the origin. ``parents`` (B,): a skeleton's tree, as :func:`gltf_rig`'s
    (``centres`` its joints): each bone local to its parent joint (:func:`tree_locals`)."""
    rotation, scale = to_gltf_axes(up_axis, meters_per_unit)
    turned = np.einsum("ij,fbjk,lk->fbil", rotation, np.asarray(rotations, dtype=np.float64), rotation)
    moved = scale * (np.asarray(translations, dtype=np.float64) @ rotation.T)
    root_r = root_t = None
    if ground is not None:
        rest, bone_indices, bone_weights = ground
        root_r, root_t = ground_motion(turned, moved, _converted(up_axis, meters_per_unit, rest), bone_indices,
                                       bone_weights, np.array([0.0, 1.0, 0.0]))
    joints = _converted(up_axis, meters_per_unit, centres)
    if parents is None:
        quaternions, locals_ = joint_locals(turned, moved, joints, root_r, root_t)
    else:
        quaternions, locals_ = tree_locals(turned, moved, joints, parents, root_r, root_t)
    clip = {"name": name, "times": np.arange(len(turned)) / float(fps), "rotations": quaternions,
            "translations": locals_}
    if ground is not None:
        clip.update(root_rotations=_xyzw(root_r), root_translations=root_t)
    return clip


def gltf_scene(skin, clips, up_axis, quantize=None, root_motion=False, morph=None, skeleton=None):
    """A skin's rig and ``clips`` ((name, rotations (F, B, 3, 3), translations (F, B, 3)), consumed
    in order) as a glTF skinned scene's arrays, in glTF's Y up and metres from ``up_axis`` and the
    skin's metersPerUnit: (rig, clips, morph target names or None). ``skin``: rest_vertices,
    faces, bone_indices, bone_weights, bone_rest_frames, face_uvs, fps, scene. rig:
    :func:`gltf_rig`'s (UVs split at seams; ``quantize`` 8 or 16 bit weights); clips: a generator
    of :func:`gltf_clip`'s, each with its ``morph_weights`` ((F, 2k) or None); ``root_motion``: the
    ground motion on the root. ``morph``: (targets (k, V, 3), weights [(F, k) per clip, in the
    clips' order]), rest-pose displacements in the skin's axes and units played before skinning (a
    puppet's correctives, :mod:`.morph_targets`), as 2k targets "corrective_Np" and
    "corrective_Nn", ± pairs weighted in [0, 1] (:func:`.morph_targets.unit_range_pairs`:
    Blender's importer clamps weights to a range it takes from the first key); None for none.
    ``skeleton``: the skin's /skin/skeleton (``skin.skeleton``), the joints as its tree at its
    joints (:func:`tree_locals`); None: every bone under the root, at its rest centre. ValueError
    (:func:`gltf_rig`) for a rig glTF cannot hold."""
    if morph is not None:  # one scale per target over every clip: the targets are shared
        from .morph_targets import unit_range_pairs

        lengths = [len(w) for w in morph[1]]
        targets, weights = unit_range_pairs(morph[0], np.concatenate(morph[1]))
        morph = targets, np.split(weights, np.cumsum(lengths)[:-1])
    centres = skin.bone_rest_frames[:, :3, 3] if skeleton is None else skeleton["joints"]
    parents, jointed = (None, None) if skeleton is None else (skeleton["parents"], skeleton["jointed"])
    axes = dict(up_axis=up_axis, meters_per_unit=skin.scene.meters_per_unit)
    rig = gltf_rig(skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights, centres, **axes,
                   quantize=quantize, face_uvs=skin.face_uvs,  # UVs split at seams (pipeline.uv_seams)
                   morph_targets=None if morph is None else morph[0], parents=parents, jointed=jointed,
                   names=None if skeleton is None else bone_names(skeleton))
    ground = (skin.rest_vertices, skin.bone_indices, skin.bone_weights) if root_motion else None
    morph_weights = iter(() if morph is None else morph[1])
    animations = ({**gltf_clip(name, rotations, translations, centres, skin.fps, **axes, ground=ground,
                             parents=parents), "morph_weights": None if morph is None else next(morph_weights)}
                  for name, rotations, translations in clips)
    names = None if morph is None else [f"corrective_{i}{s}" for i in range(len(morph[0]) // 2) for s in "pn"]
    return rig, animations, names


def bone_texels(rotations, translations):
    """What a bone-animation texture holds of one animation: (F, B, 2, 4) float64, per frame and
    bone the LBS transform itself, texel 0 its rotation as a unit quaternion (x, y, z, w) (each
    bone's sequence on one hemisphere, so that a shader blending two frames takes the short way)
    and texel 1 its translation (x, y, z, 1). A vertex shader then skins rest position r with
    v = Σ_k w_k (rotate(q_k, r) + t_k) over the vertex's four influences; rotate(q, r) =
    r + 2 q.xyz × (q.xyz × r + q.w r)."""
    quaternions = _xyzw(rotations)
    texels = np.empty(quaternions.shape[:2] + (2, 4))
    texels[:, :, 0] = quaternions
    texels[:, :, 1, :3], texels[:, :, 1, 3] = translations, 1.0
    return texels


def texture_influences(bone_indices, bone_weights):
    """(bones (V, 4), weights (V, 4)) for a bone-animation texture's rest mesh: the four heaviest
    influences, heaviest first, bone ids as fitted (unused slots bone 0 with weight 0), rows
    summing to 1. ValueError for more than four per vertex (as :func:`four_influences`)."""
    joints, weights = four_influences(bone_indices, bone_weights)
    return np.maximum(joints - 1, 0), weights
