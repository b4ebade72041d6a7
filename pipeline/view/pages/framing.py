"""What every page starts from: the plain mesh colour and the first view, framed on the page's points."""

import numpy as np

MESH_COLOR = (175, 185, 205)


def frame_camera(server, points, up_axis):
    """Point the first view at points (N, 3) from a three-quarter front, up_axis "Y" or "Z"."""
    lower, upper = points.min(axis=0), points.max(axis=0)
    centre, radius = (lower + upper) / 2, max(float(np.linalg.norm(upper - lower)) / 2, 1e-6)
    up = np.eye(3)[1 if up_axis == "Y" else 2]
    front = np.array([0.0, 0.0, 1.0]) if up_axis == "Y" else np.array([0.0, -1.0, 0.0])
    direction = 0.55 * np.array([1.0, 0.0, 0.0]) + 0.35 * up + front
    server.scene.set_up_direction("+y" if up_axis == "Y" else "+z")
    server.initial_camera.up = tuple(up)
    server.initial_camera.look_at = tuple(centre)
    server.initial_camera.position = tuple(centre + direction / np.linalg.norm(direction) * 2.2 * radius)

