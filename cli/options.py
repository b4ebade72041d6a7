"""Option groups shared by the commands (as COLMAP's option groups): each option is declared once
here, with its type, default and check; a command passes only its own help text, which says what
the option means for that command."""

import click

from skinsynth.pipeline.errors import OptionError


def up_axis_option(help):
    """``--up-axis Y|Z`` (default None: the input's, as each command says)."""
    return click.option("--up-axis", type=click.Choice(["Y", "Z"]), default=None, help=help)


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
