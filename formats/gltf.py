"""glTF 2.0 binary (.glb) of a skinned mesh and its animation clips (Khronos glTF 2.0 §3.7 skins,
§3.11 animations), from a plain record (:class:`SkinnedScene`): the arrays are made by
``pipeline.skeleton``; this module only lays them out.

Layout: scene 0 holds the mesh node (with the skin) and the root joint node; the bone joint
nodes are children of the root, their default TRS the bind pose (a translation to each bone's
centre). A scene with joint ``parents`` (a skeleton's tree) nests them as it says instead, each
node's ``children`` in ascending joint order and its default translation local to its parent; a
scene without them is written byte for byte as before they existed. One animation per clip,
LINEAR samplers keyed at each frame's time (frame / fps), a translation and a rotation channel
per moving joint. All data in one buffer, the GLB's BIN chunk.

Morph targets (§3.7.2.2), when the scene has them: POSITION displacements of the rest pose, added
before skinning, each a float32 accessor with its min and max (as the spec requires of POSITION);
the mesh's default ``weights`` zeros and ``extras.targetNames`` their names (three.js, Blender and
Babylon.js name the targets from it); per clip that has them, one ``weights`` channel on the mesh
node whose LINEAR sampler outputs frames × targets scalars, frame-major (§3.11: the output count
is the input count times the number of targets). The targets carry no NORMAL displacements:
normals are not linear in the positions, so no displacement blended by the weights gives the
normals of the blended shape; engines skin the rest normals, so the lighting does not follow a
corrective's change of shape (the positions do). A scene without morph targets is written byte
for byte as before they existed.
"""

import json
import struct
from dataclasses import dataclass, field

import numpy as np

from .atomic import atomic_output
from .errors import require_finite
from .validation import tree_depths

_FLOAT, _UBYTE, _USHORT, _UINT = 5126, 5121, 5123, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_COMPONENT = {np.dtype(np.float32): _FLOAT, np.dtype(np.uint8): _UBYTE, np.dtype(np.uint16): _USHORT,
              np.dtype(np.uint32): _UINT}
_TYPE = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4", 16: "MAT4"}


@dataclass
class Clip:
    """One animation: ``name``; ``times`` (F,) seconds; bones' local ``rotations`` (F, B, 4)
    (x, y, z, w) and ``translations`` (F, B, 3); the root's ``root_rotations`` (F, 4) and
    ``root_translations`` (F, 3), or None for a root that does not move; ``morph_weights`` (F, k)
    the weights of the scene's k morph targets per frame, or None (they stay at the mesh's
    default weights, zero)."""
    name: str
    times: np.ndarray
    rotations: np.ndarray
    translations: np.ndarray
    root_rotations: np.ndarray | None = None
    root_translations: np.ndarray | None = None
    morph_weights: np.ndarray | None = None


@dataclass
class SkinnedScene:
    """positions, normals (V, 3); faces (T, 3); joints (V, 4) into ``joint_names``; weights
    (V, 4) float32 or normalised uint8/uint16; inverse_binds (J, 4, 4); bind_translations (J, 3)
    each joint's default translation (the root's its parent's frame, the bones' the root's);
    uvs (V, 2) or None; clips [Clip]; ``mesh_name``; morph_targets (k, V, 3) POSITION
    displacements added before skinning, or None, named ``target_names`` (k,) (default
    "target_N"); parents (J,) each joint's parent joint (−1 for joint 0, the root, and
    ``bind_translations`` then local to the parent), or None: every bone under the root."""
    positions: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    inverse_binds: np.ndarray
    bind_translations: np.ndarray
    joint_names: list
    clips: list = field(default_factory=list)
    uvs: np.ndarray | None = None
    mesh_name: str = "mesh"
    morph_targets: np.ndarray | None = None
    target_names: list | None = None
    parents: np.ndarray | None = None


class _Buffer:
    """The BIN chunk being laid out, with its bufferViews and accessors."""

    def __init__(self):
        self.parts, self.length, self.views, self.accessors = [], 0, [], []

    def view(self, data, target=None):
        data = np.ascontiguousarray(data)
        pad = (-self.length) % 4
        if pad:
            self.parts.append(b"\0" * pad)
            self.length += pad
        entry = {"buffer": 0, "byteOffset": self.length, "byteLength": data.nbytes}
        if target is not None:
            entry["target"] = target
        self.views.append(entry)
        self.parts.append(data.tobytes())
        self.length += data.nbytes
        return len(self.views) - 1

    def accessor(self, view, array, offset=0, bounds=False, normalized=False):
        """An accessor over ``view`` at byte ``offset``: ``array`` (count, n) or (count,) gives
        type and count (its values are what the view holds there)."""
        width = 1 if array.ndim == 1 else int(np.prod(array.shape[1:]))
        entry = {"bufferView": view, "componentType": _COMPONENT[array.dtype], "count": int(array.shape[0]),
                 "type": _TYPE[width]}
        if offset:
            entry["byteOffset"] = int(offset)
        if normalized:
            entry["normalized"] = True
        if bounds:
            flat = array.reshape(array.shape[0], -1)
            entry["min"] = [float(v) for v in flat.min(axis=0)]
            entry["max"] = [float(v) for v in flat.max(axis=0)]
        self.accessors.append(entry)
        return len(self.accessors) - 1

    def array(self, array, target=None, bounds=False, normalized=False):
        return self.accessor(self.view(array, target), array, bounds=bounds, normalized=normalized)


def write_skinned_glb(path, scene: SkinnedScene):
    """Write ``scene`` as a .glb (atomic)."""
    require_finite(path, "the vertex positions", scene.positions)
    for clip in scene.clips:
        require_finite(path, f"the animation {clip.name!r}", clip.translations)
    morph_count = _check_morph_targets(path, scene)
    buffer = _Buffer()
    positions = np.asarray(scene.positions, dtype=np.float32)
    attributes = {"POSITION": buffer.array(positions, _ARRAY_BUFFER, bounds=True),
                  "NORMAL": buffer.array(np.asarray(scene.normals, dtype=np.float32), _ARRAY_BUFFER)}
    if scene.uvs is not None:
        attributes["TEXCOORD_0"] = buffer.array(np.asarray(scene.uvs, dtype=np.float32), _ARRAY_BUFFER)
    joint_type = np.uint8 if len(scene.joint_names) <= 256 else np.uint16
    attributes["JOINTS_0"] = buffer.array(np.asarray(scene.joints).astype(joint_type), _ARRAY_BUFFER)
    weights = np.asarray(scene.weights)
    attributes["WEIGHTS_0"] = buffer.array(weights, _ARRAY_BUFFER, normalized=weights.dtype != np.float32)
    indices = buffer.array(np.asarray(scene.faces, dtype=np.uint32).reshape(-1), _ELEMENT_ARRAY_BUFFER)
    primitive = {"attributes": attributes, "indices": indices, "mode": 4}
    mesh = {"name": scene.mesh_name, "primitives": [primitive]}
    if morph_count:
        targets = np.asarray(scene.morph_targets, dtype=np.float32)
        primitive["targets"] = [{"POSITION": buffer.array(target, _ARRAY_BUFFER, bounds=True)} for target in targets]
        mesh["weights"] = [0.0] * morph_count
        mesh["extras"] = {"targetNames": list(scene.target_names or [f"target_{i}" for i in range(morph_count)])}

    bones = len(scene.joint_names) - 1
    mesh_node, root_node = 0, 1
    joint_nodes = [root_node] + list(range(2, 2 + bones))
    children = _joint_children(scene.parents, bones + 1)
    nodes = [{"name": scene.mesh_name, "mesh": 0, "skin": 0},
             {"name": scene.joint_names[0], "children": [joint_nodes[c] for c in children[0]]}]
    for j in range(1, bones + 1):
        nodes.append({"name": scene.joint_names[j],
                      "translation": [float(v) for v in scene.bind_translations[j]]})
        if children[j]:
            nodes[-1]["children"] = [joint_nodes[c] for c in children[j]]
    if np.any(scene.bind_translations[0]):
        nodes[root_node]["translation"] = [float(v) for v in scene.bind_translations[0]]
    ibm = np.ascontiguousarray(np.swapaxes(np.asarray(scene.inverse_binds, dtype=np.float32), 1, 2))  # column-major
    skin = {"joints": joint_nodes, "skeleton": root_node,
            "inverseBindMatrices": buffer.array(ibm.reshape(len(ibm), 16))}
    animations = [_animation(buffer, clip, root_node, joint_nodes[1:], mesh_node) for clip in scene.clips]

    document = {
        "asset": {"version": "2.0", "generator": "skinsynth"},
        "scene": 0, "scenes": [{"nodes": [mesh_node, root_node]}], "nodes": nodes,
        "meshes": [mesh],
        "skins": [skin], "accessors": buffer.accessors, "bufferViews": buffer.views,
        "buffers": [{"byteLength": buffer.length}],
    }
    if animations:
        document["animations"] = animations
    with atomic_output(path, expected_bytes=buffer.length + (1 << 20)) as tmp:
        with open(tmp, "wb") as handle:
            _write_glb(handle, document, buffer.parts, buffer.length)


def _joint_children(parents, joints):
    """Each joint's children, ascending: every bone under the root when ``parents`` is None;
    ValueError unless ``parents`` (J,) is one tree under joint 0."""
    if parents is None:
        return [list(range(1, joints))] + [[] for _ in range(joints - 1)]
    parents = np.asarray(parents, dtype=np.int64)
    if parents.shape != (joints,) or parents[0] != -1 or (parents[1:] < 0).any() or (parents >= joints).any():
        raise ValueError(f"joint parents must be ({joints},), -1 for the root joint 0 and a joint for every other, "
                         f"got {parents.tolist()}")
    if (tree_depths(parents) < 0).any():
        raise ValueError("the joint parents are not a tree under the root joint (a cycle)")
    children = [[] for _ in range(joints)]
    for joint in range(1, joints):
        children[parents[joint]].append(joint)
    return children


def _check_morph_targets(path, scene):
    """The scene's number of morph targets (0 for none), after checking that they and every
    clip's weights are finite and of matching shapes (ValueError for a mismatch)."""
    count = 0 if scene.morph_targets is None else len(scene.morph_targets)
    if count:
        targets = np.asarray(scene.morph_targets)
        if targets.shape != (count, len(scene.positions), 3):
            raise ValueError(f"morph targets must have shape (k, {len(scene.positions)}, 3), got {targets.shape}")
        if scene.target_names is not None and len(scene.target_names) != count:
            raise ValueError(f"{len(scene.target_names)} target names for {count} morph targets")
        require_finite(path, "the morph targets", targets)
    for clip in scene.clips:
        if clip.morph_weights is None:
            continue
        if np.shape(clip.morph_weights) != (len(clip.times), count) or not count:
            raise ValueError(f"the morph weights of {clip.name!r} must have shape ({len(clip.times)}, {count}) "
                             f"(frames, morph targets), got {np.shape(clip.morph_weights)}")
        require_finite(path, f"the morph weights of {clip.name!r}", clip.morph_weights)
    return count


def _animation(buffer, clip, root_node, bone_nodes, mesh_node):
    times = np.asarray(clip.times, dtype=np.float32)
    frames = len(times)
    time_accessor = buffer.array(times, bounds=True)
    samplers, channels = [], []

    def channel(node, path, view, values, offset):
        samplers.append({"input": time_accessor, "output": buffer.accessor(view, values, offset), "interpolation":
                         "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": path}})

    if clip.root_rotations is not None:
        rotations = np.asarray(clip.root_rotations, dtype=np.float32)
        translations = np.asarray(clip.root_translations, dtype=np.float32)
        channel(root_node, "rotation", buffer.view(rotations), rotations, 0)
        channel(root_node, "translation", buffer.view(translations), translations, 0)
    rotations = np.ascontiguousarray(np.swapaxes(np.asarray(clip.rotations, dtype=np.float32), 0, 1))  # (B, F, 4)
    translations = np.ascontiguousarray(np.swapaxes(np.asarray(clip.translations, dtype=np.float32), 0, 1))
    rotation_view, translation_view = buffer.view(rotations), buffer.view(translations)
    for b, node in enumerate(bone_nodes):
        channel(node, "rotation", rotation_view, rotations[b], b * frames * 16)
        channel(node, "translation", translation_view, translations[b], b * frames * 12)
    if clip.morph_weights is not None:  # frames × targets scalars, frame-major (§3.11)
        weights = np.asarray(clip.morph_weights, dtype=np.float32).reshape(-1)
        channel(mesh_node, "weights", buffer.view(weights), weights, 0)
    return {"name": clip.name, "samplers": samplers, "channels": channels}


def _write_glb(handle, document, parts, length):
    """GLB container (glTF 2.0 §4.4): header, JSON chunk padded with spaces, BIN chunk padded with zeros."""
    text = json.dumps(document, separators=(",", ":")).encode()
    text += b" " * ((-len(text)) % 4)
    pad = (-length) % 4
    total = 12 + 8 + len(text) + 8 + length + pad
    handle.write(struct.pack("<4sII", b"glTF", 2, total))
    handle.write(struct.pack("<I4s", len(text), b"JSON"))
    handle.write(text)
    handle.write(struct.pack("<I4s", length + pad, b"BIN\0"))
    for part in parts:
        handle.write(part)
    handle.write(b"\0" * pad)


def write_static_glb(path, positions, faces, attributes=None):
    """A .glb of one unskinned mesh: positions (V, 3), faces (T, 3) and ``attributes`` {glTF
    attribute name (e.g. "TEXCOORD_1"): float32 (V, n)} (atomic)."""
    buffer = _Buffer()
    positions = np.asarray(positions, dtype=np.float32)
    primitive = {"attributes": {"POSITION": buffer.array(positions, _ARRAY_BUFFER, bounds=True)}, "mode": 4}
    for name, values in (attributes or {}).items():
        primitive["attributes"][name] = buffer.array(np.asarray(values, dtype=np.float32), _ARRAY_BUFFER)
    primitive["indices"] = buffer.array(np.asarray(faces, dtype=np.uint32).reshape(-1), _ELEMENT_ARRAY_BUFFER)
    document = {"asset": {"version": "2.0", "generator": "skinsynth"}, "scene": 0, "scenes": [{"nodes": [0]}],
                "nodes": [{"name": "rest", "mesh": 0}], "meshes": [{"name": "rest", "primitives": [primitive]}],
                "accessors": buffer.accessors, "bufferViews": buffer.views, "buffers": [{"byteLength": buffer.length}]}
    with atomic_output(path, expected_bytes=buffer.length + (1 << 20)) as tmp:
        with open(tmp, "wb") as handle:
            _write_glb(handle, document, buffer.parts, buffer.length)
