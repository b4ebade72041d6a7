"""Run by Blender's Python (bpy), as a user's DCC would write a cache: a mesh animation (an .npz of
vertices (F, V, 3), Y up, metres, and faces) built in Blender (its Z-up world, as Blender's own
importers place a Y-up file) with a shape key per frame, written to .abc or .fbx.

    python_with_bpy blender_writer.py IN.npz OUT.abc|OUT.fbx '{"fps": 30, "unit": "cm", "up": "Z", "second": true}'

fps: the scene's rate (also stated in the file); unit (FBX): "cm" (Blender's default, coordinates
×100) or "m"; up (FBX): "Y" or "Z"; second: a second, static mesh beside the first; build: the
mesh's faces appear over the frames (Blender's Build modifier: a topology that changes); empty: an
FBX holding no mesh (an Empty object alone).
"""

import json
import sys

import bpy
import numpy as np


def main(source, output, options):
    data = np.load(source)
    frames, faces = np.asarray(data["vertices"], dtype=np.float64), np.asarray(data["faces"])
    world = np.stack([frames[..., 0], -frames[..., 2], frames[..., 1]], axis=-1)  # Y up -> Blender's Z up
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = int(options.get("fps", 24)), 1.0
    mesh = bpy.data.meshes.new("BodyShape")
    body = bpy.data.objects.new("Body", mesh)
    scene.collection.objects.link(body)
    mesh.from_pydata(world[0].tolist(), [], faces.tolist())
    body.shape_key_add(name="Basis")
    count = len(world)
    for frame in range(count):  # key f is whole at frame f + 1 and nothing at its neighbours
        key = body.shape_key_add(name=f"frame_{frame}")
        key.data.foreach_set("co", world[frame].ravel())
        for at, value in ((frame, 0.0), (frame + 1, 1.0), (frame + 2, 0.0)):
            if 1 <= at <= count:
                key.value = value
                key.keyframe_insert("value", frame=at)
    if options.get("build"):
        build = body.modifiers.new("Build", "BUILD")
        build.frame_start, build.frame_duration = 1, count
    if options.get("empty"):
        bpy.data.objects.remove(body)
        scene.collection.objects.link(bpy.data.objects.new("Nothing", None))
    if options.get("second"):
        other = bpy.data.meshes.new("PropShape")
        other.from_pydata([(0.0, 0.0, 0.0), (0.1, 0.0, 0.0), (0.0, 0.1, 0.0)], [], [(0, 1, 2)])
        scene.collection.objects.link(bpy.data.objects.new("Prop", other))
    scene.frame_start, scene.frame_end = 1, count
    if output.endswith(".abc"):
        bpy.ops.wm.alembic_export(filepath=output, start=1, end=count)
    else:
        up = options.get("up", "Y")
        bpy.ops.export_scene.fbx(filepath=output, object_types={"MESH", "EMPTY"}, bake_anim=True,
                                 bake_anim_simplify_factor=0.0, bake_anim_force_startend_keying=True,
                                 bake_anim_use_all_actions=False, bake_anim_use_nla_strips=False,
                                 axis_up=up, axis_forward="-Z" if up == "Y" else "Y",
                                 apply_scale_options="FBX_SCALE_UNITS" if options.get("unit") == "m"
                                 else "FBX_SCALE_NONE")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], json.loads(sys.argv[3]) if len(sys.argv) > 3 else {})
