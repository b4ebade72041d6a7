"""``skinsynth fit-skin``: skinning decomposition of a mesh sequence."""

import time
from dataclasses import replace

import click
import numpy as np

from .common import Progress, check_memory, check_output_path, command_line, report, summary_options, tool_version, user_errors
from .options import device_option, up_axis_option

#: ``--skeleton`` without a file: find the skeleton.
FOUND = "found"
#: More joint steps per iteration than this is a typo, not a fit (one step costs about 5 iterations).
MAX_TRANSFORM_STEPS = 100


@click.command("fit-skin")
@click.argument("input_specs", metavar="INPUT...", nargs=-1, required=True)
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Skin model file to write (.h5).")
@click.option("--bones", "-b", type=int, default=None,
              help="Number of rigid bones; exactly this many are delivered. Required unless --rig gives them.")
@click.option("--rig", type=click.Path(dir_okay=False), default=None,
              help="A skin file whose rig (rest pose, bones, weights) to keep: only the bone transforms of the "
                   "INPUT clips are solved (Dem Bones' 'solve bones for given weights'), so the new takes drive "
                   "the same skeleton. The clips must be the rig's mesh.")
@click.option("--max-influences", default=4, show_default=True, type=int, help="Most bones per vertex (K).")
@click.option("--iterations", default=100, show_default=True, type=int, help="Most alternations of bone and weight updates.")
@click.option("--tolerance", default=None, type=float,
              help="Stop once the last --patience iterations together improved the RMSE by less than this "
                   "(relative): more iterations stop paying. The summary says which rule stopped the fit. "
                   "Default 0.02 (0.001 with --rig, whose iterations cost milliseconds).")
@click.option("--patience", default=5, show_default=True, type=click.IntRange(min=1),
              help="Iterations over which --tolerance is measured.")
@click.option("--rest-frame", default="0", show_default=True,
              help="Frame used as the rest pose: a number over all clips in order, or CLIP:FRAME.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0), help="Seed of the clustering initialisation.")
@click.option("--transform-steps", default=None, type=int,
              help="Joint Levenberg-Marquardt steps on all bones of a frame per iteration (0: per-bone updates only; "
                   "a step costs about four iterations and gains less than they do on the real captures). "
                   "Default 0, and 1 with --rig (the weights are fixed there, and coupled bones move together).")
@device_option(default="cpu",
              help="Where the weight solve and the bone sweep run: cpu (compiled, every core), cuda or cuda:N (warp "
                   "kernels on that GPU; the same fit to rounding), or auto (a GPU when there is one).")
@click.option("--skeleton", "skeleton", is_flag=False, flag_value=FOUND, default=None, metavar="[FROM.usd]",
              help="Also find joints and a bone hierarchy (Le & Deng 2014) and refit the rig so that every joint "
                   "holds: each bone turns about its joint with its parent, only the root (and any free bone) "
                   "translates. Exported as a real skeleton (glTF, UsdSkel). With a USD file, use its UsdSkel "
                   "Skeleton instead (joints, topology, bind pose, which must be the rest frame's): one bone per "
                   "joint, fitted under it (then --bones may be left out). Put a bare --skeleton after the INPUTs "
                   "or before another option. docs/skeleton.md.")
@click.option("--root-bone", default=None, type=click.IntRange(min=0),
              help="--skeleton: the root bone. Default: the bone that carries the most weight (the body).")
@click.option("--max-joint-drift", default=None, type=click.FloatRange(min=0.0),
              help="--skeleton: the largest drift of a joint (RMS distance its two bones carry it apart, over the "
                   "rest diagonal) the hierarchy uses; bones with no such joint to the rest hang free from the "
                   "root. Default 0.02.")
@click.option("--prim", default=None, help="USD input: path of the mesh prim (default: first time-sampled mesh).")
@click.option("--fps", default=None, type=float, help="Frame rate, when the input does not carry one (default 24).")
@click.option("--meters-per-unit", default=None, type=float,
              help="Units of the input's coordinates (USD metersPerUnit; 0.01 for centimetres). Default: what a "
                   "USD input states, else 1. Every USD written downstream states it again.")
@up_axis_option("The input's up axis. Default: what a USD input states, else Y.")
@click.option("--start-frame", default=None, type=float,
              help="Time code of the input's first frame. Default: a USD input's first sample, else 0.")
@summary_options
@user_errors
def fit_skin(input_specs, output, bones, rig, max_influences, iterations, tolerance, patience, device, rest_frame, seed,
             transform_steps, skeleton, root_bone, max_joint_drift, prim, fps, meters_per_unit, up_axis, start_frame,
             quiet, as_json):
    """Fit a linear-blend-skinning model with rigid bones to one or more clips of a mesh.

    Each INPUT is a clip: a folder or glob of OBJ/PLY/OFF frames (natural frame order), a USD
    file with a time-sampled mesh, or an .npz/.h5 file with vertices (F, V, 3) and faces (T, 3).
    Several clips of one mesh get one rig: one rest pose, one set of weights, bone transforms
    for every frame of every clip, fitted together. NAME=INPUT names a clip; by default it is
    the file's name less the prefix all share (horse_gallop.npz horse_collapse.npz: gallop,
    collapse). Weights are non-negative, sum to one and have at most --max-influences
    non-zeros per vertex (Le & Deng 2012, as used by Zheng et al. 2013 §3.1).

    \b
    Examples:
      skinsynth fit-skin 'horse/horse-gallop-*.obj' -o horse.skin.h5 --bones 22
      skinsynth fit-skin horse_gallop.npz horse_collapse.npz -o horse.skin.h5 --bones 22
      skinsynth fit-skin horse_poses.npz --rig horse.skin.h5 -o poses.skin.h5
    """
    from skinsynth.formats.clip_inputs import read_clips
    from skinsynth.pipeline.inputs.clips import Clips
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.mesh.geometry import bounding_box_diagonal
    from skinsynth.pipeline.skin import fit_memory_bytes, validate_fit_options

    given_file = [skeleton] if skeleton not in (None, FOUND) else []
    check_output_path(output, (".h5", ".hdf5"), inputs=list(input_specs) + ([rig] if rig else []) + given_file)
    if fps is not None and not 0 < fps < float("inf"):
        raise OptionError(f"--fps must be positive and finite (got {fps})")
    if (tolerance is not None and tolerance < 0) or (transform_steps is not None and transform_steps < 0):
        raise OptionError("--tolerance and --transform-steps must not be negative")
    if transform_steps is not None and transform_steps > MAX_TRANSFORM_STEPS:  # a joint solve of every bone of every frame
        raise OptionError(f"--transform-steps {transform_steps}: at most {MAX_TRANSFORM_STEPS} per iteration (each "
                          "is a joint solve of every bone of every frame; 0 or 1 is the useful range)")
    if rig is not None:
        source = click.get_current_context().get_parameter_source
        given = [f"--{name.replace('_', '-')}" for name in ("rest_frame", "seed", "max_influences")
                 if source(name) == click.core.ParameterSource.COMMANDLINE]
        if given:
            raise OptionError(f"{', '.join(given)} do(es) not apply with --rig: the rig's rest pose and weights are "
                              "kept, only the bone transforms are solved")
    if not skeleton and (root_bone is not None or max_joint_drift is not None):
        raise OptionError("--root-bone and --max-joint-drift apply only with --skeleton")
    if skeleton and rig is not None:
        raise OptionError("--skeleton and --rig do not combine yet: --rig keeps a rig's weights, --skeleton refits them")
    brought = None  # --skeleton FILE: (Skeleton, the file's UsdSkeleton record)
    if skeleton not in (None, FOUND):
        if root_bone is not None or max_joint_drift is not None:
            raise OptionError("--root-bone and --max-joint-drift apply to a skeleton found, not to --skeleton FILE")
        brought = _read_given_skeleton(skeleton, bones)
        bones = brought[0].bones
    if rig is None and bones is None:
        raise OptionError("--bones is required (or --rig, a skin file whose bones and weights to keep)")
    if tolerance is None:
        tolerance = 0.001 if rig else 0.02
    if transform_steps is None:
        transform_steps = 1 if rig else 0
    if device != "cpu":  # "cpu" runs numba's loops and never imports warp (about 1 s)
        from skinsynth.gpu import resolve_device

        device = resolve_device(device)
    warp_device = None if device == "cpu" else device
    sequence = read_clips(input_specs, prim=prim, fps=fps)
    try:
        sequence = replace(sequence, scene=sequence.scene.overridden(meters_per_unit, up_axis, start_frame))
    except ValueError as error:
        raise OptionError(str(error)) from None
    clips = Clips(sequence.clip_names, sequence.clip_frames)
    frames, count = sequence.vertices.shape[:2]
    if brought is not None:
        _check_skeleton_scene(skeleton, brought[1], sequence.scene)
    rig_model = _read_rig(rig, sequence, bones) if rig else None
    if rig_model is not None:
        bones = rig_model.bones
        rest_frame = 0  # the rest pose is the rig's, not one of these frames (docs/format.md: /mesh)
    else:
        rest_frame = clips.frame(rest_frame, "--rest-frame")
        validate_fit_options(frames, count, bones, max_influences, iterations, rest_frame)
        if root_bone is not None and root_bone >= bones:
            raise OptionError(f"--root-bone {root_bone} is not one of the {bones} bones (0..{bones - 1})")
        check_memory(fit_memory_bytes(frames, count, bones, transform_steps),
                     f"fit-skin --bones {bones} on {count} vertices × {frames} frames"
                     + (f" with --transform-steps {transform_steps}" if transform_steps else ""))
    rest_vertices = rig_model.rest_vertices if rig_model is not None else sequence.vertices[rest_frame]
    diagonal = bounding_box_diagonal(rest_vertices)
    if not diagonal > 0.0:
        raise OptionError(f"{input_specs[0]}: the rest frame has no extent (all vertices coincide)")

    started = time.perf_counter()
    history = []  # (seconds, RMSE over the diagonal) after each iteration

    def progress(iteration, rmse):
        history.append((round(time.perf_counter() - started, 3), rmse / diagonal))
        bar.update(1, f"RMSE/diag {rmse / diagonal:.2e}")

    jointed = None
    if brought is not None:
        result, jointed = _fit_under(sequence, rest_vertices, brought[0], max_influences, diagonal, quiet)
    else:
        with Progress(iterations, f"fit-skin {bones} bones" + (" on the rig" if rig else ""), quiet) as bar:
            result = _fit(sequence.vertices, rig_model, bones, max_influences, iterations, rest_frame, seed,
                          tolerance, patience, transform_steps, warp_device, progress)
        if skeleton:
            result, jointed = _fit_skeleton(sequence, result, root_bone, max_joint_drift, max_influences, diagonal,
                                            quiet)
    seconds = time.perf_counter() - started

    from skinsynth.formats.model import write_model
    from skinsynth.formats.provenance import provenance_record
    from skinsynth.formats.skin_file import skin_groups
    from skinsynth.pipeline.skin import finish_fit

    frame_rmse, dq, rest_frames = finish_fit(result, sequence.vertices)
    if rig_model is not None:
        rest_frames = rig_model.bone_rest_frames  # the same skeleton, exactly
    scene = sequence.scene
    parameters = dict(bones=bones, rig=rig, max_influences=max_influences, iterations=iterations, tolerance=tolerance,
                      patience=patience, device=device,
                      rest_frame=rest_frame, seed=seed, transform_steps=transform_steps, skeleton=skeleton,
                      root_bone=root_bone, max_joint_drift=max_joint_drift, prim=prim, fps=sequence.fps,
                      meters_per_unit=scene.meters_per_unit, up_axis=scene.up_axis, start_frame=scene.start_frame)
    record = provenance_record("skin", command_line(), parameters, list(input_specs) + ([rig] if rig else []) + given_file,
                               tool_version(), seed)
    write_model(output, "skin", skin_groups(sequence, rest_frame, result, dq, rest_frames, frame_rmse, diagonal,
                                            jointed), [record], tool_version())
    summary, lines = _summary(output, sequence, bones, result, diagonal, seconds, device, history, clips, frame_rmse)
    if jointed is not None:
        summary["skeleton"], line = _skeleton_summary(jointed, result, sequence, diagonal)
        lines.append(line)
    report(summary, lines, as_json, quiet)
    if result.bones_without_weight:
        click.echo(f"warning: {result.bones_without_weight} bone(s) ended with no vertex weight: the sequence "
                   "has fewer independently moving parts than --bones", err=True)


def _fit(vertices, rig, bones, max_influences, iterations, rest_frame, seed, tolerance, patience, transform_steps,
         device, progress):
    """A full fit, or with ``rig`` (a SkinModel) only the bone transforms on its rig."""
    from skinsynth.pipeline.skin import fit_bones_to_rig, fit_skin

    if rig is not None:
        return fit_bones_to_rig(vertices, rig.rest_vertices, rig.bone_indices, rig.bone_weights, rig.bones,
                                iterations=iterations, tolerance=tolerance, patience=patience,
                                joint_steps=transform_steps, progress=progress, device=device)
    return fit_skin(vertices, bones, max_influences=max_influences, iterations=iterations, rest_frame=rest_frame,
                    seed=seed, tolerance=tolerance, patience=patience, joint_steps=transform_steps, device=device,
                    progress=progress)


def _fit_skeleton(sequence, free, root_bone, max_joint_drift, max_influences, diagonal, quiet):
    """The free fit's joints and tree, then the rig refitted so that they hold: (SkinFit, the
    /skin/skeleton record)."""
    from skinsynth.pipeline.skin import MAX_JOINT_DRIFT, find_skeleton, fit_jointed

    max_drift = MAX_JOINT_DRIFT if max_joint_drift is None else max_joint_drift
    found = find_skeleton(free.rest_vertices, sequence.faces, free.bone_indices, free.bone_weights, free.rotations,
                          free.translations, root=root_bone, max_drift=max_drift, diagonal=diagonal)
    iterations = 40  # per phase: joints moving, then fixed inside the body (pipeline/skin/jointed_fit.py)
    with Progress(2 * iterations, "fit-skin --skeleton: the rig refitted on its joints", quiet) as bar:
        fitted, skeleton = fit_jointed(sequence.vertices, free.rest_vertices, free.bone_indices, free.bone_weights,
                                       free.rotations, found, faces=sequence.faces, max_influences=max_influences,
                                       iterations=iterations,
                                       progress=lambda i, rmse: bar.update(1, f"RMSE/diag {rmse / diagonal:.2e}"))
    record = {"parents": skeleton.parents, "jointed": skeleton.jointed, "joints": skeleton.joints,
              "drift": found.drift, "root": skeleton.root, "free_rmse": free.rmse, "max_drift": max_drift}
    return fitted, record


def _read_given_skeleton(path, bones):
    """(Skeleton, the file's UsdSkeleton record) of ``--skeleton FILE``; refused in one line unless
    it is a USD file with a UsdSkel Skeleton of one tree, and (--bones given) that many bones."""
    from skinsynth.formats.errors import FormatError
    from skinsynth.formats.usd import read_skeleton
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.skin import given_skeleton

    if not str(path).lower().endswith((".usd", ".usda", ".usdc", ".usdz")):
        raise OptionError(f"--skeleton {path}: a skeleton comes from a USD file (.usd, .usda, .usdc) with a UsdSkel "
                          "Skeleton; leave the file out to find one")
    record = read_skeleton(path)
    try:
        found, _ = given_skeleton(record.names, record.parents, record.positions, record.free)
    except ValueError as error:
        raise FormatError(path, str(error)) from None
    if bones is not None and bones != found.bones:
        raise OptionError(f"--bones {bones} differs from the {found.bones} bones of --skeleton {path} (leave --bones "
                          "out: the skeleton gives one bone per joint)")
    return found, record


def _check_skeleton_scene(path, record, scene):
    """Refuse ``--skeleton FILE`` whose stage's units or up axis are not the input's: its bind pose
    would then sit at another scale, or lie on its side."""
    from skinsynth.formats.errors import FormatError

    if not np.isclose(record.meters_per_unit, scene.meters_per_unit, rtol=1e-9) or record.up_axis != scene.up_axis:
        raise FormatError(path, f"its skeleton is in {record.meters_per_unit:g} m per unit, {record.up_axis} up, the "
                                f"input in {scene.meters_per_unit:g}, {scene.up_axis} up: give --meters-per-unit and "
                                "--up-axis of the skeleton's scene, or a skeleton exported from this character's fit")


def _fit_under(sequence, rest, skeleton, max_influences, diagonal, quiet):
    """The rig fitted under ``--skeleton FILE``'s joints: (SkinFit, the /skin/skeleton record)."""
    from skinsynth.pipeline.skin import fit_given_skeleton

    iterations = 40
    with Progress(4 * iterations, f"fit-skin under the given skeleton ({skeleton.bones} bones)", quiet) as bar:
        fitted, skeleton = fit_given_skeleton(sequence.vertices, rest, sequence.faces, skeleton,
                                              max_influences=max_influences,
                                              iterations=iterations,
                                              progress=lambda i, rmse: bar.update(1, f"RMSE/diag {rmse / diagonal:.2e}"))
    record = {"parents": skeleton.parents, "jointed": skeleton.jointed, "joints": skeleton.joints,
              "drift": skeleton.drift, "root": skeleton.root, "free_rmse": float("nan"), "max_drift": float("nan")}
    return fitted, record


def _skeleton_summary(record, fit, sequence, diagonal):
    """--json's "skeleton" and its text line."""
    from skinsynth.pipeline.mesh.geometry import points_inside

    jointed = np.asarray(record["jointed"])
    inside = points_inside(np.asarray(record["joints"])[jointed], fit.rest_vertices, sequence.faces)
    free = int((~jointed).sum()) - 1
    summary = {"root": int(record["root"]), "joints": int(jointed.sum()), "free_bones": free,
               "parents": [int(p) for p in record["parents"]],
               "joints_inside": int(inside.sum()), "largest_drift": float(np.max(record["drift"], initial=0.0)),
               "free_rmse": float(record["free_rmse"]), "rmse": float(fit.rmse),
               "rmse_over_free": float(fit.rmse / record["free_rmse"]) if record["free_rmse"] > 0 else None}
    # --skeleton FILE has no free fit to compare with (NaN stored; null here)
    summary["free_rmse"] = summary["free_rmse"] if np.isfinite(summary["free_rmse"]) else None
    ratio = f"{summary['rmse_over_free']:.2f}×" if summary["rmse_over_free"] is not None else "—"
    free_error = f" ({record['free_rmse'] / diagonal:.2e} of the diagonal)" if summary["free_rmse"] else ""
    line = (f"skeleton: root bone {summary['root']}, {summary['joints']} joints ({summary['joints_inside']} inside the "
            f"mesh, largest drift {summary['largest_drift']:.2%} of the diagonal), {free} free bone(s) under the root; "
            + (f"RMSE {ratio} the free fit's{free_error}" if summary["free_rmse"] else "given (--skeleton FILE)"))
    return summary, line


def _read_rig(path, sequence, bones):
    """The rig of ``--rig`` (a SkinModel), refused unless it is the clips' mesh and has ``bones``."""
    from skinsynth.formats.clip_inputs import mesh_difference
    from skinsynth.formats.errors import FormatError
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.errors import OptionError

    rig = read_skin(path)
    difference = mesh_difference(len(rig.rest_vertices), rig.faces, sequence.vertices.shape[1], sequence.faces,
                                 sequence.source)
    if difference:
        raise FormatError(path, f"the rig {difference}: --rig needs the clips' own mesh, its vertices in the same "
                                "order")
    if bones is not None and bones != rig.bones:
        raise OptionError(f"--bones {bones} differs from the rig's {rig.bones} bones (leave --bones out with --rig)")
    return rig


def _summary(output, sequence, bones, result, diagonal, seconds, device, history, clips, frame_rmse):
    """The command's summary (--json) and its text lines."""
    frames, count = sequence.vertices.shape[:2]
    scene = sequence.scene
    state = result.stopped
    summary = {"output": output, "bones": bones, "vertices": int(count), "frames": int(frames), "fps": sequence.fps,
               "rmse": result.rmse, "rmse_over_diagonal": result.rmse / diagonal, "iterations": int(result.iterations),
               "converged": bool(result.converged), "stopped": result.stopped, "seconds": round(seconds, 3),
               "device": device,
               "bones_without_weight": int(result.bones_without_weight), "meters_per_unit": scene.meters_per_unit,
               "up_axis": scene.up_axis, "start_frame": scene.start_frame, "prim_path": scene.prim_path,
               "history": [[t, float(f"{e:.6g}")] for t, e in history]}
    clip_rmse = [float(np.sqrt(np.mean(frame_rmse[a:b] ** 2))) for a, b in zip(clips.starts[:-1], clips.starts[1:])]
    summary["clips"] = [{"name": name, "frames": int(n), "rmse": rmse, "rmse_over_diagonal": rmse / diagonal}
                        for name, n, rmse in zip(clips.names, clips.frames, clip_rmse)]
    lines = [f"wrote {output}: {bones} bones, {count} vertices, {frames} frames; "
             f"RMSE {result.rmse:.4g} = {result.rmse / diagonal:.2e} of the bounding-box diagonal "
             f"({result.iterations} iterations, {state}, {seconds:.1f} s)",
             f"scene: {scene.describe(frames)} at {sequence.fps:g} fps (stated again by every USD written "
             "from it; --meters-per-unit, --up-axis, --start-frame override)"]
    if len(clips) > 1:
        lines.append("clips: " + ", ".join(f"{c['name']} ({c['frames']} frames, RMSE/diag {c['rmse_over_diagonal']:.2e})"
                                           for c in summary["clips"]))
    return summary, lines
