"""Alembic and FBX read through Blender (formats/blender.py, issue 67): caches a DCC writes (Blender
itself, tests/formats/blender_writer.py) read back to the capture, with their frame rate, units, up
axis and mesh name; two meshes chosen by path; fit-skin on a cache as on the arrays; and every way
it can go wrong refused in one line: a file Blender cannot read, no mesh, a topology that changes,
no Blender, Blender crashing or hanging.

The round trips need Blender's Python (``bpy``): ``SKINSYNTH_BLENDER``, or the ``.venv-blender``
``make test`` installs (``make blender``); they skip without one. The refusals without Blender run
everywhere."""

import json
import os
import pathlib
import stat
import subprocess

import numpy as np
import pytest

from cli_helpers import assert_ok, assert_user_error, cli
from skinsynth.formats.meshseq import read_mesh_sequence, write_array_sequence
from skinsynth.pipeline.inputs.examples import bending_bar

ROOT = pathlib.Path(__file__).resolve().parents[2]
WRITER = pathlib.Path(__file__).with_name("blender_writer.py")


def _blender_python():
    named = os.environ.get("SKINSYNTH_BLENDER")
    if named and os.path.basename(named).lower().startswith("python"):
        return named
    beside = ROOT / ".venv-blender" / "bin" / "python"
    return str(beside) if beside.is_file() else None


BLENDER = _blender_python()
needs_blender = pytest.mark.skipif(BLENDER is None, reason="no Python with bpy: make blender (or SKINSYNTH_BLENDER)")


@pytest.fixture
def blender(monkeypatch):
    monkeypatch.setenv("SKINSYNTH_BLENDER", BLENDER)
    return BLENDER


@pytest.fixture(scope="module")
def bar(tmp_path_factory):
    """A 12-frame bending bar at 30 fps (Y up, metres) as arrays."""
    folder = tmp_path_factory.mktemp("blender_bar")
    vertices, faces = bending_bar(frames=12, rings=8, segments=6)
    write_array_sequence(folder / "bar.npz", vertices, faces, 30.0)
    return folder / "bar.npz"


def written(capture, output, **options):
    """``capture`` (.npz) written by Blender to ``output`` (.abc/.fbx) with the writer's options."""
    run = subprocess.run([BLENDER, str(WRITER), str(capture), str(output), json.dumps(options)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and os.path.isfile(output), run.stderr[-3000:]
    return output


def _in_the_files_axes(vertices, up):
    """Y-up capture coordinates as a file with ``up`` holds them (Z up: (x, −z, y))."""
    return vertices if up == "Y" else np.stack([vertices[..., 0], -vertices[..., 2], vertices[..., 1]], axis=-1)


@needs_blender
@pytest.mark.parametrize("name, options, unit, up", [
    ("bar.abc", {}, 1.0, "Y"),
    ("bar_cm.fbx", {}, 0.01, "Y"),  # Blender's default FBX: centimetres, Y up
    ("bar_cm_z.fbx", {"up": "Z"}, 0.01, "Z"),  # a cm, Z-up, 30 fps cache
    ("bar_m.fbx", {"unit": "m"}, 1.0, "Y"),
])
def test_a_cache_blender_writes_reads_back_to_the_capture(blender, bar, tmp_path, name, options, unit, up):
    capture = np.load(bar)
    cache = written(bar, tmp_path / name, fps=30, **options)
    reported = []  # the progress Blender reports, frame by frame (fit-skin's bar)
    sequence = read_mesh_sequence(cache, progress=lambda done, total: reported.append((done, total)))
    assert reported and reported[-1] == (12, 12) and all(a <= b for (a, _), (b, _) in zip(reported, reported[1:]))
    diagonal = np.linalg.norm(np.ptp(capture["vertices"][0], axis=0))
    assert sequence.vertices.shape == capture["vertices"].shape and sequence.fps == 30.0
    assert sequence.scene.meters_per_unit == unit and sequence.scene.up_axis == up
    assert sequence.scene.prim_path == ("/Body/BodyShape" if name.endswith(".abc") else "Body")
    placed = sequence.vertices * unit  # metres, in the file's axes
    assert np.abs(placed - _in_the_files_axes(capture["vertices"], up)).max() <= 1e-6 * diagonal
    assert np.array_equal(np.sort(sequence.faces, axis=1), np.sort(capture["faces"], axis=1))


@pytest.fixture(scope="module")
def horse_fit(shared_data, tmp_path_factory):
    """The shared horse gallop's .npz and fit-skin's --json summary of it (12 bones, seed 0), once."""
    capture = shared_data / "horse_gallop" / "horse_gallop.npz"
    if not capture.exists():
        pytest.skip(f"the horse gallop is needed at {capture}")
    out = tmp_path_factory.mktemp("horse_fit") / "npz.h5"
    return capture, json.loads(assert_ok(cli("fit-skin", capture, "-o", out, "--bones", 12, "--seed", 0,
                                             "--json")).stdout)


@needs_blender
@pytest.mark.slow
@pytest.mark.parametrize("name", ["horse.abc", "horse.fbx"])
def test_fit_skin_on_a_cache_gives_the_skin_of_the_capture(blender, horse_fit, tmp_path, name):
    """The shared horse gallop written by Blender, read back to its vertices (1e-6 of the
    diagonal), and fit-skin on it gives the fit of the capture's .npz: the vertices differ by
    float32 rounding only, and the fit's error agrees to 1e-6 of the diagonal; the rate kept."""
    capture, arrays = horse_fit
    cache = written(capture, tmp_path / name, fps=24, unit="m")
    frames = np.load(capture)["vertices"]
    sequence = read_mesh_sequence(cache)
    diagonal = np.linalg.norm(np.ptp(frames[0], axis=0))
    assert sequence.vertices.shape == frames.shape and sequence.fps == 24.0
    assert np.abs(sequence.vertices * sequence.scene.meters_per_unit - frames).max() <= 1e-6 * diagonal
    fit = json.loads(assert_ok(cli("fit-skin", cache, "-o", tmp_path / "cache.h5", "--bones", 12, "--seed", 0,
                                   "--json")).stdout)
    assert abs(fit["rmse_over_diagonal"] - arrays["rmse_over_diagonal"]) <= 1e-6
    assert fit["fps"] == 24.0 and fit["frames"] == len(frames)


@needs_blender
def test_two_meshes_are_chosen_by_path(blender, bar, tmp_path):
    cache = written(bar, tmp_path / "two.abc", fps=30, second=True)
    refused = assert_user_error(cli("fit-skin", cache, "-o", tmp_path / "s.h5", "--bones", 2, "-q"))
    assert "2 meshes (/Body/BodyShape, /Prop/PropShape): choose one with --prim" in refused
    assert read_mesh_sequence(cache, prim="/Body/BodyShape").vertices.shape[1] == 50
    assert read_mesh_sequence(cache, prim="/Prop/PropShape").vertices.shape[1] == 3
    missing = assert_user_error(cli("fit-skin", cache, "--prim", "/Nope", "-o", tmp_path / "s.h5", "--bones", 2, "-q"))
    assert "no mesh '/Nope' (it has /Body/BodyShape, /Prop/PropShape)" in missing
    assert not (tmp_path / "s.h5").exists()


@needs_blender
def test_what_blender_cannot_read_is_one_line(blender, bar, tmp_path):
    whole = written(bar, tmp_path / "whole.abc", fps=30)
    cut = tmp_path / "cut.abc"
    cut.write_bytes(whole.read_bytes()[:len(whole.read_bytes()) // 2])
    text = tmp_path / "text.abc"
    text.write_text("not an archive\n")
    empty = tmp_path / "empty.abc"
    empty.write_bytes(b"")
    nothing = written(bar, tmp_path / "nothing.fbx", fps=30, empty=True)
    growing = written(bar, tmp_path / "growing.abc", fps=30, build=True)
    not_fbx = tmp_path / "text.fbx"
    not_fbx.write_text("; FBX 7.4.0 project file, truncated\n")
    for source, needle in ((cut, "cut.abc: "), (text, "not an Alembic archive"), (empty, "empty file"),
                           (nothing, "no mesh in it"), (growing, "the mesh's topology changes at frame"),
                           (not_fbx, "text.fbx: ")):
        line = assert_user_error(cli("fit-skin", source, "-o", tmp_path / "s.h5", "--bones", 2, "-q"))
        assert needle in line, line
    assert not (tmp_path / "s.h5").exists()


def _fake_blender(folder, body):
    """A stand-in for Blender's Python: a shell script named python."""
    script = folder / "python"
    script.write_text("#!/bin/sh\n" + body + "\n")
    script.chmod(script.stat().st_mode | stat.S_IXUSR)
    return script


@pytest.mark.parametrize("body, needle", [
    ("kill -SEGV $$", "Blender failed reading it (exit status -11"),
    ("echo 'Error: EXCEPTION_ACCESS_VIOLATION' >&2; exit 1", "(exit status 1: Error: EXCEPTION_ACCESS_VIOLATION)"),
    ("sleep 30 & wait", "Blender did not finish reading it within 1 s (SKINSYNTH_BLENDER_TIMEOUT)"),  # a child too
])
def test_blender_crashing_or_hanging_is_one_line(tmp_path, monkeypatch, body, needle):
    monkeypatch.setenv("SKINSYNTH_BLENDER", str(_fake_blender(tmp_path, body)))
    monkeypatch.setenv("SKINSYNTH_BLENDER_TIMEOUT", "1")
    cache = tmp_path / "take.abc"
    cache.write_bytes(b"Ogawa" + bytes(64))
    line = assert_user_error(cli("fit-skin", cache, "-o", tmp_path / "s.h5", "--bones", 2, "-q"))
    assert line.startswith(f"skinsynth: error: {cache}: ") and needle in line, line
    assert not (tmp_path / "s.h5").exists()


def test_a_time_limit_that_is_no_number_is_one_line(tmp_path, monkeypatch):
    monkeypatch.setenv("SKINSYNTH_BLENDER", str(_fake_blender(tmp_path, "exit 0")))
    monkeypatch.setenv("SKINSYNTH_BLENDER_TIMEOUT", "soon")
    cache = tmp_path / "take.abc"
    cache.write_bytes(b"Ogawa" + bytes(64))
    line = assert_user_error(cli("fit-skin", cache, "-o", tmp_path / "s.h5", "--bones", 2, "-q"))
    assert "SKINSYNTH_BLENDER_TIMEOUT must be a positive number of seconds (got 'soon')" in line


def test_without_blender_reading_abc_or_fbx_says_what_to_install(tmp_path, monkeypatch):
    monkeypatch.delenv("SKINSYNTH_BLENDER", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))  # no blender on it
    from skinsynth.formats import blender

    monkeypatch.setattr(blender.importlib.util, "find_spec", lambda name: None)  # and no bpy here
    for name in ("take.abc", "take.fbx"):
        (tmp_path / name).write_bytes(b"Ogawa" + bytes(64))
        line = assert_user_error(cli("fit-skin", tmp_path / name, "-o", tmp_path / "s.h5", "--bones", 2, "-q"))
        assert "without Blender: skinsynth reads and writes them through Blender: pip install bpy" in line
        assert "SKINSYNTH_BLENDER" in line
    missing = _fake_blender(tmp_path, "exit 0")
    missing.unlink()
    monkeypatch.setenv("SKINSYNTH_BLENDER", str(missing))
    line = assert_user_error(cli("fit-skin", tmp_path / "take.abc", "-o", tmp_path / "s.h5", "--bones", 2, "-q"))
    assert "cannot run Blender" in line
    assert not (tmp_path / "s.h5").exists()


# -- Alembic out: export -o X.abc --------------------------------------------------------------------

@pytest.fixture(scope="module")
def bar_skin(bar, tmp_path_factory):
    folder = tmp_path_factory.mktemp("blender_skin")
    assert_ok(cli("fit-skin", bar, "-o", folder / "skin.h5", "--bones", 4, "--seed", 0, "-q"))
    return folder / "skin.h5"


@needs_blender
@pytest.mark.parametrize("up", [None, "Z"])
def test_export_writes_an_alembic_point_cache_blender_reads_back(blender, bar_skin, tmp_path, up):
    """export -o X.abc: the skin's reconstruction as Blender's exporter writes it, read back by
    Blender to 1e-6 of the diagonal, with its frames, rate and start frame (Alembic is Y up: a
    --up-axis Z export comes back turned as Blender turns it)."""
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.gpu import lbs_reference

    out = tmp_path / "bar.abc"
    summary = json.loads(assert_ok(cli("export", bar_skin, "-o", out, "--json", *(["--up-axis", up] if up else [])))
                         .stdout)
    assert summary["kind"] == "Alembic point cache" and os.listdir(tmp_path) == ["bar.abc"]
    skin = read_skin(bar_skin)
    expected = lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations,
                             skin.translations)
    if up == "Z":  # written as Blender writes its Z-up world: (x, y, z) -> (x, z, -y), read back Y up
        expected = np.stack([expected[..., 0], expected[..., 2], -expected[..., 1]], axis=-1)
    sequence = read_mesh_sequence(out)
    diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    assert sequence.vertices.shape == expected.shape and sequence.fps == skin.fps
    assert sequence.scene.start_frame == skin.scene.start_frame and sequence.scene.up_axis == "Y"
    assert np.abs(sequence.vertices - expected).max() <= 1e-6 * diagonal
    assert np.array_equal(np.sort(sequence.faces, axis=1), np.sort(skin.faces, axis=1))


def test_export_to_alembic_without_blender_is_refused_before_any_work(bar_skin, tmp_path, monkeypatch):
    monkeypatch.delenv("SKINSYNTH_BLENDER", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))
    from skinsynth.formats import blender

    monkeypatch.setattr(blender.importlib.util, "find_spec", lambda name: None)
    line = assert_user_error(cli("export", bar_skin, "-o", tmp_path / "bar.abc"), folder=tmp_path)
    assert "cannot write .abc without Blender" in line
    refused = assert_user_error(cli("export", bar_skin, "-o", tmp_path / "bar.abc", "--as", "skel"), folder=tmp_path)
    assert "an Alembic file is a point cache" in refused


# -- FBX out: export -o X.fbx ------------------------------------------------------------------------

PARENTS_PROBE = """
import bpy, json, sys
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.fbx(filepath=sys.argv[1], anim_offset=0.0)
rigs = [o for o in bpy.context.scene.objects if o.type == 'ARMATURE']
print('PROBE' + json.dumps({b.name: (b.parent.name if b.parent else None) for r in rigs for b in r.data.bones}))
"""


def _armature_parents(fbx):
    """{bone: parent or None} of the armature Blender imports from ``fbx``."""
    run = subprocess.run([BLENDER, "-c", PARENTS_PROBE, str(fbx)], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and "PROBE" in run.stdout, run.stderr[-3000:]
    return json.loads(run.stdout.split("PROBE", 1)[1])


@needs_blender
def test_export_fbx_of_a_jointed_skin_is_an_armature_blender_plays_as_skinsynth(blender, jointed_skins, tmp_path):
    """export -o X.fbx of a --skeleton skin: Blender imports an armature whose parents are the
    skin's tree, bone for bone by joint name, and plays it to 1e-4 of the diagonal of skinsynth's
    own linear blend skinning (measured 1e-6 on the samba's; a float32 pose per frame)."""
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.gpu import lbs_reference

    out = tmp_path / "walker.fbx"
    summary = json.loads(assert_ok(cli("export", jointed_skins / "skin.h5", "-o", out, "--json")).stdout)
    skin = read_skin(jointed_skins / "skin.h5")
    assert summary["kind"] == "FBX skin" and summary["joints"] == skin.rotations.shape[1]
    names, parents = [str(n) for n in skin.skeleton["names"]], np.asarray(skin.skeleton["parents"])
    assert _armature_parents(out) == {names[b]: (names[p] if p >= 0 else None) for b, p in enumerate(parents)}
    expected = lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations,
                             skin.translations)
    played = read_mesh_sequence(out)
    diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    assert played.vertices.shape == expected.shape and played.fps == skin.fps
    assert np.abs(played.vertices * played.scene.meters_per_unit - expected).max() <= 1e-4 * diagonal


@needs_blender
def test_export_fbx_keeps_a_centimetre_z_up_skin_as_it_is(blender, jointed_skins, tmp_path):
    """The walker's fit recorded Z up in centimetres, as FBX: the file states centimetres and Z up,
    and Blender plays it back in them to 1e-6 of the diagonal."""
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.gpu import lbs_reference

    assert_ok(cli("export", jointed_skins / "zup.h5", "-o", tmp_path / "zup.fbx", "-q"))
    skin = read_skin(jointed_skins / "zup.h5")
    played = read_mesh_sequence(tmp_path / "zup.fbx")
    assert played.scene.meters_per_unit == 0.01 and played.scene.up_axis == "Z"
    expected = lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations,
                             skin.translations)
    diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    assert np.abs(played.vertices - expected).max() <= 1e-6 * diagonal


@needs_blender
def test_export_fbx_of_a_synthesis_plays_as_its_point_cache(blender, jointed_skins, tmp_path):
    """A synthesized animation as FBX (the skin's bones, moved as synthesize moves them) plays in
    Blender and in three.js as skinsynth's own USD point cache of it does, to 1e-4 of the diagonal;
    --as points to an .fbx is refused before any work."""
    assert_ok(cli("build-graph", jointed_skins / "skin.h5", "-o", tmp_path / "graph.h5", "-q"))
    assert_ok(cli("synthesize", tmp_path / "graph.h5", "-o", tmp_path / "bones.h5", "-n", 1, "-m", 40, "--seed", 0,
                  "-q"))
    assert_ok(cli("export", tmp_path / "bones.h5", "--animation", 0, "-o", tmp_path / "walk.fbx", "-q"))
    assert_ok(cli("export", tmp_path / "bones.h5", "--animation", 0, "-o", tmp_path / "walk.usdc", "--as", "points",
                  "-q"))
    played, cache = read_mesh_sequence(tmp_path / "walk.fbx"), read_mesh_sequence(tmp_path / "walk.usdc")
    diagonal = np.linalg.norm(np.ptp(cache.vertices[0], axis=0))
    assert played.vertices.shape == cache.vertices.shape == (40, cache.vertices.shape[1], 3)
    assert np.abs(played.vertices * played.scene.meters_per_unit - cache.vertices).max() <= 1e-4 * diagonal
    frames = [0, 20, 39]  # three.js plays it so too
    corners = read_skin_faces(tmp_path / "bones.h5")
    three = _three_positions(tmp_path / "walk.fbx", cache.fps, frames, tmp_path)
    assert np.abs(three - cache.vertices[frames][:, corners]).max() <= 1e-4 * diagonal
    refused = assert_user_error(cli("export", tmp_path / "bones.h5", "--animation", 0, "-o", tmp_path / "w.fbx",
                                    "--as", "points"))
    assert "an FBX file is a skinned mesh" in refused and not (tmp_path / "w.fbx").exists()


def read_skin_faces(path):
    """The face corners' vertex ids (3T,) of the skin a model file carries."""
    from skinsynth.formats.skin_file import read_skin

    return np.asarray(read_skin(path).faces).ravel()


def _three_positions(fbx, fps, frames, tmp_path):
    """three.js's FBXLoader playing ``fbx`` at ``frames`` (tests/contracts/js/fbx_three.mjs): (frames, corners, 3),
    a vertex per triangle corner, in face order."""
    import shutil

    js = ROOT / "tests" / "contracts" / "js"
    if shutil.which("node") is None or not (js / "node_modules" / "three").is_dir():
        pytest.skip("node and tests/contracts/js/node_modules (three) are needed: run make setup")
    out = tmp_path / "three.bin"
    run = subprocess.run(["node", str(js / "fbx_three.mjs"), str(fbx), str(out), str(fps), *map(str, frames)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    return np.fromfile(out, dtype=np.float32).reshape(len(frames), -1, 3)


@needs_blender
def test_three_js_fbx_loader_plays_the_exported_fbx_as_skinsynth(blender, jointed_skins, tmp_path):
    """The walker's jointed skin as FBX, played by three.js (FBXLoader, AnimationMixer, CPU skinning)
    at its first, middle and last frames: within 1e-4 of the diagonal of skinsynth's own linear
    blend skinning (the samba's measured 5.3e-7)."""
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.gpu import lbs_reference

    assert_ok(cli("export", jointed_skins / "skin.h5", "-o", tmp_path / "walker.fbx", "-q"))
    skin = read_skin(jointed_skins / "skin.h5")
    frames = [0, len(skin.rotations) // 2, len(skin.rotations) - 1]
    played = _three_positions(tmp_path / "walker.fbx", skin.fps, frames, tmp_path)
    expected = lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations[frames],
                             skin.translations[frames])[:, skin.faces.ravel()]
    diagonal = np.linalg.norm(np.ptp(skin.rest_vertices, axis=0))
    assert played.shape == expected.shape
    assert np.abs(played - expected).max() <= 1e-4 * diagonal


@needs_blender
def test_the_fbx_carries_the_meshs_uvs(blender, tmp_path):
    """A skin fitted to OBJ frames with material UVs (tests/uv_meshes.py): its FBX carries them,
    and three.js reads each face corner's (u, v) as the skin has it."""
    from uv_meshes import uv_bar, write_obj_frames

    from skinsynth.formats.skin_file import read_skin

    write_obj_frames(tmp_path / "frames", *uv_bar())
    assert_ok(cli("fit-skin", tmp_path / "frames", "-o", tmp_path / "skin.h5", "--bones", 4, "--iterations", 4, "-q"))
    assert_ok(cli("export", tmp_path / "skin.h5", "-o", tmp_path / "uv.fbx", "-q"))
    skin = read_skin(tmp_path / "skin.h5")
    assert skin.face_uvs is not None
    _three_positions(tmp_path / "uv.fbx", skin.fps, [0], tmp_path)
    uvs = np.fromfile(tmp_path / "three.bin.uv", dtype=np.float32).reshape(-1, 2)
    assert np.abs(uvs - skin.face_uvs.reshape(-1, 2)).max() <= 1e-6
