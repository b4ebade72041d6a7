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


def test_blender_plays_the_linear_puppet_rig_as_computed(tmp_path):
    """play --skinning linear: Blender's own import of the UsdSkel rig, correctives as blend shapes
    included, matches play's bake to 1e-4 of the diagonal (measured 3e-7; the dual-quaternion rig,
    which Blender skins linearly, was 1.7e-2 away on the horse; signed shape weights, before they
    were split into ± pairs in [0, 1], 1e-3)."""
    import h5py

    vertices, faces = bending_bar(frames=24, rings=10, segments=8)
    write_array_sequence(tmp_path / "bar.npz", vertices, faces, 24.0)
    runner = CliRunner()
    for args in (["fit-skin", "bar.npz", "-o", "s.h5", "--bones", "4", "-q"],
                 ["select-controls", "s.h5", "-o", "c.h5", "--count", "6", "-q"],
                 ["train-kcca", "c.h5", "-o", "p.h5", "--correctives", "1e-4", "-q"],
                 ["play", "p.h5", "-c", "bar.npz", "-o", "rig.usdc", "--skinning", "linear", "--device", "cpu", "-q"],
                 ["play", "p.h5", "-c", "bar.npz", "-o", "bake.h5", "--skinning", "linear", "--device", "cpu", "-q"]):
        result = runner.invoke(main, [str(tmp_path / a) if a.endswith((".npz", ".h5", ".usdc")) else a for a in args])
        assert result.exit_code == 0, result.output
    with h5py.File(tmp_path / "bake.h5") as f:
        expected = f["vertices"][()].reshape(24, -1, 3)
    probe = pathlib.Path(__file__).with_name("blender_probe.py")
    run = subprocess.run([BLENDER_PYTHON, str(probe), str(tmp_path / "rig.usdc"), "0", "7", "19"],
                         capture_output=True, text=True, timeout=300)
    played = json.loads(run.stdout.split("PROBE", 1)[1])
    diagonal = np.linalg.norm(np.ptp(vertices[0], axis=0))
    for frame, points in played.items():
        want = expected[int(frame)]
        want_z_up = np.stack([want[:, 0], -want[:, 2], want[:, 1]], axis=1)  # Blender's Y-up to Z-up
        assert np.abs(np.array(points) - want_z_up).max() < 1e-4 * diagonal


def test_blender_shows_a_centimetre_z_up_capture_at_its_size_axis_and_frames(tmp_path):
    """A capture in cm, Z up, at time codes 1001…: Blender shows skinsynth's export in metres
    (metersPerUnit 0.01 applied), unrotated (Z up kept), at the same frame numbers."""
    from pxr import Usd, UsdGeom

    from test_interchange import production_capture

    vertices, faces = bending_bar(frames=24, rings=10, segments=8)
    production_capture(tmp_path / "capture.usda", vertices, faces)
    runner = CliRunner()
    for args in (["fit-skin", str(tmp_path / "capture.usda"), "-o", str(tmp_path / "s.h5"), "--bones", "4", "-q"],
                 ["export", str(tmp_path / "s.h5"), "-o", str(tmp_path / "points.usdc"), "--as", "points"]):
        assert runner.invoke(main, args).exit_code == 0
    stage = Usd.Stage.Open(str(tmp_path / "points.usdc"))
    written = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/World/body")).GetPointsAttr().Get(1010))
    probe = pathlib.Path(__file__).with_name("blender_probe.py")
    run = subprocess.run([BLENDER_PYTHON, str(probe), str(tmp_path / "points.usdc"), "1010"], capture_output=True,
                         text=True, timeout=300)
    played = np.array(json.loads(run.stdout.split("PROBE", 1)[1])["1010"])
    assert np.abs(played - 0.01 * written).max() < 1e-4 * np.linalg.norm(np.ptp(0.01 * written, axis=0))
