"""Alembic (``.abc``) and FBX (``.fbx``) mesh animations read through Blender (issue 67).

No maintained Python package reads Alembic, and the FBX readers most used outside Autodesk's are
Blender's; so skinsynth asks Blender. :mod:`.blender_reader` runs in Blender's own Python, in a
subprocess (a crash or a hang of Blender stays there: a time limit, its exit status turned into
one line), and hands the frames back in an ``.npz`` in a temporary folder.

Which Blender: ``SKINSYNTH_BLENDER`` names either a Blender executable (``blender``, run as
``--background --factory-startup --python``) or a Python that can ``import bpy`` (the ``bpy``
wheel: ``pip install bpy``, for the Python it was built for; ``make blender`` makes one in
``.venv-blender``); without it, ``blender`` on PATH, then this Python if it has ``bpy``. None:
refused in one line that says what to install.
``SKINSYNTH_BLENDER_TIMEOUT``: seconds Blender may take (default :data:`TIMEOUT`).
"""

import importlib.util
import os
import shutil
import signal
import subprocess
import sys
import tempfile

import numpy as np

from .errors import FormatError

#: Seconds Blender may take to read a file before it is stopped (``SKINSYNTH_BLENDER_TIMEOUT``).
TIMEOUT = 600.0
_READER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "blender_reader.py")
_INSTALL = ("Blender reads .abc and .fbx here: pip install bpy (its wheel is for Python 3.11), or set "
            "SKINSYNTH_BLENDER to a Blender executable or to a Python that imports bpy (make blender makes one)")


def find_blender():
    """(kind, path): ``("python", p)`` a Python with bpy, ``("blender", p)`` a Blender executable;
    None when there is neither (module notes)."""
    named = os.environ.get("SKINSYNTH_BLENDER")
    if named:
        return _kind(named)
    on_path = shutil.which("blender")
    if on_path:
        return "blender", on_path
    if importlib.util.find_spec("bpy") is not None:
        return "python", sys.executable
    return None


def _kind(path):
    """What SKINSYNTH_BLENDER names: a Blender executable or a Python (by its name)."""
    name = os.path.basename(path).lower()
    return ("python" if name.startswith("python") else "blender"), path


def read_blender_sequence(path, mesh=None, fps=None):
    """An ``.abc`` or ``.fbx`` file's animated mesh -> (vertices (F, V, 3), faces (T, 3), fps, scene
    fields {meters_per_unit, up_axis, start_frame, prim_path}); mesh: the Alembic object path or
    FBX object name (None: the only mesh); fps: read at this rate (None: the file's own).
    FormatError (one line naming the file) for a file Blender cannot read, no Blender, a crash or
    a time limit passed."""
    path = os.fspath(path)
    found = find_blender()
    if found is None:
        raise FormatError(path, f"cannot read {os.path.splitext(path)[1]} without Blender: {_INSTALL}")
    kind, executable = found
    if not os.path.isfile(path):
        raise FormatError(path, "no such file")
    if os.path.getsize(path) == 0:
        raise FormatError(path, "empty file")
    timeout = float(os.environ.get("SKINSYNTH_BLENDER_TIMEOUT", TIMEOUT))
    with tempfile.TemporaryDirectory(prefix="skinsynth-blender-") as folder:
        output = os.path.join(folder, "frames.npz")
        arguments = [os.path.abspath(path), output, mesh or "", "" if fps is None else repr(float(fps))]
        command = [executable, _READER, *arguments] if kind == "python" else \
            [executable, "--background", "--factory-startup", "--python", _READER, "--", *arguments]
        returncode, stderr = _run(path, command, folder, timeout, executable)
        said = [line for line in stderr.splitlines() if line.startswith("SKINSYNTH: ")]
        if said:
            raise FormatError(path, said[-1][len("SKINSYNTH: "):])
        if returncode != 0 or not os.path.isfile(output):
            last = next((line for line in reversed(stderr.splitlines()) if line.strip()), "no message")
            raise FormatError(path, f"Blender failed reading it (exit status {returncode}: {last.strip()})")
        with np.load(output) as frames:
            scene = {"meters_per_unit": float(frames["meters_per_unit"]), "up_axis": str(frames["up_axis"]),
                     "start_frame": float(frames["start_frame"]), "prim_path": str(frames["mesh"])}
            return frames["vertices"], frames["faces"], float(frames["fps"]), scene


def _run(path, command, folder, timeout, executable):
    """Run Blender in a process group of its own: (exit status, stderr). Past ``timeout`` seconds,
    or when the command itself is stopped (a signal), the whole group is killed, so no Blender
    outlives the command."""
    try:
        process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                   stdin=subprocess.DEVNULL, cwd=folder, start_new_session=True)
    except OSError as error:
        raise FormatError(path, f"cannot run Blender ({executable}: {error.strerror or error}): {_INSTALL}") from None
    try:
        _, stderr = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        _kill(process)
        raise FormatError(path, f"Blender did not finish reading it within {timeout:g} s "
                                "(SKINSYNTH_BLENDER_TIMEOUT)") from None
    except BaseException:
        _kill(process)
        raise
    return process.returncode, stderr


def _kill(process):
    """Kill ``process``'s whole group and reap it."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    process.communicate()
