"""The JavaScript glTF clients (Khronos glTF-Validator, three.js) the glTF contract tests run, and the skin's vertices in glTF's axes."""

import json
import os
import shutil
import subprocess

import numpy as np
import pytest

from skinsynth.formats.model import read_model
from skinsynth.formats.skin_file import read_skin

JS = os.path.join(os.path.dirname(__file__), "js")


def skip_without_clients():
    """Skips the calling test module where node or tests/contracts/js/node_modules is missing."""
    if shutil.which("node") is None or not os.path.isdir(os.path.join(JS, "node_modules", "three")):
        pytest.skip("node and tests/contracts/js/node_modules (three, gltf-validator) are needed: run make setup",
                    allow_module_level=True)


def validate(path):
    done = subprocess.run(["node", os.path.join(JS, "gltf_validate.mjs"), str(path)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def three_positions(path, fps, frames, tmp_path):
    """(clips, frames, V, 3) float32 as three.js skins them, and the clip names."""
    out = tmp_path / "three.bin"
    done = subprocess.run(["node", os.path.join(JS, "gltf_three.mjs"), str(path), str(out), str(fps),
                           *[str(f) for f in frames]], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    info = json.loads(done.stdout)
    return np.fromfile(out, dtype=np.float32).reshape(len(info["clips"]), len(frames), info["vertices"], 3), \
        info["clips"]


def skin_of(path):
    return read_skin(path, read_model(path, groups=("mesh", "examples", "skin")))


def in_gltf_axes(vertices, scene):
    """What glTF holds of skinsynth's vertices: Y up, metres."""
    vertices = np.asarray(vertices, dtype=np.float64) * scene.meters_per_unit
    return vertices if scene.up_axis == "Y" else np.stack([vertices[..., 0], vertices[..., 2], -vertices[..., 1]], -1)
