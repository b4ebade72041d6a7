"""Atomic output: write beside the target, rename into place only once complete.

An interrupted or failed command therefore never leaves a partial or corrupt file, and a
failed overwrite leaves the old file intact.
"""

import contextlib
import os
import tempfile

from .errors import FormatError


@contextlib.contextmanager
def atomic_output(path):
    """Yield a temporary path in the target's folder with the target's suffix.

    The suffix is kept because USD and OpenEXR choose their encoding from the extension.
    On success the temporary file is fsynced and renamed onto ``path``; on any exception it
    is removed and the exception propagates.
    """
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    base = os.path.basename(path)
    stem, dot, ext = base.rpartition(".")
    suffix = "." + ext if dot else ""
    if not os.path.isdir(folder):
        raise FormatError(path, f"cannot write here: the folder {folder} does not exist")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{stem or base}.", suffix=".tmp" + suffix, dir=folder)
    except OSError as error:
        raise FormatError(path, f"cannot write here: {error.strerror}") from None
    os.close(fd)
    # mkstemp makes the file private (0600); give it the permissions a plain open() would.
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    try:
        yield tmp
        with open(tmp, "rb+") as handle:
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.remove(tmp)
        raise
