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
