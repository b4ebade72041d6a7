"""``skinsynth evaluate``: held-out error of a puppet against Feng's baselines."""

import json

import click

from .common import summary_options, check_output_path, fail, user_errors

METHODS = {
    "kcca": "kernel CCA + Poisson translation solver",
    "kcca_no_translation_solver": "kernel CCA, predicted translations",
    "pca_blendshape": "PCA blendshapes, weights by least squares",
    "rbf": "direct RBF regression",
    "kcca_on_joints": "kernel CCA, bones put back on the skeleton's joints (play's rig of a jointed skin)",
}


@click.command("evaluate")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("--plot", type=click.Path(dir_okay=False), default=None, help="Write per-frame error curves to this PNG.")
@click.option("--skinning", type=click.Choice(["dual-quaternion", "linear"]), default=None,
              help="Skinning of the predicted bones: dual quaternions (Feng §6.3) or linear (the fitted model).  "
                   "[default: the one the puppet was trained for (train-kcca --skinning)]")
@click.option("--pca-components", type=int, default=None,
              help="Blendshape count of the PCA baseline (default: leave-one-out cross-validation on the training frames).")
@click.option("--extrapolate", type=float, default=None, metavar="FRACTION",
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
    train on; errors are RMS vertex distances with the largest side of the rest bounding box
    scaled to 1 (as Feng §7 reports). The global-motion mode of the puppet is used for all.
    --extrapolate and --hold-out-clip add harder tests, each with a puppet retrained on frames
    that never include the tested ones.

    \b
    Examples:
      skinsynth evaluate horse.puppet.h5
      skinsynth evaluate horse.puppet.h5 --json --plot horse_errors.png
      skinsynth evaluate horse.puppet.h5 --hold-out-clip collapse
    """
    from skinsynth.formats.puppet_file import read_puppet
    from skinsynth.pipeline.puppet import puppet_from_record
    from skinsynth.pipeline.inputs.clips import Clips
    from skinsynth.pipeline.puppet import (clip_hold_out_split, evaluate_clip_hold_out, evaluate_extrapolation,
                                           evaluate_puppet, extrapolation_split)

    if plot is not None:
        check_output_path(plot, (".png",), inputs=[path])
    record, test_frames, skin, options = read_puppet(path, with_options=True)
    options.setdefault("skinning", record.skinning)  # a file from before the option: its own
    puppet = puppet_from_record(record)
    if len(test_frames) == 0:
        fail(f"{path}: no held-out frames (trained with --train-frames covering every example); "
             "retrain leaving some out, e.g. --train-frames every:4")
    split = None if extrapolate is None else extrapolation_split(skin.examples.shape[0], extrapolate)
    clips = Clips(skin.clip_names, skin.clip_frames)
    if hold_out_clips:  # a bad name fails before any work
        clip_hold_out_split(clips, hold_out_clips, record.training_clips)
    skeleton = None if skin.skeleton is None else tuple(skin.skeleton[k] for k in ("parents", "jointed", "joints"))
    result = evaluate_puppet(puppet, skin.examples, test_frames, skinning=skinning, pca_components=pca_components,
                             skeleton=skeleton)
    skinning = result.notes["skinning"]
    beyond = None
    if split is not None:
        beyond = evaluate_extrapolation(skin, puppet.control_indices, options, *split, skinning, pca_components)
    unseen = None
    if hold_out_clips:
        unseen = evaluate_clip_hold_out(skin, puppet.control_indices, options, clips, hold_out_clips,
                                        record.training_clips, skinning, pca_components)
    if plot is not None:
        from skinsynth.formats.plots import write_error_plot

        write_error_plot(plot, result.test_frames, result.per_frame,
                         title=f"{path}: held-out error ({result.notes['global_motion']}, {skinning} skinning)",
                         ylabel="RMS vertex error / largest bounding-box side")
    if as_json:
        payload = dict(result.overall)
        payload.update(test_frames=[int(f) for f in result.test_frames], train_frames=[int(f) for f in puppet.train_frames],
                       per_frame={k: [float(e) for e in v] for k, v in result.per_frame.items()},
                       clips=list(record.training_clips or clips.names), **result.notes)
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
        click.echo(json.dumps(payload, sort_keys=True))
        return
    if quiet:
        return
    click.echo(f"{path}: {len(result.test_frames)} held-out frames, {len(puppet.train_frames)} training; "
               f"global motion: {result.notes['global_motion']} ({result.notes['global_motion_reason']}); "
               f"{skinning} skinning; "
               f"kernel {result.notes['kernel']}; PCA baseline with {result.notes['pca_components']} blendshapes"
               + (f"; translation prior {result.notes['translation_prior']:g}"
                  if result.notes["translation_prior"] is not None else "")
               + f"; correctives: {result.notes['correctives'] or 'off'}"
               + (f"; clips {', '.join(record.training_clips or clips.names)}" if len(clips) > 1 else ""))
    _table(result)
    if "joint_projection_cost" in result.notes:
        click.echo(f"  the skeleton's joints: play's rig puts the predicted bones back on them, which moves the "
                   f"prediction by {result.notes['joint_projection_cost']:.5f} (RMS, same scale)")
    if beyond is not None:
        click.echo(f"extrapolation: trained on frames 0..{beyond.notes['train_frames'] - 1}, tested on the "
                   f"{len(beyond.test_frames)} after")
        _table(beyond)
    if unseen is not None:
        click.echo(f"clip hold-out: trained on {', '.join(unseen.notes['train_clips'])} "
                   f"({len(unseen.notes['train_frames'])} frames), tested on {', '.join(unseen.notes['test_clips'])} "
                   f"({len(unseen.test_frames)} frames); global motion {unseen.notes['global_motion']}, "
                   f"PCA baseline with {unseen.notes['pca_components']} blendshapes")
        _table(unseen)
    if plot is not None:
        click.echo(f"wrote {plot}")


def _table(result):
    best = min(result.overall, key=result.overall.get)
    for name, label in METHODS.items():
        if name not in result.overall:  # kcca_on_joints: only for a skin with a skeleton
            continue
        if name == "kcca" and not result.notes["translation_solver"]:
            label += " (trained without the solver: same as below)"
        mark = "  <- lowest" if name == best else ""
        click.echo(f"  {name:<28} {result.overall[name]:.5f}  {label}{mark}")
