"""Generated characters with known skeletons (issue 65's truth): a humanoid and a quadruped, each
built from a skeleton's spec, posed by its own true rig in several motions.

A character is a tree of bones (:class:`Body`: names, parents, each bone's joint with its parent
and the end its tube reaches, at rest), one closed tube per bone (a multi-shell mesh, as the
walker is), skinned by linear blend skinning with the weights a real skin has at a joint: along
each tube, within ``blend`` of its joint, the parent's weight rises to ½ at the joint, and along
the parent's tube the weight of the child that continues it (the one whose joint is the tube's
end) rises the same way (:func:`body_weights`). So neighbouring bones share skin as they do on a
capture, and every joint is exactly where the truth says: a fit of the true bones must find each
of them, and the tree.

The rest pose: a humanoid in an A pose (arms 30° out from its sides), 1.75 tall, Y up, facing +z,
its left at +x (:func:`humanoid_body`); a quadruped standing, its head at +z (:func:`quadruped_body`).
``limbs`` scales the legs' and arms' lengths (other proportions: a long-legged or a stocky
figure). The motions (:data:`HUMANOID_MOTIONS`, :data:`QUADRUPED_MOTIONS`) are local rotations of
each bone against its parent, per frame, in closed form (:func:`character`); forward kinematics
gives each bone's world rotation and joint; the lowest point is set on y = 0 in every frame but in
a jump's flight. What each motion moves is in its docstring; the point of several is that every
joint turns in some of them (a joint that never turns is anywhere along its pair: its place is not
in the data).
"""

from dataclasses import dataclass

import numpy as np

from .examples import _rotation, _smoothstep, _tube


@dataclass
class Body:
    """A character's skeleton at rest: names [str] (B,), parents (B,) int64 (−1 at the root),
    joints (B, 3) each bone's joint with its parent (the root's: its tube's start), ends (B, 3)
    where its tube ends, radii (B,) its tube's radius. Parents come before their children."""

    names: list
    parents: np.ndarray
    joints: np.ndarray
    ends: np.ndarray
    radii: np.ndarray

    def index(self, name):
        return self.names.index(name)


@dataclass
class CharacterRig:
    """A generated character's true rig: the :class:`Body`; rest (V, 3); weights (V, B); the bones'
    LBS transforms rotations (F, B, 3, 3) and translations (F, B, 3), v = Σ_b w_b (R_b r + t_b) exactly;
    names (B,) the chain names a correct labelling gives (``leg_l_01``…, issue 44's scheme); ground
    (F,) bool: the frames with a foot on the ground (all but a jump's flight)."""

    body: Body
    rest: np.ndarray
    weights: np.ndarray
    rotations: np.ndarray
    translations: np.ndarray
    names: list
    ground: np.ndarray


def _body(bones):
    """A :class:`Body` from [(name, parent name or None, joint, end, radius)], parents first."""
    names = [b[0] for b in bones]
    return Body(names=names, parents=np.array([-1 if b[1] is None else names.index(b[1]) for b in bones]),
                joints=np.array([b[2] for b in bones], float), ends=np.array([b[3] for b in bones], float),
                radii=np.array([b[4] for b in bones], float))


def _limb(name, parent, start, direction, lengths, radii):
    """[(name_i, parent, joint, end, radius)] of a chain of straight bones from ``start`` along the
    unit ``direction`` (a sequence of directions: one per bone), each ``lengths[i]`` long."""
    bones, at = [], np.asarray(start, float)
    directions = np.asarray(direction, float).reshape(-1, 3)
    for i, (bone, length, radius) in enumerate(zip(name, lengths, radii)):
        d = directions[min(i, len(directions) - 1)]
        end = at + length * d / np.linalg.norm(d)
        bones.append((bone, parent if i == 0 else name[i - 1], tuple(at), tuple(end), radius))
        at = end
    return bones


#: The humanoid's bones, parents first, and the chain names a correct labelling gives them.
HUMANOID_NAMES = {"pelvis": "body", "spine": "spine_01", "chest": "spine_02", "neck": "neck_01", "head": "neck_02",
                  "upper_arm_l": "arm_l_01", "forearm_l": "arm_l_02", "hand_l": "arm_l_03",
                  "upper_arm_r": "arm_r_01", "forearm_r": "arm_r_02", "hand_r": "arm_r_03",
                  "thigh_l": "leg_l_01", "shin_l": "leg_l_02", "foot_l": "leg_l_03",
                  "thigh_r": "leg_r_01", "shin_r": "leg_r_02", "foot_r": "leg_r_03"}


def humanoid_body(limbs=1.0):
    """The humanoid at rest (module notes): 17 bones (:data:`HUMANOID_NAMES`), about 1.75 tall at
    ``limbs`` 1 (its legs and arms ``limbs`` times as long; the trunk, neck and head unchanged)."""
    leg = 0.42 * limbs
    hip_y = 0.08 + 2.0 * leg
    waist, chest, shoulder = hip_y + 0.13, hip_y + 0.33, hip_y + 0.52
    bones = [("pelvis", None, (0.0, hip_y - 0.06, 0.0), (0.0, waist, 0.0), 0.14),
             ("spine", "pelvis", (0.0, waist, 0.0), (0.0, chest, 0.0), 0.13),
             ("chest", "spine", (0.0, chest, 0.0), (0.0, shoulder + 0.03, 0.0), 0.15),
             ("neck", "chest", (0.0, shoulder + 0.03, 0.0), (0.0, shoulder + 0.13, 0.0), 0.05),
             ("head", "neck", (0.0, shoulder + 0.13, 0.0), (0.0, shoulder + 0.36, 0.02), 0.095)]
    for side, x in (("l", 1.0), ("r", -1.0)):
        out = (x * np.sin(np.radians(30.0)), -np.cos(np.radians(30.0)), 0.0)  # the A pose
        bones += _limb([f"upper_arm_{side}", f"forearm_{side}", f"hand_{side}"], "chest",
                       (x * 0.19, shoulder, 0.0), out, np.array([0.29, 0.26, 0.12]) * limbs, (0.045, 0.04, 0.035))
    for side, x in (("l", 1.0), ("r", -1.0)):
        bones += _limb([f"thigh_{side}", f"shin_{side}", f"foot_{side}"], "pelvis", (x * 0.1, hip_y, 0.0),
                       [(0, -1, 0), (0, -1, 0), (0, -0.3, 1)], (leg, leg, 0.21), (0.07, 0.05, 0.04))
    return _body(bones)


#: The quadruped's bones and their chain names (issue 44's scheme for four legs).
QUADRUPED_NAMES = {"trunk_back": "body", "trunk_front": "spine_01", "neck": "neck_01", "head": "neck_02",
                   "tail_01": "tail_01", "tail_02": "tail_02",
                   **{f"{part}_{end}_{side}": f"leg_{end}_{side}_0{i + 1}" for end in ("front", "back")
                      for side in ("l", "r") for i, part in enumerate(("upper", "lower", "hoof"))}}


def quadruped_body(limbs=1.0):
    """The quadruped at rest (module notes): 18 bones (:data:`QUADRUPED_NAMES`), its back at 1.0 at
    ``limbs`` 1, 2 long from nose to tail, its head at +z."""
    leg = 0.43 * limbs
    back = 0.14 + 2.0 * leg
    bones = [("trunk_back", None, (0.0, back, -0.5), (0.0, back, 0.0), 0.2),
             ("trunk_front", "trunk_back", (0.0, back, 0.0), (0.0, back + 0.02, 0.5), 0.21),
             ("neck", "trunk_front", (0.0, back + 0.02, 0.5), (0.0, back + 0.32, 0.75), 0.09),
             ("head", "neck", (0.0, back + 0.32, 0.75), (0.0, back + 0.2, 1.05), 0.08)]
    bones += _limb(["tail_01", "tail_02"], "trunk_back", (0.0, back, -0.5), [(0, -0.5, -1), (0, -1, -0.4)],
                   (0.22, 0.22), (0.045, 0.035))
    for end, z in (("front", 0.4), ("back", -0.38)):
        for side, x in (("l", 1.0), ("r", -1.0)):
            knee = (0, -1, 0.12) if end == "back" else (0, -1, 0)
            bones += _limb([f"upper_{end}_{side}", f"lower_{end}_{side}", f"hoof_{end}_{side}"],
                           "trunk_front" if end == "front" else "trunk_back", (x * 0.13, back - 0.05, z),
                           [knee, (0, -1, -0.12 if end == "back" else 0), (0, -1, 0.3)],
                           (leg, leg - 0.05, 0.11), (0.07, 0.045, 0.04))
    return _body(bones)


def body_weights(body, rings_per_metre=60, segments=10, blend=0.04):
    """The body's mesh and skin: (rest (V, 3), faces (T, 3), weights (V, B)) (module notes): one
    closed tube per bone, ``rings_per_metre`` rings along it (at least 4) of ``segments`` vertices;
    within ``blend`` of its joint the parent's weight rises to ½, and within ``blend`` of its end
    that of the child whose joint is there (a smooth C¹ ramp)."""
    bones = len(body.names)
    continuing = np.full(bones, -1)
    for b in range(bones):
        p = body.parents[b]
        if p >= 0 and np.allclose(body.joints[b], body.ends[p]):
            continuing[p] = b
    parts = []
    for b in range(bones):
        axis = body.ends[b] - body.joints[b]
        length = float(np.linalg.norm(axis))
        vertices, faces, s = _tube(body.joints[b], axis / length, length, body.radii[b],
                                   max(4, int(round(rings_per_metre * length))), segments)
        weights = np.zeros((len(vertices), bones))
        if body.parents[b] >= 0:
            weights[:, body.parents[b]] = 0.5 * (1.0 - _smoothstep(s / blend))
        if continuing[b] >= 0:
            weights[:, continuing[b]] = 0.5 * (1.0 - _smoothstep((length - s) / blend))
        weights[:, b] = 1.0 - weights.sum(axis=1)
        parts.append((vertices, faces, weights))
    offsets = np.cumsum([0] + [len(v) for v, _, _ in parts])
    return (np.concatenate([v for v, _, _ in parts]),
            np.concatenate([f + o for (_, f, _), o in zip(parts, offsets)]).astype(np.int64),
            np.concatenate([w for _, _, w in parts]))


def _humanoid_walk(u, turns):
    """Walking in place: the legs swing ±0.45 rad, the knees bend in swing, the feet lift their toes;
    the arms swing against the legs, the elbows bend; the spine turns, the head nods."""
    phi = 2.0 * np.pi * turns * u
    moves = {}
    for side, shift in (("l", 0.0), ("r", np.pi)):
        swing = np.cos(phi + shift)
        lift = np.maximum(0.0, np.sin(phi + shift)) ** 2
        moves[f"thigh_{side}"] = [(0, -0.45 * swing - 0.3 * lift)]
        moves[f"shin_{side}"] = [(0, 0.9 * lift)]
        moves[f"foot_{side}"] = [(0, -0.3 * lift)]
        moves[f"upper_arm_{side}"] = [(0, 0.4 * swing)]
        moves[f"forearm_{side}"] = [(0, -0.3 - 0.3 * lift)]
        moves[f"hand_{side}"] = [(0, -0.3 * swing)]
    moves["spine"] = [(1, 0.15 * np.cos(phi))]
    moves["chest"] = [(1, -0.1 * np.cos(phi)), (0, 0.05 * np.sin(2 * phi))]
    moves["neck"] = [(0, 0.15 * np.sin(2 * phi))]
    moves["head"] = [(1, 0.3 * np.sin(phi))]
    return moves, None


def _humanoid_raise(u, turns):
    """Arms raised over the head (out to the side and up, 2.3 rad) and lowered, the elbows bending
    on the way, the hands turning, the head tilting back and turning, the chest bending sideways."""
    up = np.sin(np.pi * u) ** 2
    moves = {}
    for side, sign in (("l", 1.0), ("r", -1.0)):
        moves[f"upper_arm_{side}"] = [(2, sign * 2.3 * up), (0, -0.3 * np.sin(2 * np.pi * u))]
        moves[f"forearm_{side}"] = [(0, -1.2 * np.sin(2 * np.pi * u) ** 2)]
        moves[f"hand_{side}"] = [(2, sign * 0.6 * up)]
        moves[f"thigh_{side}"] = [(2, sign * 0.15 * up)]
        moves[f"foot_{side}"] = [(2, -sign * 0.15 * up)]
    moves["neck"] = [(0, -0.3 * up)]
    moves["head"] = [(1, 0.6 * np.sin(2 * np.pi * u))]
    moves["chest"] = [(2, 0.25 * np.sin(2 * np.pi * u))]
    moves["spine"] = [(2, 0.15 * np.sin(2 * np.pi * u))]
    return moves, None


def _crouch(down):
    """The local rotations of a squat ``down`` (F,) deep (1: the hips flexed 1.3 rad, the knees 2.0,
    the feet level; the trunk leaning forward, the arms reaching ahead, the head looking up)."""
    moves = {}
    for side in ("l", "r"):
        moves[f"thigh_{side}"] = [(0, -1.3 * down)]
        moves[f"shin_{side}"] = [(0, 2.0 * down)]
        moves[f"foot_{side}"] = [(0, -0.7 * down)]
        moves[f"upper_arm_{side}"] = [(0, -1.3 * down)]
        moves[f"forearm_{side}"] = [(0, -0.5 * down)]
    moves["spine"] = [(0, 0.35 * down)]
    moves["chest"] = [(0, 0.2 * down)]
    moves["neck"] = [(0, -0.3 * down)]
    moves["head"] = [(0, -0.2 * down)]
    return moves


def _humanoid_crouch(u, turns):
    """A squat and back up (:func:`_crouch`), the hands turning as it goes."""
    moves = _crouch(np.sin(np.pi * u) ** 2)
    for side, sign in (("l", 1.0), ("r", -1.0)):
        moves[f"hand_{side}"] = [(1, sign * 0.8 * np.sin(2 * np.pi * u))]
    return moves, None


def _humanoid_jump(u, turns):
    """A jump: a third of the motion crouching 0.6 deep and rising, a third in the air (the lowest
    point 0.45 above the ground at the top, the toes pointing, the arms swung up), a third landing
    into the crouch and standing up."""
    air = np.clip(3.0 * u - 1.0, 0.0, 1.0)
    down = 0.6 * np.where(u < 1 / 3, np.sin(3 * np.pi * u) ** 2,
                          np.where(u >= 2 / 3, np.sin(3 * np.pi * (u - 2 / 3)) ** 2, 0.0))
    moves = _crouch(down)
    for side in ("l", "r"):
        moves[f"foot_{side}"].append((0, 0.5 * np.sin(np.pi * air)))
        moves[f"upper_arm_{side}"].append((0, -1.5 * np.sin(np.pi * air)))
    return moves, np.where((air > 0.0) & (air < 1.0), 0.45 * np.sin(np.pi * air), 0.0)


def _quadruped_walk(u, turns):
    """A walk: each leg swings ±0.35 rad in a lateral sequence (hind left, fore left, hind right,
    fore right a quarter cycle apart), the lower leg folding in swing, the hoof flicking; the back
    bends side to side (0.25 rad) and rolls, the neck and head nod twice a cycle, the tail swings
    side to side."""
    phi = 2.0 * np.pi * turns * u
    moves = {}
    for (end, side), shift in zip((("back", "l"), ("front", "l"), ("back", "r"), ("front", "r")),
                                  (0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi)):
        swing = np.cos(phi + shift)
        lift = np.maximum(0.0, np.sin(phi + shift)) ** 2
        fold = 1.0 if end == "front" else -1.0
        moves[f"upper_{end}_{side}"] = [(0, -0.35 * swing)]
        moves[f"lower_{end}_{side}"] = [(0, fold * 0.8 * lift)]
        moves[f"hoof_{end}_{side}"] = [(0, -fold * 0.5 * lift)]
    moves["trunk_front"] = [(2, 0.06 * np.sin(phi)), (1, 0.25 * np.cos(phi))]
    moves["neck"] = [(0, 0.15 * np.sin(2 * phi))]
    moves["head"] = [(0, -0.2 * np.sin(2 * phi)), (1, 0.2 * np.sin(phi))]
    moves["tail_01"] = [(1, 0.5 * np.sin(phi))]
    moves["tail_02"] = [(1, 0.6 * np.sin(phi - 1.0)), (0, 0.3 * np.cos(phi))]
    return moves, None


def _quadruped_graze(u, turns):
    """The head lowered to the ground and raised (the neck 1.1 rad down, the head 0.6), turning to
    each side, the back arching down (0.25 rad); the forelegs splay a little, the hind legs shift the
    weight back, the tail lifts."""
    down = np.sin(np.pi * u) ** 2
    moves = {"neck": [(0, 1.1 * down), (1, 0.4 * np.sin(2 * np.pi * u))], "head": [(0, 0.6 * down)],
             "trunk_front": [(0, 0.25 * down)], "tail_01": [(0, -0.6 * down)], "tail_02": [(0, -0.4 * down)]}
    for side, sign in (("l", 1.0), ("r", -1.0)):
        moves[f"upper_front_{side}"] = [(2, sign * 0.15 * down), (0, -0.1 * down)]
        moves[f"lower_front_{side}"] = [(0, 0.2 * down)]
        moves[f"hoof_front_{side}"] = [(0, -0.1 * down)]
        moves[f"upper_back_{side}"] = [(0, 0.25 * down)]
        moves[f"lower_back_{side}"] = [(0, -0.3 * down)]
        moves[f"hoof_back_{side}"] = [(0, 0.05 * down)]
    return moves, None


#: Each humanoid motion: its local rotations in closed form (its docstring says what moves).
HUMANOID_MOTIONS = {"walk": _humanoid_walk, "raise": _humanoid_raise, "crouch": _humanoid_crouch,
                    "jump": _humanoid_jump}
#: Each quadruped motion.
QUADRUPED_MOTIONS = {"walk": _quadruped_walk, "graze": _quadruped_graze}
#: The characters: their body, motions and chain names.
CHARACTERS = {"humanoid": (humanoid_body, HUMANOID_MOTIONS, HUMANOID_NAMES),
              "quadruped": (quadruped_body, QUADRUPED_MOTIONS, QUADRUPED_NAMES)}


def character_memory(kind, frames, limbs=1.0, rings_per_metre=60, segments=10):
    """(bytes, what): an upper estimate of the memory :func:`character` holds at its peak (the
    vertices and a few frame-sized temporaries), and those sizes in words (for a refusal)."""
    body = CHARACTERS[kind][0](limbs)
    lengths = np.linalg.norm(body.ends - body.joints, axis=1)
    vertex_count = int(np.sum(np.maximum(4, np.round(rings_per_metre * lengths)) * segments + 2))
    return frames * vertex_count * 3 * 8 * 4, f"{frames} frames of {vertex_count} vertices"


def pose_body(body, local):
    """Forward kinematics: world rotations (F, B, 3, 3) and joints (F, B, 3) of ``body`` posed by
    its bones' ``local`` rotations (F, B, 3, 3) against their parents (the root's: in the world,
    about its joint where it rests)."""
    frames = local.shape[0]
    rotations = np.empty_like(local)
    joints = np.empty((frames, len(body.names), 3))
    for b, p in enumerate(body.parents):  # parents come first
        if p < 0:
            rotations[:, b] = local[:, b]
            joints[:, b] = body.joints[b]
        else:
            rotations[:, b] = rotations[:, p] @ local[:, b]
            joints[:, b] = joints[:, p] + np.einsum("fab,b->fa", rotations[:, p], body.joints[b] - body.joints[p])
    return rotations, joints


def character(kind="humanoid", motions=None, frames_per_motion=48, turns=2, limbs=1.0, rings_per_metre=60,
              segments=10):
    """A generated character (module notes) moving through ``motions`` (names of ``kind``'s
    motions, in order; default all of them), ``frames_per_motion`` frames each (``turns`` cycles of
    a walk): (vertices (F, V, 3), faces (T, 3), :class:`CharacterRig`). Every frame's lowest point
    is on y = 0 but in a jump's flight, which rises above it."""
    build, table, truth = CHARACTERS[kind]
    body = build(limbs)
    rest, faces, weights = body_weights(body, rings_per_metre, segments)
    local, flight = [], []
    u = np.arange(frames_per_motion) / frames_per_motion
    for name in (list(table) if motions is None else motions):
        moves, air = table[name](u, turns)
        rotation = np.broadcast_to(np.eye(3), (frames_per_motion, len(body.names), 3, 3)).copy()
        for bone, turns_of in moves.items():
            for axis, angle in turns_of:  # applied in order, each about the bone's own (turned) axes
                rotation[:, body.index(bone)] = rotation[:, body.index(bone)] @ _rotation(axis, angle)
        local.append(rotation)
        flight.append(np.zeros(frames_per_motion) if air is None else air)
    local, flight = np.concatenate(local), np.concatenate(flight)
    rotations, joints = pose_body(body, local)
    translations = joints - np.einsum("fbij,bj->fbi", rotations, body.joints)
    vertices = np.einsum("vb,fbij,vj->fvi", weights, rotations, rest) + np.einsum("vb,fbi->fvi", weights, translations)
    lift = flight - vertices[..., 1].min(axis=1)
    vertices[..., 1] += lift[:, None]
    translations[..., 1] += lift[:, None]
    names = [truth[n] for n in body.names]
    return vertices, faces, CharacterRig(body=body, rest=rest, weights=weights, rotations=rotations,
                                         translations=translations, names=names, ground=flight == 0.0)
