"""Example animations on disk: one mesh, fixed topology, vertex positions per frame.

Accepted inputs: a folder of OBJ/PLY/OFF frame files, a glob of them, a USD file with a
time-sampled mesh, an Alembic (``.abc``) or FBX (``.fbx``) animation (read through Blender:
:mod:`.blender`), or an ``.npz``/``.h5`` file holding ``vertices (F, V, 3)`` and
``faces (T, 3)`` (optional scalar ``fps``).
"""

from __future__ import annotations

import glob
import os
import re
import warnings
import zipfile
from dataclasses import dataclass, field, replace

import numpy as np

from skinsynth.formats.errors import FormatError, declared_size_problem, require_coordinates, require_finite
from skinsynth.formats.scene import Scene

FRAME_EXTENSIONS = (".obj", ".ply", ".off")
USD_EXTENSIONS = (".usd", ".usda", ".usdc")
ARRAY_EXTENSIONS = (".npz", ".h5", ".hdf5")
BLENDER_EXTENSIONS = (".abc", ".fbx")  # read through Blender (formats/blender.py)
DEFAULT_FPS = 24.0


@dataclass(frozen=True)
class MeshSequence:
    """vertices (F, V, 3) float64, faces (T, 3) int64 triangles, fps, the input as given, its
    scene (units, up axis, first frame, prim path; USD states them, other inputs default), and
    face_uvs (T, 3, 2) float64, the material UVs of each face corner (OBJ ``vt``, USD
    ``primvars:st``; v up, as both store them), or None when the input has none. Clips read
    together (:func:`~.clip_inputs.read_clips`) set ``clip_names`` (C,) and ``clip_frames`` (C,),
    summing to F; None means one clip."""

    vertices: np.ndarray
    faces: np.ndarray
    fps: float
    source: str
    scene: Scene = field(default_factory=Scene)
    face_uvs: np.ndarray | None = None
    clip_names: tuple | None = None
    clip_frames: tuple | None = None


def read_mesh_sequence(spec: str, prim: str | None = None, fps: float | None = None, progress=None) -> MeshSequence:
    """Read an example animation from a folder, glob, USD file or array file.

    ``prim`` picks the USD mesh (default: the first Mesh with time-sampled points); ``fps``
    overrides the frame rate stored in the file (frame files and arrays without one: 24);
    ``progress(done, total)``: called as Blender reads an ``.abc``/``.fbx``'s frames.
    Bad input raises FormatError naming the file (for frame files, the first offending frame).
    """
    spec = os.fspath(spec)
    if fps is not None and not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps}")
    ext = os.path.splitext(spec)[1].lower()
    if prim is not None and ext not in USD_EXTENSIONS + BLENDER_EXTENSIONS:
        raise FormatError(spec, "a prim path applies only to USD, Alembic and FBX input")

    # An existing path wins over a glob reading, so folders named like "take[1]" still work.
    if os.path.isdir(spec):
        sequence = _read_frame_files(spec, _folder_frames(spec))
    elif not os.path.exists(spec):
        if not glob.has_magic(spec):
            raise FormatError(spec, "no such file or folder")
        sequence = _read_frame_files(spec, _glob_frames(spec))
    elif ext in USD_EXTENSIONS:
        # pxr takes a third of a second to import: pay for it only when reading USD.
        from skinsynth.formats.usd import read_face_uvs, read_points_cache, read_scene

        sequence = sequence_from_arrays(spec, *read_points_cache(spec, prim))
        sequence = replace(sequence, scene=read_scene(spec, prim),
                           face_uvs=checked_face_uvs(spec, read_face_uvs(spec, prim), sequence.faces))
    elif ext in BLENDER_EXTENSIONS:
        from skinsynth.formats.blender import read_blender_sequence

        vertices, faces, rate, scene = read_blender_sequence(spec, prim, fps, progress)
        sequence = replace(sequence_from_arrays(spec, vertices, faces, rate), scene=Scene(**scene))
    elif ext == ".npz":
        sequence = _read_npz(spec)
    elif ext in (".h5", ".hdf5"):
        sequence = _read_h5(spec)
    elif ext in FRAME_EXTENSIONS:
        raise FormatError(spec, "a single frame is not a sequence; give the folder or a glob of the frames")
    else:
        raise FormatError(spec, f"unknown extension {ext or '(none)'!r}; expected a folder, a glob, "
                                f"{'/'.join(USD_EXTENSIONS + BLENDER_EXTENSIONS + ARRAY_EXTENSIONS)}")

    if fps is not None:
        sequence = replace(sequence, fps=float(fps))
    return sequence


def sequence_from_arrays(source, vertices, faces, fps=None) -> MeshSequence:
    """Validate vertices (F, V, 3) and faces (T, 3) read from ``source`` into a MeshSequence.

    Raises FormatError for every defect a user's file can have; ``fps`` None means 24.
    """
    source = os.fspath(source)
    vertices = np.asarray(vertices)
    faces = np.asarray(faces)
    if vertices.ndim != 3 or vertices.shape[2] != 3:
        raise FormatError(source, f"vertices must have shape (frames, vertices, 3), got {vertices.shape}")
    if not np.issubdtype(vertices.dtype, np.number) or np.iscomplexobj(vertices):
        raise FormatError(source, f"vertices must be real numbers, got dtype {vertices.dtype}")
    frames, count = vertices.shape[:2]
    if frames < 2:
        raise FormatError(source, f"{frames} frame(s); an animation needs at least 2")
    if count == 0:
        raise FormatError(source, "the mesh has no vertices")
    vertices = vertices.astype(np.float64, copy=False)
    require_coordinates(source, vertices, "vertex")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise FormatError(source, f"faces must have shape (triangles, 3), got {faces.shape}")
    if len(faces) == 0:
        raise FormatError(source, "the mesh has no faces")
    if not np.issubdtype(faces.dtype, np.integer):
        raise FormatError(source, f"faces must be integers, got dtype {faces.dtype}")
    if faces.min() < 0 or faces.max() >= count:
        raise FormatError(source, f"face indices must lie in [0, {count}), found {faces.min()}..{faces.max()}")
    if fps is None:
        fps = DEFAULT_FPS
    if not (np.isfinite(fps) and fps > 0):
        raise FormatError(source, f"frame rate must be positive, got {fps}")
    return MeshSequence(vertices, faces.astype(np.int64, copy=False), float(fps), source)


def checked_face_uvs(source, face_uvs, faces):
    """face_uvs (T, 3, 2) read from ``source`` for faces (T, 3) as float64, or None for None;
    FormatError for a wrong shape or a NaN or inf."""
    if face_uvs is None:
        return None
    face_uvs = np.asarray(face_uvs)
    if face_uvs.shape != (len(faces), 3, 2) or not np.issubdtype(face_uvs.dtype, np.number):
        raise FormatError(source, f"texture coordinates must be numbers of shape ({len(faces)}, 3, 2) (per triangle "
                                  f"corner), got {face_uvs.dtype} {face_uvs.shape}")
    face_uvs = face_uvs.astype(np.float64, copy=False)
    require_finite(source, "the texture coordinates", face_uvs)
    return face_uvs


def natural_key(path):
    """Sort key putting frame2 before frame10: digit runs compare as numbers."""
    name = os.path.basename(path)
    # re.split with a group alternates text and digits, so the key's types line up position by position.
    parts = re.split(r"(\d+)", name)
    return [int(p) if p.isdigit() else p.lower() for p in parts], name


def _glob_frames(pattern):
    paths = sorted((p for p in glob.glob(pattern) if os.path.isfile(p)), key=natural_key)
    if not paths:
        raise FormatError(pattern, "the pattern matches no files")
    for path in paths:
        if os.path.splitext(path)[1].lower() not in FRAME_EXTENSIONS:
            raise FormatError(path, f"not a frame file; expected {'/'.join(FRAME_EXTENSIONS)}")
    return paths


def _folder_frames(folder):
    paths = [
        entry.path
        for entry in os.scandir(folder)
        if entry.is_file()
        and not entry.name.startswith(".")  # hidden and half-written temporary files
        and os.path.splitext(entry.name)[1].lower() in FRAME_EXTENSIONS
    ]
    if not paths:
        raise FormatError(folder, f"no {'/'.join(FRAME_EXTENSIONS)} frame files in the folder")
    return sorted(paths, key=natural_key)


def _read_frame_files(source, paths) -> MeshSequence:
    first_vertices, faces = _read_frame(paths[0])
    vertices = np.empty((len(paths), len(first_vertices), 3))
    vertices[0] = first_vertices
    for index, path in enumerate(paths[1:], start=1):
        frame_vertices, frame_faces = _read_frame(path)
        if len(frame_vertices) != len(first_vertices):
            raise FormatError(path, f"{len(frame_vertices)} vertices, but the first frame "
                                    f"{os.path.basename(paths[0])} has {len(first_vertices)}")
        if not np.array_equal(frame_faces, faces):
            raise FormatError(path, f"faces differ from the first frame {os.path.basename(paths[0])}")
        vertices[index] = frame_vertices
    sequence = sequence_from_arrays(source, vertices, faces)
    if os.path.splitext(paths[0])[1].lower() == ".obj":  # UVs are the first frame's
        sequence = replace(sequence, face_uvs=checked_face_uvs(paths[0], obj_face_uvs(paths[0], faces), faces))
    return sequence


def _read_frame(path):
    """One frame file as vertices (V, 3) float64 in file order and faces (T, 3) int64."""
    # trimesh takes a second to import: pay for it only when reading frame files.
    import trimesh

    ext = os.path.splitext(path)[1].lower()
    options = {"process": False}
    if ext == ".obj":
        # maintain_order stops trimesh from splitting vertices at UV/normal seams, which would
        # renumber them; materials are irrelevant and would only split the mesh further.
        options.update(maintain_order=True, skip_materials=True)
    if ext in (".obj", ".off") and _looks_binary(path):
        raise FormatError(path, f"cannot read as {ext[1:].upper()}: not a text file in a known encoding")
    try:
        with warnings.catch_warnings():
            # trimesh warns while guessing UVs of unreferenced vertices; UVs are not read here.
            warnings.simplefilter("ignore", RuntimeWarning)
            loaded = trimesh.load(path, file_type=ext[1:], **options)
    except (ImportError, UnicodeDecodeError):
        # trimesh falls back to an optional text-encoding detector for bytes that are not UTF-8.
        raise FormatError(path, f"cannot read as {ext[1:].upper()}: not a text file in a known encoding") from None
    except Exception as error:  # trimesh raises anything from parsing errors to IndexError
        raise FormatError(path, f"cannot read as {ext[1:].upper()}: {error}") from None

    vertices, faces = _merge_geometry(path, loaded)
    if len(vertices) == 0:
        raise FormatError(path, "the mesh has no vertices")
    if len(faces) == 0:
        raise FormatError(path, "the mesh has no faces")
    require_coordinates(path, np.asarray(vertices)[None], "vertex")
    return vertices, faces


def _looks_binary(path, sample=1 << 16):
    """Whether a text format's file is binary data: over 1 % of its first ``sample`` bytes are
    control characters no text has (NUL and the like; tabs and line ends aside). trimesh decodes
    bytes that are not UTF-8 with whichever encoding detector is installed, so without this check
    the same garbage file was "not text" on one machine and an empty mesh on another."""
    try:
        with open(path, "rb") as handle:
            head = np.frombuffer(handle.read(sample), dtype=np.uint8)
    except OSError:
        return False  # trimesh says what is wrong
    control = (head < 32) & ~np.isin(head, (9, 10, 12, 13))
    return head.size > 0 and control.mean() > 0.01


def fan_corners(counts):
    """Polygons of counts (P,) corners, fan-triangulated in polygon order: (T, 3) int64, each
    triangle corner as its position in the polygons' corners laid end to end."""
    counts = np.asarray(counts, dtype=np.int64)
    starts = np.cumsum(counts) - counts
    fans = counts - 2
    polygon = np.repeat(np.arange(len(counts)), fans)
    corner = np.arange(fans.sum()) - np.repeat(np.cumsum(fans) - fans, fans) + 1  # 1..n-2 within a polygon
    first = starts[polygon]
    return np.stack([first, first + corner, first + corner + 1], axis=1)


def obj_face_uvs(path, faces):
    """The corner UVs (T, 3, 2) float64 of an OBJ file for ``faces`` (T, 3) as :func:`_read_frame`
    read them (trimesh's triangles, grouped by material), or None unless every face corner names
    a ``vt``.

    trimesh keeps vertex order only by keeping one UV per vertex, so the file's own ``f`` lines
    give the corners: each polygon fan-triangulated, its triangles matched to trimesh's as equal
    vertex triples up to a rotation of their corners (how trimesh splits a quad). FormatError when
    a ``vt`` index is out of range or the triangles do not match."""
    with open(path, encoding="utf-8", errors="replace") as handle:
        text = handle.read()
    texcoords = re.findall(r"^[ \t]*vt[ \t]+(\S+)(?:[ \t]+(\S+))?", text, flags=re.MULTILINE)  # (u, v or "")
    if not texcoords:
        return None
    texcoords = np.array(texcoords)
    texcoords[texcoords == ""] = "0"  # OBJ's v defaults to 0
    try:
        texcoords = texcoords.astype(np.float64)
    except ValueError as error:
        raise FormatError(path, f"a vt line is not numbers: {error}") from None
    lines = re.findall(r"^[ \t]*f[ \t]+([^\n]*)", text, flags=re.MULTILINE)
    counts = np.array([len(line.split()) for line in lines], dtype=np.int64)
    # each corner "v/vt" or "v/vt/vn", at the start of a token
    refs = re.findall(r"(?<!\S)(-?\d+)/(-?\d*)", " ".join(lines))
    if len(refs) != counts.sum() or not refs or any(not vt for _, vt in refs):
        return None  # a corner without a UV (or no faces): the mesh has none as a whole
    refs = np.array(refs).astype(np.int64)  # (C, 2) vertex and vt of each corner, one-based
    kept = np.repeat(counts >= 3, counts)  # trimesh skips faces of fewer corners too
    corners = refs[kept][fan_corners(counts[counts >= 3])]  # (T, 3, 2)
    corners_v, corners_t = corners[..., 0].copy(), corners[..., 1].copy()  # corners keeps the file's numbers
    if not len(corners_v):
        return None
    corners_v[corners_v > 0] -= 1  # one-based; a negative index counts from the end of the list, as in trimesh
    corners_t[corners_t > 0] -= 1
    corners_v[corners_v < 0] += len(re.findall(r"^[ \t]*v[ \t]", text, flags=re.MULTILINE))
    corners_t[corners_t < 0] += len(texcoords)
    outside = (corners_t < 0) | (corners_t >= len(texcoords))
    if outside.any():
        raise FormatError(path, f"a face names texture coordinate (vt) {int(corners[..., 1][outside][0])}, beyond "
                                f"the {len(texcoords)} in the file")
    file_uvs = texcoords[corners_t]  # (T, 3, 2)

    def canonical(triangles):
        """The rotation of each triangle's corners that is least as a triple, and its shift."""
        rotations = np.stack([np.roll(triangles, -r, axis=1) for r in range(3)], axis=1)  # (T, shift, 3)
        rows = np.arange(len(triangles))
        best = np.zeros(len(triangles), dtype=np.int64)
        for r in (1, 2):
            a, b = rotations[:, r], rotations[rows, best]
            less = (a[:, 0] < b[:, 0]) | ((a[:, 0] == b[:, 0]) & ((a[:, 1] < b[:, 1]) |
                                                                  ((a[:, 1] == b[:, 1]) & (a[:, 2] < b[:, 2]))))
            best[less] = r
        return rotations[rows, best], best

    faces = np.asarray(faces, dtype=np.int64)
    mismatch = FormatError(path, "its texture coordinates (vt) cannot be matched to the triangles read; remove the "
                                 "vt lines to read it without UVs")
    if len(corners_v) != len(faces):
        raise mismatch
    file_key, file_shift = canonical(corners_v)
    read_key, read_shift = canonical(faces)
    file_order = np.lexsort(file_key.T[::-1])
    read_order = np.lexsort(read_key.T[::-1])
    if not np.array_equal(file_key[file_order], read_key[read_order]):
        raise mismatch
    match = np.empty(len(faces), dtype=np.int64)  # read triangle -> file triangle
    match[read_order] = file_order
    # corner k of a read triangle is corner (k − its shift) of the canonical triangle, which is
    # corner (k − its shift + the file triangle's shift) of the file's
    k = np.arange(3)
    corner = (k[None, :] - read_shift[:, None] + file_shift[match][:, None]) % 3
    return file_uvs[match[:, None], corner]


def _merge_geometry(path, loaded):
    """Vertices and faces from a trimesh result, which is a Scene when an OBJ has several materials.

    With maintain_order, trimesh gives every OBJ part a prefix of the file's vertex list and
    faces indexed into it, so the longest prefix is the file's vertex list and faces just
    concatenate. (An OBJ's unreferenced trailing vertices may be dropped; earlier ones keep
    their index.)
    """
    import trimesh

    if isinstance(loaded, trimesh.Scene):
        parts = [g for g in loaded.geometry.values() if isinstance(g, trimesh.Trimesh)]
    elif isinstance(loaded, trimesh.Trimesh):
        parts = [loaded]
    else:
        parts = []
    if not parts:
        raise FormatError(path, "no triangle mesh in the file")
    vertices = np.asarray(max(parts, key=lambda g: len(g.vertices)).vertices, dtype=np.float64)
    for part in parts:
        part_vertices = np.asarray(part.vertices, dtype=np.float64)
        if not np.array_equal(part_vertices, vertices[: len(part_vertices)], equal_nan=True):
            raise FormatError(path, "the file holds several meshes whose vertex order cannot be kept")
    faces = np.concatenate([np.asarray(part.faces, dtype=np.int64).reshape(-1, 3) for part in parts])
    return vertices, faces


def _read_npz(path) -> MeshSequence:
    # np.load treats a non-zip file as a pickle and would blame pickling; say what is wrong.
    if not zipfile.is_zipfile(path):
        raise FormatError(path, "not an .npz file (not a zip archive)")
    _check_npz_sizes(path, ("vertices", "faces", "fps"))
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in ("vertices", "faces", "fps") if name in data.files}
    except Exception as error:  # zipfile, pickle and format errors all mean "not a usable npz"
        raise FormatError(path, f"cannot read as .npz: {error}") from None
    return _from_named_arrays(path, arrays)


def _check_npz_sizes(path, names):
    """Refuse members whose .npy header declares far more than their compressed bytes, before
    np.load allocates what the header asks for."""
    try:
        with zipfile.ZipFile(path) as archive:
            for name in names:
                try:
                    info = archive.getinfo(name + ".npy")
                except KeyError:
                    continue
                with archive.open(info) as member:
                    version = np.lib.format.read_magic(member)
                    read_header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                                   else np.lib.format.read_array_header_2_0)
                    shape, _, dtype = read_header(member)
                declared = int(np.prod(shape, dtype=object)) * dtype.itemsize
                problem = declared_size_problem(f"'{name}'", declared, info.compress_size)
                if problem:
                    raise FormatError(path, problem)
    except FormatError:
        raise
    except Exception as error:  # zipfile and .npy header errors: not a usable npz
        raise FormatError(path, f"cannot read as .npz: {error}") from None


def _read_h5(path) -> MeshSequence:
    import h5py

    try:
        with h5py.File(path, "r") as data:
            found = {name: data[name] for name in ("vertices", "faces", "fps")
                     if isinstance(data.get(name), h5py.Dataset)}
            for name, item in found.items():
                _check_stored(path, f"'{name}'", item)
            arrays = {name: item[()] for name, item in found.items()}
            if "fps" not in arrays and "fps" in data.attrs:
                arrays["fps"] = data.attrs["fps"]
    except OSError as error:
        raise FormatError(path, f"cannot read as HDF5: {error}") from None
    return _from_named_arrays(path, arrays)


def _check_stored(path, what, dataset):
    """FormatError unless the file (or a virtual dataset's sources) holds ``dataset``'s data:
    HDF5 reads what is missing as fill values, and a small file must not declare gigabytes."""
    from .hdf5_storage import DeclaredTooLarge, check_stored

    try:
        check_stored(dataset, what)
    except DeclaredTooLarge as error:
        raise FormatError(path, str(error)) from None


def _from_named_arrays(path, arrays) -> MeshSequence:
    for name in ("vertices", "faces"):
        if name not in arrays:
            raise FormatError(path, f"no '{name}' array")
    fps = arrays.get("fps")
    if fps is not None:
        fps = np.asarray(fps)
        if fps.size != 1 or not np.issubdtype(fps.dtype, np.number):
            raise FormatError(path, f"'fps' must be one number, got shape {fps.shape} {fps.dtype}")
        fps = float(fps.reshape(()))
    return sequence_from_arrays(path, arrays["vertices"], arrays["faces"], fps)


def write_array_sequence(path, vertices, faces, fps):
    """Write vertices (F, V, 3), faces (T, 3) and fps as an .npz that read_mesh_sequence reads back."""
    from .atomic import atomic_output

    with atomic_output(path) as tmp:
        with open(tmp, "wb") as handle:
            np.savez_compressed(handle, vertices=np.asarray(vertices, dtype=np.float64),
                                faces=np.asarray(faces, dtype=np.int64), fps=np.float64(fps))


def write_vertex_animation(path, vertices, faces, fps, names=None):
    """Write played characters as HDF5: ``vertices (C, F, V, 3)`` float32, ``faces (T, 3)``, ``@fps``,
    ``names (C,)``. A single character's file is also a sequence ``read_mesh_sequence`` reads
    back (it then holds ``vertices (F, V, 3)``)."""
    import h5py

    from .atomic import atomic_output

    vertices = np.asarray(vertices, dtype=np.float32)
    require_finite(path, "the vertices", vertices)
    with atomic_output(path, expected_bytes=vertices.nbytes + (1 << 20)) as tmp:
        with h5py.File(tmp, "w") as f:
            data = vertices[0] if vertices.shape[0] == 1 else vertices
            f.create_dataset("vertices", data=data, compression="gzip", compression_opts=4, shuffle=True,
                             track_times=False)
            f.create_dataset("faces", data=np.asarray(faces, dtype=np.int64), track_times=False)
            f.attrs["fps"] = float(fps)
            if names is not None:
                f.create_dataset("names", data=np.array(names, dtype=h5py.string_dtype()), track_times=False)


def read_played_characters(path):
    """A ``play -o OUT.h5`` file: (names [C], vertices (C, F, V, 3) float64, faces (T, 3), fps). A
    one-character file (``vertices (F, V, 3)``) is read as one character."""
    import h5py

    try:
        with h5py.File(path, "r") as data:
            item, faces = data.get("vertices"), data.get("faces")
            if not isinstance(item, h5py.Dataset) or item.ndim not in (3, 4):
                raise FormatError(path, "no 'vertices' array of shape (F, V, 3) or (C, F, V, 3)")
            if not isinstance(faces, h5py.Dataset):
                raise FormatError(path, "no 'faces' array")
            _check_stored(path, "'vertices'", item)
            vertices = np.asarray(item[()], dtype=np.float64)
            faces = faces[()]
            fps = data.attrs.get("fps", None)
            names = [n.decode() if isinstance(n, bytes) else str(n) for n in data["names"][()]] \
                if isinstance(data.get("names"), h5py.Dataset) else None
    except OSError as error:
        raise FormatError(path, f"cannot read as HDF5: {error}") from None
    if vertices.ndim == 3:
        vertices = vertices[None]
    sequences = [sequence_from_arrays(path, v, faces, None if fps is None else float(fps)) for v in vertices]
    if names is None or len(names) != len(sequences):
        names = [f"character {c}" for c in range(len(sequences))]
    return names, np.stack([s.vertices for s in sequences]), sequences[0].faces, sequences[0].fps
