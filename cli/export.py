"""``skinsynth export``: any animation a file holds, as USD or an OpenEXR vertex-animation texture."""

import contextlib

import click
import numpy as np

from skinsynth.formats.animation_source import AnimationSource
from skinsynth.formats.output_folder import FolderOutputs

from .options import (animation_selection, check_max_width, chosen_animations, device_option, texture_options,
                      up_axis_option)
from .common import report, summary_options, user_errors
from .outputs import (TEXTURES, check_animation_output, check_bone_texture_output, check_texture_output,
                      usd_joint_tree, write_bone_textures, write_gltf, write_textures)


@click.command("export")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(),
              help="Output: .usd/.usda/.usdc, .glb (glTF 2.0: the skinned mesh, one clip per animation), .fbx (the "
                   "skinned mesh, its skeleton's tree or a flat rig) or .abc (an Alembic point cache), both through "
                   "Blender, .exr for a vertex-animation texture, or a folder (ending in /) for an engine-ready one: "
                   "textures, normals, the rest mesh with texel UVs (.obj/.glb), vat.json.")
@click.option("--animation", "selections", multiple=True, type=animation_selection, metavar="N|A:B",
              help="Synthesis file: which animations; play .h5: which characters (repeatable; A:B is A to B−1). "
                   "A USD file or an .exr holds one, a .glb or a folder any number.  [default: all]")
@click.option("--clip", default=None, metavar="NAME",
              help="Skin file with several clips (fit-skin CLIP...): export only this clip's frames, its first at "
                   "the scene's start frame.  [default: every frame; a .glb or a texture folder holds one animation "
                   "per clip, named after it, and a USD stage one timeline whose layer metadata (customLayerData "
                   "\"skinsynth:clips\": names, startTimeCodes, endTimeCodes) says where each clip begins and ends]")
@click.option("--root-motion", is_flag=True,
              help=".glb and UsdSkel: the root joint carries the character's ground motion (its turn about the up "
                   "axis and its ground-plane travel, as synthesize's ground alignment defines it) and the bones move "
                   "in place under it.  [default: the root stays at the origin]")
@click.option("--quantize", type=click.Choice(["8", "16"]), default=None,
              help=".glb only: vertex weights as normalised 8- or 16-bit integers (rows summing exactly to one).  "
                   "[default: 32-bit floats]")
@click.option("--as", "kind", type=click.Choice(["skel", "points", "bones"]), default=None,
              help="USD: UsdSkel skeleton with joint weights (editable), or a baked time-sampled mesh. A folder: "
                   "bones writes bone-animation textures (every animation's bone motion in one bones.exr, the "
                   "influences on rest.glb, a clip table in bones.json) instead of vertex-animation textures.  "
                   "[default: skel where the file has a skeleton (skin and synthesis files), else points]")
@device_option("Where the skinning kernel runs: auto, cpu, cuda or cuda:N.")
@texture_options("Textures only: store 16-bit half floats instead of 32-bit.",
                 "EXR only: texture width limit; vertices wrap to more rows.")
@up_axis_option("USD stage up axis; for .glb and .abc, the axis the input is up along (glTF and Alembic are Y "
                "up).  [default: the input's, as fit-skin recorded it]")
@summary_options
@user_errors
def export(path, output, selections, clip, kind, root_motion, quantize, device, half, max_width, up_axis, quiet,
           as_json):
    """Export any animation a file holds.

    \b
    - a skin file (and controls, puppet and graph files, which carry it): the LBS reconstruction
      of the example frames, every clip's (--clip: one clip's);
    - a synthesis file: its animations (--animation), read one at a time, so a cluster run of
      any size exports in bounded memory;
    - play's .h5: its characters (--animation), as point caches or textures.

    At the input's units, up axis, time codes and mesh prim path (as fit-skin recorded them): as
    UsdSkel (--as skel: joints, bind/rest transforms, animation and joint weights, so animators
    get curves), as a time-sampled mesh (--as points), as an Alembic point cache (.abc, for Houdini
    and Maya, written by Blender's exporter: docs/blender.md), or as an OpenEXR vertex-animation
    texture (.exr: per-vertex offsets from the rest pose, one row block per frame, bounds in the
    header; a folder holds every animation chosen, one clip each).

    \b
    Examples:
      skinsynth export skin.h5 -o skin.usdc
      skinsynth export horse.h5 --clip collapse -o collapse.usdc
      skinsynth export skin.h5 -o skin.usda --as points
      skinsynth export skin.h5 -o skin_vat.exr --half
      skinsynth export bones.h5 --animation 7 -o walk_7.usdc
      skinsynth export bones.h5 --animation 7 -o walk_7.abc
      skinsynth export skin.h5 -o rig.fbx
      skinsynth export bones.h5 --animation 0:16 -o crowd_vat/
    """
    from skinsynth.gpu import resolve_device
    from skinsynth.pipeline.errors import OptionError

    folders = FolderOutputs([path], [output])
    output_kind = check_animation_output(output, ("usd", "gltf", "exr", "abc", "fbx", "folder"), [path], folders)
    if output_kind == "abc" and kind not in (None, "points"):
        raise OptionError(f"{output}: an Alembic file is a point cache (--as points); for a skeleton write FBX, "
                          "UsdSkel (.usdc) or glTF (.glb)")
    if output_kind == "fbx" and kind not in (None, "skel"):
        raise OptionError(f"{output}: an FBX file is a skinned mesh (--as skel); for a point cache write Alembic "
                          "(.abc) or USD (.usdc --as points)")
    if output_kind in ("abc", "fbx"):
        from skinsynth.formats.blender import check_blender

        check_blender(output, "write")
    if kind == "bones" and output_kind != "folder":
        raise OptionError(f"--as bones writes a folder of bone-animation textures: end -o with / (-o {_stem(output)}/)")
    if quantize is not None and output_kind != "gltf":
        raise OptionError(f"--quantize is for .glb outputs (got {output})")
    check_max_width(max_width)
    device = resolve_device(device)
    with _animations(path, device, clip) as source:
        chosen = chosen_animations(selections, source.count, source.path, source.what)
        kind = kind or ("skel" if source.has_skeleton and output_kind != "abc" else "points")
        _check_request(path, output, output_kind, kind, source, chosen, root_motion, max_width)
        written = _write(output, output_kind, kind, source, chosen, half, max_width, quantize, root_motion, up_axis,
                         folders)
    report(*_summary(output, output_kind, kind, source, chosen, clip, half, written), as_json, quiet)


def _write(output, output_kind, kind, source, chosen, half, max_width, quantize, root_motion, up_axis, folders):
    """Write the ``chosen`` animations of ``source`` to ``output`` as ``kind`` (--as); returns the
    bytes of bones.exr per animation (--as bones), else None."""
    if kind == "bones":
        return write_bone_textures(output, source.skin, (part for a in chosen for part in source.parts(a)), half,
                                   max_width, folders.guard(output), label=source.path) // len(chosen)
    if output_kind == "gltf":
        write_gltf(output, source.skin, (part for a in chosen for part in source.parts(a)),
                   up_axis or source.scene.up_axis, None if quantize is None else int(quantize), root_motion,
                   label=source.path, skeleton=source.skin.skeleton)
    elif output_kind in TEXTURES:
        frames = (part for a in chosen for part in source.vertex_parts(a)) if output_kind == "folder" else \
            ((source.names[a], source.vertices(a)) for a in chosen)  # a folder: a texture per clip
        write_textures(output, output_kind, source.rest_vertices, source.faces, frames, source.fps,
                       source.scene, half, max_width, folders.guard(output))
    elif output_kind == "abc":
        from skinsynth.formats.blender import write_alembic

        write_alembic(output, source.vertices(chosen[0]), source.faces, source.fps, source.scene, up_axis)
    elif output_kind == "fbx":
        from skinsynth.formats.blender import write_fbx

        write_fbx(output, source.skin, *source.motions(chosen[0]), up_axis)
    elif kind == "skel":
        from skinsynth.formats.usd import write_skel_cache

        skin = source.skin
        rotations, translations = source.motions(chosen[0])
        root = None
        if root_motion:
            from skinsynth.pipeline.rig.skeleton import ground_motion

            up = np.eye(3)["XYZ".index(up_axis or skin.scene.up_axis)]
            root = ground_motion(np.asarray(rotations, np.float64), np.asarray(translations, np.float64),
                                 skin.rest_vertices, skin.bone_indices, skin.bone_weights, up)
        tree = None if skin.skeleton is None else usd_joint_tree(skin.skeleton, rotations, translations, root)
        write_skel_cache(output, skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights, rotations,
                         translations, skin.bone_rest_frames[:, :3, 3] if tree is None else skin.skeleton["joints"],
                         skin.fps, up_axis=up_axis, scene=skin.scene, root_motion=root, clips=source.clips,
                         joint_tree=tree)
    else:
        from skinsynth.formats.usd import write_points_cache

        write_points_cache(output, source.vertices(chosen[0]), source.faces, source.fps, up_axis=up_axis,
                           scene=source.scene, clips=source.clips)
    return None


def _summary(output, output_kind, kind, source, chosen, clip, half, bytes_per_animation):
    """The command's summary (--json) and its text lines: what was written, of which animations
    or clips; with --as bones, the texels per animation against a vertex-animation folder's."""
    to_exr = output_kind in TEXTURES
    what = "bone-animation texture" if kind == "bones" else "vertex-animation texture" if to_exr else \
        "glTF" if output_kind == "gltf" else "Alembic point cache" if output_kind == "abc" else \
        "FBX skin" if output_kind == "fbx" else \
        ("UsdSkel" if kind == "skel" else "point cache")
    joints = int(source.skin.rotations.shape[1]) + 1 if what in ("UsdSkel", "glTF") else \
        int(source.skin.rotations.shape[1]) if what == "FBX skin" else None  # bones, and the root of USD's and glTF's
    summary = {"output": output, "frames": int(source.frames), "vertices": int(source.rest_vertices.shape[0]),
               "kind": what, "joints": joints, "animations": [int(a) for a in chosen],
               "names": [name for a in chosen for name in source.part_names(a)]
               if output_kind in ("gltf", "folder") else [source.names[a] for a in chosen]}
    if source.clips is not None:
        summary["clips"] = list(source.clips[0])
    detail = "" if to_exr else f" ({what}, {joints} joints)" if joints else " (point cache)"
    chosen_text = "" if source.count == 1 else f" of {len(chosen)} {source.what}(s) ({_ranges(chosen)})"
    if source.clips is not None and (clip is not None or len(source.clips[0]) > 1):
        chosen_text = f" of clip{'s' if len(source.clips[0]) > 1 else ''} {', '.join(source.clips[0])}"
    lines = [f"wrote {output}: {source.frames} frames{chosen_text}, {source.rest_vertices.shape[0]} vertices" + detail]
    if kind == "bones":
        texel = 2 if half else 4
        raw = source.frames * 2 * source.skin.rotations.shape[1] * 4 * texel
        vat = 2 * source.frames * source.rest_vertices.shape[0] * 3 * texel  # offsets and normals
        summary.update(bytes_per_animation=bytes_per_animation, texel_bytes_per_animation=raw,
                       vat_texel_bytes_per_animation=vat)
        lines.append(f"bone textures: {raw / 1e6:.3f} MB of texels per animation ({bytes_per_animation / 1e6:.3f} MB "
                     f"compressed on disk); a vertex-animation folder: {vat / 1e6:.1f} MB of texels per animation")
    return summary, lines


def _check_request(path, output, output_kind, kind, source, chosen, root_motion, max_width):
    """Refuse, before any work, what the chosen animations cannot become in ``output``, and a
    texture too large at ``max_width``."""
    from skinsynth.pipeline.errors import OptionError

    if output_kind not in ("folder", "gltf") and len(chosen) != 1:
        raise OptionError(f"{output}: {len(chosen)} {source.what}s chosen, and a {output_kind.upper()} file holds "
                          f"one: give --animation N, or a .glb or a folder (-o {_stem(output)}/) for several")
    if not source.has_skeleton:
        needs = "a glTF skin" if output_kind == "gltf" else "an FBX skin" if output_kind == "fbx" else \
            "bone textures" if kind == "bones" else \
            "--as skel" if kind == "skel" and output_kind == "usd" else None
        if needs:
            raise OptionError(f"{path}: {needs} needs a skeleton, and the {source.what}s of a played file are "
                              "vertices only: export them as USD points or vertex-animation textures")
    if root_motion and not (output_kind == "gltf" or (output_kind == "usd" and kind == "skel")):
        raise OptionError(f"--root-motion moves a skeleton's root: it is for .glb and UsdSkel outputs (got {output}"
                          + (" --as points)" if output_kind == "usd" else ")"))
    if kind == "bones":
        check_bone_texture_output(output, source.skin.rotations.shape[1], source.frames * len(chosen), max_width)
    else:  # a folder holds one texture per animation
        check_texture_output(output, output_kind, source.rest_vertices.shape[0], source.frames, max_width)


def _stem(path):
    text = str(path)
    return text[:text.rfind(".")] if "." in text else text


def _no_clips(path, clip, what):
    """Refuse --clip for a file without a skin's example clips (``what`` says what it is)."""
    from skinsynth.pipeline.errors import OptionError

    if clip is not None:
        raise OptionError(f"--clip {clip}: chooses one clip of a skin file's examples, and {path} is {what}")


def _ranges(indices):
    """[0, 1, 2, 7] -> "0–2, 7"."""
    parts, start = [], None
    for i, a in enumerate(indices):
        if start is None:
            start = a
        if i + 1 == len(indices) or indices[i + 1] != a + 1:
            parts.append(f"{start}" if start == a else f"{start}–{a}")
            start = None
    return ", ".join(parts)


@contextlib.contextmanager
def _animations(path, device, clip=None):
    """The :class:`AnimationSource` of any file that holds animation (a synthesis's motions stay in the
    file, read one animation at a time); ``clip`` names the one clip of a skin's examples to
    take (OptionError for an unknown one, or a file that is no skin's)."""
    from skinsynth.formats.errors import FormatError
    from skinsynth.formats.model import read_header, read_model
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.gpu import lbs

    try:
        stage, _ = read_header(path)
    except FormatError as error:
        if "not a skinsynth model file" not in str(error):
            raise
        stage = None
    if stage is None:  # play's .h5: characters of vertices
        from skinsynth.formats.meshseq import read_played_characters

        try:
            names, vertices, faces, fps = read_played_characters(path)
        except FormatError as error:
            if not error.problem.startswith("no '"):
                raise
            raise FormatError(path, "not a skinsynth model file, nor a played animation (an HDF5 file with "
                                    f"'vertices' and 'faces'): {error.problem}") from None
        from skinsynth.formats.scene import Scene

        _no_clips(path, clip, "a played file, whose characters --animation chooses")
        yield AnimationSource(path, "character", list(names), vertices.shape[1], vertices[0, 0], faces, fps, Scene(),
                      vertices=lambda a: vertices[a])
        return
    skin = read_skin(path, read_model(path, groups=("mesh", "examples", "skin")))
    if stage != "synthesis":
        from skinsynth.pipeline.inputs.clips import Clips

        clips = Clips(skin.clip_names, skin.clip_frames)
        rotations, translations, name = skin.rotations, skin.translations, "animation"
        if clip is not None:  # its frames alone, renumbered from the scene's start frame
            frames = clips.select([clip], "--clip")
            rotations, translations, name = rotations[frames], translations[frames], clip
            clips = clips.subset([clip])
        yield AnimationSource(path, "animation", [name], rotations.shape[0], skin.rest_vertices, skin.faces,
                      skin.fps, skin.scene, skin=skin, motions=lambda a: (rotations, translations),
                      vertices=lambda a: lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, rotations,
                                             translations, device=device),
                      clips=(clips.names, clips.frames))
        return
    _no_clips(path, clip, "a synthesis file, whose animations --animation chooses")
    from skinsynth.formats.synthesis_file import open_motions
    from skinsynth.pipeline.synthesis import SkinnedAnimations

    with open_motions(path) as (F, t):
        count, frames = F.shape[:2]
        skinned = SkinnedAnimations(skin, F, t, np.zeros((count, 3)), device)  # as synthesize --usd skins them
        try:
            yield AnimationSource(path, "animation", [f"animation_{a:04d}" for a in range(count)], frames, skin.rest_vertices,
                          skin.faces, skin.fps, skin.scene, skin=skin, motions=lambda a: (F[a], t[a]),
                          vertices=lambda a: skinned[a])
        finally:
            skinned.close()
