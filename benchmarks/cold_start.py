"""A command's first run on a fresh install: compiling (numba loops, warp kernels) versus
``skinsynth precompile`` done once at install (issue 34). Goal: every ``make demo`` command's
first run after the step ≤ 1.5× its warm run.

The commands are ``make demo``'s, read from the Makefile's demo recipe, run in order as
subprocesses (outputs in a fresh folder each pass). Caches: NUMBA_CACHE_DIR and
SKINSYNTH_CACHE_DIR point at new empty folders (numba then never reads the ``__pycache__``
beside the sources). Three states:

- cold: empty caches, each command compiles what it needs (``--cold-rounds`` passes, each on new
  empty caches);
- after: the caches as ``skinsynth precompile`` left them (run once on empty caches, timed; each
  round copies them afresh), and the first run of each command on them;
- warm: the same command run again on that round's caches.

Medians over the rounds. One JSON line per command: ``cold_s``, ``after_s``, ``warm_s``,
``cold_ratio`` and ``after_ratio`` (over warm), ``new_cache_files`` (files the command added to the
caches after precompile: compiling it missed; 0 expected) and ``goal_met`` (after_ratio ≤ 1.5);
one line for the precompile step itself; one for fit-skin of the real horse (shared/data
horse_gallop, --bones 22: cold, after, warm; skipped with a reason when absent); one summary.

    python benchmarks/cold_start.py [--rounds 3] [--cold-rounds 1] [--no-horse] [--work DIR]
"""

import argparse
import json
import os
import pathlib
import re
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from datasets import SHARED_DATA

ROOT = pathlib.Path(__file__).resolve().parents[1]
GOAL = 1.5
HORSE = SHARED_DATA / "horse_gallop" / "horse_gallop.npz"


def skinsynth():
    """The skinsynth command of this interpreter's environment."""
    beside = pathlib.Path(sys.executable).with_name("skinsynth")
    return str(beside) if beside.exists() else shutil.which("skinsynth") or "skinsynth"


def demo_commands(makefile=ROOT / "Makefile"):
    """make demo's skinsynth commands, as argument lists with ``{out}`` for $(DEMO)."""
    text = makefile.read_text().replace("\\\n", " ")
    recipe = re.search(r"^demo:.*?\n((?:\t.*\n)+)", text, re.M)
    if recipe is None:
        raise SystemExit(f"no demo recipe in {makefile}")
    commands = []
    for line in recipe.group(1).splitlines():
        line = line.strip()
        if line.startswith("$(BIN)/skinsynth "):
            commands.append(shlex.split(line.replace("$(DEMO)", "{out}"))[1:])
    return commands


def label(args):
    """A short name: the subcommand and its output (-o), else its input."""
    target = args[args.index("-o") + 1] if "-o" in args else args[1]
    return f"{args[0]} {os.path.basename(target.rstrip('/'))}"


def cache_files(caches):
    return {os.path.join(root, name) for folder in caches.values() for root, _, files in os.walk(folder)
            for name in files}


def run(args, caches, out=None):
    """Wall seconds of one command with these caches; raises on failure."""
    env = dict(os.environ, NUMBA_CACHE_DIR=caches["numba"], SKINSYNTH_CACHE_DIR=caches["warp"])
    argv = [skinsynth()] + [a.format(out=out) for a in args]
    start = time.perf_counter()
    done = subprocess.run(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seconds = time.perf_counter() - start
    if done.returncode:
        raise SystemExit(f"{shlex.join(argv)} failed ({done.returncode}): {done.stderr.strip()[-2000:]}")
    return seconds, done.stdout


def chain(commands, caches, out):
    """Run the demo chain once into the new folder ``out``: per command (seconds, new cache files)."""
    os.makedirs(out)
    results = []
    for args in commands:
        before = cache_files(caches)
        seconds, _ = run(args, caches, out)
        results.append((seconds, len(cache_files(caches) - before)))
    return results


def fresh_caches(work, name, template=None):
    caches = {kind: os.path.join(work, name, kind) for kind in ("numba", "warp")}
    for kind, folder in caches.items():
        if template is None:
            os.makedirs(folder)
        else:
            shutil.copytree(template[kind], folder)
    return caches


def median(values):
    return statistics.median(values) if values else None


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3, help="after-precompile and warm passes (medians)")
    parser.add_argument("--cold-rounds", type=int, default=1, help="passes on empty caches (medians)")
    parser.add_argument("--no-horse", action="store_true", help="skip fit-skin of the real horse")
    parser.add_argument("--work", default=None, help="folder for caches and outputs (default: a new temporary one)")
    args = parser.parse_args()
    work = args.work or tempfile.mkdtemp(prefix="skinsynth-cold-")
    commands = demo_commands()

    cold = [[] for _ in commands]
    for r in range(args.cold_rounds):
        caches = fresh_caches(work, f"cold{r}")
        for i, (seconds, _) in enumerate(chain(commands, caches, os.path.join(work, f"cold{r}", "out"))):
            cold[i].append(seconds)

    step = fresh_caches(work, "precompiled")
    seconds, stdout = run(["precompile", "--json"], step)
    summary = json.loads(stdout)
    print(json.dumps({"command": "precompile", "seconds": round(seconds, 2), "compiled": summary["compiled"],
                      "loaded": summary["loaded"],
                      "items": {f"{i['kind']} {i['name']}": round(i["seconds"], 2) for i in summary["items"]}}),
          flush=True)

    after, warm, new_files = [[] for _ in commands], [[] for _ in commands], [0] * len(commands)
    for r in range(args.rounds):
        caches = fresh_caches(work, f"after{r}", template=step)
        for i, (seconds, added) in enumerate(chain(commands, caches, os.path.join(work, f"after{r}", "out"))):
            after[i].append(seconds)
            new_files[i] += added
        for i, (seconds, _) in enumerate(chain(commands, caches, os.path.join(work, f"after{r}", "warm"))):
            warm[i].append(seconds)

    met = 0
    for i, command in enumerate(commands):
        c, a, w = median(cold[i]), median(after[i]), median(warm[i])
        line = {"command": label(command), "args": shlex.join(command).replace("{out}", "$(DEMO)"),
                "cold_s": c and round(c, 2), "after_s": round(a, 2), "warm_s": round(w, 2),
                "cold_ratio": c and round(c / w, 2), "after_ratio": round(a / w, 2), "new_cache_files": new_files[i],
                "goal_met": a <= GOAL * w}
        met += line["goal_met"]
        print(json.dumps(line), flush=True)

    if args.no_horse:
        print(json.dumps({"command": "fit-skin horse_gallop", "skipped": "--no-horse"}), flush=True)
    elif not HORSE.exists():
        print(json.dumps({"command": "fit-skin horse_gallop", "skipped": f"no capture at {HORSE}"}), flush=True)
    else:
        horse = ["fit-skin", str(HORSE), "-o", "{out}/horse.h5", "--bones", "22", "--seed", "0", "-q"]
        times = {}
        for state, template in (("cold", None), ("after", step)):
            caches = fresh_caches(work, f"horse_{state}", template)
            os.makedirs(os.path.join(work, f"horse_{state}", "out"))
            times[state], _ = run(horse, caches, os.path.join(work, f"horse_{state}", "out"))
            if state == "after":
                times["warm"] = median([run(horse, caches, os.path.join(work, f"horse_{state}", "out"))[0]
                                        for _ in range(args.rounds)])
        print(json.dumps({"command": "fit-skin horse_gallop", "args": shlex.join(horse).replace("{out}/", ""),
                          "cold_s": round(times["cold"], 2), "after_s": round(times["after"], 2),
                          "warm_s": round(times["warm"], 2), "cold_ratio": round(times["cold"] / times["warm"], 2),
                          "after_ratio": round(times["after"] / times["warm"], 2),
                          "goal_met": times["after"] <= GOAL * times["warm"]}), flush=True)

    print(json.dumps({"summary": f"{met} of {len(commands)} make-demo commands within {GOAL}x of warm after "
                                 "precompile", "goal_met": met == len(commands), "rounds": args.rounds,
                      "cold_rounds": args.cold_rounds, "work": work}), flush=True)
    if not args.work:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
