"""Engine-ready vertex animation: everything a VAT shader needs, in one folder.

A folder (written whole, :func:`~skinsynth.formats.output_folder.atomic_folder`, with its manifest) holding, per animation
``NAME``:

- ``NAME.exr``: offsets from the rest pose (:func:`~skinsynth.formats.exr.write_vat`'s layout:
  ``width`` texels a row, ``rows_per_frame`` rows a frame, frames top to bottom);
- ``NAME_normals.exr``: the deformed mesh's unit vertex normals, same layout (area-weighted);

and once for all animations of the folder:

- ``rest.obj`` and ``rest.glb``: the rest mesh, vertices in skinsynth's order, with one UV per
  vertex at the centre of its texel in frame 0, bottom-up like OBJ and OpenGL
  (``u = (i mod width + 0.5) / width``, ``v = 1 − (i div width + 0.5) / height``; glTF stores
  ``1 − v``, its own convention, and engines flip it back on import);
- ``vat.json``: what shaders need (frame count, fps, width, height, rows per frame, bounds,
  encoding, the decode formula, units and up axis).

Decoding frame ``f`` in a vertex shader: ``v_f = v − f · rows_per_frame / height``, sample with
point filtering (no mips, no compression, linear colour space), ``position = rest + texel``.
``docs/vat.md`` spells it out for Unity, Unreal and Houdini's Labs VAT conventions.
"""

import json
import os

import numpy as np

from .errors import FormatError

#: Largest texture side the common engines load (Unity, Unreal, most GPUs: 16384).
MAX_TEXTURE_SIDE = 16384


def texture_layout(vertex_count, frame_count, max_width):
    """(width, rows_per_frame, height) of a VAT."""
    width = int(min(vertex_count, max_width))
    rows = -(-vertex_count // width)
    return width, rows, rows * frame_count


def check_texture_size(path, vertex_count, frame_count, max_width, limit=MAX_TEXTURE_SIDE):
    """FormatError naming ``path`` when the texture would exceed ``limit`` texels on a side."""
    width, rows, height = texture_layout(vertex_count, frame_count, max_width)
    if height > limit or width > limit:
        raise FormatError(path, f"the texture would be {width} × {height} texels ({frame_count} frames × {rows} "
                                f"rows); engines load at most {limit} on a side: play fewer frames or split the "
                                f"animation (--max-width {max_width} already)")
    return width, rows, height


def vertex_uvs(vertex_count, width, height):
    """(V, 2) texel-centre UVs of frame 0, bottom-up (OBJ / OpenGL)."""
    index = np.arange(vertex_count)
    return np.stack([(index % width + 0.5) / width, 1.0 - (index // width + 0.5) / height], axis=1)


def rest_mesh_files(folder, rest_vertices, faces, width, height):
    """``rest.obj`` and ``rest.glb`` in ``folder``: vertices in order, one UV per vertex."""
    import trimesh

    uv = vertex_uvs(len(rest_vertices), width, height)
    # OBJ by hand: trimesh writes UVs only together with a material file, which no VAT shader uses
    with open(os.path.join(folder, "rest.obj"), "w") as handle:
        handle.write("# skinsynth rest mesh: one UV per vertex, the centre of its texel in frame 0 (vat.json)\n")
        np.savetxt(handle, rest_vertices, fmt="v %.9g %.9g %.9g")
        np.savetxt(handle, uv, fmt="vt %.9g %.9g")
        np.savetxt(handle, np.repeat(faces + 1, 2, axis=1), fmt="f %d/%d %d/%d %d/%d")
    mesh = trimesh.Trimesh(rest_vertices, faces, process=False, visual=trimesh.visual.TextureVisuals(uv=uv))
    mesh.export(os.path.join(folder, "rest.glb"))


def sidecar(animations, count, width, rows, height, frames, fps, half, scene, bounds):
    """The ``vat.json`` dict: animations [name, ...], bounds [(min (3,), max (3,))], and what the
    shader needs."""
    return {
        "format": "skinsynth vertex animation texture 1",
        "animations": [{"name": n, "offsets": f"{n}.exr", "normals": f"{n}_normals.exr",
                        "bounds_min": [float(v) for v in b[0]], "bounds_max": [float(v) for v in b[1]]}
                       for n, b in zip(animations, bounds)],
        "rest_mesh": {"obj": "rest.obj", "glb": "rest.glb", "uv": "texel centre of frame 0, v bottom-up"},
        "vertex_count": int(count), "frame_count": int(frames), "fps": float(fps), "width": int(width),
        "height": int(height), "rows_per_frame": int(rows),
        "encoding": {"channels": "RGB", "type": "half" if half else "float32", "offsets": "model units, from the "
                     "rest position", "normals": "unit vectors", "frames": "top to bottom"},
        "decode": "v_f = v - f * rows_per_frame / height; position = rest + sample_point(offsets, (u, v_f))",
        "meters_per_unit": float(scene.meters_per_unit), "up_axis": scene.up_axis,
    }


def write_vat_folder(folder, rest_vertices, faces, animations, fps, scene, max_width=8192, half=False, inputs=(),
                     outputs=()):
    """Write the folder: ``animations`` yields (name, vertices (F, V, 3), unit vertex normals
    (F, V, 3)) of one rest mesh (``pipeline.geometry.vertex_normals`` computes them), and is
    consumed once (it may skin each animation only when asked: a crowd never has to fit in
    memory). The texture size is checked on the first (:func:`check_texture_size`). ``inputs``
    and ``outputs``: the command's input files and other outputs, which the folder must not hold
    (:func:`~skinsynth.formats.output_folder.atomic_folder`). Returns the sidecar dict."""
    from .output_folder import atomic_folder
    from .exr import check_half_range, write_vat

    count = len(rest_vertices)
    names, bounds, layout = [], [], None
    with atomic_folder(folder, inputs, outputs) as tmp:
        for name, vertices, normals in animations:
            if layout is None:
                frames = len(vertices)
                layout = check_texture_size(folder, count, frames, max_width)
            if half:
                check_half_range(folder, vertices - rest_vertices, f"{name}: offsets from the rest pose")
            meta = write_vat(os.path.join(tmp, f"{name}.exr"), rest_vertices, vertices, fps, max_width, half)
            names.append(name)
            bounds.append((meta["vat_bounds_min"], meta["vat_bounds_max"]))
            write_vat(os.path.join(tmp, f"{name}_normals.exr"), np.zeros_like(rest_vertices), normals, fps,
                      max_width, half)
        if layout is None:
            raise ValueError("no animations to write")
        width, rows, height = layout
        rest_mesh_files(tmp, rest_vertices, faces, width, height)
        description = sidecar(names, count, width, rows, height, frames, fps, half, scene, bounds)
        with open(os.path.join(tmp, "vat.json"), "w") as handle:
            json.dump(description, handle, indent=2)
    return description
