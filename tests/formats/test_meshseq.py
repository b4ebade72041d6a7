"""Reading example animations: frame files, arrays and USD, and every way they can be wrong."""

import os

import h5py
import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from skinsynth.formats.errors import FormatError
from skinsynth.formats.meshseq import MeshSequence, natural_key, read_mesh_sequence

# A unit square (quad 0-1-2-3) plus a triangle (1-4-2): 5 vertices, 3 triangles once split.
SQUARE = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0.5, 0]], dtype=float)
POLYGONS = [[0, 1, 2, 3], [1, 4, 2]]


def frame_positions(frame, vertices=SQUARE):
    """Distinct positions per frame so that a wrong frame order is visible."""
    return vertices + np.array([0.0, 0.0, 0.25 * frame])


def write_obj(path, vertices, polygons=POLYGONS):
    lines = ["v " + " ".join(repr(float(c)) for c in row) for row in vertices]  # repr: exact round trip
    lines += ["f " + " ".join(str(i + 1) for i in polygon) for polygon in polygons]
    path.write_text("\n".join(lines) + "\n")


def write_ply(path, vertices, polygons=POLYGONS):
    header = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}", "property float x",
              "property float y", "property float z", f"element face {len(polygons)}",
              "property list uchar int vertex_indices", "end_header"]
    body = [f"{x} {y} {z}" for x, y, z in vertices] + [f"{len(p)} " + " ".join(map(str, p)) for p in polygons]
    path.write_text("\n".join(header + body) + "\n")


def write_off(path, vertices, polygons=POLYGONS):
    lines = ["OFF", f"{len(vertices)} {len(polygons)} 0"] + [f"{x} {y} {z}" for x, y, z in vertices]
    lines += [f"{len(p)} " + " ".join(map(str, p)) for p in polygons]
    path.write_text("\n".join(lines) + "\n")


def write_frames(folder, writer=write_obj, ext="obj", numbers=(1, 2, 10), stem="frame"):
    folder.mkdir(exist_ok=True)
    for order, number in enumerate(numbers):
        writer(folder / f"{stem}{number}.{ext}", frame_positions(order))
    return folder


def assert_square_faces(faces):
    """The quad became two triangles over its own corners, the triangle stayed."""
    assert faces.shape == (3, 3) and faces.dtype == np.int64
    quad = [set(f) for f in faces if set(f) <= {0, 1, 2, 3}]
    assert len(quad) == 2 and set.union(*quad) == {0, 1, 2, 3}
    assert {1, 2, 4} in [set(f) for f in faces]


# ---------------------------------------------------------------- frame files


def test_natural_sort_key():
    names = ["f10.obj", "f2.obj", "f1.obj", "F3.obj"]
    assert sorted(names, key=natural_key) == ["f1.obj", "f2.obj", "F3.obj", "f10.obj"]


def test_folder_of_obj_frames_in_natural_order(tmp_path):
    folder = write_frames(tmp_path / "frames")
    (folder / "notes.txt").write_text("not a frame")
    (folder / ".frame0.obj").write_text("half-written")  # hidden files are skipped

    sequence = read_mesh_sequence(str(folder))

    assert isinstance(sequence, MeshSequence)
    assert sequence.vertices.shape == (3, 5, 3) and sequence.vertices.dtype == np.float64
    for order in range(3):  # frame1, frame2, frame10, not frame1, frame10, frame2
        np.testing.assert_array_equal(sequence.vertices[order], frame_positions(order))
    assert_square_faces(sequence.faces)
    assert sequence.fps == 24.0 and sequence.source == str(folder)


def test_glob_of_obj_frames_in_natural_order(tmp_path):
    write_frames(tmp_path, numbers=(1, 2, 10), stem="horse-")
    write_obj(tmp_path / "other-1.obj", SQUARE + 100)

    sequence = read_mesh_sequence(str(tmp_path / "horse-*.obj"), fps=30)

    assert sequence.vertices.shape == (3, 5, 3)
    np.testing.assert_array_equal(sequence.vertices[2], frame_positions(2))
    assert sequence.fps == 30.0


@pytest.mark.parametrize("writer,ext", [(write_ply, "ply"), (write_off, "off")])
def test_ply_and_off_frames(tmp_path, writer, ext):
    folder = write_frames(tmp_path / ext, writer, ext)
    sequence = read_mesh_sequence(str(folder))
    np.testing.assert_allclose(sequence.vertices[1], frame_positions(1), rtol=0, atol=1e-7)
    assert_square_faces(sequence.faces)


def test_obj_vertex_order_kept_with_uv_and_normal_seams(tmp_path):
    """trimesh splits OBJ vertices at vt/vn seams unless told not to: file order must survive.

    Faces reference vertices out of order, one vertex is used with two different UVs, one
    vertex is unreferenced, and two materials make trimesh load two parts.
    """
    rng = np.random.default_rng(0)
    folder = tmp_path / "seams"
    folder.mkdir()
    frames = rng.normal(size=(2, 6, 3))
    for index, positions in enumerate(frames):
        text = "\n".join("v " + " ".join(repr(float(c)) for c in row) for row in positions) + "\n"
        text += "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nvn 0 1 0\n"
        text += "usemtl skin\nf 6/1/1 4/2/1 2/3/1\nf 2/4/2 4/1/2 1/2/2\n"
        # a quad not reaching vertex 6, so trimesh gives this part a shorter vertex list
        text += "usemtl cloth\nf 1/3/1 2/4/2 4/1/1 5/2/2\n"  # vertex 3 is never used
        (folder / f"pose{index}.obj").write_text(text)

    sequence = read_mesh_sequence(str(folder))

    np.testing.assert_array_equal(sequence.vertices, frames)
    assert sequence.faces.shape == (4, 3)
    used = {tuple(sorted(f)) for f in sequence.faces}
    assert (1, 3, 5) in used and (0, 1, 3) in used  # zero-based triangles from the first material


def test_obj_quads_triangulated(tmp_path):
    folder = write_frames(tmp_path / "quads")
    assert_square_faces(read_mesh_sequence(str(folder)).faces)


# ---------------------------------------------------------------- array files


def test_npz_with_and_without_fps(tmp_path):
    vertices = np.stack([frame_positions(f) for f in range(4)])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    np.savez(tmp_path / "a.npz", vertices=vertices, faces=faces, fps=np.float64(12.5))
    np.savez(tmp_path / "b.npz", vertices=vertices.astype(np.float32), faces=faces.astype(np.int32))

    a = read_mesh_sequence(str(tmp_path / "a.npz"))
    b = read_mesh_sequence(str(tmp_path / "b.npz"))
    c = read_mesh_sequence(str(tmp_path / "a.npz"), fps=60)

    np.testing.assert_array_equal(a.vertices, vertices)
    np.testing.assert_array_equal(a.faces, faces)
    assert (a.fps, b.fps, c.fps) == (12.5, 24.0, 60.0)
    assert b.vertices.dtype == np.float64 and b.faces.dtype == np.int64


@pytest.mark.parametrize("ext", ["h5", "hdf5"])
def test_h5_arrays(tmp_path, ext):
    vertices = np.stack([frame_positions(f) for f in range(3)])
    with h5py.File(tmp_path / f"seq.{ext}", "w") as f:
        f["vertices"] = vertices
        f["faces"] = np.array([[0, 1, 2]])
        f.attrs["fps"] = 30.0
    sequence = read_mesh_sequence(str(tmp_path / f"seq.{ext}"))
    np.testing.assert_array_equal(sequence.vertices, vertices)
    assert sequence.fps == 30.0


# ---------------------------------------------------------------- USD input


def write_usd_sequence(path, frames=3, fps=12.0, static_first=True):
    """A quad + triangle under a translated Xform, points sampled at time codes 0..frames-1."""
    stage = Usd.Stage.CreateNew(str(path))
    stage.SetTimeCodesPerSecond(fps)
    if static_first:
        still = UsdGeom.Mesh.Define(stage, "/a_static")
        still.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(SQUARE.astype(np.float32)))
        still.CreateFaceVertexCountsAttr([3])
        still.CreateFaceVertexIndicesAttr([0, 1, 2])
    xform = UsdGeom.Xform.Define(stage, "/world")
    xform.AddTranslateOp().Set(Gf.Vec3d(10, 0, 0))
    mesh = UsdGeom.Mesh.Define(stage, "/world/body")
    mesh.CreateFaceVertexCountsAttr([4, 3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3, 1, 4, 2])
    points = mesh.CreatePointsAttr()
    for frame in range(frames):
        points.Set(Vt.Vec3fArray.FromNumpy(frame_positions(frame).astype(np.float32)), frame)
    stage.GetRootLayer().Save()
    return path


def test_usd_mesh_with_time_samples(tmp_path):
    path = write_usd_sequence(tmp_path / "anim.usda")

    sequence = read_mesh_sequence(str(path))

    assert sequence.vertices.shape == (3, 5, 3)
    # world space: the Xform's translation is applied
    np.testing.assert_allclose(sequence.vertices[2], frame_positions(2) + [10, 0, 0], atol=1e-6)
    assert sequence.faces.tolist() == [[0, 1, 2], [0, 2, 3], [1, 4, 2]]  # fan, in polygon order
    assert sequence.fps == 12.0
    explicit = read_mesh_sequence(str(path), prim="/world/body", fps=25)
    np.testing.assert_array_equal(explicit.vertices, sequence.vertices)
    assert explicit.fps == 25.0


def test_usd_left_handed_winding_is_flipped(tmp_path):
    path = write_usd_sequence(tmp_path / "left.usda", static_first=False)
    stage = Usd.Stage.Open(str(path))
    UsdGeom.Mesh(stage.GetPrimAtPath("/world/body")).CreateOrientationAttr(UsdGeom.Tokens.leftHanded)
    stage.GetRootLayer().Save()
    del stage
    assert read_mesh_sequence(str(path)).faces.tolist() == [[0, 2, 1], [0, 3, 2], [1, 2, 4]]


# ---------------------------------------------------------------- errors


def assert_format_error(spec, *words, **kwargs):
    with pytest.raises(FormatError) as caught:
        read_mesh_sequence(str(spec), **kwargs)
    message = str(caught.value)
    for word in words:
        assert str(word) in message, message
    return message


def test_error_missing_path(tmp_path):
    assert_format_error(tmp_path / "nothing", tmp_path / "nothing", "no such file")


def test_error_empty_folder_and_glob(tmp_path):
    (tmp_path / "empty").mkdir()
    assert_format_error(tmp_path / "empty", tmp_path / "empty", "no .obj")
    assert_format_error(tmp_path / "x-*.obj", "x-*.obj", "matches no files")


def test_error_glob_matching_a_non_frame_file(tmp_path):
    write_frames(tmp_path)
    (tmp_path / "frame.txt").write_text("x")
    assert_format_error(tmp_path / "frame*", tmp_path / "frame.txt", "not a frame file")


def test_error_unknown_extension_and_single_frame(tmp_path):
    (tmp_path / "a.stl").write_text("x")
    assert_format_error(tmp_path / "a.stl", tmp_path / "a.stl", "unknown extension")
    write_obj(tmp_path / "one.obj", SQUARE)
    assert_format_error(tmp_path / "one.obj", tmp_path / "one.obj", "single frame")


def test_error_fewer_than_two_frames(tmp_path):
    folder = write_frames(tmp_path / "f", numbers=(1,))
    assert_format_error(folder, folder, "at least 2")


def test_error_vertex_count_mismatch_names_first_offending_frame(tmp_path):
    folder = write_frames(tmp_path / "f", numbers=(1, 2, 3, 4))
    bad = folder / "frame3.obj"
    write_obj(bad, np.vstack([frame_positions(0), [[5, 5, 5]]]))
    write_obj(folder / "frame4.obj", np.vstack([frame_positions(0), [[5, 5, 5]]]))
    message = assert_format_error(folder, bad, "6 vertices", "frame1.obj")
    assert "frame4" not in message


def test_error_faces_mismatch(tmp_path):
    folder = write_frames(tmp_path / "f")
    bad = folder / "frame2.obj"
    write_obj(bad, frame_positions(1), [[0, 1, 2], [0, 2, 3], [1, 4, 2]])  # same count, other split
    assert_format_error(folder, bad, "faces differ")


def test_error_nan_in_a_frame_file(tmp_path):
    folder = write_frames(tmp_path / "f")
    bad = folder / "frame10.obj"
    write_obj(bad, np.vstack([[np.nan, 0, 0], SQUARE[1:]]))
    assert_format_error(folder, bad, "NaN")


def test_error_unreadable_frame_file(tmp_path):
    folder = write_frames(tmp_path / "f")
    bad = folder / "frame2.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 9\nend_header\n\x00")
    assert_format_error(folder, bad)


@pytest.mark.parametrize("arrays,words", [
    (dict(vertices=np.zeros((3, 4, 3))), ["no 'faces'"]),
    (dict(faces=np.zeros((1, 3), int)), ["no 'vertices'"]),
    (dict(vertices=np.zeros((1, 4, 3)), faces=[[0, 1, 2]]), ["at least 2"]),
    (dict(vertices=np.zeros((3, 0, 3)), faces=np.zeros((1, 3), int)), ["no vertices"]),
    (dict(vertices=np.zeros((3, 4, 2)), faces=[[0, 1, 2]]), ["shape"]),
    (dict(vertices=np.full((3, 4, 3), np.inf), faces=[[0, 1, 2]]), ["NaN or inf", "frame 0"]),
    (dict(vertices=np.zeros((3, 4, 3)), faces=[[0, 1, 4]]), ["face indices"]),
    (dict(vertices=np.zeros((3, 4, 3)), faces=[[0.0, 1, 2]]), ["integers"]),
    (dict(vertices=np.zeros((3, 4, 3)), faces=[[0, 1, 2, 3]]), ["(triangles, 3)"]),
    (dict(vertices=np.zeros((3, 4, 3)), faces=[[0, 1, 2]], fps=[1, 2]), ["'fps'"]),
])
def test_error_bad_npz_contents(tmp_path, arrays, words):
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    assert_format_error(path, path, *words)


def test_error_nan_in_npz_names_frame(tmp_path):
    vertices = np.zeros((4, 3, 3))
    vertices[2, 1, 0] = np.nan
    np.savez(tmp_path / "n.npz", vertices=vertices, faces=[[0, 1, 2]])
    assert_format_error(tmp_path / "n.npz", "frame 2")


@pytest.mark.parametrize("name,words", [("garbage.npz", "not an .npz"), ("garbage.h5", "cannot read as HDF5"),
                                        ("garbage.usda", "cannot open as USD"), ("garbage.usdc", "cannot open as USD")])
def test_error_unreadable_container(tmp_path, name, words):
    path = tmp_path / name
    path.write_bytes(b"\x00\x01 this is not the right format at all")
    assert_format_error(path, path, words)


def test_error_usda_syntax_error_is_one_line(tmp_path):
    path = tmp_path / "broken.usda"
    path.write_text('#usda 1.0\ndef Mesh "m" {\n  point3f[] points = [(1, 2\n}\n')
    message = assert_format_error(path, path, "parse error")
    assert "\n" not in message and "pxrInternal" not in message


def test_error_h5_without_arrays(tmp_path):
    with h5py.File(tmp_path / "e.h5", "w") as f:
        f.create_group("vertices")  # a group, not an array
    assert_format_error(tmp_path / "e.h5", "no 'vertices'")


def test_error_usd_prim_problems(tmp_path):
    path = write_usd_sequence(tmp_path / "anim.usdc")
    assert_format_error(path, path, "no prim at /nope", prim="/nope")
    assert_format_error(path, path, "/world is a Xform, not a Mesh", prim="/world")
    assert_format_error(path, path, "/a_static", "at least 2", prim="/a_static")
    assert_format_error(path, path, "not an absolute prim path", prim="world/body")
    write_obj(tmp_path / "x.obj", SQUARE)
    assert_format_error(tmp_path / "*.obj", "prim path applies only to USD", prim="/world")


def test_error_usd_without_animated_mesh(tmp_path):
    stage = Usd.Stage.CreateNew(str(tmp_path / "still.usda"))
    UsdGeom.Mesh.Define(stage, "/m").CreatePointsAttr(Vt.Vec3fArray.FromNumpy(SQUARE.astype(np.float32)))
    stage.GetRootLayer().Save()
    assert_format_error(tmp_path / "still.usda", "still.usda", "no Mesh with time-sampled points")
    stage = Usd.Stage.CreateNew(str(tmp_path / "empty.usda"))
    UsdGeom.Xform.Define(stage, "/x")
    stage.GetRootLayer().Save()
    assert_format_error(tmp_path / "empty.usda", "empty.usda", "no Mesh prim")


def test_error_usd_single_time_sample(tmp_path):
    path = write_usd_sequence(tmp_path / "one.usda", frames=1, static_first=False)
    assert_format_error(path, path, "1 time sample")


def test_fps_argument_must_be_positive(tmp_path):
    with pytest.raises(ValueError):
        read_mesh_sequence(str(write_frames(tmp_path / "f")), fps=0)


def test_paths_can_be_pathlike(tmp_path):
    folder = write_frames(tmp_path / "f")
    assert read_mesh_sequence(folder).source == os.fspath(folder)


# ---------------------------------------------------------------- material UVs (issue 23)


def test_obj_uvs_per_corner_across_a_seam_keep_the_vertices(tmp_path):
    """A vertex with several UVs stays one vertex; its corners keep their own UVs, whatever the
    order trimesh returns the faces in (materials) and however it splits a quad."""
    rng = np.random.default_rng(3)
    frames = rng.normal(size=(2, 6, 3))
    uvs = {1: (0.0, 0.0), 2: (1.0, 0.0), 3: (1.0, 1.0), 4: (0.0, 1.0), 5: (0.5, 0.5), 6: (0.25, 0.75)}
    for index, positions in enumerate(frames):
        text = "".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in positions)
        text += "".join(f"vt {u} {v}\n" for u, v in uvs.values()) + "vn 0 0 1\n"
        # vertex 3 (one-based) has UVs 3, 5 and 1: a seam; vertex 1 has 1 and 6
        text += "usemtl a\nf 1/1/1 2/2/1 3/3/1 4/4/1\nusemtl b\nf 3/5/1 2/1/1 5/2/1\nf 5/3 6/4 3/1\nf 6/6 1/6 4/4\n"
        (tmp_path / f"f{index}.obj").write_text(text)

    sequence = read_mesh_sequence(str(tmp_path / "f*.obj"))

    np.testing.assert_array_equal(sequence.vertices, frames)  # count and order kept
    assert sequence.face_uvs.shape == (5, 3, 2) and sequence.face_uvs.dtype == np.float64
    corners = {(1, 1), (2, 2), (3, 3), (4, 4), (3, 5), (2, 1), (5, 2), (5, 3), (6, 4), (3, 1), (6, 6), (1, 6)}
    for face, face_uvs in zip(sequence.faces, sequence.face_uvs):
        for vertex, uv in zip(face, face_uvs):
            assert any(v == vertex + 1 and tuple(uv) == uvs[t] for v, t in corners), (face, face_uvs)
    # each triangle keeps its polygon's UVs: the quad's two halves, the other three whole
    expected = {(1, 2, 3): [1, 2, 3], (3, 4, 1): [3, 4, 1], (3, 2, 5): [5, 1, 2], (5, 6, 3): [3, 4, 1],
                (6, 1, 4): [6, 6, 4]}
    got = {}
    for face, face_uvs in zip(sequence.faces + 1, sequence.face_uvs):
        shift = int(np.argmin(face))  # compare triangles up to a rotation of their corners
        key = tuple(np.roll(face, -shift))
        got[key] = [next(t for t, uv in uvs.items() if uv == tuple(c)) for c in np.roll(face_uvs, -shift, axis=0)]
    want = {}
    for face, ts in expected.items():
        shift = int(np.argmin(face))
        want[tuple(np.roll(face, -shift))] = list(np.roll(ts, -shift))
    assert got == want


def test_obj_without_uvs_on_every_corner_has_none(tmp_path):
    folder = write_frames(tmp_path / "plain")
    assert read_mesh_sequence(str(folder)).face_uvs is None
    partial = tmp_path / "partial"
    partial.mkdir()
    for index in range(2):
        text = "".join(f"v {x} {y} {z}\n" for x, y, z in frame_positions(index))
        (partial / f"f{index}.obj").write_text(text + "vt 0 0\nvt 1 0\nvt 1 1\nf 1/1 2/2 3/3\nf 2 5 3\n")
    sequence = read_mesh_sequence(str(partial))
    assert sequence.face_uvs is None and sequence.vertices.shape == (2, 5, 3)


def test_obj_uv_index_beyond_the_list_is_one_error(tmp_path):
    for index in range(2):
        text = "".join(f"v {x} {y} {z}\n" for x, y, z in frame_positions(index))
        (tmp_path / f"f{index}.obj").write_text(text + "vt 0 0\nvt 1 0\nf 1/1 2/2 3/7\n")
    assert_format_error(tmp_path / "f*.obj", "f0.obj", "texture coordinate (vt) 7")


def usd_with_st(path, interpolation, values, indices=None, static_first=False):
    path = write_usd_sequence(path, static_first=static_first)
    stage = Usd.Stage.Open(str(path))
    primvar = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/world/body")).CreatePrimvar(
        "st", Sdf.ValueTypeNames.TexCoord2fArray, interpolation)
    primvar.Set(Vt.Vec2fArray.FromNumpy(np.asarray(values, dtype=np.float32)))
    if indices is not None:
        primvar.SetIndices(Vt.IntArray(list(indices)))
    stage.GetRootLayer().Save()
    del stage
    return path


#: faceVertexIndices of write_usd_sequence: the quad 0 1 2 3 then the triangle 1 4 2 (7 corners),
#: fanned into (0, 1, 2), (0, 2, 3), (1, 4, 2): corners (0, 1, 2), (0, 2, 3), (4, 5, 6).
USD_CORNERS = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6]])


def test_usd_face_varying_indexed_st_per_corner(tmp_path):
    values = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.25]])
    indices = [0, 1, 2, 3, 4, 1, 2]  # vertex 1 has UV 1 in the quad, 4 in the triangle: a seam
    sequence = read_mesh_sequence(str(usd_with_st(tmp_path / "fv.usda", UsdGeom.Tokens.faceVarying, values,
                                                  indices, static_first=True)))
    np.testing.assert_array_equal(sequence.face_uvs, values[np.array(indices)][USD_CORNERS])
    assert sequence.vertices.shape == (3, 5, 3)
    flat = values[np.array(indices)]  # the same, not indexed
    unindexed = read_mesh_sequence(str(usd_with_st(tmp_path / "flat.usda", UsdGeom.Tokens.faceVarying, flat)))
    np.testing.assert_array_equal(unindexed.face_uvs, sequence.face_uvs)


@pytest.mark.parametrize("interpolation", ["vertex", "varying"])
def test_usd_vertex_st_indexed_by_the_faces(tmp_path, interpolation):
    values = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [2, 0.5]]) / 2
    sequence = read_mesh_sequence(str(usd_with_st(tmp_path / "v.usda", getattr(UsdGeom.Tokens, interpolation),
                                                  values)))
    np.testing.assert_array_equal(sequence.face_uvs, values[sequence.faces])


def test_usd_without_st_or_with_constant_st_has_none(tmp_path):
    assert read_mesh_sequence(str(write_usd_sequence(tmp_path / "none.usda"))).face_uvs is None
    path = usd_with_st(tmp_path / "c.usda", UsdGeom.Tokens.constant, [[0.5, 0.5]])
    assert read_mesh_sequence(str(path)).face_uvs is None


@pytest.mark.parametrize("interpolation, count, words", [
    ("faceVarying", 6, "6 values for faceVarying interpolation, which needs 7"),
    ("vertex", 4, "4 values for vertex interpolation, which needs 5"),
])
def test_usd_st_of_the_wrong_length_is_one_error(tmp_path, interpolation, count, words):
    path = usd_with_st(tmp_path / "bad.usda", getattr(UsdGeom.Tokens, interpolation), np.zeros((count, 2)))
    assert_format_error(path, "bad.usda", "primvars:st", words)


def test_usd_st_with_nan_is_one_error(tmp_path):
    values = np.zeros((5, 2))
    values[2, 1] = np.nan
    path = usd_with_st(tmp_path / "nan.usda", UsdGeom.Tokens.vertex, values)
    assert_format_error(path, "nan.usda", "primvars:st", "NaN")


def test_usd_st_index_out_of_range_is_one_error(tmp_path):
    path = usd_with_st(tmp_path / "idx.usda", UsdGeom.Tokens.faceVarying, np.zeros((2, 2)), [0, 1, 0, 1, 5, 0, 1])
    assert_format_error(path, "idx.usda", "primvars:st:indices holds 5, outside its 2 values")
