"""Key vertices and bone-weight gradients at them (Zheng §3.3 "Selection of Key Vertices", App. A).

Splicing blends deformation gradients only at a few *key vertices*: for each bone the vertex it
weighs most, and for each pair of bones the vertex where both weigh most jointly (Zheng §3.3).
Eq. 8 needs the spatial derivatives ∂w_ib/∂v̄_i of the skinning weights there; the weights live
only on the surface, so they are estimated from the one-ring by least squares (eq. 16–17) with
Σ_b ∂w_ib/∂v̄_i = 0 (eq. 15) imposed exactly, which makes eq. 8 return F wherever the whole mesh
undergoes one affine map {F, t}.

Choices the paper leaves open (all documented where they are made):
- A bone whose weight is zero at every vertex gets no key vertex (its argmax is meaningless).
  Ties are broken by the lower vertex index. :func:`key_vertices` takes each influence-list
  entry as it is (the fit names a bone at most once per vertex); the gradient code sums
  duplicate entries of one bone.
- Pairs are searched only among bone pairs that co-occur in some vertex's influence list: any
  other pair has w_vi·w_vj = 0 everywhere and is never kept (Zheng keeps only products > 0).
- The "related bones" of a vertex i (Zheng App. A) are the bones with non-zero weight at i *or*
  at any one-ring neighbour: a bone that is zero at i but not at a neighbour has a non-zero
  gradient at i. ``max_bones`` optionally caps the set; i's own bones are always kept (otherwise
  Σ_b w_ib < 1 over the kept set and the affine property is lost), the others are ranked by their
  weight summed over i and its ring.
- Eq. 17 is block-diagonal with the *same* block A_i for every bone, so projecting onto the null
  space of eq. 15 (the orthogonal projector I − 11ᵀ/m over the m related bones, an explicit
  orthonormal basis of {Σ_b d_b = 0}) commutes with the blocks: the constrained solution is
  A_i⁺ applied to the bone-centred right-hand sides. A_i⁺ is a batched SVD pseudo-inverse
  (``np.linalg.pinv`` on stacked, zero-padded A_i), so a vertex whose neighbours do not span 3D
  (fewer than 3 non-collinear edge directions, or a flat fan) gets the minimum-norm solution:
  no component along the directions its ring does not see.
"""

from dataclasses import dataclass

import numpy as np

from ..mesh.geometry import mesh_edges


@dataclass
class KeyVertices:
    """Key vertices of an LBS model (Zheng §3.3).

    vertices (n,) sorted unique vertex ids. Each reason one was chosen is a row of
    ``choice_bones (m, 2)``: ``(b, -1)`` for "max weight of bone b", ``(bi, bj)`` with bi < bj for
    "max w_vi·w_vj of the pair"; ``choice_key (m,)`` is the row's index into ``vertices`` and
    ``choice_value (m,)`` the weight (or product) that won. A vertex may have several reasons.
    """

    vertices: np.ndarray
    choice_bones: np.ndarray
    choice_key: np.ndarray
    choice_value: np.ndarray

    def reasons(self, i):
        """The (b, -1) / (bi, bj) reasons of the i-th key vertex, (r, 2)."""
        return self.choice_bones[self.choice_key == i]


def _best_per_group(group, vertex, value):
    """For each distinct ``group`` the entry with the largest value (ties: lowest vertex)."""
    order = np.lexsort((vertex, -value, group))
    group, vertex, value = group[order], vertex[order], value[order]
    first = np.ones(group.shape[0], dtype=bool)
    first[1:] = group[1:] != group[:-1]
    return group[first], vertex[first], value[first]


def key_vertices(bone_indices, bone_weights, bones, subset=None):
    """Key vertices by Zheng §3.3.

    bone_indices (V, K) int, bone_weights (V, K) (≥ 0, zero padding), bones: the bone count B;
    subset: optional bone ids — then only those bones, and pairs of two of them, are considered
    (e.g. one bone-graph component). Returns :class:`KeyVertices`.
    """
    idx = np.asarray(bone_indices, dtype=np.int64)
    w = np.asarray(bone_weights, dtype=np.float64)
    count, k = idx.shape
    allowed = np.ones(bones, dtype=bool)
    if subset is not None:
        allowed[:] = False
        allowed[np.asarray(subset, dtype=np.int64)] = True
    live = (w > 0.0) & allowed[idx]
    vertex = np.broadcast_to(np.arange(count)[:, None], idx.shape)

    # v_b = argmax_v w_vb, over the bones that weigh something somewhere.
    b, vb, wb = _best_per_group(idx[live], vertex[live], w[live])
    choices = [np.stack([b, np.full_like(b, -1)], 1)]
    winners, values = [vb], [wb]

    # v_ij = argmax_v w_vi w_vj over co-occurring pairs; kept when the product is > 0.
    pair_groups, pair_vertices, pair_values = [], [], []
    for s1 in range(k):
        for s2 in range(s1 + 1, k):
            ok = live[:, s1] & live[:, s2] & (idx[:, s1] != idx[:, s2])
            lo = np.minimum(idx[ok, s1], idx[ok, s2])
            hi = np.maximum(idx[ok, s1], idx[ok, s2])
            pair_groups.append(lo * bones + hi)
            pair_vertices.append(np.nonzero(ok)[0])
            pair_values.append(w[ok, s1] * w[ok, s2])
    if pair_groups:
        g, vp, wp = _best_per_group(np.concatenate(pair_groups), np.concatenate(pair_vertices),
                                    np.concatenate(pair_values))
        keep = wp > 0.0
        choices.append(np.stack([g[keep] // bones, g[keep] % bones], 1))
        winners.append(vp[keep])
        values.append(wp[keep])

    winners = np.concatenate(winners)
    vertices, choice_key = np.unique(winners, return_inverse=True)
    return KeyVertices(vertices=vertices, choice_bones=np.concatenate(choices).astype(np.int64),
                       choice_key=choice_key.astype(np.int64), choice_value=np.concatenate(values))


def vertex_neighbours(faces, count):
    """One-ring of every vertex from the mesh edges: (indptr (count+1,), indices (nnz,)).

    The neighbours of vertex i are ``indices[indptr[i]:indptr[i+1]]``, sorted.
    """
    edges = mesh_edges(np.asarray(faces, dtype=np.int64))
    rows = np.concatenate([edges[:, 0], edges[:, 1]])
    cols = np.concatenate([edges[:, 1], edges[:, 0]])
    order = np.lexsort((cols, rows))
    indptr = np.zeros(count + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=count), out=indptr[1:])
    return indptr, cols[order]


def _padded_rings(neighbours, vertices):
    """(ring (n, P) vertex ids, mask (n, P)) of the listed vertices, padded to the largest ring."""
    indptr, indices = neighbours
    start, stop = indptr[vertices], indptr[vertices + 1]
    size = stop - start
    width = int(size.max()) if size.size else 0
    slot = np.arange(width)
    mask = slot[None] < size[:, None]
    ring = np.where(mask, indices[np.minimum(start[:, None] + slot[None], max(indices.size - 1, 0))], 0)
    return ring, mask


def _weights_of(bone_indices, bone_weights, at, bones):
    """Weights of ``bones (n, K')`` (-1 = none) at vertices ``at (n, S)``: (n, S, K').

    Duplicate entries of one bone in an influence list are summed.
    """
    idx = bone_indices[at]  # (n, S, K)
    w = bone_weights[at]
    match = (idx[..., :, None] == bones[:, None, None, :]) & (bones[:, None, None, :] >= 0)
    return np.einsum("nsk,nskb->nsb", w, match.astype(np.float64))


def related_bones(neighbours, bone_indices, bone_weights, vertices, max_bones=None):
    """The related bones of each listed vertex (see module notes): bones (n, K'), -1 padding.

    Order within a row: the vertex's own bones first, then by weight summed over the one-ring,
    then by bone id. K' is the largest set, or ``max(max_bones, own count)`` when capped.
    """
    idx = np.asarray(bone_indices, dtype=np.int64)
    w = np.asarray(bone_weights, dtype=np.float64)
    vertices = np.asarray(vertices, dtype=np.int64)
    n, k = vertices.shape[0], idx.shape[1]
    ring, mask = _padded_rings(neighbours, vertices)
    stencil = np.concatenate([vertices[:, None], ring], axis=1)  # (n, 1+P): i then its ring
    smask = np.concatenate([np.ones((n, 1), dtype=bool), mask], axis=1)
    row = np.broadcast_to(np.arange(n)[:, None, None], stencil.shape + (k,))
    own = np.broadcast_to((np.arange(stencil.shape[1]) == 0)[None, :, None], row.shape)
    live = smask[..., None] & (w[stencil] > 0.0)
    r, b, ws, o = row[live], idx[stencil][live], w[stencil][live], own[live]
    # Per (row, bone): summed weight, and whether the vertex itself has it.
    stride = int(idx.max()) + 1
    uniq, inverse = np.unique(r * stride + b, return_inverse=True)
    total = np.bincount(inverse, weights=ws)
    is_own = np.bincount(inverse, weights=o.astype(np.float64)) > 0
    ur, ub = uniq // stride, uniq % stride
    order = np.lexsort((ub, -total, ~is_own, ur))
    ur, ub, is_own = ur[order], ub[order], is_own[order]
    counts = np.bincount(ur, minlength=n)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    rank = np.arange(ur.shape[0]) - first[ur]
    width = int(counts.max()) if counts.size else 0
    if max_bones is not None:
        own_count = np.bincount(ur[is_own], minlength=n)
        limit = np.maximum(max_bones, own_count)
        keep = rank < limit[ur]
        ur, ub, rank = ur[keep], ub[keep], rank[keep]
        width = int(np.minimum(counts, limit).max()) if counts.size else 0
    out = np.full((n, width), -1, dtype=np.int64)
    out[ur, rank] = ub
    return out


def gather_weights(bone_indices, bone_weights, vertices, bones):
    """The vertices' own weights of ``bones (n, K')`` (-1 padding -> 0): (n, K').

    0 where a related bone only has a gradient at the vertex; these are eq. 8's w_ib.
    """
    vertices = np.asarray(vertices, dtype=np.int64)
    return _weights_of(np.asarray(bone_indices, dtype=np.int64), np.asarray(bone_weights, dtype=np.float64),
                       vertices[:, None], np.asarray(bones, dtype=np.int64))[:, 0]


def weight_gradients(rest, neighbours, bone_indices, bone_weights, vertices, max_bones=None, rcond=1e-10):
    """∂w_ib/∂v̄_i at the listed vertices by Zheng App. A (eq. 15–17).

    rest (V, 3); neighbours (indptr, indices) from :func:`vertex_neighbours`; bone_indices (V, K),
    bone_weights (V, K); vertices (n,). Returns (bones (n, K') with -1 padding — the related bones,
    see :func:`related_bones` — and gradients (n, K', 3), zero on padding), with
    Σ_b gradients[i, b] = 0 for every i (eq. 15). ``rcond``: relative singular-value cut-off of the
    pseudo-inverse of each A_i (minimum-norm solution where the ring does not span 3D).
    """
    rest = np.asarray(rest, dtype=np.float64)
    idx = np.asarray(bone_indices, dtype=np.int64)
    w = np.asarray(bone_weights, dtype=np.float64)
    vertices = np.asarray(vertices, dtype=np.int64)
    bones = related_bones(neighbours, idx, w, vertices, max_bones)
    active = (bones >= 0).astype(np.float64)  # (n, K')
    ring, mask = _padded_rings(neighbours, vertices)
    edge = rest[ring] - rest[vertices][:, None]  # v_j − v_i, (n, P, 3)
    length = np.linalg.norm(edge, axis=-1)
    scale = np.where(mask, 1.0 / np.where(length > 0.0, length, 1.0), 0.0)  # rows weighted by 1/|v_j − v_i|
    a = edge * scale[..., None]  # A_i, zero rows for padding (Zheng eq. 16)
    at_ring = _weights_of(idx, w, ring, bones)  # w_jb (n, P, K')
    at_self = _weights_of(idx, w, vertices[:, None], bones)  # w_ib (n, 1, K')
    c = (at_ring - at_self) * scale[..., None]  # weighted w_jb − w_ib (Zheng eq. 16)
    # Zheng eq. 15 null space: project each row of c onto {Σ_b = 0} over the active bones
    # (I − 11ᵀ/m); with identical blocks A_i (eq. 17) the constrained LSQ is A_i⁺ (c P).
    m = np.maximum(active.sum(axis=1), 1.0)
    c = (c - (c * active[:, None]).sum(axis=-1, keepdims=True) / m[:, None, None]) * active[:, None]
    grads = np.einsum("nap,npk->nka", np.linalg.pinv(a, rcond=rcond), c)  # (n, K', 3)
    # Re-apply the (idempotent) projector so eq. 15 holds to rounding of one subtraction.
    grads = (grads - (grads * active[..., None]).sum(axis=1, keepdims=True) / m[:, None, None]) * active[..., None]
    return bones, grads
