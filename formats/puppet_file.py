"""The ``puppet`` stage file written by ``train-kcca``.

Copies forward ``/mesh``, ``/examples``, ``/skin`` and ``/controls`` and adds:

- ``/training``: ``train_frames (n_p,)``, ``test_frames (n_t,)`` int64 (example frames held out),
  ``reference_controls (n_c, 3)`` (rest-frame control positions defining "in place");
  ``@global_motion`` ("control-frame" | "world"), ``@global_motion_reason`` (why, for auto),
  ``@skinning`` ("dual-quaternion" | "linear": the skinning the puppet was trained for and plays
  with; absent in files written before it existed, which are dual-quaternion), ``@clips`` (the
  names of the clips of ``/examples`` trained on, in file order: ``train-kcca --clips``; both
  frame lists hold global frame ids within them, and the other clips' frames are in neither;
  absent in files written before it, which used every clip).
- ``/kcca``: ``predictor (8B, n_p)`` the concatenated M of Feng §6.1 (rows bone-major: bone b
  owns rows 8b..8b+7, its dual quaternion (w, x, y, z, w_e, x_e, y_e, z_e)), ``bias (8B,)``,
  ``training_controls (n_p, 3 n_c)`` standardised, ``control_mean (3 n_c,)``,
  ``correlations (B, n_f)``, ``regularization (B,)``; ``@kernel``, ``@scale``, ``@offset``,
  ``@degree``, ``@bases``, ``@regularization_mode``. At run time ``d = M ξ(x) + bias`` with
  ``x = (c − control_mean) / scale`` and ξ_j = k(x, training_controls[j]).
- ``/poisson`` (when trained with the translation solver): ``rotation_operator (B, B, 3)``,
  ``control_operator (B, n_c)``, ``prior_operator (B, B)``; ``@beta``, ``@prior`` (the relative
  weight γ of the pull towards the regression's translations) and ``@prior_reason``. Translations
  are ``t_b = Σ_b' R_b' Γ[b, b'] + Σ_l Q[b, l] c_l + Σ_b' Π[b, b'] t̂_b'``.
- ``/correctives`` (when the pose-space correctives are on, ``pipeline.correctives``):
  ``weights (n_p, n_p)``, ``offsets (n_p, V, 3)``, with an affine tail also ``tail (n_p, 1 + r)``
  and ``axes (r, 3 n_c)``; ``@ridge``, ``@power``, ``@reason``. Before skinning the rest pose
  becomes ``rest + Σ_j w_j offsets[j]`` with blend weights
  ``w = weights @ ξ^power + tail @ [1, x @ axesᵀ]`` (n_p blend shapes; ξ^power elementwise).
  ``/training/@correctives_reason`` says why they are on or off.
"""

from dataclasses import dataclass

import numpy as np

from .controls_file import read_controls
from .errors import FormatError
from .model import read_model, require
from .skin_file import read_skin
from .validation import check_controls, check_puppet


def puppet_groups(model, puppet, test_frames, regularization_mode, clips=None):
    """All groups of a puppet file: the controls file's groups forwarded, plus the puppet's.
    clips: the names of the clips trained on (``/training/@clips``; None writes no attribute)."""
    bones = puppet.regression.predictor.shape[0]
    groups = {name: model[name] for name in ("mesh", "examples", "skin", "controls")}
    groups["training"] = {"train_frames": puppet.train_frames.astype(np.int64),
                          "test_frames": np.asarray(test_frames, dtype=np.int64),
                          "reference_controls": puppet.reference_controls,
                          "@global_motion": puppet.global_motion,
                          "@global_motion_reason": puppet.global_motion_reason,
                          "@correctives_reason": puppet.correctives_reason,
                          "@skinning": puppet.skinning}
    if clips is not None:
        groups["training"]["@clips"] = [str(name) for name in clips]
    k = puppet.kernel
    groups["kcca"] = {"predictor": puppet.regression.predictor.reshape(bones * 8, -1),
                      "bias": puppet.regression.bias.reshape(-1),
                      "training_controls": puppet.training_controls, "control_mean": k.mean,
                      "correlations": puppet.regression.correlations,
                      "regularization": puppet.regression.regularization,
                      "@kernel": k.kind, "@scale": float(k.scale), "@offset": float(k.offset),
                      "@degree": int(k.degree), "@bases": int(puppet.regression.correlations.shape[1]),
                      "@regularization_mode": str(regularization_mode),
                      "@width_reason": puppet.kernel_width_reason}
    if puppet.translations is not None:
        op = puppet.translations
        groups["poisson"] = {"rotation_operator": op.rotation_operator, "control_operator": op.control_operator,
                             "prior_operator": op.prior_operator, "@beta": float(puppet.beta),
                             "@prior": float(puppet.translation_prior),
                             "@prior_reason": puppet.translation_prior_reason}
    if puppet.correctives is not None:
        c = puppet.correctives
        groups["correctives"] = {"weights": c.weights, "offsets": c.offsets, "@ridge": float(c.ridge),
                                 "@power": float(c.power), "@reason": c.reason}
        if c.tail is not None:
            groups["correctives"].update(tail=c.tail, axes=c.axes)
    return groups


#: train-kcca's options that ``train_puppet`` takes, as recorded in the puppet's provenance.
TRAINING_OPTIONS = ("kernel", "kernel_width", "bases", "regularization", "translation_solver", "beta",
                    "translation_prior", "global_motion", "correctives", "skinning")


def training_options(model):
    """The options train-kcca was given for this puppet ({name: value} for ``train_puppet``),
    from its provenance; options it does not record keep train_puppet's defaults."""
    records = [r for r in model.get("provenance", []) if r.get("stage") == "puppet"]
    parameters = records[-1].get("parameters", {}) if records else {}
    return {name: parameters[name] for name in TRAINING_OPTIONS if name in parameters}


@dataclass
class PuppetRecord:
    """A puppet file's run-time contents as plain arrays and values (``pipeline.puppet``'s
    ``puppet_from_record`` builds the Puppet): the Puppet's fields, with ``kernel`` {kind, mean,
    scale, offset, degree}, ``regression`` {predictor (B, 8, n_p), bias (B, 8), correlations,
    regularization}, ``translations`` {rotation_operator, control_operator, prior_operator} or
    None, and ``correctives`` {weights, offsets, ridge, power, tail, axes, reason} or None;
    ``training_clips``: the clip names trained on (``/training/@clips``; empty in older files:
    every clip); ``marker_labels`` (n_c,) and ``marker_offsets`` (n_c,): the marker layout the
    controls were chosen from (``select-controls --markers``; empty and None without one)."""

    rest_vertices: np.ndarray
    bone_indices: np.ndarray
    bone_weights: np.ndarray
    control_indices: np.ndarray
    reference_controls: np.ndarray
    global_motion: str
    kernel: dict
    training_controls: np.ndarray
    regression: dict
    translations: dict | None
    beta: float
    train_frames: np.ndarray
    global_motion_reason: str
    translation_prior: float
    translation_prior_reason: str
    kernel_width_reason: str
    correctives: dict | None
    correctives_reason: str
    skinning: str = "dual-quaternion"
    training_clips: tuple = ()
    marker_labels: tuple = ()
    marker_offsets: np.ndarray | None = None


def read_puppet(path, with_options=False):
    """(PuppetRecord, test_frames (n_t,), skin: SkinModel) from a puppet file, and with
    ``with_options`` also train-kcca's options (:func:`training_options`); FormatError if not one."""
    model = read_model(path, stages=("puppet",))
    skin = read_skin(path, model)
    controls = read_controls(path, model)
    training = require(model, path, "training", ("train_frames", "test_frames", "reference_controls"))
    kcca = require(model, path, "kcca", ("predictor", "bias", "training_controls", "control_mean",
                                         "correlations", "regularization"))
    dims = {"F": skin.rotations.shape[0], "B": skin.bones, "V": skin.rest_vertices.shape[0]}
    check_controls(path, model, dims)
    check_puppet(path, model, dims)
    bones = skin.bones
    if kcca["predictor"].shape[0] != 8 * bones:
        raise FormatError(path, f"/kcca/predictor has {kcca['predictor'].shape[0]} rows, expected 8 × {bones} bones")
    kernel = dict(kind=str(kcca["@kernel"]), mean=kcca["control_mean"], scale=float(kcca["@scale"]),
                  offset=float(kcca["@offset"]), degree=int(kcca["@degree"]))
    regression = dict(predictor=kcca["predictor"].reshape(bones, 8, -1), bias=kcca["bias"].reshape(bones, 8),
                      correlations=kcca["correlations"], regularization=kcca["regularization"])
    operator, beta, prior, prior_reason = None, float("nan"), float("nan"), ""
    if "poisson" in model:
        pois = require(model, path, "poisson", ("rotation_operator", "control_operator", "prior_operator"))
        operator = dict(rotation_operator=pois["rotation_operator"], control_operator=pois["control_operator"],
                        prior_operator=pois["prior_operator"])
        beta = float(pois.get("@beta", np.nan))
        prior, prior_reason = float(pois.get("@prior", np.nan)), str(pois.get("@prior_reason", ""))
    correctives = None
    if "correctives" in model:
        group = require(model, path, "correctives", ("weights", "offsets"))
        if ("tail" in group) != ("axes" in group):
            raise FormatError(path, "/correctives has one of tail and axes without the other")
        correctives = dict(weights=group["weights"], offsets=group["offsets"], ridge=float(group["@ridge"]),
                           power=float(group.get("@power", 1.0)), tail=group.get("tail"), axes=group.get("axes"),
                           reason=str(group.get("@reason", "")))
    puppet = PuppetRecord(rest_vertices=skin.rest_vertices, bone_indices=skin.bone_indices,
                          bone_weights=skin.bone_weights, control_indices=np.asarray(controls.vertex_indices),
                          reference_controls=training["reference_controls"],
                          global_motion=str(training.get("@global_motion", "control-frame")), kernel=kernel,
                          training_controls=kcca["training_controls"], regression=regression, translations=operator,
                          beta=beta, train_frames=training["train_frames"],
                          global_motion_reason=str(training.get("@global_motion_reason", "")),
                          translation_prior=prior, translation_prior_reason=prior_reason,
                          kernel_width_reason=str(kcca.get("@width_reason", "")), correctives=correctives,
                          correctives_reason=str(training.get("@correctives_reason", "")),
                          skinning=_skinning(path, training),
                          training_clips=tuple(str(name) for name in np.atleast_1d(training.get("@clips", []))),
                          marker_labels=controls.marker_labels, marker_offsets=controls.marker_offsets)
    if with_options:
        return puppet, training["test_frames"], skin, training_options(model)
    return puppet, training["test_frames"], skin


def _skinning(path, training):
    """The skinning a puppet was trained for: ``/training/@skinning``, "dual-quaternion" where a
    file written before the attribute existed has none; FormatError for any other value."""
    skinning = str(training.get("@skinning", "dual-quaternion"))
    if skinning not in ("dual-quaternion", "linear"):
        raise FormatError(path, f"/training/@skinning is {skinning!r}; expected dual-quaternion or linear")
    return skinning
