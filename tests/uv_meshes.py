"""Inputs with material UVs for the tests of issue 23's UVs: the bending bar with cylindrical UVs
(a seam down its side, planar caps: many vertices carry several UVs), written as OBJ frames with
``vt`` or as USD with ``primvars:st``."""

import numpy as np

from skinsynth.pipeline.inputs.examples import bending_bar

LENGTH = 4.0  # bending_bar's default


def uv_bar(frames=40, rings=10, segments=8, cycles=2):
    """(vertices (F, V, 3), faces (T, 3), face_uvs (T, 3, 2)): the bar and its corner UVs, u around
    the side (0 … 1, the faces across the seam reaching 1), v along it, the caps planar."""
    vertices, faces = bending_bar(frames=frames, rings=rings, segments=segments, cycles=cycles)
    rest = vertices[0]
    corners = rest[faces]  # (T, 3, 3)
    u = (np.arctan2(corners[..., 2], corners[..., 1]) / (2 * np.pi)) % 1.0
    wraps = (u.max(axis=1) - u.min(axis=1)) > 0.5
    u[wraps] = np.where(u[wraps] < 0.25, u[wraps] + 1.0, u[wraps])
    face_uvs = np.stack([u, corners[..., 0] / LENGTH], axis=-1)
    caps = (faces >= rings * segments).any(axis=1)
    face_uvs[caps] = 0.5 + corners[caps][..., 1:]
    return vertices, faces, face_uvs


def distinct_uvs(face_uvs):
    """(uvs (N, 2), index (T, 3)): the distinct UVs and each corner's, as files list them."""
    uvs, index = np.unique(face_uvs.reshape(-1, 2), axis=0, return_inverse=True)
    return uvs, index.reshape(face_uvs.shape[:2])


def write_obj_frames(folder, vertices, faces, face_uvs):
    """One OBJ a frame, ``frame_NNN.obj``, every one with the same ``vt`` list and ``f v/vt``
    corners (exact round trip: repr of each float)."""
    folder.mkdir(parents=True, exist_ok=True)
    uvs, index = distinct_uvs(face_uvs)
    uv_text = "".join(f"vt {float(a)!r} {float(b)!r}\n" for a, b in uvs)
    face_text = "".join("f " + " ".join(f"{v + 1}/{t + 1}" for v, t in zip(fv, ft)) + "\n"
                        for fv, ft in zip(faces, index))
    for f, frame in enumerate(vertices):
        text = "".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in frame)
        (folder / f"frame_{f:03d}.obj").write_text(text + uv_text + face_text)
    return folder


def write_usd_sequence(path, vertices, faces, st, interpolation, indices=None, fps=24.0):
    """A Mesh ``/bar`` with points at time codes 0 … F−1 and ``primvars:st`` of ``interpolation``
    ("faceVarying": st per face corner, or "vertex"), with ``indices`` when given."""
    from pxr import Sdf, Usd, UsdGeom, Vt

    stage = Usd.Stage.CreateNew(str(path))
    stage.SetTimeCodesPerSecond(fps)
    mesh = UsdGeom.Mesh.Define(stage, "/bar")
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, dtype=np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.astype(np.int32).ravel()))
    points = mesh.CreatePointsAttr()
    for f, frame in enumerate(vertices):
        points.Set(Vt.Vec3fArray.FromNumpy(frame.astype(np.float32)), f)
    primvar = UsdGeom.PrimvarsAPI(mesh.GetPrim()).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                                getattr(UsdGeom.Tokens, interpolation))
    primvar.Set(Vt.Vec2fArray.FromNumpy(np.asarray(st, dtype=np.float32)))
    if indices is not None:
        primvar.SetIndices(Vt.IntArray.FromNumpy(np.asarray(indices, dtype=np.int32).ravel()))
    stage.GetRootLayer().Save()
    return path
