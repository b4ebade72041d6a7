"""Built-in procedural example animations (no files needed): for the demo, tests and benchmarks.

- :func:`bending_bar`: a capped cylinder bending back and forth and twisting, the "bending
  bar/cylinder" kind of example of Feng Table 1. Its deformation is smooth and not itself an
  LBS model, so a fit has real work to do.
- :func:`synthetic_lbs`: an exact LBS animation with known rigid bones and sparse weights, the
  closed-form truth a skinning fit must recover.
"""

import numpy as np

from .rotations import rotation_exp


def cylinder_mesh(rings=40, segments=16, length=4.0, radius=0.5):
    """A closed tube along x from 0 to ``length``: (rest (V, 3), faces (T, 3)).

    ``rings`` circles of ``segments`` vertices, plus one centre vertex per cap.
    """
    x = np.linspace(0.0, length, rings)
    angle = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    xx, aa = np.meshgrid(x, angle, indexing="ij")
    side = np.stack([xx, radius * np.cos(aa), radius * np.sin(aa)], axis=-1).reshape(-1, 3)
    caps = np.array([[0.0, 0.0, 0.0], [length, 0.0, 0.0]])
    rest = np.concatenate([side, caps])
    r, s = np.meshgrid(np.arange(rings - 1), np.arange(segments), indexing="ij")
    a = r * segments + s
    b = r * segments + (s + 1) % segments
    c = a + segments
    d = b + segments
    quads = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    first, last = rings * segments, rings * segments + 1
    ring0 = np.arange(segments)
    ring1 = (rings - 1) * segments + np.arange(segments)
    cap0 = np.stack([np.full(segments, first), np.roll(ring0, -1), ring0], -1)
    cap1 = np.stack([np.full(segments, last), ring1, np.roll(ring1, -1)], -1)
    return rest, np.concatenate([quads, cap0, cap1]).astype(np.int64)


def bending_bar(frames=60, rings=40, segments=16, length=4.0, radius=0.5, bend=1.6, twist=0.8, cycles=1):
    """A cylinder whose centre line bends into a circular arc and twists, over ``cycles`` cycles.

    Returns (vertices (F, V, 3), faces (T, 3)). Frame 0 is the straight rest pose; over a cycle
    (phase t from 0 to 1) the bend angle follows ``bend · sin²(πt)`` and the twist
    ``twist · sin(2πt)`` (radians, end to end).
    """
    rest, faces = cylinder_mesh(rings, segments, length, radius)
    s = rest[:, 0] / length
    phase = cycles * np.arange(frames) / frames
    total_bend = bend * np.sin(np.pi * phase) ** 2
    total_twist = twist * np.sin(2.0 * np.pi * phase)
    out = np.empty((frames, rest.shape[0], 3))
    for f in range(frames):
        theta = total_bend[f] * s
        spin = total_twist[f] * s
        y = rest[:, 1] * np.cos(spin) - rest[:, 2] * np.sin(spin)
        z = rest[:, 1] * np.sin(spin) + rest[:, 2] * np.cos(spin)
        if abs(total_bend[f]) < 1e-9:
            cx, cy, nx, ny = rest[:, 0], np.zeros_like(s), np.zeros_like(s), np.ones_like(s)
        else:
            r = length / total_bend[f]
            cx, cy = r * np.sin(theta), r * (1.0 - np.cos(theta))
            nx, ny = -np.sin(theta), np.cos(theta)
        out[f, :, 0] = cx + y * nx
        out[f, :, 1] = cy + y * ny
        out[f, :, 2] = z
    return out, faces


def synthetic_lbs(bones=6, frames=30, max_influences=4, rings=48, segments=12, seed=0, angle=0.5, width=0.6):
    """An exact LBS animation of a tube with known rigid bones.

    Bones sit evenly along the tube; weights fall off with distance along its axis, are kept to
    the ``max_influences`` largest and renormalised (so they are sparse, ≥ 0, sum 1); each bone
    gets a random rotation (up to ``angle`` radians) and translation per frame, frame 0 is the
    rest pose. Returns a dict with vertices (F, V, 3), faces, rest (V, 3), bone_indices (V, K),
    bone_weights (V, K), rotations (F, B, 3, 3), translations (F, B, 3).
    """
    rng = np.random.default_rng(seed)
    length = 4.0
    rest, faces = cylinder_mesh(rings, segments, length)
    centres = (np.arange(bones) + 0.5) * length / bones
    spacing = length / bones
    falloff = np.exp(-((rest[:, :1] - centres[None]) / (width * spacing)) ** 2)
    k = min(max_influences, bones)
    indices = np.argsort(-falloff, axis=1, kind="stable")[:, :k]
    weights = np.take_along_axis(falloff, indices, axis=1)
    weights /= weights.sum(axis=1, keepdims=True)
    rotations = rotation_exp(rng.uniform(-angle, angle, size=(frames, bones, 3)))
    translations = rng.normal(scale=0.3, size=(frames, bones, 3))
    rotations[0] = np.eye(3)
    translations[0] = 0.0
    moved = np.einsum("fvkab,vb->fvka", rotations[:, indices], rest) + translations[:, indices]
    vertices = np.einsum("fvka,vk->fva", moved, weights)
    return dict(vertices=vertices, faces=faces, rest=rest, bone_indices=indices.astype(np.int32),
                bone_weights=weights, rotations=rotations, translations=translations)


def articulated_tube(frames=160, rings=120, segments=12, joints=4, length=8.0, radius=0.35, amplitude=0.9,
                     joint_width=0.25, period=(60.0, 150.0), periods=None, seed=0):
    """A tube that bends at ``joints`` soft joints, each swinging in two planes at its own rate.

    Joint j at arclength s_j swings by ``amplitude`` radians (about z and about y, with
    incommensurate frequencies and random phases); the bend is spread over ``joint_width`` of
    arclength by a logistic ramp, so the deformation is smooth and not itself an LBS model. The
    centre line is integrated from the rotation field along the tube. Many nonlinear degrees of
    freedom sampled sparsely: the setting where puppet regression has to generalise. ``periods``
    (2, joints) in frames overrides the random ones (drawn from ``period``), e.g. to make a body
    exactly periodic while a tail swings at its own rate. Returns (vertices (F, V, 3), faces (T, 3)).
    """
    rng = np.random.default_rng(seed)
    rest, faces = cylinder_mesh(rings, segments, length, radius)
    s = rest[:, 0]
    ring_s = np.linspace(0.0, length, rings)
    centres = (np.arange(joints) + 1.0) * length / (joints + 1.0)
    time = np.arange(frames)[:, None]
    drawn = rng.uniform(period[0], period[1], size=(2, joints))
    rate = 2.0 * np.pi / (drawn if periods is None else np.broadcast_to(np.asarray(periods, dtype=float), (2, joints)))
    phase = rng.uniform(0.0, 2.0 * np.pi, size=(2, joints))
    angle_z = amplitude * np.sin(rate[0] * time + phase[0])  # (F, J)
    angle_y = 0.6 * amplitude * np.sin(rate[1] * time + phase[1])
    ramp = 1.0 / (1.0 + np.exp(-(ring_s[:, None] - centres[None]) / (joint_width / 4.0)))  # (rings, J)
    phi_z = angle_z @ ramp.T  # (F, rings)
    phi_y = angle_y @ ramp.T
    frame = rotation_exp(np.stack([np.zeros_like(phi_z), np.zeros_like(phi_z), phi_z], -1)) @ \
        rotation_exp(np.stack([np.zeros_like(phi_y), phi_y, np.zeros_like(phi_y)], -1))  # (F, rings, 3, 3)
    step = np.diff(ring_s, prepend=0.0)
    tangent = frame[..., :, 0]
    centre_line = np.cumsum(tangent * step[None, :, None], axis=1)
    ring_of = np.clip(np.round(s / length * (rings - 1)).astype(int), 0, rings - 1)
    offset = rest.copy()
    offset[:, 0] = 0.0
    vertices = centre_line[:, ring_of] + np.einsum("fvab,vb->fva", frame[:, ring_of], offset)
    return vertices, faces
