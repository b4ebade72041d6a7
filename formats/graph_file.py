"""The ``graph`` stage file written by ``build-graph`` (Zheng §3.2, §3.3, §4.1).

Copies forward ``/mesh``, ``/examples`` and ``/skin`` and adds ``/graph``:

- ``weights (B, B)`` bone-graph edge weights d_ij (eq. 11); ``kept_edges (E, 2)`` the edges left
  after pruning; ``cut_nodes (n,)`` the bones shared by two or more components (where Alg. 1
  merges them); ``articulation_points (m,)`` every cut node of the pruned graph (blocks smaller
  than ``@min_bones`` are merged, so some lie inside one component); attributes ``@components``, ``@transitions`` (total),
  ``@threshold_scale``, ``@threshold_reference``, ``@edge_threshold``, ``@svd_threshold``,
  ``@min_gap``, ``@min_bones``, ``@single_component``, ``@min_segment`` (frames; synthesize's
  default), ``@coverage``, ``@up_axis`` ("Y" or "Z"; synthesize's default), ``@posture_weight``.
- ``/graph/component_NNN`` per component: ``bones (b,)``; ``local_bones (b−1,)`` (the
  non-reference bones, in the order of the reduced-coordinate basis and of eq. 9's unknowns);
  ``reduced_coordinates (F, r)``, ``basis (6(b−1), r)``, ``singular (r,)`` (eq. 3–4);
  ``reference_motion (F, 6)`` (eq. 6); ``costs (F, F)`` D(i, j) (eq. 5); ``transitions (M, 2)``
  candidate (i, j) pairs by increasing cost and ``transition_costs (M,)``: (i, j) plays j + 1
  after i, j = −(c+1) continues at the first frame of clip c (one clip: j = −1, frame 0);
  ``key_vertices (n,)``,
  ``key_bones (n, K')`` (−1 padding), ``key_weights (n, K')``, ``weight_gradients (n, K', 3)``
  (Appendix A); ``rotation_strain (F, n, 9)`` (axis-angle of U then S's upper triangle s00 s01
  s02 s11 s12 s22 of the local-frame deformation gradient D = U S, eq. 8); ``operator (3n, 4(b−1))``
  G₀, the row-separable block of eq. 9's G, ``operator_constant (9n,)`` (the reference bone's
  contribution), ``operator_factor (4(b−1), 4(b−1))`` the lower Cholesky factor of G₀ᵀG₀ + λI;
  attributes ``@reference``, ``@threshold``, ``@alpha``, ``@beta``, ``@lambda``, ``@ridge``,
  ``@admitted`` (transitions above the threshold admitted for coverage), ``@recurrent_share``
  (frames on the motion graph's largest strongly connected part). Key-vertex data use the component's own weights, renormalised over
  its bones (the component is synthesised as if it were the whole mesh).

- ``held_runs (R, 2)`` and ``@held_keep``, only when the clip holds a pose still (issue 63,
  :mod:`~skinsynth.pipeline.synthesis.held_poses`): each held run's first and last frame; walks
  show a run's first ``@held_keep`` frames and its last, the frames between never (each
  component's transitions hold the skip from the one to the other).
- ``/graph/contacts``, only when the input's ground contacts were found (issue 35): ``vertices (N,)``
  patch after patch, ``offsets (P + 1,)``, ``planted (F, P)`` uint8, ``ground (C,)`` per clip;
  attributes ``@patches``, ``@character_height`` and the thresholds ``@height``, ``@speed``,
  ``@release``, ``@min_duration``, ``@min_support`` (:func:`~skinsynth.pipeline.synthesis.contact.patches.find_contacts`).
  A capture without contacts gets no group and no attribute: its file is --no-contacts' file.

Several clips (issue 26) need nothing new here: the clip table lives in ``/examples``
(``clip_frames``, ``@clip_names``), copied forward, and every frame-indexed dataset above uses
the global frame numbers of the clips in order. ``reference_motion`` holds eq. 6 within each
clip (a clip's first frame takes its own first step); ``costs`` compares frames of any two
clips; ``@threshold`` is T_c over the steps within clips, pooled; with several clips
``clip_thresholds (C, C)`` holds the T_c each transition was judged by, per (clip left, clip
entered) (:func:`~skinsynth.pipeline.synthesis.transitions.clip_thresholds`).
"""

from dataclasses import dataclass

import numpy as np

from .errors import FormatError
from .model import read_model, require
from .skin_file import read_skin
from .validation import CONTACT_THRESHOLDS, check_graph

_COMPONENT_DATASETS = ("bones", "local_bones", "reduced_coordinates", "costs", "transitions", "transition_costs",
                       "key_vertices", "key_bones", "key_weights", "weight_gradients", "rotation_strain")


def graph_groups(model, analysis):
    """The groups of a graph file: the skin file's groups forwarded plus ``/graph``."""
    groups = {name: model[name] for name in ("mesh", "examples", "skin")}
    options = analysis.options
    graph = {"weights": analysis.weights, "kept_edges": analysis.kept_edges,
             "cut_nodes": np.asarray(analysis.cut_nodes, dtype=np.int64),
             "articulation_points": np.asarray(analysis.articulation_points, dtype=np.int64),
             "@components": len(analysis.components), "@transitions": analysis.transition_count,
             "@threshold_scale": float(options["threshold_scale"]),
             "@threshold_reference": str(options["threshold_reference"]),
             "@edge_threshold": float(options["edge_threshold"]), "@svd_threshold": float(options["svd_threshold"]),
             "@min_gap": int(options["min_gap"]), "@min_bones": int(options["min_bones"]),
             "@single_component": bool(options["single_component"]),
             "@min_segment": int(options["min_segment"]), "@coverage": float(options["coverage"]),
             "@up_axis": "XYZ"[int(options["up_axis"])], "@posture_weight": float(options["posture_weight"])}
    if options.get("walk_clips") is not None:  # the clips walks may play (build-graph --clips; default every clip)
        graph["@clips"] = [str(name) for name in options["walk_clips"]]
    for number, c in enumerate(analysis.components):
        t, op = c.transitions, c.operator
        graph[f"component_{number:03d}"] = {
            "bones": np.asarray(c.bones, dtype=np.int64), "local_bones": np.asarray(t.local_bones, dtype=np.int64),
            "reduced_coordinates": t.q, "basis": t.basis, "singular": t.singular, "reference_motion": t.r,
            "costs": t.D, "transitions": np.asarray(t.pairs, dtype=np.int64).reshape(-1, 2),
            "transition_costs": np.asarray(t.costs, dtype=np.float64),
            "key_vertices": c.key.astype(np.int64), "key_bones": c.key_bones.astype(np.int64),
            "key_weights": c.key_weights, "weight_gradients": c.key_gradients, "rotation_strain": c.strain,
            "operator": op.reduced, "operator_constant": op.constant, "operator_factor": np.tril(op.factor[0]),
            "@reference": int(t.reference), "@threshold": float(t.threshold), "@alpha": float(t.alpha),
            "@beta": float(t.beta), "@lambda": float(op.lam), "@ridge": float(op.ridge),
            "@admitted": int(t.admitted), "@recurrent_share": float(t.share)}
        if getattr(c, "contact_agrees", None) is not None:  # issue 35: the transitions keeping the contacts
            graph[f"component_{number:03d}"]["contact_agrees"] = np.asarray(c.contact_agrees, dtype=np.uint8)
        if getattr(t, "thresholds", None) is not None:  # several clips: T_c per (clip left, clip entered)
            graph[f"component_{number:03d}"]["clip_thresholds"] = np.asarray(t.thresholds, dtype=np.float64)
    held = getattr(analysis, "held", None)
    if held is not None and len(held.runs):  # issue 63: only then, so a clip that never stands still keeps its file
        graph["held_runs"] = np.asarray(held.runs, dtype=np.int64).reshape(-1, 2)
        graph["@held_keep"] = int(held.keep)
    contacts = getattr(analysis, "contacts", None)
    if contacts is not None and contacts.count:  # only then: a capture without contacts keeps every dataset
        graph["contacts"] = {
            "vertices": np.asarray(contacts.vertices, dtype=np.int64),
            "offsets": np.asarray(contacts.offsets, dtype=np.int64),
            "planted": np.asarray(contacts.planted, dtype=np.uint8),
            "ground": np.asarray(contacts.ground, dtype=np.float64),
            "@character_height": float(contacts.height), "@patches": int(contacts.count),
            **{f"@{name}": float(value) for name, value in contacts.options.items()}}
    groups["graph"] = graph
    return groups


@dataclass
class ContactsRecord:
    """/graph/contacts as read: vertices (N,) patch by patch, offsets (P + 1,) (patch p is
    vertices[offsets[p]:offsets[p + 1]]), planted (F, P) bool, ground (C,) per clip, height (the
    thresholds' unit) and the options found with ({name: value})."""

    vertices: np.ndarray
    offsets: np.ndarray
    planted: np.ndarray
    ground: np.ndarray
    height: float
    options: dict

    @property
    def count(self):
        return int(self.offsets.size - 1)


def read_contacts(graph):
    """The :class:`ContactsRecord` of a read /graph (checked by :func:`.validation.check_graph`),
    or None when it has none (no contact found, or a file from before)."""
    data = graph.get("contacts")
    if data is None:
        return None
    return ContactsRecord(vertices=np.asarray(data["vertices"]), offsets=np.asarray(data["offsets"]),
                          planted=np.asarray(data["planted"]).astype(bool), ground=np.asarray(data["ground"]),
                          height=float(data.get("@character_height", 1.0)),
                          options={name: float(data[f"@{name}"]) for name in CONTACT_THRESHOLDS if f"@{name}" in data})


def read_graph_contacts(path, model, skin):
    """/graph/contacts of a graph file read as ``model`` (with its skin, a :class:`SkinFile`), the
    graph checked first (:func:`.validation.check_graph`): a :class:`ContactsRecord` or None."""
    check_graph(path, model, _dims(skin))
    return read_contacts(model["graph"])


def _dims(skin):
    return {"F": skin.rotations.shape[0], "B": skin.bones, "V": skin.rest_vertices.shape[0]}


#: build-graph's options as /graph records them (attribute names without "@").
GRAPH_OPTIONS = ("threshold_scale", "threshold_reference", "edge_threshold", "svd_threshold", "min_gap", "min_bones",
                 "single_component", "min_segment", "coverage", "up_axis", "posture_weight")


@dataclass
class ComponentRecord:
    """One /graph/component_NNN as read (Zheng §3.2, §3.3): its bones (b,) and local_bones,
    the reference bone, reduced coordinates q (F, r) with basis, singular values and the
    reference motion (None in files that lack them), the cost matrix costs (F, F), transitions
    (n, 2) with transition_costs (n,), the threshold T_c and the cost balance alpha, beta; key
    vertices (k,) with key_bones, key_weights, weight_gradients and rotation_strain; the
    ridge of the eq. 9 solve; contact_agrees (n,) bool, which transitions keep the input's ground
    contacts (None: no contacts, or a file from before)."""

    bones: np.ndarray
    local_bones: np.ndarray
    reference: int
    reduced_coordinates: np.ndarray
    basis: np.ndarray | None
    singular: np.ndarray | None
    reference_motion: np.ndarray | None
    costs: np.ndarray
    transitions: np.ndarray
    transition_costs: np.ndarray
    threshold: float
    alpha: float
    beta: float
    key_vertices: np.ndarray
    key_bones: np.ndarray
    key_weights: np.ndarray
    weight_gradients: np.ndarray
    rotation_strain: np.ndarray
    ridge: float
    contact_agrees: np.ndarray | None = None


@dataclass
class GraphFile:
    """A graph file as read: skin (SkinModel), graph (the /graph dict), options (build-graph's
    options the file records, {name: value}, ``up_axis`` as "Y" or "Z"), components
    (list of :class:`ComponentRecord`), provenance (the file's records), contacts (the input's
    ground contacts, :class:`ContactsRecord`, or None: none found, or a file from before); held_runs
    (R, 2) the held poses' first and last frames and held_keep the frames a walk shows of each
    (None and 0: the clip never stands still, or a file from before)."""

    skin: object
    graph: dict
    options: dict
    components: list
    provenance: list
    contacts: object = None
    held_runs: np.ndarray | None = None
    held_keep: int = 0


def _component_record(data):
    return ComponentRecord(
        bones=data["bones"], local_bones=data["local_bones"], reference=int(data["@reference"]),
        reduced_coordinates=data["reduced_coordinates"], basis=data.get("basis"), singular=data.get("singular"),
        reference_motion=data.get("reference_motion"), costs=data["costs"], transitions=data["transitions"],
        transition_costs=data["transition_costs"], threshold=float(data.get("@threshold", 0.0)),
        alpha=float(data.get("@alpha", 1.0)), beta=float(data.get("@beta", 1.0)), key_vertices=data["key_vertices"],
        key_bones=data["key_bones"], key_weights=data["key_weights"], weight_gradients=data["weight_gradients"],
        rotation_strain=data["rotation_strain"], ridge=float(data.get("@ridge", 1e-9)),
        contact_agrees=None if data.get("contact_agrees") is None else np.asarray(data["contact_agrees"]).astype(bool))


def read_graph(path):
    """GraphFile of a graph stage file; FormatError if it is not one or is incomplete."""
    model = read_model(path, stages=("graph",))
    skin = read_skin(path, model)
    graph = require(model, path, "graph", ("weights", "kept_edges", "cut_nodes"))
    check_graph(path, model, _dims(skin))
    names = sorted(k for k in graph if k.startswith("component_"))
    if not names:
        raise FormatError(path, "/graph has no components: the file is incomplete")
    components = []
    for name in names:
        missing = [d for d in _COMPONENT_DATASETS if d not in graph[name]]
        if missing:
            raise FormatError(path, f"/graph/{name} lacks {', '.join(missing)}: the file is incomplete")
        components.append(_component_record(graph[name]))
    options = {name: graph[f"@{name}"] for name in GRAPH_OPTIONS if f"@{name}" in graph}
    contacts = read_contacts(graph)
    held_runs = graph.get("held_runs")
    if held_runs is not None:
        held_runs = np.asarray(held_runs, np.int64).reshape(-1, 2)  # shape, type and range: check_graph
        if held_runs.size and (held_runs[:, 1] < held_runs[:, 0]).any():
            raise FormatError(path, "/graph/held_runs has a run that ends before it starts: the file is damaged")
    return GraphFile(skin=skin, graph=graph, options=options, components=components, provenance=model["provenance"],
                     contacts=contacts, held_runs=held_runs, held_keep=int(graph.get("@held_keep", 0)))
