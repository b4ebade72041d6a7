"""Engine-ready bone animation: a skeleton's motion in one texture, the skin on the rest mesh.

A folder (written whole, with its manifest, :func:`~skinsynth.formats.output_folder.atomic_folder`):

- ``bones.exr``: RGBA, float32 or half. Global frame ``g`` (the clips laid end to end) and bone
  ``j`` have two texels: ``x = (g mod frames_per_row) · 2B + 2j + k``, ``y = g div
  frames_per_row`` (row 0 on top), ``k = 0`` the rotation quaternion (x, y, z, w), ``k = 1`` the
  translation (x, y, z, 1) of the bone's LBS transform (``pipeline.skeleton.bone_texels``);
- ``rest.glb``: the rest mesh, vertices in skinsynth's order, with the four influences in extra
  UV sets: TEXCOORD_1 = bones 0, 1 and TEXCOORD_2 = bones 2, 3 (as floats), TEXCOORD_3 = weights
  0, 1 and TEXCOORD_4 = weights 2, 3; TEXCOORD_0 holds the material UVs in glTF's convention
  (u, 1 − v), its vertices split at UV seams (the originals first, in order, then the copies,
  each with its original's influences), or zero when the input had no UVs (glTF numbers UV sets
  from 0); ``rest.obj`` the same mesh without the influences, with the UVs as ``vt`` (v up, OBJ's
  convention) and its vertices unsplit;
- ``bones.json``: the layout, the units and up axis, and the clip table: each clip's name, its
  first and last global frame (both inclusive) and fps, so that many clips share one texture.

``docs/bone_textures.md`` gives the decode for three.js, Unity, Unreal and Godot.
"""

import json
import os

import numpy as np

from .errors import FormatError, require_finite
from .vat_bundle import MAX_TEXTURE_SIDE


def bone_texture_layout(bones, frame_count, max_width):
    """(width, frames_per_row, height) of a texture of ``frame_count`` frames of ``bones`` bones."""
    per_frame = 2 * bones
    frames_per_row = max(1, int(max_width) // per_frame)
    width = per_frame * min(frames_per_row, frame_count)
    return width, frames_per_row, -(-frame_count // frames_per_row)


def check_bone_texture_size(path, bones, frame_count, max_width, limit=MAX_TEXTURE_SIDE):
    """FormatError naming ``path`` when the texture would exceed ``limit`` texels on a side."""
    if 2 * bones > max_width:
        raise FormatError(path, f"one frame of {bones} bones takes {2 * bones} texels, more than --max-width "
                                f"{max_width}")
    width, frames_per_row, height = bone_texture_layout(bones, frame_count, max_width)
    if width > limit or height > limit:
        raise FormatError(path, f"the bone texture would be {width} × {height} texels ({frame_count} frames of "
                                f"{bones} bones, {frames_per_row} frames a row); engines load at most {limit} on a "
                                "side: export fewer animations")
    return width, frames_per_row, height


def write_bone_texture_folder(folder, rest_vertices, faces, influences, clips, bones, fps, scene, max_width=8192,
                              half=False, inputs=(), outputs=(), uv_split=None):
    """Write the folder. ``influences``: (bone ids (V, 4), weights (V, 4)); ``clips``: (name,
    texels (F, B, 2, 4)) pairs (``pipeline.skeleton.bone_texels``); ``uv_split``: None, or the
    material UVs split at seams (``pipeline.uv_seams.split_uv_seams``: vertex_map (V',), faces
    (T, 3) into the V' vertices, uvs (V', 2) v up). Returns the bones.json dict."""
    import OpenEXR

    from .gltf import write_static_glb
    from .output_folder import atomic_folder

    names, spans, blocks, total = [], [], [], 0
    for name, texels in clips:
        texels = np.asarray(texels)
        if texels.shape[1:] != (bones, 2, 4):
            raise ValueError(f"texels must have shape (F, {bones}, 2, 4), got {texels.shape}")
        require_finite(folder, f"the bone motion of {name}", texels)
        names.append(name)
        spans.append((total, total + len(texels) - 1))
        blocks.append(texels.reshape(len(texels), -1, 4))
        total += len(texels)
    if not names:
        raise ValueError("no animations to write")
    width, frames_per_row, height = check_bone_texture_size(folder, bones, total, max_width)
    frames = np.concatenate(blocks)  # (G, 2B, 4)
    dtype = np.float16 if half else np.float32
    if half and np.abs(frames).max() > np.finfo(np.float16).max:
        raise FormatError(folder, "bone translations exceed the half-float range (65504): write float32 textures")
    image = np.zeros((height * frames_per_row, 2 * bones, 4), dtype=dtype)
    image[:total] = frames
    image = image.reshape(height, frames_per_row * 2 * bones, 4)[:, :width]
    bone_ids, weights = influences
    description = {
        "format": "skinsynth bone animation texture 1", "texture": "bones.exr", "bones": int(bones),
        "width": int(width), "height": int(height), "frames_per_row": int(frames_per_row), "frame_count": int(total),
        "encoding": {"channels": "RGBA", "type": "half" if half else "float32", "rows": "row 0 on top",
                     "texel": "x = (g mod frames_per_row) * 2 * bones + 2 * bone + k, y = g div frames_per_row; "
                              "k = 0: rotation quaternion (x, y, z, w); k = 1: translation (x, y, z, 1)"},
        "decode": "v = sum_k w_k (rotate(q_k, rest) + t_k), rotate(q, r) = r + 2 q.xyz x (q.xyz x r + q.w r)",
        "clips": [{"name": n, "first": int(a), "last": int(b), "fps": float(fps)} for n, (a, b) in zip(names, spans)],
        "rest_mesh": {"glb": "rest.glb", "obj": "rest.obj",
                      "uv": "TEXCOORD_0 (zero: no material UVs)" if uv_split is None else
                      "TEXCOORD_0 (material UVs, glTF's (u, 1 - v); rest.glb's vertices split at UV seams: the "
                      "originals first, then the copies)",
                      "bones": "TEXCOORD_1 (0, 1), TEXCOORD_2 (2, 3)",
                      "weights": "TEXCOORD_3 (0, 1), TEXCOORD_4 (2, 3)"},
        "vertex_count": int(len(rest_vertices)), "meters_per_unit": float(scene.meters_per_unit),
        "up_axis": scene.up_axis,
    }
    with atomic_folder(folder, inputs, outputs) as tmp:
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        with OpenEXR.File(header, {"RGBA": np.ascontiguousarray(image)}) as exr:
            exr.write(os.path.join(tmp, "bones.exr"))
        ids = np.asarray(bone_ids, dtype=np.float32)
        weights = np.asarray(weights, dtype=np.float32)
        if uv_split is None:
            glb_vertices, glb_faces, texcoords = rest_vertices, faces, np.zeros((len(ids), 2), np.float32)
        else:  # glTF's UV origin is the top left: v' = 1 − v
            vertex_map, glb_faces, uvs = uv_split
            glb_vertices, ids, weights = np.asarray(rest_vertices)[vertex_map], ids[vertex_map], weights[vertex_map]
            texcoords = np.stack([uvs[:, 0], 1.0 - uvs[:, 1]], axis=1)
        write_static_glb(os.path.join(tmp, "rest.glb"), glb_vertices, glb_faces,
                         {"TEXCOORD_0": texcoords, "TEXCOORD_1": ids[:, :2], "TEXCOORD_2": ids[:, 2:],
                          "TEXCOORD_3": weights[:, :2], "TEXCOORD_4": weights[:, 2:]})
        with open(os.path.join(tmp, "rest.obj"), "w") as handle:
            handle.write("# skinsynth rest mesh of a bone animation texture (bones.json); influences in rest.glb\n")
            np.savetxt(handle, rest_vertices, fmt="v %.9g %.9g %.9g")
            if uv_split is None:
                np.savetxt(handle, np.asarray(faces) + 1, fmt="f %d %d %d")
            else:  # OBJ keeps a UV per corner: the vertices stay unsplit, the split vertices are the vt
                np.savetxt(handle, uvs, fmt="vt %.9g %.9g")
                corners = np.stack([np.asarray(faces), glb_faces], axis=2).reshape(len(faces), 6) + 1
                np.savetxt(handle, corners, fmt="f %d/%d %d/%d %d/%d")
        with open(os.path.join(tmp, "bones.json"), "w") as handle:
            json.dump(description, handle, indent=2)
    return description


def read_bone_texture(path):
    """(image (height, width, 4) float32) of a ``bones.exr``; FormatError when unreadable."""
    import OpenEXR

    try:
        with OpenEXR.File(os.fspath(path)) as exr:
            channels = {name: channel.pixels for name, channel in exr.channels().items()}
    except Exception as error:  # OpenEXR raises RuntimeError/IOError with library messages
        raise FormatError(path, f"cannot read as OpenEXR: {error}") from None
    if "RGBA" not in channels:
        raise FormatError(path, "no RGBA channels: not a bone animation texture")
    return np.asarray(channels["RGBA"], dtype=np.float32)
