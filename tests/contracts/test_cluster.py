"""synthesize --cluster: real Dask clusters (worker processes) give the single-machine datasets,
survive a worker killed mid-run, resume from finished shards, and refuse what cannot work."""

import json
import logging
import os
import shutil

import h5py
import numpy as np
import pytest
from distributed import WorkerPlugin

from skinsynth.formats.model import content_digests
from skinsynth.pipeline.runtime.execution import StoredRows, concatenate_rows

from cli_helpers import assert_ok, assert_user_error, cli

COUNT, FRAMES = 600, 60  # three batches: 250, 250, 100


@pytest.fixture(scope="module")
def graph(stage_files):
    return stage_files(frames=40, bones=4, iterations=10, cycles=2, graph=("--min-segment", 4)) / "graph.h5"


@pytest.fixture(scope="module")
def reference(graph, tmp_path_factory):
    """The single-machine run every cluster run must equal."""
    out = tmp_path_factory.mktemp("reference") / "one.h5"
    assert_ok(cli("synthesize", graph, "-o", out, "-n", COUNT, "-m", FRAMES, "--seed", 4, "--jobs", 1, "-q"))
    return out


def contents(path):
    """sha256 of every dataset and attribute but the provenance's (formats.model.content_digests)."""
    return content_digests(path)


def run_cluster(graph, out, address, *extra):
    done = assert_ok(cli("synthesize", graph, "-o", out, "-n", COUNT, "-m", FRAMES, "--seed", 4, "--cluster", address,
                         "--json", *extra))
    return json.loads(done.stdout)


def shards_of(out):
    return sorted(p for p in (out.parent / (out.name + ".shards")).iterdir() if not p.name.startswith("."))


def test_a_local_cluster_gives_the_single_machine_datasets(graph, reference, tmp_path):
    out = tmp_path / "many.h5"
    summary = run_cluster(graph, out, "local:2")
    assert summary["cluster"]["workers"] == 2 and summary["cluster"]["tasks"] == 3
    assert summary["cluster"]["retries"] == 0 and summary["cluster"]["reused_batches"] == 0
    assert contents(out) == contents(reference)
    with h5py.File(out) as f:  # the motions are the shards' rows, not copies
        assert f["synthesis/bone_matrices"].is_virtual and f["synthesis/bone_translations"].is_virtual
    assert len(shards_of(out)) == 3
    # every reader works on it as on any synthesis file; inspect --digests shows it is the same data
    summary = json.loads(assert_ok(cli("inspect", out, "--json", "--digests")).stdout)
    assert summary["stage"] == "synthesis" and summary["digests"] == contents(reference)
    from skinsynth.formats.model import read_model

    partial = read_model(out, groups=("skin",))  # a reader that needs the skin leaves the motions alone
    assert "skin" in partial and "synthesis" not in partial
    listed = assert_ok(cli("inspect", reference, "--digests")).stdout
    assert f"{summary['digests']['synthesis/bone_matrices']}  synthesis/bone_matrices" in listed.splitlines()


@pytest.fixture(scope="module")
def scheduler():
    """A running local cluster (2 worker processes) addressed as a remote one: tcp://…"""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, silence_logs=logging.ERROR,
                      dashboard_address=":0") as cluster:
        yield cluster


class KillFirstTask(WorkerPlugin):
    """A worker plugin: the first worker to start a skinsynth batch dies on the spot (os._exit),
    once (a marker file says it happened); its nanny starts a fresh worker."""

    def __init__(self, marker):
        self.marker = marker

    def transition(self, key, start, finish, **kwargs):
        if finish == "executing" and "skinsynth-batch" in str(key):
            try:  # created or not in one step: of two workers starting batches at once, one dies
                os.close(os.open(self.marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            except FileExistsError:
                return
            os._exit(1)


def test_a_worker_killed_mid_run_loses_nothing(graph, reference, scheduler, tmp_path):
    from distributed import Client

    marker = tmp_path / "killed"
    with Client(scheduler) as client:
        client.register_plugin(KillFirstTask(str(marker)), name="kill-first-task")
        try:
            summary = run_cluster(graph, tmp_path / "many.h5", scheduler.scheduler_address)
        finally:
            client.unregister_worker_plugin("kill-first-task")
    assert marker.exists()  # a worker did die mid-batch …
    assert summary["cluster"]["retries"] >= 1
    assert contents(tmp_path / "many.h5") == contents(reference)  # … and nothing was lost or duplicated
    assert len(shards_of(tmp_path / "many.h5")) == 3


def test_a_rerun_reuses_finished_shards_by_their_provenance(graph, reference, scheduler, tmp_path):
    out = tmp_path / "many.h5"
    run_cluster(graph, out, scheduler.scheduler_address)
    first, second, third = shards_of(out)
    # an interruption: the output never written, one batch unfinished; a shard renamed (names are not trusted)
    os.remove(out)
    os.remove(second)
    os.rename(third, third.with_name("renamed.h5"))
    # a shard of another run (another seed) in the folder is not taken for one of this run
    other = tmp_path / "other.h5"
    run_cluster(graph, other, scheduler.scheduler_address, "--seed", 5)
    alien = shards_of(other)[1]
    shutil.copy(alien, second.with_name(alien.name))
    summary = run_cluster(graph, out, scheduler.scheduler_address)
    assert summary["cluster"]["reused_batches"] == 2 and summary["cluster"]["tasks"] == 1
    assert contents(out) == contents(reference)
    names = sorted(p.name for p in shards_of(out))
    assert "renamed.h5" in names and alien.name not in names  # the other run's shard is cleared away
    # the same command once more computes nothing
    again = run_cluster(graph, out, scheduler.scheduler_address)
    assert again["cluster"]["tasks"] == 0 and again["cluster"]["reused_batches"] == 3


def test_an_interrupted_run_leaves_its_finished_shards_and_resumes_from_them(graph, reference, tmp_path):
    """A run stopped (SIGTERM) with one batch stored and the rest still to come. Its worker runs
    tests/cluster_hold.py: it stores its first batch and holds the next (made, not stored) until it
    is closed, so the run cannot finish before the signal lands, nor store a second shard."""
    import hashlib
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "many.h5"
    command = [sys.executable, "-c", "import sys; from skinsynth.cli.main import main; sys.exit(main())",
               "synthesize", str(graph), "-o", str(out), "-n", str(COUNT), "-m", str(FRAMES), "--seed", "4",
               "--cluster", "local:1", "-q"]
    hold = os.path.join(os.path.dirname(__file__), "cluster_hold.py")
    held = tmp_path / "held"  # made by the worker once it holds its second batch
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env={**os.environ, "DASK_DISTRIBUTED__WORKER__PRELOAD": json.dumps([hold]),
                                    "CLUSTER_HOLD_MARKER": str(held)})
    folder = tmp_path / "many.h5.shards"
    try:
        deadline = time.monotonic() + 120
        while not (held.exists() and any(p.name.startswith("batch_") for p in folder.iterdir())):
            assert process.poll() is None, f"the run ended (exit {process.returncode}) before it was held"
            assert time.monotonic() < deadline, "no shard and held batch within 120 s"
            time.sleep(0.02)
        assert process.poll() is None  # still going: a batch made and held, unstored, until its worker closes
        process.send_signal(signal.SIGTERM)
        _, stderr = process.communicate(timeout=120)
    finally:
        process.kill()  # a no-op when it has ended
        process.communicate()
    assert process.returncode == 128 + signal.SIGTERM, stderr
    assert stderr.strip().splitlines() == ["skinsynth: interrupted (SIGTERM); no output written"], stderr
    assert not out.exists()
    [finished] = shards_of(out)  # the first batch's, and no other
    kept = hashlib.sha256(finished.read_bytes()).hexdigest()
    summary = run_cluster(graph, out, "local:1")
    assert summary["cluster"]["reused_batches"] == 1 and summary["cluster"]["tasks"] == 2
    assert finished in shards_of(out) and hashlib.sha256(finished.read_bytes()).hexdigest() == kept
    assert len(shards_of(out)) == 3
    assert contents(out) == contents(reference)


def test_min_difference_rounds_on_a_cluster_equal_the_single_machine(graph, tmp_path):
    args = ("-n", 260, "-m", 60, "--seed", 9, "--min-difference", 0.05)
    assert_ok(cli("synthesize", graph, "-o", tmp_path / "one.h5", "--jobs", 1, "-q", *args))
    summary = json.loads(assert_ok(cli("synthesize", graph, "-o", tmp_path / "many.h5", "--cluster", "local:2",
                                       "--json", *args)).stdout)
    assert contents(tmp_path / "one.h5") == contents(tmp_path / "many.h5")
    # the case where rows are dropped across batches and replaced by a second round of batches
    assert summary["rejected"]["too_similar"] > 0 and summary["cluster"]["tasks"] > 2


def test_caches_of_a_cluster_run_are_the_single_machine_caches(graph, tmp_path):
    from skinsynth.formats.usd import read_points_cache

    for name, where in (("one", ("--jobs", 1)), ("many", ("--cluster", "local:1"))):
        assert_ok(cli("synthesize", graph, "-o", tmp_path / f"{name}.h5", "-n", 3, "-m", 20, "--seed", 1,
                      "--crowd", tmp_path / f"{name}.usda", "--device", "cpu", "-q", *where))
    for a in range(3):
        one, _, _ = read_points_cache(tmp_path / "one.usda", prim=f"/characters/animation_{a:04d}")
        many, _, _ = read_points_cache(tmp_path / "many.usda", prim=f"/characters/animation_{a:04d}")
        assert np.array_equal(one, many)


def test_a_missing_shard_is_an_error_not_zeros(graph, tmp_path):
    out = tmp_path / "many.h5"
    assert_ok(cli("synthesize", graph, "-o", out, "-n", 3, "-m", 20, "--cluster", "local:1", "-q"))
    [shard] = shards_of(out)
    os.remove(shard)
    assert_user_error(cli("inspect", out), "many.h5", shard.name, "missing")


@pytest.mark.parametrize("address, needle", [("local:0", "local:N"), ("local:two", "local:N"),
                                             ("nonsense:port", "not a scheduler address"),
                                             ("tcp://127.0.0.1:1", "cannot reach"), ("", "needs an address"),
                                             ("local:100000", "worker processes")])
def test_a_bad_cluster_address_is_one_line_and_leaves_nothing(graph, tmp_path, address, needle):
    assert_user_error(cli("synthesize", graph, "-o", tmp_path / "o.h5", "-n", 3, "-m", 20, "--cluster", address),
                      address, needle, folder=tmp_path)


def test_shards_larger_than_the_free_disk_are_refused_before_any_batch_and_reused_ones_count_for_nothing(
        graph, reference, scheduler, tmp_path, monkeypatch):
    """Issue 25: the shards and the output, estimated from the request's shapes, against the shard
    folder's free space (one disk here: they add up), before any batch runs; on a rerun the shards
    an earlier run finished need no space."""
    import shutil

    from skinsynth.formats.synthesis_shards import shard_bytes

    out = tmp_path / "many.h5"
    usage = shutil.disk_usage
    with h5py.File(graph) as f:
        components = int(f["graph"].attrs["components"])
    one_shard = shard_bytes(250, FRAMES, 4, components)
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(path)._replace(free=2 * one_shard))
    line = assert_user_error(cli("synthesize", graph, "-o", out, "-n", COUNT, "-m", FRAMES, "--seed", 4, "--cluster",
                                 scheduler.scheduler_address), "not enough space", f"of disk in {tmp_path} ",
                             f"its shards {(2 * one_shard + shard_bytes(100, FRAMES, 4, components)) / 2 ** 20:.1f} MiB "
                             f"in {out}.shards", f"{2 * one_shard / 2 ** 20:.1f} MiB is free", folder=tmp_path)
    assert "the output" in line
    monkeypatch.setattr(shutil, "disk_usage", usage)
    run_cluster(graph, out, scheduler.scheduler_address)
    os.remove(out)
    os.remove(shards_of(out)[0])  # an interruption: one batch of 250 left to make
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(path)._replace(free=2 * one_shard))
    summary = run_cluster(graph, out, scheduler.scheduler_address)
    assert summary["cluster"]["reused_batches"] == 2 and contents(out) == contents(reference)


def test_content_digests_see_values_not_storage(tmp_path):
    from skinsynth.formats.model import Uncompressed, write_model

    values = np.random.default_rng(1).normal(size=(300, 4)).astype(np.float32)
    for name, stored in (("packed.h5", values), ("plain.h5", Uncompressed(values))):  # gzip vs contiguous
        write_model(tmp_path / name, "skin", {"skin": {"rotations": stored, "@bones": 4}}, [], "test")
    changed = values.copy()
    changed[299, 3] = np.nextafter(changed[299, 3], np.float32(np.inf))
    write_model(tmp_path / "changed.h5", "skin", {"skin": {"rotations": changed, "@bones": 4}}, [], "test")
    write_model(tmp_path / "attribute.h5", "skin", {"skin": {"rotations": values, "@bones": 5}}, [], "test")
    packed = content_digests(tmp_path / "packed.h5", block_bytes=1000)  # read in blocks of 62 rows
    assert packed == content_digests(tmp_path / "plain.h5")
    assert packed["skin/rotations"] != content_digests(tmp_path / "changed.h5")["skin/rotations"]
    assert packed["skin@bones"] != content_digests(tmp_path / "attribute.h5")["skin@bones"]


def test_stored_rows_select_and_concatenate_as_arrays_do():
    rng = np.random.default_rng(0)
    for _ in range(50):
        counts = rng.integers(1, 6, size=rng.integers(1, 5))
        pieces = [(f"piece{k}", int(n)) for k, n in enumerate(counts)]
        data = {name: rng.normal(size=(n, 2)) for name, n in pieces}
        whole = np.concatenate([data[name] for name, _ in pieces])
        keep = rng.random(len(whole)) < 0.6
        parts = [StoredRows(pieces, (2,))[keep], StoredRows(pieces[:1], (2,))]
        stored = concatenate_rows(parts)
        expected = np.concatenate([whole[keep], data["piece0"]])
        assert stored.shape == expected.shape
        rebuilt = np.full(expected.shape, np.nan)
        for name, rows, first, at, length in stored.runs():
            assert rows == data[name].shape[0]
            rebuilt[at:at + length] = data[name][first:first + length]
        assert np.array_equal(rebuilt, expected)


def test_outputs_differing_only_in_suffix_keep_their_shards_apart(tmp_path):
    """take.h5 and take.hdf5 shared take.shards/ (issue 27): writing one removed the other's shards."""
    from skinsynth.formats.synthesis_shards import shard_folder

    assert shard_folder(tmp_path / "take.h5") != shard_folder(tmp_path / "take.hdf5")
    assert shard_folder(tmp_path / "take.h5") == str(tmp_path / "take.h5.shards")


def test_a_stored_shard_holding_nan_is_computed_again_not_reused(tmp_path):
    """A reused shard passes the check a fresh batch does (issue 27): NaN in a shard with the
    right key is never taken for finished work."""
    from skinsynth.formats.synthesis_shards import shard_record, stored_shards, write_synthesis_shard

    record = shard_record([{"sha256": "0" * 64}], {"seed": 0}, "test")
    count, frames, bones = 2, 5, 3
    F = np.tile(np.eye(3, dtype=np.float32), (count, frames, bones, 1, 1))
    t = np.zeros((count, frames, bones, 3), dtype=np.float32)
    rest = [np.zeros((1, count, frames), np.int64), np.zeros((count, 1), np.int64), np.zeros((count, frames), np.uint8),
            {"collisions": 0, "too_similar": 0, "merges": 0}]
    write_synthesis_shard(str(tmp_path), record, 0, count, [F, t, *rest])
    assert list(stored_shards(str(tmp_path), record, frames, bones)) == [(0, count)]
    t[1, 2, 0, 1] = np.nan
    write_synthesis_shard(str(tmp_path), record, 1, count, [F, t, *rest])
    assert list(stored_shards(str(tmp_path), record, frames, bones)) == [(0, count)]
    # made by another revision of the batch code: never reused, whatever the version says
    newer = shard_record([{"sha256": "0" * 64}], {"seed": 0}, "test", batch_revision=1)
    assert list(stored_shards(str(tmp_path), newer, frames, bones)) == []


def test_another_runs_shard_under_this_runs_name_is_refused_by_every_reader(graph, scheduler, tmp_path):
    """Issue 27: a shard of another seed planted under the name of one of this run's shards was
    read as this run's animations (inspect --digests exit 0); a shard holding NaN made preview
    render empty frames. Every reader now says so in one line."""
    out, other = tmp_path / "many.h5", tmp_path / "other.h5"
    run_cluster(graph, out, scheduler.scheduler_address)
    run_cluster(graph, other, scheduler.scheduler_address, "--seed", 5)
    mine, theirs = shards_of(out)[1], shards_of(other)[1]
    shutil.copy(theirs, mine)  # same batch, same shapes, another run's key
    for args in (("inspect", out, "--digests"), ("preview", out, "-o", tmp_path / "p.png", "--animation", 3,
                                                 "--size", "64x48")):
        assert_user_error(cli(*args), str(out), "another run's batch", folder=None)
    assert not (tmp_path / "p.png").exists()
    run_cluster(graph, out, scheduler.scheduler_address)  # a rerun makes this run's shard again
    with h5py.File(mine, "r+") as f:  # a damaged shard: this run's key, NaN motions
        f["bone_translations"][0, 0, 0, 0] = np.nan
    assert_user_error(cli("preview", out, "-o", tmp_path / "p.png", "--animation", 250, "--size", "64x48"),
                      "animation 250", "NaN")  # the first animation of the second batch
    assert not (tmp_path / "p.png").exists()


def test_a_second_run_writing_the_same_output_at_once_is_refused(graph, tmp_path):
    """Issue 27: two runs writing one output at once both exited 0 and left an output that did not
    read. The run holds a lock on its shard folder; a second one is refused in one line."""
    import fcntl

    from skinsynth.formats.synthesis_shards import LOCK, shard_folder

    out = tmp_path / "many.h5"
    folder = shard_folder(out)
    os.makedirs(folder)
    with open(os.path.join(folder, LOCK), "w") as held:  # as the first run holds it
        fcntl.flock(held, fcntl.LOCK_EX)
        assert_user_error(cli("synthesize", graph, "-o", out, "-n", 3, "-m", 20, "--cluster", "local:1"),
                          "another synthesize is writing this output")
    assert not out.exists() and os.listdir(folder) == [LOCK]
    assert_ok(cli("synthesize", graph, "-o", out, "-n", 3, "-m", 20, "--cluster", "local:1", "-q"))  # released


def test_a_scheduler_that_never_answers_does_not_keep_the_command_from_a_signal(graph, tmp_path):
    """Issue 27: --cluster tcp:// to a listener that accepts but never answers hung for minutes,
    ignoring SIGTERM (the thread reaching it was joined at exit). Now SIGTERM ends the command at
    once, with its one line."""
    import signal
    import socket
    import subprocess
    import sys
    import time

    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(8)  # accepts (the kernel does), never answers
    process = None
    try:
        address = f"tcp://127.0.0.1:{listener.getsockname()[1]}"
        command = [sys.executable, "-c", "import sys; from skinsynth.cli.main import main; sys.argv[0] = 'skinsynth'; "
                   "sys.exit(main())", "synthesize", str(graph), "-o", str(tmp_path / "o.h5"), "-n", "3", "-m", "20",
                   "--cluster", address, "-q"]
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(4)  # the graph read, the command waiting for the scheduler
        assert process.poll() is None
        started = time.monotonic()
        process.send_signal(signal.SIGTERM)
        _, stderr = process.communicate(timeout=30)
        assert time.monotonic() - started < 10
        assert process.returncode == 143 and stderr.strip().splitlines() == [
            "skinsynth: interrupted (SIGTERM); no output written"], stderr
        assert not (tmp_path / "o.h5").exists()
    finally:
        if process is not None and process.poll() is None:
            process.kill()
        listener.close()


def _synthesize_process(graph, out, address, env=None, **kwargs):
    import subprocess
    import sys

    command = [sys.executable, "-c", "import sys; from skinsynth.cli.main import main; sys.argv[0] = 'skinsynth'; "
               "sys.exit(main())", "synthesize", str(graph), "-o", str(out), "-n", str(COUNT), "-m", str(FRAMES),
               "--seed", "4", "--cluster", address, "-q"]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, **(env or {})}, **kwargs)


def _held_run(graph, out, address, tmp_path):
    """A synthesize run in its own process group whose worker stores its first batch and holds the
    next (tests/cluster_hold.py), returned once a batch is held: it cannot end on its own."""
    import time

    held = tmp_path / "held"
    hold = os.path.join(os.path.dirname(__file__), "cluster_hold.py")
    process = _synthesize_process(graph, out, address, start_new_session=True,
                                  env={"DASK_DISTRIBUTED__WORKER__PRELOAD": json.dumps([hold]),
                                       "CLUSTER_HOLD_MARKER": str(held)})
    deadline = time.monotonic() + 120
    try:
        while not held.exists():
            assert process.poll() is None, process.communicate()[1]
            assert time.monotonic() < deadline, "no batch held within 120 s"
            time.sleep(0.05)
    except BaseException:
        if process.poll() is None:
            os.killpg(process.pid, 9)
            process.communicate()
        raise
    return process


@pytest.mark.parametrize("fault, needles", [("deleted", ["does not exist"]), ("full", ["No space left"])])
def test_a_shard_folder_deleted_or_full_mid_run_is_one_line(graph, tmp_path, fault, needles):
    """Issue 27: a worker whose shard write failed was logged by Dask ("distributed.worker - ERROR -
    Compute Failed" and its traceback) on the command's stderr: seven lines before the one line.
    A batch's failure now travels to the client as a value and is raised there alone."""
    out = tmp_path / "many.h5"
    preload = os.path.join(os.path.dirname(__file__), "cluster_faults.py")
    process = _synthesize_process(graph, out, "local:1", env={"DASK_DISTRIBUTED__WORKER__PRELOAD": json.dumps([preload]),
                                                              "CLUSTER_FAULT": fault})
    _, stderr = process.communicate(timeout=300)
    lines = stderr.strip().splitlines()
    assert process.returncode == 2 and len(lines) == 1, stderr
    assert lines[0].startswith("skinsynth: error: ") and str(tmp_path / "many.h5.shards") in lines[0], lines[0]
    for needle in needles:
        assert needle in lines[0], lines[0]
    assert not out.exists()


def test_ctrl_c_to_a_local_clusters_process_group_is_one_line(graph, tmp_path):
    """Issue 27: Ctrl-C reached every worker of a local:N cluster (they share the terminal's process
    group), and each printed its event loop's KeyboardInterrupt traceback: about 60 lines before the
    command's one. The workers now ignore SIGINT (the command closes them), and none is left."""
    import signal
    import time

    out = tmp_path / "many.h5"
    process = _held_run(graph, out, "local:2", tmp_path)
    try:
        os.killpg(process.pid, signal.SIGINT)  # what a terminal's Ctrl-C does
        _, stderr = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.communicate()
    assert process.returncode == 130, stderr
    assert stderr.strip().splitlines() == ["skinsynth: interrupted (SIGINT); no output written"], stderr
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:  # the group's processes (the workers) gone with the command
        try:
            os.killpg(process.pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.2)
    else:
        pytest.fail("worker processes outlived the command")


def test_a_reader_of_the_old_output_keeps_its_shards_through_a_rerun(graph, tmp_path, monkeypatch):
    """Issue 27: inspect during a rerun failed 1 read in 4: a reader that had opened the old output
    just before the new one was renamed in found the old shards removed (HDF5 opens a virtual
    dataset's sources as it reads them, and read them as fill values). Readers hold a shared
    lock; the rerun removes old shards only under the exclusive one, or leaves them for later."""
    from skinsynth.formats import synthesis_shards
    from skinsynth.formats.synthesis_shards import reading_output

    monkeypatch.setattr(synthesis_shards, "READERS_WAIT", 0.5)
    out = tmp_path / "many.h5"
    run_cluster(graph, out, "local:1")  # seed 4
    old_shards = shards_of(out)
    with reading_output(out), h5py.File(out, "r") as old:  # a reader that opened the old output
        done = assert_ok(cli("synthesize", graph, "-o", out, "-n", COUNT, "-m", FRAMES, "--seed", 5, "--cluster",
                             "local:1"))
        assert "the old output's shards are kept" in done.stdout
        motions = old["synthesis/bone_matrices"][()]
        assert np.isfinite(motions).all() and np.abs(motions).max() > 0  # the old shards, not fill values
    assert set(old_shards) < set(shards_of(out))
    summary = json.loads(assert_ok(cli("synthesize", graph, "-o", out, "-n", COUNT, "-m", FRAMES, "--seed", 5,
                                       "--cluster", "local:1", "--json")).stdout)
    assert summary["cluster"]["reused_batches"] == 3 and not set(old_shards) & set(shards_of(out))
    assert len(shards_of(out)) == 3


def test_a_run_killed_outright_resumes_to_the_uninterrupted_datasets(graph, reference, tmp_path):
    """Issue 27 asks that a rerun after SIGKILL equal an uninterrupted run. The command and its
    local workers are killed at once (SIGKILL to the process group) while the first shard is
    stored and a second batch held unstored (tests/cluster_hold.py); the rerun reuses the stored
    shard, ignores the dead run's temporaries, and gives the reference's datasets."""
    import signal

    out = tmp_path / "many.h5"
    process = _held_run(graph, out, "local:1", tmp_path)
    try:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.communicate()
    assert process.returncode == -signal.SIGKILL and not out.exists()
    [finished] = shards_of(out)
    summary = run_cluster(graph, out, "local:1")
    assert summary["cluster"]["reused_batches"] == 1 and summary["cluster"]["tasks"] == 2
    assert contents(out) == contents(reference)
