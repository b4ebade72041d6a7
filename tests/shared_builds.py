"""What a test run builds once for all its xdist workers (``make test`` runs one per core): the
run's shared folder and :func:`built_once`, which the session fixtures of ``conftest.py`` and a
few modules' expensive fixtures build through."""

import os


def run_folder(tmp_path_factory):
    """The folder of this run that every xdist worker sees (the parent of each worker's base
    temporary folder; without xdist, the session's own)."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def built_once(tmp_path_factory, name, build):
    """``build(folder)``'s result (JSON-able), built once per run whatever the number of workers:
    the first worker to ask builds it in ``<run folder>/name`` under a file lock, the others wait
    for it and read its result. A build that failed half-way is built again by the next asker."""
    import fcntl
    import json
    import shutil

    root = run_folder(tmp_path_factory)
    folder, done = root / name, root / f"{name}.built.json"
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir()
            done.write_text(json.dumps(build(folder)))
        return json.loads(done.read_text())
