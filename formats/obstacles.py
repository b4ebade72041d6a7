"""Obstacle meshes for ``synthesize --obstacle``: static meshes no frame may penetrate (Zheng §3.4)."""

import os

import numpy as np

from .errors import FormatError, require_coordinates


def read_obstacle(path):
    """(vertices (N, 3), faces (T, 3)) of an obstacle mesh file (OBJ/PLY/OFF/STL…, via trimesh);
    FormatError naming the file when it is missing, unreadable, has no faces, coordinates that
    are not finite or too large, or no extent or area (an obstacle must be a surface: a flat one
    is fine)."""
    import trimesh

    if not os.path.isfile(path):
        raise FormatError(path, "no such obstacle file")
    try:
        mesh = trimesh.load(path, force="mesh", process=True)
    except Exception as error:  # trimesh raises anything from parsing errors to ValueError
        raise FormatError(path, f"cannot load the obstacle mesh: {error}") from None
    if len(getattr(mesh, "faces", [])) == 0:
        raise FormatError(path, "the obstacle has no faces")
    vertices = np.asarray(mesh.vertices)
    require_coordinates(path, vertices[None], "vertex")
    extent = float(np.ptp(vertices, axis=0).max())
    if extent == 0.0:
        raise FormatError(path, "all the obstacle's vertices are one point: it has no size to avoid")
    if not float(mesh.area) > 1e-12 * extent ** 2:  # voxelised, it would be a few scattered voxels
        raise FormatError(path, "the obstacle's faces have no area (every triangle is degenerate): nothing to avoid")
    return vertices, np.asarray(mesh.faces)
