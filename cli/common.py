"""What every command shares: user-error handling, exit codes, progress, provenance."""

import errno
import functools
import io
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
    """Turn the errors a user can cause into one stderr line and exit 2 (never a traceback). What
    the input clip cannot give (``ClipError``) is said of the command's input, its ``path``."""
    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        from skinsynth.formats.atomic import stop_if_received
        from skinsynth.gpu import DeviceError
        from skinsynth.pipeline.errors import ClipError

        try:
            result = command(*args, **kwargs)
            stop_if_received()  # a signal whose exception a library swallowed still ends the command
            sys.stdout.flush()  # a full disk or a closed pipe on stdout shows here, not at exit
            return result
        except KeyboardInterrupt as stop:
            interrupted(stop)
        except Exception as error:
            stop = signalled()
            if stop is not None:  # the signal surfaced as another exception: it is what ended the command
                interrupted(stop)
            if isinstance(error, ClipError):
                fail(f"{kwargs['path']}: {error}" if kwargs.get("path") else str(error))
            if isinstance(error, (FormatError, OptionError, DeviceError)):
                fail(str(error))
            if isinstance(error, MemoryError):
                fail("out of memory: the input is too large for this machine at these settings")
            if isinstance(error, OSError):
                _release_stdout()
                fail(os_error_message(error))
            raise
    return wrapper


def signalled():
    """The first signal this command received (:data:`skinsynth.formats.atomic.RECEIVED`) as the
    KeyboardInterrupt :func:`interrupted` takes, or None. A signal can surface as another
    exception than its own: one that lands while Python initialises a C extension (a lazy
    ``import scipy.spatial``) comes out as ``ImportError: initialization failed``, the signal's
    exception its cause; the command then ends as interrupted, in one line, not with a traceback."""
    from skinsynth.formats.atomic import RECEIVED

    if not RECEIVED:
        return None
    stop = KeyboardInterrupt(RECEIVED[0])
    stop.signum = RECEIVED[0]
    return stop


def os_error_message(error):
    """One line for an operating-system error: the file (or stdout) and what the system said."""
    if isinstance(error, BrokenPipeError) or error.errno == errno.EPIPE:
        return "stdout: the reading end of the pipe closed before the output was written"
    # a rename names the destination (the user's path) second, the temporary first
    where = next((name for name in (error.filename2, error.filename) if name is not None), "stdout")
    return f"{where}: {error.strerror or error}"


def _release_stdout():
    """After an error, let nothing more fail on stdout: what is still buffered for a full disk
    or a closed pipe would fail again at exit, with a traceback; send it to the null device."""
    try:
        sys.stdout.flush()
    except OSError:
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass


def interrupted(stop):
    """Exit after a signal: say which and what was written (only files complete in place)."""
    import signal

    from skinsynth.formats.atomic import WRITTEN

    number = getattr(stop, "signum", signal.SIGINT)
    name = signal.Signals(number).name
    done = f"wrote only {', '.join(WRITTEN)}" if WRITTEN else "no output written"
    click.echo(f"skinsynth: interrupted ({name}); {done}", err=True)
    sys.exit(128 + number)


class _ClosedStream(io.TextIOBase):
    """sys.stdout for a command started with stdout closed (``>&-``): writing to it is the
    OSError a closed pipe gives, so it ends as one line naming stdout (``-q`` writes nothing)."""

    encoding = "utf-8"

    def writable(self):
        return True

    def write(self, text):
        raise OSError(errno.EBADF, "closed (the command was started with stdout closed, as by >&-): the report "
                                   "cannot be written; use -q to write none")


def guard_standard_streams():
    """Open the null device on any of file descriptors 0–2 the command was started without, so
    that no file the command opens takes their number (a library writing to fd 1 or 2 would
    write into it); a closed stdout then fails on the first write (:class:`_ClosedStream`)."""
    for fd, mode in ((0, os.O_RDONLY), (1, os.O_WRONLY), (2, os.O_WRONLY)):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, mode)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
            if fd == 1:
                sys.stdout = _ClosedStream()
            elif fd == 2:
                sys.stderr = open(fd, "w", closefd=False)


def summary_options(command):
    """``--json`` and ``--quiet``, meaning the same on every command."""
    command = click.option("--quiet", "-q", is_flag=True,
                           help="No progress bar and no summary (warnings still go to stderr).")(command)
    return click.option("--json", "as_json", is_flag=True,
                        help="Print the summary as one JSON object on stdout, and nothing else there.")(command)


def report(summary, lines, as_json=False, quiet=False):
    """A command's summary: ``summary`` as one JSON object (``--json``), else the text ``lines``
    unless ``--quiet``. Numpy scalars and arrays become JSON numbers and lists."""
    import json

    if as_json:
        click.echo(json.dumps(summary, sort_keys=True, default=_jsonable))
    elif not quiet:
        for line in lines:
            click.echo(line)


def _jsonable(value):
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


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

    def restart(self, length, label):
        """Finish the bar shown (if any); the next update shows another, of ``length`` steps: a
        command's next phase."""
        self.__exit__(None, None, None)
        self.length, self.label, self.bar = length, label, None

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
