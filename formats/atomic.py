"""Atomic output: write beside the target, rename into place only once complete.

An interrupted or failed command therefore never leaves a partial or corrupt file, and a
failed overwrite leaves the old file intact.

Signals: while a file is being written (in the main thread), SIGINT, SIGTERM and SIGHUP are held
back rather than raised wherever the interpreter happens to be (inside HDF5's C callbacks a
KeyboardInterrupt was reported as "Exception ignored" and lost, so an interrupted command
finished with status 0). Once the writer is done, a held-back signal abandons the file: the
temporary is removed, the old file stays, and :class:`Interrupted` is raised. So a file is either
complete and in place or not touched, and :data:`WRITTEN` lists the ones that were. Outside a
write the command's handler, :func:`raise_interrupted`, raises :class:`Interrupted` at once, and
:func:`quiet_interruptions` records one Python cannot raise (in a finaliser) instead of printing it.
"""

import contextlib
import os
import signal
import sys
import tempfile
import threading

from .errors import FormatError

#: The outputs this process has renamed into place, in order (what an interruption leaves).
WRITTEN = []
_HELD = tuple(s for s in (getattr(signal, n, None) for n in ("SIGINT", "SIGTERM", "SIGHUP")) if s is not None)


#: The signals that have raised :class:`Interrupted` in this command, in order. Libraries may
#: swallow the exception (trimesh wraps its optional imports and some of its code in ``except
#: BaseException``), so outputs and the command's end check here too (:func:`stop_if_received`).
RECEIVED = []


class Interrupted(KeyboardInterrupt):
    """A signal (SIGINT, SIGTERM, SIGHUP) stopped the command; ``signum`` says which."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = int(signum)
        RECEIVED.append(self.signum)


def stop_if_received():
    """Raise :class:`Interrupted` again for a signal that arrived earlier, in case the exception
    it raised then was swallowed on its way out."""
    if RECEIVED:
        raise Interrupted(RECEIVED[0])


def raise_interrupted(signum, frame):
    """Signal handler: SIGINT, SIGTERM and SIGHUP end the command alike (outputs cleaned up), each
    recorded (:data:`RECEIVED`) in case a library swallows the exception."""
    raise Interrupted(signum)


def quiet_interruptions(unraisable, default=sys.__unraisablehook__):
    """``sys.unraisablehook``: a signal's :class:`Interrupted` raised where Python cannot raise it
    (a weakref callback, a ``__del__``) is recorded and stops the command at its next check
    (:func:`stop_if_received`), so Python's "Exception ignored in …" traceback would only be noise
    on stderr. Once a signal has been received the command is ending, and what a finaliser then
    fails on is the signal's doing too (an llvmlite object the signal left half closed raises
    ``AttributeError`` when collected at exit), so it is quiet as well; before any signal,
    anything else goes to the default hook."""
    if not isinstance(unraisable.exc_value, Interrupted) and not RECEIVED:
        default(unraisable)


@contextlib.contextmanager
def held_signals():
    """Hold SIGINT, SIGTERM and SIGHUP back inside the block (main thread only; elsewhere
    nothing changes); yields the list of the signal numbers that arrived meanwhile."""
    pending = []
    if threading.current_thread() is not threading.main_thread():
        yield pending
        return
    previous = {}
    for number in _HELD:
        handler = signal.getsignal(number)
        if handler is signal.SIG_IGN or handler is None:
            continue
        previous[number] = handler
        signal.signal(number, lambda signum, frame: pending.append(signum))
    try:
        yield pending
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def _sweep_stale(folder, prefix, suffix):
    """Remove ``prefix<pid>.*<suffix>`` temporaries (files, or folders of a folder output) of
    processes that no longer exist."""
    try:
        names = os.listdir(folder)
    except OSError:
        return
    for name in names:
        if not (name.startswith(prefix) and name.endswith(suffix)):
            continue
        pid = name[len(prefix):].split(".", 1)[0]
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            os.kill(int(pid), 0)
            continue  # its writer is still running
        except ProcessLookupError:
            pass
        except OSError:  # e.g. another user's process: leave it
            continue
        path = os.path.join(folder, name)
        if os.path.isdir(path) and not os.path.islink(path):
            import shutil

            shutil.rmtree(path, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                os.remove(path)


def _out_of_space(error):
    """Whether an exception from a writer means the disk (or quota) is full: an OSError with
    ENOSPC/EDQUOT, or a library error quoting it (h5py reports HDF5's write failures so)."""
    import errno

    if isinstance(error, OSError) and error.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)):
        return True
    text = str(error).lower()  # also this module's own FormatError, met again by an enclosing folder
    return "no space left on" in text or "disk quota exceeded" in text


def _megabytes(count):
    return f"{count / 2 ** 20:.1f} MB"


@contextlib.contextmanager
def atomic_output(path, expected_bytes=0, interruptible=False):
    """Yield a temporary path in the target's folder with the target's suffix.

    The suffix is kept because USD and OpenEXR choose their encoding from the extension.
    On success the temporary file is fsynced and renamed onto ``path``; on any exception it
    is removed and the exception propagates. The temporary's name holds the writer's process
    id: one left by a writer killed outright (SIGKILL, a power cut) is removed by the next write
    of the same file once that process is gone.

    Space: ``expected_bytes`` (the writer's estimate, an upper bound) is checked against the
    free space first, because HDF5 does not fail cleanly on a full disk (it crashed the process
    and left the temporary); a full disk met anyway is one FormatError line.

    Signals: SIGINT, SIGTERM and SIGHUP are held back while the body writes (a library stopped
    inside a C call may leave its file or its state broken) and acted on once the file is in
    place or abandoned. ``interruptible`` writers (pure Python, or a child process they stop
    themselves, like a long video encode) are stopped at once instead; the rename is held back
    either way.
    """
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    base = os.path.basename(path)
    stem, dot, ext = base.rpartition(".")
    suffix = "." + ext if dot else ""
    if not os.path.isdir(folder):
        raise FormatError(path, f"cannot write here: the folder {folder} does not exist")
    prefix = f".{stem or base}."
    _sweep_stale(folder, prefix, ".tmp" + suffix)
    if expected_bytes:
        import shutil

        free = shutil.disk_usage(folder).free
        if free < expected_bytes:
            raise FormatError(path, f"not enough space: about {_megabytes(expected_bytes)} needed, "
                                    f"{_megabytes(free)} free in {folder}; nothing written")
    tmp = None
    with (contextlib.nullcontext([]) if interruptible else held_signals()) as pending:
        try:
            with held_signals() as creating:  # a signal as the temporary is made must not leave it behind
                try:
                    fd, tmp = tempfile.mkstemp(prefix=f"{prefix}{os.getpid()}.", suffix=".tmp" + suffix,
                                               dir=folder)
                except OSError as error:
                    raise FormatError(path, f"cannot write here: {error.strerror}") from None
                os.close(fd)
                # mkstemp makes the file private (0600); give it the permissions a plain open() would.
                os.chmod(tmp, 0o666 & ~_umask())
            if creating:  # nothing written yet: stop now
                raise Interrupted(creating[0])
            yield tmp
            if pending:  # stopped while writing: abandon the file, keep the old one
                raise Interrupted(pending[0])
            stop_if_received()
            with held_signals() as renaming:
                with open(tmp, "rb+") as handle:
                    os.fsync(handle.fileno())
                os.replace(tmp, path)
                WRITTEN.append(path)
            pending += renaming
        except BaseException as error:
            if tmp is not None:
                with contextlib.suppress(FileNotFoundError):
                    os.remove(tmp)
            if _out_of_space(error):
                raise FormatError(path, f"no space left on the device of {folder}; nothing written") from None
            raise
    if pending:  # arrived during the rename: the file is complete; stop now
        raise Interrupted(pending[0])


def _umask():
    """The process's umask (reading it means setting it, so it is set straight back)."""
    umask = os.umask(0)
    os.umask(umask)
    return umask
