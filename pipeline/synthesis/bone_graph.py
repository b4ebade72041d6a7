"""Bone graph, cut nodes and weakly coupled bone components (Zheng §4.1).

From a fitted LBS model (``bone_indices (V, K)``, ``bone_weights (V, K)``, ≥ 0, rows sum to 1,
zero padding):

1. :func:`bone_graph_weights`: d_ij = max_v w_vi w_vj (Zheng eq. 11).
2. :func:`prune_weak_edges`: drop edges lighter than T_e = 0.1 max d, lightest first, without
   breaking a connected component apart.
3. :func:`decompose`: cut nodes (articulation points) and components. A cut node b_c that splits
   the graph into B1 and B2 gives the components B1 ∪ {b_c} and B2 ∪ {b_c}; in graph terms the
   components are the blocks (biconnected components) of the block–cut tree, which share their
   cut nodes. Blocks smaller than ``min_bones`` are merged into a neighbour so a chain of bones
   does not shatter into single edges.

Graph algorithms are networkx's (articulation points, biconnected components, paths), imported by
the functions that use them: synthesize reads eq. 11's couplings (:func:`bone_graph_weights`) alone.
"""

from dataclasses import dataclass, field

import numpy as np

from ..errors import OptionError


def bone_graph_weights(bone_indices, bone_weights, bones):
    """Bone coupling weights (Zheng eq. 11): d (B, B), d_ij = max_v w_vi w_vj.

    bone_indices (V, K) int, bone_weights (V, K). The max runs over vertices where both weights
    are non-zero; d_ij = 0 where there is none (no edge). Symmetric, zero diagonal. Vectorised
    over vertices: one ``np.maximum.at`` per pair of influence slots k < l.
    """
    idx = np.asarray(bone_indices, dtype=np.int64)
    w = np.asarray(bone_weights, dtype=np.float64)
    if idx.shape != w.shape or idx.ndim != 2:
        raise ValueError(f"bone_indices {idx.shape} and bone_weights {w.shape} must both be (V, K)")
    if idx.size and (idx.min() < 0 or idx.max() >= bones):
        raise OptionError(f"bone indices must lie in 0..{bones - 1}")
    d = np.zeros((bones, bones))
    for k in range(idx.shape[1]):
        for l in range(k + 1, idx.shape[1]):
            product = w[:, k] * w[:, l]
            # Zheng eq. 11: only vertices where both weights are non-zero (padding has w = 0).
            use = (product > 0.0) & (idx[:, k] != idx[:, l])
            a, b, p = idx[use, k], idx[use, l], product[use]
            np.maximum.at(d, (a, b), p)
            np.maximum.at(d, (b, a), p)
    np.fill_diagonal(d, 0.0)
    return d


def prune_weak_edges(d, edge_threshold=0.1):
    """The bone graph with weak couplings removed (Zheng §4.1, "Cut Nodes") -> networkx.Graph.

    d (B, B) symmetric coupling weights. The graph has all B nodes and an edge (i, j) with
    attribute ``weight = d_ij`` wherever d_ij > 0. Edges with d_ij < ``edge_threshold`` × max d
    (Zheng: T_e = 0.1 max d_ij) are removed in increasing order of weight, ties by (i, j),
    skipping any removal that would disconnect a connected component ("without breaking the
    graph into disconnected components"), i.e. an edge that is a bridge at its turn stays. The
    graph records ``graph.graph["edge_threshold"]`` (the absolute T_e), ``["removed_edges"]``
    and ``["kept_weak_edges"]`` (lists of (i, j), i < j, in the order they were considered).
    """
    d = np.asarray(d, dtype=np.float64)
    if d.ndim != 2 or d.shape[0] != d.shape[1]:
        raise ValueError(f"d must be a square (B, B) matrix (got {d.shape})")
    if not np.allclose(d, d.T):
        raise ValueError("d must be symmetric")
    bones = d.shape[0]
    import networkx as nx

    graph = nx.Graph()
    graph.add_nodes_from(range(bones))
    i, j = np.nonzero(np.triu(d, k=1) > 0.0)
    graph.add_weighted_edges_from((int(a), int(b), float(d[a, b])) for a, b in zip(i, j))
    limit = edge_threshold * (float(d.max()) if d.size else 0.0)
    weak = [(float(d[a, b]), int(a), int(b)) for a, b in zip(i, j) if d[a, b] < limit]
    removed, kept = [], []
    for weight, a, b in sorted(weak):
        graph.remove_edge(a, b)
        if nx.has_path(graph, a, b):
            removed.append((a, b))
        else:  # a bridge at this point: removing it would split its component
            graph.add_edge(a, b, weight=weight)
            kept.append((a, b))
    graph.graph.update(edge_threshold=limit, removed_edges=removed, kept_weak_edges=kept)
    return graph


@dataclass
class Decomposition:
    """Bone components of a bone graph (Zheng §4.1).

    cut_nodes: sorted articulation points of the (pruned) graph; components: sorted lists of
    bone ids, sorted by their first id; each pair of components shares at most one bone, a cut
    node; component_of_cut: {cut node: sorted indices into ``components``} for every cut node
    that still joins two or more components after merging (a cut node that ended up inside one
    merged component is not listed); blocks: the biconnected components (plus isolated bones)
    before merging; min_bones: the merge size used.
    """

    cut_nodes: list
    components: list
    component_of_cut: dict
    blocks: list = field(default_factory=list)
    min_bones: int = 0


def decompose(graph, single_component=False, min_bones=3):
    """Cut nodes and weakly coupled components of a bone graph (Zheng §4.1) -> Decomposition.

    ``graph``: a networkx.Graph over bone ids (e.g. from :func:`prune_weak_edges`).
    ``single_component=True``: one component with every bone and no cut nodes (Zheng §3, and
    what cloth gives anyway).

    Otherwise each block of the block–cut tree (``networkx.biconnected_components``; a bridge is
    a two-bone block) is a component: a cut node b_c that separates B1 from B2 gives B1 ∪ {b_c}
    and B2 ∪ {b_c}. Bones without any edge form a component of their own. Then blocks with fewer
    than ``min_bones`` bones (cut nodes counted) are merged, smallest first (ties by their
    sorted ids), into a neighbouring block, i.e. one sharing one of their cut nodes. The
    neighbour chosen is the one giving the smallest union, then the one holding the shared cut
    node most strongly (largest total weight of its edges at that cut node), then the lowest ids.
    Smallest-union first lets a run of single edges (a tail, a chain) coalesce into a piece of
    ``min_bones`` bones instead of each edge being swallowed by the big block at its end: a
    coupling-first rule would always pick the body for a tail's first edge, since the
    attachment bone's edges inside the body outweigh the tail's single edge. Merging stops when
    no small block has a neighbour (a whole small connected component stays as it is).
    ``min_bones=2`` merges nothing (every block has at least 2 bones); the default 3 merges the
    single-edge blocks.
    """
    nodes = sorted(int(n) for n in graph.nodes)
    if single_component:
        return Decomposition(cut_nodes=[], components=[nodes] if nodes else [], component_of_cut={},
                             blocks=[nodes] if nodes else [], min_bones=min_bones)
    import networkx as nx

    cut_nodes = sorted(int(n) for n in nx.articulation_points(graph))
    blocks = [frozenset(int(n) for n in block) for block in nx.biconnected_components(graph)]
    blocks += [frozenset([n]) for n in nodes if graph.degree(n) == 0]
    raw_blocks = sorted(sorted(block) for block in blocks)
    cut_set = set(cut_nodes)
    blocks = [frozenset(b) for b in raw_blocks]
    while True:
        small = [b for b in blocks if len(b) < min_bones and _neighbours(b, blocks, cut_set)]
        if not small:
            break
        block = min(small, key=lambda b: (len(b), sorted(b)))
        best = min(_neighbours(block, blocks, cut_set),
                   key=lambda nb: (len(block | nb), -_hold(graph, nb, block & nb), sorted(nb)))
        blocks = [b for b in blocks if b is not block and b is not best] + [block | best]
    components = sorted(sorted(b) for b in blocks)
    component_of_cut = {}
    for c in cut_nodes:
        owners = [k for k, comp in enumerate(components) if c in comp]
        if len(owners) >= 2:
            component_of_cut[c] = owners
    return Decomposition(cut_nodes=cut_nodes, components=components, component_of_cut=component_of_cut,
                         blocks=raw_blocks, min_bones=min_bones)


def bone_components(bone_indices, bone_weights, bones, edge_threshold=0.1, single_component=False,
                    min_bones=3):
    """Eq. 11, pruning and decomposition in one call -> (d (B, B), pruned graph, Decomposition)."""
    d = bone_graph_weights(bone_indices, bone_weights, bones)
    graph = prune_weak_edges(d, edge_threshold)
    return d, graph, decompose(graph, single_component=single_component, min_bones=min_bones)


def _neighbours(block, blocks, cut_set):
    """Blocks other than ``block`` sharing one of its cut nodes."""
    shared = block & cut_set
    return [b for b in blocks if b is not block and b & shared]


def _hold(graph, block, shared):
    """Total weight of the edges of ``block`` at its shared node(s) ``shared``."""
    return sum(float(data.get("weight", 1.0)) for c in shared for n, data in graph[c].items() if n in block)
