"""Obstacle meshes for ``synthesize --obstacle``: static meshes no frame may penetrate (Zheng §3.4)."""

import os

import numpy as np

from .errors import FormatError


def read_obstacle(path):
    """(vertices (N, 3), faces (T, 3)) of an obstacle mesh file (OBJ/PLY/OFF/STL…, via trimesh);
    FormatError naming the file when it is missing, unreadable or has no faces."""
    import trimesh

    if not os.path.isfile(path):
        raise FormatError(path, "no such obstacle file")
    try:
        mesh = trimesh.load(path, force="mesh", process=True)
    except Exception as error:  # trimesh raises anything from parsing errors to ValueError
        raise FormatError(path, f"cannot load the obstacle mesh: {error}") from None
    if len(getattr(mesh, "faces", [])) == 0:
        raise FormatError(path, "the obstacle has no faces")
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)
