"""``skinsynth train-kcca``: learn how the control points drive every bone (Feng §4–5)."""

import time

import click
import numpy as np

from skinsynth.formats.output_file import check_output_path
from skinsynth.pipeline.errors import OptionError

from .options import FINITE_FLOAT
from .common import command_line, report, summary_options, tool_version, user_errors


@click.command("train-kcca")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Puppet file to write (.h5).")
@click.option("--kernel", default="gaussian", show_default=True,
              help="Kernel on the control side: gaussian, polynomial ((xᵀy + c)^5) or linear.")
@click.option("--kernel-width", default="auto", show_default=True,
              help="Gaussian width as a multiple of the training controls' spread σ, or 'auto' (0.5σ…8σ by "
                   "cross-validation on the training frames, printed).")
@click.option("--bases", default=8, show_default=True, type=int, help="Kernel-CCA bases per bone (n_f; at most 8).")
@click.option("--regularization", default="auto", show_default=True,
              help="κ relative to the mean kernel eigenvalue, or 'auto' (per bone, by cross-validation on the training frames).")
@click.option("--translation-solver/--no-translation-solver", default=True, show_default=True,
              help="Recompute bone translations by the Poisson solve of Feng §5.")
@click.option("--beta", default=100.0, show_default=True, type=FINITE_FLOAT, help="Weight of the control-point constraints in the Poisson solve.")
@click.option("--translation-prior", default="auto", show_default=True,
              help="Pull of the Poisson solve towards the regression's own translations, relative to its mean "
                   "diagonal: 1e-6 is Feng's plain solve, 100 about the regression's translations; 'auto' "
                   "picks from 1e-6…100 by cross-validation on the training frames (printed).")
@click.option("--train-frames", default="every:4", show_default=True,
              help="Example frames to train on: every:N, first:N, all (each within every clip, from its first "
                   "frame), or a list of global frames like 0,4,10-20; the clips' other frames are held out.")
@click.option("--clips", "clip_list", default=None, metavar="A,B,...",
              help="Train on these clips only (names as fit-skin stored them; inspect lists them); the other "
                   "clips' frames are neither trained on nor held out  [default: every clip].")
@click.option("--global-motion", type=click.Choice(["auto", "control-frame", "world"]), default="auto", show_default=True,
              help="control-frame: train and run in a rigid frame fitted to the control points (for travelling "
                   "or turning examples); world: use positions as they are; auto: control-frame when the "
                   "examples move as a whole and the controls fix a frame well, else world (the choice is printed).")
@click.option("--correctives", default="auto", show_default=True,
              help="Pose-space correctives: what skinning misses at each example, kept in the rest pose and "
                   "interpolated over the controls (n_p blend shapes). A ridge relative to the kernel's mean "
                   "diagonal, 'off', or 'auto' (1e-6…1 or off, by cross-validation on the training frames; printed).")
@click.option("--skinning", type=click.Choice(["linear", "dual-quaternion"]), default="linear", show_default=True,
              help="The skinning the puppet is trained for and plays with: dual quaternions (Feng §6.3), or linear "
                   "blend skinning, which glTF, game engines and Blender play (needed for play -o X.glb and bone "
                   "textures). The cross-validated choices and the correctives are fitted for it.")
@summary_options
@user_errors
def train_kcca(path, output, kernel, kernel_width, bases, regularization, translation_solver, beta, translation_prior, train_frames,
               global_motion, correctives, skinning, clip_list, quiet, as_json):
    """Train the puppet: per-bone kernel CCA from control points to bone dual quaternions.

    PATH is a controls file from select-controls. The examples are brought in place by a rigid
    frame fitted to the control points (--global-motion), each bone's dual quaternion is
    regressed on the kernelised control vector (Feng §4), and the Poisson translation operator
    (Feng §5, eq. 10–11) is precomputed so that run-time translations are one matrix product.
    What the skinned prediction still misses at the examples is learnt as pose-space correctives
    (--correctives; Park and Hodgins 2006, cited by Feng §2).

    A file of several clips (fit-skin CLIP...) trains on every clip, or on --clips; --train-frames
    samples within each clip, and the clips trained on are recorded (/training/@clips).

    \b
    Examples:
      skinsynth train-kcca horse.controls.h5 -o horse.puppet.h5
      skinsynth train-kcca face.controls.h5 -o face.puppet.h5 --kernel polynomial --train-frames every:10
      skinsynth train-kcca horse.controls.h5 -o horse.puppet.h5 --clips gallop
    """
    from skinsynth.formats.controls_file import read_controls
    from skinsynth.formats.model import read_model, write_model
    from skinsynth.formats.provenance import provenance_record
    from skinsynth.formats.puppet_file import puppet_groups
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.inputs.clips import Clips
    from skinsynth.pipeline.puppet import clip_training_frames, train_puppet, training_summary

    check_output_path(output, (".h5", ".hdf5"), inputs=[path])
    regularization, kernel_width, translation_prior, correctives = _numbers(kernel, regularization, kernel_width,
                                                                            translation_prior, correctives)
    model = read_model(path, stages=("controls",))
    skin = read_skin(path, model)
    controls = read_controls(path, model)
    clips = Clips(skin.clip_names, skin.clip_frames)
    train, test, used = clip_training_frames(train_frames, clips, clip_list, "--clips")

    started = time.perf_counter()
    puppet = train_puppet(skin.examples, skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights,
                          skin.rotations, skin.translations, np.asarray(controls.vertex_indices), train,
                          kernel=kernel, bases=bases, regularization=regularization,
                          translation_solver=translation_solver, beta=beta, global_motion=global_motion,
                          translation_prior=translation_prior, kernel_width=kernel_width, correctives=correctives,
                          skinning=skinning)
    seconds = time.perf_counter() - started
    parameters = dict(kernel=kernel, bases=bases, regularization=regularization, translation_solver=translation_solver,
                      beta=beta, translation_prior=translation_prior, train_frames=train_frames,
                      global_motion=global_motion, kernel_width=kernel_width, correctives=correctives,
                      skinning=skinning, clips=list(used))
    record = provenance_record("puppet", command_line(), parameters, [path], tool_version())
    write_model(output, "puppet", puppet_groups(model, puppet, test, "auto" if regularization == "auto" else "fixed",
                                               clips=used),
                model["provenance"] + [record], tool_version())
    report(*training_summary(output, puppet, skin.bones, train, test, clips, used, seconds), as_json, quiet)


def _numbers(kernel, regularization, kernel_width, translation_prior, correctives):
    """--regularization, --kernel-width, --translation-prior and --correctives as numbers, or
    'auto' (and 'off', --correctives); OptionError for a value out of range, or an unknown --kernel."""
    from skinsynth.pipeline.puppet import KERNELS

    if kernel not in KERNELS:
        raise OptionError(f"--kernel {kernel!r} does not exist; choose one of {', '.join(KERNELS)}")
    regularization = _number_or_auto("--regularization", regularization, "a positive finite number", low_open=True)
    kernel_width = _number_or_auto("--kernel-width", kernel_width, "a positive finite number", low_open=True)
    translation_prior = _number_or_auto("--translation-prior", translation_prior, "a finite number ≥ 0")
    if correctives != "off":
        correctives = _number_or_auto("--correctives", correctives, "a positive finite ridge, 'auto' or 'off'",
                                      low_open=True)
    return regularization, kernel_width, translation_prior, correctives


def _number_or_auto(option, value, what, low_open=False):
    """'auto', or the option's value as a finite number ≥ 0 (> 0 when ``low_open``); OptionError otherwise."""
    if value == "auto":
        return value
    try:
        number = float(value)
    except ValueError:
        raise OptionError(f"{option} must be a number or 'auto' (got {value!r})") from None
    if not (0.0 < number if low_open else 0.0 <= number) or not number < np.inf:
        raise OptionError(f"{option} must be {what} (got {number})")
    return number
