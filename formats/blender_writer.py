"""Run by Blender's own Python (``bpy``), never imported by skinsynth: write a vertex animation as
an Alembic point cache with Blender's exporter (:func:`skinsynth.formats.blender.write_alembic`
runs it).

    python_with_bpy blender_writer.py FRAMES.npz CACHE.pc2 OUTPUT.abc

FRAMES.npz: ``rest (V, 3)`` (Blender's world: Z up), ``faces (T, 3)``, ``fps``, ``start_frame``,
``name`` (the object's); CACHE.pc2: every frame's vertices in the same frame, as Blender's Mesh
Cache modifier reads them. The mesh is built once, the modifier moves it frame by frame (no shape
key per frame: the export stays linear in the frames), and ``wm.alembic_export`` samples every
scene frame, writing the rate it ran at (``FramesPerTimeUnit``). A problem: one line on stderr
after ``SKINSYNTH:``, exit status 3.
"""

import sys

import numpy as np


def main(frames_path, cache_path, output):
    import bpy

    data = np.load(frames_path)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    rate = float(data["fps"])
    for base in (1, 1001, 1000):  # 29.97 as 30000 / 1001
        if abs(rate * base - round(rate * base)) < 1e-6 * rate * base and round(rate * base) <= 32767:
            break
    scene.render.fps, scene.render.fps_base = int(round(rate * base)), float(base)
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


if __name__ == "__main__":
    arguments = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    main(*arguments)
