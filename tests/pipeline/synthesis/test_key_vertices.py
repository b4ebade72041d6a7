import numpy as np
import pytest

from skinsynth.pipeline.inputs.examples import cylinder_mesh, synthetic_lbs
from skinsynth.pipeline.synthesis.key_vertices import (gather_weights, key_vertices, related_bones, vertex_neighbours,
                                             weight_gradients)
from mesh_cases import dense, irregular_sphere, random_sparse_weights


@pytest.mark.parametrize("seed", [0, 1])
def test_key_vertices_match_brute_force(seed):
    bones = 9
    idx, w = random_sparse_weights(400, bones, 3, seed=seed)
    w = np.round(w, 2)  # produce ties; broken by the lower vertex index
    w /= w.sum(axis=1, keepdims=True)
    full = dense(idx, w, bones)
    kv = key_vertices(idx, w, bones)
    assert np.all(np.diff(kv.vertices) > 0)
    singles = kv.choice_bones[kv.choice_bones[:, 1] < 0, 0]
    assert sorted(singles.tolist()) == list(range(bones))
    for b in range(bones):
        # One per bone, its max-weight vertex (the first on ties).
        (row,) = np.nonzero((kv.choice_bones[:, 0] == b) & (kv.choice_bones[:, 1] < 0))
        assert kv.vertices[kv.choice_key[row[0]]] == np.argmax(full[:, b])
    pairs = {tuple(p): kv.vertices[k] for p, k in zip(kv.choice_bones, kv.choice_key) if p[1] >= 0}
    for i in range(bones):
        for j in range(i + 1, bones):
            product = full[:, i] * full[:, j]
            if product.max() > 0:
                assert pairs[(i, j)] == np.argmax(product)
                v = pairs[(i, j)]
                assert full[v, i] > 0 and full[v, j] > 0
            else:
                assert (i, j) not in pairs
    for i in range(len(kv.vertices)):
        assert len(kv.reasons(i)) >= 1


def test_key_vertices_pairs_only_where_both_weights_nonzero():
    # Tube with two-influence weights: only neighbouring bones share vertices.
    model = synthetic_lbs(bones=6, max_influences=2)
    kv = key_vertices(model["bone_indices"], model["bone_weights"], 6)
    full = dense(model["bone_indices"], model["bone_weights"], 6)
    pairs = kv.choice_bones[kv.choice_bones[:, 1] >= 0]
    assert {tuple(p) for p in pairs} == {(b, b + 1) for b in range(5)}
    for (i, j), k in zip(kv.choice_bones, kv.choice_key):
        if j >= 0:
            assert full[kv.vertices[k], i] > 0 and full[kv.vertices[k], j] > 0


def test_key_vertices_subset_and_unused_bone():
    idx, w = random_sparse_weights(200, 6, 3, seed=4)
    idx[idx == 5] = 4  # bone 5 never used; bone 4 may now appear twice in a row
    kv = key_vertices(idx, w, 6)
    assert 5 not in kv.choice_bones
    assert not np.any(kv.choice_bones[:, 0] == kv.choice_bones[:, 1])
    sub = key_vertices(idx, w, 6, subset=[0, 2, 3])
    assert set(np.unique(sub.choice_bones[sub.choice_bones >= 0]).tolist()) <= {0, 2, 3}
    assert sum(1 for p in sub.choice_bones if p[1] < 0) == 3


def test_vertex_neighbours_match_faces():
    rest, faces = irregular_sphere(80)
    indptr, indices = vertex_neighbours(faces, rest.shape[0])
    ring = [set() for _ in range(rest.shape[0])]
    for a, b, c in faces:
        ring[a] |= {b, c}
        ring[b] |= {a, c}
        ring[c] |= {a, b}
    for v in range(rest.shape[0]):
        assert indices[indptr[v]:indptr[v + 1]].tolist() == sorted(ring[v])


def assert_gradients_sum_to_zero(rest, faces, idx, w, vertices):
    neighbours = vertex_neighbours(faces, rest.shape[0])
    bones, grads = weight_gradients(rest, neighbours, idx, w, vertices)
    assert np.all(grads[bones < 0] == 0.0)
    # Zheng eq. 15 at every listed vertex.
    assert np.abs(grads.sum(axis=1)).max() < 1e-10
    assert np.abs(grads).max() > 1e-3  # not trivially zero
    return neighbours, bones, grads


def test_gradients_sum_to_zero_on_irregular_mesh():
    rest, faces = irregular_sphere(300, seed=2)
    idx, w = random_sparse_weights(rest.shape[0], 8, 4, seed=2)
    kv = key_vertices(idx, w, 8)
    assert_gradients_sum_to_zero(rest, faces, idx, w, kv.vertices)
    assert_gradients_sum_to_zero(rest, faces, idx, w, np.arange(rest.shape[0]))  # every vertex, not only key ones


def test_gradients_sum_to_zero_on_tube():
    model = synthetic_lbs(bones=6, max_influences=4)
    kv = key_vertices(model["bone_indices"], model["bone_weights"], 6)
    neighbours, bones, grads = assert_gradients_sum_to_zero(model["rest"], model["faces"], model["bone_indices"],
                                         model["bone_weights"], kv.vertices)
    # Related bones: every bone with weight at the vertex or its ring, own bones first.
    indptr, indices = neighbours
    full = dense(model["bone_indices"], model["bone_weights"], 6)
    for row, v in enumerate(kv.vertices):
        stencil = np.concatenate([[v], indices[indptr[v]:indptr[v + 1]]])
        expected = set(np.nonzero(full[stencil].sum(axis=0) > 0)[0].tolist())
        got = bones[row][bones[row] >= 0]
        assert set(got.tolist()) == expected
        own = full[v, got] > 0
        assert not np.any(own[1:] & ~own[:-1])  # own bones come first


def test_linear_weights_recovered_exactly():
    rest, faces = irregular_sphere(250, seed=5)
    a = np.array([[0.10, 0.05, -0.02], [-0.04, 0.08, 0.03], [0.02, -0.10, 0.06], [-0.08, -0.03, -0.07]])
    c = np.array([0.3, 0.25, 0.2, 0.25])
    assert np.allclose(a.sum(axis=0), 0.0) and np.isclose(c.sum(), 1.0)
    full = rest @ a.T + c
    assert full.min() > 0.0 and full.max() < 1.0
    rng = np.random.default_rng(1)
    idx = np.argsort(rng.random(full.shape), axis=1)  # shuffled influence order
    w = np.take_along_axis(full, idx, axis=1)
    vertices = np.arange(rest.shape[0])
    bones, grads = weight_gradients(rest, vertex_neighbours(faces, rest.shape[0]), idx, w, vertices)
    assert bones.shape == (rest.shape[0], 4) and np.all(bones >= 0)
    assert np.abs(grads - a[bones]).max() < 1e-10
    assert np.allclose(gather_weights(idx, w, vertices, bones), full[vertices[:, None], bones], atol=1e-15)


def test_flat_fan_gets_minimum_norm_solution():
    # The tube's cap centre: all neighbours lie in its plane x = 0, so ∂w/∂x is not seen.
    rest, faces = cylinder_mesh(rings=6, segments=10)
    a = np.array([[0.05, 0.2, -0.1], [-0.05, -0.2, 0.1]])
    full = rest @ a.T + np.array([0.5, 0.5])
    idx = np.tile([0, 1], (rest.shape[0], 1))
    centre = rest.shape[0] - 2
    bones, grads = weight_gradients(rest, vertex_neighbours(faces, rest.shape[0]), idx, full, [centre])
    assert np.all(np.isfinite(grads))
    assert np.allclose(grads[0, :, 0], 0.0, atol=1e-14)  # minimum norm: nothing along the normal
    assert np.allclose(grads[0, :, 1:], a[bones[0], 1:], atol=1e-12)  # in-plane part is exact


def test_cap_keeps_own_bones():
    model = synthetic_lbs(bones=6, max_influences=4)
    idx, w = model["bone_indices"], model["bone_weights"]
    neighbours = vertex_neighbours(model["faces"], model["rest"].shape[0])
    vertices = np.arange(0, model["rest"].shape[0], 7)
    full_set = related_bones(neighbours, idx, w, vertices)
    capped = related_bones(neighbours, idx, w, vertices, max_bones=2)
    assert capped.shape[1] < full_set.shape[1]
    full = dense(idx, w, 6)
    for row, v in enumerate(vertices):
        own = set(np.nonzero(full[v])[0].tolist())
        assert own <= set(capped[row].tolist())
        assert np.all(capped[row][: max(2, len(own))] == full_set[row][: max(2, len(own))])
    bones, grads = weight_gradients(model["rest"], neighbours, idx, w, vertices, max_bones=2)
    assert np.array_equal(bones, capped)
    assert np.abs(grads.sum(axis=1)).max() < 1e-10
