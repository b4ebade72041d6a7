"""The ``skinsynth`` command: one click group, one module per subcommand."""

import contextlib
import functools
import os
import signal
import sys
import threading
import warnings

import click

from . import common
from .example import example
from .export import export
from .fit_skin import fit_skin
from .inspect_file import inspect_file
from .select_controls import select_controls
from .train_kcca import train_kcca
from .evaluate import evaluate
from .build_graph import build_graph
from .play import play
from .precompile import precompile
from .preview import preview
from .synthesize import synthesize
from .view import view


@contextlib.contextmanager
def _warnings_policy():
    """A command's stderr is its progress and, on failure, one error line: library warnings
    (numpy overflow on a hostile input, deprecations) are not shown, since every result is checked
    finite before it is written and every input is validated. SKINSYNTH_WARNINGS=1, or Python's own
    -W / PYTHONWARNINGS, keeps Python's filters (the test suite turns every warning into an error)."""
    if os.environ.get("SKINSYNTH_WARNINGS") or sys.warnoptions:
        yield
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


class _Stopped(Exception):
    """A KeyboardInterrupt (Ctrl-C, or SIGTERM/SIGHUP turned into one) carried past click, which
    would print a blank line before turning it into Abort."""

    def __init__(self, stop):
        super().__init__()
        self.stop = stop


class SkinsynthGroup(click.Group):
    """A click group whose usage errors are one line on stderr (exit 2), like every other user error."""

    def invoke(self, ctx):
        try:
            with _warnings_policy():
                return super().invoke(ctx)
        except KeyboardInterrupt as stop:
            raise _Stopped(stop) from None

    def main(self, args=None, prog_name=None, **extra):
        args = list(sys.argv[1:] if args is None else args)
        common.guard_standard_streams()
        common.INVOCATION[:] = ["skinsynth"] + [str(a) for a in args]
        from skinsynth.formats.atomic import RECEIVED, WRITTEN, quiet_interruptions, raise_interrupted

        WRITTEN.clear()  # what this command writes (several run in one process under tests)
        RECEIVED.clear()
        if threading.current_thread() is threading.main_thread():
            # SIGINT too: Python's own handler raises a KeyboardInterrupt that leaves no record
            # when a library swallows it; ours records the signal (formats.atomic.RECEIVED)
            for name in ("SIGINT", "SIGTERM", "SIGHUP"):
                if hasattr(signal, name) and signal.getsignal(getattr(signal, name)) is not signal.SIG_IGN:
                    signal.signal(getattr(signal, name), raise_interrupted)
            if not getattr(sys.unraisablehook, "quiet_interruptions", False):  # once, over whatever hook was set
                sys.unraisablehook = functools.partial(quiet_interruptions, default=sys.unraisablehook)
                sys.unraisablehook.quiet_interruptions = True
        try:
            return super().main(args, prog_name=prog_name or "skinsynth", standalone_mode=False, **extra)
        except click.exceptions.Exit as done:  # --help, --version
            sys.exit(done.exit_code)
        except _Stopped as stopped:
            common.interrupted(stopped.stop)
        except click.exceptions.Abort as abort:  # click turns a KeyboardInterrupt (ours carry the signal) into Abort
            cause = abort.__cause__ or abort.__context__
            common.interrupted(cause if isinstance(cause, KeyboardInterrupt) else KeyboardInterrupt())
        except KeyboardInterrupt as stop:  # a signal outside a command's own handling
            common.interrupted(stop)
        except click.ClickException as error:
            ctx = getattr(error, "ctx", None)
            hint = f" (see '{ctx.command_path} --help')" if isinstance(error, click.UsageError) and ctx else ""
            click.echo(f"skinsynth: error: {error.format_message()}{hint}", err=True)
            sys.exit(error.exit_code)


@click.group(cls=SkinsynthGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(common.tool_version(), prog_name="skinsynth")
def main():
    """Example-based mesh animation: skinning, puppetry and one-to-many synthesis.

    Stages read and write self-contained HDF5 model files, so they chain like Makefile rules:

    \b
      skinsynth example bending-bar -o bar.npz --frames 96 --cycles 2
      skinsynth fit-skin bar.npz -o skin.h5 --bones 8
      skinsynth export skin.h5 -o skin.usdc --as skel
      skinsynth select-controls skin.h5 -o controls.h5
      skinsynth train-kcca controls.h5 -o puppet.h5
      skinsynth evaluate puppet.h5 --plot errors.png
      skinsynth play puppet.h5 --controls bar.npz --instances 16 -o crowd.usdc
      skinsynth build-graph skin.h5 -o graph.h5 --plot plots
      skinsynth synthesize graph.h5 -o bones.h5 --count 100 --frames 600 --crowd synth.usdc
      skinsynth inspect graph.h5
    """


main.add_command(fit_skin)
main.add_command(inspect_file)
main.add_command(export)
main.add_command(example)
main.add_command(select_controls)
main.add_command(train_kcca)
main.add_command(evaluate)
main.add_command(play)
main.add_command(build_graph)
main.add_command(synthesize)
main.add_command(preview)
main.add_command(view)
main.add_command(precompile)
