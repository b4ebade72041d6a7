"""The generalized winding number, compiled: one pass over the triangles per point, nothing
stored between them.

The numpy version (kept as the reference in ``tests/pipeline/mesh/winding_reference.py``) builds
some forty (points × triangles) temporaries; a skeleton fit tests a few hundred points against a
20,000-triangle body in each of its inside-the-mesh bisections, where those arrays were most of
the time (the samba's ``fit-skin --skeleton``: 5 of 37 s). Same formula, same sums per triangle
(Van Oosterom & Strackee's solid angle), added in triangle order.
"""

import numba
import numpy as np


#: Runs of triangles each point's sum is split into (summed in this order afterwards): the
#: (point, run) pairs are shared among the threads, so a few points against a large body (a
#: skeleton fit's bisections: 1–3 joints against 85,000 triangles) use every core; a fixed count,
#: not one per thread, so the sums are the same on any machine.
RUNS = 8


@numba.njit(cache=True, parallel=True, nogil=True)
def winding_loop(points, corners, out):
    """out (P,) the winding number at each of points (P, 3) of the triangles corners (T, 3, 3)
    (corner, axis): Σ_t 2 atan2(N_t, D_t) / 4π, over :data:`RUNS` runs of triangles added in order."""
    count, triangles = points.shape[0], corners.shape[0]
    length = (triangles + RUNS - 1) // RUNS
    partial = np.zeros((count, RUNS))
    for task in numba.prange(count * RUNS):
        p, run = task // RUNS, task % RUNS
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        total = 0.0
        for t in range(run * length, min(triangles, (run + 1) * length)):
            ax, ay, az = corners[t, 0, 0] - px, corners[t, 0, 1] - py, corners[t, 0, 2] - pz
            bx, by, bz = corners[t, 1, 0] - px, corners[t, 1, 1] - py, corners[t, 1, 2] - pz
            cx, cy, cz = corners[t, 2, 0] - px, corners[t, 2, 1] - py, corners[t, 2, 2] - pz
            la = np.sqrt(ax * ax + ay * ay + az * az)
            lb = np.sqrt(bx * bx + by * by + bz * bz)
            lc = np.sqrt(cx * cx + cy * cy + cz * cz)
            numerator = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
            denominator = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (ax * cx + ay * cy + az * cz) * lb
                           + (bx * cx + by * cy + bz * cz) * la)
            total += np.arctan2(numerator, denominator)
        partial[p, run] = total
    for p in range(count):
        total = 0.0
        for run in range(RUNS):
            total += partial[p, run]
        out[p] = total / (2.0 * np.pi)


def triangle_corners(vertices, faces):
    """corners (T, 3, 3) (triangle, corner, axis) of the mesh (vertices (V, 3), faces (T, 3)), laid
    out for :func:`winding_at`: gathered once where many points are tested against one mesh."""
    return np.ascontiguousarray(np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64)])


def winding_at(points, corners):
    """:func:`winding_numbers` of the triangles ``corners`` (T, 3, 3) (:func:`triangle_corners`)."""
    points = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    out = np.zeros(len(points))
    winding_loop(points, corners, out)
    return out


def winding_numbers(points, vertices, faces):
    """The generalized winding number of the mesh (vertices (V, 3), faces (T, 3)) at each of
    points (P, 3): (P,) float64, Σ over the triangles of their solid angle seen from the point over
    4π. 1 inside a closed, outward-oriented shell, 0 outside, 2 where two shells overlap (a
    multi-shell character: a leg tube inside the pelvis tube); the sign flips with the orientation."""
    return winding_at(points, triangle_corners(vertices, faces))
