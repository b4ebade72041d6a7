"""Run inside Blender's Python (bpy): import a USD file, print evaluated world-space vertices as JSON.

Usage: BLENDER_PYTHON blender_probe.py FILE.usd FRAME [FRAME ...]
"""

import json
import sys

import bpy

path, frames = sys.argv[1], [int(f) for f in sys.argv[2:]]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath=path)
scene = bpy.context.scene
mesh = [o for o in scene.objects if o.type == "MESH"][0]
out = {}
for frame in frames:
    scene.frame_set(frame)
    evaluated = mesh.evaluated_get(bpy.context.evaluated_depsgraph_get())
    data = evaluated.to_mesh()
    out[frame] = [list(evaluated.matrix_world @ v.co) for v in data.vertices]
    evaluated.to_mesh_clear()
print("PROBE" + json.dumps(out))
