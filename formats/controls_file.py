"""The ``controls`` stage file written by ``select-controls``.

It copies ``/mesh``, ``/examples`` and ``/skin`` forward unchanged from the skin file (see
:mod:`skinsynth.formats.skin_file`) and adds:

- ``/controls``: ``vertex_indices (N,)`` int64 the control vertices in the order chosen,
  ``control_basis (N,)`` int32 the rotated basis each one represents, ``reasons (N,)``
  variable-length UTF-8 strings (why each was chosen), ``candidate_vertices (2K,)`` int64 the two
  representative vertices of each varimax-rotated PCA basis (basis 0 first),
  ``candidate_basis (2K,)`` int32, ``candidate_loading (2K,)`` float64 (length of the candidate's
  loading 3-vector in its basis), ``basis_variance (K,)`` float64 (share of the in-place
  variance of each rotated basis, decreasing); attributes ``@components`` (K), ``@count`` (N),
  ``@method`` ("auto" or "user"), ``@explained`` (sum of ``basis_variance``), ``@min_spacing``
  (absolute spacing the automatic rule used), ``@clips`` (the names of the clips of
  ``/examples`` whose frames the selection used, in file order; ``select-controls --clips``;
  absent in files written before it, which used every frame), and where ``select-controls
  --markers`` chose the controls, the marker layout: ``marker_labels (N,)`` UTF-8 (the marker on
  each control, in control order) and ``marker_offsets (N,)`` float64 (each marker's distance out
  from the skin along the rest normal, mesh units); ``play`` and ``view`` read a C3D take with it.
"""

from dataclasses import dataclass

import h5py
import numpy as np

from .errors import FormatError
from .model import read_model, require, text
from .validation import check_controls

#: Groups a controls file carries forward from the skin file, unchanged.
CARRIED_GROUPS = ("mesh", "examples", "skin")
_DATASETS = ("vertex_indices", "candidate_vertices", "candidate_basis", "candidate_loading", "basis_variance",
             "reasons")


@dataclass
class ControlsData:
    """What ``/controls`` holds, as plain arrays (see the module docstring)."""

    vertex_indices: np.ndarray
    control_basis: np.ndarray
    reasons: list
    candidate_vertices: np.ndarray
    candidate_basis: np.ndarray
    candidate_loading: np.ndarray
    basis_variance: np.ndarray
    components: int
    count: int
    method: str
    explained: float
    min_spacing: float
    clips: tuple = ()
    marker_labels: tuple = ()
    marker_offsets: np.ndarray | None = None


def controls_groups(selection, model=None, clips=None, markers=None):
    """The HDF5 groups of a controls file from a pipeline ControlSelection.

    model: the skin file as :func:`~skinsynth.formats.model.read_model` returned it; its
    ``/mesh``, ``/examples`` and ``/skin`` are carried forward unchanged. clips: the names of the
    clips the selection used (``@clips``; None writes no attribute). markers: (labels (N,),
    offsets (N,)) of a marker layout, in control order, or None.
    """
    groups = {} if model is None else {name: model[name] for name in CARRIED_GROUPS}
    groups["controls"] = {
        "vertex_indices": np.asarray(selection.indices, dtype=np.int64),
        "control_basis": np.asarray(selection.control_basis, dtype=np.int32),
        "reasons": np.array([str(r) for r in selection.reasons], dtype=h5py.string_dtype("utf-8")),
        "candidate_vertices": np.asarray(selection.candidates, dtype=np.int64),
        "candidate_basis": np.asarray(selection.candidate_basis, dtype=np.int32),
        "candidate_loading": np.asarray(selection.candidate_loading, dtype=np.float64),
        "basis_variance": np.asarray(selection.basis_variance, dtype=np.float64),
        "@components": int(selection.components),
        "@count": int(len(selection.indices)),
        "@method": str(selection.method),
        "@explained": float(selection.explained),
        "@min_spacing": float(selection.min_spacing),
    }
    if clips is not None:
        groups["controls"]["@clips"] = [str(name) for name in clips]
    if markers is not None:
        labels, offsets = markers
        groups["controls"]["marker_labels"] = np.array([str(label) for label in labels],
                                                       dtype=h5py.string_dtype("utf-8"))
        groups["controls"]["marker_offsets"] = np.asarray(offsets, dtype=np.float64)
    return groups


def read_controls(path, model=None):
    """Read ``/controls`` of a file that carries one; FormatError when it is missing or inconsistent."""
    model = read_model(path) if model is None else model
    if "controls" not in model:
        raise FormatError(path, f"is a '{model['stage']}' file without control points (/controls); "
                                "run select-controls first")
    group = require(model, path, "controls", _DATASETS)
    if "mesh" in model and "rest_vertices" in model["mesh"]:
        check_controls(path, model, {"V": np.shape(model["mesh"]["rest_vertices"])[0]})
    indices = np.asarray(group["vertex_indices"]).astype(np.int64)
    reasons = [text(r) for r in np.atleast_1d(group["reasons"])]
    candidates = np.asarray(group["candidate_vertices"]).astype(np.int64)
    variance = np.asarray(group["basis_variance"], dtype=np.float64)
    candidate_basis = np.asarray(group["candidate_basis"]).astype(np.int32)
    control_basis = np.asarray(group.get("control_basis", np.full(indices.shape, -1))).astype(np.int32)
    if indices.ndim != 1 or indices.size == 0 or len(reasons) != indices.size or control_basis.shape != indices.shape:
        raise FormatError(path, "/controls: vertex_indices, control_basis and reasons must be equally long and not empty")
    if candidates.shape != candidate_basis.shape or candidates.shape != np.shape(group["candidate_loading"]):
        raise FormatError(path, "/controls: candidate arrays of different lengths")
    if candidate_basis.size and (candidate_basis.min() < 0 or candidate_basis.max() >= variance.size):
        raise FormatError(path, "/controls: candidate_basis refers to a basis that basis_variance lacks")
    if "mesh" in model and "rest_vertices" in model["mesh"]:
        count = model["mesh"]["rest_vertices"].shape[0]
        if indices.min() < 0 or indices.max() >= count or (candidates.size and
                                                          (candidates.min() < 0 or candidates.max() >= count)):
            raise FormatError(path, f"/controls: vertex ids outside the mesh's {count} vertices")
    if np.unique(indices).size != indices.size:
        raise FormatError(path, "/controls: a control vertex is listed twice")
    labels, offsets = (), None
    if ("marker_labels" in group) != ("marker_offsets" in group):
        raise FormatError(path, "/controls has one of marker_labels and marker_offsets without the other")
    if "marker_labels" in group:
        labels = tuple(text(label) for label in np.atleast_1d(group["marker_labels"]))
        offsets = np.asarray(group["marker_offsets"], dtype=np.float64)
        if len(labels) != indices.size or offsets.shape != indices.shape or not np.isfinite(offsets).all():
            raise FormatError(path, "/controls: marker_labels and marker_offsets must give one finite entry per "
                                    "control vertex")
    return ControlsData(
        vertex_indices=indices, control_basis=control_basis, reasons=reasons, candidate_vertices=candidates,
        candidate_basis=candidate_basis, candidate_loading=np.asarray(group["candidate_loading"], dtype=np.float64),
        basis_variance=variance, components=int(group.get("@components", variance.size)),
        count=int(group.get("@count", indices.size)), method=text(group.get("@method", "")),
        explained=float(group.get("@explained", variance.sum())),
        min_spacing=float(group.get("@min_spacing", np.nan)),
        clips=tuple(text(name) for name in np.atleast_1d(group.get("@clips", []))),
        marker_labels=labels, marker_offsets=offsets)
