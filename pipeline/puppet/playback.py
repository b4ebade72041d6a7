"""Many characters from one puppet: their control trajectories, placement, and world-space bones.

``play`` drives C characters over F frames. Characters come from several control files (one
each) or from ``--instances N`` copies of one trajectory, copy i starting i·F/N frames later
(cyclically) so a crowd does not move in lock-step. Characters are laid out on a grid on the
ground plane after prediction — the controls themselves are not moved, so a world-space puppet
stays inside the region it was trained on.
"""

import os
import time

import numpy as np

from .alignment import apply_frames, invert_frames
from ..errors import OptionError
from .correctives import blend_weights
from .puppet import in_place, predict_bones
from ..rig.rotations import dual_quaternion_to_rigid


def instance_trajectories(trajectories, instances=1):
    """controls (C, F, n_c, 3) from a list of (F, n_c, 3) trajectories, or N shifted copies of one."""
    if instances < 1:
        raise OptionError(f"--instances must be at least 1 (got {instances})")
    if len(trajectories) > 1:
        if instances != 1:
            raise OptionError("--instances applies to a single --controls file; give one file per character instead")
        lengths = {t.shape[0] for t in trajectories}
        if len(lengths) != 1:
            raise OptionError(f"control files have different frame counts ({sorted(lengths)}); they must match")
        return np.stack(trajectories)
    base = trajectories[0]
    frames = base.shape[0]
    shifts = (np.arange(instances) * frames) // instances
    order = (np.arange(frames)[None, :] + shifts[:, None]) % frames
    return base[order]


def character_offsets(characters, spacing, rest_vertices, up_axis="Y"):
    """Each character's place (C, 3) on a near-square grid of the ground plane
    (:func:`~skinsynth.pipeline.mesh.geometry.grid_offsets`), ``spacing`` apart (None: 1.5 × the
    largest side of the rest pose rest_vertices (V, 3)); one character stays at the origin.
    OptionError for a spacing that is not a finite distance ≥ 0."""
    from ..mesh.geometry import grid_offsets, largest_side

    spacing = 1.5 * largest_side(rest_vertices) if spacing is None else spacing
    if not np.isfinite(spacing) or spacing < 0.0:
        raise OptionError(f"--spacing must be a finite distance ≥ 0 (got {spacing})")
    return grid_offsets(characters, spacing, up_axis) if characters > 1 else np.zeros((1, 3))


def world_bones(puppet, controls, translation_solver=True):
    """Bone transforms in the world: controls (N, n_c, 3) -> (rotations (N, B, 3, 3), translations
    (N, B, 3), blend-shape weights (N, n_p) of the puppet's correctives or None)."""
    d, frame_r, frame_t, (xi, x) = predict_bones(puppet, controls, translation_solver)
    rotations, translations = dual_quaternion_to_rigid(d)
    inv_r, inv_t = invert_frames(frame_r, frame_t)
    weights = None if puppet.correctives is None else blend_weights(puppet.correctives, xi, x)
    return (np.einsum("nac,nbcd->nbad", inv_r, rotations),
            np.einsum("nac,nbc->nba", inv_r, translations) + inv_t[:, None, :], weights)


def character_bones(puppet, controls, translation_solver=True, skeleton=None, beyond=None):
    """Each character's world bones for a rig output: controls (C, F, n_c, 3) -> (rotations
    (C, F, B, 3, 3), translations (C, F, B, 3), corrective blend weights (C·F, n_p) or None)
    (:func:`world_bones`). ``skeleton``: a jointed skin's /skin/skeleton as read
    (``skin.skeleton``), or None: the bones play's path predicts do not hold its joints (about
    1.5 % of the diagonal on the walker), so every jointed bone is put back on its joint and every
    sliding one within its travel (:func:`~skinsynth.pipeline.rig.skeleton.hold_joints`;
    ``evaluate`` reports what that costs, kcca_on_joints); vertex outputs play the prediction
    itself. beyond: the skeleton path's :class:`~.jointed_play.BeyondExamples` of those controls
    (:func:`play_characters`'), or None: its frames' bones taken from it, every frame's correctives'
    weights scaled by 1 − α."""
    from ..rig.skeleton import held_rig, hold_joints

    characters, frames = controls.shape[:2]
    flat = controls.reshape(-1, *controls.shape[2:])
    rotations, translations, shape_weights = world_bones(puppet, flat, translation_solver)
    if beyond is not None:
        if beyond.rows.size:
            rotations[beyond.rows], translations[beyond.rows] = beyond.rotations, beyond.translations
        if shape_weights is not None:
            shape_weights *= (1.0 - beyond.alpha)[:, None]
    if skeleton is not None:
        hold_joints(rotations, translations, *held_rig(skeleton))
    return (rotations.reshape(characters, frames, *rotations.shape[1:]),
            translations.reshape(characters, frames, *translations.shape[1:]), shape_weights)


def play_extrapolation(puppet, examples, names, trajectories):
    """How far each trajectory (F, n_c, 3) named by ``names`` goes from what the puppet was trained
    on, its examples (F, V, 3) the skin's, per frame
    (:func:`~skinsynth.pipeline.rig.extrapolation.extrapolation_report`, in place, the rest box's
    largest side = 1): (entries, lines)."""
    from ..mesh.geometry import largest_side
    from ..rig.extrapolation import extrapolation_report

    training = host_inputs(puppet, examples[puppet.train_frames][:, puppet.control_indices])[1]
    return extrapolation_report(names, [host_inputs(puppet, t)[1] for t in trajectories], training,
                                largest_side(puppet.rest_vertices))


def host_inputs(puppet, controls):
    """Host side of the run time for a ``pipeline.puppet.Puppet``: world controls (N, n_c, 3) ->
    (standardised_controls (N, d), controls_in_place (N, n_c, 3), world_frames (N, 4, 4)).

    world_frames are the inverse control frames (``pipeline.alignment``) as column-vector
    homogeneous transforms: in-place positions -> world.
    """
    controls = np.asarray(controls, dtype=np.float64)
    frame_r, frame_t = in_place(controls, puppet.reference_controls, puppet.global_motion)
    placed = apply_frames(frame_r, frame_t, controls)
    standardised = puppet.kernel.standardise(placed.reshape(controls.shape[0], -1))
    inv_r, inv_t = invert_frames(frame_r, frame_t)
    frames = np.zeros((controls.shape[0], 4, 4))
    frames[:, :3, :3] = inv_r
    frames[:, :3, 3] = inv_t
    frames[:, 3, 3] = 1.0
    return standardised, placed, frames


class DevicePlayer:
    """A puppet uploaded once to ``device`` and played on demand through its whole run-time path
    in warp kernels (Feng §6, ``gpu.run_puppet``): what ``play`` writes and what ``skinsynth view``
    shows at every move. ``skinning``: "dual-quaternion", "linear", or None for the puppet's own
    (``Puppet.skinning``)."""

    def __init__(self, puppet, device, skinning=None, translation_solver=True):
        from skinsynth.gpu import DevicePuppet

        self.puppet, self.skinning, self.translation_solver = puppet, skinning or puppet.skinning, translation_solver
        self.device_puppet = DevicePuppet(puppet, device)

    def play(self, controls, threads=1):
        """Vertices (N, V, 3) float32 of world controls (N, n_c, 3), on ``threads`` CPU threads."""
        from skinsynth.gpu import run_puppet

        vertices = np.empty((len(controls), self.puppet.rest_vertices.shape[0], 3), dtype=np.float32)
        run_puppet(self.device_puppet, *host_inputs(self.puppet, controls), translation_solver=self.translation_solver,
                   out=vertices, threads=threads, skinning=self.skinning)
        return vertices


def play_characters(puppet, controls, device, skinning=None, translation_solver=True, threads=0, poses=None,
                    clip_frames=None, fps=None):
    """Every vertex of every frame of controls (C·F, n_c, 3) played through the puppet on
    ``device``: (vertices (C·F, V, 3) float32, seconds of compute, the skeleton path's
    :class:`~.jointed_play.BeyondExamples` or None). Both
    skinnings run the whole run-time path in warp kernels (:class:`DevicePlayer`, ``threads`` CPU
    threads, 0: all cores). The kernels are compiled (or loaded) on a one-frame warm-up first,
    outside the time. poses: the skeleton's :class:`~.jointed_play.ExamplePoses`, or None: the
    frames beyond the examples played by its skeleton (:mod:`.jointed_play`), and with ``fps`` the
    frames it tears (controls: characters of ``clip_frames`` each, None: one). Rig outputs take the
    world bones from :func:`character_bones`."""
    from .jointed_play import play_beyond_examples

    player = DevicePlayer(puppet, device, skinning, translation_solver)
    player.play(controls[:1])  # warm-up, untimed
    started = time.perf_counter()
    vertices = player.play(controls, threads or os.cpu_count() or 1)
    beyond = None if poses is None else play_beyond_examples(puppet, poses, controls, vertices, device,
                                                             translation_solver, clip_frames, fps)
    return vertices, time.perf_counter() - started, beyond


def play_summary(characters, frames, seconds, device, skinning, translation_solver, written, extrapolation,
                 takes=(), morph=None, shapes=0, beyond=None):
    """play's summary (the --json object) and text lines: ``characters`` × ``frames`` played on
    ``device`` in ``seconds`` of compute, ``written`` the outputs; extrapolation: (entries, lines)
    (``pipeline.view.extrapolation_report``); takes: each motion-capture take's (summary, lines);
    morph: the glTF morph targets of the ``shapes`` correctives
    (``pipeline.rig.morph_targets.played_morph_targets``), or None; beyond: the skeleton path's
    :class:`~.jointed_play.BeyondExamples` (:func:`~.jointed_play.skeleton_summary`), or None."""
    summary = {"frames": int(frames), "characters": int(characters), "seconds": round(seconds, 4),
               "frames_per_second": round(frames / seconds, 1),
               "character_frames_per_second": round(characters * frames / seconds, 1),
               "device": device, "translation_solver": bool(translation_solver), "skinning": skinning,
               "outputs": written, "extrapolation": extrapolation[0]}
    if takes:
        summary["takes"] = [take_summary for take_summary, _ in takes]
    lines = [line for _, take_lines in takes for line in take_lines]
    lines.append(f"played {characters} character(s) × {frames} frames on {device} in {seconds:.3f} s: "
                 f"{summary['frames_per_second']:.0f} frames/s, {summary['character_frames_per_second']:.0f} "
                 f"character-frames/s (compute only); wrote {', '.join(written)}")
    if beyond is not None:
        from .jointed_play import skeleton_summary

        summary["skeleton"], skeleton_lines = skeleton_summary(beyond)
        lines += skeleton_lines
    if morph is not None:
        summary.update(morph_targets=len(morph[0]), morph_target_error=morph[2])
        lines.append(f"correctives: {shapes} shapes as {len(morph[0])} morph target(s), "
                     f"{morph[2]:.2g} of the diagonal away at most")
    return summary, lines + extrapolation[1]
