"""Run by Blender's own Python (``bpy``), never imported by skinsynth: write a vertex animation as
an Alembic point cache, or a skinned mesh as FBX, with Blender's exporters
(:func:`skinsynth.formats.blender.write_alembic`, :func:`~skinsynth.formats.blender.write_fbx`).

    python_with_bpy blender_writer.py FRAMES.npz CACHE.pc2 OUTPUT.abc
    python_with_bpy blender_writer.py SKIN.npz OUTPUT.fbx

SKIN.npz (FBX): ``rest (V, 3)``, ``faces (T, 3)``, ``bone_indices``, ``bone_weights (V, K)``,
``parents (B,)`` (−1: a root; all −1: a flat rig), ``joints (B, 3)``, ``names (B,)``, ``rotations
(F, B, 3, 3)``, ``translations (F, B, 3)`` (each bone's world motion from the rest pose, as linear
blend skinning applies it), ``fps``, ``start_frame``, ``name``, ``up_axis``, ``meters_per_unit``,
``face_uvs (T, 3, 2)`` where the mesh has material UVs;
everything in Blender's world (Z up). An armature gets a bone per skinsynth bone at its joint
(parents as given), the mesh its vertex groups and an Armature modifier, and each bone, every
frame, the pose that moves its rest frame as skinsynth's bone moves the vertices
(armature-space pose P = M · Rest; the key its basis, Rest_local⁻¹ · P_parent⁻¹ · P); FBX
exported with the animation baked at every frame, no leaf bones, the file's up axis and unit the
input's.

FRAMES.npz: ``rest (V, 3)`` (Blender's world: Z up), ``faces (T, 3)``, ``fps``, ``start_frame``,
``name`` (the object's); CACHE.pc2: every frame's vertices in the same frame, as Blender's Mesh
Cache modifier reads them. The mesh is built once, the modifier moves it frame by frame (no shape
key per frame: the export stays linear in the frames), and ``wm.alembic_export`` samples every
scene frame, writing the rate it ran at (``FramesPerTimeUnit``). A problem: one line on stderr
after ``SKINSYNTH:``, exit status 3.
"""

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # run beside the reader: its frame-rate rule
from blender_reader import set_rate  # noqa: E402


def main(frames_path, cache_path, output):
    import bpy

    data = np.load(frames_path)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    set_rate(scene, float(data["fps"]))
    name = str(data["name"]) or "mesh"
    mesh = bpy.data.meshes.new(name + "Shape")
    mesh.from_pydata(np.asarray(data["rest"]).tolist(), [], np.asarray(data["faces"]).tolist())
    body = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(body)
    count = int(data["frames"])
    start = int(round(float(data["start_frame"])))
    cache = body.modifiers.new("skinsynth", "MESH_CACHE")
    cache.cache_format, cache.filepath = "PC2", cache_path
    cache.time_mode, cache.play_mode, cache.frame_start = "FRAME", "SCENE", float(start)
    cache.interpolation, cache.deform_mode = "NONE", "OVERWRITE"
    cache.forward_axis, cache.up_axis = "POS_Y", "POS_Z"  # the cache is in Blender's world already
    scene.frame_start, scene.frame_end = start, start + count - 1
    result = bpy.ops.wm.alembic_export(filepath=output, start=start, end=start + count - 1, uvs=False,
                                       normals=False, face_sets=False, evaluation_mode="RENDER")
    if "FINISHED" not in result:
        print("SKINSYNTH: Blender's Alembic exporter did not finish", file=sys.stderr)
        sys.exit(3)


def main_fbx(inputs, output):
    import bpy
    from mathutils import Matrix

    data = np.load(inputs)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    set_rate(scene, float(data["fps"]))
    scene.unit_settings.scale_length = float(data["meters_per_unit"])
    rest, faces = np.asarray(data["rest"]), np.asarray(data["faces"])
    parents, joints, names = np.asarray(data["parents"]), np.asarray(data["joints"]), [str(n) for n in data["names"]]
    rotations, translations = np.asarray(data["rotations"]), np.asarray(data["translations"])
    count, bones = rotations.shape[:2]
    size = float(np.ptp(rest, axis=0).max()) or 1.0
    armature = bpy.data.armatures.new("Armature")
    rig = bpy.data.objects.new("Armature", armature)
    scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    edit = []
    for b in range(bones):  # bones, never vertices
        bone = armature.edit_bones.new(names[b])
        bone.head, bone.tail = joints[b].tolist(), (joints[b] + np.array([0.0, 0.0, 0.05 * size])).tolist()
        edit.append(bone)
    for b in np.flatnonzero(parents >= 0):
        edit[b].parent = edit[parents[b]]
    bpy.ops.object.mode_set(mode="OBJECT")
    rest_matrices = np.array([np.array(armature.bones[names[b]].matrix_local) for b in range(bones)])
    mesh = bpy.data.meshes.new(str(data["name"]) + "Shape")
    mesh.from_pydata(rest.tolist(), [], faces.tolist())
    if "face_uvs" in data:  # each face corner's (u, v), in the faces' order: Blender's loops
        mesh.uv_layers.new(name="UVMap").data.foreach_set("uv", np.asarray(data["face_uvs"]).ravel())
    body = bpy.data.objects.new(str(data["name"]), mesh)
    scene.collection.objects.link(body)
    body.parent = rig
    body.modifiers.new("Armature", "ARMATURE").object = rig
    groups = [body.vertex_groups.new(name=names[b]) for b in range(bones)]
    indices, weights = np.asarray(data["bone_indices"]), np.asarray(data["bone_weights"])
    for b in range(bones):  # Blender sets a group's weights per value: the vertices sharing one at once
        rows, slots = np.nonzero((indices == b) & (weights > 0))
        values = weights[rows, slots]
        for value in np.unique(values):
            groups[b].add(rows[values == value].tolist(), float(value), "REPLACE")
    motion = np.tile(np.eye(4), (count, bones, 1, 1))
    motion[:, :, :3, :3], motion[:, :, :3, 3] = rotations, translations
    posed = motion @ rest_matrices[None]  # (F, B, 4, 4) armature space
    inverse_rest = np.linalg.inv(rest_matrices)
    basis = np.empty_like(posed)
    for b in range(bones):
        p = parents[b]
        basis[:, b] = inverse_rest[b] @ posed[:, b] if p < 0 else \
            np.linalg.inv(inverse_rest[p] @ rest_matrices[b])[None] @ np.linalg.inv(posed[:, p]) @ posed[:, b]
    start = int(round(float(data["start_frame"])))
    for b in range(bones):
        pose = rig.pose.bones[names[b]]
        pose.rotation_mode = "QUATERNION"
        for f in range(count):  # frames of one bone
            location, rotation, _ = Matrix(basis[f, b].tolist()).decompose()
            pose.location, pose.rotation_quaternion = location, rotation
            pose.keyframe_insert("location", frame=start + f)
            pose.keyframe_insert("rotation_quaternion", frame=start + f)
    scene.frame_start, scene.frame_end = start, start + count - 1
    up = str(data["up_axis"])
    result = bpy.ops.export_scene.fbx(filepath=output, object_types={"ARMATURE", "MESH"}, add_leaf_bones=False,
                                      bake_anim=True, bake_anim_simplify_factor=0.0,
                                      bake_anim_force_startend_keying=True, bake_anim_use_nla_strips=False,
                                      bake_anim_use_all_actions=False, primary_bone_axis="Y", secondary_bone_axis="X",
                                      armature_nodetype="NULL", axis_up=up, axis_forward="-Z" if up == "Y" else "Y",
                                      apply_scale_options="FBX_SCALE_UNITS")
    if "FINISHED" not in result:
        print("SKINSYNTH: Blender's FBX exporter did not finish", file=sys.stderr)
        sys.exit(3)


if __name__ == "__main__":
    arguments = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    (main_fbx if arguments[-1].lower().endswith(".fbx") else main)(*arguments)
