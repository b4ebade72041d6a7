"""numpy arrays onto a device, in the dtypes and layouts the kernels take (host code)."""

import numpy as np

from . import runtime


def float32_array(values, dtype, device):
    """values as a warp array of ``dtype`` (float32 scalars, vec3, mat33, vec8, …) on ``device``."""
    return runtime.warp().array(np.ascontiguousarray(values, dtype=np.float32), dtype=dtype, device=device)


def float64_array(values, dtype, device):
    """values as a warp array of ``dtype`` (float64 scalars, vec8d) on ``device``."""
    return runtime.warp().array(np.ascontiguousarray(values, dtype=np.float64), dtype=dtype, device=device)


def predictor_columns(predictor):
    """M (8B, n_p) -> (B, n_p, 8) float64, so each bone's column j is one vec8d."""
    predictor = np.asarray(predictor)
    bones = predictor.shape[0] // 8
    return np.ascontiguousarray(predictor.reshape(bones, 8, -1).transpose(0, 2, 1), dtype=np.float64)
