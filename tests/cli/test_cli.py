"""The command line as a user meets it: the happy path, every bad input, determinism, round trips.

Most cases run in-process through click's CliRunner (stderr kept apart from stdout); a few run
the installed console script in a subprocess, where anything native code prints on file
descriptor 2 (warp's banner, CUDA driver warnings) would show too.

The data is tiny (a 50-vertex bending bar, 12 frames, 3 bones, a few iterations), so the whole
file runs in seconds.
"""

import json
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np
import pytest

from skinsynth.formats.exr import read_vat
from skinsynth.formats.meshseq import write_array_sequence
from skinsynth.formats.model import FORMAT_VERSION, write_model
from skinsynth.formats.skin_file import read_skin
from skinsynth.formats.usd import read_points_cache, read_skel_points
from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.inputs.examples import bending_bar

from cli_helpers import assert_folder_holds, assert_ok, assert_user_error, cli

FRAMES, RINGS, SEGMENTS = 12, 8, 6
VERTICES = RINGS * SEGMENTS + 2  # 50: the rings plus one centre vertex per cap
BONES = 3
FIT = ["--bones", str(BONES), "--iterations", "6"]
SCRIPT = os.path.join(os.path.dirname(sys.executable), "skinsynth")


# ---------------------------------------------------------------- helpers


def write_obj(path, vertices, faces):
    with open(path, "w") as handle:
        handle.write("".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in vertices))
        handle.write("".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces))


def write_obj_frames(folder, vertices, faces, count=4):
    folder.mkdir(parents=True, exist_ok=True)
    for frame in range(count):
        write_obj(folder / f"frame{frame + 1}.obj", vertices[frame], faces)
    return folder


def h5_datasets(path):
    """{name: (dtype, shape, bytes, filters)} of every dataset, and {object: {attr: value}}."""
    datasets, attributes = {}, {}

    def visit(name, item):
        attributes[name] = {k: v if isinstance(v, (str, bytes)) else np.asarray(v).tolist()
                            if np.asarray(v).dtype.kind == "O" else np.asarray(v).tobytes()  # strings: values, not pointers
                            for k, v in item.attrs.items()}
        if isinstance(item, h5py.Dataset):
            datasets[name] = (item.dtype.str, item.shape, item[()].tobytes(),
                              item.compression, item.compression_opts, item.shuffle, item.chunks)

    with h5py.File(path, "r") as f:
        attributes["/"] = dict(f.attrs)
        f.visititems(visit)
    return datasets, attributes


# ---------------------------------------------------------------- shared data


@pytest.fixture(scope="module")
def data(stage_files):
    """bar.npz (what ``skinsynth example bending-bar --frames FRAMES --rings RINGS --segments SEGMENTS``
    writes) and skin.h5 fitted to it with FIT; tests must not modify them."""
    stages = stage_files(frames=FRAMES, rings=RINGS, segments=SEGMENTS, bones=BONES, iterations=FIT[-1])
    return {"folder": stages.folder, "bar": stages / "bar.npz", "skin": stages / "skin.h5"}


@pytest.fixture
def out(tmp_path):
    """An empty output folder; tests check that failures leave it empty."""
    folder = tmp_path / "out"
    folder.mkdir()
    return folder


@pytest.fixture
def inputs(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    return folder


# ---------------------------------------------------------------- happy path


def test_example_fit_inspect_export(tmp_path, out):
    bar, skin = tmp_path / "bar.npz", tmp_path / "skin.h5"
    done = assert_ok(cli("example", "bending-bar", "-o", bar, "--frames", FRAMES, "--rings", RINGS,
                         "--segments", SEGMENTS))
    assert bar.is_file() and "wrote" in done.stdout

    done = assert_ok(cli("fit-skin", bar, "-o", skin, "--bones", BONES, "--iterations", 6))
    assert skin.is_file()
    assert f"{BONES} bones, {VERTICES} vertices, {FRAMES} frames" in done.stdout and "RMSE" in done.stdout

    text = assert_ok(cli("inspect", skin)).stdout
    for line in ("stage: skin", f"bones: {BONES}", f"frames: {FRAMES}", f"vertices: {VERTICES}", "rmse: ",
                 "provenance: skin"):
        assert line in text, text

    summary = json.loads(assert_ok(cli("inspect", skin, "--json")).stdout)
    assert summary["stage"] == "skin" and summary["format_version"] == FORMAT_VERSION
    assert (summary["bones"], summary["frames"], summary["vertices"]) == (BONES, FRAMES, VERTICES)
    assert np.isfinite(summary["rmse"]) and summary["rmse"] >= 0.0
    assert 0.0 <= summary["rmse_over_diagonal"] < 0.1
    assert summary["provenance"][0]["stage"] == "skin"

    for name, extra in (("points.usda", ["--as", "points"]), ("skel.usdc", ["--as", "skel"]), ("vat.exr", [])):
        done = assert_ok(cli("export", skin, "-o", out / name, "--device", "cpu", *extra))
        assert (out / name).stat().st_size > 0 and "wrote" in done.stdout
    assert_folder_holds(out, ["points.usda", "skel.usdc", "vat.exr"])


def test_fit_skin_reads_obj_folder_and_glob(tmp_path, out):
    vertices, faces = bending_bar(frames=4, rings=4, segments=4)
    folder = write_obj_frames(tmp_path / "frames", vertices, faces)
    for name, spec in (("folder.h5", folder), ("glob.h5", folder / "frame*.obj")):
        assert_ok(cli("fit-skin", spec, "-o", out / name, "--bones", 2, "--iterations", 2, "-q"))
        summary = json.loads(assert_ok(cli("inspect", out / name, "--json")).stdout)
        assert (summary["frames"], summary["vertices"]) == (4, len(vertices[0]))


COMMANDS = ["fit-skin", "inspect", "export", "example"]


@pytest.mark.parametrize("command", [None] + COMMANDS)
def test_help_works(command):
    args = ([command] if command else []) + ["--help"]
    text = assert_ok(cli(*args)).stdout
    assert text.startswith("Usage: skinsynth")
    if command is None:
        assert all(c in text for c in COMMANDS)


@pytest.mark.parametrize("command", [
    None, "fit-skin", "export",
    "inspect",
    "example",
])
def test_help_shows_examples(command):
    text = assert_ok(cli(*(([command] if command else []) + ["--help"]))).stdout
    body = [line.strip() for line in text.splitlines() if not line.startswith("Usage:")]
    wanted = "skinsynth " + (command or "")
    assert any(line.startswith(wanted) for line in body), text


# ---------------------------------------------------------------- bad input: fit-skin


def bar_frames(**kwargs):
    return bending_bar(frames=kwargs.pop("frames", 3), rings=kwargs.pop("rings", 4), segments=4)


def case_missing(inputs):
    return inputs / "nope.npz", ["nope.npz", "no such file"]


def case_empty_folder(inputs):
    (inputs / "empty").mkdir()
    return inputs / "empty", [str(inputs / "empty"), "no .obj"]


def case_glob_nothing(inputs):
    return inputs / "take*.obj", ["take*.obj", "matches no files"]


def case_vertex_count_differs(inputs):
    vertices, faces = bar_frames()
    folder = write_obj_frames(inputs / "frames", vertices, faces, count=3)
    other, other_faces = bar_frames(rings=5)
    write_obj(folder / "frame2.obj", other[1], other_faces)
    return folder, ["frame2.obj", "vertices", "frame1.obj"]


def case_faces_differ(inputs):
    vertices, faces = bar_frames()
    folder = write_obj_frames(inputs / "frames", vertices, faces, count=3)
    write_obj(folder / "frame3.obj", vertices[2], faces[:, ::-1])  # same vertices, flipped winding
    return folder, ["frame3.obj", "faces differ"]


def npz_case(values, *needles):
    def build(inputs):
        vertices, faces = bar_frames()
        vertices[1, 2, 1] = values
        write_array_sequence(inputs / "bar.npz", vertices, faces, 24.0)
        return inputs / "bar.npz", ["bar.npz", *needles]
    return build


def obj_case(value):
    def build(inputs):
        vertices, faces = bar_frames()
        vertices[1, 2, 1] = value
        return write_obj_frames(inputs / "frames", vertices, faces, count=3), ["frame2.obj", "non-finite"]
    return build


def case_single_frame_npz(inputs):
    vertices, faces = bar_frames(frames=1)
    write_array_sequence(inputs / "one.npz", vertices, faces, 24.0)
    return inputs / "one.npz", ["one.npz", "1 frame(s)", "at least 2"]


def case_single_frame_folder(inputs):
    vertices, faces = bar_frames(frames=1)
    folder = write_obj_frames(inputs / "frames", vertices, faces, count=1)
    return folder, [str(folder), "at least 2"]


def case_garbage_text_obj(inputs):
    vertices, faces = bar_frames()
    folder = write_obj_frames(inputs / "frames", vertices, faces, count=3)
    (folder / "frame2.obj").write_text("this is { not an OBJ file\nat all\n")
    return folder, ["frame2.obj"]


def case_garbage_binary_obj(inputs):
    vertices, faces = bar_frames()
    folder = write_obj_frames(inputs / "frames", vertices, faces, count=3)
    (folder / "frame2.obj").write_bytes(bytes(np.random.default_rng(0).integers(0, 256, 512, dtype=np.uint8)))
    return folder, ["frame2.obj", "cannot read as OBJ"]


def case_garbage_npz(inputs):
    (inputs / "bar.npz").write_text("not a zip")
    return inputs / "bar.npz", ["bar.npz", "not an .npz"]


INPUT_CASES = {
    "missing-file": case_missing,
    "empty-folder": case_empty_folder,
    "glob-matches-nothing": case_glob_nothing,
    "vertex-count-differs": case_vertex_count_differs,
    "faces-differ": case_faces_differ,
    "nan-vertex-npz": npz_case(np.nan, "NaN", "frame 1"),
    "inf-vertex-npz": npz_case(np.inf, "inf", "frame 1"),
    "nan-vertex-obj": obj_case(np.nan),
    "inf-vertex-obj": obj_case(-np.inf),
    "single-frame-npz": case_single_frame_npz,
    "single-frame-folder": case_single_frame_folder,
    "garbage-text-obj": case_garbage_text_obj,
    "garbage-binary-obj": case_garbage_binary_obj,
    "garbage-npz": case_garbage_npz,
}


@pytest.mark.parametrize("case", list(INPUT_CASES))
def test_fit_skin_bad_input(case, inputs, out):
    spec, needles = INPUT_CASES[case](inputs)
    result = cli("fit-skin", spec, "-o", out / "skin.h5", "--bones", 2, "--iterations", 2)
    assert_user_error(result, *needles, folder=out)


def test_fit_skin_binary_obj_message_names_the_problem(inputs, out):
    spec, _ = case_garbage_binary_obj(inputs)
    line = assert_user_error(cli("fit-skin", spec, "-o", out / "skin.h5", "--bones", 2, "-q"), folder=out)
    assert "module" not in line.lower()


@pytest.mark.parametrize("options,needles", [
    (["--bones", 0], ["--bones", "at least 1"]),
    (["--bones", VERTICES + 1], [f"--bones {VERTICES + 1}", f"{VERTICES} vertices"]),
    (["--rest-frame", FRAMES], [f"--rest-frame {FRAMES}", f"{FRAMES} frames"]),
    (["--rest-frame", -FRAMES - 1], [f"--rest-frame {-FRAMES - 1}", f"{FRAMES} frames"]),
    (["--max-influences", 0], ["--max-influences", "at least 1"]),
    (["--iterations", 0], ["--iterations", "at least 1"]),
    (["--fps", 0], ["--fps", "positive"]),
    (["--tolerance", -1], ["--tolerance"]),
], ids=["bones-0", "bones-over-vertices", "rest-frame-past-end", "rest-frame-before-start",
        "max-influences-0", "iterations-0", "fps-0", "tolerance-negative"])
def test_fit_skin_impossible_options(data, out, options, needles):
    result = cli("fit-skin", data["bar"], "-o", out / "skin.h5", *FIT, *options)
    assert_user_error(result, *needles, folder=out)


@pytest.mark.parametrize("name", ["skin.txt", "skin", "skin.h5.bak"])
def test_fit_skin_output_extension(data, out, name):
    assert_user_error(cli("fit-skin", data["bar"], "-o", out / name, *FIT), name, ".h5", folder=out)


def test_fit_skin_output_in_missing_folder(data, out):
    assert_user_error(cli("fit-skin", data["bar"], "-o", out / "no" / "skin.h5", *FIT),
                      str(out / "no"), folder=out)


def test_example_bad_options(out):
    assert_user_error(cli("example", "bending-bar", "-o", out / "bar.txt"), "bar.txt", ".npz", folder=out)
    assert_user_error(cli("example", "bending-bar", "-o", out / "bar.npz", "--frames", 1), "--frames", folder=out)
    assert_user_error(cli("example", "bending-bar", "-o", out / "bar.npz", "--event"), "--event", folder=out)
    assert_user_error(cli("example", "walker", "-o", out / "w.npz", "--event", "--planted"), "--event", folder=out)
    assert_user_error(cli("example", "walker", "-o", out / "w.npz", "--limbs", 1.2), "--limbs", folder=out)
    assert_user_error(cli("example", "quadruped", "-o", out / "q.npz", "--motion", "jump"), "jump", "walk, graze",
                      folder=out)
    assert_user_error(cli("example", "humanoid", "-o", out / "h.npz", "--planted"), "humanoid", folder=out)


def test_example_walker_with_an_event(out):
    """Issue 63's one-time event: 2 s standing (a held pose to build-graph), 4 s walking, a stumble,
    3 s running, at the frame rate asked."""
    from skinsynth.pipeline.inputs.examples import walker_event

    done = assert_ok(cli("example", "walker", "--event", "-o", out / "event.npz", "--fps", 12, "--json"))
    assert json.loads(done.stdout)["frames"] == 114 and json.loads(done.stdout)["event"]
    with np.load(out / "event.npz") as f:
        vertices = f["vertices"]
    assert vertices.shape[0] == 114 and np.allclose(vertices, walker_event(fps=12.0)[0], atol=1e-6)
    assert np.ptp(vertices[:24], axis=0).max() == 0.0 and np.ptp(vertices[24:48], axis=0).max() > 0.1


def test_example_characters_with_known_skeletons(out):
    """Issue 65's truth as a user makes it: the humanoid's motions in the order asked, --frames a
    motion, --limbs its proportions; the sequence is the generator's."""
    from skinsynth.pipeline.inputs.characters import character

    done = assert_ok(cli("example", "humanoid", "-o", out / "h.npz", "--motion", "crouch", "--motion", "walk",
                         "--frames", 10, "--limbs", 1.25, "--json"))
    summary = json.loads(done.stdout)
    assert summary["frames"] == 20 and summary["motions"] == ["crouch", "walk"] and summary["limbs"] == 1.25
    with np.load(out / "h.npz") as f:
        vertices = f["vertices"]
    assert np.allclose(vertices, character("humanoid", ["crouch", "walk"], 10, limbs=1.25)[0], atol=1e-6)
    done = assert_ok(cli("example", "quadruped", "-o", out / "q.npz", "--frames", 6, "--json"))
    assert json.loads(done.stdout)["motions"] == ["walk", "graze"] and json.loads(done.stdout)["frames"] == 12


def test_fit_skin_bones_auto_chooses_the_walkers_parts_and_says_how(out):
    """Issue 68: ``--bones auto`` gives the walker its ten parts, and the summary (text and --json)
    gives the count, the rule and the rigid-cluster error around it; it is refused where the bones
    are brought (--rig, --skeleton FILE) and a count that is neither a number nor auto is refused."""
    assert_ok(cli("example", "walker", "-o", out / "walker.npz", "-q"))
    done = assert_ok(cli("fit-skin", out / "walker.npz", "-o", out / "walker.skin.h5", "--bones", "auto"))
    assert "bones: auto chose 10, the elbow of the rigid-cluster error curve" in done.stdout
    summary = json.loads(assert_ok(cli("fit-skin", out / "walker.npz", "-o", out / "again.skin.h5", "--bones", "auto",
                                       "--json", "-q")).stdout)
    assert summary["bones"] == 10 and summary["bone_count"]["chosen"] == 10
    assert [k for k, _ in summary["bone_count"]["rigid_cluster_errors"]] == [8, 9, 10, 11, 12]
    assert_user_error(cli("fit-skin", out / "walker.npz", "-o", out / "x.h5", "--bones", "many"), "--bones", "auto",
                      folder=out, keep=["walker.npz", "walker.skin.h5", "again.skin.h5"])
    assert_user_error(cli("fit-skin", out / "walker.npz", "-o", out / "x.h5", "--bones", "auto", "--rig",
                          out / "walker.skin.h5"), "--bones auto", "--rig",
                      folder=out, keep=["walker.npz", "walker.skin.h5", "again.skin.h5"])


# ---------------------------------------------------------------- bad input: inspect and export


def model_not_hdf5(folder, data):
    (folder / "notes.h5").write_text("these are my notes, not HDF5\n")
    return folder / "notes.h5", ["notes.h5", "not an HDF5 file"]


def model_foreign_hdf5(folder, data):
    with h5py.File(folder / "other.h5", "w") as f:
        f["vertices"] = np.zeros((2, 3, 3))
        f.attrs["format"] = "something-else"
    return folder / "other.h5", ["other.h5", "not a skinsynth model file"]


def model_newer_version(folder, data):
    path = folder / "future.h5"
    shutil.copy(data["skin"], path)
    with h5py.File(path, "r+") as f:
        f.attrs["format_version"] = FORMAT_VERSION + 1
    return path, ["future.h5", f"format_version {FORMAT_VERSION + 1}", "newer", "upgrade"]


def model_missing(folder, data):
    return folder / "nope.h5", ["nope.h5", "no such file"]


def model_is_a_capture(folder, data):
    """A mesh sequence given where a model file is needed: the error names the command that reads it
    (issue 68: build-graph capture.npz said only "not an HDF5 file")."""
    return data["bar"], [data["bar"].name, "not an HDF5 file", "mesh sequence", "fit-skin"]


def graph_file(folder):
    path = folder / "graph.h5"
    write_model(path, "graph", {"graph": {"reference_bone": np.int64(0), "@threshold": 0.5}}, [], "0")
    return path


MODEL_CASES = {
    "missing-file": model_missing,
    "not-hdf5": model_not_hdf5,
    "hdf5-not-skinsynth": model_foreign_hdf5,
    "newer-format-version": model_newer_version,
    "a-capture": model_is_a_capture,
}


@pytest.mark.parametrize("case", list(MODEL_CASES))
def test_inspect_bad_file(case, data, inputs):
    path, needles = MODEL_CASES[case](inputs, data)
    before = sorted(os.listdir(inputs))
    assert_user_error(cli("inspect", path), *needles, folder=inputs, keep=before)
    assert_user_error(cli("inspect", path, "--json"), *needles, folder=inputs, keep=before)


@pytest.mark.parametrize("case", list(MODEL_CASES))
@pytest.mark.parametrize("name", ["anim.usdc", "vat.exr"])
def test_export_bad_file(case, name, data, inputs, out):
    path, needles = MODEL_CASES[case](inputs, data)
    assert_user_error(cli("export", path, "-o", out / name, "--device", "cpu"), *needles, folder=out)


def test_truncated_model_file(data, inputs, out):
    path = inputs / "cut.h5"
    path.write_bytes(data["skin"].read_bytes()[:4096])
    assert_user_error(cli("inspect", path), "cut.h5")
    assert_user_error(cli("export", path, "-o", out / "vat.exr", "--device", "cpu"), "cut.h5", folder=out)


def test_non_integer_format_version(data, inputs, out):
    path = inputs / "odd.h5"
    shutil.copy(data["skin"], path)
    with h5py.File(path, "r+") as f:
        f.attrs["format_version"] = "one"
    assert_user_error(cli("inspect", path), "odd.h5", "format_version")
    assert_user_error(cli("export", path, "-o", out / "vat.exr", "--device", "cpu"), "odd.h5", "format_version",
                      folder=out)


@pytest.mark.parametrize("dataset", ["mesh/rest_vertices", "skin/bone_weights"])
def test_export_incomplete_skin_file(data, inputs, out, dataset):
    path = inputs / "holey.h5"
    shutil.copy(data["skin"], path)
    with h5py.File(path, "r+") as f:
        del f[dataset]
    assert_user_error(cli("export", path, "-o", out / "vat.exr", "--device", "cpu"),
                      "holey.h5", dataset.split("/")[1], "incomplete", folder=out)


@pytest.mark.parametrize("dataset", ["mesh/rest_vertices", "skin/bone_weights"])
def test_inspect_incomplete_skin_file(data, inputs, dataset):
    path = inputs / "holey.h5"
    shutil.copy(data["skin"], path)
    with h5py.File(path, "r+") as f:
        del f[dataset]
    assert_user_error(cli("inspect", path), "holey.h5", dataset.split("/")[1])


def test_stage_without_skin(inputs, out):
    """inspect summarises any stage; export needs /skin and says which command makes it."""
    path = graph_file(inputs)
    summary = json.loads(assert_ok(cli("inspect", path, "--json")).stdout)
    assert summary["stage"] == "graph" and "bones" not in summary
    for name in ("anim.usdc", "vat.exr"):
        assert_user_error(cli("export", path, "-o", out / name, "--device", "cpu"),
                          "graph.h5", "'graph'", "/skin", "fit-skin", folder=out)


@pytest.mark.parametrize("name", ["anim.obj", "anim.ma", "anim", "anim.exr.gz"])
def test_export_output_extension(data, out, name):
    assert_user_error(cli("export", data["skin"], "-o", out / name), name, ".usd", ".exr", folder=out)


@pytest.mark.parametrize("options,needles", [
    (["--device", "bogus"], ["--device bogus", "unknown device"]),
    (["--max-width", 0], ["--max-width"]),
])
def test_export_bad_options(data, out, options, needles):
    assert_user_error(cli("export", data["skin"], "-o", out / "vat.exr", *options), *needles, folder=out)


def test_export_half_overflow(inputs, out):
    vertices, faces = bending_bar(frames=4, rings=4, segments=4)
    write_array_sequence(inputs / "big.npz", vertices * 1e5, faces, 24.0)  # offsets of ~1e5 units
    assert_ok(cli("fit-skin", inputs / "big.npz", "-o", inputs / "big.h5", "--bones", 2, "--iterations", 2))
    assert_user_error(cli("export", inputs / "big.h5", "-o", out / "vat.exr", "--half", "--device", "cpu"),
                      "--half", folder=out)


def run_script(*args, cwd):
    env = dict(os.environ)
    return subprocess.run([SCRIPT, *map(str, args)], capture_output=True, text=True, cwd=cwd, env=env, timeout=120)


def test_export_cuda_without_gpu_subprocess(data, out):
    """In a real process: warp's native CUDA warnings must not reach the terminal either."""
    from skinsynth.gpu import available_devices

    if any(d.startswith("cuda") for d in available_devices()):
        pytest.skip("this machine has a CUDA device")
    for name in ("anim.usdc", "vat.exr"):
        done = run_script("export", data["skin"], "-o", out / name, "--device", "cuda", cwd=out)
        assert done.returncode == 2, done.stderr
        assert done.stdout == ""
        assert done.stderr.splitlines() == [
            "skinsynth: error: --device cuda: no CUDA device is available (warp found only cpu)"]
        assert_folder_holds(out)


def test_fit_skin_missing_input_subprocess(tmp_path, out):
    done = run_script("fit-skin", "missing.npz", "-o", out / "skin.h5", "--bones", 2, cwd=tmp_path)
    assert done.returncode == 2
    assert done.stdout == ""
    assert done.stderr.splitlines() == ["skinsynth: error: missing.npz: no such file or folder"]
    assert_folder_holds(out)


# ---------------------------------------------------------------- failures never clobber


OLD = b"an earlier, precious result\n"


@pytest.mark.parametrize("case", ["nan-vertex-npz", "bones-over-vertices"])
def test_failed_fit_skin_keeps_existing_output(case, data, inputs, out):
    target = out / "skin.h5"
    target.write_bytes(OLD)
    if case == "nan-vertex-npz":
        spec, _ = INPUT_CASES[case](inputs)
        args = ["fit-skin", spec, "-o", target, *FIT]
    else:
        args = ["fit-skin", data["bar"], "-o", target, *FIT, "--bones", VERTICES + 1]
    assert_user_error(cli(*args), folder=out, keep=["skin.h5"])
    assert target.read_bytes() == OLD


def test_failed_export_keeps_existing_output(data, inputs, out):
    path, _ = model_not_hdf5(inputs, data)
    for name in ("vat.exr", "anim.usdc"):
        (out / name).write_bytes(OLD)
        assert_user_error(cli("export", path, "-o", out / name, "--device", "cpu"), folder=out,
                          keep=os.listdir(out))
        assert (out / name).read_bytes() == OLD


def test_interrupted_write_keeps_existing_output(data, out, monkeypatch):
    """Ctrl-C while the HDF5 file is half written: exit 130, old file intact, no temporary left."""
    from skinsynth.formats import model

    target = out / "skin.h5"
    target.write_bytes(OLD)
    real = model._write_group
    calls = []

    def interrupted(group, contents):
        calls.append(group.name)
        if len(calls) == 2:  # /mesh written, /examples half-way
            raise KeyboardInterrupt
        return real(group, contents)

    monkeypatch.setattr(model, "_write_group", interrupted)
    result = cli("fit-skin", data["bar"], "-o", target, *FIT)
    assert result.exit_code == 130, result.stderr
    assert "no output written" in result.stderr and "Traceback" not in result.output
    assert target.read_bytes() == OLD
    assert_folder_holds(out, ["skin.h5"])


def test_a_signal_that_surfaces_as_another_error_ends_the_command_as_interrupted(data, out, monkeypatch):
    """A SIGHUP landing while Python initialises a C extension (a lazy scipy import inside the
    command) comes out as ``ImportError: initialization failed``, the signal's exception its cause:
    the command says it was interrupted, in one line, exit 128 + 1, no traceback (it printed one:
    tests/contracts/test_faults.py caught it once in a whole run)."""
    import signal

    from skinsynth.formats import model
    from skinsynth.formats.atomic import Interrupted

    target = out / "skin.h5"
    target.write_bytes(OLD)

    def import_interrupted(group, contents):
        try:
            raise Interrupted(signal.SIGHUP)  # as the handler raises it, recorded
        except Interrupted as stop:
            raise ImportError("initialization failed") from stop

    monkeypatch.setattr(model, "_write_group", import_interrupted)
    result = cli("fit-skin", data["bar"], "-o", target, *FIT)
    assert result.exit_code == 128 + signal.SIGHUP, result.output
    assert result.stderr.strip().splitlines()[-1] == "skinsynth: interrupted (SIGHUP); no output written"
    assert "Traceback" not in result.output and "ImportError" not in result.output
    assert target.read_bytes() == OLD
    assert_folder_holds(out, ["skin.h5"])


# ---------------------------------------------------------------- determinism


def test_same_seed_gives_byte_identical_datasets(data, tmp_path):
    first, target = tmp_path / "first.h5", tmp_path / "skin.h5"
    args = ["fit-skin", data["bar"], "-o", target, "--bones", BONES, "--iterations", 8, "--seed", 5, "-q"]
    assert_ok(cli(*args))
    os.replace(target, first)
    assert_ok(cli(*args))  # same command line, so provenance differs only by date

    datasets_a, attrs_a = h5_datasets(first)
    datasets_b, attrs_b = h5_datasets(target)
    assert datasets_a.keys() == datasets_b.keys()
    for name in datasets_a:
        assert datasets_a[name] == datasets_b[name], f"dataset {name} differs"
    assert attrs_a.keys() == attrs_b.keys()
    for name in attrs_a:
        a, b = dict(attrs_a[name]), dict(attrs_b[name])
        if name.startswith("provenance/"):
            assert "date" in a and "date" in b
            a.pop("date"), b.pop("date")
        assert a == b, f"attributes of {name} differ"

    # The contract of docs/format.md: big numeric datasets are gzip + shuffle compressed.
    assert datasets_a["examples/vertices"][3:6] == ("gzip", 4, True)
    assert datasets_a["skin/rotations"][3:6] == ("gzip", 4, True)
    with h5py.File(first, "r") as f:
        assert json.loads(f["provenance/00_skin"].attrs["parameters"])["seed"] == 5


# ---------------------------------------------------------------- round trips


@pytest.fixture(scope="module")
def reconstruction(data):
    skin = read_skin(data["skin"])
    frames = lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations,
                           skin.translations)
    diagonal = float(np.linalg.norm(np.ptp(skin.rest_vertices, axis=0)))
    return skin, frames, diagonal


@pytest.mark.parametrize("kind,reader", [("points", read_points_cache), ("skel", read_skel_points)])
def test_usd_export_round_trip(data, out, reconstruction, kind, reader):
    skin, expected, diagonal = reconstruction
    path = out / f"{kind}.usdc"
    assert_ok(cli("export", data["skin"], "-o", path, "--as", kind, "--device", "cpu"))
    got = reader(path)
    if kind == "points":
        got, faces, fps = got
        np.testing.assert_array_equal(faces, skin.faces)
        assert fps == pytest.approx(skin.fps)
    assert got.shape == expected.shape == (FRAMES, VERTICES, 3)
    error = np.abs(got - expected).max()
    assert error <= 1e-4 * diagonal, (error, diagonal)


def test_exr_export_round_trip(data, out, reconstruction):
    skin, expected, _ = reconstruction
    path = out / "vat.exr"
    assert_ok(cli("export", data["skin"], "-o", path, "--device", "cpu"))
    offsets, meta = read_vat(path)
    assert offsets.dtype == np.float32
    assert (meta["vat_frame_count"], meta["vat_vertex_count"]) == (FRAMES, VERTICES)
    assert meta["vat_fps"] == pytest.approx(skin.fps)
    got = offsets.astype(np.float64) + skin.rest_vertices
    # float32 precision: the kernel runs in float32 and offsets are stored as float32.
    tolerance = 16 * np.finfo(np.float32).eps * np.abs(expected).max()
    np.testing.assert_allclose(got, expected, rtol=0, atol=tolerance)
    np.testing.assert_array_equal(meta["vat_bounds_min"], offsets.min(axis=(0, 1)))
    np.testing.assert_array_equal(meta["vat_bounds_max"], offsets.max(axis=(0, 1)))


@pytest.mark.parametrize("args,needles", [
    (["fit-skin", "x.npz", "-o", "y.h5", "--bones", "abc"], ["--bones", "abc", "skinsynth fit-skin --help"]),
    (["fit-skin"], ["INPUT"]),
    (["no-such-command"], ["no-such-command"]),
    (["export", "x.h5", "-o", "y.usdc", "--as", "mesh"], ["--as", "mesh"]),
], ids=["not-an-integer", "missing-argument", "unknown-command", "bad-choice"])
def test_usage_errors_are_one_line(args, needles):
    assert_user_error(cli(*args), *needles)


def test_provenance_records_the_command_as_typed(data, out):
    assert_ok(cli("fit-skin", data["bar"], "-o", out / "p.h5", *FIT, "--seed", "3"))
    with h5py.File(out / "p.h5") as f:
        record = next(iter(f["provenance"].values()))
        command = record.attrs["command"]
        assert command.startswith("skinsynth fit-skin ") and "--seed 3" in command
        assert json.loads(record.attrs["parameters"])["seed"] == 3
        assert json.loads(record.attrs["inputs"])[0]["sha256"]
