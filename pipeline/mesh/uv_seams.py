"""UV seams: a mesh whose UVs are per face corner, as formats that want one UV per vertex (glTF,
engines' vertex buffers) need it, with each vertex that carries several UVs split into copies.

Part of the floor (docs/architecture.md): arrays in, arrays out, no file.
"""

import numpy as np


def split_uv_seams(faces, face_uvs, vertex_count):
    """One UV per vertex: faces (T, 3) into ``vertex_count`` vertices and their corner UVs
    face_uvs (T, 3, 2) -> (vertex_map (V',) int64, the original vertex of each new one; faces
    (T, 3) int64 into the new vertices; uvs (V', 2) float64).

    The new vertices are the originals first, in order (vertex i keeps the UV of its first corner
    in ``faces.ravel()`` order; one no face uses gets UV (0, 0)), then one copy per further
    distinct (vertex, UV) pair, in the order their first corner appears. V' is the least that
    gives every corner its UV: the distinct (vertex, UV) pairs plus the unused vertices; when
    every vertex has one UV, V' = V and the map is the identity. UVs compare as numbers (exactly).
    """
    faces = np.asarray(faces, dtype=np.int64)
    face_uvs = np.asarray(face_uvs, dtype=np.float64)
    if faces.ndim != 2 or faces.shape[1] != 3 or face_uvs.shape != faces.shape + (2,):
        raise ValueError(f"faces (T, 3) and face_uvs (T, 3, 2) needed, got {faces.shape} and {face_uvs.shape}")
    vertex_count = int(vertex_count)
    vertex = faces.ravel()  # (C,) the vertex of each corner, C = 3T
    uv = face_uvs.reshape(-1, 2)
    if vertex.size and (vertex.min() < 0 or vertex.max() >= vertex_count):
        raise ValueError(f"face indices outside [0, {vertex_count})")

    # Corners sorted by (vertex, u, v), stable: each run of equal keys is one (vertex, UV) pair,
    # its first element the pair's first corner in face order.
    order = np.lexsort((uv[:, 1], uv[:, 0], vertex))
    sorted_vertex, sorted_uv = vertex[order], uv[order]
    starts = np.ones(order.size, dtype=bool)
    starts[1:] = (sorted_vertex[1:] != sorted_vertex[:-1]) | np.any(sorted_uv[1:] != sorted_uv[:-1], axis=1)
    pair_of_sorted = np.cumsum(starts) - 1  # (C,) pair id of each sorted corner
    pair_vertex = sorted_vertex[starts]  # (P,)
    pair_uv = sorted_uv[starts]  # (P, 2)
    pair_first = order[starts]  # (P,) the first corner of each pair

    # A vertex's primary pair is the one whose first corner comes first; the rest are copies.
    by_vertex = np.lexsort((pair_first, pair_vertex))
    grouped = pair_vertex[by_vertex]
    leads = np.ones(grouped.size, dtype=bool)
    leads[1:] = grouped[1:] != grouped[:-1]
    primary = np.zeros(pair_vertex.size, dtype=bool)
    primary[by_vertex[leads]] = True
    copies = np.flatnonzero(~primary)
    copies = copies[np.argsort(pair_first[copies], kind="stable")]

    new_index = np.empty(pair_vertex.size, dtype=np.int64)
    new_index[primary] = pair_vertex[primary]
    new_index[copies] = vertex_count + np.arange(copies.size)
    vertex_map = np.concatenate([np.arange(vertex_count, dtype=np.int64), pair_vertex[copies]])
    uvs = np.zeros((vertex_map.size, 2))
    uvs[pair_vertex[primary]] = pair_uv[primary]
    uvs[vertex_count:] = pair_uv[copies]
    corner_pair = np.empty(order.size, dtype=np.int64)
    corner_pair[order] = pair_of_sorted
    return vertex_map, new_index[corner_pair].reshape(faces.shape), uvs


def gltf_texcoords(uvs):
    """uvs (N, 2) in OBJ's and USD's convention (origin bottom left, v up) as glTF's TEXCOORD
    (origin top left, v down): (u, 1 − v)."""
    uvs = np.asarray(uvs, dtype=np.float64)
    return np.stack([uvs[:, 0], 1.0 - uvs[:, 1]], axis=1)
