"""Geometry every stage measures by: bounding boxes, mesh edges, vertex normals, accelerations, crowd
layout.

The lowest floor of ``pipeline`` with :mod:`.rotations`: the stages (skin, puppet, synthesis,
view) import it and never each other.
"""

import numpy as np
import scipy.sparse


def bounding_box_diagonal(points):
    """Length of the axis-aligned bounding-box diagonal of points (N, 3)."""
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def points_inside(points, vertices, faces):
    """Whether each of points (P, 3) lies inside the mesh's volume: bool (P,), where the
    magnitude of the winding number (:func:`.winding.winding_numbers`) is at least ½. For one closed shell
    this is the ray-parity verdict; where shells overlap (several tubes in one mesh) parity would
    call the overlap outside, the winding number counts it twice, inside."""
    from .winding import triangle_corners

    return inside_test(triangle_corners(vertices, faces))(points)


def inside_test(corners):
    """:func:`points_inside` of the mesh whose triangles are ``corners`` (T, 3, 3)
    (:func:`.winding.triangle_corners`, gathered once for many tests) as a function of the points
    (P, 3) alone."""
    from .winding import winding_at

    return lambda points: np.abs(winding_at(points, corners)) >= 0.5


def largest_side(points):
    """Largest side of the axis-aligned bounding box of points (N, 3)."""
    return float(np.ptp(points, axis=0).max())


def frame_accelerations(vertices):
    """Largest vertex acceleration ‖x(m+1) − 2 x(m) + x(m−1)‖ per frame: vertices (M, V, 3) ->
    (M,), NaN at the first and last frame (no second difference there)."""
    out = np.full(vertices.shape[0], np.nan)
    if vertices.shape[0] >= 3:
        out[1:-1] = np.linalg.norm(np.diff(vertices, n=2, axis=0), axis=-1).max(axis=1)
    return out


def largest_acceleration(vertices, starts=None, block=32):
    """The largest vertex acceleration (:func:`frame_accelerations`) of vertices (F, V, 3), inside
    each clip (``starts`` (C + 1,) the clips' first frames and F; None: one clip), never across the
    step from one clip's last frame to the next one's first; NaN with no clip of 3 frames. In
    blocks of ``block`` second differences, so a long capture's differences are never all in memory."""
    starts = [0, vertices.shape[0]] if starts is None else np.asarray(starts, np.int64)
    return max((np.nanmax(frame_accelerations(vertices[m:min(m + block + 2, b)]))
                for a, b in zip(starts[:-1], starts[1:]) for m in range(a, b - 2, block)), default=np.nan)


def vertex_areas(vertices, faces):
    """(V,): each vertex's share of the surface, a third of the area of every triangle it is a corner
    of (vertices (V, 3), faces (T, 3)): how much skin a vertex stands for, whatever the tessellation."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    corners = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    return np.bincount(faces.ravel(), weights=np.repeat(area / 3.0, 3), minlength=len(vertices))


def mesh_edges(faces):
    """Unique undirected edges (E, 2), lower index first, in order, of triangles faces (T, 3). Each
    edge as one integer (lower · count + higher: the same order) for a 1-D unique, 4–5× faster
    than the unique of rows."""
    pairs = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    count = int(pairs.max()) + 1 if pairs.size else 1
    keys = np.unique(pairs[:, 0].astype(np.int64) * count + pairs[:, 1])
    return np.stack([keys // count, keys % count], axis=1).astype(pairs.dtype)


def grid_offsets(characters, spacing, up_axis="Y"):
    """offsets (C, 3): a near-square grid on the ground plane (x–z for Y-up, x–y for Z-up)."""
    columns = int(np.ceil(np.sqrt(characters)))
    index = np.arange(characters)
    offsets = np.zeros((characters, 3))
    offsets[:, 0] = (index % columns) * spacing
    offsets[:, 2 if up_axis == "Y" else 1] = (index // columns) * spacing
    return offsets


def vertex_normals(vertices, faces, block_bytes=64 << 20):
    """Unit area-weighted vertex normals (F, V, 3) of vertices (F, V, 3) and faces (T, 3), in
    float64 (a vertex no face touches, or whose faces cancel, gets 0). Frames are taken in blocks
    whose face corners hold about ``block_bytes`` (each frame's normals are its own: the same
    values whatever the blocks; a 600-frame samba animation peaked at 2.2 GB whole)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    frames, count = vertices.shape[:2]
    faces = np.asarray(faces)
    incidence = scipy.sparse.csr_matrix((np.ones(faces.size), (faces.ravel(), np.repeat(np.arange(len(faces)), 3))),
                                        shape=(count, len(faces)))
    out = np.empty((frames, count, 3))
    step = max(1, block_bytes // max(1, 72 * len(faces)))
    for start in range(0, frames, step):
        corners = vertices[start:start + step, faces]  # (f, T, 3, 3)
        face_normals = np.cross(corners[:, :, 1] - corners[:, :, 0], corners[:, :, 2] - corners[:, :, 0])  # area × 2
        block = len(corners)
        summed = (incidence @ face_normals.transpose(1, 0, 2).reshape(len(faces), -1)).reshape(count, block, 3)
        summed = summed.transpose(1, 0, 2)
        length = np.linalg.norm(summed, axis=-1, keepdims=True)
        out[start:start + block] = np.where(length > 0.0, summed / np.where(length > 0.0, length, 1.0), 0.0)
    return out
