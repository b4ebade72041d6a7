"""``skinsynth play``: drive the trained puppet with control trajectories, many characters at once."""

import os

import click
import numpy as np

from skinsynth.formats.output_folder import FolderOutputs
from skinsynth.pipeline.runtime.resources import check_memory

from .options import FINITE_FLOAT, device_option, marker_take_options, texture_options, up_axis_option
from .common import report, summary_options, user_errors
from .outputs import (TEXTURES, check_animation_output, check_bone_texture_output, check_texture_output,
                      usd_joint_tree, write_bone_textures, write_gltf, write_textures)


@click.command("play")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("--controls", "-c", "control_files", multiple=True, required=True,
              help="Control trajectories: CSV (frame,point,x,y,z), .npy (F, n_c, 3), a mesh sequence whose "
                   "control vertices are used, or a motion-capture take (.c3d, with a marker layout: --markers; "
                   "docs/mocap.md). Repeat for several characters.")
@click.option("-o", "--output", required=True, type=click.Path(),
              help="USD (.usd/.usda/.usdc), glTF (.glb: the rig, one clip per character, a puppet's correctives "
                   "as at most 8 morph targets; --skinning linear), an OpenEXR vertex-animation texture (.exr, one "
                   "character), a folder (ending in /: engine-ready textures per character, normals, the rest mesh "
                   "with texel UVs as .obj/.glb and vat.json; with --as bones, bone-animation textures), or .h5 "
                   "vertices.")
@click.option("--instances", default=1, show_default=True, type=int,
              help="Characters from one --controls file, each starting a fraction of the clip later.")
@click.option("--as", "kind", type=click.Choice(["skel", "points", "bones"]), default="skel", show_default=True,
              help="USD: UsdSkel skinned as played (skinningMethod classicLinear or dualQuaternion, by "
                   "--skinning; editable bones; a puppet's correctives as blend shapes), or baked time-sampled "
                   "meshes. A folder: bones writes bone-animation textures "
                   "(each character a clip of one bones.exr, in place; --skinning linear, no correctives; "
                   "docs/bone_textures.md) instead of vertex-animation textures.")
@click.option("--skinning", type=click.Choice(["linear", "dual-quaternion"]), default=None,
              help="Linear blend skinning or dual quaternions (Feng §6.3), for every output. UsdSkel's "
                   "dualQuaternion is ignored by Blender's importer (it skins linearly: 1.7e-2 of the diagonal "
                   "away on the horse); linear gives a rig every DCC and engine plays as computed.  [default: the "
                   "one the puppet was trained for (train-kcca --skinning, linear unless asked otherwise)]")
@texture_options("Textures (-o DIR/ or .exr): 16-bit half floats instead of 32-bit.",
                 "Textures: width limit; vertices wrap to more rows.")
@click.option("--spacing", default=None, type=FINITE_FLOAT,
              help="Grid spacing between characters on the ground plane (default 1.5 × the largest rest bounding-box side).")
@click.option("--translation-solver/--no-translation-solver", default=True, show_default=True,
              help="Recompute bone translations with the Poisson solve (needs a puppet trained with it).")
@click.option("--ik/--no-ik", default=True, show_default=True, help="Frames beyond the puppet's examples follow the "
              "controls with a skeleton (a jointed skin's own, fit-skin --skeleton; a free skin's found from its "
              "bones) instead of the kernel CCA's extrapolation, and so do frames near them whose skin the "
              "prediction tears (docs/mocap.md).")
@device_option("auto, cpu, cuda or cuda:N.")
@click.option("--threads", default=0, type=int, help="CPU threads for the kernels (default: all cores).")
@up_axis_option("Ground plane and USD up axis (default: the input's, as fit-skin recorded it).")
@marker_take_options
@summary_options
@user_errors
def play(path, control_files, output, instances, kind, skinning, half, max_width, spacing, translation_solver, ik,
         device, threads, up_axis, as_json, quiet, **take_options):
    """Play a puppet: control-point trajectories in, whole-surface animation out (Feng §6).

    Per frame and character: kernel vector, d = M ξ for all bones, dual-quaternion
    normalisation, Poisson translations, then skinning by the puppet's skinning (linear blend
    unless it was trained with train-kcca --skinning dual-quaternion; --skinning chooses) — all
    frames and characters in one batch of warp kernels (CUDA when present, else the CPU).

    \b
    Examples:
      skinsynth play face.puppet.h5 --controls mocap.csv -o face.usdc
      skinsynth play horse.puppet.h5 --controls gallop.npy --instances 100 -o herd.usdc --as points
      skinsynth play horse.puppet.h5 -c a.npy -c b.npy -o horses.h5 --json
      skinsynth play bar.puppet.h5 -c bar.npz --instances 16 -o crowd_vat/
      skinsynth play samba.puppet.h5 -c serve.c3d --markers samba.layout.json -o serve.glb
    """
    from skinsynth.formats.puppet_file import read_puppet
    from skinsynth.gpu import resolve_device
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.puppet import (character_offsets, play_characters, play_extrapolation,
                                           play_summary, puppet_from_record)

    from .marker_take import check_take_options
    from .skeleton_poses import skeleton_poses

    check_take_options(control_files, take_options)
    folders = FolderOutputs([path, *control_files], [output])
    output_kind = check_animation_output(output, ("usd", "gltf", "exr", "h5", "folder"), [path, *control_files],
                                         folders)
    if kind == "bones" and output_kind != "folder":
        raise OptionError(f"--as bones writes a folder of bone-animation textures: end -o with / "
                          f"(-o {os.path.splitext(output)[0]}/)")
    device = resolve_device(device)
    record, _, skin = read_puppet(path)
    puppet = puppet_from_record(record)
    skinning = _check_puppet(path, output, output_kind, kind, puppet, skinning or puppet.skinning, translation_solver)
    takes, trajectories, skin = _read_controls(path, control_files, puppet, record, skin, take_options)
    controls = _characters(output, output_kind, kind, skin, trajectories, instances, max_width)  # (C, F, n_c, 3)
    characters, frames = controls.shape[:2]
    up_axis = up_axis or skin.scene.up_axis
    offsets = character_offsets(characters, spacing, skin.rest_vertices, up_axis)
    # before any output is written: writing is the last step (a signal after it would say "interrupted"
    # of a complete file)
    extrapolation = play_extrapolation(puppet, skin.examples, control_files, trajectories)
    poses = skeleton_poses(puppet, skin, device) if ik else None
    vertices, seconds, beyond = play_characters(puppet, controls.reshape(-1, *controls.shape[2:]), device, skinning,
                                                translation_solver, threads, poses, frames, skin.fps)
    vertices = vertices.reshape(characters, frames, -1, 3) + offsets[:, None, None, :].astype(np.float32)
    morph = _write(output, output_kind, kind, path, skin, puppet, controls, vertices, offsets, up_axis, skinning,
                   translation_solver, half, max_width, folders, beyond)
    summary, lines = play_summary(characters, frames, seconds, device, skinning, translation_solver, [output],
                                  extrapolation, [(take.summary, take.lines) for take in takes], morph,
                                  0 if puppet.correctives is None else len(puppet.correctives.offsets), beyond)
    report(summary, lines, as_json, quiet)


def _check_puppet(path, output, output_kind, kind, puppet, skinning, translation_solver):
    """Refuse, before any work, an output ``puppet`` cannot play with ``skinning``; returns it."""
    from skinsynth.pipeline.errors import OptionError

    if (output_kind == "gltf" or kind == "bones") and skinning != "linear":
        what = "glTF skins" if output_kind == "gltf" else "bone textures skin"
        raise OptionError(f"{output}: {what} linearly, and this plays {skinning} skinning (the puppet was trained "
                          f"for {puppet.skinning}): train it with train-kcca --skinning linear, or give --skinning "
                          "linear")
    if kind == "bones" and puppet.correctives is not None:
        raise OptionError(f"{path}: the puppet's pose-space correctives ({len(puppet.correctives.offsets)} shapes) "
                          "move vertices, and bone textures carry bones only: train it with train-kcca --correctives "
                          f"off, or write the vertex-animation folder (-o {output} without --as bones)")
    if translation_solver and puppet.translations is None:
        raise OptionError(f"{path}: trained without the translation solver; play with --no-translation-solver")
    return skinning


def _read_controls(path, control_files, puppet, record, skin, take_options):
    """(the motion-capture takes among ``control_files`` (:class:`~skinsynth.cli.marker_take.TakeControls`),
    every file's trajectory (F, n_c, 3), the skin played: at the takes' rate from the first take's
    time when there are takes)."""
    from dataclasses import replace

    from skinsynth.formats.trajectories import read_control_trajectories

    from .marker_take import is_take, take_controls

    count = len(puppet.control_indices)
    takes = {f: take_controls(f, puppet, record, skin, take_options, path) for f in control_files if is_take(f)}
    trajectories = [takes[f].controls if f in takes else
                    read_control_trajectories(f, count, puppet.control_indices, skin.rest_vertices.shape[0])
                    for f in control_files]
    if takes:  # the output plays at the takes' rate, from the first take's time
        first = next(iter(takes.values()))
        skin = replace(skin, fps=first.fps, scene=skin.scene.overridden(start_frame=first.start_time * first.fps))
    return list(takes.values()), trajectories, skin


def _characters(output, output_kind, kind, skin, trajectories, instances, max_width):
    """Every character's controls (C, F, n_c, 3) (``pipeline.puppet.instance_trajectories``), once
    their vertices are known to fit in memory and their textures within their limits."""
    from skinsynth.pipeline.puppet import instance_trajectories

    if instances > 0 and trajectories:  # the vertices (float32, and their placed copy) before any is allocated
        played = max(len(trajectories), instances) * trajectories[0].shape[0]
        check_memory(played * (skin.rest_vertices.shape[0] * 3 * 4 * 2 + trajectories[0].shape[1] * 3 * 8 * 3),
                     f"{max(len(trajectories), instances)} character(s) × {trajectories[0].shape[0]} frames")
    controls = instance_trajectories(trajectories, instances)
    characters, frames = controls.shape[:2]
    if kind == "bones":  # every character a clip of one texture
        check_bone_texture_output(output, skin.rotations.shape[1], frames * characters, max_width)
    else:
        check_texture_output(output, output_kind, skin.rest_vertices.shape[0], frames, max_width, characters)
    return controls


def _write(output, output_kind, kind, label, skin, puppet, controls, vertices, offsets, up_axis, skinning,
           translation_solver, half, max_width, folders, beyond=None):
    """Write the characters, controls (C, F, n_c, 3) played as vertices (C, F, V, 3) placed by
    offsets (C, 3): a rig (glTF, bone textures, UsdSkel) from their world bones, else their
    vertices (USD points, textures, .h5). Returns the glTF's morph targets
    (``pipeline.rig.morph_targets.played_morph_targets``), or None."""
    from skinsynth.pipeline.puppet import character_bones

    names = [f"character_{c:03d}" for c in range(len(controls))]
    if output_kind == "gltf" or kind == "bones" or (output_kind == "usd" and kind == "skel"):
        rotations, translations, shape_weights = character_bones(puppet, controls, translation_solver, skin.skeleton,
                                                                 beyond)
        clips = ((name, rotations[c], translations[c]) for c, name in enumerate(names))  # each character in place
        if kind == "bones":  # one rig, each character a clip (no grid: clips alternate)
            write_bone_textures(output, skin, clips, half, max_width, folders.guard(output), label=label)
        elif output_kind == "gltf":
            from skinsynth.pipeline.mesh.geometry import bounding_box_diagonal
            from skinsynth.pipeline.rig.morph_targets import played_morph_targets

            morph = played_morph_targets(None if puppet.correctives is None else puppet.correctives.offsets,
                                         shape_weights, bounding_box_diagonal(skin.rest_vertices), len(names), label)
            write_gltf(output, skin, clips, up_axis, morph=morph[:2] if morph and len(morph[0]) else None,
                       skeleton=skin.skeleton)
            return morph
        else:
            _write_rig(output, skin, puppet, rotations, translations + offsets[:, None, None, :], shape_weights,
                       names, up_axis, skinning)
    elif output_kind == "usd":
        from skinsynth.formats.usd import write_points_characters

        write_points_characters(output, vertices, skin.faces, skin.fps, names=names, up_axis=up_axis, scene=skin.scene)
    elif output_kind in TEXTURES:
        # each character's offsets from its own grid cell, so one rest mesh serves them all
        write_textures(output, output_kind, skin.rest_vertices, skin.faces,
                       ((name, vertices[c] - offsets[c].astype(np.float32)) for c, name in enumerate(names)),
                       skin.fps, skin.scene, half, max_width, folders.guard(output))
    else:
        from skinsynth.formats.meshseq import write_vertex_animation

        write_vertex_animation(output, vertices, skin.faces, skin.fps, names)
    return None


def _write_rig(output, skin, puppet, rotations, translations, shape_weights, names, up_axis, skinning):
    """The characters as UsdSkel rigs: world bones, rotations (C, F, B, 3, 3) and translations
    (C, F, B, 3) placed, corrective blend weights (C·F, n_p) or None."""
    from skinsynth.formats.usd import write_skel_characters

    characters, frames = rotations.shape[:2]
    shapes = None  # the correctives are blend shapes, played before skinning, as ± pairs in [0, 1]
    if shape_weights is not None:
        from skinsynth.pipeline.rig.morph_targets import unit_range_pairs

        pairs, weights = unit_range_pairs(puppet.correctives.offsets, shape_weights.reshape(characters, frames, -1))
        shapes = (pairs, weights, [f"shape_{j:03d}{s}" for j in range(len(pairs) // 2) for s in "pn"])
    tree, centres = None, skin.bone_rest_frames[:, :3, 3]
    if skin.skeleton is not None:  # the joint tree, every character's frames at once (locals are per frame)
        tree, centres = usd_joint_tree(skin.skeleton, rotations, translations), skin.skeleton["joints"]
    write_skel_characters(output, skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights,
                          rotations, translations, centres, skin.fps, names=names,
                          up_axis=up_axis, skinning=skinning, blend_shapes=shapes, scene=skin.scene, joint_tree=tree)
    if skinning == "dual-quaternion":
        click.echo("warning: Blender's USD importer ignores skinningMethod dualQuaternion and skins this rig "
                   "linearly, away from what skinsynth computed; --skinning linear gives a rig every DCC "
                   "plays as computed", err=True)
