"""File outputs (a model file, a USD cache, a plot, a sequence): refused before any work when the
command cannot write them (their suffix, their folder) or when writing one would replace an input.
Folder outputs have their own rules (:mod:`.output_folder`); every write is atomic (:mod:`.atomic`)."""

import os

from .errors import FormatError


def check_output_path(path, suffixes, inputs=()):
    """Refuse (FormatError naming ``path``), before any work, an output path whose extension the
    command cannot write (``suffixes``), whose folder is missing or not writable, or that is one
    of ``inputs`` (:func:`check_not_an_input`)."""
    lower = str(path).lower()
    if not any(lower.endswith(s) for s in suffixes):
        raise FormatError(path, f"output must end in {', '.join(suffixes)}")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise FormatError(path, f"cannot write here: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise FormatError(path, f"cannot write here: the folder {folder} is not writable")
    check_not_an_input(path, inputs)


def check_not_an_input(path, inputs):
    """Refuse an output that is one of the input files: the same file by device and inode, so
    another name, a hard link or a symbolic link to an input is caught too."""
    try:
        target = os.stat(path)
    except OSError:
        return  # not there yet: it cannot be an input
    for source in inputs:
        try:
            found = os.stat(source)
        except OSError:
            continue
        if (found.st_dev, found.st_ino) == (target.st_dev, target.st_ino):
            raise FormatError(path, f"the output is the input {source}; write the result to another file")
