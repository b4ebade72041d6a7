"""Where segments last cross a mesh's surface, compiled: one pass over the triangles per segment.

Putting a joint back inside the body (:func:`..skin.joints.inside_mesh`) needs the point where the
segment from the joint to an anchor inside enters the body for the last time; bisecting it with
winding numbers (:mod:`.winding`) took one pass over the triangles per halving (12 when a
skeleton is found: 0.2 of the horse collapse's 0.36 s), this takes one. Möller–Trumbore's
segment–triangle test; the largest crossing of each segment over :data:`.winding.RUNS` fixed runs
of triangles shared among the cores (a maximum: the same on any machine).
"""

import numba
import numpy as np

from .winding import RUNS

#: Crossings this close to a triangle's plane, as a share of its edges' product, are not counted
#: (a segment lying in a triangle's plane).
PARALLEL = 1e-12


@numba.njit(cache=True, parallel=True, nogil=True)
def crossing_loop(starts, ends, corners, out):
    """out (S,) the largest t in [0, 1] at which starts + t (ends − starts) (S, 3) meets one of the
    triangles corners (T, 3, 3), or −1 where the segment meets none."""
    count, triangles = starts.shape[0], corners.shape[0]
    length = (triangles + RUNS - 1) // RUNS
    partial = np.full((count, RUNS), -1.0)
    for task in numba.prange(count * RUNS):
        s, run = task // RUNS, task % RUNS
        ox, oy, oz = starts[s, 0], starts[s, 1], starts[s, 2]
        dx, dy, dz = ends[s, 0] - ox, ends[s, 1] - oy, ends[s, 2] - oz
        best = -1.0
        for t in range(run * length, min(triangles, (run + 1) * length)):
            ax, ay, az = corners[t, 0, 0], corners[t, 0, 1], corners[t, 0, 2]
            e1x, e1y, e1z = corners[t, 1, 0] - ax, corners[t, 1, 1] - ay, corners[t, 1, 2] - az
            e2x, e2y, e2z = corners[t, 2, 0] - ax, corners[t, 2, 1] - ay, corners[t, 2, 2] - az
            px, py, pz = dy * e2z - dz * e2y, dz * e2x - dx * e2z, dx * e2y - dy * e2x
            det = e1x * px + e1y * py + e1z * pz
            scale = np.sqrt((e1x * e1x + e1y * e1y + e1z * e1z) * (e2x * e2x + e2y * e2y + e2z * e2z)
                            * (dx * dx + dy * dy + dz * dz))
            if abs(det) <= PARALLEL * scale:
                continue
            inverse = 1.0 / det
            sx, sy, sz = ox - ax, oy - ay, oz - az
            u = (sx * px + sy * py + sz * pz) * inverse
            if u < 0.0 or u > 1.0:
                continue
            qx, qy, qz = sy * e1z - sz * e1y, sz * e1x - sx * e1z, sx * e1y - sy * e1x
            v = (dx * qx + dy * qy + dz * qz) * inverse
            if v < 0.0 or u + v > 1.0:
                continue
            along = (e2x * qx + e2y * qy + e2z * qz) * inverse
            if 0.0 <= along <= 1.0 and along > best:
                best = along
        partial[s, run] = best
    for s in range(count):
        best = -1.0
        for run in range(RUNS):
            best = max(best, partial[s, run])
        out[s] = best


def last_crossings(starts, ends, corners):
    """(S,) the fraction along each segment from starts (S, 3) to ends (S, 3) at which it last
    meets the triangles ``corners`` (T, 3, 3) (:func:`.winding.triangle_corners`), −1 where never."""
    starts = np.ascontiguousarray(np.asarray(starts, dtype=np.float64).reshape(-1, 3))
    ends = np.ascontiguousarray(np.asarray(ends, dtype=np.float64).reshape(-1, 3))
    out = np.empty(len(starts))
    crossing_loop(starts, ends, corners, out)
    return out
