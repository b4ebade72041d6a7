"""``skinsynth preview``: look at any animation without a DCC: .mp4, .gif or a .png contact sheet."""

import os
import time

import click
import numpy as np

from skinsynth.formats.output_file import check_output_path
from skinsynth.pipeline.runtime.resources import check_memory

from .common import Progress, report, summary_options, user_errors
from .options import FINITE_FLOAT, animation_selection, chosen_animations, up_axis_option

MESH_SUFFIXES = (".npz", ".usd", ".usda", ".usdc")
#: Frame rates a video may play at: a GIF holds at most 655 s per frame, players show at most 240.
PLAYABLE_FPS = (0.1, 240.0)


def _size(text):
    try:
        width, height = (int(v) for v in text.lower().split("x"))
        if width < 16 or height < 16 or width > 8192 or height > 8192:
            raise ValueError
        return width, height
    except ValueError:
        raise click.BadParameter(f"{text!r}: expected WIDTHxHEIGHT, e.g. 640x480 (16 to 8192 each)") from None


def _frame_range(text):
    first, sep, last = text.partition(":")
    try:
        if not sep:
            raise ValueError
        return (int(first) if first else None, int(last) if last else None)
    except ValueError:
        raise click.BadParameter(f"{text!r}: expected A:B (either may be left out), e.g. 0:48") from None


@click.command("preview")
@click.argument("path", type=click.Path())
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Video (.mp4, H.264), animated .gif, or a .png contact sheet of evenly spaced frames.")
@click.option("--animation", "animations", multiple=True, type=animation_selection, metavar="N|A:B",
              help="Synthesis file: the animation to show (repeatable, or A:B for A to B−1: several in a grid).  "
                   "[default: 0]")
@click.option("--clip", default=None, metavar="NAME",
              help="A file with a skin's examples (skin, controls, puppet, graph) that holds several clips: show this "
                   "clip only (--frames then counts its own frames).  [default: every frame; each is named "
                   "CLIP:FRAME, e.g. collapse:12, when the file holds several clips]")
@click.option("--examples", is_flag=True, help="Skin file: show the input frames instead of the fitted reconstruction.")
@click.option("--compare", is_flag=True,
              help="Skin file: the input and the reconstruction side by side, the reconstruction coloured by each "
                   "vertex's error (red at --error-scale).")
@click.option("--error-scale", default=0.01, show_default=True, type=FINITE_FLOAT,
              help="Error shown full red, as a fraction of the rest pose's bounding-box diagonal (--compare, puppets).")
@click.option("--size", default="640x480", show_default=True, type=_size, metavar="WxH", help="Size of each panel.")
@click.option("--fps", default=None, type=FINITE_FLOAT,
              help="Frames per second of the video, 0.1 to 240.  [default: the file's]")
@click.option("--frames", "frame_range", default=None, type=_frame_range, metavar="A:B",
              help="Only frames A to B−1 (Python slice; either end may be left out).")
@click.option("--camera", type=click.Choice(["three-quarter", "front", "side"]), default="three-quarter",
              show_default=True, help="Where the camera stands, looking at the character.")
@click.option("--framing", type=click.Choice(["auto", "follow", "fixed"]), default="auto", show_default=True,
              help="fixed: one camera frames the whole animation (a crowd's characters, standing apart, each their "
                   "own, all as far away); follow: it tracks each character's ground position, smoothed; auto: "
                   "follow a character that travels more than its own size.")
@click.option("--flat", is_flag=True, help="Flat shading (one normal per face) instead of smooth.")
@up_axis_option("Up axis.  [default: the file's (USD, skinsynth files), else Y]")
@click.option("--sheet-frames", default=12, show_default=True, type=click.IntRange(min=1),
              help=".png: frames on the contact sheet (4 per row).")
@summary_options
@user_errors
def preview(path, output, animations, clip, examples, compare, error_scale, size, fps, frame_range, camera, framing,
            flat, up_axis, sheet_frames, as_json, quiet):
    """Render the animation a file holds, headless (no display, no OpenGL).

    PATH: an input sequence (a folder or glob of OBJ/PLY/OFF frames, .npz, .h5, USD); a skin file
    (its reconstruction; --examples the input; --compare both, the error as colour); a puppet
    (its held-out frames: prediction next to truth, the error as colour); a play output (.h5,
    USD; every character in a grid); a synthesis file (--animation N, seams marked in red: where
    a component's input frame does not play on from the one before, a jump into another clip
    included). Each frame names its source frame in the corner (CLIP:FRAME when the file holds
    several clips).

    \b
    Examples:
      skinsynth preview horse.skin.h5 -o horse_fit.mp4 --compare
      skinsynth preview horse.skin.h5 -o collapse.mp4 --clip collapse
      skinsynth preview herd.h5 -o herd.gif --animation 0 --animation 1 --animation 2 --animation 3
      skinsynth preview puppet.h5 -o puppet.png --camera front
    """
    from skinsynth.formats.video import SUFFIXES, sheet_indices, write_frames
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.view import Preview, preview_summary

    check_output_path(output, SUFFIXES, inputs=[path])
    low, high = PLAYABLE_FPS
    if fps is not None and not low <= fps <= high:
        raise OptionError(f"--fps must lie in [{low:g}, {high:g}] (got {fps:g}): slower is a still, faster than "
                          "players show")
    if not error_scale > 0:
        raise OptionError(f"--error-scale must be positive (got {error_scale})")
    panels, file_fps, file_up = _panels(path, list(animations), clip, examples, compare, error_scale)
    up = "XYZ".index(up_axis or file_up)
    count = min(p.vertices.shape[0] for p in panels)
    frames = np.arange(count)[slice(*frame_range)] if frame_range else np.arange(count)
    if frames.size == 0:
        raise OptionError(f"--frames {frame_range[0]}:{frame_range[1]} selects none of the {count} frames")
    if output.lower().endswith(".png"):
        frames = frames[sheet_indices(len(frames), sheet_frames)]
    elif fps is None and not low <= file_fps <= high:
        raise OptionError(f"{path}: its frame rate {file_fps:g} lies outside [{low:g}, {high:g}]: give --fps")
    _check_memory(output, len(panels), size, len(frames))
    movie = Preview(panels, size=size, frames=frames, preset=camera, smooth=not flat, up_axis=up, framing=framing,
                    fps=fps or file_fps)
    started = time.perf_counter()
    with Progress(len(movie), "preview", quiet or as_json) as bar:
        def rendered():
            for n, image in enumerate(movie):
                bar.update(1, f"frame {int(movie.frames[n])}")
                yield image

        write_frames(output, rendered(), len(movie), fps or file_fps, sheet_columns=max(1, 4 // len(panels)))
    summary, lines = preview_summary(output, len(movie), len(panels), size, time.perf_counter() - started,
                                     fps or file_fps, movie.follow)
    report(summary, lines, as_json, quiet)


def _check_memory(output, panels, size, frames):
    """Refuse, before any is made, what ``frames`` frames of ``panels`` panels of ``size`` need: an
    RGB image per frame of the panel grid, all held for a .gif or a contact sheet (twice:
    quantised, or the sheet, which PIL copies again at 4 bytes a pixel to save it), and the
    rasteriser's float buffers per pixel, against the memory the process may have (its ulimit and
    cgroup included)."""
    pixels = panels * size[0] * size[1]
    lower = output.lower()
    per_frame = 3 + 3 + 4 if lower.endswith(".png") else 3 + 3 if lower.endswith(".gif") else 0
    check_memory(pixels * (per_frame * frames + 3 + 48),
                 f"{frames} frame(s) of {panels} panel(s) at {size[0]}×{size[1]}")


def _panels(path, animations, clip, examples, compare, error_scale):
    """(panels, fps, up axis "Y"/"Z") for whatever animation ``path`` holds (``clip``: one clip
    of a skin's examples, or None for every frame)."""
    from skinsynth.formats.errors import FormatError
    from skinsynth.formats.meshseq import read_mesh_sequence, read_played_characters
    from skinsynth.formats.model import read_header
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.view import Panel

    lower = str(path).lower()
    if (examples or compare) and not lower.endswith((".h5", ".hdf5")):
        raise OptionError("--examples and --compare apply to skin files")
    if lower.endswith((".h5", ".hdf5")) and os.path.isfile(path):
        try:
            stage, _ = read_header(path)
        except FormatError:
            stage = None  # not a skinsynth model file: a sequence or played characters
        if stage is not None:
            return _model_panels(path, stage, animations, clip, examples, compare, error_scale)
        _no_clips(path, clip)
        names, vertices, faces, fps = read_played_characters(path)
        return [Panel(v, faces, name if len(names) > 1 else "") for name, v in zip(names, vertices)], fps, "Y"
    if animations:
        raise OptionError("--animation applies to synthesis files")
    _no_clips(path, clip)
    if lower.endswith((".usd", ".usda", ".usdc")) and os.path.isfile(path):
        from skinsynth.formats.usd import animated_mesh_paths, read_skel_animation

        meshes = animated_mesh_paths(path)
        if not meshes:  # no time-sampled mesh: a UsdSkel rig, skinned by UsdSkel itself
            characters, fps, up = read_skel_animation(path)
            return ([Panel(v, faces, name.rsplit("/", 2)[-2] if len(characters) > 1 else "")
                     for name, v, faces in characters[:16]], fps, up)
        panels, sequence = [], None
        for mesh in meshes[:16]:  # a crowd: every character (at most 16) in a grid
            sequence = read_mesh_sequence(path, prim=mesh)
            panels.append(Panel(sequence.vertices, sequence.faces, mesh.rsplit("/", 1)[-1] if len(meshes) > 1 else ""))
        return panels, sequence.fps, sequence.scene.up_axis
    sequence = read_mesh_sequence(path)
    return [Panel(sequence.vertices, sequence.faces, "")], sequence.fps, sequence.scene.up_axis


def _no_clips(path, clip, what="holds no skin's examples"):
    """Refuse --clip for a file that has no clips to choose from."""
    from skinsynth.pipeline.errors import OptionError

    if clip is not None:
        raise OptionError(f"--clip {clip}: chooses a clip of a skin's examples (skin, controls, puppet, graph "
                          f"files), and {path} {what}")


def _clips_of(skin):
    from skinsynth.pipeline.inputs.clips import Clips

    return Clips(skin.clip_names, skin.clip_frames)


def _model_panels(path, stage, animations, clip, examples, compare, error_scale):
    from skinsynth.formats.model import read_model
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.view import skin_panels

    if animations and stage != "synthesis":
        raise OptionError("--animation applies to synthesis files")
    if (examples or compare) and stage not in ("skin", "controls", "graph"):
        raise OptionError("--examples and --compare apply to skin files")
    if stage == "synthesis":
        _no_clips(path, clip, "is a synthesis file, whose animations --animation chooses")
    if stage == "puppet":
        return _puppet_panels(path, clip, error_scale)
    # only the skin: a synthesis's motions are read one animation at a time below
    skin = read_skin(path, read_model(path, groups=("mesh", "examples", "skin")))
    panels = _synthesis_panels(path, skin, animations or [(0, 1)]) if stage == "synthesis" else \
        skin_panels(skin, clip, examples, compare, error_scale)
    return panels, skin.fps, skin.scene.up_axis


def _puppet_panels(path, clip, error_scale):
    from skinsynth.formats.puppet_file import read_puppet
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.puppet import predict_vertices, puppet_from_record
    from skinsynth.pipeline.view import compared_panels, frame_captions

    record, test_frames, skin = read_puppet(path)
    puppet = puppet_from_record(record)
    if len(test_frames) == 0:
        raise OptionError(f"{path}: the puppet has no held-out frames to show (train with --train-frames)")
    clips = _clips_of(skin)
    if clip is not None:
        chosen = clips.index(clip, "--clip")
        test_frames = np.asarray(test_frames)[clips.clip_of(test_frames) == chosen]
        if len(test_frames) == 0:
            raise OptionError(f"--clip {clip}: none of the puppet's held-out frames is in clip {clip!r}")
    truth = skin.examples[test_frames]
    predicted = predict_vertices(puppet, truth[:, puppet.control_indices])
    return compared_panels(truth, predicted, skin.faces, "truth", "puppet", error_scale, skin.rest_vertices,
                           frame_captions(clips, test_frames, "held-out frame")), skin.fps, skin.scene.up_axis


def _synthesis_panels(path, skin, animations):
    from skinsynth.formats.errors import require_finite
    from skinsynth.formats.synthesis_file import open_motions, read_sources, synthesis_count
    from skinsynth.gpu import lbs_reference
    from skinsynth.pipeline.view import Panel, walk_captions

    clips = _clips_of(skin)
    count = synthesis_count(path)
    animations = chosen_animations(animations, count, path, once=False)
    chosen = read_sources(path, animations)  # (C, len(animations), M): the shown animations' only
    panels = []
    with open_motions(path) as (F, t):
        for n, a in enumerate(animations):
            rotations, translations = F[a], t[a]
            require_finite(path, f"/synthesis animation {a}'s bone motions", rotations)  # a damaged shard
            require_finite(path, f"/synthesis animation {a}'s bone motions", translations)
            vertices = lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, rotations, translations)
            captions, seams = walk_captions(clips, chosen[:, n])  # chosen[:, n]: (C, M)
            panels.append(Panel(vertices, skin.faces, f"animation {a}", captions=captions, marked=seams))
    return panels
