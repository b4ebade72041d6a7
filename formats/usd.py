"""USD animation caches: baked point caches and UsdSkel skeletons, and reading them back.

Skinning convention of skinsynth (column vectors): for vertex i with influences k,
``v_i(t) = sum_k w_ik (R_b(t) @ rest_i + t_b(t))``, b = bone_indices[i, k].
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import re
import sys
import tempfile

import numpy as np

from skinsynth.formats.atomic import Interrupted, atomic_output, held_signals
from skinsynth.formats.errors import FormatError, declared_size_problem, require_finite
from skinsynth.formats.meshseq import USD_EXTENSIONS, fan_corners
from skinsynth.formats.validation import tree_depths

# pxr loads the Python modules of the C++ libraries it uses as it is imported, through Tf's C++
# module loader, which catches what they raise, prints it and goes on: a signal's exception raised
# there left pxr half-loaded (its warnings, then "TypeError: No to_python (by-value) converter found
# for C++ type: ArResolverContext" and a traceback). So pxr is imported with SIGINT, SIGTERM and
# SIGHUP held back, and one that arrived meanwhile stops the command once pxr is whole.
with held_signals() as _arrived:
    from pxr import Gf, Sdf, Tf, Usd, UsdGeom, UsdSkel, Vt
if _arrived:
    raise Interrupted(_arrived[0])

#: Unsaved time samples (bytes) after which a binary crowd's layer is saved and let go of them
#: (:func:`write_points_characters`).
SAVE_EVERY_BYTES = 256 << 20


def _reader(read):
    """A reader of a USD file (its first argument): whatever pxr raises or prints while the file
    is read becomes one FormatError line (:func:`_reading`)."""
    @functools.wraps(read)
    def reader(path, *args, **kwargs):
        with _reading(path):
            return read(path, *args, **kwargs)
    return reader


# ---------------------------------------------------------------- writing


def write_points_cache(path, vertices, faces, fps, prim_name=None, up_axis=None, scene=None, clips=None) -> None:
    """Write vertices (F, V, 3) and faces (T, 3) as a Mesh with points at time codes start..start+F-1.

    ``scene`` (:class:`~skinsynth.formats.scene.Scene`, default: 1 m per unit, Y up, from 0, at
    ``/mesh``) gives the stage's metersPerUnit, upAxis and first time code and the mesh's path
    (parents become Xforms); ``prim_name`` (``/<prim_name>``) and ``up_axis`` override it. The
    encoding (.usda text, .usdc/.usd binary) follows the extension. ``clips``: (names (C,), frame
    counts (C,)) of the takes the frames hold end to end; with two or more, the stage's layer
    metadata says where each one begins and ends (:data:`CLIPS_KEY`); None (or one clip) writes
    none. Raises ValueError for malformed arrays; nothing is left on disk when writing fails.
    """
    scene = _scene(scene, up_axis, prim_name)
    vertices = _float_array("vertices", vertices, (None, None, 3), path)
    write_points_characters(path, vertices[None], faces, fps, names=[scene.prim_name], group=None, scene=scene,
                            clips=clips)


def write_points_caches(folder, animations, faces, fps, up_axis=None, scene=None):
    """Write each (name, vertices (F, V, 3)) of ``animations`` as ``folder``/name.usdc
    (:func:`write_points_cache`) as it passes, and pass it on: one pass over animations made on
    demand (skinned, say) also feeds another writer. A generator; nothing is written until it
    is consumed."""
    for name, vertices in animations:
        write_points_cache(os.path.join(folder, f"{name}.usdc"), vertices, faces, fps, up_axis=up_axis, scene=scene)
        yield name, vertices


def write_points_characters(path, vertices, faces, fps, names=None, up_axis=None, group="characters",
                            scene=None, clips=None) -> None:
    """Several baked characters as Meshes ``/<group>/<name>`` (group None: the one mesh at the
    scene's prim path). ``scene``, ``up_axis`` and ``clips`` as :func:`write_points_cache`.

    vertices: an array (C, F, V, 3), or any sequence whose item c is character c's (F, V, 3) —
    e.g. a lazy one that skins each character only when it is written, so a crowd never has to
    fit in memory at once.
    """
    if isinstance(vertices, np.ndarray) or not hasattr(vertices, "__getitem__"):
        vertices = _float_array("vertices", vertices, (None, None, None, 3), path)
    characters = len(vertices)
    first = _float_array("vertices[0]", vertices[0], (None, None, 3), path)
    frames, count = first.shape[:2]
    faces = _faces("faces", faces, count)
    scene = _scene(scene, up_axis)
    names = _character_names(names, characters)
    _check_common(path, fps, group or names[0], scene.up_axis, frames)
    start = scene.start_frame

    # float32 points and a float extent per frame and character (usda text takes several times that)
    expected = characters * frames * (count * 12 + 48) * (6 if str(path).lower().endswith(".usda") else 1)
    with atomic_output(path, expected_bytes=expected + (1 << 20)) as tmp:
        stage = _new_stage(tmp, fps, frames, scene, clips)
        parent = _group_parent(stage, group)
        unsaved, binary = 0, not str(path).lower().endswith(".usda")
        for c, name in enumerate(names):
            character = first if c == 0 else _float_array(f"vertices[{c}]", vertices[c], (frames, count, 3), path)
            mesh_path = Sdf.Path(scene.prim_path) if group is None else parent.AppendChild(name)
            _define_parents(stage, mesh_path)
            mesh = _define_mesh(stage, mesh_path, faces)
            if group is None and c == 0:
                _set_default_prim(stage, mesh.GetPath())
            # One attribute at a time: interleaving Sets on two attributes is ~4x slower in pxr 26.
            points = mesh.GetPointsAttr()
            for frame in range(frames):
                points.Set(Vt.Vec3fArray.FromNumpy(character[frame].astype(np.float32)), Usd.TimeCode(start + frame))
            extent = mesh.GetExtentAttr()
            for frame in range(frames):
                extent.Set(_extent(character[frame]), Usd.TimeCode(start + frame))
            unsaved += frames * (count * 12 + 48)
            if binary and unsaved >= SAVE_EVERY_BYTES and c + 1 < characters:
                # A binary (crate) save appends what changed and leaves the saved samples in the
                # file, read back on demand: the layer stops holding them, so a crowd of any size
                # is written in bounded memory (20 samba-sized characters × 600 frames: 829 → 175
                # MiB peak). A crowd under the bound is saved once, as before; .usda text is
                # always written whole.
                stage.GetRootLayer().Save()
                unsaved = 0
        stage.GetRootLayer().Save()
        del stage  # release the layer before the file is renamed under it


def write_skel_cache(path, rest_vertices, faces, bone_indices, bone_weights, rotations, translations,
                     bind_centers, fps, prim_name=None, up_axis=None, skinning="linear", scene=None,
                     root_motion=None, clips=None, joint_tree=None) -> None:
    """Write a rigid-bone animation as UsdSkel so that UsdSkel's skinning reproduces skinsynth's.

    rest_vertices (V, 3); faces (T, 3); bone_indices (V, K) int and bone_weights (V, K)
    (non-negative, rows summing to 1; written as given, K = elementSize); rotations (F, B, 3, 3)
    and translations (F, B, 3), the per-frame bone transforms; bind_centers (B, 3), each bone's
    joint in the rest pose; skinning "linear" (classicLinear) or "dual-quaternion"; ``scene``,
    ``prim_name`` and ``up_axis`` as :func:`write_points_cache`. Layout: the mesh keeps the
    scene's prim path and its parent becomes the SkelRoot, holding ``Skeleton`` (one root joint
    ``root`` at the origin, the bones ``root/bone_000``... under it) and ``Skeleton/Animation``;
    a mesh at the root (``/mesh``) cannot have a SkelRoot above it, so there the SkelRoot is
    ``/mesh`` and the mesh ``/mesh/Mesh``.

    Each joint's bind transform is a translation to its centre c. In Gf's row-vector form the
    skinning transform is inverse(bind) * joint, and it must equal our A(t) = [R^T 0; t 1]; so
    joint = bind * A(t) = [R^T 0; c R^T + t 1]: the joint turns by R and sits at R c + t.

    ``root_motion``: (rotations (F, 3, 3), translations (F, 3)), the root joint's world transform
    per frame (the bones' are divided by it); None keeps the root at the origin. ``clips`` as
    :func:`write_points_cache`: one timeline, the takes' boundaries in the layer's metadata.

    ``joint_tree``: a :class:`JointTree` (its locals (F, B, 3, 3) and (F, B, 3), this one
    animation's) to write the bones as that tree, ``bind_centers`` then its joints; None: every
    bone under the root.
    """
    scene = _scene(scene, up_axis, prim_name)
    rotations = _float_array("rotations", rotations, (None, None, 3, 3))
    if joint_tree is not None:
        joint_tree = dataclasses.replace(joint_tree, rotations=np.asarray(joint_tree.rotations)[None],
                                         translations=np.asarray(joint_tree.translations)[None])
    write_skel_characters(path, rest_vertices, faces, bone_indices, bone_weights, rotations[None],
                          np.asarray(translations)[None], bind_centers, fps, names=[scene.prim_name],
                          skinning=skinning, group=None, scene=scene, clips=clips,
                          root_motion=None if root_motion is None else tuple(np.asarray(a)[None] for a in root_motion),
                          joint_tree=joint_tree)


SKINNING_METHODS = {"linear": "classicLinear", "dual-quaternion": "dualQuaternion"}
#: A custom attribute of a written Skeleton prim: the joints (paths) that hang from their parent
#: without a joint (a ``fit-skin --skeleton`` rig's free bones); :func:`read_skeleton` reads it.
FREE_JOINTS = "skinsynth:freeJoints"
#: The one root joint of every skeleton written; the bones are ``root/bone_NNN`` (a
#: :class:`JointTree`'s: ``root/<its root bone>/...``, each bone under its parent).
ROOT_JOINT = "root"


@dataclasses.dataclass
class JointTree:
    """A rig whose bones are a tree under the root joint, as ``pipeline.skeleton`` computes it
    (this module lays it out): ``parents`` (B,) each bone's parent bone, −1 for the one bone
    under the root joint; ``names`` (B,) the bones' joint names (USD identifiers); ``rest`` (B, 3)
    each bone's rest translation local to its parent joint; ``rotations`` (C, F, B, 3, 3) and
    ``translations`` (C, F, B, 3), each bone's joint transform local to its parent joint per
    character and frame (the top bone's local to the root joint, whose own transform is the
    writer's ``root_motion`` or the identity). The bind transforms stay world translations to
    the joints (the writer's ``bind_centers``)."""

    parents: np.ndarray
    names: list
    rest: np.ndarray
    rotations: np.ndarray
    translations: np.ndarray
    free: np.ndarray | None = None  # (B,) bool: bones that hang from their parent without a joint

    def order(self):
        """The bones in UsdSkel's joint order (every parent before its children: by depth, then
        by bone id), (B,) int64; ValueError unless the parents are one tree."""
        parents = np.asarray(self.parents, dtype=np.int64)
        if np.count_nonzero(parents < 0) != 1 or (parents >= len(parents)).any():
            raise ValueError(f"a joint tree has one bone under the root joint (parent -1), got {parents.tolist()}")
        depth = tree_depths(parents)
        if (depth < 0).any():
            raise ValueError("the joint tree's parents are not a tree (a cycle)")
        return np.argsort(depth, kind="stable")

    def paths(self, order):
        """The joints' paths for UsdSkel (``root/<top bone>/.../<bone>``), in ``order``."""
        paths = {}
        for bone in order:
            parent = self.parents[bone]
            paths[bone] = (ROOT_JOINT if parent < 0 else paths[parent]) + "/" + self.names[bone]
        return [paths[bone] for bone in order]


def write_skel_characters(path, rest_vertices, faces, bone_indices, bone_weights, rotations, translations,
                          bind_centers, fps, names=None, up_axis=None, skinning="linear", group="characters",
                          blend_shapes=None, scene=None, root_motion=None, clips=None, joint_tree=None) -> None:
    """Several characters sharing one rig, each with its own bone animation, as UsdSkel.

    rotations (C, F, B, 3, 3), translations (C, F, B, 3); the rest as :func:`write_skel_cache`.
    Each character is a SkelRoot ``/<group>/<name>`` holding its ``Mesh`` (group None: one
    character laid out as :func:`write_skel_cache`; names default to character_000...). World
    placement is part of the bone transforms. ``scene``, ``up_axis`` and ``clips`` as
    :func:`write_points_cache`.
    blend_shapes: optional (offsets (S, V, 3), weights (C, F, S), names (S,)): rest-pose offsets
    that UsdSkel adds, weighted per frame, before skinning (a puppet's pose-space correctives, as
    ± pairs with weights in [0, 1], ``pipeline.morph_targets.unit_range_pairs``: Blender's shape
    keys clamp to [0, 1]); the shapes are written once, under the first character's mesh, and
    every character's mesh targets them.
    joint_tree: a :class:`JointTree` to write the bones as that tree (``bind_centers`` its joints;
    the joints in UsdSkel's order, parents first, and the meshes' joint indices to match), None
    for every bone under the root.
    """
    rest = _float_array("rest_vertices", rest_vertices, (None, 3))
    count = len(rest)
    faces = _faces("faces", faces, count)
    rotations = _float_array("rotations", rotations, (None, None, None, 3, 3), path)
    characters, frames, bones = rotations.shape[:3]
    translations = _float_array("translations", translations, (characters, frames, bones, 3), path)
    centers = _float_array("bind_centers", bind_centers, (bones, 3))
    indices, weights = _influences(bone_indices, bone_weights, count, bones)
    _check_rotations(rotations.reshape(-1, bones, 3, 3))
    scene = _scene(scene, up_axis)
    names = _character_names(names, characters)
    if skinning not in SKINNING_METHODS:
        raise ValueError(f"skinning must be one of {', '.join(SKINNING_METHODS)}, got {skinning!r}")
    _check_common(path, fps, group or names[0], scene.up_axis, frames)
    start = scene.start_frame
    shape_offsets = shape_weights = None
    if blend_shapes is not None:
        shape_offsets = _float_array("blend shape offsets", blend_shapes[0], (None, count, 3), path)
        shape_weights = _float_array("blend shape weights", blend_shapes[1],
                                     (characters, frames, shape_offsets.shape[0]), path)
        if len(blend_shapes[2]) != len(shape_offsets):
            raise ValueError(f"{len(blend_shapes[2])} blend shape names for {len(shape_offsets)} shapes")
        shape_names = Vt.TokenArray(list(blend_shapes[2]))

    # One root joint with every bone under it (engines such as Unreal refuse several roots); the
    # root stays at the origin, so each bone's parent-local transform is its world transform.
    # A joint tree: the bones under it as the tree says, in UsdSkel's order (parents first).
    order = np.arange(bones) if joint_tree is None else _checked_tree(joint_tree, characters, frames, bones, path)
    joints = Vt.TokenArray([ROOT_JOINT] + ([f"{ROOT_JOINT}/bone_{b:03d}" for b in range(bones)] if joint_tree is None
                                           else joint_tree.paths(order)))
    bind = np.tile(np.eye(4), (bones + 1, 1, 1))
    bind[1:, 3, :3] = centers[order]
    rest_transforms = None
    if joint_tree is not None:
        rest_transforms = np.tile(np.eye(4), (bones + 1, 1, 1))
        rest_transforms[1:, 3, :3] = np.asarray(joint_tree.rest, dtype=np.float64)[order]
        rest_transforms = Vt.Matrix4dArray.FromNumpy(rest_transforms)
    bind = Vt.Matrix4dArray.FromNumpy(bind)
    ones = Vt.Vec3hArray.FromNumpy(np.ones((bones + 1, 3), dtype=np.float16))
    if joint_tree is not None:  # bone b is the joint at its place in the order
        position = np.empty(bones, dtype=np.int32)
        position[order] = np.arange(bones)
        indices = position[indices]
    indices = indices + 1  # joint 0 is the root, which carries no vertex

    with atomic_output(path) as tmp:
        stage = _new_stage(tmp, fps, frames, scene, clips)
        parent = _group_parent(stage, group)
        for c, name in enumerate(names):
            root_path, mesh_path = _skel_paths(parent, name, scene if group is None else None)
            _define_parents(stage, root_path)
            UsdSkel.Root.Define(stage, root_path)
            if group is None and c == 0:
                _set_default_prim(stage, root_path)
            root = None if root_motion is None else (root_motion[0][c], root_motion[1][c])
            tree = None if joint_tree is None else (joint_tree.rotations[c][:, order],
                                                    joint_tree.translations[c][:, order], rest_transforms)
            animation = _define_skeleton(stage, root_path, joints, bind, ones, rotations[c], translations[c], centers,
                                         start, root, tree)
            if joint_tree is not None and joint_tree.free is not None and np.any(joint_tree.free):
                free = [str(joints[1 + i]) for i, bone in enumerate(order) if joint_tree.free[bone]]
                stage.GetPrimAtPath(root_path.AppendChild("Skeleton")).CreateAttribute(
                    FREE_JOINTS, Sdf.ValueTypeNames.TokenArray, custom=True).Set(Vt.TokenArray(free))
            mesh = _define_mesh(stage, mesh_path, faces)
            mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(rest.astype(np.float32)))
            mesh.GetExtentAttr().Set(_extent(rest))
            binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
            binding.CreateSkeletonRel().SetTargets([root_path.AppendChild("Skeleton")])
            element_size = indices.shape[1]
            binding.CreateJointIndicesPrimvar(False, element_size).Set(Vt.IntArray.FromNumpy(indices.ravel()))
            binding.CreateJointWeightsPrimvar(False, element_size).Set(Vt.FloatArray.FromNumpy(weights.ravel()))
            binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))
            binding.CreateSkinningMethodAttr(SKINNING_METHODS[skinning])
            if shape_offsets is not None:
                if c == 0:
                    shape_paths = [mesh.GetPath().AppendChild(n) for n in shape_names]
                    for shape_path, offsets in zip(shape_paths, shape_offsets):
                        UsdSkel.BlendShape.Define(stage, shape_path).CreateOffsetsAttr(
                            Vt.Vec3fArray.FromNumpy(offsets.astype(np.float32)))
                binding.CreateBlendShapesAttr(shape_names)
                binding.CreateBlendShapeTargetsRel().SetTargets(shape_paths)
                animation.CreateBlendShapesAttr(shape_names)
                attribute = animation.CreateBlendShapeWeightsAttr()
                for frame in range(frames):
                    attribute.Set(Vt.FloatArray.FromNumpy(shape_weights[c, frame].astype(np.float32)),
                                  Usd.TimeCode(start + frame))
        stage.GetRootLayer().Save()
        del stage


def _define_skeleton(stage, root_path, joints, bind, ones, rotations, translations, centers, start=0.0, root=None,
                     tree=None):
    """Skeleton and Animation of one character: rotations (F, B, 3, 3), translations (F, B, 3);
    root None (the root joint at the origin) or its (rotations (F, 3, 3), translations (F, 3)).
    tree: (local rotations (F, B, 3, 3), local translations (F, B, 3), rest transforms (B + 1))
    of a joint tree, in the joints' order, written as they are; None: the bones under the root.
    Returns the UsdSkel.Animation."""
    frames, bones = rotations.shape[:2]
    if tree is not None:  # the joints' parent-local transforms as given (pipeline.skeleton's)
        rotations, joint_translations = np.asarray(tree[0], dtype=np.float64), tree[1]
    else:
        joint_translations = np.einsum("fbij,bj->fbi", rotations, centers) + translations
        if root is not None:  # each bone local to the moving root: root⁻¹ ∘ world
            inverse = np.swapaxes(np.asarray(root[0], dtype=np.float64), -1, -2)
            rotations = np.einsum("fij,fbjk->fbik", inverse, rotations)
            joint_translations = np.einsum("fij,fbj->fbi", inverse, joint_translations - np.asarray(root[1])[:, None])
    if root is not None:
        rotations = np.concatenate([np.asarray(root[0])[:, None], rotations], axis=1)
    joint_matrices = np.zeros((rotations.shape[0] * rotations.shape[1], 4, 4))
    joint_matrices[:, :3, :3] = rotations.reshape(-1, 3, 3).transpose(0, 2, 1)  # row-vector form
    joint_matrices[:, 3, 3] = 1.0
    # UsdSkel's own decomposition gives quaternions in its conventions, in one C++ call.
    _, quats, _ = UsdSkel.DecomposeTransforms(Vt.Matrix4dArray.FromNumpy(joint_matrices))
    quats = np.asarray(quats, dtype=np.float32).reshape(frames, -1, 4)  # x, y, z, w

    skeleton = UsdSkel.Skeleton.Define(stage, root_path.AppendChild("Skeleton"))
    skeleton.CreateJointsAttr(joints)
    skeleton.CreateJointNamesAttr(joints)
    skeleton.CreateBindTransformsAttr(bind)
    # the root at the origin: parent-local equals world; a tree's rest transforms are its own
    skeleton.CreateRestTransformsAttr(bind if tree is None else tree[2])

    animation = UsdSkel.Animation.Define(stage, skeleton.GetPath().AppendChild("Animation"))
    animation.CreateJointsAttr(joints)
    anim_translations = animation.CreateTranslationsAttr()
    anim_rotations = animation.CreateRotationsAttr()
    animation.CreateScalesAttr(ones)  # without scales DCCs ignore the animation
    root_translations = np.zeros((frames, 1, 3)) if root is None else np.asarray(root[1])[:, None]
    joint_translations = np.concatenate([root_translations, joint_translations], axis=1).astype(np.float32)
    if root is None:
        quats = np.concatenate([np.tile(np.array([0.0, 0.0, 0.0, 1.0], np.float32), (frames, 1, 1)), quats], axis=1)
    for frame in range(frames):  # one attribute at a time, as in write_points_cache
        anim_translations.Set(Vt.Vec3fArray.FromNumpy(joint_translations[frame]), Usd.TimeCode(start + frame))
    for frame in range(frames):
        anim_rotations.Set(Vt.QuatfArray.FromNumpy(np.ascontiguousarray(quats[frame])), Usd.TimeCode(start + frame))
    UsdSkel.BindingAPI.Apply(skeleton.GetPrim()).CreateAnimationSourceRel().SetTargets([animation.GetPath()])
    return animation


def _checked_tree(tree, characters, frames, bones, path):
    """A :class:`JointTree`'s joint order, after checking its shapes (ValueError) and values."""
    if len(tree.parents) != bones or len(tree.names) != bones:
        raise ValueError(f"a joint tree of {len(tree.parents)} parents and {len(tree.names)} names for {bones} bones")
    if not all(Sdf.Path.IsValidIdentifier(n) for n in tree.names):
        raise ValueError(f"joint names must be USD identifiers, got {list(tree.names)!r}")
    _float_array("joint tree rest", tree.rest, (bones, 3), path)
    _float_array("joint tree rotations", tree.rotations, (characters, frames, bones, 3, 3), path)
    _float_array("joint tree translations", tree.translations, (characters, frames, bones, 3), path)
    return tree.order()


def _character_names(names, characters):
    names = [f"character_{c:03d}" for c in range(characters)] if names is None else list(names)
    if len(names) != characters or not all(Sdf.Path.IsValidIdentifier(n) for n in names):
        raise ValueError(f"need {characters} valid USD identifiers as names, got {names!r}")
    return names


def _group_parent(stage, group):
    """Where characters go: the pseudo-root, or a default-prim Xform ``/<group>``."""
    if group is None:
        return Sdf.Path.absoluteRootPath
    parent = Sdf.Path("/" + group)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, parent).GetPrim())
    return parent


def _scene(scene, up_axis=None, prim_name=None):
    """The writer's Scene: ``scene`` (default Scene()) with ``up_axis`` and ``prim_name`` applied."""
    from dataclasses import replace

    from skinsynth.formats.scene import Scene

    scene = Scene() if scene is None else scene
    if up_axis is not None:
        scene = replace(scene, up_axis=up_axis)
    if prim_name is not None:
        scene = replace(scene, prim_path="/" + prim_name)
    if not Sdf.Path.IsValidPathString(scene.prim_path) or not Sdf.Path(scene.prim_path).IsAbsolutePath() \
            or not Sdf.Path(scene.prim_path).IsPrimPath():
        raise ValueError(f"prim path {scene.prim_path!r} is not an absolute USD prim path")
    return scene


def _skel_paths(parent, name, scene):
    """(SkelRoot path, mesh path) of a character: ``/<group>/<name>`` and its ``Mesh``, or for a
    single rig (scene given) the scene's mesh path under its parent as SkelRoot (a root-level
    mesh ``/m`` cannot have one: SkelRoot ``/m``, mesh ``/m/Mesh``)."""
    if scene is None:
        root = parent.AppendChild(name)
        return root, root.AppendChild("Mesh")
    mesh = Sdf.Path(scene.prim_path)
    if mesh.GetParentPath() == Sdf.Path.absoluteRootPath:
        return mesh, mesh.AppendChild("Mesh")
    return mesh.GetParentPath(), mesh


def _define_parents(stage, path):
    """Ancestors of ``path`` that do not exist yet become Xforms (DCCs expect transformable parents)."""
    for ancestor in Sdf.Path(path).GetParentPath().GetPrefixes():  # top first
        if not stage.GetPrimAtPath(ancestor).IsValid():
            UsdGeom.Xform.Define(stage, ancestor)


def _set_default_prim(stage, path):
    """The default prim is the root-level ancestor of ``path`` (USD wants a root prim)."""
    stage.SetDefaultPrim(stage.GetPrimAtPath(Sdf.Path(path).GetPrefixes()[0]))


#: The layer metadata (customLayerData) that holds the clips of a stage whose frames are several
#: takes end to end: {names: string[], startTimeCodes: double[], endTimeCodes: double[]}, one
#: entry per clip in timeline order (each clip's first and last time code, inclusive).
CLIPS_KEY = "skinsynth:clips"


def clip_time_codes(clips, frames, start):
    """{names, startTimeCodes, endTimeCodes} of ``clips`` (names (C,), frame counts (C,)) over
    ``frames`` frames from time code ``start``; ValueError when the counts do not sum to them."""
    names, counts = (list(part) for part in clips)
    counts = np.asarray(counts, dtype=np.int64)
    if len(names) != len(counts) or counts.size == 0 or np.any(counts < 1) or int(counts.sum()) != frames:
        raise ValueError(f"clips {names} of {counts.tolist()} frames do not divide the {frames} frames")
    ends = np.cumsum(counts)
    return {"names": [str(n) for n in names], "startTimeCodes": (start + ends - counts).astype(float).tolist(),
            "endTimeCodes": (start + ends - 1).astype(float).tolist()}


@_reader
def read_clips(path):
    """The clips a stage's metadata names (:data:`CLIPS_KEY`): [(name, first, last time code)],
    or [] for a stage without them."""
    stage = _open(path)  # held: the layer lives as long as its stage
    entry = stage.GetRootLayer().customLayerData.get(CLIPS_KEY)
    if not entry:
        return []
    return [(str(n), float(a), float(b)) for n, a, b in zip(entry["names"], entry["startTimeCodes"],
                                                             entry["endTimeCodes"])]


def _new_stage(tmp, fps, frames, scene, clips=None):
    table = None if clips is None or len(clips[0]) < 2 else clip_time_codes(clips, frames, scene.start_frame)
    stage = Usd.Stage.CreateNew(tmp)
    if table is not None:  # only then: a one-clip stage is written byte for byte as before clips
        stage.GetRootLayer().customLayerData = {CLIPS_KEY: {
            "names": Vt.StringArray(table["names"]), "startTimeCodes": Vt.DoubleArray(table["startTimeCodes"]),
            "endTimeCodes": Vt.DoubleArray(table["endTimeCodes"])}}
    stage.SetTimeCodesPerSecond(fps)
    stage.SetFramesPerSecond(fps)
    stage.SetStartTimeCode(scene.start_frame)
    stage.SetEndTimeCode(scene.start_frame + frames - 1)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if scene.up_axis == "Y" else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, scene.meters_per_unit)
    return stage


def _define_mesh(stage, path, faces):
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)  # else DCCs subdivide the cage
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, dtype=np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.astype(np.int32).ravel()))
    mesh.CreatePointsAttr()
    mesh.CreateExtentAttr()
    return mesh


def _extent(points):
    return Vt.Vec3fArray.FromNumpy(np.stack([points.min(axis=0), points.max(axis=0)]).astype(np.float32))


# ---------------------------------------------------------------- argument checks (programming errors)


def _float_array(name, values, shape, path=None):
    """values as float64 of ``shape`` (None: any size); ValueError for a wrong shape; NaN or inf
    is a FormatError naming ``path`` when given (a result out of range), else a ValueError."""
    array = np.asarray(values, dtype=np.float64)
    if array.ndim != len(shape) or any(want is not None and got != want for got, want in zip(array.shape, shape)):
        wanted = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {wanted}, got {array.shape}")
    if path is not None:
        require_finite(path, name, array)
    elif not np.isfinite(array).all():
        raise ValueError(f"{name} contains NaN or inf")
    return array


def _faces(name, faces, count):
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise ValueError(f"{name} must be integers of shape (T, 3), got {faces.dtype} {faces.shape}")
    if faces.size and (faces.min() < 0 or faces.max() >= count):
        raise ValueError(f"{name} index outside [0, {count})")
    return faces


def _influences(bone_indices, bone_weights, count, bones):
    indices = np.asarray(bone_indices)
    weights = np.asarray(bone_weights, dtype=np.float64)
    if indices.ndim != 2 or indices.shape[0] != count or not np.issubdtype(indices.dtype, np.integer):
        raise ValueError(f"bone_indices must be integers of shape ({count}, K), got {indices.dtype} {indices.shape}")
    if weights.shape != indices.shape:
        raise ValueError(f"bone_weights must have the shape of bone_indices {indices.shape}, got {weights.shape}")
    if indices.min() < 0 or indices.max() >= bones:
        raise ValueError(f"bone_indices outside [0, {bones})")
    if not np.isfinite(weights).all() or weights.min() < 0:
        raise ValueError("bone_weights must be finite and non-negative")
    if not np.allclose(weights.sum(axis=1), 1.0, atol=1e-5):
        raise ValueError("bone_weights rows must sum to 1 (UsdSkel does not normalise them)")
    return indices.astype(np.int32), weights.astype(np.float32)


def _check_rotations(rotations):
    gram = np.einsum("fbki,fbkj->fbij", rotations, rotations)
    if not np.allclose(gram, np.eye(3), atol=1e-4) or (np.linalg.det(rotations) <= 0).any():
        raise ValueError("rotations must be proper rotation matrices (UsdSkel joints are rigid); "
                         "write affine bones as a points cache")


def _check_common(path, fps, prim_name, up_axis, frames):
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext not in USD_EXTENSIONS:
        raise FormatError(path, f"a USD file must end in {'/'.join(USD_EXTENSIONS)}, not {ext or '(none)'!r}")
    if frames < 1:
        raise ValueError("at least one frame is needed")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be positive, got {fps}")
    if not Sdf.Path.IsValidIdentifier(prim_name):
        raise ValueError(f"prim_name {prim_name!r} is not a valid USD identifier")
    if up_axis not in ("Y", "Z"):
        raise ValueError(f"up_axis must be 'Y' or 'Z', got {up_axis!r}")


# ---------------------------------------------------------------- reading


@_reader
def read_points_cache(path, prim=None) -> tuple[np.ndarray, np.ndarray, float]:
    """Read a time-sampled mesh: (vertices (F, V, 3) float64 world space, faces (T, 3) int64, fps).

    ``prim`` is the mesh's path; by default the first Mesh in traversal with time-sampled points.
    Points are read at every authored time sample; fps is timeCodesPerSecond (24 when unset)
    divided by the sample spacing. Polygons are fan-triangulated. Raises FormatError.
    """
    from skinsynth.formats.meshseq import sequence_from_arrays

    stage = _open(path)
    mesh = _find_mesh(path, stage, prim)
    where = mesh.GetPath()
    times = mesh.GetPointsAttr().GetTimeSamples()
    if len(times) < 2:
        raise FormatError(path, f"{where}: {len(times)} time sample(s) of points; an animation needs at least 2")
    steps = np.diff(times)
    if not np.allclose(steps, steps[0], rtol=1e-6):
        raise FormatError(path, f"{where}: points are sampled at uneven time codes; resample to a fixed frame rate")
    fps = stage.GetTimeCodesPerSecond() / steps[0]

    faces = _triangles(path, mesh, Usd.TimeCode(times[0]))
    if mesh.GetFaceVertexIndicesAttr().ValueMightBeTimeVarying() or \
            mesh.GetFaceVertexCountsAttr().ValueMightBeTimeVarying():
        for time in times[1:]:
            if not np.array_equal(_triangles(path, mesh, Usd.TimeCode(time)), faces):
                raise FormatError(path, f"{where}: topology changes at time code {time:g}")

    vertices = None
    for frame, time in enumerate(times):
        code = Usd.TimeCode(time)
        points = mesh.GetPointsAttr().Get(code)
        if points is None:  # a value block
            raise FormatError(path, f"{where}: no points at time code {time:g}")
        points = np.asarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3:  # a value of another type (a damaged file)
            raise FormatError(path, f"{where}: points at time code {time:g} are not 3-vectors")
        if vertices is None:
            # A crate file stores a repeated value once, so a few kilobytes can hold a million
            # samples of the same points: bound the whole array by the bytes of every layer.
            problem = declared_size_problem(f"{where}: {len(times)} samples of {len(points)} points",
                                            len(times) * points.nbytes, _stage_bytes(stage))
            if problem:
                raise FormatError(path, problem)
            vertices = np.empty((len(times),) + points.shape)
        if points.shape != vertices.shape[1:]:
            raise FormatError(path, f"{where}: {len(points)} points at time code {time:g}, "
                                    f"{len(vertices[0])} at the first")
        # Caches from DCCs often sit under animated transforms: report what a viewer shows.
        world = np.array(mesh.ComputeLocalToWorldTransform(code))
        vertices[frame] = points @ world[:3, :3] + world[3, :3]
    return sequence_from_arrays(path, vertices, faces, fps).vertices, faces, float(fps)


@_reader
def read_scene(path, prim=None):
    """The :class:`~skinsynth.formats.scene.Scene` of the mesh ``read_points_cache`` reads:
    the stage's metersPerUnit and upAxis (an X-up stage counts as Y up: skinsynth's ground plane
    needs Y or Z), the time code of the first points sample, and the mesh's path."""
    from skinsynth.formats.scene import Scene

    stage = _open(path)
    mesh = _find_mesh(path, stage, prim)
    times = mesh.GetPointsAttr().GetTimeSamples()
    meters_per_unit = float(UsdGeom.GetStageMetersPerUnit(stage))
    if not (np.isfinite(meters_per_unit) and meters_per_unit > 0.0):
        raise FormatError(path, f"metersPerUnit is {meters_per_unit:g}: it must be a positive number of metres "
                                "(the stage says so; fix it in the file)")
    return Scene(meters_per_unit=meters_per_unit,
                 up_axis="Z" if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z else "Y",
                 start_frame=float(times[0]) if times else 0.0, prim_path=str(mesh.GetPath()))


@dataclasses.dataclass
class UsdSkeleton:
    """A UsdSkel ``Skeleton`` as :func:`read_skeleton` reads it: ``names`` (J,) each joint's path
    (``root/chain_00_joint_00/...``), ``parents`` (J,) int64 (−1 for a top joint), ``positions``
    (J, 3) each joint's origin in its bind pose (world, the file's units), ``free`` (J,) bool
    (listed in :data:`FREE_JOINTS`: no joint holds it to its parent), and the stage's
    ``meters_per_unit`` and ``up_axis``."""

    names: list
    parents: np.ndarray
    positions: np.ndarray
    free: np.ndarray
    meters_per_unit: float
    up_axis: str


@_reader
def read_skeleton(path) -> UsdSkeleton:
    """The first UsdSkel ``Skeleton`` of a USD file: its joints, topology and bind pose
    (bindTransforms, world: each joint's origin is where it turns). FormatError when the file has
    none, or its bind transforms do not match its joints."""
    stage = _open(path)
    for prim in stage.Traverse():
        if prim.IsA(UsdSkel.Skeleton):
            skeleton = UsdSkel.Skeleton(prim)
            joints = [str(j) for j in (skeleton.GetJointsAttr().Get() or [])]
            binds = skeleton.GetBindTransformsAttr().Get()
            if not joints:
                raise FormatError(path, f"the Skeleton {prim.GetPath()} has no joints")
            if binds is None or len(binds) != len(joints):
                raise FormatError(path, f"the Skeleton {prim.GetPath()} has {0 if binds is None else len(binds)} bind "
                                        f"transforms for its {len(joints)} joints")
            _check_joint_list(path, prim.GetPath(), joints)
            topology = UsdSkel.Topology(Vt.TokenArray(joints))
            valid, why = topology.Validate()
            if not valid:
                raise FormatError(path, f"the Skeleton {prim.GetPath()}'s joints are no tree UsdSkel reads: {why}")
            parents = np.asarray(topology.GetParentIndices(), dtype=np.int64)
            positions = _bind_positions(path, prim.GetPath(), joints, binds)
            listed = prim.GetAttribute(FREE_JOINTS)
            free_names = set(str(n) for n in (listed.Get() or [])) if listed and listed.IsValid() else set()
            return UsdSkeleton(names=joints, parents=parents, positions=positions,
                               free=np.array([j in free_names for j in joints], dtype=bool),
                               meters_per_unit=float(UsdGeom.GetStageMetersPerUnit(stage)),
                               up_axis=str(UsdGeom.GetStageUpAxis(stage)))
    raise FormatError(path, "holds no UsdSkel Skeleton (--skeleton FILE needs one: joints, topology, bind transforms)")


def _check_joint_list(path, where, joints):
    """FormatError naming the first joint a Skeleton lists twice (UsdSkel would give both the
    same parent: the tree would change without a word)."""
    seen = set()
    for joint in joints:
        if joint in seen:
            raise FormatError(path, f"the Skeleton {where} lists the joint {joint!r} twice")
        seen.add(joint)


#: The smallest ratio of a bind transform's smallest to largest singular value (of its 3 × 3
#: part) that counts as invertible: a joint frame squashed flatter than this cannot be inverted
#: to bind a vertex (double precision keeps 1e-16; 1e-9 leaves margin for the file's rounding).
BIND_CONDITION = 1e-9


def _bind_positions(path, where, joints, binds):
    """Each joint's origin (J, 3) of its bind transform (world, row-vector form: the translation
    is the last row), once every transform is finite, affine (last column 0, 0, 0, 1) and
    invertible (:data:`BIND_CONDITION`); FormatError naming the first joint that is not."""
    matrices = np.array([[[m[i][j] for j in range(4)] for i in range(4)] for m in binds], dtype=np.float64)
    for index, matrix in enumerate(matrices):
        problem = None
        if not np.isfinite(matrix).all():
            problem = "holds NaN or inf values"
        elif not np.allclose(matrix[:, 3], [0.0, 0.0, 0.0, 1.0], atol=1e-9):
            problem = f"is not affine (its last column is {matrix[:, 3].tolist()}, not [0, 0, 0, 1])"
        else:
            singular = np.linalg.svd(matrix[:3, :3], compute_uv=False)
            if not singular[-1] > BIND_CONDITION * singular[0]:
                problem = "is singular (no inverse: its axes are flat or zero)"
        if problem:
            raise FormatError(path, f"the Skeleton {where}'s bind transform of joint {joints[index]!r} {problem}")
    return matrices[:, 3, :3].copy()


#: How far outside its mesh a given skeleton's joint may lie, in the mesh's bounding-box
#: diagonals beyond the box (every frame's vertices): a character's joints sit inside its body,
#: so one diagonal out means the skeleton belongs elsewhere (other units, another placement).
JOINT_REACH = 1.0


def check_skeleton_placement(path, skeleton, vertices):
    """FormatError naming the first joint of ``skeleton`` (:class:`UsdSkeleton`) that lies more
    than :data:`JOINT_REACH` diagonals outside the bounding box of vertices (F, V, 3) (the clips'
    every frame): fitted there, bones would keep no vertex."""
    points = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    low, high = points.min(axis=0), points.max(axis=0)
    diagonal = float(np.linalg.norm(high - low))
    outside = np.linalg.norm(np.maximum(low - skeleton.positions, 0.0) + np.maximum(skeleton.positions - high, 0.0),
                             axis=1)
    far = np.flatnonzero(~(outside <= JOINT_REACH * diagonal))
    if far.size:
        joint = int(far[0])
        raise FormatError(path, f"the joint {skeleton.names[joint]!r} lies {outside[joint] / diagonal:.3g} diagonals "
                                f"outside the mesh (its bind position {skeleton.positions[joint].tolist()}): this "
                                "skeleton is not placed on this character (other units, or moved)")


def check_skeleton_scene(path, skeleton, scene):
    """Refuse (FormatError naming ``path``) a :class:`UsdSkeleton` whose stage's units or up axis
    are not those of ``scene`` (the input's :class:`~.scene.Scene`): its bind pose would then sit
    at another scale, or lie on its side."""
    if not np.isclose(skeleton.meters_per_unit, scene.meters_per_unit, rtol=1e-9) or skeleton.up_axis != scene.up_axis:
        raise FormatError(path, f"its skeleton is in {skeleton.meters_per_unit:g} m per unit, {skeleton.up_axis} up, "
                                f"the input in {scene.meters_per_unit:g}, {scene.up_axis} up: give --meters-per-unit "
                                "and --up-axis of the skeleton's scene, or a skeleton exported from this character's "
                                "fit")


@_reader
def read_skel_points(path) -> np.ndarray:
    """Vertices (F, V, 3) as UsdSkel itself skins the first skinned mesh, at time codes start..end.

    The oracle that a DCC playing the file shows the same positions as skinsynth computed.
    """
    return read_skel_characters(path)[0][1]


@_reader
def read_skel_characters(path) -> list:
    """[(mesh prim path, vertices (F, V, 3))] for every skinned mesh, as UsdSkel itself skins them."""
    stage = _open(path)
    cache = UsdSkel.Cache()
    out = []
    for prim in stage.Traverse():
        if prim.IsA(UsdSkel.Root):
            root = UsdSkel.Root(prim)
            cache.Populate(root, Usd.PrimDefaultPredicate)
            for binding in cache.ComputeSkelBindings(root, Usd.PrimDefaultPredicate):
                skeleton = cache.GetSkelQuery(binding.GetSkeleton())
                for target in binding.GetSkinningTargets():
                    if target.GetPrim().IsA(UsdGeom.Mesh):
                        out.append((str(target.GetPrim().GetPath()), _skin_all_frames(stage, skeleton, target)))
    if not out:
        raise FormatError(path, "no skinned mesh under a SkelRoot")
    return out


def _skin_all_frames(stage, skeleton, target):
    """UsdSkel's own result: blend shapes (if bound) applied to the rest points, then skinning."""
    rest_points = UsdGeom.Mesh(target.GetPrim()).GetPointsAttr()
    start, end = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    shapes = None
    if target.HasBlendShapes() and skeleton.GetAnimQuery():
        query = UsdSkel.BlendShapeQuery(UsdSkel.BindingAPI(target.GetPrim()))
        shapes = (query, query.ComputeBlendShapePointIndices(), query.ComputeSubShapePointOffsets())
    frames = []
    for time in np.arange(start, end + 0.5):
        code = Usd.TimeCode(float(time))
        points = rest_points.Get(code)
        if shapes is not None:
            query, point_indices, point_offsets = shapes
            weights = skeleton.GetAnimQuery().ComputeBlendShapeWeights(code)
            mapped = target.GetBlendShapeMapper().Remap(weights) if target.GetBlendShapeMapper() else weights
            sub_weights, shape_indices, sub_indices = query.ComputeSubShapeWeights(mapped)
            query.ComputeDeformedPoints(sub_weights, shape_indices, sub_indices, point_indices, point_offsets, points)
        transforms = skeleton.ComputeSkinningTransforms(code)
        if transforms is None or not target.ComputeSkinnedPoints(transforms, points, code):
            raise FormatError(stage.GetRootLayer().realPath, f"UsdSkel cannot skin {target.GetPrim().GetPath()}")
        frames.append(np.asarray(points, dtype=np.float64))
    return np.stack(frames)


def _open(path):
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FormatError(path, "no such file")
    try:
        with _native_stderr_filtered():
            stage = Usd.Stage.Open(path, Usd.Stage.LoadAll)
    except Exception as error:  # pxr.Tf.ErrorException
        raise FormatError(path, f"cannot open as USD: {_usd_reason(error)}") from None
    if stage is None:
        raise FormatError(path, "cannot open as USD")
    return stage


#: What USD's C++ prints straight to the process's stderr while mapping a damaged crate file
#: (advice to the kernel that failed: the read that follows fails or succeeds on its own).
_NATIVE_NOISE = re.compile(rb"^failed call to posix_madvise\(.*$\n?", flags=re.MULTILINE)


@contextlib.contextmanager
def _reading(path):
    """Read ``path`` in the body, pxr's complaints kept off the user's stderr. A damaged crate
    file fails anywhere, not only in its opening: its values are read on demand (a Tf error, a
    value pxr has no Python type for, a token that is not UTF-8), and pxr prints its warnings (an
    invalid prim name for each property of a damaged path table) and Python's conversion errors
    straight to file descriptor 2 before it raises. The reason becomes one FormatError naming the
    file, and what pxr printed is dropped (on success it is passed on, but for
    :data:`_NATIVE_NOISE`)."""
    try:
        with _native_stderr_filtered():
            yield
    except Tf.ErrorException as error:
        raise FormatError(path, f"cannot read as USD: {_usd_reason(error)}") from None
    except UnicodeDecodeError:
        raise FormatError(path, "cannot read as USD: a name or string in it is not UTF-8 (a damaged file?)") from None
    except TypeError as error:  # boost.python: a value of a C++ type it cannot hand to Python
        if "converter found for C++ type" not in str(error):
            raise
        raise FormatError(path, "cannot read as USD: it holds a value of a type USD cannot read back "
                                "(a damaged file?)") from None


@contextlib.contextmanager
def _native_stderr_filtered():
    """Run the body with file descriptor 2 sent to a temporary file, then pass on what it wrote
    except :data:`_NATIVE_NOISE`: USD's C++ writes there directly, past Python's sys.stderr, and a
    user error must stay one line. When the body raises, nothing it wrote is passed on: the
    exception says what went wrong (one line, for the errors a file causes)."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no stderr to protect
        yield
        return
    with tempfile.TemporaryFile() as captured:
        os.dup2(captured.fileno(), 2)
        succeeded = False
        try:
            yield
            succeeded = True
        finally:
            try:
                sys.stderr.flush()  # Python's own writes to fd 2 in the body belong to it too
            except (OSError, ValueError):
                pass
            os.dup2(saved, 2)
            os.close(saved)
            captured.seek(0)
            rest = _NATIVE_NOISE.sub(b"", captured.read()) if succeeded else b""
            if rest:
                try:
                    os.write(2, rest)
                except OSError:
                    pass


def _stage_bytes(stage):
    """The bytes of every file layer the stage composes (a small file may reference a big cache)."""
    return sum(os.path.getsize(layer.realPath) for layer in stage.GetUsedLayers()
               if layer.realPath and os.path.isfile(layer.realPath))


def _usd_reason(error):
    """The first diagnostic of a Tf error, without C++ source locations and namespaces."""
    messages = re.findall(r" : '(.*?)'\s*(?=\n\tError|$)", str(error), flags=re.DOTALL)
    reason = messages[0] if messages else str(error)
    reason = re.sub(r"pxrInternal_\w+?__pxrReserved__::", "", reason)
    return " ".join(reason.split()) or "not a USD file"


def _find_mesh(path, stage, prim):
    if prim is not None:
        if not Sdf.Path.IsValidPathString(prim) or not Sdf.Path(prim).IsAbsolutePath():
            raise FormatError(path, f"{prim!r} is not an absolute prim path")
        found = stage.GetPrimAtPath(prim)
        if not found.IsValid():
            raise FormatError(path, f"no prim at {prim}")
        if not found.IsA(UsdGeom.Mesh):
            raise FormatError(path, f"{prim} is a {found.GetTypeName() or 'typeless prim'}, not a Mesh")
        return UsdGeom.Mesh(found)
    static = 0
    for candidate in stage.Traverse():
        if candidate.IsA(UsdGeom.Mesh):
            mesh = UsdGeom.Mesh(candidate)
            if mesh.GetPointsAttr().GetNumTimeSamples() > 0:
                return mesh
            static += 1
    if static:
        raise FormatError(path, f"no Mesh with time-sampled points ({static} static mesh(es); "
                                "skeletal animation must be baked to points)")
    raise FormatError(path, "no Mesh prim in the stage")


def _triangles(path, mesh, time):
    """Fan-triangulate the mesh's polygons, in polygon order: faces (T, 3) int64."""
    corners, indices = _triangle_corners(path, mesh, time)
    return indices[corners]


def _triangle_corners(path, mesh, time):
    """(corners (T, 3) int64, faceVertexIndices (N,) int64): the polygons fan-triangulated in
    polygon order, each triangle corner as its position in faceVertexIndices."""
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(time) or [], dtype=np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(time) or [], dtype=np.int64)
    for name, values in (("faceVertexCounts", counts), ("faceVertexIndices", indices)):
        if values.ndim != 1:  # a value of another type (a damaged file)
            raise FormatError(path, f"{mesh.GetPath()}: {name} is not an array of integers")
    if counts.sum() != len(indices):
        raise FormatError(path, f"{mesh.GetPath()}: faceVertexCounts sum to {counts.sum()} "
                                f"but there are {len(indices)} faceVertexIndices")
    if (counts < 3).any():
        raise FormatError(path, f"{mesh.GetPath()}: a face has fewer than 3 vertices")
    corners = fan_corners(counts)
    if mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded:
        corners = corners[:, [0, 2, 1]]  # keep outward normals right-handed like the other readers
    return corners, indices


#: primvars:st interpolations read as material UVs: per point, or per face corner.
_UV_INTERPOLATIONS = (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying, UsdGeom.Tokens.faceVarying)


@_reader
def read_face_uvs(path, prim=None):
    """The material UVs of the mesh :func:`read_points_cache` reads, per corner of its triangles:
    face_uvs (T, 3, 2) float64 from ``primvars:st`` (indexed or not, at the first points sample),
    or None when the mesh has no ``st`` or one of another interpolation than vertex, varying or
    faceVarying (constant and uniform UVs texture nothing). FormatError for a malformed ``st``."""
    stage = _open(path)
    mesh = _find_mesh(path, stage, prim)
    primvar = UsdGeom.PrimvarsAPI(mesh.GetPrim()).GetPrimvar("st")
    if not primvar or not primvar.HasValue() or primvar.GetInterpolation() not in _UV_INTERPOLATIONS:
        return None
    times = mesh.GetPointsAttr().GetTimeSamples()
    code = Usd.TimeCode(times[0]) if times else Usd.TimeCode.Default()
    where = f"{mesh.GetPath()}.primvars:st"
    values = primvar.Get(code)
    values = np.asarray(values if values is not None else [], dtype=np.float64)
    if values.ndim != 2 or values.shape[1] != 2:
        raise FormatError(path, f"{where}: must hold 2 numbers per element, got shape {values.shape}")
    if primvar.IsIndexed():  # flattened here: pxr's ComputeFlattened prints its complaints to stderr
        element = np.asarray(primvar.GetIndices(code) or [], dtype=np.int64)
        if element.size and (element.min() < 0 or element.max() >= len(values)):
            bad = element[(element < 0) | (element >= len(values))][0]
            raise FormatError(path, f"{where}:indices holds {bad}, outside its {len(values)} values")
        values = values[element]
    corners, indices = _triangle_corners(path, mesh, code)
    if primvar.GetInterpolation() == UsdGeom.Tokens.faceVarying:
        wanted, per_corner = len(indices), values
    else:
        wanted = len(mesh.GetPointsAttr().Get(code) or [])
        per_corner = values[indices] if len(values) == wanted and (not indices.size or indices.max() < wanted) \
            else None
    if len(values) != wanted or per_corner is None:
        raise FormatError(path, f"{where}: {len(values)} values for {primvar.GetInterpolation()} interpolation, "
                                f"which needs {wanted}")
    face_uvs = per_corner[corners]
    require_finite(path, where, face_uvs)
    return face_uvs


@_reader
def read_skel_animation(path):
    """([(mesh prim path, vertices (F, V, 3), faces (T, 3))], fps, up axis "Y"/"Z"): every
    skinned mesh of a UsdSkel file as UsdSkel itself skins it, with its triangles."""
    stage = _open(path)
    out = []
    for name, vertices in read_skel_characters(path):
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(name))
        out.append((name, vertices, _triangles(path, mesh, Usd.TimeCode.Default())))
    up = "Z" if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z else "Y"
    return out, float(stage.GetTimeCodesPerSecond() or 24.0), up


@_reader
def animated_mesh_paths(path):
    """Paths of every Mesh with time-sampled points (a crowd's characters), in traversal order."""
    stage = _open(path)
    return [str(p.GetPath()) for p in stage.Traverse()
            if p.IsA(UsdGeom.Mesh) and UsdGeom.Mesh(p).GetPointsAttr().GetNumTimeSamples() > 0]
