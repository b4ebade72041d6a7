"""Damage done to a stage file's datasets by the corrupted-file tests (test_faults.py,
test_damaged_attributes.py): one dataset at a time, in place."""

import h5py
import numpy as np


def damage_kinds(dtype):
    """The damages :func:`corrupt_dataset` does to a dataset of ``dtype``: NaN, a shape one value
    short, strings; an index far out of range for integers."""
    if dtype.kind not in "fiub":
        return ("shape",)
    return ("nan", "shape", "dtype") + (("range",) if dtype.kind in "iu" else ())


def corrupt_dataset(path, name, kind):
    """Replace the dataset ``name`` of the file at ``path`` by a damaged copy (:func:`damage_kinds`)."""
    with h5py.File(path, "r+") as f:
        value = f[name][()]
        del f[name]
        if kind == "nan":
            value = np.asarray(value, dtype=np.float64).copy()
            value.flat[value.size // 2] = np.nan
        elif kind == "shape":
            value = np.asarray(value).reshape(-1)[:-1] if np.size(value) > 1 else np.zeros((2, 2))
        elif kind == "dtype":
            value = np.array([b"x"] * max(1, min(np.size(value), 3)))
        else:  # an index far out of range
            value = np.asarray(value).copy()
            value.flat[0] = min(10 ** 6, np.iinfo(value.dtype).max)  # uint8 flags: 255
        f[name] = value
