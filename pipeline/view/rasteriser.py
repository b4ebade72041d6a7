"""Headless rendering of a triangle mesh to an RGB image: a z-buffered rasteriser (numba).

Groundwork for ``skinsynth preview`` (issue 16): no display and no OpenGL, so it runs on any
dataset-build machine. A scene is the mesh, a ground quad under it, one directional light plus
ambient, a perspective camera. Shading is Lambert: per face (flat) or per vertex, interpolated
across each triangle (smooth). Triangles are drawn in order with a depth test, so the result is
deterministic; one thread rasterises (writes to one z-buffer), the vertex work is numpy.

Conventions: camera space looks down −z with +y up (OpenGL's); ``view (4, 4)`` maps world to
camera; pixels have their origin at the top left, the pixel (x, y) centre at (x + ½, y + ½).
"""

from dataclasses import dataclass

import numba
import numpy as np

from ..mesh.geometry import vertex_normals as geometry_vertex_normals

BACKGROUND = (0.92, 0.93, 0.95)
MESH_COLOR = (0.72, 0.74, 0.80)
GROUND_COLOR = (0.80, 0.80, 0.78)


@dataclass
class Camera:
    """A pinhole camera: ``view (4, 4)`` world → camera, ``fov_y`` (radians) the vertical field
    of view, ``near`` the nearest depth drawn."""

    view: np.ndarray
    fov_y: float = np.radians(35.0)
    near: float = 1e-3


def look_at(eye, target, up):
    """view (4, 4) of a camera at ``eye`` looking at ``target`` with ``up`` upwards on screen."""
    eye, target, up = (np.asarray(a, dtype=np.float64) for a in (eye, target, up))
    forward = target - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = right, true_up, -forward
    view[:3, 3] = -view[:3, :3] @ eye
    return view


#: camera presets: the direction from the target to the camera, in (right, up, towards viewer)
#: of a Y-up world seen from its front (+Z).
PRESETS = {"front": (0.0, 0.15, 1.0), "side": (1.0, 0.15, 0.0), "three-quarter": (0.8, 0.35, 0.8)}


def frame_bounds(lower, upper, preset="three-quarter", up_axis=1, aspect=4 / 3, fov_y=np.radians(35.0),
                 margin=1.1):
    """A camera that sees the box [lower, upper] (the whole animation's bounds) whole from the
    ``preset`` direction, with the ``up_axis`` (1: Y, 2: Z) up on screen."""
    lower, upper = np.asarray(lower, dtype=np.float64), np.asarray(upper, dtype=np.float64)
    centre, radius = (lower + upper) / 2.0, max(np.linalg.norm(upper - lower) / 2.0, 1e-12)
    right, up, toward = PRESETS[preset]
    axes = np.eye(3) if up_axis == 1 else np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    direction = right * axes[0] + up * axes[1] + toward * axes[2]  # Z up: the front is −Y
    direction /= np.linalg.norm(direction)
    half = min(fov_y, 2.0 * np.arctan(np.tan(fov_y / 2.0) * aspect)) / 2.0
    distance = margin * radius / np.sin(half)
    return Camera(view=look_at(centre + distance * direction, centre, axes[1]), fov_y=fov_y,
                  near=max(distance - 2.0 * radius, 1e-6 * distance))


def project(points, camera, width, height):
    """Screen positions (N, 3): pixel x, pixel y, camera depth (positive in front)."""
    homogeneous = np.c_[points, np.ones(len(points))] @ camera.view.T
    depth = -homogeneous[:, 2]
    focal = (height / 2.0) / np.tan(camera.fov_y / 2.0)
    safe = np.where(depth > camera.near, depth, np.nan)
    x = width / 2.0 + focal * homogeneous[:, 0] / safe
    y = height / 2.0 - focal * homogeneous[:, 1] / safe
    return np.stack([x, y, depth], axis=1)


def _area_normals(vertices, faces):
    """(T, 3): each face's normal times twice its area."""
    return np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]])


def _unit(vectors):
    return vectors / np.maximum(np.linalg.norm(vectors, axis=1, keepdims=True), 1e-300)


def face_normals(vertices, faces):
    return _unit(_area_normals(vertices, faces))


def vertex_normals(vertices, faces):
    """Area-weighted unit vertex normals (V, 3) of one frame (:func:`skinsynth.pipeline.mesh.geometry.vertex_normals`)."""
    return geometry_vertex_normals(vertices[None], faces)[0]


def lambert(normals, light, ambient=0.3):
    """Two-sided Lambert intensity per normal (N,): ambient + (1 − ambient)·|n·l|."""
    return ambient + (1.0 - ambient) * np.abs(normals @ light)


@numba.njit(cache=True, nogil=True)
def _rasterise(screen, triangles, colors, per_vertex, image, depth):
    """Draw triangles (T, 3) of screen points (N, 3) into image (H, W, 3) with z-buffer depth
    (H, W): colors (T, 3) per face, or (N, 3) per vertex interpolated when ``per_vertex``."""
    height, width = depth.shape
    for f in range(triangles.shape[0]):
        a, b, c = triangles[f, 0], triangles[f, 1], triangles[f, 2]
        ax, ay, az = screen[a, 0], screen[a, 1], screen[a, 2]
        bx, by, bz = screen[b, 0], screen[b, 1], screen[b, 2]
        cx, cy, cz = screen[c, 0], screen[c, 1], screen[c, 2]
        if not (az == az and bz == bz and cz == cz and ax == ax and bx == bx and cx == cx):
            continue  # a corner behind the near plane (NaN): skipped, not clipped
        area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if area == 0.0:
            continue
        x0 = max(int(np.floor(min(ax, bx, cx))), 0)
        x1 = min(int(np.ceil(max(ax, bx, cx))), width - 1)
        y0 = max(int(np.floor(min(ay, by, cy))), 0)
        y1 = min(int(np.ceil(max(ay, by, cy))), height - 1)
        for y in range(y0, y1 + 1):
            py = y + 0.5
            for x in range(x0, x1 + 1):
                px = x + 0.5
                wa = ((bx - px) * (cy - py) - (by - py) * (cx - px)) / area
                wb = ((cx - px) * (ay - py) - (cy - py) * (ax - px)) / area
                wc = 1.0 - wa - wb
                if wa < 0.0 or wb < 0.0 or wc < 0.0:
                    continue
                # perspective-correct depth: interpolate 1/z
                inverse = wa / az + wb / bz + wc / cz
                z = 1.0 / inverse
                if z >= depth[y, x]:
                    continue
                depth[y, x] = z
                if per_vertex:
                    for k in range(3):
                        image[y, x, k] = (wa / az * colors[a, k] + wb / bz * colors[b, k]
                                          + wc / cz * colors[c, k]) * z
                else:
                    for k in range(3):
                        image[y, x, k] = colors[f, k]


def render(vertices, faces, camera, width=640, height=480, smooth=False, ground=None, up_axis=1,
           color=MESH_COLOR, vertex_colors=None, light=None):
    """The mesh ``vertices (V, 3)``, ``faces (T, 3)`` seen by ``camera``: image (H, W, 3) uint8.

    ground: the height of an endless checkered ground plane along ``up_axis`` (None: no
    ground), or a layer from :func:`ground_layer` (the same for every frame of a fixed camera:
    make it once); vertex_colors (V, 3) in [0, 1] replace ``color`` (e.g. an error map); the
    light comes from over the camera's shoulder unless given (a world direction towards it)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    light = default_light(camera) if light is None else np.asarray(light, dtype=np.float64) / np.linalg.norm(light)
    if ground is None:
        image = np.empty((height, width, 3))
        image[:] = BACKGROUND
        depth = np.full((height, width), np.inf)
    else:
        if not isinstance(ground, tuple):
            ground = ground_layer(camera, width, height, float(ground), up_axis, np.ptp(vertices, axis=0).max())
        image, depth = ground[0].copy(), ground[1].copy()
    base = np.broadcast_to(np.asarray(color, dtype=np.float64), vertices.shape) if vertex_colors is None \
        else np.asarray(vertex_colors, dtype=np.float64)
    screen = project(vertices, camera, width, height)
    if smooth:
        shade = lambert(vertex_normals(vertices, faces), light)[:, None] * base
        _rasterise(screen, faces, np.ascontiguousarray(shade), True, image, depth)
    else:
        shade = lambert(face_normals(vertices, faces), light)[:, None] * base[faces].mean(axis=1)
        _rasterise(screen, faces, np.ascontiguousarray(shade), False, image, depth)
    return (np.clip(image, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def default_light(camera):
    """A light over the camera's shoulder (a world direction towards it)."""
    light = camera.view[:3, :3].T @ np.array([0.35, 0.6, 0.7])
    return light / np.linalg.norm(light)


def ground_layer(camera, width, height, level, up_axis, size, light=None):
    """(image (H, W, 3), depth (H, W)) of an endless ground plane at ``level`` along the up axis,
    checkered in cells of ``size``/2, fading into the background with distance: every pixel's
    ray meets the plane exactly (no triangles, nothing clipped at the near plane)."""
    light = default_light(camera) if light is None else light
    rotation, eye = camera.view[:3, :3], -camera.view[:3, :3].T @ camera.view[:3, 3]
    focal = (height / 2.0) / np.tan(camera.fov_y / 2.0)
    x, y = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    rays_camera = np.stack([(x - width / 2.0) / focal, -(y - height / 2.0) / focal, -np.ones_like(x)], axis=-1)
    rays = rays_camera @ rotation  # camera → world (rotation is orthonormal)
    along = rays[..., up_axis]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (level - eye[up_axis]) / along
    hit = (t > 0.0) & np.isfinite(t)
    points = eye + np.where(hit, t, 0.0)[..., None] * rays
    a, b = [axis for axis in range(3) if axis != up_axis]
    cell = max(size, 1e-12) / 2.0
    checker = (np.floor(points[..., a] / cell) + np.floor(points[..., b] / cell)) % 2
    shade = lambert(np.eye(3)[up_axis][None], light)[0] * np.asarray(GROUND_COLOR)
    colour = shade * np.where(checker, 1.0, 0.94)[..., None]
    distance = np.where(hit, t * np.linalg.norm(rays, axis=-1), np.inf)
    fade = np.clip(distance / (40.0 * cell), 0.0, 1.0)[..., None] ** 2  # towards the horizon
    image = np.where(hit[..., None], (1.0 - fade) * colour + fade * np.asarray(BACKGROUND), np.asarray(BACKGROUND))
    depth = np.where(hit, t, np.inf)  # camera depth along −z: rays have unit −z in camera space
    return np.ascontiguousarray(image), np.ascontiguousarray(depth)
