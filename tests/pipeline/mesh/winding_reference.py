"""The numpy reference of :func:`skinsynth.pipeline.mesh.winding.winding_numbers` (what it replaced:
the same formula on (points × triangles) arrays, in blocks)."""

import numpy as np


def winding_numbers(points, vertices, faces, block_elements=1 << 22):
    """The generalized winding number of the mesh (vertices (V, 3), faces (T, 3)) at each of
    points (P, 3): (P,) float, Σ over the triangles of their solid angle seen from the point over
    4π (Van Oosterom & Strackee's formula). 1 inside a closed, outward-oriented shell, 0 outside,
    2 where two shells overlap (a multi-shell character: a leg tube inside the pelvis tube); the
    sign flips with the orientation. In blocks of at most ``block_elements`` point–triangle pairs."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)].transpose(1, 2, 0)  # (3 corners, 3 axes, T)
    out = np.zeros(len(points))
    step = max(1, block_elements // max(1, corners.shape[2]))
    for start in range(0, len(points), step):
        block = points[start:start + step]  # (p, 3)
        # Corner minus point, component by component: (p, T) arrays, no strided (p, T, 3) work.
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = (
            tuple(corners[k, axis][None, :] - block[:, axis, None] for axis in range(3)) for k in range(3))
        la, lb, lc = (np.sqrt(x * x + y * y + z * z) for x, y, z in ((ax, ay, az), (bx, by, bz), (cx, cy, cz)))
        numerator = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
        denominator = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (ax * cx + ay * cy + az * cz) * lb
                       + (bx * cx + by * cy + bz * cz) * la)
        out[start:start + step] = np.arctan2(numerator, denominator).sum(axis=1) / (2.0 * np.pi)
    return out
