"""Shared test set-up: warp's kernel cache in a per-run folder, where the real data lives, and the
stage files of small bending bars (``stage_files``) and of the real captures, built once per run.

``make test`` runs the suite on every core (pytest-xdist): each worker is a session of its own,
so what is expensive to build (stage files, fits of the real captures) is built once per run by
whichever worker asks first, under a file lock, in a folder every worker sees (:func:`built_once`),
and read by the others. Known-slow tests are handed out first (``SLOW_FIRST``), so no worker is
left with a long one at the end."""

import os
import pathlib

import pytest

from shared_builds import built_once, run_folder

SHARED_DATA = pathlib.Path(__file__).resolve().parents[1].parent / "shared" / "data"


def pytest_configure(config):
    # Before any test imports warp: keep compiled kernels out of the user's cache folder.
    os.environ.setdefault("SKINSYNTH_CACHE_DIR", str(pathlib.Path(config.rootpath) / "build" / "test-warp-cache"))
    # Commands keep Python's warning filters, so the suite's "every warning is an error" reaches
    # them in-process, and a command run as a process prints any warning it meets (tests then see
    # more than one stderr line).
    os.environ["SKINSYNTH_WARNINGS"] = "1"
    if getattr(config.option, "numprocesses", None) and not os.environ.get("PYTEST_XDIST_WORKER"):
        # A worker per core (make test): each worker's BLAS, and the commands it starts, on one
        # thread unless the caller chose (two BLAS threads per worker only wait for each other:
        # measured 329 s -> 312 s for the whole suite on 2 cores). The tests of results whatever
        # the BLAS threads set them themselves.
        for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ.setdefault(name, "1")


@pytest.fixture(scope="session")
def shared_data():
    """The real sequences in ../shared/data; skips the test when they are not there."""
    if not SHARED_DATA.is_dir() or not any(SHARED_DATA.iterdir()):
        pytest.skip(f"real data not found at {SHARED_DATA} (read-only folder beside the checkout)")
    return SHARED_DATA


# -- stage files -----------------------------------------------------------------------------------

#: Each stage file the factory makes: the file it reads and the command that writes it.
STAGES = {"skin.h5": ("bar.npz", "fit-skin"), "controls.h5": ("skin.h5", "select-controls"),
          "puppet.h5": ("controls.h5", "train-kcca"), "graph.h5": ("skin.h5", "build-graph"),
          "bones.h5": ("graph.h5", "synthesize")}


class Stages:
    """One recipe's stage files, all in ``folder``: bar.npz (the bending bar, whose ``vertices``
    (F, V, 3) and ``faces`` (T, 3) are kept here too), skin.h5 and those the recipe asked for.
    Shared by every test that asks for the same recipe: read them, never change them (a test that
    must, works on ``copy_to(its folder)``)."""

    def __init__(self, folder, names, vertices, faces):
        self.folder, self.names, self.vertices, self.faces = folder, tuple(names), vertices, faces

    def __truediv__(self, name):
        return self.folder / name

    def copy_to(self, folder):
        """Copies of the stage files in ``folder`` (made if needed), for a test or a module that
        changes them or writes beside them; returns ``folder``."""
        import shutil

        folder.mkdir(parents=True, exist_ok=True)
        for name in self.names:
            shutil.copyfile(self.folder / name, folder / name)
        return folder


class StageFiles:
    """``stage_files(frames=, bones=, iterations=, cycles=1, rings=10, segments=8, controls=None,
    puppet=None, graph=None, synthesis=None)``: the stage files of a small bending bar (``rings`` ×
    ``segments`` vertices, ``frames`` frames, ``cycles`` bend-and-twist cycles, at 24 fps) fitted
    with ``fit-skin --bones --iterations``, and, for each of the other options given (a tuple of
    command-line options; ``()`` for the defaults), controls.h5 (``select-controls``), puppet.h5
    (``train-kcca``, from controls.h5), graph.h5 (``build-graph``) and bones.h5 (``synthesize``,
    from graph.h5). Each recipe is built once per run (whatever the number of xdist workers); a
    file two recipes share (same file, same options, same inputs) is made once and copied. The
    files must stay as they were built: the session ends with an error naming any that a test
    changed, removed or added."""

    def __init__(self, tmp_path_factory):
        self.factory, self.recipes, self.digests = tmp_path_factory, {}, {}

    def __call__(self, *, frames, bones, iterations, cycles=1, rings=10, segments=8, controls=None, puppet=None,
                 graph=None, synthesis=None):
        options = {"skin.h5": ("--bones", bones, "--iterations", iterations), "controls.h5": controls,
                   "puppet.h5": puppet, "graph.h5": graph, "bones.h5": synthesis}
        keys = {"bar.npz": ("bar.npz", frames, rings, segments, cycles)}  # a file's key: its recipe and its inputs'
        for name, (source, command) in STAGES.items():
            if options[name] is not None:
                if source not in keys:
                    raise ValueError(f"{name} ({command}) reads {source}: ask for it too")
                keys[name] = (name, tuple(str(o) for o in options[name]), keys[source])
        recipe = tuple(keys.values())
        if recipe not in self.recipes:
            self.recipes[recipe] = self._build(recipe, keys, options)
        return self.recipes[recipe]

    def _build(self, recipe, keys, options):
        """The recipe's folder (named by its digest), built once per run, by this worker or read
        from the one that built it; each file's digest is taken here, for :meth:`changed`."""
        import shutil

        from skinsynth.pipeline.inputs.examples import bending_bar

        def build(folder):
            for name, key in keys.items():
                shutil.copyfile(self._file(name, key, keys, options), folder / name)
            return sorted(keys)

        name = f"recipe_{_digest(recipe)}"
        built_once(self.factory, name, build)
        folder = run_folder(self.factory) / name
        for file in keys:
            self.digests[folder / file] = _sha256(folder / file)
        _, frames, rings, segments, cycles = keys["bar.npz"]
        vertices, faces = bending_bar(frames=frames, rings=rings, segments=segments, cycles=cycles)
        return Stages(folder, keys, vertices, faces)

    def _file(self, name, key, keys, options):
        """The path of one stage file, made once per run whatever the recipes that share it (same
        file, same options, same inputs: the same ``key``), its source made first."""
        from cli_helpers import assert_ok, cli
        from skinsynth.formats.meshseq import write_array_sequence
        from skinsynth.pipeline.inputs.examples import bending_bar

        def make(folder):
            if name == "bar.npz":
                _, frames, rings, segments, cycles = key
                vertices, faces = bending_bar(frames=frames, rings=rings, segments=segments, cycles=cycles)
                write_array_sequence(folder / name, vertices, faces, 24.0)
            else:
                source, command = STAGES[name]
                read = self._file(source, keys[source], keys, options)
                assert_ok(cli(command, read, "-o", folder / name, *options[name], "-q"))
            return name

        stored = f"file_{_digest(key)}"
        built_once(self.factory, stored, make)
        return run_folder(self.factory) / stored / name

    def changed(self):
        """The stage files (and strays beside them) not as built, one line each."""
        problems = []
        for path, digest in self.digests.items():
            if not path.exists():
                problems.append(f"{path}: removed")
            elif _sha256(path) != digest:
                problems.append(f"{path}: changed")
        for stages in self.recipes.values():
            problems += [f"{stages / name}: added" for name in os.listdir(stages.folder) if name not in stages.names]
        return problems


def _digest(key):
    """A short name for a recipe or a file's key (its repr digested)."""
    import hashlib

    return hashlib.sha256(repr(key).encode()).hexdigest()[:16]


def _sha256(path):
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="session")
def stage_files(tmp_path_factory):
    """The session's :class:`StageFiles` factory; at the end, an error if a test changed its files."""
    factory = StageFiles(tmp_path_factory)
    yield factory
    problems = factory.changed()
    assert not problems, "tests changed shared stage files (give them stage_files(…).copy_to(tmp_path)):\n" + \
        "\n".join(problems)


@pytest.fixture(scope="session")
def horse_clips(shared_data, tmp_path_factory):
    """The shared horse's gallop and collapse fitted together (22 bones, defaults), once per
    run: (the clip folder, the skin file, fit-skin's --json summary). A copy may be changed;
    the file itself must not be. Skips when the clips are absent."""
    import json

    from cli_helpers import assert_ok, cli

    folder = shared_data / "horse_clips"
    if not (folder / "horse_gallop.npz").is_file() or not (folder / "horse_collapse.npz").is_file():
        pytest.skip(f"the shared horse clips (gallop, collapse) are not in {folder}")

    def fit(out):
        return json.loads(assert_ok(cli("fit-skin", folder / "horse_gallop.npz", folder / "horse_collapse.npz", "-o",
                                         out / "skin.h5", "--bones", 22, "--json")).stdout)

    summary = built_once(tmp_path_factory, "horse_clips", fit)
    return folder, run_folder(tmp_path_factory) / "horse_clips" / "skin.h5", summary


@pytest.fixture(scope="session")
def horse_skeleton(shared_data, tmp_path_factory):
    """The shared horse gallop fitted with a skeleton (``fit-skin --bones 22 --skeleton``), once
    per run: (its skin file, fit-skin's --json summary). Read it, never change it. Skips when the
    gallop is absent."""
    import json

    from cli_helpers import assert_ok, cli

    gallop = shared_data / "horse_gallop" / "horse_gallop.npz"
    if not gallop.is_file():
        pytest.skip(f"{gallop} is absent")

    def fit(out):
        return json.loads(assert_ok(cli("fit-skin", gallop, "-o", out / "horse.h5", "--bones", 22, "--skeleton",
                                         "--json", "-q")).output)

    summary = built_once(tmp_path_factory, "horse_skeleton", fit)
    return run_folder(tmp_path_factory) / "horse_skeleton" / "horse.h5", summary


def _capture_skin(shared_data, tmp_path_factory, capture):
    """The shared ``capture`` (vlasic_samba, vlasic_crane) fitted as a user fits it (``fit-skin --bones 22
    --seed 0``), once per run: its skin file. Skips when the capture is absent."""
    from cli_helpers import assert_ok, cli

    source = shared_data / capture / f"{capture}.npz"
    if not source.is_file():
        pytest.skip(f"{source} is absent")

    def fit(out):
        assert_ok(cli("fit-skin", source, "-o", out / "skin.h5", "--bones", 22, "--seed", 0, "-q"))

    key = f"{capture.split('_')[-1]}_skin"
    built_once(tmp_path_factory, key, fit)
    return run_folder(tmp_path_factory) / key / "skin.h5"


@pytest.fixture(scope="session")
def samba_skin(shared_data, tmp_path_factory):
    """The shared samba's skin file (:func:`_capture_skin`). Read it, never change it."""
    return _capture_skin(shared_data, tmp_path_factory, "vlasic_samba")


@pytest.fixture(scope="session")
def crane_skin(shared_data, tmp_path_factory):
    """The shared crane's skin file (:func:`_capture_skin`). Read it, never change it."""
    return _capture_skin(shared_data, tmp_path_factory, "vlasic_crane")


@pytest.fixture(scope="session")
def dancer_graph(shared_data, tmp_path_factory):
    """Zheng's own dancer (``geomvideo_dance``) fitted and analysed as a user would (``fit-skin
    --bones 27 --seed 0``, ``build-graph`` at its defaults: four components), once per run: its
    graph file. Read it, never change it. Skips when the capture is absent."""
    from cli_helpers import assert_ok, cli

    capture = shared_data / "geomvideo_dance" / "geomvideo_dance.npz"
    if not capture.is_file():
        pytest.skip(f"{capture} is absent")

    def build(out):
        assert_ok(cli("fit-skin", capture, "-o", out / "skin.h5", "--bones", 27, "--seed", 0, "-q"))
        assert_ok(cli("build-graph", out / "skin.h5", "-o", out / "graph.h5", "-q"))

    built_once(tmp_path_factory, "dancer_graph", build)
    return run_folder(tmp_path_factory) / "dancer_graph" / "graph.h5"


@pytest.fixture(scope="session")
def jointed_skins(tmp_path_factory):
    """Skins whose rig is a joint tree (fit-skin --skeleton), once per run, in one folder:
    walker.npz (the walker example, two gait cycles in 32 frames, 648 vertices), skin.h5 (10 bones,
    every bone jointed), free.h5 (the same with --max-joint-drift 0.0003: some bones have no fixed
    joint and slide on a neighbour) and zup.h5 (skin.h5's fit recorded Z up in centimetres). A test copies what it
    changes; it must not change these."""
    from cli_helpers import assert_ok, cli


    def fit(folder):
        assert_ok(cli("example", "walker", "-o", folder / "walker.npz", "--frames", 32, "--cycles", 2, "--rings", 12,
                      "-q"))
        fit = ("--bones", 10, "--skeleton", "--iterations", 20, "-q")
        assert_ok(cli("fit-skin", folder / "walker.npz", "-o", folder / "skin.h5", *fit))
        assert_ok(cli("fit-skin", folder / "walker.npz", "-o", folder / "free.h5", *fit, "--max-joint-drift", 0.0003))
        assert_ok(cli("fit-skin", folder / "walker.npz", "-o", folder / "zup.h5", *fit, "--up-axis", "Z",
                      "--meters-per-unit", 0.01))

    built_once(tmp_path_factory, "jointed", fit)
    return run_folder(tmp_path_factory) / "jointed"


# The warp devices of the kernel tests: a test taking ``device`` runs once per device here.
import functools  # noqa: E402 (this block stands alone)


@functools.cache
def _warp_devices():
    """["cpu"], plus "cuda:0" where warp sees a GPU (warp is imported on the first call only)."""
    from skinsynth.gpu import available_devices

    return ["cpu"] + (["cuda:0"] if "cuda:0" in available_devices() else [])


def pytest_generate_tests(metafunc):
    if "device" in metafunc.fixturenames:
        metafunc.parametrize("device", _warp_devices(), indirect=True)


@pytest.fixture
def device(request):
    """A warp device name, "cpu" or "cuda:0": each kernel test runs on every one present."""
    return request.param


@pytest.fixture(scope="session")
def samba_marker_puppet(shared_data, samba_skin, tmp_path_factory):
    """The shared samba's puppet on the controls of the committed Plug-in-Gait layout
    (docs/markers/vlasic_samba.layout.json), once per run: the skin of ``samba_skin`` (fit-skin
    --bones 22), select-controls --markers, train-kcca --correctives off (its .glb plays in any
    engine). -> (folder with skin.h5 and puppet.h5, the layout's path). Skips without the capture
    or the takes."""
    import shutil

    from cli_helpers import assert_ok, cli

    if not (shared_data / "mocap_c3d").is_dir():
        pytest.skip(f"the mocap_c3d takes are needed in {shared_data}")
    layout = pathlib.Path(__file__).resolve().parents[1] / "docs" / "markers" / "vlasic_samba.layout.json"

    def build(folder):
        shutil.copyfile(samba_skin, folder / "skin.h5")
        assert_ok(cli("select-controls", folder / "skin.h5", "-o", folder / "controls.h5", "--markers", layout, "-q"))
        assert_ok(cli("train-kcca", folder / "controls.h5", "-o", folder / "puppet.h5", "--correctives", "off", "-q"))

    built_once(tmp_path_factory, "samba_markers", build)
    return run_folder(tmp_path_factory) / "samba_markers", layout


#: Test files handed out first: the slowest of the suite (whole-tool contracts, the browser and
#: precompile tests) and any file with a slow real-data test. With a worker per core, a long test
#: started last would leave the other cores idle while it runs.
SLOW_FIRST = ("tests/contracts/", "tests/cli/test_view.py", "tests/cli/test_precompile.py")


def pytest_collection_modifyitems(config, items):
    """Orders the run: the files of ``SLOW_FIRST`` and those with a ``slow`` test first, each file's
    tests kept together and in their order (so module fixtures are built once per worker)."""
    slow_files = {item.nodeid.split("::")[0] for item in items if item.get_closest_marker("slow")}

    def slow(item):
        path = item.nodeid.split("::")[0]
        return path in slow_files or any(path.startswith(prefix) for prefix in SLOW_FIRST)

    items[:] = [item for item in items if slow(item)] + [item for item in items if not slow(item)]
