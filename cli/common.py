"""What every command shares: user-error handling, exit codes, progress, provenance."""

import functools
import os
import sys
from importlib.metadata import PackageNotFoundError, version

import click

from skinsynth.formats.errors import FormatError
from skinsynth.pipeline.errors import OptionError

EXIT_USER_ERROR = 2
#: The command line as the user typed it (set by the group's main), for provenance records.
INVOCATION = []


def tool_version():
    try:
        return version("skinsynth")
    except PackageNotFoundError:  # running from a source tree without an install
        return "0+unknown"


def fail(message):
    """Print one error line on stderr and exit with status 2."""
    click.echo(f"skinsynth: error: {message}", err=True)
    sys.exit(EXIT_USER_ERROR)


def user_errors(command):
    """Turn the errors a user can cause into one stderr line and exit 2 (never a traceback)."""
    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        from skinsynth.gpu import DeviceError

        try:
            return command(*args, **kwargs)
        except (FormatError, OptionError, DeviceError) as error:
            fail(str(error))
        except MemoryError:
            fail("out of memory: the input is too large for this machine at these settings")
        except KeyboardInterrupt:
            click.echo("skinsynth: interrupted; no output written", err=True)
            sys.exit(130)
    return wrapper


def check_output_path(path, suffixes):
    """Refuse an output path whose extension this command cannot write, before any work."""
    lower = str(path).lower()
    if not any(lower.endswith(s) for s in suffixes):
        fail(f"{path}: output must end in {', '.join(suffixes)}")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        fail(f"{path}: cannot write here: the folder {folder} does not exist")


def command_line():
    import shlex

    return shlex.join(INVOCATION or ["skinsynth"] + sys.argv[1:])


class Progress:
    """A click progress bar on stderr that shows the latest figure, or nothing when quiet.

    The bar appears on the first update, so an error raised before any work is done is still
    the only line on stderr.
    """

    def __init__(self, length, label, quiet=False):
        self.length, self.label, self.quiet = length, label, quiet
        self.bar = None

    def __enter__(self):
        return self

    def update(self, steps, text=None):
        if self.quiet:
            return
        if self.bar is None:
            self.bar = click.progressbar(length=self.length, label=self.label, file=sys.stderr, show_pos=True,
                                         item_show_func=lambda x: x)
            self.bar.__enter__()
        self.bar.update(steps, text)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.__exit__(*exc)
