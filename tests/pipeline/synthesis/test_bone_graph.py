import itertools

import networkx as nx
import numpy as np
import pytest

from skinsynth.pipeline.synthesis.bone_graph import (bone_components, bone_graph_weights, decompose,
                                           prune_weak_edges)
from skinsynth.pipeline.inputs.examples import synthetic_lbs


def random_model(vertices=60, bones=7, slots=3, seed=0):
    """Sparse weights with zero padding: distinct bones per row, some slots zero, rows sum 1."""
    rng = np.random.default_rng(seed)
    idx = np.stack([rng.permutation(bones)[:slots] for _ in range(vertices)])
    w = rng.uniform(0.05, 1.0, size=(vertices, slots))
    w[rng.uniform(size=(vertices, slots)) < 0.3] = 0.0
    w[:, 0] = np.maximum(w[:, 0], 0.1)
    w /= w.sum(axis=1, keepdims=True)
    idx[w == 0.0] = 0  # padding points at bone 0 with weight 0
    return idx, w


def pair_model(couplings, bones):
    """One vertex per coupling (i, j, d): weights (w, 1 − w) with w (1 − w) = d, plus one rigid vertex per bone."""
    rows, weights = [], []
    for i, j, d in couplings:
        w = 0.5 * (1.0 + np.sqrt(1.0 - 4.0 * d))
        rows.append([i, j, 0])
        weights.append([w, 1.0 - w, 0.0])
    for b in range(bones):
        rows.append([b, 0, 0])
        weights.append([1.0, 0.0, 0.0])
    return np.array(rows), np.array(weights)


def test_eq11_matches_brute_force():
    idx, w = random_model()
    d = bone_graph_weights(idx, w, 7)
    brute = np.zeros((7, 7))
    for v in range(idx.shape[0]):
        for k, l in itertools.permutations(range(idx.shape[1]), 2):
            if w[v, k] > 0 and w[v, l] > 0 and idx[v, k] != idx[v, l]:
                brute[idx[v, k], idx[v, l]] = max(brute[idx[v, k], idx[v, l]], w[v, k] * w[v, l])
    assert np.array_equal(d, brute)
    assert np.array_equal(d, d.T) and np.all(np.diag(d) == 0.0)
    # Padding (weight 0) creates no edge, whatever bone id the padded slot holds.
    pad = bone_graph_weights(np.array([[0, 1, 2], [1, 2, 0]]), np.array([[0.5, 0.5, 0.0], [1.0, 0.0, 0.0]]), 3)
    assert np.array_equal(pad, [[0.0, 0.25, 0.0], [0.25, 0.0, 0.0], [0.0, 0.0, 0.0]])


def test_chain_of_bones_along_a_tube():
    lbs = synthetic_lbs(bones=6, frames=2, max_influences=2)
    d = bone_graph_weights(lbs["bone_indices"], lbs["bone_weights"], 6)
    # Two influences per vertex: only neighbours along the tube share vertices.
    assert all((d[i, j] > 0) == (abs(i - j) == 1) for i in range(6) for j in range(6) if i != j)
    graph = prune_weak_edges(d)
    assert sorted(graph.edges) == [(i, i + 1) for i in range(5)]
    split = decompose(graph, min_bones=2)
    assert split.cut_nodes == [1, 2, 3, 4]
    assert split.components == [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5]]
    assert split.component_of_cut == {1: [0, 1], 2: [1, 2], 3: [2, 3], 4: [3, 4]}
    merged = decompose(graph)  # default min_bones = 3: single edges merge along the chain
    assert merged.cut_nodes == [1, 2, 3, 4]
    assert merged.components == [[0, 1, 2], [2, 3, 4, 5]]
    assert merged.component_of_cut == {2: [0, 1]}
    assert merged.blocks == split.components
    assert decompose(graph, min_bones=10).components == [[0, 1, 2, 3, 4, 5]]


def body_and_tail():
    """Bones 0–4 all coupled (a body), a chain 4–5–6–7 (a tail), one weak body–tail coupling 1–6."""
    body = [(i, j, 0.15 + 0.01 * (i + j)) for i, j in itertools.combinations(range(5), 2)]
    tail = [(4, 5, 0.15), (5, 6, 0.2), (6, 7, 0.18)]
    return body + tail + [(1, 6, 0.01)]


def test_body_and_tail_separates_the_tail_at_the_attachment_bone():
    idx, w = pair_model(body_and_tail(), 8)
    d, graph, split = bone_components(idx, w, 8)
    assert d[1, 6] == pytest.approx(0.01) and d[4, 5] == pytest.approx(0.15)
    assert (1, 6) not in graph.edges and graph.graph["removed_edges"] == [(1, 6)]
    assert split.cut_nodes == [4, 5, 6]
    assert split.components == [[0, 1, 2, 3, 4], [4, 5, 6, 7]]
    assert split.component_of_cut == {4: [0, 1]}
    # Without pruning the weak coupling closes a cycle body–4–5–6–1: only the tail tip hangs off 6,
    # and that single edge merges back (min_bones = 3).
    unpruned = decompose(prune_weak_edges(d, edge_threshold=0.0))
    assert unpruned.cut_nodes == [6] and unpruned.blocks == [[0, 1, 2, 3, 4, 5, 6], [6, 7]]
    assert unpruned.components == [list(range(8))] and unpruned.component_of_cut == {}
    # Pairwise, components share at most one bone, and it is a cut node.
    for a, b in itertools.combinations(split.components, 2):
        shared = set(a) & set(b)
        assert len(shared) <= 1 and shared <= set(split.cut_nodes)


def test_pruning_removes_weak_edges_and_never_disconnects():
    rng = np.random.default_rng(3)
    for trial in range(20):
        bones = 12
        d = rng.uniform(0.0, 0.25, size=(bones, bones)) ** 2
        d[rng.uniform(size=d.shape) < 0.6] = 0.0
        d = np.triu(d, 1)
        d = d + d.T
        full = prune_weak_edges(d, edge_threshold=0.0)
        graph = prune_weak_edges(d, edge_threshold=0.3)
        limit = 0.3 * d.max()
        assert graph.graph["edge_threshold"] == pytest.approx(limit)
        assert sorted(graph.nodes) == list(range(bones))
        # The connected components are the same node sets.
        assert sorted(map(sorted, nx.connected_components(graph))) == \
            sorted(map(sorted, nx.connected_components(full)))
        # Every removed edge was weak; every weak edge left is a bridge (removing it would split).
        assert all(d[i, j] < limit for i, j in graph.graph["removed_edges"])
        bridges = {tuple(sorted(e)) for e in nx.bridges(graph)}
        weak_left = {(i, j) for i, j in graph.edges if d[i, j] < limit}
        assert weak_left <= bridges
        assert all(graph.edges[i, j]["weight"] == d[i, j] for i, j in graph.edges)
        assert len(graph.graph["removed_edges"]) + graph.number_of_edges() == full.number_of_edges()


def test_pruning_order_ties_by_edge_ids():
    d = np.zeros((4, 4))
    for i, j, v in [(0, 1, 0.01), (0, 2, 0.01), (1, 2, 0.01), (0, 3, 1.0)]:
        d[i, j] = d[j, i] = v
    graph = prune_weak_edges(d)
    assert graph.graph["removed_edges"] == [(0, 1)]
    assert graph.graph["kept_weak_edges"] == [(0, 2), (1, 2)]
    assert sorted(graph.edges) == [(0, 2), (0, 3), (1, 2)]


def test_single_component_and_isolated_bones():
    idx, w = pair_model(body_and_tail(), 10)  # bones 8 and 9 have no coupling at all
    d, graph, split = bone_components(idx, w, 10)
    assert [8] in split.components and [9] in split.components
    assert split.components[:2] == [[0, 1, 2, 3, 4], [4, 5, 6, 7]]
    one = decompose(graph, single_component=True)
    assert one.components == [list(range(10))] and one.cut_nodes == [] and one.component_of_cut == {}


def test_decomposition_is_deterministic():
    idx, w = pair_model(body_and_tail(), 8)
    d = bone_graph_weights(idx, w, 8)
    first = decompose(prune_weak_edges(d))
    # The same graph built with its nodes and edges inserted in another order.
    graph = prune_weak_edges(d)
    shuffled = nx.Graph()
    shuffled.add_nodes_from(reversed(list(graph.nodes)))
    shuffled.add_edges_from(reversed(list(graph.edges(data=True))))
    for again in (decompose(prune_weak_edges(d)), decompose(shuffled)):
        assert again.components == first.components
        assert again.cut_nodes == first.cut_nodes
        assert again.component_of_cut == first.component_of_cut
