"""Reading back the .glb files skinsynth writes, for tests: the JSON chunk, the BIN chunk, accessors."""

import json
import struct

import numpy as np

_COMPONENTS = {5126: np.float32, 5125: np.uint32, 5123: np.uint16, 5121: np.uint8}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def glb_document(path):
    """(the JSON, the BIN chunk) of a .glb."""
    data = path.read_bytes()
    length = struct.unpack_from("<I", data, 12)[0]
    return json.loads(data[20:20 + length]), data[20 + length + 8:]


def glb_accessor(document, binary, index):
    """Accessor ``index`` as a (count, width) array of its component type."""
    accessor = document["accessors"][index]
    view = document["bufferViews"][accessor["bufferView"]]
    width = _WIDTHS[accessor["type"]]
    return np.frombuffer(binary, _COMPONENTS[accessor["componentType"]], accessor["count"] * width,
                         view["byteOffset"] + accessor.get("byteOffset", 0)).reshape(-1, width)


def glb_primitive(path):
    """({attribute: (N, n) array}, indices (T, 3)) of the .glb's first primitive."""
    document, binary = glb_document(path)
    first = document["meshes"][0]["primitives"][0]
    return ({name: glb_accessor(document, binary, index) for name, index in first["attributes"].items()},
            glb_accessor(document, binary, first["indices"]).reshape(-1, 3))


def _xyzw_matrix(q):
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4) (x, y, z, w), glTF's order."""
    x, y, z, w = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
                     np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
                     np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def glb_node_parents(document):
    """{node: its parent node} of a glTF document's node hierarchy (roots absent)."""
    return {child: node for node, entry in enumerate(document["nodes"]) for child in entry.get("children", [])}


def glb_skinned(path, animation=0, keys=None):
    """(K, V, 3) float64: the .glb's first skinned mesh as a glTF engine skins it (glTF 2.0 §3.7.3)
    at keyframes ``keys`` of animation ``animation`` (all of them when None): every node's TRS
    (its channel's key, else its default) composed down the node hierarchy, each joint's world
    matrix times its inverse bind matrix, blended by WEIGHTS_0 over JOINTS_0. An oracle
    independent of skinsynth's maths; LINEAR keys are sampled exactly at their own times."""
    document, binary = glb_document(path)
    nodes, skin = document["nodes"], document["skins"][0]
    parents = glb_node_parents(document)
    channels, samplers = document["animations"][animation]["channels"], document["animations"][animation]["samplers"]
    keyed = {(c["target"]["node"], c["target"]["path"]): glb_accessor(document, binary,
                                                                      samplers[c["sampler"]]["output"])
             for c in channels if c["target"]["path"] in ("translation", "rotation")}
    count = glb_accessor(document, binary, samplers[0]["input"]).shape[0]
    keys = range(count) if keys is None else keys
    inverse_binds = np.swapaxes(glb_accessor(document, binary, skin["inverseBindMatrices"])
                                .astype(np.float64).reshape(-1, 4, 4), 1, 2)  # stored column-major
    attributes, _ = glb_primitive(path)
    positions = attributes["POSITION"].astype(np.float64)
    joints = attributes["JOINTS_0"].astype(np.int64)
    weights = attributes["WEIGHTS_0"].astype(np.float64)
    if attributes["WEIGHTS_0"].dtype != np.float32:
        weights /= np.iinfo(attributes["WEIGHTS_0"].dtype).max

    def local(node, key):
        matrix = np.eye(4)
        rotation = keyed.get((node, "rotation"))
        matrix[:3, :3] = _xyzw_matrix(rotation[key] if rotation is not None else nodes[node].get("rotation",
                                                                                                  [0, 0, 0, 1]))
        translation = keyed.get((node, "translation"))
        matrix[:3, 3] = translation[key] if translation is not None else nodes[node].get("translation", [0, 0, 0])
        return matrix

    def world(node, key):
        return local(node, key) if node not in parents else world(parents[node], key) @ local(node, key)

    out = []
    for key in keys:
        skinning = np.stack([world(node, key) @ inverse for node, inverse in zip(skin["joints"], inverse_binds)])
        blended = np.einsum("vk,vkij->vij", weights, skinning[joints])
        out.append(np.einsum("vij,vj->vi", blended[:, :3, :3], positions) + blended[:, :3, 3])
    return np.stack(out)
