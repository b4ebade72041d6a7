"""Held-out evaluation of a puppet against the baselines Feng et al. compare with (§4.3, §7).

Errors are RMS vertex distances on the held-out example frames over the rest pose's bounding-box
diagonal: the one normaliser of every error skinsynth reports (fit-skin's RMSE, preview's and view's
error colours; issue 68). Feng §7 reports over the largest side of the box instead (0.0108 against
0.0143): multiply by the diagonal over the largest side (1.11–1.22 on the shared captures, √3 for a
cube) to compare. Every
method sees the same control trajectories (the control vertices' positions in the held-out
frames) and handles global motion the same way as the puppet.

Three hold-outs: the frames the puppet did not train on (:func:`evaluate_puppet`: between its
examples), the last frames (:func:`extrapolation_split`, retrained on the first), and whole clips
of a several-clip file (:func:`evaluate_clip_hold_out`, issue 26: retrained on the other clips,
tested on poses of a take no method saw, e.g. trained on a gallop, tested on a collapse).
"""

from dataclasses import dataclass, field

import numpy as np

from .baselines import fit_pca_blendshape, fit_rbf, predict_pca_blendshape, predict_rbf
from ..errors import OptionError
from ..mesh.geometry import bounding_box_diagonal
from .puppet import predict_vertices, train_puppet


@dataclass
class Evaluation:
    """per_frame: {method: (T,) errors}; overall: {method: float}; test_frames (T,); notes."""

    per_frame: dict
    overall: dict
    test_frames: np.ndarray
    scale: float
    notes: dict = field(default_factory=dict)


def relative_errors(predicted, truth, scale):
    """(per-frame RMS (F,), overall RMS) of vertex distances divided by ``scale``."""
    squared = np.sum((predicted - truth) ** 2, axis=2)
    return np.sqrt(squared.mean(axis=1)) / scale, float(np.sqrt(squared.mean()) / scale)


def vertices_on_joints(puppet, controls, skeleton, translation_solver=True):
    """What ``play``'s rig outputs of a jointed skin show: the puppet's predicted world bones with
    every jointed bone put back on its joint (:func:`~skinsynth.pipeline.rig.skeleton.hold_joints`),
    skinned linearly (the rig's model) with the correctives' offsets. controls (F, n_c, 3);
    skeleton (parents (B,), jointed (B,), joints (B, 3), slides) (:func:`~skinsynth.pipeline.rig.skeleton.held_rig`)
    -> (vertices (F, V, 3), the same without the projection (F, V, 3))."""
    from skinsynth.gpu import lbs_reference

    from ..rig.skeleton import hold_joints
    from .playback import world_bones

    rotations, translations, weights = world_bones(puppet, controls, translation_solver)
    offsets = None if weights is None else np.einsum("fp,pvx->fvx", weights, puppet.correctives.offsets)
    free = lbs_reference(puppet.rest_vertices, puppet.bone_indices, puppet.bone_weights, rotations, translations,
                         offsets)
    held = hold_joints(rotations, translations.copy(), *skeleton)
    return lbs_reference(puppet.rest_vertices, puppet.bone_indices, puppet.bone_weights, rotations, held,
                         offsets), free


def evaluate_puppet(puppet, examples, test_frames, skinning=None, pca_components=None, skeleton=None):
    """Errors of the puppet (with and without the translation solver) and of the baselines.

    examples (F, V, 3) the example frames the puppet was trained from; test_frames (T,) the
    held-out ones; skinning None for the puppet's own. Returns :class:`Evaluation` with methods
    ``kcca``, ``kcca_no_translation_solver``, ``pca_blendshape``, ``rbf``. ``skeleton``: a jointed
    skin's (parents, jointed, joints[, slides]) (:func:`~skinsynth.pipeline.rig.skeleton.held_rig`)
    adds ``kcca_on_joints``, the rig ``play`` writes for it
    (:func:`vertices_on_joints`), and notes ``joint_projection_cost``: how far that projection
    moves the linearly skinned prediction (RMS, same scale).
    """
    skinning = skinning or puppet.skinning
    test_frames = np.asarray(test_frames)
    if test_frames.size == 0:
        raise OptionError("no held-out frames: train with --train-frames leaving some examples out")
    truth = examples[test_frames]
    controls = truth[:, puppet.control_indices]
    scale = bounding_box_diagonal(puppet.rest_vertices)
    predictions = {}
    if puppet.translations is not None:
        predictions["kcca"] = predict_vertices(puppet, controls, translation_solver=True, skinning=skinning)
    predictions["kcca_no_translation_solver"] = predict_vertices(puppet, controls, translation_solver=False,
                                                                 skinning=skinning)
    predictions.setdefault("kcca", predictions["kcca_no_translation_solver"])
    train = examples[puppet.train_frames]
    pca = fit_pca_blendshape(train, puppet.control_indices, puppet.reference_controls, components=pca_components,
                             global_motion=puppet.global_motion)
    predictions["pca_blendshape"] = predict_pca_blendshape(pca, controls)
    rbf = fit_rbf(train, puppet.control_indices, puppet.reference_controls, global_motion=puppet.global_motion)
    predictions["rbf"] = predict_rbf(rbf, controls)
    cost = None
    if skeleton is not None:
        predictions["kcca_on_joints"], free = vertices_on_joints(puppet, controls, skeleton,
                                                                 translation_solver=puppet.translations is not None)
        cost = relative_errors(predictions["kcca_on_joints"], free, scale)[1]
    per_frame, overall = {}, {}
    for name in ("kcca", "kcca_no_translation_solver", "pca_blendshape", "rbf") + (("kcca_on_joints",) if cost is not None
                                                                                   else ()):
        per_frame[name], overall[name] = relative_errors(predictions[name], truth, scale)
    notes = {"global_motion": puppet.global_motion, "global_motion_reason": puppet.global_motion_reason,
             "skinning": skinning,
             "translation_solver": puppet.translations is not None, "pca_components": int(pca.components),
             "translation_prior": (float(puppet.translation_prior) if puppet.translations is not None
                                   and np.isfinite(puppet.translation_prior) else None),
             "kernel": puppet.kernel.kind, "correctives": puppet.correctives_reason}
    if cost is not None:
        notes["joint_projection_cost"] = cost
    return Evaluation(per_frame=per_frame, overall=overall, test_frames=test_frames, scale=scale, notes=notes)


def extrapolation_split(frames, fraction):
    """(train (n,), test (F − n,)) frame ids of a contiguous hold-out: the first ``fraction`` of the
    frames, then the rest. OptionError unless 0 < fraction < 1 leaves ≥ 4 training frames and ≥ 1 test frame."""
    if not 0.0 < fraction < 1.0:
        raise OptionError(f"--extrapolate must lie strictly between 0 and 1 (got {fraction})")
    count = int(round(fraction * frames))
    if count < 4 or count >= frames:
        raise OptionError(f"--extrapolate {fraction:g} trains on {count} of {frames} frames; at least 4 are "
                          "needed and at least one must be left to test")
    return np.arange(count), np.arange(count, frames)


def evaluate_extrapolation(skin, control_indices, options, train, test, skinning=None,
                           pca_components=None):
    """A contiguous hold-out (:func:`extrapolation_split`): a puppet trained with ``options``
    (train_puppet's keywords) on ``train``, every method tested on ``test``, so on poses no method
    saw between its examples. skin: the puppet's SkinModel. Returns :class:`Evaluation` (its
    notes add ``train_frames``: the count trained on)."""
    puppet = train_puppet(skin.examples, skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights,
                          skin.rotations, skin.translations, control_indices, train, **options)
    result = evaluate_puppet(puppet, skin.examples, test, skinning, pca_components)
    result.notes["train_frames"] = int(len(train))
    return result


def clip_hold_out_split(clips, held_out, training_clips=None, option="--hold-out-clip"):
    """A whole-clip hold-out (issue 26): (train (n,) int64, test (T,) int64, train clip names,
    held-out clip names). Test: every frame of the clips ``held_out`` (names, or comma-separated
    strings); train: every frame of the other clips among ``training_clips`` (the puppet's own
    clips, None for every clip), so no test frame is trained on. Unknown names or no clip left
    to train on: OptionError naming ``option``."""
    if isinstance(held_out, str):
        held_out = (held_out,)
    held = [name.strip() for text in held_out for name in str(text).split(",") if name.strip()]
    if not held:
        raise OptionError(f"{option} needs a clip name; the clips are {', '.join(clips.names)}")
    held_ids = sorted({clips.index(name, option) for name in held})
    trained = clips.names if training_clips is None or len(training_clips) == 0 else tuple(training_clips)
    trained_ids = {clips.index(name, "the puppet's training clips") for name in trained}
    train_ids = sorted(trained_ids - set(held_ids))
    test_names = tuple(clips.names[c] for c in held_ids)
    if not train_ids:
        raise OptionError(f"{option} {','.join(test_names)} leaves no clip to train on (the puppet trained on "
                          f"{', '.join(trained)}; the file's clips are {', '.join(clips.names)})")
    train_names = tuple(clips.names[c] for c in train_ids)
    return clips.select(train_names, option), clips.select(test_names, option), train_names, test_names


def evaluate_clip_hold_out(skin, control_indices, options, clips, held_out, training_clips=None, skinning=None,
                           pca_components=None):
    """Extrapolation to a clip never seen (:func:`clip_hold_out_split`): a puppet trained with
    ``options`` (train_puppet's keywords) on every frame of the other clips, and every method (its
    PCA and RBF baselines fitted to the same frames) tested on the held-out clips' frames. skin:
    the puppet's SkinModel; clips: its :class:`~skinsynth.pipeline.inputs.clips.Clips`. Returns
    :class:`Evaluation`; its notes add ``train_clips``, ``test_clips`` (names) and
    ``train_frames`` (n,) the frame ids the retrained puppet holds."""
    train, test, train_names, test_names = clip_hold_out_split(clips, held_out, training_clips)
    result = evaluate_extrapolation(skin, control_indices, options, train, test, skinning, pca_components)
    result.notes.update(train_clips=list(train_names), test_clips=list(test_names),
                        train_frames=np.asarray(train, dtype=np.int64))
    return result


def evaluate_hold_outs(puppet, skin, test_frames, options, clips, training_clips=None, skinning=None,
                       pca_components=None, extrapolate=None, hold_out_clips=()):
    """``evaluate``'s tests: the puppet on its held-out frames ``test_frames`` (T,)
    (:func:`evaluate_puppet`, with a jointed skin's ``kcca_on_joints``) and, where asked, two
    harder ones with a puppet retrained on ``options`` (train_puppet's keywords): the last
    frames after the first ``extrapolate`` fraction (:func:`evaluate_extrapolation`) and the
    clips ``hold_out_clips`` (:func:`evaluate_clip_hold_out`; ``clips``: the skin's
    :class:`~skinsynth.pipeline.inputs.clips.Clips`, ``training_clips``: the puppet's). A bad
    fraction or clip name is an OptionError before any work. ``skinning`` None: the puppet's own.
    Returns (:class:`Evaluation`, the extrapolation's or None, the clip hold-out's or None)."""
    split = None if extrapolate is None else extrapolation_split(skin.examples.shape[0], extrapolate)
    if hold_out_clips:  # a bad name fails before any work
        clip_hold_out_split(clips, hold_out_clips, training_clips)
    from ..rig.skeleton import held_rig

    skeleton = None if skin.skeleton is None else held_rig(skin.skeleton)
    result = evaluate_puppet(puppet, skin.examples, test_frames, skinning=skinning, pca_components=pca_components,
                             skeleton=skeleton)
    skinning = result.notes["skinning"]
    beyond = None
    if split is not None:
        beyond = evaluate_extrapolation(skin, puppet.control_indices, options, *split, skinning, pca_components)
    unseen = None
    if hold_out_clips:
        unseen = evaluate_clip_hold_out(skin, puppet.control_indices, options, clips, hold_out_clips,
                                        training_clips, skinning, pca_components)
    return result, beyond, unseen


#: The methods :func:`evaluate_puppet` compares, as ``evaluate`` names them.
METHODS = {
    "kcca": "kernel CCA + Poisson translation solver",
    "kcca_no_translation_solver": "kernel CCA, predicted translations",
    "pca_blendshape": "PCA blendshapes, weights by least squares",
    "rbf": "direct RBF regression",
    "kcca_on_joints": "kernel CCA, bones put back on the skeleton's joints (play's rig of a jointed skin)",
}


def evaluation_report(path, result, train_frames, clips, training_clips=None, beyond=None, unseen=None, plot=None):
    """``evaluate``'s summary (--json) and its text lines, from :func:`evaluate_hold_outs`'s
    evaluations of the puppet file ``path`` (trained on ``train_frames``; ``clips``: the skin's
    :class:`~skinsynth.pipeline.inputs.clips.Clips`, ``training_clips``: the puppet's, None for
    every clip); ``plot``: the error curves' file, where written."""
    notes = result.notes
    payload = dict(result.overall)
    payload.update(test_frames=[int(f) for f in result.test_frames], train_frames=[int(f) for f in train_frames],
                   per_frame={k: [float(e) for e in v] for k, v in result.per_frame.items()},
                   clips=list(training_clips or clips.names), error_over="rest bounding-box diagonal", **notes)
    if beyond is not None:
        payload["extrapolation"] = dict(beyond.overall, train_frames=beyond.notes["train_frames"],
                                        test_frames=[int(f) for f in beyond.test_frames])
    if unseen is not None:
        payload["clip_hold_out"] = dict(unseen.overall, train_clips=unseen.notes["train_clips"],
                                        test_clips=unseen.notes["test_clips"],
                                        train_frames=[int(f) for f in unseen.notes["train_frames"]],
                                        test_frames=[int(f) for f in unseen.test_frames],
                                        pca_components=unseen.notes["pca_components"],
                                        global_motion=unseen.notes["global_motion"])
    lines = [f"{path}: {len(result.test_frames)} held-out frames, {len(train_frames)} training; "
             f"global motion: {notes['global_motion']} ({notes['global_motion_reason']}); "
             f"{notes['skinning']} skinning; "
             f"kernel {notes['kernel']}; PCA baseline with {notes['pca_components']} blendshapes"
             + (f"; translation prior {notes['translation_prior']:g}" if notes["translation_prior"] is not None else "")
             + f"; correctives: {notes['correctives'] or 'off'}"
             + (f"; clips {', '.join(training_clips or clips.names)}" if len(clips) > 1 else "")
             + "; errors: RMS vertex distance over the rest bounding-box diagonal",
             *_table(result)]
    if "joint_projection_cost" in notes:
        lines.append(f"  the skeleton's joints: play's rig puts the predicted bones back on them, which moves the "
                     f"prediction by {notes['joint_projection_cost']:.5f} (RMS, same scale)")
    if beyond is not None:
        lines.append(f"extrapolation: trained on frames 0..{beyond.notes['train_frames'] - 1}, tested on the "
                     f"{len(beyond.test_frames)} after")
        lines += _table(beyond)
    if unseen is not None:
        lines.append(f"clip hold-out: trained on {', '.join(unseen.notes['train_clips'])} "
                     f"({len(unseen.notes['train_frames'])} frames), tested on {', '.join(unseen.notes['test_clips'])} "
                     f"({len(unseen.test_frames)} frames); global motion {unseen.notes['global_motion']}, "
                     f"PCA baseline with {unseen.notes['pca_components']} blendshapes")
        lines += _table(unseen)
    if plot is not None:
        lines.append(f"wrote {plot}")
    return payload, lines


def _table(result):
    """One line per method: its error, its label, the lowest marked."""
    best = min(result.overall, key=result.overall.get)
    lines = []
    for name, label in METHODS.items():
        if name not in result.overall:  # kcca_on_joints: only for a skin with a skeleton
            continue
        if name == "kcca" and not result.notes["translation_solver"]:
            label += " (trained without the solver: same as below)"
        mark = "  <- lowest" if name == best else ""
        lines.append(f"  {name:<28} {result.overall[name]:.5f}  {label}{mark}")
    return lines
