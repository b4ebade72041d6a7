"""Puppetry (Feng 2008): control points chosen by PCA and varimax (:mod:`.controls`,
:mod:`.varimax`, §3), per-bone kernel CCA (:mod:`.kcca`, §4, §7), the Poisson translation solve
(:mod:`.poisson`, §5, §6.2), pose-space correctives (:mod:`.correctives`), training and
prediction (:mod:`.puppet`, §6), control frames (:mod:`.alignment`), Feng's baselines and the
held-out evaluation (:mod:`.baselines`, :mod:`.evaluation`), and many characters at once
(:mod:`.playback`).

Public: select_controls, selection_summary, train_puppet, training_summary, predict_vertices, parse_frame_spec, clip_training_frames, Puppet, puppet_from_record, KccaRegression,
ControlKernel, KERNELS, TranslationOperator, Correctives, evaluate_puppet, evaluate_extrapolation,
extrapolation_split, clip_hold_out_split, evaluate_clip_hold_out, evaluate_hold_outs, evaluation_report, instance_trajectories, host_inputs, play_extrapolation, world_bones, character_offsets, play_summary, character_bones, play_characters, DevicePlayer,
drive_from_markers, MarkerDrive, take_report, layout_order (a motion-capture take as the controls, :mod:`.markers`),
example_poses, play_beyond_examples (a skeleton beyond the examples, torn frames mended, :mod:`.jointed_play`).
"""

from .._lazy import lazy_exports

_EXPORTS = {"select_controls": "controls", "selection_summary": "controls", "train_puppet": "puppet",
            "training_summary": "puppet", "predict_vertices": "puppet",
            "parse_frame_spec": "puppet", "clip_training_frames": "puppet", "Puppet": "puppet", "puppet_from_record": "puppet", "KccaRegression": "kcca", "ControlKernel": "kcca",
            "KERNELS": "kcca", "TranslationOperator": "poisson", "Correctives": "correctives",
            "evaluate_puppet": "evaluation", "evaluate_extrapolation": "evaluation",
            "extrapolation_split": "evaluation", "clip_hold_out_split": "evaluation",
            "evaluate_clip_hold_out": "evaluation", "evaluate_hold_outs": "evaluation",
            "evaluation_report": "evaluation", "instance_trajectories": "playback", "host_inputs": "playback", "play_characters": "playback", "DevicePlayer": "playback",
            "world_bones": "playback", "drive_from_markers": "markers", "MarkerDrive": "markers", "character_offsets": "playback", "take_report": "markers", "layout_order": "markers", "play_summary": "playback", "character_bones": "playback",
            "play_extrapolation": "playback", "example_poses": "jointed_play",
            "play_beyond_examples": "jointed_play"}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
