"""``skinsynth fit-skin``: skinning decomposition of a mesh sequence."""

import time
from dataclasses import replace

import click

from skinsynth.formats.output_file import check_output_path
from skinsynth.pipeline.errors import OptionError

from .common import Progress, command_line, report, summary_options, tool_version, user_errors
from .options import FINITE_FLOAT, FiniteFloatRange, bone_count, device_option, up_axis_option

#: ``--skeleton`` without a file: find the skeleton.
FOUND = "found"
#: More joint steps per iteration than this is a typo, not a fit (one step costs about 5 iterations).
MAX_TRANSFORM_STEPS = 100


@click.command("fit-skin")
@click.argument("input_specs", metavar="INPUT...", nargs=-1, required=True)
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Skin model file to write (.h5).")
@click.option("--bones", "-b", default=None, metavar="N|auto", callback=bone_count,
              help="Number of rigid bones; exactly this many are delivered. Required unless --rig or --skeleton FILE "
                   "gives them. auto: the elbow of the clip's error against bones (rigid clusters of 1 to 48 bones), "
                   "said in the summary with the error at the counts around it (docs/own_capture.md).")
@click.option("--rig", type=click.Path(dir_okay=False), default=None,
              help="A skin file whose rig (rest pose, bones, weights) to keep: only the bone transforms of the "
                   "INPUT clips are solved (Dem Bones' 'solve bones for given weights'), so the new takes drive "
                   "the same skeleton. The clips must be the rig's mesh.")
@click.option("--max-influences", default=4, show_default=True, type=int, help="Most bones per vertex (K).")
@click.option("--iterations", default=100, show_default=True, type=int, help="Most alternations of bone and weight updates.")
@click.option("--tolerance", default=None, type=FINITE_FLOAT,
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
              help="Also find joints and a bone tree (Le & Deng 2014) and refit the rig so that they hold: each bone "
                   "turns about its joint with its parent (a sliding joint also translates, within bounds). Exported "
                   "as a real skeleton (glTF, UsdSkel). With a USD file, its UsdSkel Skeleton instead (bind pose: the "
                   "rest frame's), one bone per joint (--bones may be left out). A bare --skeleton goes after the "
                   "INPUTs or before another option. docs/skeleton.md.")
@click.option("--root-bone", default=None, type=click.IntRange(min=0),
              help="--skeleton: the root bone. Default: a biped's hips (where its legs part), else the tree's "
                   "centre by skin weight (no part hanging from it holds more than half the skin).")
@click.option("--max-joint-drift", default=None, type=FiniteFloatRange(min=0.0),
              help="--skeleton: the largest drift of a joint (RMS distance its two bones carry it apart, over the "
                   "rest diagonal) that is fixed; a bone with no such joint slides on its neighbour. Default 0.02.")
@click.option("--max-sliding-share", default=None, type=FiniteFloatRange(min=0.0, max=1.0),
              help="--skeleton: the largest share of the bones that may slide (those drifting most). Default 0.2, "
                   "lifted where holding the others costs more than 1.5x the free fit's error (the body is soft: "
                   "the summary says so); given, it holds.")
@click.option("--surplus-bones", default=0.0, type=FiniteFloatRange(min=0.0),
              help="--skeleton: start from (1 + this) × --bones bones and merge the redundant ones into their parents "
                   "as the joints are fitted (Le & Deng 2014): more fixed joints, 2-5x the time. Default 0 (off).")
@click.option("--contacts/--no-contacts", default=True, show_default=True,
              help="Weigh the fit toward the capture's ground contacts (where build-graph's contact finder finds a "
                   "ground): the vertices near the ground are fitted first, so the rig replays planted feet still. "
                   "Not with --rig or --skeleton. The summary compares the playback's feet with the capture's. "
                   "docs/contact.md.")
@click.option("--contact-weight", default=None, type=FiniteFloatRange(min=0.0),
              help="--contacts: the extra weight of a near-ground vertex's error (lowered where the near vertices "
                   "would carry over a fifth of the fit's error). Default 20. Refused where no contact fit runs "
                   "(--no-contacts, --rig, --skeleton).")
@click.option("--prim", default=None, help="USD, Alembic or FBX input: the mesh to read (a USD prim path, an Alembic "
              "object path such as /Body/BodyShape, an FBX object name; default: USD's first time-sampled mesh, the "
              "only mesh of an .abc or .fbx; docs/blender.md).")
@click.option("--fps", default=None, type=FINITE_FLOAT, help="Frame rate, when the input does not carry one (default 24). Every later stage counts "
                   "time in it: build-graph's threshold and held poses, synthesize's blends and segments.")
@click.option("--meters-per-unit", default=None, type=FINITE_FLOAT,
              help="Units of the input's coordinates (USD metersPerUnit; 0.01 for centimetres). Default: what a "
                   "USD input states, else 1. Every USD written downstream states it again.")
@up_axis_option("The input's up axis. Default: what a USD input states, else Y.")
@click.option("--start-frame", default=None, type=FINITE_FLOAT,
              help="Time code of the input's first frame. Default: a USD input's first sample, else 0.")
@summary_options
@user_errors
def fit_skin(input_specs, output, bones, rig, max_influences, iterations, tolerance, patience, device, rest_frame, seed,
             transform_steps, skeleton, root_bone, max_joint_drift, max_sliding_share, surplus_bones, contacts,
             contact_weight, prim, fps, meters_per_unit, up_axis, start_frame, quiet, as_json):
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
    from skinsynth.formats.model import write_model
    from skinsynth.formats.provenance import provenance_record
    from skinsynth.formats.skin_file import skin_groups
    from skinsynth.pipeline.skin import finish_fit, fit_rest_pose, fit_rig, playback_feet, skin_summary

    inputs = list(input_specs) + ([rig] if rig else []) + ([skeleton] if skeleton not in (None, FOUND) else [])
    check_output_path(output, (".h5", ".hdf5"), inputs=inputs)
    bones, tolerance, transform_steps, brought, device = _resolved_options(
        bones, rig, tolerance, transform_steps, skeleton, root_bone, max_joint_drift, fps, device, contacts,
        contact_weight)
    with Progress(0, "", quiet) as reading:
        sequence, clips, rig_model = _read_inputs(input_specs, prim, fps, meters_per_unit, up_axis, start_frame, rig,
                                                  skeleton, brought, _reading_progress(reading))
    bones, rest_frame, diagonal, chosen = fit_rest_pose(input_specs[0], sequence.vertices, clips, rig_model, bones,
                                                        rest_frame, max_influences, iterations, root_bone,
                                                        transform_steps, surplus_bones)
    ground = _capture_ground(sequence, clips)
    near = ground[1] if ground is not None and contacts and rig is None and skeleton is None else None
    with Progress(iterations, "", quiet) as bar:
        phases = _Phases(bar, bones, rig, diagonal)
        result, jointed = fit_rig(sequence.vertices, sequence.faces, bones, rig=rig_model,
                                  given=None if brought is None else brought[0], find_joints=skeleton == FOUND,
                                  root_bone=root_bone, max_joint_drift=max_joint_drift, max_influences=max_influences,
                                  iterations=iterations, rest_frame=rest_frame, seed=seed, tolerance=tolerance,
                                  patience=patience, joint_steps=transform_steps,
                                  device=None if device == "cpu" else device, diagonal=diagonal, surplus=surplus_bones,
                                  up_axis=sequence.scene.up_axis, max_sliding_share=max_sliding_share, near=near,
                                  contact_weight=contact_weight, progress=phases)
    seconds = time.perf_counter() - phases.started
    frame_rmse, dq, rest_frames = finish_fit(result, sequence.vertices,
                                              rest_frames=None if rig_model is None else rig_model.bone_rest_frames)
    feet = None if ground is None else playback_feet(result, sequence.vertices, clips.starts, ground[0])
    scene = sequence.scene
    parameters = dict(bones=bones, rig=rig, max_influences=max_influences, iterations=iterations, tolerance=tolerance,
                      patience=patience, device=device, rest_frame=rest_frame, seed=seed, prim=prim, fps=sequence.fps,
                      transform_steps=transform_steps, skeleton=skeleton, root_bone=root_bone, surplus_bones=surplus_bones,
                      max_joint_drift=max_joint_drift, max_sliding_share=max_sliding_share,
                      contacts=near is not None, contact_weight=contact_weight,
                      meters_per_unit=scene.meters_per_unit, up_axis=scene.up_axis, start_frame=scene.start_frame)
    record = provenance_record("skin", command_line(), parameters, inputs, tool_version(), seed)
    write_model(output, "skin", skin_groups(sequence, rest_frame, result, dq, rest_frames, frame_rmse, diagonal,
                                            jointed), [record], tool_version())
    report(*skin_summary(output, result, frame_rmse, clips, diagonal, sequence.fps, scene, seconds, device,
                         phases.history, jointed, sequence.faces, feet, near, contact_weight, chosen), as_json, quiet)
    if result.bones_without_weight:
        click.echo(f"warning: {result.bones_without_weight} bone(s) ended with no vertex weight: the sequence "
                   "has fewer independently moving parts than --bones", err=True)


def _resolved_options(bones, rig, tolerance, transform_steps, skeleton, root_bone, max_joint_drift, fps, device,
                      contacts=True, contact_weight=None):
    """Refuse, before reading the clips, options that do not combine or are out of range; read
    ``--skeleton FILE``. Returns (bones, tolerance, transform steps, (Skeleton, the file's
    UsdSkeleton record) of --skeleton FILE or None, the device resolved)."""
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
    if skeleton != FOUND and (root_bone is not None or max_joint_drift is not None):
        raise OptionError("--root-bone and --max-joint-drift apply only with a bare --skeleton (a skeleton found)")
    if skeleton and rig is not None:
        raise OptionError("--skeleton and --rig do not combine yet: --rig keeps a rig's weights, --skeleton refits them")
    if contact_weight is not None and (not contacts or rig is not None or skeleton):
        raise OptionError("--contact-weight weighs the fit toward the ground contacts: it applies with --contacts, not "
                          "with --no-contacts, --rig or --skeleton")
    if bones == "auto" and (rig is not None or skeleton not in (None, FOUND)):
        raise OptionError("--bones auto chooses the count of a new fit: --rig and --skeleton FILE bring their own bones")
    brought = None
    if skeleton not in (None, FOUND):
        brought = _read_given_skeleton(skeleton, bones)
        bones = brought[0].bones
    if rig is None and bones is None:
        raise OptionError("--bones is required (or --rig, a skin file whose bones and weights to keep)")
    if device != "cpu":  # "cpu" runs numba's loops and never imports warp (about 1 s)
        from skinsynth.gpu import resolve_device

        device = resolve_device(device)
    return (bones, (0.001 if rig else 0.02) if tolerance is None else tolerance,
            (1 if rig else 0) if transform_steps is None else transform_steps, brought, device)


def _reading_progress(bar):
    """progress(clip, done, total) for :func:`~skinsynth.formats.clip_inputs.read_clips`: a bar per
    clip Blender reads (an .abc or .fbx), labelled with it."""
    shown = {}

    def progress(clip, done, total):
        if clip not in shown:
            bar.restart(total, f"reading {clip} (Blender)")
            shown[clip] = 0
        bar.update(done - shown[clip])
        shown[clip] = done

    return progress


def _read_inputs(input_specs, prim, fps, meters_per_unit, up_axis, start_frame, rig, skeleton, brought, progress=None):
    """The INPUT clips (a MeshSequence, its scene as the options override it), their
    :class:`Clips`, and the skin of ``--rig`` (None without); refused unless ``--rig`` is the
    clips' mesh, and ``--skeleton FILE`` (``brought``) in their units and up axis, its joints on
    their mesh."""
    from skinsynth.formats.clip_inputs import read_clips, read_rig
    from skinsynth.formats.usd import check_skeleton_placement, check_skeleton_scene
    from skinsynth.pipeline.inputs.clips import Clips

    sequence = read_clips(input_specs, prim=prim, fps=fps, progress=progress)
    try:
        sequence = replace(sequence, scene=sequence.scene.overridden(meters_per_unit, up_axis, start_frame))
    except ValueError as error:
        raise OptionError(str(error)) from None
    if brought is not None:
        check_skeleton_scene(skeleton, brought[1], sequence.scene)
        check_skeleton_placement(skeleton, brought[1], sequence.vertices)
    return sequence, Clips(sequence.clip_names, sequence.clip_frames), read_rig(rig, sequence) if rig else None


class _Phases:
    """``progress`` of :func:`~skinsynth.pipeline.skin.fit_rig`: a bar for each phase of the fit,
    and ``history``, the (seconds, RMSE over the diagonal) after each iteration of the main fit."""

    def __init__(self, bar, bones, rig, diagonal):
        self.bar, self.diagonal, self.history = bar, diagonal, []
        self.labels = {"fit": f"fit-skin {bones} bones" + (" on the rig" if rig else ""), "prune": "bones merged",
                       "grow": "fit-skin --surplus-bones: the larger free fit", "given": f"fit-skin under the given "
                       f"skeleton ({bones} bones)", "joints": "fit-skin --skeleton: the rig refitted on its joints",
                       "soft": "fit-skin --skeleton: over the error budget, refitted with its drifting joints sliding",
                       "contacts": "the fit weighed toward the ground contacts",
                       "helpers": "fit-skin --skeleton: bones that dominate no vertex put where the fit lacks one"}
        self.started = time.perf_counter()

    def __call__(self, phase, length):
        self.bar.restart(length, self.labels[phase])

        def progress(iteration, rmse):
            if phase in ("fit", "grow"):
                self.history.append((round(time.perf_counter() - self.started, 3), rmse / self.diagonal))
            self.bar.update(1, f"RMSE/diag {rmse / self.diagonal:.2e}")
        return progress


def _capture_ground(sequence, clips):
    """(the up axis's index, near (F, V) bool: the vertices near their clip's ground) where
    build-graph's contact finder finds a ground in the capture (:func:`~skinsynth.pipeline.synthesis.find_contacts`,
    a clip without plants has none), else None (a swinging bar, a falling cloth)."""
    import numpy as np

    from skinsynth.pipeline.skin import near_ground
    from skinsynth.pipeline.synthesis import find_contacts

    up = "XYZ".index(sequence.scene.up_axis)
    found = find_contacts(sequence.vertices, sequence.faces, sequence.fps, up, clips)
    if not found.count:
        return None
    starts = clips.starts
    grounded = np.array([found.planted[a:b].any() for a, b in zip(starts[:-1], starts[1:])])
    return up, near_ground(sequence.vertices, starts, np.where(grounded, found.ground, np.nan), up, found.height)


def _read_given_skeleton(path, bones):
    """(Skeleton, the file's UsdSkeleton record) of ``--skeleton FILE``; refused in one line unless
    it is a USD file with a UsdSkel Skeleton of one tree, and (--bones given) that many bones."""
    from skinsynth.formats.errors import FormatError
    from skinsynth.formats.usd import read_skeleton
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
