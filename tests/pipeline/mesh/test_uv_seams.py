"""pipeline.uv_seams against a brute-force walk over the corners: every corner keeps its UV and its
vertex, the split is the least one, originals first; and the glTF rig split at the seams."""

import numpy as np
import pytest

from skinsynth.pipeline.rig.skeleton import gltf_rig
from skinsynth.pipeline.mesh.uv_seams import gltf_texcoords, split_uv_seams


def reference_split(faces, face_uvs, vertex_count):
    """The rule spelled out corner by corner: a vertex's first corner keeps the vertex, each
    further distinct UV of it a new vertex, numbered in the order first met."""
    uvs = [(0.0, 0.0)] * vertex_count
    vertex_map = list(range(vertex_count))
    seen = {}  # (vertex, u, v) -> new vertex
    used = set()
    new_faces = np.empty_like(faces)
    for t in range(len(faces)):
        for k in range(3):
            vertex, uv = int(faces[t, k]), (float(face_uvs[t, k, 0]), float(face_uvs[t, k, 1]))
            key = (vertex,) + uv
            if key not in seen:
                if vertex not in used:
                    used.add(vertex)
                    seen[key] = vertex
                    uvs[vertex] = uv
                else:
                    seen[key] = len(vertex_map)
                    vertex_map.append(vertex)
                    uvs.append(uv)
            new_faces[t, k] = seen[key]
    return np.array(vertex_map), new_faces, np.array(uvs)


def random_mesh(rng):
    """A small mesh whose UVs come from a few values, so that seams (one vertex, several UVs) and
    shared UVs both happen; some vertices may be unused."""
    vertex_count = int(rng.integers(1, 12))
    triangles = int(rng.integers(1, 15))
    faces = rng.integers(0, vertex_count, size=(triangles, 3))
    per_vertex = rng.integers(0, 3, size=vertex_count) / 2.0  # a UV each vertex mostly keeps
    face_uvs = np.stack([per_vertex[faces], np.full(faces.shape, 0.25)], axis=-1)
    seams = rng.random(faces.shape) < rng.random()  # some corners take another UV
    face_uvs[seams] = rng.integers(0, 3, size=(int(seams.sum()), 2)) / 4.0
    return faces, face_uvs, vertex_count


@pytest.mark.parametrize("seed", range(200))
def test_the_split_is_the_brute_force_walk_and_keeps_every_corner(seed):
    faces, face_uvs, count = random_mesh(np.random.default_rng(seed))
    vertex_map, new_faces, uvs = split_uv_seams(faces, face_uvs, count)
    ref_map, ref_faces, ref_uvs = reference_split(faces, face_uvs, count)
    np.testing.assert_array_equal(vertex_map, ref_map)
    np.testing.assert_array_equal(new_faces, ref_faces)
    np.testing.assert_array_equal(uvs, ref_uvs)
    # the properties themselves
    np.testing.assert_array_equal(uvs[new_faces], face_uvs)  # every corner's UV
    np.testing.assert_array_equal(vertex_map[new_faces], faces)  # every corner's original vertex
    np.testing.assert_array_equal(vertex_map[:count], np.arange(count))  # originals first, in order
    pairs = {(int(v),) + tuple(uv) for v, uv in zip(faces.ravel(), face_uvs.reshape(-1, 2))}
    unused = count - len(np.unique(faces))
    assert len(vertex_map) == len(pairs) + unused  # the least split
    assert vertex_map.dtype == np.int64 and new_faces.dtype == np.int64 and uvs.dtype == np.float64


def test_one_uv_per_vertex_splits_nothing():
    rng = np.random.default_rng(5)
    faces = np.array([[0, 1, 2], [2, 1, 3], [3, 4, 2]])
    per_vertex = rng.random((5, 2))
    vertex_map, new_faces, uvs = split_uv_seams(faces, per_vertex[faces], 5)
    np.testing.assert_array_equal(vertex_map, np.arange(5))
    np.testing.assert_array_equal(new_faces, faces)
    np.testing.assert_array_equal(uvs, per_vertex)


def test_a_seam_vertex_gets_one_copy_per_extra_uv():
    faces = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1]])
    face_uvs = np.array([[[0, 0], [1, 0], [1, 1]], [[1, 0], [1, 1], [0, 1]], [[0, 0], [0, 1], [1, 0]]], float)
    vertex_map, new_faces, uvs = split_uv_seams(faces, face_uvs, 4)
    assert vertex_map.tolist() == [0, 1, 2, 3, 0]  # vertex 0 carries (0, 0) and (1, 0)
    assert new_faces.tolist() == [[0, 1, 2], [4, 2, 3], [0, 3, 1]]
    assert uvs.tolist() == [[0, 0], [1, 0], [1, 1], [0, 1], [1, 0]]


def test_bad_shapes_are_refused():
    with pytest.raises(ValueError):
        split_uv_seams(np.zeros((2, 3), int), np.zeros((2, 3, 3)), 3)
    with pytest.raises(ValueError):
        split_uv_seams(np.array([[0, 1, 5]]), np.zeros((1, 3, 2)), 3)


def test_gltf_texcoords_flip_v():
    np.testing.assert_array_equal(gltf_texcoords(np.array([[0.25, 0.0], [1.0, 0.75]])), [[0.25, 1.0], [1.0, 0.25]])


def test_gltf_rig_with_uvs_duplicates_each_seam_vertex_whole():
    rng = np.random.default_rng(2)
    rest = rng.normal(size=(4, 3))
    faces = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1]])
    face_uvs = rng.random((3, 3, 2))
    face_uvs[:, :, :] = face_uvs[0, 0]  # one UV everywhere but at vertex 1 in the last face
    face_uvs[2, 2] = (0.5, 0.5)
    indices = np.array([[0, 1], [1, 0], [1, 0], [0, 1]])
    weights = np.array([[0.7, 0.3], [1.0, 0.0], [0.6, 0.4], [0.5, 0.5]])
    centres = rng.normal(size=(2, 3))
    plain = gltf_rig(rest, faces, indices, weights, centres, up_axis="Z", meters_per_unit=0.01)
    split = gltf_rig(rest, faces, indices, weights, centres, up_axis="Z", meters_per_unit=0.01, face_uvs=face_uvs)
    assert "uvs" not in plain
    vertex_map = [0, 1, 2, 3, 1]
    for name in ("positions", "normals", "joints", "weights"):
        np.testing.assert_array_equal(split[name], plain[name][vertex_map])
    for name in ("inverse_binds", "bind_translations"):
        np.testing.assert_array_equal(split[name], plain[name])
    assert split["faces"].tolist() == [[0, 1, 2], [0, 2, 3], [0, 3, 4]]
    np.testing.assert_array_equal(split["uvs"][split["faces"]], gltf_texcoords(face_uvs.reshape(-1, 2)).reshape(3, 3, 2))
