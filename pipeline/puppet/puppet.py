"""The trained puppet (Feng et al. 2008): control points in, every vertex out.

Training (:func:`train_puppet`): bring the training examples in place (a rigid frame fitted to
the control points, :mod:`.alignment`), express each bone's pose in that frame as a dual
quaternion with consistent signs, fit per-bone kernel CCA regression (:mod:`.kcca`), and
precompute the Poisson translation operator (:mod:`.poisson`).

Run time (:func:`predict_vertices`, the numpy reference of the whole path): align the controls,
kernel vector ξ, ``d = M ξ + m`` for all bones, normalise each dual quaternion and take its
rotation, recompute translations with ``t = Γ·R + Q·c`` (optional), skinning, and carry the
result back to the world with the inverse control frame.

A puppet is trained for one skinning (``Puppet.skinning``): Feng §6.3's dual quaternions, or the
linear blend skinning the weights were fitted for and that glTF, engines and Blender play. The
bones are regressed as dual quaternions either way (Feng §4.3: the better-interpolating, smaller
representation); the skinning decides what the cross-validation scores (the kernel width, the
translation prior, the global-motion mode) and what the pose-space correctives are fitted to.
"""

from dataclasses import dataclass

import numpy as np

from .alignment import apply_frames, control_frames, frame_conditioning, invert_frames
from .correctives import (POWER_GRID, Correctives, Model, choose_model, corrective_offsets, cross_validated_errors,
                          fit_correctives, rest_offsets)
from ..errors import OptionError
from ..mesh.geometry import mesh_edges
from .kcca import (WIDTH_GRID, ControlKernel, KccaRegression, choose_regularization, control_kernel, cv_folds,
                   fit_kcca, predict)
from .poisson import (PRIOR_GRID, TranslationOperator, choose_translation_prior, fit_edge_weights,
                      operator_from_system, solve_translations, translation_system)
from ..rig.rotations import dual_quaternion_to_rigid, rigid_to_dual_quaternion, with_translations

GLOBAL_MOTION = ("auto", "control-frame", "world")
SKINNING = ("dual-quaternion", "linear")
#: The skinning a puppet is trained for unless told: linear blend skinning, what glTF, engines and
#: Blender play, and on the shared captures as good as dual quaternions (1.01× their held-out
#: error in the geometric mean over 18 capture-and-split cases, 0.83×–1.17×; benchmarks/puppet.py).
DEFAULT_SKINNING = "linear"
#: A frame fitted to the controls is trusted only above this conditioning (s₂/s₁, every frame).
FRAME_CONDITIONING = 0.15


def choose_global_motion(examples, rest, faces, bone_indices, bone_weights, rotations, translations,
                         control_indices, train_frames, kernel, folds=4, skinning="dual-quaternion"):
    """("control-frame" | "world", reason) for ``--global-motion auto``.

    A frame fitted to the controls removes travel and turns, but it also adds a nonlinear
    function of the controls to every bone's pose, and it flips when the controls are nearly
    collinear (a tube with controls along it). Which helps depends on the data, so: if the
    controls fix a rotation poorly in some training frame (conditioning ≤ FRAME_CONDITIONING),
    world; otherwise the mode with the lower vertex error in ``folds``-fold cross-validation over
    the training frames (interleaved folds, leave-one-out when a fold would leave fewer than the 4
    frames a puppet needs; fixed κ = 1e-2, width σ and no translation solver, to keep it cheap;
    vertices skinned as ``skinning``).
    With 5 training frames (the horse at every:10) the old 4-fold rule fell back to control-frame
    without looking, and the horse's error was 6× world's.
    """
    conditioning = frame_conditioning(examples[train_frames][:, control_indices])
    if conditioning <= FRAME_CONDITIONING:
        return "world", (f"the controls are nearly collinear (conditioning {conditioning:.2f}): a frame fitted "
                         "to them would be unstable; spread the controls in 3D to allow control-frame")
    if len(train_frames) - -(-len(train_frames) // folds) < 4:
        folds = len(train_frames)  # leave one out: every fold must keep the 4 frames a puppet needs
    if len(train_frames) < 5:
        return "control-frame", (f"too few training frames to cross-validate; the controls fix a frame well "
                                 f"(conditioning {conditioning:.2f})")
    errors = {}
    flat = examples[train_frames][:, control_indices].reshape(len(train_frames), -1)
    spread = max(float(np.sqrt(np.sum(flat.var(axis=0)))), np.finfo(float).tiny)
    fold_tests = [train_frames[test] for test in cv_folds(flat / spread, folds)]
    for mode in ("control-frame", "world"):
        total = 0.0
        for test in fold_tests:
            train = np.setdiff1d(train_frames, test)
            puppet = train_puppet(examples, rest, faces, bone_indices, bone_weights, rotations, translations,
                                  control_indices, train, kernel=kernel, regularization=1e-2,
                                  translation_solver=False, global_motion=mode, kernel_width=1.0,
                                  correctives="off", skinning=skinning)
            pred = predict_vertices(puppet, examples[test][:, control_indices], translation_solver=False)
            total += float(np.sum((pred - examples[test]) ** 2))
        errors[mode] = np.sqrt(total / (len(train_frames) * rest.shape[0]))
    chosen = min(errors, key=errors.get)
    return chosen, (f"cross-validated RMS error {errors['control-frame']:.4g} in the control frame vs "
                    f"{errors['world']:.4g} in world space (controls' frame conditioning {conditioning:.2f})")


@dataclass
class Puppet:
    """Everything the run time needs (shapes: V vertices, B bones, n_c controls, n_p examples).

    rest_vertices (V, 3); bone_indices, bone_weights (V, K); control_indices (n_c,);
    reference_controls (n_c, 3) rest-frame control positions that define "in place";
    global_motion "control-frame" | "world" (and why: global_motion_reason); kernel: ControlKernel; training_controls (n_p, 3 n_c)
    standardised; regression: KccaRegression (predictor (B, 8, n_p), bias (B, 8));
    translations: TranslationOperator or None; beta; translation_prior (relative γ of
    :mod:`.poisson`, and why: translation_prior_reason); train_frames (n_p,); correctives:
    :class:`.correctives.Correctives` or None (rest-pose offsets added before skinning);
    skinning: "dual-quaternion" | "linear", the skinning it was trained for and plays with.
    """

    rest_vertices: np.ndarray
    bone_indices: np.ndarray
    bone_weights: np.ndarray
    control_indices: np.ndarray
    reference_controls: np.ndarray
    global_motion: str
    kernel: ControlKernel
    training_controls: np.ndarray
    regression: KccaRegression
    translations: TranslationOperator | None
    beta: float
    train_frames: np.ndarray
    global_motion_reason: str = ""
    translation_prior: float = 1e-6
    translation_prior_reason: str = ""
    kernel_width_reason: str = ""
    correctives: Correctives | None = None
    correctives_reason: str = ""
    skinning: str = "dual-quaternion"


def puppet_from_record(record):
    """The :class:`Puppet` of a stage file's plain record (``formats.puppet_file.PuppetRecord``:
    the same fields, with the kernel, regression, translation operator and correctives as dicts)."""
    import dataclasses

    fields = {f.name: getattr(record, f.name) for f in dataclasses.fields(Puppet)}
    fields["kernel"] = ControlKernel(**record.kernel)
    fields["regression"] = KccaRegression(**record.regression)
    if record.translations is not None:
        fields["translations"] = TranslationOperator(**record.translations)
    if record.correctives is not None:
        fields["correctives"] = Correctives(**record.correctives)
    return Puppet(**fields)


def parse_frame_spec(spec, frames):
    """Training frames from a spec: ``every:N`` (0, N, 2N…), ``first:N``, ``all``, or a list
    ``0,4,10-20`` (ranges inclusive). Returns sorted unique indices; OptionError if invalid."""
    spec = spec.strip()
    try:
        if spec == "all":
            chosen = np.arange(frames)
        elif spec.startswith("every:"):
            step = int(spec[6:])
            if step < 1:
                raise ValueError
            chosen = np.arange(0, frames, step)
        elif spec.startswith("first:"):
            chosen = np.arange(min(int(spec[6:]), frames))
        else:
            parts = []
            for item in spec.split(","):
                lo, _, hi = item.partition("-")
                parts.append(np.arange(int(lo), int(hi or lo) + 1))
            chosen = np.unique(np.concatenate(parts))
    except ValueError:
        raise OptionError(f"--train-frames {spec!r}: expected every:N, first:N, all or a list like 0,4,10-20") from None
    if chosen.size and (chosen.min() < 0 or chosen.max() >= frames):
        raise OptionError(f"--train-frames {spec!r}: frames must lie in 0..{frames - 1}")
    return chosen


def clip_training_frames(spec, clips, names=None, option="--clips"):
    """Training and held-out frames of the clips ``names`` (train-kcca's ``--train-frames`` and
    ``--clips``; issue 26): (train (n_p,) int64, held_out (n_t,) int64, the clip names used).

    clips: a :class:`~skinsynth.pipeline.inputs.clips.Clips`; names: None (every clip), an iterable of
    names or one comma-separated string (an unknown name is an OptionError naming ``option`` and
    the clips). A sampling spec (``every:N``, ``first:N``, ``all``) runs within each chosen clip,
    from that clip's first frame; a list (``0,4,10-20``) names global frames, each of which must
    lie in a chosen clip. The held-out frames are the chosen clips' other frames: the unchosen
    clips are neither. Every id is global. One clip chosen whole: exactly
    ``parse_frame_spec(spec, F)``. Nothing here (nor in training: its folds interleave frames,
    :func:`.kcca.cv_folds`) looks at a frame's neighbours, so nothing crosses a clip boundary."""
    selected = clips.select(names, option)
    chosen = np.unique(clips.clip_of(selected))
    starts = clips.starts
    text = spec.strip()
    if text == "all" or text.startswith(("every:", "first:")):
        train = np.concatenate([parse_frame_spec(text, clips.frames[c]) + starts[c] for c in chosen])
    else:
        train = parse_frame_spec(text, clips.total)
        outside = train[~np.isin(train, selected)]
        if outside.size:
            frame = int(outside[0])
            raise OptionError(f"--train-frames {spec!r}: frame {frame} ({clips.label(frame)}) is in clip "
                              f"{clips.names[int(clips.clip_of(frame))]!r}, not one of {option} "
                              f"{','.join(clips.names[c] for c in chosen)}")
    train = train.astype(np.int64)
    return train, np.setdiff1d(selected, train).astype(np.int64), tuple(clips.names[c] for c in chosen)


def in_place(controls, reference, global_motion):
    """Rigid frames (R (F,3,3), t (F,3)) bringing controls (F, n_c, 3) in place."""
    if global_motion == "world":
        frames = controls.shape[0]
        return np.tile(np.eye(3), (frames, 1, 1)), np.zeros((frames, 3))
    return control_frames(controls, reference)


def _bone_dual_quaternions(rotations, translations):
    """Dual quaternions (F, B, 8) with one sign branch per bone over the frames (Feng §4.3).

    Signs follow the bone's mean real part (not time order: training frames may be sparse)."""
    dq = rigid_to_dual_quaternion(rotations, translations)
    for _ in range(2):
        mean = dq[..., :4].mean(axis=0)
        dq *= np.where(np.einsum("fbc,bc->fb", dq[..., :4], mean) < 0.0, -1.0, 1.0)[..., None]
    return dq


def train_puppet(examples, rest, faces, bone_indices, bone_weights, rotations, translations, control_indices,
                 train_frames, kernel="gaussian", bases=8, regularization="auto", translation_solver=True,
                 beta=100.0, global_motion="auto", translation_prior="auto", kernel_width="auto",
                 correctives="auto", skinning=DEFAULT_SKINNING):
    """Train a puppet from a skin fit. examples (F, V, 3); rotations (F, B, 3, 3), translations
    (F, B, 3) the fitted bones; control_indices (n_c,); train_frames (n_p,); translation_prior:
    the Poisson solve's pull towards the regression's translations (:mod:`.poisson`), a number or
    "auto" (cross-validated); kernel_width: the Gaussian's width as a multiple of the controls'
    spread σ, or "auto" (cross-validated, :func:`_choose_width_and_kappa`); correctives: the
    pose-space correctives' relative ridge (:mod:`.correctives`), "auto" (cross-validated) or
    "off"; skinning: "dual-quaternion" or "linear", what every cross-validated choice and the
    correctives are fitted for and what the puppet plays with. Returns Puppet."""
    if skinning not in SKINNING:
        raise OptionError(f"--skinning must be one of {', '.join(SKINNING)} (got {skinning!r})")
    if global_motion not in GLOBAL_MOTION:
        raise OptionError(f"--global-motion must be one of {', '.join(GLOBAL_MOTION)}")
    if len(train_frames) < 4:
        raise OptionError(f"only {len(train_frames)} training frames; kernel CCA needs at least 4")
    if bases < 1:
        raise OptionError(f"--bases must be at least 1 (got {bases})")
    if not beta > 0.0:
        raise OptionError(f"--beta must be positive (got {beta})")
    control_indices = np.asarray(control_indices)
    if control_indices.size == 0 or control_indices.min() < 0 or control_indices.max() >= rest.shape[0]:
        raise OptionError(f"control vertex ids must lie in 0..{rest.shape[0] - 1}")
    reason = f"chosen by the user (--global-motion {global_motion})"
    if global_motion == "auto":
        global_motion, reason = choose_global_motion(examples, rest, faces, bone_indices, bone_weights, rotations,
                                                     translations, control_indices, np.asarray(train_frames), kernel,
                                                     skinning=skinning)
    reference = rest[control_indices]
    controls = examples[train_frames][:, control_indices]
    frame_r, frame_t = in_place(controls, reference, global_motion)
    placed_controls = apply_frames(frame_r, frame_t, controls)
    rot = np.einsum("fac,fbcd->fbad", frame_r, rotations[train_frames])
    trans = np.einsum("fac,fbc->fba", frame_r, translations[train_frames]) + frame_t[:, None, :]

    flat_controls = placed_controls.reshape(len(train_frames), -1)
    kern = control_kernel(kernel, flat_controls)
    targets = np.swapaxes(_bone_dual_quaternions(rot, trans), 0, 1)  # (B, n_p, 8)
    if kernel_width != "auto" and not float(kernel_width) > 0.0:
        raise OptionError(f"--kernel-width must be a positive number or 'auto' (got {kernel_width})")
    if regularization != "auto" and not float(regularization) >= 0.0:
        raise OptionError(f"--regularization must be a non-negative number or 'auto' (got {regularization})")
    if translation_prior != "auto" and not float(translation_prior) >= 0.0:
        raise OptionError(f"--translation-prior must be a non-negative number or 'auto' (got {translation_prior})")
    if correctives not in ("auto", "off") and not 0.0 < float(correctives) < np.inf:
        raise OptionError(f"--correctives must be a positive ridge, 'auto' or 'off' (got {correctives})")

    system = None
    placed = apply_frames(frame_r, frame_t, examples[train_frames])
    if translation_solver:
        edges = mesh_edges(faces)
        edge_vectors = placed[:, edges[:, 0]] - placed[:, edges[:, 1]]
        edge_bones, edge_weights = fit_edge_weights(rest, edges, bone_indices, bone_weights, rot, edge_vectors)
        system = translation_system(rest, edges, bone_indices, bone_weights, edge_bones, edge_weights,
                                    control_indices, beta=beta)
    kappa, scores, width_reason = _choose_width_and_kappa(kern, kernel_width, regularization, translation_prior,
                                                          correctives == "auto", flat_controls, targets, bases,
                                                          system, placed, placed_controls, rest, bone_indices,
                                                          bone_weights, skinning)
    x = kern.standardise(flat_controls)
    kernel_matrix = kern.matrix(x, x)
    regression = fit_kcca(kernel_matrix, targets, bases=bases, regularization=kappa)

    operator, prior, prior_reason = None, 1e-6, ""
    if system is not None:
        if translation_prior == "auto":
            errors = scores.priors
            prior = min(errors, key=errors.get)
            prior_reason = (f"cross-validated RMS {errors[prior]:.4g} at prior {prior:g} (Feng's plain solve, prior "
                            f"1e-06: {errors[min(errors)]:.4g}; nearest the regression's translations, prior "
                            f"{max(errors):g}: {errors[max(errors)]:.4g})")
        else:
            prior, prior_reason = float(translation_prior), "chosen by the user (--translation-prior)"
        operator = operator_from_system(system, prior)
    puppet = Puppet(rest_vertices=rest, bone_indices=bone_indices, bone_weights=bone_weights,
                    control_indices=np.asarray(control_indices), reference_controls=reference,
                    global_motion=global_motion, kernel=kern, training_controls=x, regression=regression,
                    translations=operator, beta=float(beta), train_frames=np.asarray(train_frames),
                    global_motion_reason=reason, translation_prior=float(prior), translation_prior_reason=prior_reason,
                    kernel_width_reason=width_reason, skinning=skinning)
    if correctives == "off":
        model, puppet.correctives_reason = None, "off, chosen by the user (--correctives off)"
    elif correctives == "auto":
        model, puppet.correctives_reason = choose_model(scores.correctives)
    else:
        model = Model(float(correctives))
        puppet.correctives_reason = f"{model}, chosen by the user (--correctives)"
    if model is not None:
        d = predict_bones(puppet, controls)[0]
        offsets = rest_offsets(rest, bone_indices, bone_weights, d, placed, skinning)
        puppet.correctives = fit_correctives(kernel_matrix, x, offsets, model, puppet.correctives_reason)
    return puppet


def training_summary(output, puppet, bones, train, test, clips, used, seconds):
    """``train-kcca``'s summary (--json) and its text lines: the puppet (:func:`train_puppet`) of
    a skin of ``bones`` bones, trained on the frames ``train`` (n_p,) with ``test`` (T,) held out,
    in ``seconds``; ``clips``: the skin's :class:`~skinsynth.pipeline.inputs.clips.Clips`,
    ``used``: the names of those trained on."""
    corr = puppet.regression.correlations
    solver = puppet.translations is not None
    lines = [f"wrote {output}: {bones} bones, {len(puppet.control_indices)} controls, "
             f"{len(train)} training / {len(test)} held-out frames, {puppet.kernel.kind} kernel, "
             f"{corr.shape[1]} bases (mean first correlation {corr[:, 0].mean():.3f}), "
             f"translation solver {'on' if solver else 'off'}, {puppet.skinning} skinning; "
             f"{seconds:.1f} s"]
    if len(clips) > 1:
        lines.append(f"clips: {', '.join(used)} ({len(train)} training / {len(test)} held-out frames of "
                     f"{clips.total} in {len(clips)} clips)")
    lines.append(f"global motion: {puppet.global_motion} ({puppet.global_motion_reason})")
    if puppet.kernel_width_reason:
        lines.append(f"kernel width: {puppet.kernel_width_reason}")
    if solver:
        lines.append(f"translation prior: {puppet.translation_prior:g} ({puppet.translation_prior_reason})")
    lines.append(f"correctives: {puppet.correctives_reason}")
    summary = {"output": output, "bones": bones, "controls": len(puppet.control_indices),
               "train_frames": len(train), "test_frames": len(test), "kernel": puppet.kernel.kind,
               "bases": int(corr.shape[1]),
               "kernel_scale": float(puppet.kernel.scale), "kernel_width_reason": puppet.kernel_width_reason,
               "regularization": puppet.regression.regularization, "global_motion": puppet.global_motion,
               "global_motion_reason": puppet.global_motion_reason, "translation_solver": solver,
               "translation_prior": puppet.translation_prior if solver else None,
               "translation_prior_reason": puppet.translation_prior_reason,
               "correctives": puppet.correctives is not None, "correctives_reason": puppet.correctives_reason,
               "skinning": puppet.skinning,
               "seconds": round(seconds, 3), "clips": list(used)}
    return summary, lines


@dataclass
class _Scores:
    """Cross-validated RMS vertex errors at one kernel width: priors {prior: error} (no
    correctives; keyed 0.0 without the solver) and correctives {:class:`.correctives.Model`:
    error} (at the best prior) or None when not asked for."""

    priors: dict
    correctives: dict | None

    @property
    def best(self):
        return min((self.correctives or self.priors).values())


def _choose_width_and_kappa(kern, kernel_width, regularization, translation_prior, correctives, flat_controls,
                            targets, bases, system, placed, placed_controls, rest, bone_indices, bone_weights,
                            skinning="dual-quaternion"):
    """(κ (B,) or scalar, :class:`_Scores` or None, width reason); sets ``kern.scale``.

    Feng §7 takes the Gaussian's σ from the data, but no fixed multiple suits every capture
    (measured at every:4: the horse's six distinct poses want a wide kernel, the samba σ). With
    ``kernel_width`` "auto" each width of WIDTH_GRID gets its per-bone κ (dual-quaternion
    cross-validation, when "auto") and is scored by the out-of-fold skinned-vertex error at its
    best translation prior, the quantity ``evaluate`` reports, with the best pose-space
    correctives when ``correctives`` (they change which width is best: the Vellum sheet at
    every:4 wanted 8σ without them, 0.5σ with); the lowest wins (ties: the narrower). The scores
    at the chosen width also pick the prior and the correctives' ridge."""
    gaussian = kern.kind == "gaussian"
    widths = WIDTH_GRID if gaussian and kernel_width == "auto" else (
        float(kernel_width) if gaussian and kernel_width != "auto" else 1.0,)
    priors = PRIOR_GRID if translation_prior == "auto" else (float(translation_prior),)
    base_scale, tried = kern.scale, {}
    for width in widths:
        kern.scale = base_scale * width
        x = kern.standardise(flat_controls)
        kappa = (choose_regularization(kern, x, targets, bases=bases) if regularization == "auto"
                 else float(regularization))
        scores = None
        if len(widths) > 1 or (system is not None and len(priors) > 1) or correctives:
            scores = _cross_validated_vertex_errors(system, priors, kern, x, targets, bases, kappa, placed,
                                                    placed_controls, rest, bone_indices, bone_weights, correctives,
                                                    skinning=skinning)
        tried[width] = (kappa, scores)
    width = min(widths, key=lambda w: (tried[w][1].best, w)) if len(widths) > 1 else widths[0]
    kern.scale = base_scale * width
    reason = ""
    if gaussian and len(widths) > 1:
        listed = ", ".join(f"{w:g}σ {tried[w][1].best:.4g}" for w in widths)
        reason = f"{width:g}σ (cross-validated RMS vertex error {listed})"
    elif gaussian:
        reason = f"{width:g}σ, chosen by the user (--kernel-width)"
    return tried[width][0], tried[width][1], reason


#: Vertices used to score the translation prior and the kernel width (evenly spaced; the whole mesh when smaller).
PRIOR_VERTICES = 4096


def _cross_validated_vertex_errors(system, priors, kern, x, targets, bases, kappa, placed, placed_controls, rest,
                                   bone_indices, bone_weights, correctives=False, folds=5, skinning="dual-quaternion"):
    """:class:`_Scores` of the skinned vertices (``skinning``) of out-of-fold predictions, with
    the Poisson translations at each prior (``system`` None: the regression's own translations,
    keyed by 0.0), and with ``correctives`` also each corrective model at the best prior
    (:func:`.correctives.cross_validated_errors`: each fold's puppet predicts every row, its own
    rows giving the residuals it learns). Folds keep repeated poses together
    (:func:`.kcca.cv_folds`); κ per bone as chosen; the edge weights and the kernel's parameters
    are those fitted on all training frames. Scored on PRIOR_VERTICES evenly spaced vertices."""
    from skinsynth.gpu import dqs_reference, lbs_reference

    n = x.shape[0]
    kernel_matrix = kern.matrix(x, x)
    fold_tests = cv_folds(x, folds)
    d = np.empty((n,) + targets.shape[:1] + (8,))
    every_row = []
    for test in fold_tests:
        train = np.setdiff1d(np.arange(n), test)
        model = fit_kcca(kernel_matrix[np.ix_(train, train)], targets[:, train], bases=bases, regularization=kappa)
        rows = predict(model, kernel_matrix[:, train])
        d[test] = rows[test]
        if correctives:  # the corrective models learn from each fold's own rows too
            every_row.append(rows / np.linalg.norm(rows[..., :4], axis=-1, keepdims=True))
    d /= np.linalg.norm(d[..., :4], axis=-1, keepdims=True)
    rot, trans = dual_quaternion_to_rigid(d)
    subset = _vertex_subset(rest.shape[0])

    def vertex_error(rotations, translations):
        if skinning == "linear":
            skinned = lbs_reference(rest[subset], bone_indices[subset], bone_weights[subset], rotations, translations)
        else:
            skinned = dqs_reference(rest[subset], bone_indices[subset], bone_weights[subset],
                                    rigid_to_dual_quaternion(rotations, translations))
        return np.sum((skinned - placed[:, subset]) ** 2)

    if system is None:
        errors = {0.0: vertex_error(rot, trans)}
    else:
        _, errors = choose_translation_prior(system, rot, placed_controls, trans, vertex_error, grid=priors)
    errors = {p: float(np.sqrt(e / (n * subset.size))) for p, e in errors.items()}
    corrective_errors = None
    if correctives:
        if system is not None:
            operator = operator_from_system(system, min(errors, key=errors.get))
            for i, rows in enumerate(every_row):
                r, t = dual_quaternion_to_rigid(rows)
                every_row[i] = with_translations(rows, solve_translations(operator, r, placed_controls, t))
        corrective_errors = cross_validated_errors(kernel_matrix, x, fold_tests, every_row, placed[:, subset],
                                                   rest[subset], bone_indices[subset], bone_weights[subset],
                                                   powers=POWER_GRID if kern.kind == "gaussian" else (1.0,),
                                                   skinning=skinning)
    return _Scores(priors=errors, correctives=corrective_errors)


def _vertex_subset(count):
    """Evenly spaced vertex ids (at most PRIOR_VERTICES of count) that cross-validation scores."""
    return np.unique(np.linspace(0, count - 1, min(PRIOR_VERTICES, count)).astype(np.int64))


def predict_bones(puppet, controls, translation_solver=True):
    """controls (F, n_c, 3) world -> (dual quaternions (F, B, 8) in place, frame_r, frame_t,
    (kernel vectors ξ (F, n_p), standardised controls x (F, d))).

    The dual quaternions are unit and, with the solver, carry its translations."""
    frames = controls.shape[0]
    frame_r, frame_t = in_place(controls, puppet.reference_controls, puppet.global_motion)
    placed = apply_frames(frame_r, frame_t, controls)
    x = puppet.kernel.standardise(placed.reshape(frames, -1))
    xi = puppet.kernel.matrix(x, puppet.training_controls)  # kernel vector ξ (F, n_p)   (Feng §6.1)
    d = predict(puppet.regression, xi)  # d = M ξ + m, all bones at once
    d = d / np.linalg.norm(d[..., :4], axis=-1, keepdims=True)
    if translation_solver and puppet.translations is not None:
        rot, trans = dual_quaternion_to_rigid(d)
        trans = solve_translations(puppet.translations, rot, placed, trans)  # t = P·T   (Feng §6.2)
        d = with_translations(d, trans)
    return d, frame_r, frame_t, (xi, x)


def predict_vertices(puppet, controls, translation_solver=True, skinning=None):
    """The whole run-time prediction in numpy: controls (F, n_c, 3) -> vertices (F, V, 3).

    ``skinning``: None for the puppet's own (``Puppet.skinning``), "dual-quaternion" as Feng §6.3
    (no candy-wrapper collapse), or "linear", the model the skin weights were fitted for (exact on
    LBS data; see ``skinsynth evaluate``). The puppet's correctives (if any) are added to the rest
    pose first; they were fitted for the puppet's own skinning, so under the other one they
    reproduce the examples only approximately."""
    from skinsynth.gpu import dqs_reference, lbs_reference

    skinning = skinning or puppet.skinning
    if skinning not in SKINNING:
        raise OptionError(f"skinning must be one of {', '.join(SKINNING)}")
    d, frame_r, frame_t, (xi, x) = predict_bones(puppet, controls, translation_solver)
    offsets = None if puppet.correctives is None else corrective_offsets(puppet.correctives, xi, x)
    if skinning == "linear":
        rot, trans = dual_quaternion_to_rigid(d)
        placed = lbs_reference(puppet.rest_vertices, puppet.bone_indices, puppet.bone_weights, rot, trans, offsets)
    else:
        placed = dqs_reference(puppet.rest_vertices, puppet.bone_indices, puppet.bone_weights, d, offsets)  # Feng §6.3
    inv_r, inv_t = invert_frames(frame_r, frame_t)
    return apply_frames(inv_r, inv_t, placed)
