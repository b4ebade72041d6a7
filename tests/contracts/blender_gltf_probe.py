"""Run inside Blender's Python (bpy): import a .glb with Blender's glTF importer, play each of its
animations and print the evaluated (armature modifier applied) world-space vertices as JSON.

Usage: BLENDER_PYTHON blender_gltf_probe.py FILE.glb FPS FRAME [FRAME ...]
       BLENDER_PYTHON blender_gltf_probe.py FILE.glb --bones
       BLENDER_PYTHON blender_gltf_probe.py FILE.glb --turn BONE [BONE ...]

With --bones it prints "PROBE" then {bone: its parent's name or null} of the armature the import
made (every bone's parent), and nothing else. With --turn it prints "PROBE" then what
blender_probe.py's ``turned`` says of the imported mesh: the vertices at rest and each vertex's
displacement when each BONE alone is rotated by hand in pose mode.

Prints "PROBE" then {"vertices": V, "rest": the mesh's own vertices (V, 3), "animations": {name:
{frame: (V, 3)}}}, the animations in the file's order. Blender's axes: Z up, (x, y, z) of glTF is
(x, -z, y) here. The scene runs at FPS (fps_base 1) before the import, so the importer keys glTF
time t at frame t * FPS: frame f of a clip sampled at f / FPS is that clip's key f, not an
interpolation. The importer makes one action per glTF animation and animated ID (the armature's
bones; the mesh's shape keys, its morph targets' weights) and stashes each on a muted NLA track of
the animation's name; the first animation is made active. Each is played here as the importer's
own "apply glTF animation" does: that track's action (and slot) made the ID's action, after every
pose bone is put back at rest and every shape key at weight 0, so nothing of the previous
animation stays.

Blender clamps a shape key's value to its slider range, [0, 1] unless widened, and Blender 5.0.1's
importer widens it to the first key's weight only (blender/imp/animation_weight.py takes
``min(coords[1:2])``, not ``coords[1::2]``): a morph weight outside [0, 1] and beyond the first
frame's is played clamped. This probe shows what that import shows and does not widen them.
"""

import json
import struct
import sys

import bpy

if sys.argv[2:] == ["--bones"]:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=sys.argv[1], merge_vertices=False, disable_bone_shape=True)
    (armature,) = [o for o in bpy.context.scene.objects if o.type == "ARMATURE"]
    print("PROBE" + json.dumps({b.name: b.parent.name if b.parent else None for b in armature.data.bones}))
    sys.exit(0)
if sys.argv[2:3] == ["--turn"]:
    from blender_probe import turned  # beside this script

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=sys.argv[1], merge_vertices=False, disable_bone_shape=True)
    (mesh,) = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    print("PROBE" + json.dumps(turned(mesh, sys.argv[3:])))
    sys.exit(0)

path, fps, frames = sys.argv[1], int(sys.argv[2]), [int(f) for f in sys.argv[3:]]
with open(path, "rb") as f:
    f.seek(12)
    length = struct.unpack("<I", f.read(4))[0]
    f.read(4)
    document = json.loads(f.read(length))
names = [a.get("name", f"Animation_{i}") for i, a in enumerate(document.get("animations", []))]

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.fps, scene.render.fps_base = fps, 1.0
# merge_vertices off (the default, said here): the mesh keeps the file's vertices in its order;
# no bone shapes, so the file's mesh is the only mesh.
bpy.ops.import_scene.gltf(filepath=path, merge_vertices=False, disable_bone_shape=True)
meshes = [o for o in scene.objects if o.type == "MESH"]
assert len(meshes) == 1, [o.name for o in meshes]
mesh = meshes[0]
armature = mesh.find_armature()


from blender_probe import evaluated_points as points  # noqa: E402 (beside this script; bpy first)


def play(data, name, rest):
    """Make the action of ``data``'s track ``name`` its action, after ``rest()``; False if it has none."""
    if data is None or data.animation_data is None:
        return False
    rest()
    tracks = [t for t in data.animation_data.nla_tracks if t.name == name and t.strips]
    data.animation_data.action = tracks[0].strips[0].action if tracks else None
    if tracks:
        data.animation_data.action_slot = tracks[0].strips[0].action_slot
    return bool(tracks)


def rest_pose():
    for bone in armature.pose.bones:
        bone.location, bone.rotation_quaternion, bone.scale = (0, 0, 0), (1, 0, 0, 0), (1, 1, 1)


def rest_shapes():
    for block in mesh.data.shape_keys.key_blocks[1:]:
        block.value = 0.0  # glTF's default weights, which skinsynth writes as zeros


out = {"vertices": len(mesh.data.vertices), "rest": [list(mesh.matrix_world @ v.co) for v in mesh.data.vertices],
       "animations": {}}
for name in names:
    # the bones' action, and the morph targets' (the shape keys' own action) where the mesh has them
    assert play(armature, name, rest_pose), (name, [t.name for t in armature.animation_data.nla_tracks])
    play(mesh.data.shape_keys, name, rest_shapes)
    played = {}
    for frame in frames:
        scene.frame_set(frame)
        played[frame] = points(mesh)
    out["animations"][name] = played
print("PROBE" + json.dumps(out))
