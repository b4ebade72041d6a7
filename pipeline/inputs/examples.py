"""Built-in procedural example animations (no files needed): for the demo, tests and benchmarks.

- :func:`bending_bar`: a capped cylinder bending back and forth and twisting, the "bending
  bar/cylinder" kind of example of Feng Table 1. Its deformation is smooth and not itself an
  LBS model, so a fit has real work to do.
- :func:`synthetic_lbs`: an exact LBS animation with known rigid bones and sparse weights, the
  closed-form truth a skinning fit must recover.
- :func:`walker`: an articulated figure (nine tubes in one mesh, ten skinned parts) walking in
  place: vertices (F, V, 3), faces (T, 3), Y up, the stance foot on y = 0. Its limbs hang from
  the torso by weak skin ties, so a fit's bone graph gives each leg a component of its own: the
  case where components' independent walks combine leg poses that never occur together. With
  ``planted=True`` it walks forward instead, its feet truly planted (two-link legs by analytic
  inverse kinematics); :func:`walker_contacts` gives that gait's contact truth in closed form.

:func:`example_memory` estimates what building one holds, which ``skinsynth example`` checks first.
"""

from typing import NamedTuple

from dataclasses import dataclass

import numpy as np

from ..rig.rotations import rotation_exp


def example_memory(name, frames, rings, segments):
    """(bytes, what): an upper estimate of the memory building the example ``name``
    ("bending-bar": :func:`bending_bar`, "walker": :func:`walker`) holds at its peak, from its
    sizes, and those sizes in words (for a refusal)."""
    if name == "walker":
        # Nine tubes: the legs have ``rings`` rings each, the other seven together about 3.1 × as
        # many (at least 4 each), two cap centres each; per-part temporaries come on top.
        vertex_count = (6 * rings + 32) * segments + 18
        return frames * vertex_count * 3 * 8 * 4, f"{frames} frames of up to {vertex_count} vertices"
    return frames * (rings * segments + 2) * 3 * 8 * 3, f"{frames} frames of {rings} × {segments} vertices"


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


def _smoothstep(x):
    """0 below 0, 1 above 1, 3x² − 2x³ between: a C¹ ramp."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _tube(start, direction, length, radius, rings, segments):
    """A closed tube (:func:`cylinder_mesh`) from ``start`` along the unit ``direction``:
    (vertices (V, 3), faces (T, 3), s (V,) the distance along the axis from ``start``)."""
    local, faces = cylinder_mesh(rings, segments, length, radius)
    d = np.asarray(direction, dtype=np.float64)
    side = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = side - (side @ d) * d
    e1 /= np.linalg.norm(e1)
    frame = np.stack([d, e1, np.cross(d, e1)], axis=1)  # a proper rotation: the faces keep facing out
    return local @ frame.T + np.asarray(start, dtype=np.float64), faces, local[:, 0]


def _rotation(axis, angle):
    """Rotations (F, 3, 3) about the coordinate axis ``axis`` (0, 1, 2: x, y, z) by ``angle`` (F,) radians."""
    angle = np.asarray(angle, dtype=np.float64)
    vector = np.zeros(angle.shape + (3,))
    vector[..., axis] = angle
    return rotation_exp(vector)


#: The walker's leg in its rest pose: hip, knee and ankle joint heights, the hips' offset from the
#: middle (left +x), and the swing foot's highest lift of its ankle (planted gait).
WALKER_HIP_Y, WALKER_KNEE_Y, WALKER_ANKLE_Y, WALKER_HIP_X = 0.92, 0.5, 0.08, 0.1
WALKER_CLEARANCE = 0.12
_SWING_HOLD = 0.12  # the share of a swing at each end where the foot only rises or sets down


class WalkerContacts(NamedTuple):
    """The planted walker's ground contacts in closed form (:func:`walker_contacts`); feet in the
    order (left, right).

    - ``planted`` (F, 2) bool: the foot is in stance (level, still, its sole on y = 0).
    - ``ankles`` (F, 2, 3): each ankle joint's world position, in stance and swing.
    - ``anchors`` (F, 2, 3): where a planted foot stands, the ground point (x, 0, z) under its
      ankle; NaN while the foot swings.
    - ``stances``: one ``(foot, first, last, anchor (3,))`` per stance, frames ``first`` to
      ``last`` inclusive, in order of ``first`` then foot (a stance cut by the clip's end is cut
      here too).
    - ``travel``: how far the body moves along +z per gait cycle (the stride, two steps), so that
      frame ``f + frames / cycles`` is frame ``f`` moved by ``travel`` along z.
    - ``reach``: the largest distance from a planted ankle to the hip along z.
    """
    planted: np.ndarray
    ankles: np.ndarray
    anchors: np.ndarray
    stances: list
    travel: float
    reach: float


def _cycle_time(frames, cycles, start, tempo=0.0):
    """Each frame's time in gait cycles (frame 0 at ``start``). ``tempo`` (in [0, 1)): the gait
    speeds up over the clip, from 1 − tempo to 1 + tempo times its mean speed
    (``1 − tempo cos(π f / frames)``), so no two strides are sampled alike, as in a walk that gets
    going (a captured walk's strides differ); frame ``frames`` still falls on ``start + cycles``."""
    if not 0.0 <= tempo < 1.0:
        raise ValueError(f"tempo {tempo} must lie in [0, 1)")
    f = np.arange(frames, dtype=np.float64)
    return start + cycles * (f - tempo * frames / np.pi * np.sin(np.pi * f / frames)) / frames


def walker_contacts(frames=48, cycles=2, stride=0.4, stance=0.6, start=0.0, tempo=0.0):
    """The contact truth of ``walker(planted=True)`` with the same arguments: which foot is planted
    in each frame and where (:class:`WalkerContacts`).

    Each leg's cycle (the right half a cycle after the left, phase 0 the left heel strike) is a
    stance, the first ``stance`` of it, then a swing. In stance the ankle stays on its anchor while
    the hip, carried by the body at a constant ``travel`` per cycle along +z, passes over it from
    ``reach`` behind to ``reach`` ahead, ``reach = 0.97 · leg · sin(stride)``; so ``travel = 2 reach
    / stance`` and nothing slides. In swing the ankle rises (``WALKER_CLEARANCE`` at mid-swing,
    ``(1 − cos 2πv) / 2``), moves to the next anchor ``travel`` ahead on a cycloid (its speed 0 at
    both ends; still for the first and last ``_SWING_HOLD`` of the swing, where it only rises or sets
    down) and lands: position, velocity and height are continuous.
    """
    if not 0.0 < stance < 1.0:
        raise ValueError(f"stance {stance} must lie strictly between 0 and 1")
    time = _cycle_time(frames, cycles, start, tempo)
    leg = WALKER_HIP_Y - WALKER_ANKLE_Y
    reach = 0.97 * leg * np.sin(stride)
    travel = 2.0 * reach / stance
    planted = np.zeros((frames, 2), dtype=bool)
    ankles = np.zeros((frames, 2, 3))
    anchors = np.full((frames, 2, 3), np.nan)
    for foot, (sign, shift) in enumerate(((1.0, 0.0), (-1.0, 0.5))):
        cycle = time + shift
        k = np.floor(cycle)
        phase = cycle - k
        down = phase <= stance
        anchor = travel * (k - shift) + 0.5 * travel * stance  # z of this cycle's stance
        v = np.clip((phase - stance) / (1.0 - stance), 0.0, 1.0)  # swing progress
        w = np.clip((v - _SWING_HOLD) / (1.0 - 2.0 * _SWING_HOLD), 0.0, 1.0)
        ahead = np.where(down, 0.0, w - np.sin(2.0 * np.pi * w) / (2.0 * np.pi))
        lift = np.where(down, 0.0, 0.5 * WALKER_CLEARANCE * (1.0 - np.cos(2.0 * np.pi * v)))
        planted[:, foot] = down
        ankles[:, foot] = np.stack([np.full(frames, sign * WALKER_HIP_X), WALKER_ANKLE_Y + lift,
                                    anchor + travel * ahead], axis=-1)
        anchors[down, foot] = np.stack([np.full(frames, sign * WALKER_HIP_X), np.zeros(frames), anchor],
                                       axis=-1)[down]
    stances = []
    for foot in range(2):
        edges = np.flatnonzero(np.diff(np.concatenate([[0], planted[:, foot].astype(np.int8), [0]])))
        stances += [(foot, int(a), int(b) - 1, anchors[a, foot].copy()) for a, b in zip(edges[::2], edges[1::2])]
    stances.sort(key=lambda item: (item[1], item[0]))
    return WalkerContacts(planted, ankles, anchors, stances, float(travel), float(reach))


#: Seconds of :func:`walker_event` at its defaults (2 standing, 4 walking, 0.5 stumbling, 3 running).
WALKER_EVENT_SECONDS = 9.5


def walker_event(fps=24.0, rings=24, segments=10, stand=2.0, walk=4.0, stumble=0.5, run=3.0, pace=1.8, rig=False):
    """A walk with a one-time event (issue 63): the in-place :func:`walker` stands ``stand`` s in its
    first pose, walks ``walk`` s at a cycle a second, stumbles once over ``stumble`` s (chest pitched,
    arms thrown up, knees buckled: poses it shows nowhere else) and runs off at ``pace`` cycles a
    second for ``run`` s, leaning into it with longer strides and higher knees (pace and posture
    ramped over 0.3 s from the stumble's height, so that the stumble recovers into the run, never
    into a walking pose), so that nothing in the run resembles the walk: a one-time event, and a
    part of the clip it leads into and nothing leads back from. Returns walker's (vertices,
    faces[, rig])."""
    fps = float(fps)
    seconds = np.arange(int(round((stand + walk + stumble + run) * fps))) / fps
    moving = np.clip(seconds - stand, 0.0, None)
    ramp = np.clip((moving - walk - 0.5 * stumble) / 0.3, 0.0, 1.0)
    speed_gain = np.cumsum(ramp) / fps * (pace - 1.0)  # the extra cycles the run adds
    phase = moving + speed_gain
    into = (seconds - stand - walk) / stumble
    lurch = np.where((into > 0.0) & (into < 1.0), np.sin(np.pi * np.clip(into, 0.0, 1.0)) ** 2, 0.0)
    return walker(frames=seconds.size, rings=rings, segments=segments, phase=phase, lurch=lurch, lean=0.35 * ramp,
                  stride=0.4 + 0.25 * ramp, knee=1.1 + 0.7 * ramp, rig=rig)


def _two_link(hip, ankle, upper, lower):
    """Analytic inverse kinematics of a two-link leg, the knee bending forward (+z): world rotations
    (F, 3, 3) of the upper and the lower link, each taking its rest direction (straight down) to
    the link, with no twist about it beyond what keeps +z forward."""
    reach = ankle - hip
    distance = np.linalg.norm(reach, axis=-1)
    if np.any(distance >= upper + lower) or np.any(distance <= abs(upper - lower)):
        raise ValueError("the ankle is out of the leg's reach")
    e = reach / distance[:, None]
    forward = np.array([0.0, 0.0, 1.0]) - e[:, 2:3] * e
    forward /= np.linalg.norm(forward, axis=-1, keepdims=True)
    cos_hip = (upper ** 2 + distance ** 2 - lower ** 2) / (2.0 * upper * distance)
    knee = hip + upper * (cos_hip[:, None] * e + np.sqrt(1.0 - cos_hip ** 2)[:, None] * forward)

    def along(direction):  # columns: x' = y' × z', y' = −direction, z' = +z made orthogonal
        down = direction / np.linalg.norm(direction, axis=-1, keepdims=True)
        ahead = np.array([0.0, 0.0, 1.0]) - down[:, 2:3] * down
        ahead /= np.linalg.norm(ahead, axis=-1, keepdims=True)
        return np.stack([np.cross(-down, ahead), -down, ahead], axis=-1)

    return along(knee - hip), along(ankle - knee)


#: The walker's rigid parts (its true bones), parents first, in the order of its skinning weights.
WALKER_PARTS = ("pelvis", "chest", "thigh_l", "shin_l", "foot_l", "thigh_r", "shin_r", "foot_r", "arm_l", "arm_r")


@dataclass
class WalkerRig:
    """The walker's true rig (:func:`walker` with ``rig=True``): ``parents (10,)`` int64 (−1 for the
    pelvis) and ``joints (10, 3)`` (each part's joint with its parent at rest; the pelvis's at the
    hips' height) over :data:`WALKER_PARTS`; ``weights (V, 10)``; the parts' LBS transforms
    ``rotations (F, 10, 3, 3)`` and ``translations (F, 10, 3)``, so v = Σ_k w_k (R_k r + t_k)
    gives the walker's vertices exactly from its rest pose ``rest (V, 3)`` (legs straight, arms
    down; ``planted=False``'s lift to the ground is in the translations)."""

    rest: np.ndarray
    parents: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    rotations: np.ndarray
    translations: np.ndarray


def walker(frames=48, cycles=2, rings=24, segments=10, stride=0.4, knee=1.1, stance=0.6, arm_swing=0.4,
           blend=0.05, coupling=0.1, start=0.0, planted=False, rig=False, tempo=0.0, shoulder_slide=0.0, phase=None,
           lurch=None, lean=None):
    """An articulated figure walking in place (as on a treadmill): ``cycles`` gait cycles over ``frames``.

    Returns (vertices (F, V, 3) float64, faces (T, 3) int64): metres, Y up, facing +z, about 1.75
    tall, its lowest point on y = 0 in every frame. Nine closed tubes in one mesh (multi-shell,
    in this order): chest, pelvis, head, then per side (left, +x, first) a leg from hip to ankle,
    a foot and an arm; ``segments`` vertices around each tube, ``rings`` rings along a leg and as
    many per metre along the others (at least 4). The defaults give 1,248 vertices. Ten rigid
    parts (:data:`WALKER_PARTS`) drive them by linear blend skinning. Inside a leg the thigh's and
    the shin's weights cross over smoothly at the knee (a C¹ ramp ``blend`` metres either side),
    as a real skin does. Where a tube hangs from a part of another (the pelvis tube from the
    chest, a leg from the pelvis, a foot from its shin, an arm from the chest) its last ``blend``
    metres also follow that part, with weight ``coupling`` at the end fading to 0: a weak tie, so that
    the bone graph of a skinning fit (Zheng eq. 11, weak edges pruned) keeps the limbs apart and
    ``build-graph`` gives each leg a component of its own. The head is rigid with the chest.

    The gait, per leg, the right half a cycle after the left; phase 0 (``start``, in cycles, is
    frame 0's) is the left heel strike. In stance (the first ``stance`` of the cycle) the hip
    extends from ``+stride`` to ``−stride`` radians, the foot level on the ground sliding back,
    the knee giving a little after heel strike; in swing the hip flexes back, the knee bends up to
    ``knee`` radians at mid-swing, the thigh swings a little out and the toes drop at push-off.
    The pelvis turns, sways over the stance foot and drops on the swing side; the chest turns and
    leans against it; the arms swing ``arm_swing`` radians opposite to the legs. Then the whole
    figure is raised so that its lowest point lies on y = 0 in every frame: the stance foot stays
    on the ground while the other swings above it (up to about 0.23 at the defaults), and the
    pelvis bobs (about 0.05), lowest at double support (both feet down, legs spread) and highest
    at mid-stance (stance leg upright). Frame ``frames / cycles`` repeats frame 0, so a whole
    number of cycles loops; the default two cycles in 48 frames (1 s a cycle at 24 fps) also
    repeat inside the clip, which gives every bone component exact transitions. At ``start`` 0
    frame 0 has both knees straight, so a fit whose rest pose is frame 0 sees no bent skin blend
    and finds the parts with little stray weight: measured, ``fit-skin --bones 12`` (10 parts and
    some slack) then ``build-graph`` split each leg off for every fit seed 0–9 at the default and
    at a coarse resolution; ``--bones 10`` for 17 of those 20.

    On a treadmill the stance foot slides back (3.5 % of the height a frame at the defaults).
    ``planted=True`` walks forward instead, with truly planted feet: the body travels along +z at
    the speed the stride sets, each leg is two links posed by analytic inverse kinematics (the
    knee bending forward) from the hip, carried by the body, to the ankle, which
    :func:`walker_contacts` gives in closed form: still on its anchor through each stance, the
    foot level, then swinging on a smooth arc to the next anchor. The stance foot's sole lies on
    y = 0 (its lowest ring exactly there: nothing is moved per frame) and its contact vertices
    never move in stance (the foot's weak tie to its shin holds only the foot's upper half). The
    pelvis bobs over the straighter stance leg as before, sways and turns; ``stride`` is then the
    angle of the leg at heel strike and ``knee`` is unused (the knees bend as the legs need).
    Frame ``f + frames / cycles`` is frame ``f`` moved ``walker_contacts(...).travel`` along z.

    ``tempo`` > 0 varies the gait's speed over the clip (:func:`_cycle_time`): the strides are no
    longer copies of each other (then frame ``f + frames / cycles`` only resembles frame ``f``), as
    in a captured walk, whose transitions must be found between strides that differ.

    ``shoulder_slide`` > 0 (metres) gives each arm a shoulder that slides on the chest, as a
    scapula does (no bony joint): the arm's joint, in the chest's frame, goes round a circle of that
    radius in the chest's sagittal plane (up and forward) once a gait cycle, the right half a cycle
    after the left; the other joints hold. The truth for a sliding joint (``fit-skin --skeleton``).

    ``phase`` (F,) (in place only): each frame's time in gait cycles, instead of ``cycles`` even
    ones (a figure that stands, walks and runs: :func:`walker_event`); ``lurch`` (F,) in [0, 1]: how
    far the figure stumbles at each frame, the chest pitched forward, the arms thrown up and the
    knees buckled (0: not at all); ``lean`` (F,) radians the chest leans forward (a run); ``stride``
    and ``knee`` may also be (F,) (in place only).

    ``rig=True`` also returns the true rig, a :class:`WalkerRig`: (vertices, faces, rig).
    """
    hip_y, knee_y, ankle_y, hip_x = WALKER_HIP_Y, WALKER_KNEE_Y, WALKER_ANKLE_Y, WALKER_HIP_X
    waist_y, shoulder_y, hand_y = 1.12, 1.45, 0.87
    shoulder_x = 0.21
    joint = {"pelvis": (None, (0.0, hip_y, 0.0)), "chest": ("pelvis", (0.0, waist_y, 0.0))}
    for side, x in (("l", 1.0), ("r", -1.0)):
        joint.update({f"thigh_{side}": ("pelvis", (x * hip_x, hip_y, 0.0)),
                      f"shin_{side}": (f"thigh_{side}", (x * hip_x, knee_y, 0.0)),
                      f"foot_{side}": (f"shin_{side}", (x * hip_x, ankle_y, 0.0)),
                      f"arm_{side}": ("chest", (x * shoulder_x, shoulder_y, 0.0))})

    # The rest pose (legs straight, arms down): tubes and their weights (V, parts).
    per_metre = rings / (hip_y - ankle_y)
    down, ahead = (0.0, -1.0, 0.0), (0.0, 0.0, 1.0)
    tubes = []  # (vertices, faces, weights)

    def tube(origin, direction, length, radius, *ramps, rings_along=None, upper_half=False):
        """ramps: (part, weight (V,) as a function of the distance s along the axis or None); the
        first part takes what the others leave. ``upper_half``: the others' weights fade to 0
        from the top of the tube to its axis (nothing below the axis)."""
        count = rings_along or max(4, int(round(per_metre * length)))
        vertices, faces, s = _tube(origin, direction, length, radius, count, segments)
        weights = np.zeros((vertices.shape[0], len(WALKER_PARTS)))
        above = _smoothstep((vertices[:, 1] - origin[1]) / radius) if upper_half else 1.0
        for part, ramp in ramps[1:]:
            weights[:, WALKER_PARTS.index(part)] += above * ramp(s)
        weights[:, WALKER_PARTS.index(ramps[0][0])] += 1.0 - weights.sum(axis=1)
        tubes.append((vertices, faces, weights))

    def joint_ramp(at):  # 0 → 1 across a joint at distance ``at`` along a tube
        return lambda s: _smoothstep((s - at + blend) / (2.0 * blend))

    def tie(s):  # the end of a tube hanging from another part
        return coupling * (1.0 - _smoothstep(s / blend))

    # The torso: a chest tube over the top of a slightly narrower pelvis tube that hangs from it.
    tube((0.0, 1.5, 0.0), down, 1.5 - (waist_y - 0.02), 0.15, ("chest", None))
    tube((0.0, waist_y + 0.02, 0.0), down, waist_y + 0.02 - 0.82, 0.14, ("pelvis", None), ("chest", tie))
    tube((0.0, 1.76, 0.0), down, 0.24, 0.09, ("chest", None))
    for side, x in (("l", 1.0), ("r", -1.0)):
        tube((x * hip_x, hip_y, 0.0), down, hip_y - ankle_y, 0.065, (f"thigh_{side}", None),
             (f"shin_{side}", joint_ramp(hip_y - knee_y)), ("pelvis", tie), rings_along=rings)
        if planted:  # the sole's lowest ring exactly on y = 0, held by the foot alone
            sole = 0.045 * np.max(-np.sin(np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)))
            tube((x * hip_x, sole, -0.06), ahead, 0.26, 0.045, (f"foot_{side}", None), (f"shin_{side}", tie),
                 upper_half=True)
        else:
            tube((x * hip_x, 0.045, -0.06), ahead, 0.26, 0.045, (f"foot_{side}", None), (f"shin_{side}", tie))
        tube((x * shoulder_x, shoulder_y, 0.0), down, shoulder_y - hand_y, 0.045, (f"arm_{side}", None),
             ("chest", tie))
    rest = np.concatenate([v for v, _, _ in tubes])
    weights = np.concatenate([w for _, _, w in tubes])
    offsets = np.cumsum([0] + [v.shape[0] for v, _, _ in tubes])
    faces = np.concatenate([f + o for (_, f, _), o in zip(tubes, offsets)]).astype(np.int64)

    # The gait: each part's rotation relative to its parent, per frame (F, 3, 3).
    time = _cycle_time(frames, cycles, start, tempo) if phase is None else np.asarray(phase, np.float64)  # in cycles
    stumble = np.zeros(frames) if lurch is None else np.asarray(lurch, np.float64)
    lean = 0.0 if lean is None else np.asarray(lean, np.float64)
    phi = 2.0 * np.pi * time
    turn = np.cos(phi)  # +1 with the left leg forward
    over = np.sin(phi - np.pi * (stance - 0.5))  # +1 over the left foot (mid left stance), −1 over the right
    local = {"pelvis": _rotation(1, -0.15 * turn) @ _rotation(2, 0.05 * over),  # drops on the swing side
             "chest": _rotation(2, -0.14 * over) @ _rotation(1, 0.27 * turn)  # turns and leans against it
             @ _rotation(0, 0.7 * stumble + lean)}  # and pitches forward in a stumble, or leans
    world = {}  # parts turned in the world rather than against their parent: thighs and feet
    for side, sign, shift in (("l", 1.0, 0.0), ("r", -1.0, 0.5)):
        cycle = np.mod(time + shift, 1.0)
        in_stance = cycle < stance
        u = np.clip(cycle / stance, 0.0, 1.0)  # stance progress
        v = np.clip((cycle - stance) / (1.0 - stance), 0.0, 1.0)  # swing progress
        forward = np.cos(np.pi * np.where(in_stance, u, 1.0 + v))  # +1 at heel strike, −1 at toe-off
        lift = np.where(in_stance, 0.0, np.sin(np.pi * v) ** 2)  # 0 in stance, 1 at mid-swing
        loading = np.where(in_stance, np.sin(np.pi * np.minimum(u / 0.7, 1.0)) ** 2, 0.0)  # after heel strike
        push = np.where(in_stance, 0.0, np.maximum(0.0, np.sin(2.0 * np.pi * v)) ** 2)  # early swing
        # The thigh swings in its own plane (not turned with the pelvis), a little out in swing.
        world[f"thigh_{side}"] = _rotation(2, sign * 0.1 * lift) @ _rotation(0, -stride * forward)
        local[f"shin_{side}"] = _rotation(0, 0.12 * loading + knee * lift + 0.5 * stumble)
        world[f"foot_{side}"] = _rotation(0, 0.5 * push)  # level, the toes down at push-off
        # The arm hangs a little out from the body and swings back as this side's leg goes forward.
        local[f"arm_{side}"] = _rotation(2, sign * (0.1 + 0.8 * stumble)) @ _rotation(0, arm_swing * forward - 1.3 * stumble)
    # Forward kinematics: world rotations R and joint positions p; the pelvis at its rest height,
    # swaying 3 cm over the stance foot.
    # Planted: the pelvis travels along +z and bobs, lowest in double support (the middle of it)
    # and highest at mid-stance, below the legs' reach; each leg is posed by inverse kinematics.
    rot, pos = {}, {}
    if planted:
        contacts = walker_contacts(frames, cycles, stride, stance, start, tempo)
        leg = hip_y - ankle_y
        high = 0.97 * leg
        low = np.sqrt(high ** 2 - contacts.reach ** 2) - 0.01
        bob = 0.5 * (1.0 - np.cos(4.0 * np.pi * (time - 0.5 * (stance - 0.5))))
        body = np.stack([0.03 * over, ankle_y + low + (high - low) * bob, contacts.travel * time], axis=-1)
    for part in WALKER_PARTS:
        parent, at = joint[part]
        if parent is None:
            rot[part] = local[part]
            pos[part] = body if planted else np.stack([0.03 * over, np.full(frames, at[1]), np.zeros(frames)],
                                                      axis=-1)
            continue
        if planted and part.startswith("thigh"):
            hip = pos[parent] + np.einsum("fab,b->fa", rot[parent], np.subtract(at, joint[parent][1]))
            foot = contacts.ankles[:, 0 if part.endswith("_l") else 1]
            world[part], shin = _two_link(hip, foot, hip_y - knee_y, knee_y - ankle_y)
            local["shin" + part[5:]] = np.swapaxes(world[part], 1, 2) @ shin
            world["foot" + part[5:]] = np.broadcast_to(np.eye(3), (frames, 3, 3))  # level
        rot[part] = world[part] if part in world else rot[parent] @ local[part]
        offset = np.broadcast_to(np.subtract(at, joint[parent][1]), (frames, 3))
        if part.startswith("arm") and shoulder_slide > 0.0:  # the shoulder slides on the chest
            angle = phi + (0.0 if part.endswith("_l") else np.pi)
            offset = offset + shoulder_slide * np.stack([np.zeros(frames), np.sin(angle), np.cos(angle)], axis=-1)
        pos[part] = pos[parent] + np.einsum("fab,fb->fa", rot[parent], offset)
    vertices = np.zeros((frames, rest.shape[0], 3))
    for k, part in enumerate(WALKER_PARTS):  # linear blend skinning: Σ_k w_vk (R_k (v − j_k) + p_k)
        used = weights[:, k] > 0.0
        moved = np.einsum("fab,vb->fva", rot[part], rest[used] - joint[part][1]) + pos[part][:, None]
        vertices[:, used] += weights[used, k][None, :, None] * moved
    lift = np.zeros(frames)
    if not planted:
        lift = -vertices[..., 1].min(axis=1)
        vertices[..., 1] += lift[:, None]  # the lowest point on the ground
    if not rig:
        return vertices, faces
    rotations = np.stack([rot[part] for part in WALKER_PARTS], axis=1)
    joints = np.array([joint[part][1] for part in WALKER_PARTS], dtype=np.float64)
    translations = np.stack([pos[part] for part in WALKER_PARTS], axis=1) - np.einsum("fkab,kb->fka", rotations, joints)
    translations[..., 1] += lift[:, None]
    parents = np.array([-1 if joint[part][0] is None else WALKER_PARTS.index(joint[part][0]) for part in WALKER_PARTS])
    return vertices, faces, WalkerRig(rest=rest, parents=parents, joints=joints, weights=weights, rotations=rotations,
                                      translations=translations)
