"""Fault injection (issue 11): a full disk, signals at random moments, an output that is an input,
NaN results, oversized inputs, and parallelism that must not change a bit of the output.

Commands that must be killed or must see their own environment (BLAS threads, a full filesystem)
run as real processes; the rest in-process."""

import hashlib
import os
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from cli_helpers import assert_folder_holds, assert_ok, assert_user_error, cli
from damage_cases import corrupt_dataset, damage_kinds
from forked_commands import ForkedCommands

SKINSYNTH = [sys.executable, "-c", "import sys; from skinsynth.cli.main import main; sys.argv[0] = 'skinsynth'; "
                                   "sys.exit(main())"]


@pytest.fixture(scope="module")
def chain(stage_files, tmp_path_factory):
    """bar.npz → skin.h5 → graph.h5 (two components) → bones.h5, controls.h5 → puppet.h5, and controls.csv."""
    stages = stage_files(frames=48, bones=6, iterations=8, cycles=2, graph=("--min-segment", 4, "--edge-threshold", 0.5),
                         controls=("--count", 4), puppet=(), synthesis=("-n", 2, "-m", 30))
    root = stages.copy_to(tmp_path_factory.mktemp("faults"))  # controls.csv beside them
    vertices = stages.vertices
    with h5py.File(root / "graph.h5") as f:
        assert f["graph"].attrs["components"] >= 2
    with h5py.File(root / "controls.h5") as f:
        ids = f["controls/vertex_indices"][()]
    rows = [f"{frame},{p},{x},{y},{z}" for frame in range(6) for p, (x, y, z) in enumerate(vertices[frame, ids])]
    (root / "controls.csv").write_text("frame,point,x,y,z\n" + "\n".join(rows) + "\n")
    return root


def digest(path):
    with open(path, "rb") as handle:
        return hashlib.sha256(handle.read()).hexdigest()


def run(args, env=None, **kwargs):
    return subprocess.run(SKINSYNTH + [str(a) for a in args], capture_output=True, text=True,
                          env={**os.environ, **(env or {})}, **kwargs)


# -- an output that is an input -------------------------------------------------------------------

COMMANDS = [  # (command line with {out} for -o, the input it must not overwrite)
    (["fit-skin", "bar.npz", "--bones", 3, "-o", "{out}"], "bar.npz"),
    (["build-graph", "skin.h5", "-o", "{out}"], "skin.h5"),
    (["select-controls", "skin.h5", "-o", "{out}"], "skin.h5"),
    (["train-kcca", "controls.h5", "-o", "{out}"], "controls.h5"),
    (["synthesize", "graph.h5", "-n", 2, "-m", 20, "-o", "{out}"], "graph.h5"),
    (["play", "puppet.h5", "-c", "controls.csv", "-o", "{out}"], "puppet.h5"),
]


@pytest.mark.parametrize("command, source", COMMANDS, ids=[c[0][0] for c in COMMANDS])
@pytest.mark.parametrize("alias", ["same name", "symbolic link", "hard link"])
def test_an_output_that_is_an_input_is_refused_before_any_work(chain, tmp_path, command, source, alias):
    target = chain / source
    before = digest(target)
    if alias == "same name":
        out = target
    else:
        out = tmp_path / ("alias" + os.path.splitext(source)[1])
        (os.symlink if alias == "symbolic link" else os.link)(target, out)
    if source.endswith(".npz"):  # fit-skin writes .h5: alias an .h5 name to the input instead
        out = tmp_path / "alias.h5"
        (os.symlink if alias != "hard link" else os.link)(target, out)
    args = [str(out) if a == "{out}" else (str(chain / a) if isinstance(a, str) and (chain / a).exists() else a)
            for a in command]
    assert_user_error(cli(*args), "the output is the input")
    assert digest(target) == before


# -- a full disk ------------------------------------------------------------------------------------

@pytest.fixture
def full_disk(tmp_path):
    """A 64 KiB tmpfs (root on Linux only; skipped with the reason elsewhere)."""
    folder = tmp_path / "tiny"
    folder.mkdir()
    if not sys.platform.startswith("linux") or os.geteuid() != 0:
        pytest.skip("mounting a tiny tmpfs needs root on Linux")
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(folder)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.decode().strip()}")
    yield folder
    subprocess.run(["umount", str(folder)], capture_output=True)


def test_a_full_disk_is_one_line_and_leaves_nothing(chain, full_disk, tmp_path):
    cases = [["fit-skin", chain / "bar.npz", "--bones", 3, "-o", full_disk / "x.h5", "-q"],
             ["export", chain / "skin.h5", "-o", full_disk / "x.usda", "--as", "points"],
             ["export", chain / "skin.h5", "-o", full_disk / "x.exr"],
             ["example", "bending-bar", "-o", full_disk / "x.npz", "--frames", 96],
             ["evaluate", chain / "puppet.h5", "--plot", full_disk / "x.png"],
             ["synthesize", chain / "graph.h5", "-n", 20, "-m", 100, "-o", full_disk / "x.h5", "-q"],
             ["play", chain / "puppet.h5", "-c", chain / "controls.csv", "-o", full_disk / "x.usdc", "--instances", 500],
             # folder outputs (issue 27): the temporary folder goes, and the line names the user's folder
             ["export", chain / "skin.h5", "-o", f"{full_disk / 'vat'}/"],
             ["play", chain / "puppet.h5", "-c", chain / "controls.csv", "-o", f"{full_disk / 'vat'}/", "--instances", 8],
             ["synthesize", chain / "graph.h5", "-n", 20, "-m", 100, "-o", tmp_path / "s.h5", "-q", "--usd",
              full_disk / "usd"],
             ["synthesize", chain / "graph.h5", "-n", 8, "-m", 100, "-o", tmp_path / "s.h5", "-q", "--plot",
              full_disk / "plots", "--plot-count", 8],
             ["build-graph", chain / "skin.h5", "-o", tmp_path / "g.h5", "--edge-threshold", 0.5, "--plot",
              full_disk / "plots", "-q"],
             # ffmpeg failing on a full disk once left a truncated .mp4 (no index) in place, exit 0
             ["preview", chain / "skin.h5", "-o", full_disk / "x.mp4", "-q"]]
    # each command a child of one interpreter (tests/forked_commands.py): fd 2 is the child's own
    with ForkedCommands(preload=["h5py", "skinsynth.formats.usd", "skinsynth.formats.model"]) as commands:
        for args in cases:
            done = commands.run(args)
            lines = done.stderr.strip().splitlines()
            assert done.returncode == 2 and len(lines) == 1, (args, done.stderr[-2000:])
            assert "space" in lines[0] and str(full_disk) in lines[0], lines[0]
            assert_folder_holds(full_disk)  # no output, no temporary


def _free_space(monkeypatch, free):
    """Every disk seems to have ``free`` bytes free (shutil.disk_usage, in-process)."""
    import shutil

    usage = shutil.disk_usage
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(path)._replace(free=free))


def _no_synthesis(monkeypatch):
    """synthesize's animations are never made (the refusal must come first)."""
    def made(*args, **kwargs):
        raise AssertionError("the animations were made before the refusal")

    import skinsynth.pipeline.synthesis.synthesis as synthesis

    monkeypatch.setattr(synthesis, "synthesize", made)
    monkeypatch.setattr("skinsynth.pipeline.synthesis.synthesize", made, raising=False)


def test_an_output_larger_than_the_free_disk_is_refused_before_any_work(chain, tmp_path, monkeypatch):
    """Issue 25: ``synthesize -n 1000 -m 600`` to a 64 MB disk computed for 11 s, then said "not
    enough space". The estimate the write checks, made from the request's shapes, is checked
    against the output folder's free space at once: one line naming both and the folder."""
    out = tmp_path / "out"
    out.mkdir()
    _free_space(monkeypatch, 64 << 20)
    _no_synthesis(monkeypatch)
    line = assert_user_error(cli("synthesize", chain / "graph.h5", "-o", out / "b.h5", "-n", 1000, "-m", 600),
                             "not enough space", "1000 animations × 600 frames", f"of disk in {out},",
                             "64.0 MiB is free", folder=out)
    needed = float(line.split("needs about ")[1].split(" MiB")[0])
    bones = 6
    assert needed > 1000 * 600 * bones * 48 / 2 ** 20  # the motions alone, float32


def test_the_estimate_before_the_work_is_the_one_the_write_checks(chain, tmp_path, monkeypatch):
    """So a request that passes the check up front is not refused after the work."""
    import skinsynth.formats.model as model
    import skinsynth.formats.synthesis_file as synthesis_file

    planned, checked = [], []
    plan, estimate = synthesis_file.planned_bytes, model.estimated_bytes
    monkeypatch.setattr(synthesis_file, "planned_bytes", lambda *a, **k: planned.append(plan(*a, **k)) or planned[-1])
    monkeypatch.setattr(model, "estimated_bytes", lambda groups: checked.append(estimate(groups)) or checked[-1])
    assert_ok(cli("synthesize", chain / "graph.h5", "-o", tmp_path / "b.h5", "-n", 300, "-m", 50, "-q"))
    assert planned == [(checked[-1], 0)]  # the write's own call, around those of its nested groups
    assert checked[-1] > os.path.getsize(tmp_path / "b.h5")


# -- folder outputs never cost the user a file (issue 27) ------------------------------------------

#: Every command with a folder output: (its arguments with {dir} for the folder and {out} for its
#: file output, or None; its input to place inside the folder when asked).
FOLDER_OUTPUTS = {
    "export": (["export", "{skin.h5}", "-o", "{dir}/", "-q"], None),
    "play": (["play", "{puppet.h5}", "-c", "{controls.csv}", "--instances", 2, "-o", "{dir}/", "-q"], None),
    "synthesize --exr": (["synthesize", "{graph.h5}", "-n", 2, "-m", 20, "-o", "{out}", "--exr", "{dir}/", "-q"],
                         "h5"),
    "synthesize --usd": (["synthesize", "{graph.h5}", "-n", 2, "-m", 20, "-o", "{out}", "--usd", "{dir}", "-q"],
                         "h5"),
    "synthesize --plot": (["synthesize", "{graph.h5}", "-n", 2, "-m", 20, "-o", "{out}", "--plot", "{dir}",
                           "--plot-count", 1, "-q"], "h5"),
    "build-graph --plot": (["build-graph", "{skin.h5}", "-o", "{out}", "--edge-threshold", 0.5, "--plot", "{dir}",
                            "-q"], "h5"),
}
#: Names a user's file may have: the names the commands write themselves among them.
USER_FILE_NAMES = st.one_of(
    st.sampled_from(["notes.txt", "project.blend", "vat.json", "rest.obj", "rest.glb", "animation.exr",
                     "character_000.exr", "animation_0000.usdc", "animation_0000.png", "bone_graph.png",
                     ".skinsynth-folder.json", ".hidden", "sub/take.h5"]),
    st.text(alphabet="abcxyz_.-", min_size=1, max_size=8).filter(lambda n: n not in (".", "..")))


def _files(folder):
    found = {}
    for top, _, names in os.walk(folder):
        for name in names:
            found[os.path.relpath(os.path.join(top, name), folder)] = digest(os.path.join(top, name))
    return found


@settings(max_examples=40, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(command=st.sampled_from(sorted(FOLDER_OUTPUTS)), made_before=st.booleans(),
       user_files=st.one_of(st.just({}), st.dictionaries(USER_FILE_NAMES, st.binary(max_size=32), min_size=1,
                                                          max_size=3)),
       inside=st.sampled_from(["nothing", "nothing", "an input", "the file output"]))
def test_a_folder_output_leaves_every_file_of_the_user_as_it_was_or_refuses(chain, command, made_before, user_files,
                                                                             inside):
    """Whatever a folder output's target holds (a folder skinsynth wrote before or not, a user's
    files, the command's own input or file output), every file that was there is byte-identical
    afterwards, or the command refused in one line; and it refuses exactly when something of the
    user's is at stake."""
    import tempfile

    template, file_output = FOLDER_OUTPUTS[command]
    with tempfile.TemporaryDirectory() as work:
        target = os.path.join(work, "target")

        def arguments(source_inside, out_inside):
            args = []
            for a in template:
                if a in ("{dir}", "{dir}/"):
                    args.append(target + a[len("{dir}"):])
                elif a == "{out}":
                    args.append(os.path.join(target if out_inside else work, "out.h5"))
                elif isinstance(a, str) and a.startswith("{"):
                    name = a[1:-1]
                    args.append(source_inside if source_inside and name == template[1][1:-1] else str(chain / name))
                else:
                    args.append(a)
            return args

        if made_before:
            assert_ok(cli(*arguments(None, False)))
            if os.path.exists(os.path.join(work, "out.h5")):
                os.remove(os.path.join(work, "out.h5"))
        os.makedirs(target, exist_ok=True)
        for name, content in user_files.items():
            os.makedirs(os.path.dirname(os.path.join(target, name)), exist_ok=True)
            with open(os.path.join(target, name), "wb") as handle:
                handle.write(content)
        source_inside = None
        if inside == "an input":
            source_inside = os.path.join(target, "input" + os.path.splitext(template[1][1:-1])[1])
            with open(source_inside, "wb") as handle:
                handle.write((chain / template[1][1:-1]).read_bytes())
        at_stake = bool(user_files) or inside == "an input" or (inside == "the file output" and file_output)
        event(f"{command}: {'refused' if at_stake else 'replaced' if made_before else 'written'}")
        before = _files(work)
        result = cli(*arguments(source_inside, inside == "the file output"))
        if at_stake:
            assert_user_error(result)
            assert _files(work) == before  # refused before any work: nothing at all was touched
        else:
            assert_ok(result)
            after = _files(work)
            assert all(after.get(name) == sha for name, sha in before.items() if not name.startswith("target/"))
            assert ".skinsynth-folder.json" in os.listdir(target)
            assert [n for n in os.listdir(work) if n.startswith(".")] == []  # no temporary left


# -- signals at random moments ---------------------------------------------------------------------

def _alive(pgid):
    try:
        os.killpg(pgid, 0)
        return True
    except ProcessLookupError:
        return False


@settings(max_examples=8, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(number=st.sampled_from([signal.SIGINT, signal.SIGTERM, signal.SIGHUP]), delay=st.floats(0.3, 4.0),
       existing=st.booleans())
def test_a_signal_at_any_moment_leaves_the_old_file_or_the_whole_new_one(chain, tmp_path, number, delay, existing):
    out = tmp_path / f"bones_{number}_{delay:.3f}_{existing}.h5"
    if existing:
        out.write_bytes(b"the old file")
    process = subprocess.Popen(SKINSYNTH + ["synthesize", str(chain / "graph.h5"), "-n", "600", "-m", "300", "-o",
                                            str(out), "--jobs", "2", "-q"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(delay)
    process.send_signal(number)
    _, stderr = process.communicate(timeout=120)
    # −N: the signal came while Python was starting up or shutting down, outside the command.
    assert process.returncode in (0, 128 + number, -number), stderr
    for _ in range(50):  # the workers end with the command
        if not _alive(process.pid):
            break
        time.sleep(0.1)
    assert not _alive(process.pid), "a worker outlived the command"
    assert not [n for n in os.listdir(tmp_path) if ".tmp" in n]
    if process.returncode == 128 + number:
        assert len(stderr.splitlines()) == 1 and stderr.startswith("skinsynth: interrupted"), stderr
    untouched = out.read_bytes() == b"the old file" if existing else not out.exists()
    if "no output written" in stderr:
        assert untouched
    if process.returncode == 0 or "wrote only" in stderr or not untouched:  # then it is the whole new file
        with h5py.File(out) as f:
            assert f["synthesis/bone_matrices"].shape[:2] == (600, 300)


def test_finalisers_failing_after_a_signal_stay_off_stderr(monkeypatch):
    """A signal that lands inside a library's finaliser can leave its object half closed; the
    error it raises when collected again at exit (llvmlite's ``ObjectRef.__del__`` in CI) is the
    signal's doing, not a second fault. Before any signal, such errors are reported as Python does."""
    from types import SimpleNamespace

    from skinsynth.formats import atomic

    reported = []
    unraisable = SimpleNamespace(exc_value=AttributeError("'ValueRef' object has no attribute '_as_parameter_'"))
    monkeypatch.setattr(atomic, "RECEIVED", [])
    atomic.quiet_interruptions(unraisable, default=reported.append)
    assert reported == [unraisable]
    atomic.RECEIVED.append(signal.SIGINT)
    atomic.quiet_interruptions(unraisable, default=reported.append)
    assert reported == [unraisable]


def test_a_killed_writer_leaves_a_temporary_the_next_write_removes(chain, tmp_path):
    out = tmp_path / "bones.h5"
    stale = tmp_path / f".bones.{2 ** 22 + 12345}.abcdefgh.tmp.h5"  # a pid no process has
    stale.write_bytes(b"partial")
    assert_ok(cli("synthesize", chain / "graph.h5", "-n", 2, "-m", 20, "-o", out, "-q"))
    assert sorted(os.listdir(tmp_path)) == ["bones.h5"]


# -- results out of range, inputs out of bounds ---------------------------------------------------

def test_non_finite_results_are_never_written(chain, tmp_path):
    from skinsynth.formats.errors import FormatError
    from skinsynth.formats.model import write_model

    with pytest.raises(FormatError, match=r"x.h5: not written: /skin/rotations holds NaN"):
        write_model(tmp_path / "x.h5", "skin", {"skin": {"rotations": np.array([0.0, np.nan])}}, [], "0")
    with pytest.raises(FormatError, match=r"/skin/@rmse holds NaN"):
        write_model(tmp_path / "x.h5", "skin", {"skin": {"@rmse": float("inf")}}, [], "0")
    assert_folder_holds(tmp_path)
    for option in ("--translation-prior", "--regularization"):
        assert_user_error(cli("train-kcca", chain / "controls.h5", "-o", tmp_path / "p.h5", option, "inf"), option,
                          folder=tmp_path)


def test_a_csv_cannot_ask_for_more_memory_than_its_rows(chain, tmp_path):
    (tmp_path / "huge.csv").write_text("frame,point,x,y,z\n100000000,0,1,2,3\n")
    assert_user_error(cli("play", chain / "puppet.h5", "-c", tmp_path / "huge.csv", "-o", tmp_path / "o.h5"),
                      "huge.csv", "frames are missing", folder=tmp_path, keep=["huge.csv"])


# -- parallelism and BLAS threads change nothing ------------------------------------------------------

@pytest.mark.parametrize("blend", ["bones", "key-vertices"])
def test_jobs_and_blas_threads_give_byte_identical_datasets(chain, tmp_path, blend):
    outputs = []
    for jobs, blas in ((1, 1), (1, 2), (2, 1)):  # each changed from the first on its own
        out = tmp_path / f"j{jobs}b{blas}.h5"
        done = run(["synthesize", chain / "graph.h5", "-n", 260, "-m", 60, "--seed", 9, "--jobs", jobs, "-o", out,
                    "--blend", blend, "-q"], env={"OPENBLAS_NUM_THREADS": str(blas), "OMP_NUM_THREADS": str(blas),
                                "MKL_NUM_THREADS": str(blas)})
        assert done.returncode == 0, done.stderr
        outputs.append(out)
    with h5py.File(outputs[0]) as first:
        names = [n for n in first["synthesis"] if isinstance(first["synthesis"][n], h5py.Dataset)]
        reference = {n: first["synthesis"][n][()].tobytes() for n in names}
    for other in outputs[1:]:
        with h5py.File(other) as f:
            for name in names:
                assert f["synthesis"][name][()].tobytes() == reference[name], (other.name, name)


def _datasets(path):
    """{name: bytes} of every dataset but the provenance (strings compared as text)."""
    out = {}
    with h5py.File(path) as f:
        def keep(name, item):
            if isinstance(item, h5py.Dataset) and not name.startswith("provenance"):
                value = item[()]
                out[name] = repr(value.tolist()) if value.dtype.kind == "O" else value.tobytes()
        f.visititems(keep)
    return out


def test_every_stage_gives_byte_identical_datasets_whatever_the_blas_threads(tmp_path):
    """A bar large enough that a threaded BLAS splits its SVDs and products (1282 vertices)."""
    from skinsynth.formats.meshseq import write_array_sequence
    from skinsynth.pipeline.inputs.examples import bending_bar

    vertices, faces = bending_bar(frames=48, rings=40, segments=32, cycles=2)
    write_array_sequence(tmp_path / "bar.npz", vertices, faces, 24.0)
    stages = [("skin", ["fit-skin", tmp_path / "bar.npz", "--bones", 4, "--iterations", 3, "-q"], None),
              ("controls", ["select-controls", "{skin}", "-q"], "skin"),
              ("puppet", ["train-kcca", "{controls}", "-q"], "controls"),
              ("graph", ["build-graph", "{skin}", "--min-segment", 4, "-q"], "skin")]
    for blas in (1, 2):
        for name, args, _ in stages:
            args = [str(a).replace("{skin}", str(tmp_path / f"skin{blas}.h5"))
                    .replace("{controls}", str(tmp_path / f"controls{blas}.h5")) for a in args]
            done = run(args + ["-o", tmp_path / f"{name}{blas}.h5"],
                       env={"OPENBLAS_NUM_THREADS": str(blas), "OMP_NUM_THREADS": str(blas), "MKL_NUM_THREADS": str(blas)})
            assert done.returncode == 0, (name, done.stderr)
    for name, _, _ in stages:
        one, two = _datasets(tmp_path / f"{name}1.h5"), _datasets(tmp_path / f"{name}2.h5")
        assert one.keys() == two.keys()
        assert [k for k in one if one[k] != two[k]] == [], name


# -- corrupted files: one dataset at a time, every dataset of every stage file ---------------------

CONSUMERS = {"skin.h5": [["build-graph", "{f}", "-o", "{out}.h5", "-q"], ["export", "{f}", "-o", "{out}.usdc"]],
             "controls.h5": [["train-kcca", "{f}", "-o", "{out}.h5"]],
             "puppet.h5": [["evaluate", "{f}"], ["play", "{f}", "-c", "{chain}/controls.csv", "-o", "{out}.h5"]],
             "graph.h5": [["synthesize", "{f}", "-o", "{out}.h5", "-n", "2", "-m", "20", "-q"]],
             "bones.h5": []}  # synthesize's output: only inspect reads it


def test_every_corrupted_dataset_is_refused_in_one_line_or_harmless(chain, tmp_path):
    counts, harmless = {"refused": 0, "harmless": 0}, []
    for stage, commands in CONSUMERS.items():
        with h5py.File(chain / stage) as f:
            names = []
            f.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) and not n.startswith("provenance")
                         else None)
            dtypes = {n: f[n].dtype for n in names}
        for name in names:
            for kind in damage_kinds(dtypes[name]):
                broken = tmp_path / stage
                broken.write_bytes((chain / stage).read_bytes())
                corrupt_dataset(broken, name, kind)
                for command in [["inspect", "{f}"]] + commands:
                    args = [a.replace("{f}", str(broken)).replace("{out}", str(tmp_path / "out"))
                            .replace("{chain}", str(chain)) for a in command]
                    result = cli(*args)
                    where = f"{stage} /{name} {kind}: {command[0]}"
                    assert isinstance(result.exception, (SystemExit, type(None))), f"{where}: {result.exception!r}"
                    if result.exit_code == 0:
                        counts["harmless"] += 1
                        harmless.append(where)
                        continue
                    lines = result.stderr.splitlines()
                    assert result.exit_code == 2 and len(lines) == 1 and str(broken) in lines[0], f"{where}: {lines}"
                    counts["refused"] += 1
                for leftover in tmp_path.glob("out*"):
                    leftover.unlink()
    print(f"corrupted-file cases: {counts}; accepted (still a valid file): {sorted(set(harmless))}")
    # What is accepted is a shorter 1-D record (an error history, a test-frame list) or a large
    # count: still a valid file. Everything else is refused.
    assert counts["refused"] > 900 and counts["harmless"] < 30, counts


def test_out_of_range_options_and_versions_are_one_line(chain, tmp_path):
    for args, needle in ((["fit-skin", chain / "bar.npz", "-o", tmp_path / "x.h5", "--bones", 3, "--seed", -5], "--seed"),
                         (["fit-skin", chain / "bar.npz", "-o", tmp_path / "x.h5", "--bones", 3, "--fps", "1e400"], "--fps"),
                         (["fit-skin", chain / "bar.npz", "-o", tmp_path / "x.h5", "--bones", 3, "--fps", "nan"], "--fps"),
                         (["synthesize", chain / "graph.h5", "-o", tmp_path / "x.h5", "-n", 2, "-m", 20, "--seed", -1],
                          "--seed"),
                         (["play", chain / "puppet.h5", "-c", chain / "controls.csv", "-o", tmp_path / "x.h5",
                           "--instances", 2, "--spacing", "nan"], "--spacing"),
                         (["example", "bending-bar", "-o", tmp_path / "x.npz", "--fps", "inf"], "--fps")):
        assert_user_error(cli(*args), needle, folder=tmp_path)
    odd = tmp_path / "odd.h5"
    odd.write_bytes((chain / "skin.h5").read_bytes())
    with h5py.File(odd, "r+") as f:
        f.attrs["format_version"] = 1.5
    assert_user_error(cli("inspect", odd), "format_version 1.5", folder=tmp_path, keep=["odd.h5"])


@pytest.mark.parametrize("kernels", [None, "Prescott"])
def test_play_threads_and_blas_threads_give_byte_identical_vertices(chain, tmp_path, kernels):
    """Also with OpenBLAS's generic x86-64 kernels (OPENBLAS_CORETYPE=Prescott), as another CPU
    runs them (issue 34): they round a product's row by where it sits, and play --threads 1 and 2
    differed in the last bits until the translation solve went in fixed blocks (ignored off x86)."""
    results = []
    for threads, blas in ((1, 1), (2, 2), (3, 1)):
        out = tmp_path / f"t{threads}b{blas}.h5"
        env = {"OPENBLAS_NUM_THREADS": str(blas), "OMP_NUM_THREADS": str(blas)}
        if kernels:
            env["OPENBLAS_CORETYPE"] = kernels
        done = run(["play", chain / "puppet.h5", "-c", chain / "controls.csv", "-o", out, "--instances", 7,
                    "--threads", threads, "--device", "cpu"], env=env)
        assert done.returncode == 0, done.stderr
        with h5py.File(out) as f:
            results.append(f["vertices"][()].tobytes())
    assert results[0] == results[1] == results[2]


def test_small_files_declaring_huge_arrays_and_obstacles_that_hit_every_frame(chain, tmp_path):
    import trimesh

    np.save(tmp_path / "small.npy", np.zeros((3, 4, 3)))
    raw = (tmp_path / "small.npy").read_bytes()
    (tmp_path / "huge.npy").write_bytes(raw.replace(b"(3, 4, 3)", b"(9999999, 4, 3)"))  # header only
    assert_user_error(cli("play", chain / "puppet.h5", "-c", tmp_path / "huge.npy", "-o", tmp_path / "o.h5"),
                      "huge.npy")
    box = trimesh.creation.box(extents=(100.0, 100.0, 100.0))
    box.export(tmp_path / "box.obj")
    assert_user_error(cli("synthesize", chain / "graph.h5", "-o", tmp_path / "b.h5", "-n", 2, "-m", 20,
                          "--obstacle", tmp_path / "box.obj"), "every one of the clip's")
    assert not (tmp_path / "o.h5").exists() and not (tmp_path / "b.h5").exists()


def test_a_model_file_cannot_declare_more_than_it_holds(chain, tmp_path):
    forged = tmp_path / "forged.h5"
    forged.write_bytes((chain / "skin.h5").read_bytes())
    with h5py.File(forged, "r+") as f:
        del f["examples/vertices"]
        f.create_dataset("examples/vertices", shape=(10 ** 6, 1000, 3), dtype="f8", chunks=(1, 1000, 3))  # unwritten
    assert forged.stat().st_size < 10 ** 7
    assert_user_error(cli("inspect", forged), "forged.h5", "/examples/vertices declares 22.4 GiB")


def test_mesh_sequences_cannot_declare_more_than_they_hold(tmp_path):
    """An .npz header, an HDF5 dataset and a USD crate's shared samples are all bounded by the bytes
    the file holds, before anything is allocated."""
    import io
    import zipfile

    from pxr import Usd, UsdGeom, Vt

    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": (10 ** 5, 10 ** 5, 3)})
    faces = io.BytesIO()
    np.save(faces, np.array([[0, 1, 2]]))
    with zipfile.ZipFile(tmp_path / "npz.npz", "w") as archive:  # a header and 64 bytes of data
        archive.writestr("vertices.npy", header.getvalue() + bytes(64))
        archive.writestr("faces.npy", faces.getvalue())
    with h5py.File(tmp_path / "h5.h5", "w") as f:
        f.create_dataset("vertices", shape=(10 ** 5, 10 ** 4, 3), dtype="f8", chunks=(1, 10 ** 4, 3))  # unwritten
        f["faces"] = [[0, 1, 2]]
    stage = Usd.Stage.CreateNew(str(tmp_path / "usd.usdc"))
    mesh = UsdGeom.Mesh.Define(stage, "/mesh")
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    points = Vt.Vec3fArray.FromNumpy(np.random.default_rng(0).random((10 ** 4, 3), dtype=np.float32))
    attribute = mesh.CreatePointsAttr()
    for code in range(3000):  # the crate stores the array once: 3000 samples cost 8 bytes each
        attribute.Set(points, code)
    stage.Save()
    for name, what in [("npz.npz", "'vertices' declares 223.5 GiB"), ("h5.h5", "'vertices' declares 22.4 GiB"),
                       ("usd.usdc", "3000 samples of 10000 points declares 0.7 GiB")]:
        assert os.path.getsize(tmp_path / name) < 10 ** 6
        assert_user_error(cli("fit-skin", tmp_path / name, "-o", tmp_path / "out.h5", "--bones", 2), name, what)
    assert not (tmp_path / "out.h5").exists()


# ``skinsynth`` whose example command meets a library warning while it works (numpy's overflow in
# a float32 product, as a hostile input would cause): its bending_bar is wrapped to do one first.
WARNING_SKINSYNTH = [sys.executable, "-c", "import sys; import numpy as np; import skinsynth.pipeline.inputs.examples as ex; "
                                           "bar = ex.bending_bar; ex.bending_bar = lambda **options: "
                                           "(np.float32(1e30) * np.float32(1e30), bar(**options))[1]; "
                                           "from skinsynth.cli.main import main; sys.argv[0] = 'skinsynth'; "
                                           "sys.exit(main())"]


def test_library_warnings_stay_off_a_commands_stderr_unless_asked(monkeypatch, tmp_path):
    import warnings

    from skinsynth.cli.main import _warnings_policy

    monkeypatch.delenv("SKINSYNTH_WARNINGS", raising=False)
    monkeypatch.setattr(sys, "warnoptions", [])
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")  # what the policy does not hide would be recorded here
        with _warnings_policy():
            warnings.warn("overflow encountered in cast", RuntimeWarning)  # the suite's filter would make it an error
            np.float32(1e30) * np.float32(1e30)
    assert seen == []
    monkeypatch.setenv("SKINSYNTH_WARNINGS", "1")
    with pytest.warns(RuntimeWarning), _warnings_policy():
        warnings.warn("shown when asked", RuntimeWarning)
    # a real command, as a user runs it: quiet by default; SKINSYNTH_WARNINGS=1 or Python's -W shows the warning
    plain = {k: v for k, v in os.environ.items() if k not in ("SKINSYNTH_WARNINGS", "PYTHONWARNINGS")}
    for name, python, env in (("quiet", [], plain), ("asked", [], {**plain, "SKINSYNTH_WARNINGS": "1"}),
                              ("python-w", ["-W", "default"], plain)):
        out = tmp_path / f"{name}.npz"
        done = subprocess.run(WARNING_SKINSYNTH[:1] + python + WARNING_SKINSYNTH[1:] + [
            "example", "bending-bar", "-o", str(out), "--frames", "4", "--rings", "2", "--segments", "3", "-q"],
            capture_output=True, text=True, env=env)
        assert done.returncode == 0 and done.stdout == "" and out.is_file(), done.stderr
        if name == "quiet":
            assert done.stderr == ""
        else:
            assert "RuntimeWarning: overflow encountered in scalar multiply" in done.stderr, done.stderr


def test_controls_beyond_float32_range_are_refused(chain, tmp_path):
    controls = np.zeros((3, 4, 3))
    controls[1, 2, 0] = 1e20
    np.save(tmp_path / "far.npy", controls)
    assert_user_error(cli("play", chain / "puppet.h5", "-c", tmp_path / "far.npy", "-o", tmp_path / "o.h5"),
                      "far.npy", "frame 1, point 2", "float32", folder=tmp_path, keep=["far.npy"])


# -- requests that would allocate without bounds (issue 27, group 3) -------------------------------

@pytest.mark.parametrize("args, needle", [
    (["synthesize", "{graph.h5}", "-o", "{out}/b.h5", "-n", 1000000000, "-m", 600], "1000000000 animations × 600"),
    (["synthesize", "{graph.h5}", "-o", "{out}/b.h5", "-n", 100000000, "-m", 600, "--crowd", "{out}/c.usdc"],
     "100000000 animations"),
    (["play", "{puppet.h5}", "-c", "{controls.csv}", "--instances", 10000000000, "-o", "{out}/p.h5"],
     "10000000000 character(s)"),
    (["example", "bending-bar", "-o", "{out}/x.npz", "--frames", 1000000000], "1000000000 frames"),
], ids=["synthesize 1e9", "synthesize 1e8 crowd", "play 1e10 instances", "example 1e9 frames"])
def test_a_request_larger_than_memory_is_refused_before_allocating(chain, tmp_path, args, needle):
    """Each asks for terabytes (more than any machine has): refused in one line, nothing written."""
    args = [str(chain / a[1:-1]) if isinstance(a, str) and a.startswith("{") and a != "{out}" and "{out}" not in a
            else (a.replace("{out}", str(tmp_path)) if isinstance(a, str) else a) for a in args]
    assert_user_error(cli(*args), needle, "GiB of memory", "ask for fewer", folder=tmp_path)


def test_a_preview_larger_than_memory_and_endless_transform_steps_are_refused(chain, tmp_path):
    many = [a for _ in range(64) for a in ("--animation", 0)]
    assert_user_error(cli("preview", chain / "bones.h5", "-o", tmp_path / "p.gif", "--size", "8192x8192", *many),
                      "64 panel(s) at 8192×8192", "GiB of memory", folder=tmp_path)
    assert_user_error(cli("fit-skin", chain / "bar.npz", "-o", tmp_path / "s.h5", "--bones", 3, "--transform-steps",
                          1000000000), "--transform-steps 1000000000", "at most 100", folder=tmp_path)


def test_a_fit_with_more_bones_than_memory_holds_is_refused_before_it_starts(tmp_path):
    """Issue 27: fit-skin --bones 8000 on the 8,431-vertex horse grew past 2.5 GB with no estimate.
    Its bone-pair sums grow as B²: 200,000 bones on a 200,000-vertex mesh would need ~20 TB."""
    from skinsynth.pipeline.skin import fit_memory_bytes

    rng = np.random.default_rng(0)
    vertices = rng.normal(size=(2, 200_000, 3))
    np.savez(tmp_path / "cloud.npz", vertices=vertices, faces=np.array([[0, 1, 2]]), fps=24.0)
    assert_user_error(cli("fit-skin", tmp_path / "cloud.npz", "-o", tmp_path / "s.h5", "--bones", 200_000),
                      "--bones 200000 on 200000 vertices × 2 frames", "GiB of memory", "ask for fewer",
                      folder=tmp_path, keep=["cloud.npz"])
    assert fit_memory_bytes(48, 8431, 2000) > fit_memory_bytes(48, 8431, 1000) > fit_memory_bytes(48, 8431, 100)
    assert fit_memory_bytes(48, 8431, 8000) > 30 * 2 ** 30  # the campaign's request: over 30 GiB


def test_synthesize_single_component_rebuilds_what_build_graph_would_store(chain, tmp_path):
    """synthesize --single-component on a two-component graph analyses the rig again as one, with
    the options the graph file records: the same animations as from build-graph --single-component."""
    assert_ok(cli("build-graph", chain / "skin.h5", "-o", tmp_path / "one.h5", "--min-segment", 4, "--edge-threshold",
                  0.5, "--single-component", "-q"))
    for graph, extra, out in ((chain / "graph.h5", ["--single-component"], "rebuilt.h5"), (tmp_path / "one.h5", [],
                                                                                              "stored.h5")):
        assert_ok(cli("synthesize", graph, "-o", tmp_path / out, "-n", 3, "-m", 40, "--seed", 2, "-q", *extra))
    with h5py.File(tmp_path / "rebuilt.h5") as a, h5py.File(tmp_path / "stored.h5") as b:
        assert a["synthesis/bone_matrices"].shape[1:] == (40, 6, 3, 3)
        for name in ("bone_matrices", "bone_translations", "sources"):
            assert np.array_equal(a[f"synthesis/{name}"][()], b[f"synthesis/{name}"][()]), name
