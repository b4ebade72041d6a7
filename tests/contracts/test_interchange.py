"""Units, up axis, frame range, frame rate and prim names survive from the input to every USD
skinsynth writes (read back with pxr, independently of skinsynth's own readers)."""

import os
import subprocess
import sys

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdSkel

from capture_cases import FPS, FRAMES, START, production_capture
from cli_helpers import assert_ok, assert_user_error, cli

@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    from skinsynth.pipeline.inputs.examples import bending_bar

    root = tmp_path_factory.mktemp("interchange")
    vertices, faces = bending_bar(frames=FRAMES, rings=10, segments=8, cycles=2)
    production_capture(root / "capture.usda", vertices, faces)
    fitted = assert_ok(cli("fit-skin", root / "capture.usda", "-o", root / "skin.h5", "--bones", 4, "--iterations", 8))
    assert f"scene: 0.01 m per unit, Z up, frames {START}–{START + FRAMES - 1}, /World/body at 25 fps" in fitted.stdout
    assert_ok(cli("select-controls", root / "skin.h5", "-o", root / "controls.h5", "--count", 6, "-q"))
    assert_ok(cli("train-kcca", root / "controls.h5", "-o", root / "puppet.h5", "-q", "--correctives", "off"))
    assert_ok(cli("build-graph", root / "skin.h5", "-o", root / "graph.h5", "--min-segment", 4, "-q"))
    return root


def assert_stage(path, frames=FRAMES, meters_per_unit=0.01, up_axis="Z", start=START):
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(meters_per_unit)
    assert UsdGeom.GetStageUpAxis(stage) == (UsdGeom.Tokens.z if up_axis == "Z" else UsdGeom.Tokens.y)
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (start, start + frames - 1)
    assert stage.GetTimeCodesPerSecond() == FPS and stage.GetFramesPerSecond() == FPS
    assert stage.GetDefaultPrim().IsValid()
    return stage


def test_export_points_keeps_units_axis_frames_and_the_prim_path(chain, tmp_path):
    assert_ok(cli("export", chain / "skin.h5", "-o", tmp_path / "points.usda", "--as", "points"))
    stage = assert_stage(tmp_path / "points.usda")
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/body"))
    assert mesh and stage.GetPrimAtPath("/World").IsA(UsdGeom.Xform)
    assert stage.GetDefaultPrim().GetPath() == "/World"
    times = mesh.GetPointsAttr().GetTimeSamples()
    assert times[0] == START and times[-1] == START + FRAMES - 1 and len(times) == FRAMES
    # the coordinates stay in the input's numbers (centimetres)
    original = Usd.Stage.Open(str(chain / "capture.usda"))  # held: its prims die with it
    first = np.asarray(UsdGeom.Mesh(original.GetPrimAtPath("/World/body")).GetPointsAttr().Get(Usd.TimeCode(START)))
    exported = np.asarray(mesh.GetPointsAttr().Get(Usd.TimeCode(START)))
    assert np.abs(exported - first).max() < 0.05 * np.ptp(first, axis=0).max()


def test_export_skel_keeps_them_with_the_mesh_at_its_path_under_a_skel_root(chain, tmp_path):
    from skinsynth.formats.usd import read_skel_points

    assert_ok(cli("export", chain / "skin.h5", "-o", tmp_path / "skel.usda"))
    stage = assert_stage(tmp_path / "skel.usda")
    assert stage.GetPrimAtPath("/World").IsA(UsdSkel.Root)
    assert stage.GetPrimAtPath("/World/body").IsA(UsdGeom.Mesh)
    assert read_skel_points(tmp_path / "skel.usda").shape[0] == FRAMES  # UsdSkel skins START…END


def test_play_and_synthesize_state_the_input_scene(chain, tmp_path):
    for kind in ("skel", "points"):
        out = tmp_path / f"play_{kind}.usda"
        assert_ok(cli("play", chain / "puppet.h5", "-c", chain / "capture.usda", "-o", out, "--as", kind,
                      "--instances", 2, "--device", "cpu"))
        stage = assert_stage(out)
        assert stage.GetPrimAtPath("/characters/character_001").IsValid()
    assert_ok(cli("synthesize", chain / "graph.h5", "-o", tmp_path / "s.h5", "-n", 2, "-m", 30, "--seed", 1,
                  "--usd", tmp_path / "each", "--crowd", tmp_path / "crowd.usda"))
    stage = assert_stage(tmp_path / "each" / "animation_0001.usdc", frames=30)
    assert stage.GetPrimAtPath("/World/body").IsA(UsdGeom.Mesh)
    stage = assert_stage(tmp_path / "crowd.usda", frames=30)
    assert stage.GetPrimAtPath("/characters/animation_0001").IsValid()


def test_array_inputs_take_their_scene_by_option_and_print_the_defaults(tmp_path):
    from skinsynth.formats.meshseq import write_array_sequence
    from skinsynth.pipeline.inputs.examples import bending_bar

    vertices, faces = bending_bar(frames=12, rings=6, segments=6)
    write_array_sequence(tmp_path / "bar.npz", vertices, faces, FPS)
    fitted = assert_ok(cli("fit-skin", tmp_path / "bar.npz", "-o", tmp_path / "default.h5", "--bones", 2,
                           "--iterations", 3))
    assert "scene: 1 m per unit, Y up, frames 0–11, /mesh at 25 fps" in fitted.stdout
    assert_ok(cli("fit-skin", tmp_path / "bar.npz", "-o", tmp_path / "skin.h5", "--bones", 2, "--iterations", 3,
                  "--meters-per-unit", 0.01, "--up-axis", "Z", "--start-frame", START, "-q"))
    assert_ok(cli("export", tmp_path / "skin.h5", "-o", tmp_path / "out.usda", "--as", "points"))
    stage = assert_stage(tmp_path / "out.usda", frames=12)
    assert stage.GetPrimAtPath("/mesh").IsA(UsdGeom.Mesh)
    assert_ok(cli("export", tmp_path / "skin.h5", "-o", tmp_path / "y.usda", "--as", "points", "--up-axis", "y"))
    assert_stage(tmp_path / "y.usda", frames=12, up_axis="Y")  # lower case is the same axis (issue 68)
    assert_user_error(cli("fit-skin", tmp_path / "bar.npz", "-o", tmp_path / "bad.h5", "--bones", 2,
                          "--meters-per-unit", -1), "--meters-per-unit")



@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (Linux)")
def test_operating_system_errors_are_one_line_without_traceback(chain, tmp_path):
    """stdout on a full device, stdout into a pipe nobody reads, and a folder where the output
    file should go: one line, exit 2, no traceback, nothing written."""
    command = [sys.executable, "-c", "import sys; from skinsynth.cli.main import main; sys.argv[0] = 'skinsynth'; "
               "main()", "inspect", str(chain / "skin.h5"), "--json"]
    with open("/dev/full", "w") as full:
        done = subprocess.run(command, stdout=full, stderr=subprocess.PIPE, text=True)
    assert done.returncode == 2 and done.stderr.splitlines() == ["skinsynth: error: stdout: No space left on device"]
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before anything is written
    try:
        done = subprocess.run(command, stdout=write_end, stderr=subprocess.PIPE, text=True)
    finally:
        os.close(write_end)
    assert done.returncode == 2 and len(done.stderr.splitlines()) == 1 and "pipe closed" in done.stderr
    (tmp_path / "out.usda").mkdir()
    assert_user_error(cli("export", chain / "skin.h5", "-o", tmp_path / "out.usda"), "out.usda")


def test_every_command_prints_one_json_object_or_nothing_when_quiet(chain, tmp_path):
    import json

    commands = {
        "example": ["example", "bending-bar", "-o", tmp_path / "bar.npz", "--frames", 12],
        "fit-skin": ["fit-skin", tmp_path / "bar.npz", "-o", tmp_path / "s.h5", "--bones", 2, "--iterations", 2],
        "select-controls": ["select-controls", chain / "skin.h5", "-o", tmp_path / "c.h5", "--count", 4],
        "train-kcca": ["train-kcca", chain / "controls.h5", "-o", tmp_path / "p.h5", "--correctives", "off"],
        "build-graph": ["build-graph", chain / "skin.h5", "-o", tmp_path / "g.h5", "--min-segment", 4],
        "export": ["export", chain / "skin.h5", "-o", tmp_path / "e.usda"],
        "play": ["play", chain / "puppet.h5", "-c", chain / "capture.usda", "-o", tmp_path / "o.h5"],
        "synthesize": ["synthesize", chain / "graph.h5", "-o", tmp_path / "y.h5", "-n", 2, "-m", 20],
        "evaluate": ["evaluate", chain / "puppet.h5"],
        "inspect": ["inspect", chain / "puppet.h5"],
    }
    keys = {"fit-skin": "rmse_over_diagonal", "select-controls": "vertex_indices", "train-kcca": "correctives_reason",
            "build-graph": "components", "export": "kind", "play": "frames_per_second", "synthesize": "animations",
            "evaluate": "kcca", "inspect": "stage", "example": "vertices"}
    for name, args in commands.items():
        quiet = assert_ok(cli(*args, "--quiet"))
        assert quiet.stdout == "", (name, quiet.stdout)
        printed = assert_ok(cli(*args, "--json")).stdout
        assert printed.count("\n") == 1, (name, printed)
        assert keys[name] in json.loads(printed), name


def test_inspect_json_has_stage_keys_provenance_parameters_and_input_hashes(chain):
    import json

    controls = json.loads(assert_ok(cli("inspect", chain / "controls.h5", "--json")).stdout)
    assert len(controls["control_vertex_indices"]) == 6 == len(controls["control_reasons"])
    assert controls["prim_path"] == "/World/body" and controls["meters_per_unit"] == 0.01
    puppet = json.loads(assert_ok(cli("inspect", chain / "puppet.h5", "--json")).stdout)
    for key in ("kernel", "kernel_scale", "global_motion", "translation_prior", "correctives_reason",
                "regularization_per_bone", "bases"):
        assert key in puppet, key
    fit = puppet["provenance"][0]
    assert fit["stage"] == "skin" and fit["parameters"]["bones"] == 4 and fit["parameters"]["up_axis"] == "Z"
    assert fit["inputs"][0]["path"].endswith("capture.usda") and len(fit["inputs"][0]["sha256"]) == 64


def test_play_linear_skinning_is_what_usdskel_plays_and_the_reference_computes(chain, tmp_path):
    import h5py

    from skinsynth.formats.puppet_file import read_puppet

    from skinsynth.pipeline.puppet import puppet_from_record
    from skinsynth.formats.usd import read_skel_points
    from skinsynth.pipeline.puppet.puppet import predict_vertices

    puppet_path = tmp_path / "corrected.h5"
    assert_ok(cli("train-kcca", chain / "controls.h5", "-o", puppet_path, "-q", "--correctives", "1e-4"))
    args = ["play", puppet_path, "-c", chain / "capture.usda", "--skinning", "linear", "--device", "cpu"]
    assert_ok(cli(*args, "-o", tmp_path / "linear.h5"))
    skel = assert_ok(cli(*args, "-o", tmp_path / "linear.usda"))
    assert "warning" not in skel.stderr
    stage = Usd.Stage.Open(str(tmp_path / "linear.usda"))
    mesh = stage.GetPrimAtPath("/characters/character_000/Mesh")
    assert UsdSkel.BindingAPI(mesh).GetSkinningMethodAttr().Get() == "classicLinear"
    record, _, skin = read_puppet(str(puppet_path))
    puppet = puppet_from_record(record)
    reference = predict_vertices(puppet, skin.examples[:, puppet.control_indices], skinning="linear")
    with h5py.File(tmp_path / "linear.h5") as f:
        baked = f["vertices"][()].reshape(reference.shape)  # one character
    scale = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    assert np.abs(baked - reference).max() < 1e-5 * scale
    assert np.abs(read_skel_points(tmp_path / "linear.usda") - reference).max() < 1e-5 * scale
    dual = assert_ok(cli("play", puppet_path, "-c", chain / "capture.usda", "-o", tmp_path / "dq.usda",
                         "--skinning", "dual-quaternion"))
    assert "Blender" in dual.stderr and "--skinning linear" in dual.stderr
