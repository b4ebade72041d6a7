"""Collision tests of animation frames against static obstacles and a ground plane (Zheng §3.4).

Obstacles are closed meshes turned once into filled voxel occupancy grids by trimesh (a
maintained library: surface voxelisation, then hole filling), so testing millions of points is
one vectorised lookup. A point counts as colliding when it falls in a filled voxel: the test is
conservative by up to one voxel (``pitch``, default 1/64 of the obstacle's largest side —
document it in results that depend on it). The ground plane is a height on the up axis; a point
more than ``tolerance`` below it collides. Frames are tested on a subset of at most
``max_points`` vertices (evenly strided), which is exact for obstacles larger than the spacing
of those vertices.
"""

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Obstacles:
    """grids: trimesh VoxelGrid per obstacle; ground: (axis, height) or None; tolerance."""

    grids: list = field(default_factory=list)
    ground: tuple | None = None
    tolerance: float = 0.0

    def __bool__(self):
        return bool(self.grids) or self.ground is not None


def build_obstacles(meshes, ground=None, pitch=None, resolution=64, tolerance=0.0):
    """meshes: list of (vertices (n, 3), faces (m, 3)); ground: (axis 0/1/2, height) or None."""
    import trimesh

    grids = []
    for vertices, faces in meshes:
        mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
        step = pitch or float(np.ptp(vertices, axis=0).max()) / resolution
        grids.append(mesh.voxelized(step).fill())
    return Obstacles(grids=grids, ground=ground, tolerance=tolerance)


def vertex_subset(count, max_points=512):
    """Evenly strided vertex ids (≤ max_points) used for collision tests."""
    return np.arange(0, count, max(1, -(-count // max_points)))


def colliding(obstacles, points):
    """points (..., P, 3) -> (...,) bool: does any point of a frame collide?"""
    shape = points.shape[:-2]
    flat = points.reshape(-1, 3)
    hit = np.zeros(flat.shape[0], dtype=bool)
    if obstacles.ground is not None:
        axis, height = obstacles.ground
        hit |= flat[:, axis] < height - obstacles.tolerance
    for grid in obstacles.grids:
        hit |= grid.is_filled(flat)
    return hit.reshape(shape + (points.shape[-2],)).any(axis=-1)
