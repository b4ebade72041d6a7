"""Control-point selection: PCA of the examples, varimax-rotated bases, two points per basis.

Feng et al. 2008 §3 (adapting Meyer & Anderson 2007, "Key point subspace acceleration and soft
caching"): run PCA on the example vertex positions, rotate the retained bases with varimax so
that each moves a localised part of the surface, take "two representative points with largest
differences" from every rotated basis, and choose the n_c control points among them. The paper
makes that last choice by hand; here it is a documented deterministic rule
(:func:`choose_controls`), or the user's own vertex ids.

The steps, as built:

1. **In place.** Examples may travel and turn. Each frame is brought onto the rest pose by the
   rigid Procrustes fit of all its vertices (:func:`align_in_place`, the same fit as
   :func:`skinsynth.pipeline.puppet.alignment.control_frames` with every vertex as a control), so PCA
   sees deformation, not global motion.
2. **PCA** of the in-place positions, each frame a 3V vector, centred over frames
   (:func:`pca_bases`). Default number of bases K: the smallest explaining ≥ 99 % of the
   in-place variance, raised to ceil(n_c / 2) so there are enough candidates, capped to
   [1, min(F − 1, 3V)] and to the numerical rank of the data. In the automatic mode without
   ``--components``, K then grows one basis at a time until the candidates hold n_c distinct
   vertices (several bases can share a representative, e.g. the free end of a bending bar).
3. **Varimax** (raw, no Kaiser normalisation; :mod:`skinsynth.pipeline.puppet.varimax`) of the K
   orthonormal bases (3V × K). The rotated bases are still orthonormal and span the same
   subspace; the variance share of rotated basis j is Σ_i share_i R_ij² (it sums to the
   explained total). Bases are renumbered by that share, largest first.
4. **Two representatives per rotated basis** (:func:`representative_vertices`). Reading of
   "two representative points with largest differences": with l_i the 3-vector of basis
   loadings at vertex i, a = argmax_i |l_i| (the vertex this mode moves most) and
   b = argmax_i |l_i − l_a| (the vertex whose motion under this mode differs most from a's,
   e.g. the lower lip for a mouth-opening mode whose a is on the upper lip). Ties go to the
   lowest vertex id.
5. **Choice of n_c** (:func:`choose_controls`), see there.

Every step is vectorised over vertices; the only Python loops run over bases or candidates.
"""

import math
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from .alignment import apply_frames, control_frames
from ..errors import OptionError
from ..mesh.geometry import bounding_box_diagonal
from .varimax import varimax

#: Feng et al. use 8 control points for most of their examples.
DEFAULT_COUNT = 8
#: Default K explains at least this share of the in-place variance.
EXPLAINED_TARGET = 0.99
#: Singular directions with a smaller variance share than this are numerically absent.
RANK_SHARE = 1e-14
#: Two near points whose distance changes less than this (relative) in every frame move as one
#: piece (:func:`choose_controls`). Measured on a 16-bone articulated tube with 8 controls: the
#: plain 5 % spacing let pairs across the tube's section through (held-out KCCA error 1.31e-3);
#: a 10 % spacing that skips only such rigid pairs spread them along it (0.74e-3).
RIGID_TOLERANCE = 0.1
#: In-place RMS motion below this fraction of the bounding-box diagonal counts as no deformation.
NO_MOTION = 1e-9


@dataclass
class ControlSelection:
    """The chosen control vertices and everything needed to explain the choice.

    indices (N,) int64 vertex ids in the order chosen; reasons: one sentence per control;
    control_basis (N,) the rotated basis each control represents (for user-given vertices, the
    basis that moves it most); candidates (2K,) int64 the two representatives of each rotated
    basis, basis 0 first; candidate_basis (2K,) int32; candidate_loading (2K,) |l_i| of the
    candidate in its basis; basis_variance (K,) variance share of each rotated basis, sorted
    decreasing; explained: their sum; components K; method "auto" or "user"; min_spacing the
    absolute spacing used by the automatic rule.
    """

    indices: np.ndarray
    reasons: list
    control_basis: np.ndarray
    candidates: np.ndarray
    candidate_basis: np.ndarray
    candidate_loading: np.ndarray
    basis_variance: np.ndarray
    explained: float
    components: int
    method: str
    min_spacing: float = 0.0
    warnings: list = field(default_factory=list)


def align_in_place(vertices, rest):
    """Remove each frame's global rigid motion: Procrustes of all vertices onto ``rest``.

    vertices (F, V, 3), rest (V, 3) -> (in_place (F, V, 3), rotations (F, 3, 3), translations
    (F, 3)) with ``in_place[f] = vertices[f] @ R[f].T + t[f]`` the best rigid fit to ``rest``.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    rotations, translations = control_frames(vertices, np.asarray(rest, dtype=np.float64))
    return apply_frames(rotations, translations, vertices), rotations, translations


def _pca(in_place):
    frames = in_place.shape[0]
    data = in_place.reshape(frames, -1)
    centred = data - data.mean(axis=0)
    _, singular, vt = np.linalg.svd(centred, full_matrices=False)
    power = singular ** 2
    total = float(power.sum())
    # "No deformation" is relative to the mesh's size: an RMS in-place motion below 1e-9 of the
    # bounding-box diagonal is round-off of the rigid alignment.
    floor = (NO_MOTION * bounding_box_diagonal(in_place.mean(axis=0))) ** 2 * data.size
    if not total > floor:
        raise OptionError("the examples do not deform once global rigid motion is removed: "
                          "there is nothing to select control points from")
    return vt, power / total


def max_components(frames, vertices):
    """Largest K PCA can give: min(F − 1, 3V) (centring over frames costs one dimension)."""
    return max(0, min(frames - 1, 3 * vertices))


def _check_component_range(components, frames, count):
    limit = max_components(frames, count)
    if components is not None and not 1 <= components <= limit:
        raise OptionError(f"--components {components} is out of range: between 1 and {limit} for {frames} "
                          f"frames of {count} vertices (at most min(frames - 1, 3 x vertices))")
    return limit


def _component_count(share, frames, count, components, min_components):
    """(K, largest usable K) from the options and the full variance shares (see :func:`pca_bases`)."""
    limit = _check_component_range(components, frames, count)
    rank = int(np.count_nonzero(share > RANK_SHARE))
    if components is None:
        needed = int(np.searchsorted(np.cumsum(share), EXPLAINED_TARGET - 1e-12) + 1)
        return max(1, min(max(needed, min_components), limit, rank)), min(limit, rank)
    if components > rank:
        raise OptionError(f"--components {components} is more than the {rank} independent directions the "
                          "in-place examples span; lower --components")
    return components, min(limit, rank)


def pca_bases(in_place, components=None, min_components=1):
    """PCA of in-place positions (F, V, 3), each frame one 3V vector, centred over frames.

    components: K, or None for the default rule (smallest K explaining ≥ 99 % of the variance,
    at least ``min_components``, at most min(F − 1, 3V) and the numerical rank).
    Returns (bases (K, V, 3) orthonormal as 3V vectors, variance_share (K,), explained total).
    Raises OptionError for K outside [1, min(F − 1, 3V)] or above the data's rank.
    """
    in_place = np.asarray(in_place, dtype=np.float64)
    frames, count = in_place.shape[:2]
    _check_component_range(components, frames, count)
    vt, share = _pca(in_place)
    k, _ = _component_count(share, frames, count, components, min_components)
    return vt[:k].reshape(k, count, 3), share[:k], float(share[:k].sum())


def representative_vertices(rotated):
    """Two representative vertices of each basis (K, V, 3): the reading of Feng §3 in the module doc.

    Returns (candidates (2K,) int64 [a_0, b_0, a_1, b_1, …], basis_of (2K,) int32,
    loading (2K,) = |l| of each candidate in its basis).
    """
    rotated = np.asarray(rotated, dtype=np.float64)
    k = rotated.shape[0]
    norms = np.linalg.norm(rotated, axis=2)                            # (K, V)
    first = np.argmax(norms, axis=1)                                   # (K,)
    spread = np.linalg.norm(rotated - rotated[np.arange(k), first][:, None, :], axis=2)
    second = np.argmax(spread, axis=1)
    candidates = np.stack([first, second], axis=1).reshape(-1).astype(np.int64)
    basis_of = np.repeat(np.arange(k, dtype=np.int32), 2)
    loading = norms[basis_of, candidates]
    return candidates, basis_of, loading


def _nearest(rest, chosen, points):
    """Distance from each of ``points`` (ids) to the nearest of ``chosen`` (ids); inf if none."""
    if len(chosen) == 0:
        return np.full(len(points), np.inf)
    diff = rest[np.asarray(points)][:, None, :] - rest[np.asarray(chosen)][None, :, :]
    return np.linalg.norm(diff, axis=2).min(axis=1)


def _rotate(bases, share):
    """Varimax of the bases (K, V, 3) as a 3V x K matrix; rotated bases renumbered by variance share."""
    k, vertex_count = bases.shape[:2]
    rotated, rotation = varimax(bases.reshape(k, -1).T)
    rotated_share = (share[:, None] * rotation ** 2).sum(axis=0)
    order = np.argsort(-rotated_share, kind="stable")
    rotated = rotated[:, order].T.reshape(k, vertex_count, 3)
    return (rotated, rotated_share[order]) + representative_vertices(rotated)


def choose_controls(candidates, basis_of, variance_share, rest, count, min_spacing, in_place=None,
                    rigid_tolerance=RIGID_TOLERANCE):
    """Choose ``count`` of the candidate vertices by a deterministic rule spread over bases and surface.

    The rule (it replaces the manual pick of Feng §3):

    1. Order the rotated bases by variance share, largest first (ties: lower basis number).
    2. Round-robin: the first representative of every basis in that order, then the second
       representatives in the same order. A candidate is skipped when it is already chosen or
       lies closer than ``min_spacing`` (rest pose, Euclidean) to a chosen control *that moves
       with it*: their distance changes by less than ``rigid_tolerance`` (relative) in every
       in-place frame ``in_place (F, V, 3)``. Two points across a tube's section move as one
       piece and the second adds nothing; an upper and a lower lip, as close, move apart, and
       both are kept. Without ``in_place`` every near control counts (plain spacing).
    3. If that leaves fewer than ``count``, fill with the remaining distinct candidates by
       farthest-point order: repeatedly the one farthest from the chosen set, ties by vertex id
       (the spacing rule is relaxed here).

    No randomness: the same inputs give the same choice. Returns (indices (count,) int64,
    reasons: one sentence per chosen control).
    """
    positions, reasons = _choose(candidates, basis_of, variance_share, rest, count, min_spacing, in_place,
                                 rigid_tolerance)
    return np.asarray(candidates, dtype=np.int64)[positions], reasons


def _choose(candidates, basis_of, variance_share, rest, count, min_spacing, in_place=None,
            rigid_tolerance=RIGID_TOLERANCE):
    """:func:`choose_controls`, returning positions in ``candidates`` (so each control keeps its basis)."""
    candidates = np.asarray(candidates, dtype=np.int64)
    basis_of = np.asarray(basis_of)
    variance_share = np.asarray(variance_share, dtype=np.float64)
    rest = np.asarray(rest, dtype=np.float64)
    distinct = np.unique(candidates)
    if count < 1:
        raise OptionError(f"--count must be at least 1 (got {count})")
    if count > len(distinct):
        raise OptionError(f"--count {count} but only {len(distinct)} candidate vertices; "
                          "lower --count or raise --components")
    basis_order = np.argsort(-variance_share, kind="stable")
    rank_of_basis = np.empty_like(basis_order)
    rank_of_basis[basis_order] = np.arange(len(basis_order))
    # Position of each candidate among its basis's representatives (0: first, 1: second).
    slot = np.zeros(len(candidates), dtype=np.int64)
    for position in range(1, len(candidates)):
        slot[position] = np.count_nonzero(basis_of[:position] == basis_of[position])
    visit = np.lexsort((np.arange(len(candidates)), rank_of_basis[basis_of], slot))

    chosen, picked, reasons = [], [], []
    for position in visit:
        if len(chosen) == count:
            break
        vertex, basis = int(candidates[position]), int(basis_of[position])
        if vertex in chosen:
            continue
        gap = _nearest(rest, chosen, [vertex])[0]
        if gap < min_spacing and _moves_with_a_control(in_place, rest, chosen, vertex, min_spacing, rigid_tolerance):
            continue
        if slot[position] == 0:
            what = f"round 1 (first representatives): the vertex basis {basis} moves most"
        else:
            partner = candidates[(basis_of == basis) & (slot == 0)]
            what = (f"round {int(slot[position]) + 1} (second representatives): moves most differently "
                    f"from vertex {int(partner[0])} under basis {basis}")
        near = "" if gap >= min_spacing else " (within the spacing, but their distance changes: it moves on its own)"
        reasons.append(what + ("" if not chosen else f"; {gap:.3g} from the nearest control{near}"))
        chosen.append(vertex)
        picked.append(int(position))

    remaining = np.setdiff1d(distinct, chosen)                     # sorted by vertex id
    first_visit = {}
    for position in visit[::-1]:                                   # earliest visit of each vertex wins
        first_visit[int(candidates[position])] = int(position)
    while len(chosen) < count:
        gaps = _nearest(rest, chosen, remaining)
        pick = int(np.argmax(gaps))                                # first maximum = lowest id
        vertex = int(remaining[pick])
        position = first_visit[vertex]
        basis = int(basis_of[position])
        kind = f"the vertex basis {basis} moves most" if slot[position] == 0 else f"second representative of basis {basis}"
        reasons.append(f"farthest-point fill (the round-robin skipped candidates within {min_spacing:.3g} of a "
                       f"control): {kind}, {gaps[pick]:.3g} from the nearest control")
        chosen.append(vertex)
        picked.append(position)
        remaining = np.delete(remaining, pick)
    return np.asarray(picked, dtype=np.int64), reasons


def _moves_with_a_control(in_place, rest, chosen, vertex, min_spacing, tolerance):
    """Whether a chosen control lies within ``min_spacing`` of ``vertex`` (rest pose) and keeps
    its distance to it within ``tolerance`` (relative, every in-place frame (F, V, 3)): such a
    pair moves as one rigid piece and the second point adds nothing. Without frames, any near
    control counts."""
    chosen = np.asarray(chosen, dtype=np.int64)
    gaps = np.linalg.norm(rest[chosen] - rest[vertex], axis=1)
    near = chosen[gaps < min_spacing]
    if in_place is None or near.size == 0:
        return near.size > 0
    rest_gap = np.linalg.norm(rest[near] - rest[vertex], axis=1)  # (c,)
    moving_gap = np.linalg.norm(in_place[:, near] - in_place[:, vertex][:, None], axis=2)  # (F, c)
    change = np.max(np.abs(moving_gap - rest_gap), axis=0) / np.maximum(rest_gap, 1e-300)
    return bool(np.any(change < tolerance))


def _check_user_vertices(user_vertices, count, vertex_count):
    ids = np.asarray(user_vertices)
    if ids.ndim != 1 or ids.size == 0:
        raise OptionError("--vertices needs at least one vertex id")
    if not np.issubdtype(ids.dtype, np.integer):
        raise OptionError("--vertices takes integer vertex ids")
    ids = ids.astype(np.int64)
    bad = ids[(ids < 0) | (ids >= vertex_count)]
    if bad.size:
        raise OptionError(f"--vertices: vertex id {int(bad[0])} is out of range (the mesh has "
                          f"{vertex_count} vertices, ids 0 to {vertex_count - 1})")
    values, counts = np.unique(ids, return_counts=True)
    if np.any(counts > 1):
        raise OptionError(f"--vertices: vertex id {int(values[counts > 1][0])} is given more than once")
    if count is not None and count != ids.size:
        raise OptionError(f"--count {count} disagrees with the {ids.size} ids given by --vertices; "
                          "give one or make them agree")
    return ids


def collinearity_warning(rest, indices, diagonal):
    """A warning when the controls cannot fix a rigid frame (fewer than 3, or all on one line)."""
    if len(indices) < 3:
        return (f"only {len(indices)} control point(s): the rigid frame fitted to the controls needs at least "
                "3 non-collinear points, so global rotation will be ambiguous")
    points = rest[indices] - rest[indices].mean(axis=0)
    singular = np.linalg.svd(points, compute_uv=False)
    if singular[1] <= 1e-9 * max(diagonal, 1e-300):
        return ("the control points are collinear at rest: the rigid frame fitted to them needs at least "
                "3 non-collinear points, so global rotation will be ambiguous")
    return None


# One BLAS thread: a threaded SVD or product sums in an order that depends on the thread count,
# and the controls chosen from it must not (issue 11: the same input gives the same file).
@threadpool_limits.wrap(limits=1, user_api="blas")
def select_controls(vertices, rest, count=None, components=None, user_vertices=None, min_spacing_fraction=0.1,
                    rigid_tolerance=RIGID_TOLERANCE):
    """Feng §3 control-point selection (after Meyer & Anderson 2007), as described in the module doc.

    vertices (F, V, 3) example frames, rest (V, 3) rest pose; count: n_c (default 8; with
    ``user_vertices`` it must be None or agree); components: K (None: default rule);
    user_vertices: the user's own vertex ids instead of the automatic choice (the PCA summary and
    candidates are still computed and kept); min_spacing_fraction: spacing of the automatic rule
    as a fraction of the rest bounding-box diagonal, within which a candidate that moves with a
    chosen control (distance change < ``rigid_tolerance``) is skipped (:func:`choose_controls`).
    Returns a :class:`ControlSelection`.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    rest = np.asarray(rest, dtype=np.float64)
    if vertices.ndim != 3 or vertices.shape[2] != 3 or rest.shape != vertices.shape[1:]:
        raise ValueError(f"vertices must be (F, V, 3) and rest (V, 3); got {vertices.shape} and {rest.shape}")
    frames, vertex_count = vertices.shape[:2]
    if frames < 3:
        raise OptionError(f"control selection needs at least 3 example frames (got {frames})")
    if not min_spacing_fraction >= 0.0:
        raise OptionError(f"--min-spacing must not be negative (got {min_spacing_fraction})")
    if not rigid_tolerance >= 0.0:
        raise OptionError(f"--rigid-tolerance must not be negative (got {rigid_tolerance})")
    if user_vertices is not None:
        user = _check_user_vertices(user_vertices, count, vertex_count)
        count = int(user.size)
    else:
        user = None
        count = DEFAULT_COUNT if count is None else int(count)
        if count < 1:
            raise OptionError(f"--count must be at least 1 (got {count})")

    _check_component_range(components, frames, vertex_count)
    in_place, _, _ = align_in_place(vertices, rest)
    vt, all_share = _pca(in_place)
    minimum = 1 if user is not None else math.ceil(count / 2)
    k, limit = _component_count(all_share, frames, vertex_count, components, minimum)
    while True:
        share = all_share[:k]
        rotated, rotated_share, candidates, basis_of, loading = _rotate(vt[:k].reshape(k, vertex_count, 3), share)
        # Default K in the automatic mode: add bases until the candidates hold enough distinct
        # vertices (several bases can share a representative, e.g. the free end of a bent bar).
        if user is not None or components is not None or k >= limit or np.unique(candidates).size >= count:
            break
        k += 1
    explained = float(share.sum())

    diagonal = bounding_box_diagonal(rest)
    spacing = float(min_spacing_fraction * diagonal)
    moves = np.linalg.norm(rotated, axis=2)                              # (K, V)
    if user is None:
        distinct = np.unique(candidates).size
        if count > distinct:
            hint = ("lower --count or raise --components" if k < limit
                    else f"lower --count (K = {k} bases is already the most these {frames} frames allow)")
            raise OptionError(f"--count {count} but only {distinct} candidate vertices; {hint}")
        positions, reasons = _choose(candidates, basis_of, rotated_share, rest, count, spacing, in_place,
                                     rigid_tolerance)
        indices, control_basis = candidates[positions], basis_of[positions].astype(np.int32)
        method = "auto"
    else:
        indices = user
        control_basis = np.argmax(moves[:, indices], axis=0).astype(np.int32)
        reasons = []
        for vertex, basis in zip(indices.tolist(), control_basis.tolist()):
            hits = np.flatnonzero(candidates == vertex)
            note = (f"also a representative of basis {int(basis_of[hits[0]])}" if hits.size
                    else "not one of the representative vertices")
            reasons.append(f"given by --vertices; {note}; basis {basis} is the one that moves it most")
        method = "user"
    warnings = [w for w in [collinearity_warning(rest, indices, diagonal)] if w]
    return ControlSelection(indices=np.asarray(indices, dtype=np.int64), reasons=reasons,
                            control_basis=control_basis, candidates=candidates,
                            candidate_basis=basis_of.astype(np.int32), candidate_loading=loading,
                            basis_variance=rotated_share, explained=explained, components=k,
                            method=method, min_spacing=spacing, warnings=warnings)


def selection_summary(output, selection, frames, clips, used):
    """``select-controls``' summary (--json) and its text lines: one line per control (its vertex,
    basis, that basis's variance share, why it was chosen), then the selection from ``frames``
    (n,) of the clips ``used`` (names) of the skin's ``clips`` (a
    :class:`~skinsynth.pipeline.inputs.clips.Clips`)."""
    lines = [f"control {number}: vertex {vertex}, basis {basis} ({100.0 * selection.basis_variance[basis]:.1f}% of "
             f"variance): {reason}"
             for number, (vertex, basis, reason) in enumerate(zip(selection.indices, selection.control_basis,
                                                                  selection.reasons))]
    lines.append(f"wrote {output}: {len(selection.indices)} control points ({selection.method}) from "
                 f"{len(set(selection.candidates.tolist()))} candidates of {selection.components} rotated PCA "
                 f"bases explaining {100.0 * selection.explained:.1f}% of the in-place variance"
                 + (f", from {len(frames)} frames of clips {', '.join(used)}" if len(clips) > 1 else ""))
    summary = {"output": output, "vertex_indices": selection.indices, "reasons": list(selection.reasons),
               "bases": selection.control_basis, "method": selection.method, "components": int(selection.components),
               "explained": float(selection.explained), "warnings": list(selection.warnings),
               "clips": list(used), "frames": int(len(frames))}
    return summary, lines
