"""Folder outputs (a VAT folder, ``--usd`` caches, ``--plot`` PNGs): written whole, and never at
the cost of a file skinsynth did not write.

A folder output is written into a temporary folder beside the target, given a manifest
(:data:`MANIFEST`: every file's size and sha256) and swapped in only once complete, so a Make
rule whose target is the folder sees it whole or not at all.

**What may be replaced.** An existing target is replaced only when it is empty, or when skinsynth
wrote it and nothing in it changed since: its manifest lists every file it holds, each with the
same size and sha256 (folders written before manifests existed: a VAT folder holding exactly
the files its ``vat.json`` names). Refused before any work, with one line and nothing touched:

- a folder holding anything else (a user's ``notes.txt``, a subfolder, a changed file);
- the working folder or a folder above it (``-o ./``), the file system's root, the home folder;
- a folder that holds an input of the command, or that holds (or lies inside) another output of
  the same command (``synthesize -o shot/bones.h5 --exr shot/``).

A symbolic link to a folder is followed: the folder it points to is written, the link stays.

**The swap.** The new folder takes the old one's place in one step where the system allows
(Linux ``renameat2(RENAME_EXCHANGE)``), else the old one is renamed aside first and the new one
in next, so there is no moment with neither. SIGINT, SIGTERM and SIGHUP are held back during the
swap and the removal of the old folder, then end the command (the new folder complete in
place). Temporary folders left by a process killed outright are removed by the next write of the
same folder, once that process is gone.
"""

import contextlib
import errno
import json
import os
import shutil
import tempfile

from .atomic import WRITTEN, Interrupted, _out_of_space, _sweep_stale, _umask, held_signals, stop_if_received
from .errors import FormatError
from .provenance import file_sha256

#: The manifest every folder output carries: ``{"format", "format_version", "files": {name:
#: {"bytes", "sha256"}}}``. Hidden, so engines importing the folder pass it over.
MANIFEST = ".skinsynth-folder.json"
MANIFEST_FORMAT = "skinsynth folder"
MANIFEST_VERSION = 1


def _real(path):
    return os.path.realpath(os.path.abspath(path))


def _located(path):
    """Where the entry ``path`` itself lives (its folder resolved, its own name kept: a symbolic
    link placed in a folder is in that folder, wherever it points)."""
    path = os.path.abspath(path).rstrip(os.sep) or os.sep
    return os.path.join(_real(os.path.dirname(path)), os.path.basename(path))


def _within(path, folder):
    """Whether ``path`` is ``folder`` or lies inside it (both absolute, resolved)."""
    return path == folder or path.startswith(folder.rstrip(os.sep) + os.sep)


def folder_target(path):
    """The folder a folder output ``path`` writes: ``path`` without its trailing separator, a
    symbolic link followed (FormatError for a link to nothing or to a file)."""
    text = os.fspath(path)
    bare = text.rstrip(os.sep) or (os.sep if text.startswith(os.sep) else ".")
    if os.path.islink(bare):
        target = _real(bare)
        if not os.path.isdir(target):
            raise FormatError(path, f"is a symbolic link to {target}, which is not a folder")
        return target
    return os.path.abspath(bare)


def check_folder_output(path, inputs=(), outputs=()):
    """Refuse, with a FormatError naming ``path``, a folder output that could cost the user a
    file (see the module's rules), or that cannot be written; returns the folder to write.

    ``inputs``: the command's input files; ``outputs``: its other outputs (files or folders)."""
    target = folder_target(path)
    real = _real(target)
    if os.path.exists(target) and not os.path.isdir(target):
        raise FormatError(path, "is a file; a folder output is written here")
    if real == os.sep:
        raise FormatError(path, "is the file system's root; give a folder of its own for the output")
    for what, place in (("the working folder", os.getcwd()), ("your home folder", os.path.expanduser("~"))):
        if _within(_real(place), real):
            where = "is" if _real(place) == real else "holds"
            raise FormatError(path, f"{where} {what}; a folder output replaces the whole folder: give a folder of "
                                    "its own (a new or empty one); nothing was touched")
    for source in inputs:
        if source is not None and any(_within(p, real) for p in {_real(source), _located(source)}):
            raise FormatError(path, f"holds {source}, an input of this command; a folder output replaces the whole "
                                    "folder: give a folder of its own; nothing was touched")
    for other in outputs:
        if other is None:
            continue
        other_real = _located(folder_target(other) if str(other).endswith(os.sep) else other)
        if _within(other_real, real) or _within(real, other_real):
            relation = "is" if other_real == real else ("holds" if _within(other_real, real) else "lies inside")
            raise FormatError(path, f"{relation} {other}, another output of this command; give each folder output "
                                    "a folder of its own")
    if os.path.isdir(target):
        unowned = unowned_entries(target)
        if unowned:
            raise FormatError(path, _unowned_message(unowned))
    writable = os.path.dirname(target)  # where the swap renames, or the nearest folder that exists above it
    while not os.path.exists(writable):
        writable = os.path.dirname(writable)
    if not os.access(writable, os.W_OK | os.X_OK):
        raise FormatError(path, f"cannot write here: {writable} is not writable")
    return target


class FolderOutputs:
    """A command's folder outputs, each refused before any work when it could cost the user a
    file: one that holds anything skinsynth did not write, the working folder, or a folder that
    holds an input or another output of the command (:func:`check_folder_output`).

    ``inputs``: the input files; ``outputs``: every output (files and folders, None where not
    asked for). :meth:`guard` gives the writer of one folder (:func:`atomic_folder`) what it must
    check again at its swap."""

    def __init__(self, inputs, outputs):
        self.inputs = [str(p) for p in inputs if p is not None]
        self.outputs = [str(p) for p in outputs if p is not None]

    def check(self, folder):
        """Check ``folder`` (one of the outputs) now; returns it."""
        if folder is not None:
            check_folder_output(folder, **self.guard(folder))
        return folder

    def guard(self, folder):
        """``inputs`` and ``outputs`` (the others) for ``folder``'s writer."""
        index = self.outputs.index(str(folder))
        return {"inputs": self.inputs, "outputs": self.outputs[:index] + self.outputs[index + 1:]}


def _unowned_message(unowned):
    name, why = unowned[0]
    more = f" (and {len(unowned) - 1} more)" if len(unowned) > 1 else ""
    return (f"holds {name}{more}, {why}; a folder output replaces only a folder skinsynth wrote: give a new or "
            "empty folder, or remove this one yourself; nothing was touched")


def _regular(path):
    """Whether ``path`` is a regular file itself (not a link, a folder or a device)."""
    import stat

    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def unowned_entries(folder):
    """[(name, why)] of what in ``folder`` skinsynth did not write, or changed since it did; []
    when the folder may be replaced (empty, or wholly skinsynth's)."""
    names = sorted(os.listdir(folder))
    if not names:
        return []
    if MANIFEST in names:
        listed = _manifest_files(os.path.join(folder, MANIFEST))
        if listed is None:
            return [(MANIFEST, "a manifest skinsynth cannot read")]
        unowned = []
        for name in names:
            if name == MANIFEST:
                continue
            path = os.path.join(folder, name)
            entry = listed.get(name)
            if entry is None or not _regular(path):
                unowned.append((name, "which skinsynth did not write"))
            elif os.path.getsize(path) != entry.get("bytes") or file_sha256(path) != entry.get("sha256"):
                unowned.append((name, "changed since skinsynth wrote it"))
        return unowned
    expected = _legacy_vat_files(folder) if "vat.json" in names else None
    if expected is None:
        return [(name, "which skinsynth did not write") for name in names]
    return [(name, "which skinsynth did not write") for name in names
            if name not in expected or not _regular(os.path.join(folder, name))]


def _manifest_files(path):
    """The manifest's ``files`` mapping, or None when it is not a skinsynth manifest."""
    try:
        with open(path) as handle:
            manifest = json.load(handle)
    except (OSError, ValueError):
        return None
    if not isinstance(manifest, dict) or manifest.get("format") != MANIFEST_FORMAT \
            or not isinstance(manifest.get("files"), dict):
        return None
    return {name: entry for name, entry in manifest["files"].items() if isinstance(entry, dict)}


def _legacy_vat_files(folder):
    """The names a VAT folder written before manifests holds (its ``vat.json`` says), or None
    when its ``vat.json`` is not skinsynth's."""
    try:
        with open(os.path.join(folder, "vat.json")) as handle:
            sidecar = json.load(handle)
        if not str(sidecar.get("format", "")).startswith("skinsynth vertex animation texture"):
            return None
        names = {"vat.json", sidecar["rest_mesh"]["obj"], sidecar["rest_mesh"]["glb"]}
        for animation in sidecar["animations"]:
            names.update((animation["offsets"], animation["normals"]))
        return {str(name) for name in names}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


def write_manifest(folder):
    """Write :data:`MANIFEST` in ``folder``, listing every file in it (size and sha256)."""
    files = {}
    for name in sorted(os.listdir(folder)):
        path = os.path.join(folder, name)
        if name != MANIFEST and _regular(path):
            files[name] = {"bytes": os.path.getsize(path), "sha256": file_sha256(path)}
    with open(os.path.join(folder, MANIFEST), "w") as handle:
        json.dump({"format": MANIFEST_FORMAT, "format_version": MANIFEST_VERSION, "files": files}, handle,
                  indent=1, sort_keys=True)
        handle.write("\n")


def _exchange(first, second):
    """Swap two existing paths in one step (Linux renameat2 with RENAME_EXCHANGE); False where
    the system or the file system cannot."""
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if renameat2(at_fdcwd, os.fsencode(first), at_fdcwd, os.fsencode(second), rename_exchange) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EPERM):
        return False
    raise OSError(code, os.strerror(code), second)


def _swap_in(tmp, target):
    """Put the folder ``tmp`` at ``target``; the old ``target`` (if any) ends at a temporary
    name, which is returned for removal (None when there was none)."""
    if not os.path.isdir(target):
        os.rename(tmp, target)
        return None
    if _exchange(tmp, target):
        return tmp
    aside = tmp[: -len(".tmp")] + ".old.tmp"
    os.rename(target, aside)
    try:
        os.rename(tmp, target)
    except BaseException:
        os.rename(aside, target)
        raise
    return aside


def _made_parents(target):
    """Create the missing folders above ``target``; returns those made, deepest first."""
    made, parent = [], os.path.dirname(target)
    while not os.path.isdir(parent):
        made.append(parent)
        parent = os.path.dirname(parent)
    for folder in reversed(made):
        os.mkdir(folder)
    return made


@contextlib.contextmanager
def atomic_folder(path, inputs=(), outputs=()):
    """Yield a temporary folder beside ``path``'s folder; on success it gets its manifest and
    replaces ``path`` (see the module's rules, checked before and again at the swap). On any
    exception the temporary folder (and any parent folder made for it) is removed and ``path``
    is not touched."""
    target = check_folder_output(path, inputs, outputs)
    made = _made_parents(target)
    parent, base = os.path.dirname(target), os.path.basename(target)
    prefix = f".{base}."
    _sweep_stale(parent, prefix, ".tmp")
    tmp, mark = None, len(WRITTEN)
    try:
        with held_signals() as creating:  # a signal as the folder is made must not leave it behind
            try:
                tmp = tempfile.mkdtemp(prefix=f"{prefix}{os.getpid()}.", suffix=".tmp", dir=parent)
            except OSError as error:
                raise FormatError(path, f"cannot write here: {error.strerror}") from None
            os.chmod(tmp, 0o777 & ~_umask())
        if creating:  # nothing written yet: stop now
            raise Interrupted(creating[0])
        yield tmp
        stop_if_received()
        write_manifest(tmp)
        unowned = unowned_entries(target) if os.path.isdir(target) else []  # changed while this command worked
        if unowned:
            raise FormatError(path, _unowned_message(unowned))
        with held_signals() as pending:
            old = _swap_in(tmp, target)
            if old is not None:
                shutil.rmtree(old, ignore_errors=True)
    except BaseException as error:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        for folder in made:
            with contextlib.suppress(OSError):
                os.rmdir(folder)
        if _out_of_space(error):  # named by the user's folder, not a file in the temporary one
            raise FormatError(path, f"no space left on the device of {parent}; nothing written") from None
        raise
    finally:
        del WRITTEN[mark:]  # the files inside the temporary folder: the folder is what counts
    WRITTEN.append(os.fspath(path))
    if pending:  # arrived during the swap: the folder is complete and in place; stop now
        raise Interrupted(pending[0])
