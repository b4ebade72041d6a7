"""Alembic (``.abc``) and FBX (``.fbx``) mesh animations read through Blender, and Alembic point
caches and skinned FBX written through it (issue 67).

No maintained Python package reads Alembic, and the FBX readers most used outside Autodesk's are
Blender's; so skinsynth asks Blender. :mod:`.blender_reader` runs in Blender's own Python, in a
subprocess (a crash or a hang of Blender stays there: a time limit, its exit status turned into
one line), and hands the frames back in an ``.npz`` in a temporary folder; :mod:`.blender_writer`
writes, the same way.

Which Blender: ``SKINSYNTH_BLENDER`` names either a Blender executable (``blender``, run as
``--background --factory-startup --python``) or a Python that can ``import bpy`` (the ``bpy``
wheel: ``pip install bpy``, for the Python it was built for; ``make blender`` makes one in
``.venv-blender``); without it, ``blender`` on PATH, then this Python if it has ``bpy``. None:
refused in one line that says what to install.
``SKINSYNTH_BLENDER_TIMEOUT``: seconds Blender may take (default :data:`TIMEOUT`).
"""

import importlib.util
import os
import queue
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

from .errors import FormatError

#: Seconds Blender may take to read a file before it is stopped (``SKINSYNTH_BLENDER_TIMEOUT``).
TIMEOUT = 600.0
_READER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "blender_reader.py")
_WRITER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "blender_writer.py")
_INSTALL = ("skinsynth reads and writes them through Blender: pip install bpy (its wheel is for Python 3.11), or set "
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


def _timeout(path):
    """``SKINSYNTH_BLENDER_TIMEOUT`` (seconds, default :data:`TIMEOUT`); FormatError for a value that is no
    positive number."""
    text = os.environ.get("SKINSYNTH_BLENDER_TIMEOUT")
    try:
        seconds = TIMEOUT if text is None else float(text)
    except ValueError:
        seconds = float("nan")
    if not (np.isfinite(seconds) and seconds > 0):
        raise FormatError(path, f"SKINSYNTH_BLENDER_TIMEOUT must be a positive number of seconds (got {text!r})")
    return seconds


def check_blender(path, doing="read"):
    """Refuse, before any work, an .abc or .fbx to ``doing`` ("read", "write") with no Blender found."""
    if find_blender() is None:
        raise FormatError(path, f"cannot {doing} {os.path.splitext(str(path))[1]} without Blender: {_INSTALL}")


def read_blender_sequence(path, mesh=None, fps=None, progress=None):
    """An ``.abc`` or ``.fbx`` file's animated mesh -> (vertices (F, V, 3), faces (T, 3), fps, scene
    fields {meters_per_unit, up_axis, start_frame, prim_path}); mesh: the Alembic object path or
    FBX object name (None: the only mesh); fps: read at this rate (None: the file's own);
    progress(done, total): called as Blender reads the frames.
    FormatError (one line naming the file) for a file Blender cannot read, no Blender, a crash or
    a time limit passed."""
    path = os.fspath(path)
    check_blender(path)
    if not os.path.isfile(path):
        raise FormatError(path, "no such file")
    if os.path.getsize(path) == 0:
        raise FormatError(path, "empty file")
    with tempfile.TemporaryDirectory(prefix="skinsynth-blender-") as folder:
        output = os.path.join(folder, "frames.npz")
        arguments = [os.path.abspath(path), output, mesh or "", "" if fps is None else repr(float(fps))]
        returncode, said, last = _in_blender(path, _READER, arguments, folder, "reading", progress)
        if said:
            raise FormatError(path, said)
        if returncode != 0 or not os.path.isfile(output):
            raise FormatError(path, f"Blender failed reading it (exit status {returncode}: {last})")
        with np.load(output) as frames:
            scene = {"meters_per_unit": float(frames["meters_per_unit"]), "up_axis": str(frames["up_axis"]),
                     "start_frame": float(frames["start_frame"]), "prim_path": str(frames["mesh"])}
            return frames["vertices"], frames["faces"], float(frames["fps"]), scene


def write_alembic(path, vertices, faces, fps, scene, up_axis=None):
    """Write vertices (F, V, 3) (faces (T, 3), ``fps``, in ``scene``'s units, axes and frames; up_axis:
    the output's, None the scene's) to ``path`` as an Alembic point cache through Blender's exporter
    (:mod:`.blender_writer`), atomically. Alembic has no units: the numbers are written as they are;
    it is Y up by convention, so a Z-up animation is turned as Blender turns its own world
    ((x, y, z) -> (x, z, −y)) and reads back Y up. FormatError without Blender or when it fails."""
    path = os.fspath(path)
    check_blender(path, "write")
    up = up_axis or scene.up_axis
    frames = np.asarray(vertices, dtype=np.float64)
    world = np.stack([frames[..., 0], -frames[..., 2], frames[..., 1]], axis=-1) if up == "Y" else frames
    name = os.path.basename(str(scene.prim_path).rstrip("/")) or "mesh"
    with tempfile.TemporaryDirectory(prefix="skinsynth-blender-") as folder:
        inputs, cache = os.path.join(folder, "frames.npz"), os.path.join(folder, "frames.pc2")
        np.savez(inputs, rest=world[0], faces=np.asarray(faces, dtype=np.int64), fps=np.float64(fps),
                 start_frame=np.float64(scene.start_frame), name=name, frames=np.int64(len(world)))
        _write_pc2(cache, world, scene.start_frame, fps)
        _exported(path, [inputs, cache], folder, int(world.size * 4 * 2 + (1 << 20)))


def write_fbx(path, skin, rotations, translations, up_axis=None):
    """Write a skin's mesh and bones, moved by rotations (F, B, 3, 3) and translations (F, B, 3)
    (each bone's world motion, as linear blend skinning applies it), to ``path`` as a skinned FBX
    through Blender's exporter (:mod:`.blender_writer`), atomically: an armature whose bones are the
    skin's skeleton (its tree and joint names) or, for a free skin, a flat rig at its bones' rest
    centres; every frame baked; the mesh's material UVs where the skin has them; in the skin's
    units and frames, ``up_axis`` (None: the skin's) the file's. FormatError without Blender or when it fails."""
    check_blender(path, "write")
    up = up_axis or skin.scene.up_axis
    turn = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]) if up == "Y" else np.eye(3)
    rotations = np.einsum("ij,fbjk,lk->fbil", turn, np.asarray(rotations, dtype=np.float64), turn)
    translations = np.asarray(translations, dtype=np.float64) @ turn.T
    bones = rotations.shape[1]
    if skin.skeleton is not None:
        parents, joints = np.asarray(skin.skeleton["parents"]), np.asarray(skin.skeleton["joints"], dtype=np.float64)
        stored = skin.skeleton.get("names") if hasattr(skin.skeleton, "get") else None
        names = [str(n) for n in stored] if stored is not None else [f"bone_{b:02d}" for b in range(bones)]
    else:
        parents, joints = -np.ones(bones, np.int64), np.asarray(skin.bone_rest_frames, np.float64)[:, :3, 3]
        names = [f"bone_{b:02d}" for b in range(bones)]
    with tempfile.TemporaryDirectory(prefix="skinsynth-blender-") as folder:
        inputs = os.path.join(folder, "skin.npz")
        np.savez(inputs, rest=np.asarray(skin.rest_vertices, np.float64) @ turn.T, faces=np.asarray(skin.faces),
                 bone_indices=np.asarray(skin.bone_indices), bone_weights=np.asarray(skin.bone_weights, np.float64),
                 parents=parents, joints=joints @ turn.T, names=np.array(names), rotations=rotations,
                 translations=translations, fps=np.float64(skin.fps), start_frame=np.float64(skin.scene.start_frame),
                 name=os.path.basename(str(skin.scene.prim_path).rstrip("/")) or "mesh", up_axis=up,
                 meters_per_unit=np.float64(skin.scene.meters_per_unit),
                 **({} if skin.face_uvs is None else {"face_uvs": np.asarray(skin.face_uvs, np.float64)}))
        _exported(path, [inputs], folder, int(rotations.size * 8 + skin.rest_vertices.size * 16 + (1 << 20)))


def _exported(path, arguments, folder, expected_bytes):
    """Run :mod:`.blender_writer` with ``arguments`` and a temporary output beside ``path``, then
    rename it into place; FormatError (one line) when Blender fails."""
    from .atomic import atomic_output

    with atomic_output(path, expected_bytes=expected_bytes, interruptible=True) as temporary:
        returncode, said, last = _in_blender(path, _WRITER, [*arguments, os.path.abspath(temporary)], folder,
                                             "writing")
        if said or returncode != 0 or not os.path.isfile(temporary) or os.path.getsize(temporary) == 0:
            raise FormatError(path, f"Blender failed writing it (exit status {returncode}: {said or last})")


def _in_blender(path, script, arguments, folder, doing, progress=None):
    """Run ``script`` (:mod:`.blender_reader` or :mod:`.blender_writer`) with ``arguments`` in the
    Blender :func:`find_blender` finds (:func:`_run`): (exit status, the script's own one-line
    complaint after ``SKINSYNTH:`` or None, Blender's last line on stderr)."""
    kind, executable = find_blender()
    command = [executable, script, *arguments] if kind == "python" else \
        [executable, "--background", "--factory-startup", "--python", script, "--", *arguments]
    returncode, stderr = _run(path, command, folder, _timeout(path), executable, doing, progress)
    lines = stderr.splitlines()
    said = next((line[len("SKINSYNTH: "):] for line in reversed(lines) if line.startswith("SKINSYNTH: ")), None)
    last = next((line.strip() for line in reversed(lines) if line.strip()), "no message")
    return returncode, said, last


def _write_pc2(path, frames, start_frame, fps):
    """frames (F, V, 3) as a PC2 point cache (what Blender's Mesh Cache modifier reads): the
    12-byte signature, version 1, points, start frame, sample rate (1: a sample a frame), samples;
    then every frame's points, float32 little-endian."""
    header = np.zeros(1, dtype=[("signature", "S12"), ("version", "<i4"), ("points", "<i4"), ("start", "<f4"),
                                ("rate", "<f4"), ("samples", "<i4")])
    header[0] = (b"POINTCACHE2\0", 1, frames.shape[1], float(start_frame), 1.0, frames.shape[0])
    with open(path, "wb") as stream:
        stream.write(header.tobytes())
        stream.write(np.ascontiguousarray(frames, dtype="<f4").tobytes())


def _run(path, command, folder, timeout, executable, doing="reading", progress=None):
    """Run Blender in a process group of its own: (exit status, stderr less its progress lines).
    Past ``timeout`` seconds, or when the command itself is stopped (a signal), the whole group is
    killed, so no Blender outlives the command. progress(done, total): called here, in this thread,
    for each frame the reader reports (``SKINSYNTH-FRAME done total`` on its stderr)."""
    try:
        process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                   stdin=subprocess.DEVNULL, cwd=folder, start_new_session=True)
    except OSError as error:
        raise FormatError(path, f"cannot run Blender ({executable}: {error.strerror or error}): {_INSTALL}") from None
    lines, frames = [], queue.Queue()

    def pump():  # stderr read as it comes: a full pipe would stall Blender
        for line in process.stderr:
            (frames.put if line.startswith("SKINSYNTH-FRAME ") else lines.append)(line)

    reader = threading.Thread(target=pump, daemon=True, name="skinsynth-blender-stderr")
    reader.start()
    deadline = time.monotonic() + timeout
    try:
        while True:
            try:
                process.wait(timeout=min(0.2, max(deadline - time.monotonic(), 0.0)))
                break
            except subprocess.TimeoutExpired:
                if time.monotonic() >= deadline:
                    raise
            finally:
                _report(frames, progress)
    except subprocess.TimeoutExpired:
        _kill(process, reader)
        raise FormatError(path, f"Blender did not finish {doing} it within {timeout:g} s "
                                "(SKINSYNTH_BLENDER_TIMEOUT)") from None
    except BaseException:
        _kill(process, reader)
        raise
    reader.join()
    process.stderr.close()
    _report(frames, progress)
    return process.returncode, "".join(lines)


def _report(frames, progress):
    """Hand the frames reported so far to ``progress`` (the latest only)."""
    latest = None
    while not frames.empty():
        latest = frames.get_nowait()
    if latest is not None and progress is not None:
        done, total = (int(x) for x in latest.split()[1:3])
        progress(done, total)


def _kill(process, reader):
    """Kill ``process``'s whole group, reap it, and let its stderr's reader end."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    process.wait()
    reader.join(timeout=5)
    process.stderr.close()
