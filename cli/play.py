"""``skinsynth play``: drive the trained puppet with control trajectories, many characters at once."""

import os

import click
import numpy as np

from .options import device_option, marker_take_options, texture_options, up_axis_option
from .common import check_memory, report, summary_options, FolderOutputs, user_errors
from .outputs import (TEXTURES, check_animation_output, check_bone_texture_output, check_texture_output,
                      write_bone_textures, write_gltf, write_textures)



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
@click.option("--spacing", default=None, type=float,
              help="Grid spacing between characters on the ground plane (default 1.5 × the largest rest bounding-box side).")
@click.option("--translation-solver/--no-translation-solver", default=True, show_default=True,
              help="Recompute bone translations with the Poisson solve (needs a puppet trained with it).")
@device_option("auto, cpu, cuda or cuda:N.")
@click.option("--threads", default=0, type=int, help="CPU threads for the kernels (default: all cores).")
@up_axis_option("Ground plane and USD up axis (default: the input's, as fit-skin recorded it).")
@marker_take_options
@summary_options
@user_errors
def play(path, control_files, output, instances, kind, skinning, half, max_width, spacing, translation_solver, device,
         threads, up_axis, as_json, quiet, **take_options):
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
    from skinsynth.pipeline.puppet import puppet_from_record
    from skinsynth.formats.trajectories import read_control_trajectories
    from skinsynth.gpu import resolve_device
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.mesh.geometry import grid_offsets, largest_side
    from skinsynth.pipeline.puppet import instance_trajectories, play_characters, world_bones
    from skinsynth.pipeline.rig.skeleton import hold_joints

    from .marker_take import check_take_options, is_take, take_controls

    check_take_options(control_files, take_options)
    folders = FolderOutputs([path, *control_files], [output])
    output_kind = check_animation_output(output, ("usd", "gltf", "exr", "h5", "folder"), [path, *control_files],
                                         folders)
    bone_textures = kind == "bones"
    if bone_textures and output_kind != "folder":
        raise OptionError(f"--as bones writes a folder of bone-animation textures: end -o with / "
                          f"(-o {os.path.splitext(output)[0]}/)")
    device = resolve_device(device)
    record, _, skin = read_puppet(path)
    puppet = puppet_from_record(record)
    skinning = skinning or puppet.skinning
    if (output_kind == "gltf" or bone_textures) and skinning != "linear":
        what = "glTF skins" if output_kind == "gltf" else "bone textures skin"
        raise OptionError(f"{output}: {what} linearly, and this plays {skinning} skinning (the puppet was trained "
                          f"for {puppet.skinning}): train it with train-kcca --skinning linear, or give --skinning "
                          "linear")
    if bone_textures and puppet.correctives is not None:
        raise OptionError(f"{path}: the puppet's pose-space correctives ({len(puppet.correctives.offsets)} shapes) "
                          "move vertices, and bone textures carry bones only: train it with train-kcca --correctives "
                          f"off, or write the vertex-animation folder (-o {output} without --as bones)")
    if translation_solver and puppet.translations is None:
        raise OptionError(f"{path}: trained without the translation solver; play with --no-translation-solver")
    count = len(puppet.control_indices)
    takes = {f: take_controls(f, puppet, record, skin, take_options, path) for f in control_files if is_take(f)}
    trajectories = [takes[f].controls if f in takes else
                    read_control_trajectories(f, count, puppet.control_indices, skin.rest_vertices.shape[0])
                    for f in control_files]
    if takes:  # the output plays at the takes' rate, from the first take's time
        from dataclasses import replace

        first = next(iter(takes.values()))
        skin = replace(skin, fps=first.fps, scene=skin.scene.overridden(start_frame=first.start_time * first.fps))
    if instances > 0 and trajectories:  # the vertices (float32, and their placed copy) before any is allocated
        played = max(len(trajectories), instances) * trajectories[0].shape[0]
        check_memory(played * (skin.rest_vertices.shape[0] * 3 * 4 * 2 + count * 3 * 8 * 3),
                     f"{max(len(trajectories), instances)} character(s) × {trajectories[0].shape[0]} frames")
    controls = instance_trajectories(trajectories, instances)  # (C, F, n_c, 3)
    characters, frames = controls.shape[:2]
    if bone_textures:  # every character a clip of one texture
        check_bone_texture_output(output, skin.rotations.shape[1], frames * characters, max_width)
    else:
        check_texture_output(output, output_kind, skin.rest_vertices.shape[0], frames, max_width, characters)
    spacing = 1.5 * largest_side(skin.rest_vertices) if spacing is None else spacing
    if not np.isfinite(spacing) or spacing < 0.0:
        raise OptionError(f"--spacing must be a finite distance ≥ 0 (got {spacing})")
    up_axis = up_axis or skin.scene.up_axis
    offsets = grid_offsets(characters, spacing, up_axis) if characters > 1 else np.zeros((1, 3))

    # before any output is written: writing is the last step (a signal after it would say "interrupted"
    # of a complete file)
    extrapolation, extrapolation_lines = _extrapolation(puppet, skin, control_files, trajectories)
    flat = controls.reshape(-1, count, 3)
    vertices, seconds = play_characters(puppet, flat, device, skinning, translation_solver, threads)
    vertices = vertices.reshape(characters, frames, -1, 3) + offsets[:, None, None, :].astype(np.float32)

    names = [f"character_{c:03d}" for c in range(characters)]
    morph = None
    # A skin with a skeleton (/skin/skeleton): the bones play's path predicts do not hold its joints
    # (about 1.5 % of the diagonal on the walker), so its rig outputs put every jointed bone back on
    # its joint (pipeline.skeleton.hold_joints) and are written as the joint tree; `evaluate` reports
    # what that costs (kcca_on_joints). Vertex outputs play the prediction itself.
    skeleton = None if skin.skeleton is None else tuple(skin.skeleton[k] for k in ("parents", "jointed", "joints"))
    if output_kind == "gltf" or bone_textures:  # one rig, each character a clip in place (no grid: clips alternate)
        rotations, translations, shape_weights = world_bones(puppet, flat, translation_solver)
        if skeleton is not None:
            hold_joints(rotations, translations, *skeleton)
        rotations = rotations.reshape(characters, frames, *rotations.shape[1:])
        translations = translations.reshape(characters, frames, *translations.shape[1:])
        clips = ((name, rotations[c], translations[c]) for c, name in enumerate(names))
        if bone_textures:
            write_bone_textures(output, skin, clips, half, max_width, folders.guard(output), label=path)
        else:
            morph = _corrective_morph_targets(path, skin, puppet, shape_weights, characters)
            write_gltf(output, skin, clips, up_axis, morph=morph[:2] if morph and len(morph[0]) else None,
                       skeleton=skin.skeleton)
        written = [output]
    elif output_kind == "usd":
        if kind == "skel":
            bones = world_bones(puppet, flat, translation_solver)
            if skeleton is not None:
                hold_joints(bones[0], bones[1], *skeleton)
            _write_rig(output, skin, puppet, bones, offsets, names, up_axis, skinning)
        else:
            from skinsynth.formats.usd import write_points_characters

            write_points_characters(output, vertices, skin.faces, skin.fps, names=names, up_axis=up_axis,
                                    scene=skin.scene)
        written = [output]
    elif output_kind in TEXTURES:
        # each character's offsets from its own grid cell, so one rest mesh serves them all
        write_textures(output, output_kind, skin.rest_vertices, skin.faces,
                       ((name, vertices[c] - offsets[c].astype(np.float32)) for c, name in enumerate(names)),
                       skin.fps, skin.scene, half, max_width, folders.guard(output))
        written = [output]
    else:
        from skinsynth.formats.meshseq import write_vertex_animation

        write_vertex_animation(output, vertices, skin.faces, skin.fps, names)
        written = [output]
    summary = {"frames": int(frames), "characters": int(characters), "seconds": round(seconds, 4),
              "frames_per_second": round(frames / seconds, 1),
              "character_frames_per_second": round(characters * frames / seconds, 1),
              "device": device, "translation_solver": bool(translation_solver), "skinning": skinning,
              "outputs": written, "extrapolation": extrapolation}
    if takes:
        summary["takes"] = [take.summary for take in takes.values()]
    lines = [line for take in takes.values() for line in take.lines] + [f"played {characters} character(s) × {frames} frames on {device} in {seconds:.3f} s: "
             f"{summary['frames_per_second']:.0f} frames/s, {summary['character_frames_per_second']:.0f} "
             f"character-frames/s (compute only); wrote {', '.join(written)}"]
    if morph is not None:
        summary.update(morph_targets=len(morph[0]), morph_target_error=morph[2])
        lines.append(f"correctives: {len(puppet.correctives.offsets)} shapes as {len(morph[0])} morph target(s), "
                     f"{morph[2]:.2g} of the diagonal away at most")
    report(summary, lines + extrapolation_lines, as_json, quiet)


def _extrapolation(puppet, skin, control_files, trajectories):
    """How far each trajectory's controls go from what the puppet was trained on, per frame: the
    ``view`` page's indicator (RMS distance over the controls, in place, to the nearest training
    example, the rest box's largest side = 1) -> (summary entries, lines)."""
    from skinsynth.pipeline.mesh.geometry import largest_side
    from skinsynth.pipeline.puppet import host_inputs
    from skinsynth.pipeline.view import extrapolation_distances, extrapolation_scale

    training = host_inputs(puppet, skin.examples[puppet.train_frames][:, puppet.control_indices])[1]
    unit = largest_side(skin.rest_vertices)
    scale = extrapolation_scale(training, unit)
    entries, lines = [], []
    for name, trajectory in zip(control_files, trajectories):
        distances, _ = extrapolation_distances(host_inputs(puppet, trajectory)[1], training, unit)
        worst = int(np.argmax(distances))
        entries.append({"controls": str(name), "per_frame": [round(float(d), 6) for d in distances],
                        "mean": float(distances.mean()), "worst": float(distances[worst]), "worst_frame": worst,
                        "scale": scale, "frames_beyond_scale": int(np.sum(distances > scale))})
        lines.append(f"extrapolation of {name}: mean {distances.mean():.3g}, worst {distances[worst]:.3g} at frame "
                     f"{worst}; {int(np.sum(distances > scale))} of {len(distances)} frames beyond {scale:.3g}, the "
                     "largest gap between training poses (distance to the nearest training pose, RMS over the "
                     "controls, the rest box's largest side = 1)")
    return entries, lines


def _corrective_morph_targets(path, skin, puppet, shape_weights, characters):
    """A puppet's correctives, played with blend weights shape_weights (C·F, n_p) or None, as
    glTF morph targets (``pipeline.morph_targets``): (targets (k, V, 3), [weights (F, k) per
    character], the largest vertex error relative to the rest diagonal; k = 0 when no played
    blend needs one), or None for a puppet without correctives; OptionError (one line) when more
    than ``pipeline.morph_targets.MAX_MORPH_TARGETS`` would be needed."""
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.mesh.geometry import bounding_box_diagonal
    from skinsynth.pipeline.rig.morph_targets import corrective_morph_targets

    if shape_weights is None:
        return None
    try:
        targets, weights, error = corrective_morph_targets(puppet.correctives.offsets, shape_weights,
                                                           bounding_box_diagonal(skin.rest_vertices))
    except ValueError as problem:
        raise OptionError(f"{path}: {problem}") from None
    return targets, list(weights.reshape(characters, -1, len(targets))), error


def _write_rig(output, skin, puppet, bones, offsets, names, up_axis, skinning):
    """The characters as UsdSkel rigs: world bones (rotations (C·F, B, 3, 3), translations
    (C·F, B, 3), corrective blend weights or None) placed by offsets (C, 3)."""
    from skinsynth.formats.usd import write_skel_characters

    characters, frames = len(names), len(bones[0]) // len(names)
    rotations, translations, shape_weights = bones
    rotations = rotations.reshape(characters, frames, *rotations.shape[1:])
    translations = translations.reshape(characters, frames, -1, 3) + offsets[:, None, None, :]
    shapes = None  # the correctives are blend shapes, played before skinning, as ± pairs in [0, 1]
    if shape_weights is not None:
        from skinsynth.pipeline.rig.morph_targets import unit_range_pairs

        pairs, weights = unit_range_pairs(puppet.correctives.offsets, shape_weights.reshape(characters, frames, -1))
        shapes = (pairs, weights, [f"shape_{j:03d}{s}" for j in range(len(pairs) // 2) for s in "pn"])
    tree, centres = None, skin.bone_rest_frames[:, :3, 3]
    if skin.skeleton is not None:  # the joint tree, every character's frames at once (locals are per frame)
        from dataclasses import replace

        from .outputs import usd_joint_tree

        tree = usd_joint_tree(skin.skeleton, rotations.reshape(-1, *rotations.shape[2:]),
                              translations.reshape(-1, *translations.shape[2:]))
        tree = replace(tree, rotations=tree.rotations.reshape(rotations.shape),
                       translations=tree.translations.reshape(translations.shape))
        centres = skin.skeleton["joints"]
    write_skel_characters(output, skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights,
                          rotations, translations, centres, skin.fps, names=names,
                          up_axis=up_axis, skinning=skinning, blend_shapes=shapes, scene=skin.scene, joint_tree=tree)
    if skinning == "dual-quaternion":
        click.echo("warning: Blender's USD importer ignores skinningMethod dualQuaternion and skins this rig "
                   "linearly, away from what skinsynth computed; --skinning linear gives a rig every DCC "
                   "plays as computed", err=True)
