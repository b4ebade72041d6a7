"""``skinsynth evaluate``: held-out error of a puppet against Feng's baselines."""

import click

from skinsynth.formats.output_file import check_output_path

from .options import FINITE_FLOAT
from .common import fail, report, summary_options, user_errors


@click.command("evaluate")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("--plot", type=click.Path(dir_okay=False), default=None, help="Write per-frame error curves to this PNG.")
@click.option("--skinning", type=click.Choice(["dual-quaternion", "linear"]), default=None,
              help="Skinning of the predicted bones: dual quaternions (Feng §6.3) or linear (the fitted model).  "
                   "[default: the one the puppet was trained for (train-kcca --skinning)]")
@click.option("--pca-components", type=int, default=None,
              help="Blendshape count of the PCA baseline (default: leave-one-out cross-validation on the training frames).")
@click.option("--extrapolate", type=FINITE_FLOAT, default=None, metavar="FRACTION",
              help="Also retrain the puppet (train-kcca's own options) on the first FRACTION of the frames, e.g. "
                   "0.6, and report every method on the rest: poses never seen, not between examples.")
@click.option("--hold-out-clip", "hold_out_clips", multiple=True, metavar="NAME",
              help="Also retrain the puppet (train-kcca's own options) on every frame of the other clips it trained "
                   "on and report every method on this clip's frames: a take never seen. Repeatable, or A,B.")
@summary_options
@user_errors
def evaluate(path, as_json, quiet, plot, skinning, pca_components, extrapolate, hold_out_clips):
    """Compare the puppet with PCA blendshapes and RBF regression on the held-out example frames.

    Each method is driven by the control vertices' positions in the frames the puppet did not
    train on; errors are RMS vertex distances over the rest pose's bounding-box diagonal, as every
    error skinsynth reports (Feng §7 reports over the box's largest side: multiply by the diagonal
    over it to compare). The global-motion mode of the puppet is used for all.
    --extrapolate and --hold-out-clip add harder tests, each with a puppet retrained on frames
    that never include the tested ones.

    \b
    Examples:
      skinsynth evaluate horse.puppet.h5
      skinsynth evaluate horse.puppet.h5 --json --plot horse_errors.png
      skinsynth evaluate horse.puppet.h5 --hold-out-clip collapse
    """
    from skinsynth.formats.puppet_file import read_puppet
    from skinsynth.pipeline.inputs.clips import Clips
    from skinsynth.pipeline.puppet import evaluate_hold_outs, evaluation_report, puppet_from_record

    if plot is not None:
        check_output_path(plot, (".png",), inputs=[path])
    record, test_frames, skin, options = read_puppet(path, with_options=True)
    options.setdefault("skinning", record.skinning)  # a file from before the option: its own
    puppet = puppet_from_record(record)
    if len(test_frames) == 0:
        fail(f"{path}: no held-out frames (trained with --train-frames covering every example); "
             "retrain leaving some out, e.g. --train-frames every:4")
    clips = Clips(skin.clip_names, skin.clip_frames)
    result, beyond, unseen = evaluate_hold_outs(puppet, skin, test_frames, options, clips, record.training_clips,
                                                skinning, pca_components, extrapolate, hold_out_clips)
    if plot is not None:
        from skinsynth.formats.plots import write_error_plot

        write_error_plot(plot, result.test_frames, result.per_frame,
                         title=f"{path}: held-out error ({result.notes['global_motion']}, "
                               f"{result.notes['skinning']} skinning)",
                         ylabel="RMS vertex error / rest bounding-box diagonal")
    report(*evaluation_report(path, result, puppet.train_frames, clips, record.training_clips, beyond, unseen, plot),
           as_json, quiet)
