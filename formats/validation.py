"""One validation layer for the datasets of stage files: every array a command reads is checked
(kind, shape, finite values, range, consistency with the others) before use, and the error names
the file and the dataset.

A group is described by :class:`Field` entries. Shapes use symbols (``"V"``, ``"F"``, ``"B"``…)
that bind to the first size seen, so ``/mesh/rest_vertices (V, 3)`` and ``/skin/bone_indices
(V, K)`` must agree on ``V`` across groups; ranges may name a symbol (``high="B"``: an index
below the bone count).
"""

import re
from dataclasses import dataclass

import numpy as np

from .errors import FormatError

_KINDS = {"float": "f", "int": "iu", "bool": "b"}
_MEANING = {"V": "mesh's vertices", "B": "skin's bones", "F": "clip's frames"}


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
    dict, updated) binds the shape symbols. Raises FormatError naming ``path`` and the dataset.
    A value may also be a dataset read block by block (it has ``all_finite``:
    :class:`~skinsynth.formats.hdf5_storage.DatasetSummary`): the same checks, verdicts and
    messages, from its shape, dtype, smallest and largest value."""
    for name, field in fields.items():
        where = f"/{group}/{name}"
        if name not in data:
            if field.optional:
                continue
            raise FormatError(path, f"{where} is missing: the file is incomplete")
        value = data[name] if hasattr(data[name], "all_finite") else np.asarray(data[name])
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
        if field.kind == "float" and field.finite and not _all_finite(value):
            raise FormatError(path, f"{where} holds NaN or inf values")
        if field.low is not None and value.min() < _size(field.low, dims):
            raise FormatError(path, f"{where} holds {value.min()}, below its lowest allowed value "
                                    f"{_size(field.low, dims)}")
        if field.high is not None and value.max() >= _size(field.high, dims):
            high = _size(field.high, dims)
            if field.high in _MEANING:
                raise FormatError(path, f"{where} holds {value.max()}, outside the {_MEANING[field.high]} "
                                        f"({high}: 0..{high - 1})")
            raise FormatError(path, f"{where} holds {value.max()}, not below {field.high} = {high}")


def _all_finite(value):
    return value.all_finite() if hasattr(value, "all_finite") else bool(np.isfinite(value).all())


def check_attribute(path, group, data, name, kind, low=None, high=None, choices=None, optional=True):
    """An attribute ``@name`` of a group: a finite number of ``kind`` ("float", "int", "bool")
    within [low, high], text (``kind`` "text"), or one of ``choices`` (strings). Returns its value
    (None when optional and absent)."""
    where = f"/{group}/@{name}"
    if f"@{name}" not in data:
        if optional:
            return None
        raise FormatError(path, f"{where} is missing: the file is incomplete")
    value = data[f"@{name}"]
    if kind == "text":
        if not isinstance(value, str):
            raise FormatError(path, f"{where} must be text, not {value!r}")
        return value
    if kind == "bool":
        if not (np.ndim(value) == 0 and np.asarray(value).dtype.kind in "biu" and value in (0, 1)):
            raise FormatError(path, f"{where} must be true or false, not {value!r}")
        return bool(value)
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


@dataclass(frozen=True)
class Attribute:
    """An attribute's kind ("float", "int", "bool", "text", "names": a list of clip names, or
    "choice" of ``choices``), its inclusive bounds (numbers, or symbols of ``dims``) and whether
    it must be there."""

    kind: str
    low: object = None
    high: object = None
    choices: tuple = ()
    optional: bool = True


def check_attributes(path, group, data, attributes, dims, clip_names=None):
    """Every attribute of ``attributes`` {name: Attribute} that ``data`` (a read group) holds,
    checked (:func:`check_attribute`); a "names" attribute must name clips of ``clip_names``.
    Returns {name: value} of those present."""
    found = {}
    for name, spec in attributes.items():
        where = f"/{group}/@{name}"
        if spec.kind == "names":
            if f"@{name}" not in data:
                continue
            value = data[f"@{name}"]
            names = list(value) if np.ndim(value) == 1 else None  # a list, even of one clip (as check_clips)
            if names is None or not names or not all(isinstance(n, str) for n in names) or (
                    clip_names is not None and not set(names) <= set(clip_names)):
                raise FormatError(path, f"{where} must name clips of the file ({', '.join(clip_names or [])}), "
                                        f"not {value!r}")
            found[name] = names
            continue
        low, high = (dims[b] if isinstance(b, str) else b for b in (spec.low, spec.high))
        value = check_attribute(path, group, data, name, None if spec.kind == "choice" else spec.kind, low=low,
                                high=high, choices=spec.choices or None, optional=spec.optional)
        if value is not None:
            found[name] = value
    return found


#: The attributes of the groups a skin fit carries (docs/format.md); their bounds bind to the
#: sizes :func:`check_skin` found (B bones, K influences, F frames).
EXAMPLES_ATTRIBUTES = {"fps": Attribute("float", low=1e-9), "meters_per_unit": Attribute("float", low=1e-300),
                       "up_axis": Attribute("choice", choices=("Y", "Z")), "start_frame": Attribute("float"),
                       "source": Attribute("text")}
SKIN_ATTRIBUTES = {"rmse": Attribute("float", low=0.0), "rmse_over_diagonal": Attribute("float", low=0.0),
                   "diagonal": Attribute("float", low=1e-300), "bones": Attribute("int", low="B", high="B"),
                   "max_influences": Attribute("int", low="K", high="K"), "iterations": Attribute("int", low=0),
                   "converged": Attribute("bool"), "bones_without_weight": Attribute("int", low=0, high="B")}


MESH = {"rest_vertices": Field("float", ("V", 3)), "faces": Field("int", ("T", 3), low=0, high="V"),
        "face_uvs": Field("float", ("T", 3, 2), optional=True)}
EXAMPLES = {"vertices": Field("float", ("F", "V", 3)),
            "clip_frames": Field("int", ("clips",), low=1, optional=True)}
CLIP_NAME = re.compile(r"^[A-Za-z0-9_.\-]+$")
SKIN = {
    "bone_indices": Field("int", ("V", "K"), low=0, high="B"),
    "bone_weights": Field("float", ("V", "K"), low=0.0),
    "rotations": Field("float", ("F", "B", 3, 3)),
    "translations": Field("float", ("F", "B", 3)),
    "dual_quaternions": Field("float", ("F", "B", 8)),
    "bone_rest_frames": Field("float", ("B", 4, 4)),
    "error_history": Field("float", (None,), low=0.0, optional=True),
    "frame_rmse": Field("float", ("F",), low=0.0, optional=True),
    "initial_labels": Field("int", ("V",), low=0, high="B", optional=True),
}


SKELETON = {
    "parents": Field("int", ("B",), low=-1, high="B"),
    "jointed": Field("bool", ("B",), low=0, high=2),
    "joints": Field("float", ("B", 3)),
    "drift": Field("float", ("B",), low=0.0),
    "sliding": Field("bool", ("B",), low=0, high=2, optional=True),
    "slide_low": Field("float", ("B", 3), optional=True),
    "slide_high": Field("float", ("B", 3), optional=True),
}


def tree_depths(parents):
    """Each node's depth below its root (parent −1) in ``parents`` (N,) (every value −1 or a node
    id): (N,) int64, −1 for a node that never reaches a root (a cycle). The one tree check of the
    skin file, the glTF and the UsdSkel writers."""
    parents = np.asarray(parents, dtype=np.int64)
    depths = np.where(parents < 0, 0, -1)
    for _ in range(parents.size):  # each pass reaches one level deeper
        undone = (depths < 0) & (depths[np.maximum(parents, 0)] >= 0)
        if not undone.any():
            break
        depths[undone] = depths[parents[undone]] + 1
    return depths


SKELETON_ATTRIBUTES = {"root": Attribute("int", low=0, high="last"), "free_rmse": Attribute("float", low=0.0),
                       "max_drift": Attribute("float", low=0.0)}


def check_skeleton(path, skeleton, dims):
    """/skin/skeleton: the arrays (:data:`SKELETON`), one root (parent −1, not jointed), every
    bone reaching it through its parents (a tree, no cycle), its attributes
    (:data:`SKELETON_ATTRIBUTES`), ``@root`` that root."""
    check_group(path, "skin/skeleton", skeleton, SKELETON, dims)
    parents = np.asarray(skeleton["parents"], dtype=np.int64)
    jointed = np.asarray(skeleton["jointed"]).astype(bool)
    roots = np.flatnonzero(parents < 0)
    if roots.size != 1:
        raise FormatError(path, f"/skin/skeleton/parents must have exactly one root (parent -1), not {roots.size}")
    if jointed[roots[0]]:
        raise FormatError(path, f"/skin/skeleton/jointed marks the root bone {roots[0]}, which has no parent to turn about")
    _check_slides(path, skeleton, jointed, roots[0])
    _check_bone_names(path, skeleton, parents.size)
    depths = tree_depths(parents)
    if (depths < 0).any():
        raise FormatError(path, f"/skin/skeleton/parents is not a tree: bone {int(np.flatnonzero(depths < 0)[0])} "
                                "never reaches the root (a cycle)")
    stated = check_attributes(path, "skin/skeleton", skeleton, SKELETON_ATTRIBUTES, dict(dims, last=parents.size - 1))
    if stated.get("root", roots[0]) != roots[0]:
        raise FormatError(path, f"/skin/skeleton/@root is {stated['root']}, but the root bone (parent -1) is "
                                f"{roots[0]}")


def _check_bone_names(path, skeleton, bones):
    """``@names``, where present: one per bone, distinct, each a name a USD prim and a glTF node
    take as it is (a letter or _, then letters, digits and _)."""
    import re

    from .model import text

    if "@names" not in skeleton:
        return
    names = [text(n) for n in np.atleast_1d(skeleton["@names"])]
    bad = [n for n in names if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", n)]
    if len(names) != bones or bad or len(set(names)) != bones:
        what = (f"holds {len(names)} names for {bones} bones" if len(names) != bones else
                f"has {bad[0]!r}, not a name (a letter or _, then letters, digits, _)" if bad else "names a bone twice")
        raise FormatError(path, f"/skin/skeleton/@names {what}")


def _check_slides(path, skeleton, jointed, root):
    """The sliding bones: all three datasets or none; not jointed, not the root; low ≤ high."""
    present = [name for name in ("sliding", "slide_low", "slide_high") if name in skeleton]
    if not present:
        return
    if len(present) < 3:
        raise FormatError(path, f"/skin/skeleton has {', '.join(present)} without "
                                f"{', '.join(n for n in ('sliding', 'slide_low', 'slide_high') if n not in present)}")
    sliding = np.asarray(skeleton["sliding"]).astype(bool)
    both = np.flatnonzero(sliding & jointed)
    if both.size or sliding[root]:
        bone, what = (int(both[0]), "is jointed") if both.size else (int(root), "is the root")
        raise FormatError(path, f"/skin/skeleton/sliding marks bone {bone}, which {what}: a sliding bone has a parent "
                                "and no fixed joint")
    if (np.asarray(skeleton["slide_low"]) > np.asarray(skeleton["slide_high"])).any():
        raise FormatError(path, "/skin/skeleton/slide_low exceeds slide_high")


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
    check_attributes(path, "examples", model["examples"], EXAMPLES_ATTRIBUTES, dims)
    check_attributes(path, "skin", model["skin"], SKIN_ATTRIBUTES, dims)
    prim_path = model["examples"].get("@prim_path")
    if prim_path is not None and not (isinstance(prim_path, str) and prim_path.startswith("/") and len(prim_path) > 1):
        raise FormatError(path, f"/examples/@prim_path is {prim_path!r}, not an absolute USD prim path")
    check_attribute(path, "mesh", model["mesh"], "rest_frame", "int", low=0, high=dims["F"] - 1)
    check_clips(path, model["examples"], dims["F"])
    if "skeleton" in model["skin"]:
        check_skeleton(path, model["skin"]["skeleton"], dims)
    return dims


def check_clips(path, examples, frames):
    """/examples/clip_frames sums to the frames, and @clip_names gives each clip a distinct name."""
    if "clip_frames" not in examples:
        return
    counts = np.atleast_1d(examples["clip_frames"])
    if int(counts.sum()) != frames:
        raise FormatError(path, f"/examples/clip_frames sums to {int(counts.sum())}, not the {frames} frames")
    stored = examples.get("@clip_names")
    names = [] if stored is None or np.ndim(stored) != 1 else \
        [n.decode() if isinstance(n, bytes) else n for n in stored]  # a list, even of one clip
    if len(names) != len(counts) or len(set(names)) != len(names) \
            or not all(isinstance(n, str) and CLIP_NAME.match(n) for n in names):
        raise FormatError(path, f"/examples/@clip_names must name each of the {len(counts)} clips once, in "
                                f"letters, digits, '_', '.' or '-' (got {names!r})")


GRAPH = {"weights": Field("float", ("B", "B")), "kept_edges": Field("int", ("E", 2), low=0, high="B"),
         "cut_nodes": Field("int", (None,), low=0, high="B"),
         "articulation_points": Field("int", (None,), low=0, high="B", optional=True),
         "held_runs": Field("int", (None, 2), low=0, high="F", optional=True)}  # issue 63: held poses
GRAPH_CONTACTS = {  # /graph/contacts, only where ground contacts were found (issue 35)
    "vertices": Field("int", (None,), low=0, high="V"),
    "offsets": Field("int", (None,), low=0),
    "planted": Field("bool", ("F", None), low=0, high=2),
    "ground": Field("float", (None,))}
GRAPH_COMPONENT = {
    "bones": Field("int", ("b",), low=0, high="B"),
    "local_bones": Field("int", ("l",), low=0, high="B"),
    "reduced_coordinates": Field("float", ("F", "r")),
    "costs": Field("float", ("F", "F"), low=0.0),
    "transitions": Field("int", ("M", 2), high="F"),  # lower bounds: _check_transition_pairs
    "transition_costs": Field("float", ("M",)),
    # which transitions keep every ground contact of the component (issue 35): synthesize --contact
    # walks only those, --no-contact all of them
    "contact_agrees": Field("bool", ("M",), low=0, high=2, optional=True),
    "clip_thresholds": Field("float", ("clips", "clips"), low=0.0, optional=True),
    "key_vertices": Field("int", ("n",), low=0, high="V"),
    "key_bones": Field("int", ("n", "k"), low=-1, high="B"),
    "key_weights": Field("float", ("n", "k"), low=0.0),
    "weight_gradients": Field("float", ("n", "k", 3)),
    "rotation_strain": Field("float", ("F", "n", 9)),
    # Kept for the record (synthesize rebuilds eq. 9's operator from the key-vertex data): still
    # checked, so a damaged file is reported whichever datasets a later version reads.
    "basis": Field("float", (None, "r"), optional=True),
    "singular": Field("float", ("r",), low=0.0, optional=True),
    "reference_motion": Field("float", ("F", 6), optional=True),
    "operator": Field("float", (None, None), optional=True),
    "operator_constant": Field("float", (None,), optional=True),
    "operator_factor": Field("float", (None, None), optional=True),
}


GRAPH_ATTRIBUTES = {  # build-graph's options (formats.graph_file.GRAPH_OPTIONS) and what it found
    "components": Attribute("int", low="C", high="C"), "transitions": Attribute("int", low=0),
    "threshold_scale": Attribute("float", low=1e-300), "edge_threshold": Attribute("float", low=1e-300),
    "svd_threshold": Attribute("float", low=1e-300), "min_gap": Attribute("int", low=1),
    "min_bones": Attribute("int", low=1), "min_segment": Attribute("int", low=1),
    "single_component": Attribute("bool"), "coverage": Attribute("float", low=0.0, high=1.0),
    "posture_weight": Attribute("float", low=0.0), "up_axis": Attribute("choice", choices=("Y", "Z")),
    "threshold_reference": Attribute("choice", choices=("median-step", "max-step")), "clips": Attribute("names"),
    "held_keep": Attribute("int", low=1)}
COMPONENT_ATTRIBUTES = {  # each component's cost balance and threshold (Zheng eqs. 4–6), its walks' share
    "threshold": Attribute("float", low=0.0), "alpha": Attribute("float", low=0.0), "beta": Attribute("float", low=0.0),
    "lambda": Attribute("float", low=0.0), "ridge": Attribute("float", low=0.0),
    "recurrent_share": Attribute("float", low=0.0, high=1.0), "admitted": Attribute("int", low=0)}


def check_graph(path, model, dims):
    """/graph of a graph file and each of its components (``dims`` from :func:`check_skin`)."""
    graph = model["graph"]
    check_group(path, "graph", graph, GRAPH, dims)
    components = sorted(k for k in graph if k.startswith("component_"))
    stated = check_attributes(path, "graph", graph, GRAPH_ATTRIBUTES, dict(dims, C=len(components)),
                              _clip_names(model))
    total = sum(int(np.shape(graph[name]["transitions"])[0]) for name in components if "transitions" in graph[name])
    if stated.get("transitions", total) != total:
        raise FormatError(path, f"/graph/@transitions is {stated['transitions']}, but the components hold {total}")
    if "contacts" in graph:
        _check_contacts(path, graph["contacts"], dims,
                        len(np.atleast_1d(model["examples"].get("clip_frames", [0]))))
    for name in sorted(k for k in graph if k.startswith("component_")):
        component, local = graph[name], dict(dims)
        check_group(path, f"graph/{name}", component, GRAPH_COMPONENT, local)
        _check_transition_pairs(path, f"/graph/{name}/transitions", component["transitions"],
                                len(np.atleast_1d(model["examples"].get("clip_frames", [0]))))
        reference = check_attribute(path, f"graph/{name}", component, "reference", "int", low=0, high=dims["B"] - 1,
                                    optional=False)
        check_attributes(path, f"graph/{name}", component, COMPONENT_ATTRIBUTES, dims)
        bones = np.asarray(component["bones"])
        if np.unique(bones).size != bones.size or reference not in bones or not np.array_equal(
                np.sort(np.asarray(component["local_bones"])), np.setdiff1d(bones, [reference])):
            raise FormatError(path, f"/graph/{name}: bones, local_bones and @reference disagree (the local bones are "
                                    "the component's bones other than its reference)")


#: The thresholds /graph/contacts records (build-graph's --contact-* options, which synthesize's
#: feet reuse), attribute names without "@" (formats.graph_file.read_contacts reads them).
CONTACT_THRESHOLDS = ("height", "speed", "release", "min_duration", "min_support")
CONTACTS_ATTRIBUTES = {name: Attribute("float", low=0.0) for name in CONTACT_THRESHOLDS}


def _check_contacts(path, contacts, dims, clips):
    """/graph/contacts: each dataset (:data:`GRAPH_CONTACTS`), offsets (P + 1,) rising from 0 to
    the vertices' count (each patch at least one vertex), planted (F, P) and a ground per clip."""
    check_group(path, "graph/contacts", contacts, GRAPH_CONTACTS, dict(dims))
    offsets, count = np.asarray(contacts["offsets"]), np.asarray(contacts["vertices"]).size
    patches = offsets.size - 1
    if (patches < 1 or offsets[0] != 0 or offsets[-1] != count or np.any(np.diff(offsets) < 1)
            or np.shape(contacts["planted"])[1] != patches or np.size(contacts["ground"]) != clips):
        raise FormatError(path, f"/graph/contacts is inconsistent: offsets (P + 1,) must rise from 0 to the {count} "
                                f"vertices, planted be (F, P) and ground hold one height per clip ({clips})")
    stated = check_attribute(path, "graph/contacts", contacts, "patches", "int", low=1, optional=False)
    if stated != patches:
        raise FormatError(path, f"/graph/contacts/@patches is {stated}, but offsets hold {patches} patches")
    height = check_attribute(path, "graph/contacts", contacts, "character_height", "float", low=0.0, optional=False)
    if not height > 0.0:
        raise FormatError(path, f"/graph/contacts/@character_height is {height}; it must be a positive length")
    check_attributes(path, "graph/contacts", contacts, CONTACTS_ATTRIBUTES, dims)


def _check_transition_pairs(path, where, pairs, clips=1):
    """Transitions (i, j): i a frame (≥ 0), j a frame or −(c+1) for one of the ``clips`` clips,
    the virtual frame before clip c's start ((i, −1): after i, continue at frame 0). Files written
    before the wrap have no −1."""
    pairs = np.asarray(pairs)
    if pairs.size == 0:
        return
    bad = (pairs[:, 0] < 0) | (pairs[:, 1] < -clips)
    if bad.any():
        i, j = (int(x) for x in pairs[np.argmax(bad)])
        lowest = "−1: the virtual frame before the clip's start, continue at frame 0" if clips == 1 else \
            f"−(c+1) for clip c of {clips}: continue at that clip's first frame"
        raise FormatError(path, f"{where} holds the pair ({i}, {j}): a transition (i, j) leaves a frame i ≥ 0 and "
                                f"enters a frame j ≥ {-clips} ({lowest})")


CONTROLS = {  # basis_variance first: it binds Kb, the bound of candidate_basis
    "basis_variance": Field("float", ("Kb",), low=0.0),
    "vertex_indices": Field("int", ("N",), low=0, high="V"),
    "control_basis": Field("int", ("N",), low=-1, high="Kb", optional=True),
    "candidate_vertices": Field("int", ("C",), low=0, high="V"),
    "candidate_basis": Field("int", ("C",), low=0, high="Kb"),
    "candidate_loading": Field("float", ("C",), low=0.0),
    "marker_offsets": Field("float", ("N",), low=0.0, optional=True),  # with marker_labels (N,) strings
}
TRAINING = {"train_frames": Field("int", ("P",), low=0, high="F"), "test_frames": Field("int", (None,), low=0, high="F"),
            "reference_controls": Field("float", ("N", 3))}
KCCA = {"predictor": Field("float", ("B8", "P")), "bias": Field("float", ("B8",)),
        "training_controls": Field("float", ("P", "N3")), "control_mean": Field("float", ("N3",)),
        "correlations": Field("float", ("B", None)), "regularization": Field("float", ("B",), low=0.0)}
POISSON = {"rotation_operator": Field("float", ("B", "B", 3)), "control_operator": Field("float", ("B", "N")),
           "prior_operator": Field("float", ("B", "B"))}
CORRECTIVES = {"weights": Field("float", ("P", "P")), "offsets": Field("float", ("P", "V", 3)),
               "tail": Field("float", ("P", "R1"), optional=True), "axes": Field("float", ("R", "N3"), optional=True)}


CONTROLS_ATTRIBUTES = {"count": Attribute("int", low="N", high="N"), "components": Attribute("int", low=1, high="Kb"),
                       "explained": Attribute("float", low=0.0, high=1.0 + 1e-9), "method": Attribute("text"),
                       "min_spacing": Attribute("float", low=0.0), "clips": Attribute("names")}
TRAINING_ATTRIBUTES = {"global_motion": Attribute("choice", choices=("control-frame", "world")),
                       "global_motion_reason": Attribute("text"), "correctives_reason": Attribute("text"),
                       "skinning": Attribute("choice", choices=("linear", "dual-quaternion")),
                       "clips": Attribute("names")}
KCCA_ATTRIBUTES = {"kernel": Attribute("choice", choices=("gaussian", "polynomial", "linear"), optional=False),
                   "scale": Attribute("float", low=1e-300, optional=False), "offset": Attribute("float"),
                   "degree": Attribute("int", low=1, high=64), "bases": Attribute("int", low=1, high=8),
                   "regularization_mode": Attribute("choice", choices=("auto", "fixed")),
                   "width_reason": Attribute("text")}
POISSON_ATTRIBUTES = {"prior": Attribute("float", low=0.0), "beta": Attribute("float", low=0.0),
                      "prior_reason": Attribute("text")}
CORRECTIVES_ATTRIBUTES = {"ridge": Attribute("float", low=1e-300, optional=False),
                          "power": Attribute("float", low=1e-300, high=1e3), "reason": Attribute("text")}


def _clip_names(model):
    return [str(n) for n in np.atleast_1d(model.get("examples", {}).get("@clip_names", []))] or None


def check_controls(path, model, dims):
    """/controls (``dims`` from :func:`check_skin`, updated with N)."""
    check_group(path, "controls", model["controls"], CONTROLS, dims)
    check_attributes(path, "controls", model["controls"], CONTROLS_ATTRIBUTES, dims, _clip_names(model))


def check_puppet(path, model, dims):
    """/training, /kcca, /poisson and /correctives of a puppet file (``dims`` after :func:`check_controls`)."""
    dims.update(B8=8 * dims["B"], N3=3 * dims["N"])
    check_group(path, "training", model["training"], TRAINING, dims)
    check_attributes(path, "training", model["training"], TRAINING_ATTRIBUTES, dims, _clip_names(model))
    check_group(path, "kcca", model["kcca"], KCCA, dims)
    check_attributes(path, "kcca", model["kcca"], KCCA_ATTRIBUTES, dims)
    if "poisson" in model:
        check_group(path, "poisson", model["poisson"], POISSON, dims)
        check_attributes(path, "poisson", model["poisson"], POISSON_ATTRIBUTES, dims)
    if "correctives" in model:
        check_group(path, "correctives", model["correctives"], CORRECTIVES, dims)
        check_attributes(path, "correctives", model["correctives"], CORRECTIVES_ATTRIBUTES, dims)
        group = model["correctives"]
        if "tail" in group and "axes" in group and group["tail"].shape[1:] != (group["axes"].shape[0] + 1,):
            raise FormatError(path, f"/correctives/tail has {group['tail'].shape[1:]} columns, expected "
                                    f"1 + {group['axes'].shape[0]} axes")


SYNTHESIS = {  # sources first: it binds C, N and M
    "sources": Field("int", ("C", "N", "M"), low=0, high="F"),
    "bone_matrices": Field("float", ("N", "M", "B", 3, 3)),
    "bone_translations": Field("float", ("N", "M", "B", 3)),
    "seams": Field("int", ("N",), low=0),
    "coverage": Field("float", ("C",), low=0.0, high=1.0 + 1e-9),
    "mean_segment_frames": Field("float", ("C",), low=0.0),
    "shortest_segment": Field("int", ("C",), low=0),
}


def check_synthesis(path, model, dims):
    """/synthesis of a synthesize output (``dims`` from :func:`check_skin`)."""
    synthesis = model["synthesis"]
    check_group(path, "synthesis", synthesis, SYNTHESIS, dims)
    check_attribute(path, "synthesis", synthesis, "count", "int", low=dims["N"], high=dims["N"])
    check_attribute(path, "synthesis", synthesis, "frames", "int", low=dims["M"], high=dims["M"])
    check_attribute(path, "synthesis", synthesis, "fps", "float", low=1e-9)
    check_attribute(path, "synthesis", synthesis, "blend", None, choices=("bones", "key-vertices"))
    check_attribute(path, "synthesis", synthesis, "alignment", None, choices=("ground", "full"))
    check_attribute(path, "synthesis", synthesis, "up_axis", None, choices=("X", "Y", "Z"))
    names = sorted(k for k in synthesis if k.startswith("component_"))
    if len(names) != dims["C"]:
        raise FormatError(path, f"/synthesis has {len(names)} component groups but /synthesis/sources has "
                                f"{dims['C']} components")
    for name in names:
        check_group(path, f"synthesis/{name}", synthesis[name], {"bones": Field("int", ("b",), low=0, high="B")},
                    dict(dims))
