"""Write small C3D marker takes for tests, with ezc3d's writer (Intel floats, scale -1)."""

import os

import numpy as np


def write_c3d(path, labels, points, rate, units="mm", first_frame=0):
    """Write ``points (T, M, 3)`` (in ``units``, the file's ``POINT:UNITS``) of the M ``labels``
    at ``rate`` samples per second, the first sample being frame ``first_frame`` (counted from 0,
    as ezc3d reports it; the file holds it 1-based). A sample with any NaN coordinate is written
    missing (residual −1). Returns ``path``."""
    import ezc3d

    points = np.asarray(points, dtype=np.float64)
    frames, markers = points.shape[:2]
    assert points.shape == (frames, markers, 3) and len(labels) == markers
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [float(rate)]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = list(labels)
    c3d["parameters"]["POINT"]["UNITS"]["value"] = [units]
    coordinates = np.ones((4, markers, frames))
    coordinates[:3] = points.transpose(2, 1, 0)
    missing = np.isnan(points).any(axis=2).T  # (M, T)
    coordinates[:3, missing] = 0.0
    residuals = np.where(missing, -1.0, 0.0)[None]
    c3d["data"]["points"] = coordinates
    c3d["data"]["meta_points"] = {"residuals": residuals, "camera_masks": np.zeros((7, markers, frames), bool)}
    c3d["header"]["points"]["first_frame"] = int(first_frame)
    c3d.write(os.fspath(path))
    return path
