"""A real DCC plays our USD: Blender (as the bpy module) imports the exports and we compare vertices.

Optional: set SKINSYNTH_BLENDER_PYTHON to a Python that can `import bpy` (e.g. a venv with
`pip install bpy==5.0.1`, ~370 MB); skipped otherwise.
"""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest
from click.testing import CliRunner

from skinsynth.cli.main import main
from skinsynth.formats.meshseq import write_array_sequence
from skinsynth.formats.skin_file import read_skin
from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.examples import bending_bar

BLENDER_PYTHON = os.environ.get("SKINSYNTH_BLENDER_PYTHON")
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not BLENDER_PYTHON, reason="SKINSYNTH_BLENDER_PYTHON (a Python with bpy) not set")]


@pytest.mark.parametrize("kind", ["skel", "points"])
def test_blender_plays_exported_usd(tmp_path, kind):
    vertices, faces = bending_bar(frames=16, rings=10, segments=8)
    write_array_sequence(tmp_path / "bar.npz", vertices, faces, 24.0)
    runner = CliRunner()
    assert runner.invoke(main, ["fit-skin", str(tmp_path / "bar.npz"), "-o", str(tmp_path / "s.h5"),
                                "--bones", "4", "--quiet"]).exit_code == 0
    usd = tmp_path / f"bar_{kind}.usdc"
    assert runner.invoke(main, ["export", str(tmp_path / "s.h5"), "-o", str(usd), "--as", kind]).exit_code == 0
    skin = read_skin(tmp_path / "s.h5")
    expected = lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations, skin.translations)
    probe = pathlib.Path(__file__).with_name("blender_probe.py")
    run = subprocess.run([BLENDER_PYTHON, str(probe), str(usd), "0", "5", "11"], capture_output=True, text=True,
                         timeout=300)
    played = json.loads(run.stdout.split("PROBE", 1)[1])
    diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    for frame, points in played.items():
        got = np.array(points)
        want = expected[int(frame)]
        # Blender converts the stage's Y-up to its Z-up: (x, y, z) -> (x, -z, y).
        want_z_up = np.stack([want[:, 0], -want[:, 2], want[:, 1]], axis=1)
        assert np.abs(got - want_z_up).max() < 1e-4 * diagonal
