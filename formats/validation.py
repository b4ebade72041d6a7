"""One validation layer for the datasets of stage files: every array a command reads is checked
(kind, shape, finite values, range, consistency with the others) before use, and the error names
the file and the dataset.

A group is described by :class:`Field` entries. Shapes use symbols (``"V"``, ``"F"``, ``"B"``…)
that bind to the first size seen, so ``/mesh/rest_vertices (V, 3)`` and ``/skin/bone_indices
(V, K)`` must agree on ``V`` across groups; ranges may name a symbol (``high="B"``: an index
below the bone count).
"""

from dataclasses import dataclass

import numpy as np

from .errors import FormatError

_KINDS = {"float": "f", "int": "iu", "bool": "b"}


@dataclass(frozen=True)
class Field:
    """kind "float", "int" or "bool"; shape: sizes (int), symbols (str) or None (any size);
    finite: no NaN or inf (floats); low, high: inclusive low and exclusive high bounds, numbers or
    symbols; optional: may be absent."""

    kind: str
    shape: tuple
    finite: bool = True
    low: object = None
    high: object = None
    optional: bool = False


def _size(bound, dims):
    return dims[bound] if isinstance(bound, str) else bound


def check_group(path, group, data, fields, dims):
    """Check ``data`` (a dict of arrays, as read) against ``fields`` {name: Field}; ``dims`` (a
    dict, updated) binds the shape symbols. Raises FormatError naming ``path`` and the dataset."""
    for name, field in fields.items():
        where = f"/{group}/{name}"
        if name not in data:
            if field.optional:
                continue
            raise FormatError(path, f"{where} is missing: the file is incomplete")
        value = np.asarray(data[name])
        if value.dtype.kind not in _KINDS[field.kind] and not (field.kind == "bool" and value.dtype.kind in "iu"):
            raise FormatError(path, f"{where} must hold {field.kind} values, not {value.dtype}")
        if value.ndim != len(field.shape):
            raise FormatError(path, f"{where} must have {len(field.shape)} dimensions {_shape_text(field.shape)}, "
                                    f"not shape {value.shape}")
        for axis, (want, got) in enumerate(zip(field.shape, value.shape)):
            if want is None:
                continue
            if isinstance(want, str) and want not in dims:
                dims[want] = int(got)
            if _size(want, dims) != got:
                raise FormatError(path, f"{where} has shape {value.shape}, but {_shape_text(field.shape)} needs "
                                        f"{want} = {_size(want, dims)} on axis {axis} (from the file's other datasets)")
        if value.size == 0:
            continue
        if field.kind == "float" and field.finite and not np.isfinite(value).all():
            raise FormatError(path, f"{where} holds NaN or inf values")
        if field.low is not None and value.min() < _size(field.low, dims):
            raise FormatError(path, f"{where} holds {value.min()}, below its lowest allowed value "
                                    f"{_size(field.low, dims)}")
        if field.high is not None and value.max() >= _size(field.high, dims):
            bound = f"{field.high} = {_size(field.high, dims)}" if isinstance(field.high, str) else field.high
            raise FormatError(path, f"{where} holds {value.max()}, not below {bound}")


def check_attribute(path, group, data, name, kind, low=None, high=None, choices=None, optional=True):
    """An attribute ``@name`` of a group: a finite number of ``kind`` ("float", "int") within
    [low, high], or one of ``choices`` (strings). Returns its value (None when optional and absent)."""
    where = f"/{group}/@{name}"
    if f"@{name}" not in data:
        if optional:
            return None
        raise FormatError(path, f"{where} is missing: the file is incomplete")
    value = data[f"@{name}"]
    if choices is not None:
        if str(value) not in choices:
            raise FormatError(path, f"{where} is {value!r}; it must be one of {', '.join(choices)}")
        return str(value)
    number = np.asarray(value)
    if number.ndim != 0 or number.dtype.kind not in ("iu" if kind == "int" else "iuf"):
        raise FormatError(path, f"{where} must be one {'integer' if kind == 'int' else 'number'}, not {value!r}")
    number = number.item()
    if not np.isfinite(number) or (low is not None and number < low) or (high is not None and number > high):
        span = f"[{low if low is not None else '−∞'}, {high if high is not None else '∞'}]"
        raise FormatError(path, f"{where} is {number}; it must be a finite number in {span}")
    return number


def _shape_text(shape):
    return "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"


MESH = {"rest_vertices": Field("float", ("V", 3)), "faces": Field("int", ("T", 3), low=0, high="V")}
EXAMPLES = {"vertices": Field("float", ("F", "V", 3))}
SKIN = {
    "bone_indices": Field("int", ("V", "K"), low=0, high="B"),
    "bone_weights": Field("float", ("V", "K"), low=0.0),
    "rotations": Field("float", ("F", "B", 3, 3)),
    "translations": Field("float", ("F", "B", 3)),
    "dual_quaternions": Field("float", ("F", "B", 8)),
    "bone_rest_frames": Field("float", ("B", 4, 4)),
}


def check_skin(path, model):
    """/mesh, /examples and /skin of any file that carries a skin fit; returns the bound sizes."""
    dims = {}
    check_group(path, "skin", model["skin"], {"rotations": SKIN["rotations"]}, dims)  # F and B first
    check_group(path, "mesh", model["mesh"], MESH, dims)
    check_group(path, "examples", model["examples"], EXAMPLES, dims)
    check_group(path, "skin", model["skin"], SKIN, dims)
    weights = np.asarray(model["skin"]["bone_weights"])
    if not np.allclose(weights.sum(axis=1), 1.0, atol=1e-6):
        row = int(np.argmax(np.abs(weights.sum(axis=1) - 1.0)))
        raise FormatError(path, f"/skin/bone_weights rows must sum to 1 (vertex {row} sums to "
                                f"{weights[row].sum():.6g})")
    check_attribute(path, "examples", model["examples"], "fps", "float", low=1e-9)
    check_attribute(path, "mesh", model["mesh"], "rest_frame", "int", low=0, high=dims["F"] - 1)
    return dims
