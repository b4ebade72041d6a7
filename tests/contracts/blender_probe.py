"""Run inside Blender's Python (bpy): import a USD file, print evaluated world-space vertices as JSON.

Usage: BLENDER_PYTHON blender_probe.py FILE.usd FRAME [FRAME ...]
       BLENDER_PYTHON blender_probe.py FILE.usd --bones

Prints "PROBE" then {frame: (V, 3)}, or with --bones {armature: {bone: its parent's name or null}}
(each armature Blender's USD import made, every bone's parent).
"""

import json
import sys

import bpy

path = sys.argv[1]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath=path)
scene = bpy.context.scene
out = {}
if sys.argv[2:] == ["--bones"]:
    for armature in (o for o in scene.objects if o.type == "ARMATURE"):
        out[armature.name] = {b.name: b.parent.name if b.parent else None for b in armature.data.bones}
else:
    mesh = [o for o in scene.objects if o.type == "MESH"][0]
    for frame in (int(f) for f in sys.argv[2:]):
        scene.frame_set(frame)
        evaluated = mesh.evaluated_get(bpy.context.evaluated_depsgraph_get())
        data = evaluated.to_mesh()
        out[frame] = [list(evaluated.matrix_world @ v.co) for v in data.vertices]
        evaluated.to_mesh_clear()
print("PROBE" + json.dumps(out))
