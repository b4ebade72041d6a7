"""Run by Blender's own Python (``bpy``), never imported by skinsynth: read one animated mesh of an
Alembic (``.abc``) or FBX (``.fbx``) file with Blender's importers and write its frames to an
``.npz`` (:mod:`skinsynth.formats.blender` runs it and reads the result).

    python_with_bpy blender_reader.py INPUT OUTPUT.npz MESH_PATH FPS
    blender --background --factory-startup --python blender_reader.py -- INPUT OUTPUT.npz MESH_PATH FPS

MESH_PATH: the Alembic object path (``/Body/BodyShape``) or the FBX object's name, "" for the one
animated mesh; FPS: the rate to read at, "" for the file's own. Writes ``vertices (F, V, 3)``
float64, ``faces (T, 3)``, ``fps``, ``up_axis``, ``meters_per_unit``, ``start_frame``, ``mesh``,
``meshes`` (every mesh's path); a problem with the file is one line on stderr after ``SKINSYNTH:``
and exit status 3.

What is read, and why so:

- **Every frame, evaluated.** The mesh as Blender's depsgraph evaluates it at each frame: an
  Alembic point cache (its MeshSequenceCache, vertex interpolation off, so each frame is a stored
  sample, not a blend of two), an FBX mesh moved by its skin, blend shapes or transforms. World
  positions (the object's and its parents' transforms applied).
- **The file's own axes and units.** Blender turns every import into its world (Z up, metres).
  The conversion is undone so the numbers are the file's: Alembic is Y up by convention (Blender
  turned it with (x, y, z) -> (x, −z, y)) and has no unit (1 unit = 1 metre, as Blender reads
  it); an FBX says its up axis and its unit (GlobalSettings ``UpAxis``, ``UnitScaleFactor``, in
  centimetres), read with Blender's own FBX parser (``io_scene_fbx.parse_fbx``).
- **The file's own frame rate.** An FBX states it (Blender's importer sets the scene's). An
  Alembic archive stores sample times in seconds, and Blender samples them at the scene's rate:
  the rate is the archive's own ``FramesPerTimeUnit`` / ``_ai_DCC_FPS`` metadata (what Blender,
  Maya and Houdini write) or the caller's FPS; an archive that states none is refused (reading it
  at another rate would blend its samples).
- **One topology.** A mesh whose vertex count or triangles change over the frames is refused,
  naming the first frame that differs.
"""

import re
import sys

import numpy as np

#: Alembic archive metadata keys that state the frame rate (Blender's writer; Alembic's
#: ``kDCCFPSKey``, which Maya's and Houdini's exporters fill).
_FPS_KEYS = (rb"FramesPerTimeUnit=([0-9.]+)", rb"_ai_DCC_FPS=([0-9.]+)")
#: FBX TimeMode values and their rates (FbxTime::EMode); 14 is "custom" (CustomFrameRate).
_FBX_TIME_MODES = {1: 120.0, 2: 100.0, 3: 60.0, 4: 50.0, 5: 48.0, 6: 30.0, 7: 30.0, 8: 30000 / 1001,
                   9: 30000 / 1001, 10: 25.0, 11: 24.0, 12: 1000.0, 13: 24000 / 1001, 15: 96.0, 16: 72.0,
                   17: 60000 / 1001, 18: 120000 / 1001}


class Refused(Exception):
    """A problem with the file, said in one line."""


def main(argv):
    source, output, mesh_path, fps = argv
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    if source.lower().endswith(".abc"):
        rate = float(fps) if fps else _alembic_rate(source)
        set_rate(scene, rate)
        result = bpy.ops.wm.alembic_import(filepath=source, set_frame_range=True, validate_meshes=False,
                                           always_add_cache_reader=True)
        if "FINISHED" not in result:
            raise Refused("Blender could not read it as Alembic")
        up, to_metres = "Y", 1.0
        paths = {obj.name: _alembic_path(obj) for obj in scene.objects if obj.type == "MESH"}
        first, last = scene.frame_start, scene.frame_end
    else:
        settings = _fbx_settings(source)
        result = bpy.ops.import_scene.fbx(filepath=source, use_anim=True, anim_offset=0.0)
        if "FINISHED" not in result:
            raise Refused("Blender could not read it as FBX")
        up, to_metres = settings["up"], settings["metres"]
        up = "Z" if up == "X" else up  # an X-up file is read in Blender's Z-up world
        if fps:
            set_rate(scene, float(fps))
        rate = scene.render.fps / scene.render.fps_base
        paths = {obj.name: obj.name for obj in scene.objects if obj.type == "MESH"}
        first, last = _animated_range(bpy, scene)
    target = _chosen(scene, paths, mesh_path)
    for modifier in target.modifiers:  # stored samples, not blends of two
        if modifier.type == "MESH_SEQUENCE_CACHE":
            modifier.use_vertex_interpolation = False
    vertices, faces = _frames(bpy, scene, target, first, last)
    if up == "Y":  # undo Blender's (x, y, z) -> (x, -z, y)
        vertices = np.stack([vertices[..., 0], vertices[..., 2], -vertices[..., 1]], axis=-1)
    np.savez(output, vertices=vertices / to_metres, faces=faces, fps=np.float64(rate), up_axis=up,
             meters_per_unit=np.float64(to_metres), start_frame=np.float64(first), mesh=paths[target.name],
             meshes=np.array(sorted(paths.values())))


def set_rate(scene, rate):
    """The scene's frame rate as an integer over a base (29.97 as 30000 / 1001)."""
    if not (np.isfinite(rate) and rate > 0):
        raise Refused(f"the frame rate must be positive (got {rate})")
    for base in (1, 1001, 1000):
        if abs(rate * base - round(rate * base)) < 1e-6 * rate * base and round(rate * base) <= 32767:
            scene.render.fps, scene.render.fps_base = int(round(rate * base)), float(base)
            return
    scene.render.fps, scene.render.fps_base = int(round(rate * 1000)), 1000.0


def _alembic_rate(source):
    """The frame rate an Alembic archive states in its metadata (module notes)."""
    with open(source, "rb") as stream:
        head = stream.read(16)
        if not head.startswith(b"Ogawa"):
            raise Refused("not an Alembic archive (Ogawa): " + ("empty" if not head else "no Ogawa header"))
        stream.seek(0)
        tail = b""
        while True:  # in blocks, a block's tail kept so a key split between two is found: memory stays small
            block = stream.read(1 << 24)
            if not block:
                break
            window = tail + block
            for pattern in _FPS_KEYS:
                found = re.search(pattern + rb"[;\x00]", window)
                if found:
                    return float(found.group(1))
            tail = window[-256:]
    raise Refused("the archive does not state its frame rate (no FramesPerTimeUnit or _ai_DCC_FPS): give --fps")


def _alembic_path(obj):
    """An imported Alembic object's path in the archive (its cache modifier's), or its name."""
    for modifier in obj.modifiers:
        if modifier.type == "MESH_SEQUENCE_CACHE" and modifier.object_path:
            return modifier.object_path
    return "/" + obj.name


def _fbx_settings(source):
    """An FBX file's up axis ("Y"/"Z"/"X") and its unit in metres, from its GlobalSettings."""
    import io_scene_fbx.parse_fbx as parse_fbx

    try:
        root, _ = parse_fbx.parse(source)
    except Exception as error:  # Blender's parser: any failure is a file it cannot read
        raise Refused(f"not an FBX file Blender reads ({type(error).__name__}: {error})") from None
    values = {}
    for element in root.elems:
        if element.id == b"GlobalSettings":
            for group in element.elems:
                if group.id == b"Properties70":
                    values.update({p.props[0]: p.props[-1] for p in group.elems if p.props})
    up = "XYZ"[int(values.get(b"UpAxis", 1))]
    # six significant digits: Blender writes the factor from its float32 scene scale (0.99999998 for 1)
    return {"up": up, "metres": float(f"{float(values.get(b'UnitScaleFactor', 1.0)):.6g}") / 100.0}


def _animated_range(bpy, scene):
    """The frames the FBX's animation covers (every action's keys), or the scene's first alone."""
    ranges = [action.frame_range for action in bpy.data.actions]
    if not ranges:
        return scene.frame_start, scene.frame_start
    return int(np.floor(min(r[0] for r in ranges) + 1e-6)), int(np.ceil(max(r[1] for r in ranges) - 1e-6))


def _chosen(scene, paths, mesh_path):
    """The mesh object to read: by path, or the only one."""
    if mesh_path:
        for obj in scene.objects:
            if obj.type == "MESH" and mesh_path in (paths[obj.name], obj.name):
                return obj
        raise Refused(f"no mesh {mesh_path!r} (it has {', '.join(sorted(paths.values())) or 'none'})")
    if not paths:
        raise Refused("no mesh in it")
    if len(paths) > 1:
        raise Refused(f"{len(paths)} meshes ({', '.join(sorted(paths.values()))}): choose one with --prim")
    return next(obj for obj in scene.objects if obj.type == "MESH")


def _snapped(matrix):
    """A world matrix with the float32 rounding of Blender's axis turns taken off: entries within
    1e-6 of 0 or ±1 set to them (a 90° turn stored in float32 has cos = −4.4e-8), so a cache with
    no transform of its own reads back the very coordinates the file holds."""
    near = np.round(matrix)
    return np.where(np.abs(matrix - near) <= 1e-6, near, matrix)


def _frames(bpy, scene, target, first, last):
    """(vertices (F, V, 3) world, in Blender's frame; faces (T, 3) of the first frame) of frames
    first..last, Refused where the topology changes (the vertex count, or which vertex each face
    corner is). One array of the output's size, filled frame by frame."""
    graph = bpy.context.evaluated_depsgraph_get()
    count = int(last) - int(first) + 1
    vertices = faces = corners = None
    for index, frame in enumerate(range(int(first), int(last) + 1)):
        scene.frame_set(frame)
        evaluated = target.evaluated_get(graph)
        mesh = evaluated.to_mesh()
        try:
            points = np.empty(len(mesh.vertices) * 3)
            mesh.vertices.foreach_get("co", points)
            these = np.empty(len(mesh.loops), dtype=np.int64)
            mesh.loops.foreach_get("vertex_index", these)
            if faces is None:
                mesh.calc_loop_triangles()
                faces = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int64)
                mesh.loop_triangles.foreach_get("vertices", faces)
                faces = faces.reshape(-1, 3)
        finally:
            evaluated.to_mesh_clear()
        if vertices is None:
            vertices, corners = np.empty((count, len(points) // 3, 3)), these
        elif len(points) != 3 * vertices.shape[1] or not np.array_equal(these, corners):
            raise Refused(f"the mesh's topology changes at frame {frame} ({len(points) // 3} vertices, "
                          f"{len(these)} face corners; frame {first}: {vertices.shape[1]}, {len(corners)})")
        matrix = _snapped(np.array(evaluated.matrix_world, dtype=np.float64))
        vertices[index] = points.reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]
        print(f"SKINSYNTH-FRAME {index + 1} {count}", file=sys.stderr, flush=True)  # skinsynth's progress bar
    return vertices, faces


if __name__ == "__main__":
    arguments = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    try:
        main(arguments)
    except Refused as problem:
        print(f"SKINSYNTH: {problem}", file=sys.stderr)
        sys.exit(3)
