"""Option groups shared by the commands (as COLMAP's option groups): each option is declared once
here, with its type, default and check; a command passes only its own help text, which says what
the option means for that command."""

import math

import click

from skinsynth.pipeline.errors import OptionError


class _Finite:
    """A click number type that also refuses nan and ±inf (nan passes every comparison of a range)."""

    def convert(self, value, param, ctx):
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        return number


class FiniteFloat(_Finite, click.types.FloatParamType):
    """The type of every number option of the commands (a test checks none takes click's float)."""


class FiniteFloatRange(_Finite, click.FloatRange):
    """click's FloatRange, finite."""


#: The type of a number option without a range.
FINITE_FLOAT = FiniteFloat()


def up_axis_option(help):
    """``--up-axis Y|Z`` (default None: the input's, as each command says); y and z are accepted too."""
    return click.option("--up-axis", metavar="[Y|Z]", default=None, callback=_up_axis, help=help)


def _up_axis(ctx, param, value):
    """--up-axis in either case, as "Y" or "Z"."""
    if value is None:
        return None
    if value.upper() not in ("Y", "Z"):
        raise click.BadParameter(f"{value!r} is not one of 'Y', 'Z'.")
    return value.upper()


def bone_count(ctx, param, value):
    """``--bones N`` (an integer) or ``--bones auto`` (the string "auto"); None when left out."""
    if value is None or value == "auto":
        return value
    try:
        return int(value)
    except ValueError:
        raise click.BadParameter(f"{value!r} is neither a whole number nor 'auto'.") from None


def device_option(help, default="auto"):
    """``--device auto|cpu|cuda|cuda:N`` (``skinsynth.gpu.resolve_device`` checks it)."""
    return click.option("--device", default=default, show_default=True, help=help)


def texture_options(half_help, width_help):
    """``--half`` and ``--max-width`` for vertex-animation textures (:func:`check_max_width`)."""
    def decorate(command):
        command = click.option("--max-width", default=8192, show_default=True, type=int, help=width_help)(command)
        return click.option("--half", is_flag=True, help=half_help)(command)
    return decorate


def check_max_width(max_width):
    """OptionError unless ``--max-width`` is a usable texture width."""
    if max_width < 1:
        raise OptionError(f"--max-width must be at least 1 (got {max_width})")


def marker_take_options(command):
    """What carries a motion-capture take (C3D) over to a puppet's controls
    (``pipeline.puppet.markers``; read by ``cli.marker_take.take_controls``)."""
    from skinsynth.cli.marker_take import TAKE_DEFAULTS
    from skinsynth.formats.c3d import MARKER_UNITS

    options = [
        click.option("--markers", "marker_layout", default=None, type=click.Path(dir_okay=False),
                     help="C3D controls: the marker layout (JSON {LABEL: vertex | [x, y, z]}, docs/mocap.md) "
                          "tying the take's labels to the puppet's control vertices  [default: the layout "
                          "select-controls --markers stored in the puppet]"),
        click.option("--marker-units", default=None, type=click.Choice(list(MARKER_UNITS)),
                     help="C3D: the take's length unit instead of its POINT:UNITS."),
        click.option("--take-up-axis", default="Z", show_default=True, type=click.Choice(["X", "Y", "Z"]),
                     help="C3D: the take's up axis (Vicon, Qualisys: Z; OptiTrack exports: Y)."),
        click.option("--fps", default=None, type=FINITE_FLOAT,
                     help="C3D: frames per second the take is resampled to and the output plays at  "
                          "[default: the puppet's]"),
        click.option("--neutral-frame", default=None, type=int,
                     help="C3D: the take frame (0-based) posed as the puppet's rest pose, where the take is aligned "
                          "(over the frames around it where the pose is held) [default: the one nearest it seeing "
                          "every marker the take has]"),
        click.option("--retarget", default="delta", show_default=True, type=click.Choice(["delta", "absolute"]),
                     help="C3D: delta moves each control by its marker's displacement from the neutral frame (a "
                          "performer of other proportions keeps the character's shape); absolute puts the "
                          "controls on the aligned markers."),
        click.option("--stabilize", default=None, metavar="A,B,C",
                     help="C3D: remove each frame's rigid motion of these markers (3 or more, e.g. a face's head "
                          "markers) from every marker."),
        click.option("--max-gap", default=TAKE_DEFAULTS["max_gap"], type=int, metavar="FRAMES",
                     help="C3D: gaps of at most this many take frames are bridged in time (a smoothing spline "
                          "through the samples around them); longer ones are filled from the other markers "
                          "through the puppet's training poses  [default: 0.3 s of the take's frames]"),
        click.option("--min-markers", default=None, type=int,
                     help="C3D: a frame seeing fewer markers is held from the last good one  [default: half the "
                          "take's markers, at least 3]"),
        click.option("--filter", "cutoff", default=TAKE_DEFAULTS["cutoff"], show_default=True,
                     metavar="HZ|auto|none",
                     help="C3D: the markers' low-pass cut-off (zero-phase Butterworth, docs/mocap.md): auto chooses "
                          "it from the take (the one leaving its samples nearest the motion; reported), or none (the "
                          "take raw, its neutral frame as measured)."),
        click.option("--allow-missing", is_flag=True,
                     help="C3D: play a take lacking some of the layout's markers (each frame filled from the others)."),
    ]
    for option in reversed(options):
        command = option(command)
    return command


def animation_selection(text):
    """``--animation N`` or ``A:B`` (animations A to B−1, as ``preview --frames``; either end may be
    left out) -> (first, stop), None for a left-out end."""
    first, sep, last = text.partition(":")
    try:
        if not sep:
            return (int(first), int(first) + 1)
        return (int(first) if first else None, int(last) if last else None)
    except ValueError:
        raise click.BadParameter(f"{text!r}: expected N or A:B, e.g. 7 or 0:10") from None


def chosen_animations(selections, count, path, what="animation", once=True):
    """The indices ``selections`` [(first, stop)] (:func:`animation_selection`) name among ``count``,
    in the order given, each once (``once=False``: as often as named, preview's panels); all of them
    when none is given. OptionError for one out of range (``path`` holds ``what``s 0..count − 1)."""
    from skinsynth.pipeline.errors import OptionError

    if not selections:
        return list(range(count))
    chosen = []
    for first, last in selections:
        start = 0 if first is None else first
        stop = count if last is None else last
        if not (0 <= start < count and start < stop <= count):
            given = f"{first}" if last == (first or 0) + 1 and first is not None else \
                f"{'' if first is None else first}:{'' if last is None else last}"
            raise OptionError(f"--animation {given}: {path} holds {what}s 0..{count - 1}")
        chosen += [a for a in range(start, stop) if not once or a not in chosen]
    return chosen
