"""Run inside Blender's Python (bpy): import a USD file, print evaluated world-space vertices as JSON.

Usage: BLENDER_PYTHON blender_probe.py FILE.usd FRAME [FRAME ...]
       BLENDER_PYTHON blender_probe.py FILE.usd --bones
       BLENDER_PYTHON blender_probe.py FILE.usd --turn BONE [BONE ...]

Prints "PROBE" then {frame: (V, 3)}, or with --bones {armature: {bone: its parent's name or null}}
(each armature Blender's USD import made, every bone's parent), or with --turn what ``turned``
says (blender_gltf_probe.py uses it too).
"""

import json
import math
import sys

import bpy
import mathutils

TURN_DEGREES = 30.0  # --turn: each bone in turn, this far about its own (bone-local) X axis


def evaluated_points(obj):
    """``obj``'s evaluated (modifiers applied) vertices, world space, in its mesh's order: [[x, y, z]]."""
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    data = evaluated.to_mesh()
    out = [list(evaluated.matrix_world @ v.co) for v in data.vertices]
    evaluated.to_mesh_clear()
    return out


def turned(mesh, names):
    """Pose ``mesh``'s armature by hand: its action taken off and every pose bone at rest (the
    first frame), then each bone of ``names`` alone rotated TURN_DEGREES about its local X axis, in
    pose mode's terms (its pose bone's rotation, about its head). Returns {"rest": the evaluated
    vertices at rest (V, 3), "moved": {bone: each vertex's displacement (V,) by that turn}}."""
    armature = mesh.find_armature()
    scene = bpy.context.scene
    if armature.animation_data is not None:
        armature.animation_data.action = None
    bpy.context.view_layer.objects.active = armature
    bpy.ops.object.mode_set(mode="POSE")
    for bone in armature.pose.bones:
        bone.rotation_mode = "QUATERNION"
        bone.location, bone.rotation_quaternion, bone.scale = (0, 0, 0), (1, 0, 0, 0), (1, 1, 1)
    scene.frame_set(scene.frame_start)
    rest = [mathutils.Vector(p) for p in evaluated_points(mesh)]
    moved = {}
    for name in names:
        bone = armature.pose.bones[name]
        bone.rotation_quaternion = mathutils.Quaternion((1, 0, 0), math.radians(TURN_DEGREES))
        bpy.context.view_layer.update()
        moved[name] = [(mathutils.Vector(p) - q).length for p, q in zip(evaluated_points(mesh), rest)]
        bone.rotation_quaternion = (1, 0, 0, 0)
    bpy.context.view_layer.update()
    return {"rest": [list(p) for p in rest], "moved": moved}


if __name__ == "__main__":
    path = sys.argv[1]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=path)
    scene = bpy.context.scene
    out = {}
    if sys.argv[2:] == ["--bones"]:
        for armature in (o for o in scene.objects if o.type == "ARMATURE"):
            out[armature.name] = {b.name: b.parent.name if b.parent else None for b in armature.data.bones}
    elif sys.argv[2:3] == ["--turn"]:
        (mesh,) = [o for o in scene.objects if o.type == "MESH"]
        out = turned(mesh, sys.argv[3:])
    else:
        mesh = [o for o in scene.objects if o.type == "MESH"][0]
        for frame in (int(f) for f in sys.argv[2:]):
            scene.frame_set(frame)
            out[frame] = evaluated_points(mesh)
    print("PROBE" + json.dumps(out))
