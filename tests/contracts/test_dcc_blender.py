"""A real DCC plays our USD and glTF: Blender (as the bpy module) imports the exports and we compare vertices.

Optional: set SKINSYNTH_BLENDER_PYTHON to a Python that can `import bpy` (`make blender` makes one,
.venv-blender, with `pip install bpy==5.0.1`, ~370 MB); skipped otherwise.
"""

import json
import os
import pathlib
import subprocess

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from skinsynth.cli.main import main
from skinsynth.formats.meshseq import write_array_sequence
from skinsynth.formats.skin_file import read_skin
from skinsynth.gpu import lbs, lbs_reference
from skinsynth.pipeline.inputs.examples import bending_bar

from cli_helpers import assert_ok, cli

BLENDER_PYTHON = os.environ.get("SKINSYNTH_BLENDER_PYTHON")
if BLENDER_PYTHON:  # a path relative to where the tests started stays right wherever a test runs
    BLENDER_PYTHON = os.path.abspath(BLENDER_PYTHON) if os.sep in BLENDER_PYTHON else BLENDER_PYTHON
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not BLENDER_PYTHON, reason="SKINSYNTH_BLENDER_PYTHON (a Python with bpy) not set")]


def probe(script, *args):
    """What ``script`` (a probe beside this file, run by Blender's Python) printed after PROBE."""
    run = subprocess.run([BLENDER_PYTHON, str(pathlib.Path(__file__).with_name(script)), *[str(a) for a in args]],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and "PROBE" in run.stdout, run.stderr[-4000:]
    return json.loads(run.stdout.split("PROBE", 1)[1])


def z_up(points):
    """Blender's view of Y-up points: it converts Y up to its Z up, (x, y, z) -> (x, -z, y)."""
    points = np.asarray(points)
    return np.stack([points[..., 0], -points[..., 2], points[..., 1]], axis=-1)


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
    played = probe("blender_probe.py", usd, 0, 5, 11)
    diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    for frame, points in played.items():
        assert np.abs(np.array(points) - z_up(expected[int(frame)])).max() < 1e-4 * diagonal


def test_blender_plays_the_linear_puppet_rig_as_computed(tmp_path):
    """play --skinning linear: Blender's own import of the UsdSkel rig, correctives as blend shapes
    included, matches play's bake to 1e-4 of the diagonal (measured 3e-7; the dual-quaternion rig,
    which Blender skins linearly, was 1.7e-2 away on the horse; signed shape weights, before they
    were split into ± pairs in [0, 1], 1e-3)."""
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
    played = probe("blender_probe.py", tmp_path / "rig.usdc", 0, 7, 19)
    diagonal = np.linalg.norm(np.ptp(vertices[0], axis=0))
    for frame, points in played.items():
        assert np.abs(np.array(points) - z_up(expected[int(frame)])).max() < 1e-4 * diagonal


def test_blender_shows_a_centimetre_z_up_capture_at_its_size_axis_and_frames(tmp_path):
    """A capture in cm, Z up, at time codes 1001…: Blender shows skinsynth's export in metres
    (metersPerUnit 0.01 applied), unrotated (Z up kept), at the same frame numbers."""
    from pxr import Usd, UsdGeom

    from capture_cases import production_capture

    vertices, faces = bending_bar(frames=24, rings=10, segments=8)
    production_capture(tmp_path / "capture.usda", vertices, faces)
    runner = CliRunner()
    for args in (["fit-skin", str(tmp_path / "capture.usda"), "-o", str(tmp_path / "s.h5"), "--bones", "4", "-q"],
                 ["export", str(tmp_path / "s.h5"), "-o", str(tmp_path / "points.usdc"), "--as", "points"]):
        assert runner.invoke(main, args).exit_code == 0
    stage = Usd.Stage.Open(str(tmp_path / "points.usdc"))
    written = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/World/body")).GetPointsAttr().Get(1010))
    played = np.array(probe("blender_probe.py", tmp_path / "points.usdc", 1010)["1010"])
    assert np.abs(played - 0.01 * written).max() < 1e-4 * np.linalg.norm(np.ptp(0.01 * written, axis=0))


# -- glTF (issue 23): Blender's own glTF importer plays each .glb skinsynth writes ----------------------

@pytest.fixture(scope="module")
def stages(stage_files):
    """The test bar of tests/contracts/test_gltf.py: its skin fit, 3 synthesized clips, a linear puppet."""
    return stage_files(frames=40, bones=4, iterations=6, cycles=2, graph=(),
                       synthesis=("-n", 3, "-m", 30, "--seed", 3), controls=("--count", 4),
                       puppet=("--correctives", "off"))


def _skinned(skin, rotations, translations):
    return lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, np.asarray(rotations, np.float64),
               np.asarray(translations, np.float64), device="cpu")


def _skin_fit(stages, out, skin):
    assert_ok(cli("export", stages / "skin.h5", "-o", out, "-q"))
    return _skinned(skin, skin.rotations, skin.translations)[None]


def _root_motion_synthesis(stages, out, skin):
    assert_ok(cli("export", stages / "bones.h5", "-o", out, "--root-motion", "-q"))  # every clip
    with h5py.File(stages / "bones.h5") as f:
        rotations, translations = f["synthesis/bone_matrices"][()], f["synthesis/bone_translations"][()]
    assert len(rotations) >= 2
    return np.stack([_skinned(skin, r, t) for r, t in zip(rotations, translations)])


def _linear_puppet(stages, out, skin):
    args = ["play", stages / "puppet.h5", "-c", stages / "bar.npz", "--instances", 2, "--spacing", 0,
            "--skinning", "linear", "--device", "cpu", "-q"]
    assert_ok(cli(*args, "-o", out))
    assert_ok(cli(*args, "-o", out.with_suffix(".h5")))
    with h5py.File(out.with_suffix(".h5")) as f:
        return f["vertices"][()]  # play's own linear skinning, (characters, F, V, 3)


def _linear_puppet_with_correctives(stages, out, skin):
    """A puppet trained for linear skinning with correctives: their morph targets, ± pairs in [0, 1]."""
    puppet = out.with_name("corrected.h5")
    assert_ok(cli("train-kcca", stages / "controls.h5", "-o", puppet, "--skinning", "linear", "--correctives",
                  "1e-3", "-q"))
    args = ["play", puppet, "-c", stages / "bar.npz", "--instances", 2, "--spacing", 0, "--device", "cpu", "-q"]
    assert_ok(cli(*args, "-o", out))
    assert_ok(cli(*args, "-o", out.with_suffix(".h5")))
    with h5py.File(out.with_suffix(".h5")) as f:
        return f["vertices"][()]


GLTF_CASES = {"skin fit": _skin_fit, "root motion, 3 synthesized clips": _root_motion_synthesis,
              "linear puppet played": _linear_puppet, "linear puppet with correctives": _linear_puppet_with_correctives}


@pytest.mark.parametrize("case", list(GLTF_CASES))
def test_blender_plays_the_glb_as_skinsynth_skins_it(stages, tmp_path, case):
    """Blender's glTF import of each clip, at its first, a middle and its last frame, is skinsynth's
    own LBS of that clip to 1e-4 of the diagonal, vertex for vertex (measured 2e-7, 3e-7 and 1e-7:
    float32)."""
    from gltf_clients import in_gltf_axes, skin_of

    skin = skin_of(stages / "skin.h5")  # the rig of every case: the synthesis's and the puppet's are this fit's
    out = tmp_path / "out.glb"
    truth = GLTF_CASES[case](stages, out, skin)  # (clips, F, V, 3) in the skin's own axes and units
    frames = [0, truth.shape[1] // 2, truth.shape[1] - 1]
    played = probe("blender_gltf_probe.py", out, round(skin.fps), *frames)
    rest = z_up(in_gltf_axes(skin.rest_vertices, skin.scene))
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))
    assert played["vertices"] == len(rest) and np.abs(np.array(played["rest"]) - rest).max() < 1e-6 * diagonal
    assert len(played["animations"]) == len(truth)
    for clip, (name, by_frame) in enumerate(played["animations"].items()):
        for frame in frames:
            want = z_up(in_gltf_axes(truth[clip, frame], skin.scene))
            error = np.abs(np.array(by_frame[str(frame)]) - want).max() / diagonal
            assert error < 1e-4, (case, name, frame, error)


def test_blender_finds_one_root_in_the_usdskel_rig(stages, tmp_path):
    """export --as skel: after Blender's USD import the armature has exactly one bone without a
    parent, the root, and every bone of the fit under it."""
    assert_ok(cli("export", stages / "skin.h5", "-o", tmp_path / "rig.usdc", "--as", "skel", "-q"))
    armatures = probe("blender_probe.py", tmp_path / "rig.usdc", "--bones")
    assert len(armatures) == 1
    (bones,) = armatures.values()
    assert [name for name, parent in bones.items() if parent is None] == ["root"]
    assert len(bones) == 1 + read_skin(stages / "skin.h5").rotations.shape[1]


# -- a skin with a skeleton (fit-skin --skeleton): Blender's armature is its tree ------------------------------

def _tree_by_name(skin):
    """{joint name: its parent joint's name} of a skin's skeleton as skinsynth exports it."""
    from skinsynth.pipeline.rig.skeleton import bone_names

    parents = skin.skeleton["parents"]
    names = bone_names(skin.skeleton)
    return {"root": None, **{names[b]: "root" if parents[b] < 0 else names[parents[b]] for b in range(len(names))}}


@pytest.mark.parametrize("source", ["skin.h5", "free.h5"])
def test_blender_imports_a_jointed_skins_glb_as_its_tree_and_plays_it_as_its_lbs(jointed_skins, tmp_path, source):
    """Blender's glTF import of a skin with a skeleton: an armature whose bones are parented as
    the tree, and the mesh it skins at three frames is skinsynth's LBS to 1e-4 of the diagonal."""
    from gltf_clients import in_gltf_axes, skin_of

    skin = skin_of(jointed_skins / source)
    out = tmp_path / "tree.glb"
    assert_ok(cli("export", jointed_skins / source, "-o", out, "-q"))
    assert probe("blender_gltf_probe.py", out, "--bones") == _tree_by_name(skin)
    frames = [0, len(skin.rotations) // 2, len(skin.rotations) - 1]
    played = probe("blender_gltf_probe.py", out, round(skin.fps), *frames)
    truth = _skinned(skin, skin.rotations, skin.translations)
    diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    (by_frame,) = played["animations"].values()
    for frame in frames:
        want = z_up(in_gltf_axes(truth[frame], skin.scene))
        error = np.abs(np.array(by_frame[str(frame)]) - want).max() / diagonal
        assert error < 1e-4, (source, frame, error)


@pytest.mark.parametrize("source", ["skin.h5", "free.h5"])
def test_blender_imports_a_jointed_skins_usdskel_as_its_tree_and_plays_it_as_its_lbs(jointed_skins, tmp_path, source):
    """export --as skel of a skin with a skeleton: Blender's USD import makes one armature whose
    bones are parented as the tree (the root joint on top), and plays it as skinsynth's LBS."""
    skin = read_skin(jointed_skins / source)
    usd = tmp_path / "tree.usdc"
    assert_ok(cli("export", jointed_skins / source, "-o", usd, "--as", "skel", "-q"))
    armatures = probe("blender_probe.py", usd, "--bones")
    assert len(armatures) == 1
    (bones,) = armatures.values()
    assert bones == _tree_by_name(skin)
    expected = lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations,
                             skin.translations)
    played = probe("blender_probe.py", usd, 0, 7, 19)
    diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    for frame, points in played.items():
        assert np.abs(np.array(points) - z_up(expected[int(frame)])).max() < 1e-4 * diagonal, (source, frame)


def _knees(skin):
    """The deepest bones in the middle of a chain of a skin's skeleton: jointed, under a parent bone,
    with a child, and the most bones above them (the walker's two knees, chain_0C_joint_01)."""
    parents, jointed = skin.skeleton["parents"], skin.skeleton["jointed"]
    depth = [0] * len(parents)
    for bone in range(len(parents)):
        above = parents[bone]
        while above >= 0:
            depth[bone], above = depth[bone] + 1, parents[above]
    middle = [b for b in range(len(parents)) if jointed[b] and parents[b] >= 0 and b in parents]
    return [b for b in middle if depth[b] == max(depth[m] for m in middle)]


def _bones_under(skin, bone):
    """{bone and every bone below it in the skeleton}."""
    parents, below = skin.skeleton["parents"], {bone}
    while grown := {b for b in range(len(parents)) if parents[b] in below} - below:
        below |= grown
    return below


def _weight_under(skin, bone):
    """Each vertex's total weight (V,) on ``bone`` and every bone below it in the skeleton."""
    return np.where(np.isin(skin.bone_indices, sorted(_bones_under(skin, bone))), skin.bone_weights, 0.0).sum(axis=1)


@pytest.mark.parametrize("source", ["skin.h5", "free.h5"])
@pytest.mark.parametrize("export", ["glb", "usdskel"])
@pytest.mark.parametrize("joint", ["knee", "hip"])
def test_blender_turning_a_jointed_skins_knee_or_hip_moves_what_hangs_below_it_and_nothing_else(
        jointed_skins, tmp_path, export, source, joint):
    """In Blender, after the import of a skin with a skeleton (.glb and UsdSkel), each knee (and each
    hip: the joint of the bone named ``leg_l_01``/``leg_r_01``, issue 44, whose leg is every bone
    below it) rotated by hand 30° in pose mode at rest moves every vertex with weight ≥ 0.5 on it
    and the bones below it, 5 % of the diagonal or more from the joint, by more than 1e-3 of the
    diagonal, and every
    vertex without weight there by less than 1e-6 (measured 0): a joint turns the bones under it,
    and only those. The import keeps skinsynth's vertex order (its rest is the skin's, vertex for
    vertex)."""
    from skinsynth.pipeline.rig.skeleton import bone_names
    from gltf_clients import in_gltf_axes, skin_of

    skin = skin_of(jointed_skins / source)
    names = bone_names(skin.skeleton)
    knees = _knees(skin) if joint == "knee" else [names.index("leg_l_01"), names.index("leg_r_01")]
    assert len(knees) == 2, [names[b] for b in knees]
    if joint == "hip":  # the whole leg hangs from its hip, and nothing else does
        for hip in knees:
            below = {names[b] for b in _bones_under(skin, hip)}
            assert below == {n for n in names if n.startswith(names[hip][:-2])}, below
    if export == "glb":
        assert_ok(cli("export", jointed_skins / source, "-o", tmp_path / "tree.glb", "-q"))
        played = probe("blender_gltf_probe.py", tmp_path / "tree.glb", "--turn", *[names[b] for b in knees])
        rest = z_up(in_gltf_axes(skin.rest_vertices, skin.scene))
    else:
        assert_ok(cli("export", jointed_skins / source, "-o", tmp_path / "tree.usdc", "--as", "skel", "-q"))
        played = probe("blender_probe.py", tmp_path / "tree.usdc", "--turn", *[names[b] for b in knees])
        rest = z_up(skin.rest_vertices)
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))
    assert np.abs(np.array(played["rest"]) - rest).max() < 1e-6 * diagonal  # the same vertices, in order
    own_diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    for knee in knees:
        weight = _weight_under(skin, knee)
        moved = np.array(played["moved"][names[knee]]) / diagonal
        # hung: carried mostly by the turned bones, 5 % of the diagonal or more from the joint (a 30°
        # turn about an axis across the limb moves it by at least 1.3 % there: w ≥ 0.5 of 2 sin 15° × 5 %)
        off = np.linalg.norm(skin.rest_vertices - skin.skeleton["joints"][knee], axis=1) > 0.05 * own_diagonal
        hung, still = (weight >= 0.5) & off, weight == 0.0
        assert hung.sum() >= 50 and still.sum() >= 50, (names[knee], hung.sum(), still.sum())
        assert moved[hung].min() > 1e-3, (names[knee], moved[hung].min())
        assert moved[still].max() < 1e-6, (names[knee], moved[still].max())


def test_blender_plays_the_samba_driven_by_a_real_take_as_computed(samba_marker_puppet, shared_data, tmp_path):
    """Issue 37: the UsdSkel rig of the samba puppet driven by the real take with its gap."""
    folder, _ = samba_marker_puppet
    take = shared_data / "mocap_c3d" / "kinematics_tennis_serve_nan.c3d"
    for out in ("take.usdc", "take.h5"):
        assert_ok(cli("play", folder / "puppet.h5", "-c", take, "-o", tmp_path / out, "-q"))
    with h5py.File(tmp_path / "take.h5") as f:
        expected = f["vertices"][()]  # one character: (F, V, 3)
    last = len(expected) - 1
    played = probe("blender_probe.py", tmp_path / "take.usdc", 0, last // 2, last)
    diagonal = np.linalg.norm(np.ptp(expected[0], axis=0))
    for frame, points in played.items():
        assert np.abs(np.array(points) - z_up(expected[int(frame)])).max() < 1e-4 * diagonal
