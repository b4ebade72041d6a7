"""A production capture as a DCC pipeline writes it (USD, Z up, centimetres, 25 fps, time codes
1001…), shared by the interchange and Blender tests."""

import numpy as np
from pxr import Usd, UsdGeom, Vt

START, FPS, FRAMES = 1001, 25.0, 40


def production_capture(path, vertices, faces):
    """A capture as a DCC pipeline writes it: centimetres, Z up, 25 fps, time codes 1001…,
    the mesh at /World/body under an Xform."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    stage.SetTimeCodesPerSecond(FPS)
    stage.SetFramesPerSecond(FPS)
    stage.SetStartTimeCode(START)
    stage.SetEndTimeCode(START + len(vertices) - 1)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    mesh = UsdGeom.Mesh.Define(stage, "/World/body")
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, dtype=np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.astype(np.int32).ravel()))
    points = mesh.CreatePointsAttr()
    for f, frame in enumerate(vertices):
        points.Set(Vt.Vec3fArray.FromNumpy((100.0 * frame).astype(np.float32)), Usd.TimeCode(START + f))
    stage.GetRootLayer().Save()
