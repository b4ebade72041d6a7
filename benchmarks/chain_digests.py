"""The whole chain on real captures, digested: proof that a change which must not change behaviour
(a refactor) did not.

For each capture (horse_gallop and vlasic_samba by default) it runs, as a user would:
fit-skin, export (UsdSkel, USD points, .exr, VAT folder), select-controls, train-kcca, evaluate
(--json, timings dropped), play (.h5, a .usdc crowd, a VAT folder), build-graph, synthesize
(with --usd), preview (.png contact sheet); then digests every output: HDF5 files by
``skinsynth inspect --digests`` (every dataset and attribute, provenance aside), other files by
their bytes' sha256, folders file by file. It also digests every command's ``--help`` text.

One JSON line per capture ({"capture", "outputs": {name: digest}}) and one for the help texts.
``--save FILE`` keeps the lines; ``--compare FILE`` prints what differs from a saved run and
exits 1 when anything does.

The command run is $SKINSYNTH when set (another checkout's, for a before/after comparison).

    python benchmarks/chain_digests.py --work DIR --save before.json          # on the old commit
    python benchmarks/chain_digests.py --work DIR --compare before.json       # on the new one
"""

import argparse
import hashlib
import json
import os
import pathlib
import shutil
import subprocess
import sys

from datasets import SHARED_DATA

CAPTURES = {"horse_gallop": ("horse_gallop/horse_gallop.npz", 22), "vlasic_samba": ("vlasic_samba/vlasic_samba.npz", 22)}
COMMANDS = ["fit-skin", "export", "select-controls", "train-kcca", "evaluate", "play", "build-graph", "synthesize",
            "preview", "inspect", "example"]
#: Keys of a --json summary that are measurements of this run, not results.
TIMINGS = ("seconds", "frames_per_second", "character_frames_per_second")


def skinsynth(*args, cwd):
    exe = os.environ.get("SKINSYNTH") or shutil.which("skinsynth", path=os.path.dirname(sys.executable)) \
        or "skinsynth"
    done = subprocess.run([exe, *map(str, args)], cwd=cwd, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"skinsynth {' '.join(map(str, args))}: exit {done.returncode}\n{done.stderr[-3000:]}")
    return done.stdout


def file_digest(path):
    with open(path, "rb") as handle:
        return hashlib.sha256(handle.read()).hexdigest()


def digest(path, cwd):
    """An output's digest: {dataset: sha256} for HDF5, {file: sha256} for a folder, else sha256."""
    path = pathlib.Path(cwd) / path
    if path.is_dir():
        return {p.name: file_digest(p) for p in sorted(path.iterdir())}
    if path.suffix == ".h5" and path.name != "play.h5":
        return json.loads(skinsynth("inspect", path, "--digests", "--json", cwd=cwd))["digests"]
    if path.suffix == ".h5":  # play's vertex animation is no model file: every dataset and attribute
        import h5py

        found = {}
        with h5py.File(path, "r") as f:
            def each(name, item):
                if isinstance(item, h5py.Dataset):
                    values = item[()]
                    data = repr(values.tolist()).encode() if values.dtype.kind == "O" else values.tobytes()
                    found[name] = hashlib.sha256(data).hexdigest()

            f.visititems(each)
            found.update({f"@{k}": repr(v) for k, v in f.attrs.items()})
        return found
    return file_digest(path)


def without_timings(value):
    if isinstance(value, dict):
        return {k: without_timings(v) for k, v in value.items() if k not in TIMINGS}
    if isinstance(value, list):
        return [without_timings(v) for v in value]
    return value


def chain(name, source, bones, work):
    """Run the chain on one capture in ``work``; returns {output: digest}."""
    work.mkdir(parents=True, exist_ok=True)
    run = lambda *args: skinsynth(*args, cwd=work)  # noqa: E731
    run("fit-skin", source, "-o", "skin.h5", "--bones", bones, "--seed", 0, "-q")
    run("export", "skin.h5", "-o", "skel.usda", "--as", "skel", "-q")
    run("export", "skin.h5", "-o", "points.usdc", "--as", "points", "-q")
    run("export", "skin.h5", "-o", "vat.exr", "-q")
    run("export", "skin.h5", "-o", "vat/", "-q")
    run("select-controls", "skin.h5", "-o", "controls.h5", "-q")
    run("train-kcca", "controls.h5", "-o", "puppet.h5", "-q")
    evaluation = without_timings(json.loads(run("evaluate", "puppet.h5", "--json")))
    (work / "evaluate.json").write_text(json.dumps(evaluation, sort_keys=True))
    run("play", "puppet.h5", "-c", source, "-o", "play.h5", "-q")
    run("play", "puppet.h5", "-c", source, "-o", "crowd.usdc", "--instances", 4, "-q")
    run("play", "puppet.h5", "-c", source, "-o", "play_vat/", "--instances", 2, "-q")
    run("build-graph", "skin.h5", "-o", "graph.h5", "-q")
    run("synthesize", "graph.h5", "-o", "bones.h5", "-n", 8, "-m", 120, "--seed", 0, "--usd", "usd", "-q")
    run("preview", "bones.h5", "-o", "synth.png", "--animation", 0, "--animation", 1, "--size", "320x240", "-q")
    outputs = ["skin.h5", "skel.usda", "points.usdc", "vat.exr", "vat", "controls.h5", "puppet.h5", "evaluate.json",
               "play.h5", "crowd.usdc", "play_vat", "graph.h5", "bones.h5", "usd", "synth.png"]
    return {output: digest(output, work) for output in outputs}


def help_digests(work):
    texts = {"": skinsynth("--help", cwd=work)}
    texts.update({command: skinsynth(command, "--help", cwd=work) for command in COMMANDS})
    return {command: hashlib.sha256(text.encode()).hexdigest() for command, text in texts.items()}


def differences(saved, now, where=""):
    if isinstance(saved, dict) and isinstance(now, dict):
        for key in sorted(set(saved) | set(now)):
            yield from differences(saved.get(key), now.get(key), f"{where}/{key}")
    elif saved != now:
        yield where


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", required=True, help="Folder for the outputs (one subfolder per capture).")
    parser.add_argument("--only", action="append", choices=sorted(CAPTURES), help="Capture(s) to run.")
    parser.add_argument("--save", help="Write the JSON lines here.")
    parser.add_argument("--compare", help="Compare with JSON lines saved by --save; exit 1 on any difference.")
    options = parser.parse_args()
    work = pathlib.Path(options.work).resolve()
    if not SHARED_DATA.is_dir():
        print(json.dumps({"skipped": f"no real data at {SHARED_DATA}"}))
        return 0
    lines = [{"help": help_digests(work.parent)}]
    for name in options.only or sorted(CAPTURES):
        relative, bones = CAPTURES[name]
        lines.append({"capture": name, "outputs": chain(name, SHARED_DATA / relative, bones, work / name)})
    for line in lines:
        print(json.dumps(line, sort_keys=True), flush=True)
    if options.save:
        pathlib.Path(options.save).write_text("".join(json.dumps(line, sort_keys=True) + "\n" for line in lines))
    if options.compare:
        saved = [json.loads(row) for row in pathlib.Path(options.compare).read_text().splitlines() if row.strip()]
        keyed = lambda rows: {row.get("capture", "help"): row for row in rows}  # noqa: E731
        found = list(differences({k: v for k, v in keyed(saved).items() if k in keyed(lines)}, keyed(lines)))
        print(json.dumps({"compared_with": options.compare, "identical": not found, "differences": found}))
        return 1 if found else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
