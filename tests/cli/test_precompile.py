"""skinsynth precompile: it fills empty caches with every numba loop and warp CPU kernel, and the
commands that follow (fit-skin, preview, export, play) compile nothing more: no file is added to
or rewritten in either cache, and numba says it loaded (NUMBA_DEBUG_CACHE) and saved nothing.

The commands run as subprocesses (a process that compiled a loop already keeps it in memory) with
NUMBA_CACHE_DIR and SKINSYNTH_CACHE_DIR at new folders, so nothing of another run's caches counts.
"""

import importlib
import json
import os
import pathlib
import subprocess
import sys

from skinsynth.pipeline.runtime.compiled import dispatchers

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCRIPT = os.path.join(os.path.dirname(sys.executable), "skinsynth")


def numba_modules():
    """Every skinsynth module that imports numba (by its source), imported."""
    names = []
    for path in sorted(ROOT.glob("[cfgp]*/**/*.py")):
        if path.parts[len(ROOT.parts)] in ("cli", "formats", "gpu", "pipeline") and \
                "import numba" in path.read_text(encoding="utf-8"):
            names.append(".".join(["skinsynth", *path.relative_to(ROOT).with_suffix("").parts]))
    return [importlib.import_module(name) for name in names]


def run(caches, *args, debug=False):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(caches / "numba"), SKINSYNTH_CACHE_DIR=str(caches / "warp"))
    env.pop("NUMBA_DEBUG_CACHE", None)
    if debug:
        env["NUMBA_DEBUG_CACHE"] = "1"
    done = subprocess.run([SCRIPT, *map(str, args)], capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr
    return done.stdout


def snapshot(folder):
    """{path: (size, modification time)} of every file under folder."""
    return {path: (path.stat().st_size, path.stat().st_mtime_ns) for path in folder.rglob("*") if path.is_file()}


def test_every_numba_loop_is_cached():
    found = [d for module in numba_modules() for d in dispatchers(module)]
    assert found
    from numba.core.caching import NullCache

    assert not [d.__name__ for d in found if isinstance(d._cache, NullCache)], "numba.njit(cache=True) everywhere"


def test_precompile_fills_empty_caches_and_the_commands_then_compile_nothing(stage_files, tmp_path):
    stages = stage_files(frames=24, bones=4, iterations=8, cycles=2, controls=("--count", 6), puppet=())
    caches = tmp_path / "caches"
    (caches / "numba").mkdir(parents=True)
    (caches / "warp").mkdir()

    summary = json.loads(run(caches, "precompile", "--json"))
    assert summary["loaded"] == 0 and summary["compiled"] >= len(summary["items"])
    assert all(item["compiled"] >= 1 for item in summary["items"])
    # every numba function skinsynth defines was compiled (a loop no stage's compile_loops runs fails here)
    compiled = {name for item in summary["items"] if item["kind"] == "numba" for name in item["functions"]}
    assert compiled == {d.__name__ for module in numba_modules() for d in dispatchers(module)}
    built = snapshot(caches)
    assert len([p for p in built if p.suffix == ".nbc"]) >= len(compiled)
    assert len([p for p in built if p.suffix == ".o"]) == sum(i["kind"] == "warp" for i in summary["items"])

    out = tmp_path / "out"
    out.mkdir()
    fitted = run(caches, "fit-skin", stages / "bar.npz", "-o", out / "skin.h5", "--bones", 4, "--iterations", 2,
                 "-q", debug=True)
    previewed = run(caches, "preview", stages / "skin.h5", "-o", out / "skin.png", "--size", "96x64", "-q", debug=True)
    for log in (fitted, previewed):
        assert "[cache] data loaded from" in log and "[cache] data saved to" not in log, log
    run(caches, "export", stages / "skin.h5", "-o", out / "points.usdc", "--as", "points", "-q")
    run(caches, "play", stages / "puppet.h5", "-c", stages / "bar.npz", "-o", out / "crowd.usda", "-q")
    run(caches, "play", stages / "puppet.h5", "-c", stages / "bar.npz", "-o", out / "played.h5", "--skinning",
        "dual-quaternion", "-q")
    assert snapshot(caches) == built, "a command compiled what precompile had not"

    again = json.loads(run(caches, "precompile", "--json"))
    assert again["compiled"] == 0 and again["loaded"] >= len(again["items"])
