"""Runs every test file on its own, each in a fresh pytest process: proof that no test depends on
another module having been collected first (a helper imported from a test module, a fixture
defined elsewhere, state left behind by an earlier test).

    python tests/run_each_file.py                 # every tests/**/test_*.py, two at a time
    python tests/run_each_file.py -j 1 tests/cli  # one folder, one at a time
    python tests/run_each_file.py -- -m "not slow"  # arguments after -- go to each pytest

One line per file (its verdict, counts and seconds), then a summary line "N passed, N failed"
(files), and exit status 1 when any file failed. A file whose every test is skipped or
deselected counts as passed (pytest's exit status 5, "no tests ran", is not a failure here)."""

import argparse
import concurrent.futures
import pathlib
import re
import subprocess
import sys
import time

TESTS = pathlib.Path(__file__).resolve().parent
ROOT = TESTS.parent
#: pytest's exit statuses that mean the file holds up on its own: all passed, or nothing to run.
PASSING = (0, 5)


def test_files(paths):
    """Every test_*.py under ``paths`` (files or folders), sorted."""
    found = set()
    for path in paths:
        path = pathlib.Path(path).resolve()
        found |= {path} if path.is_file() else set(path.rglob("test_*.py"))
    return sorted(p for p in found if "node_modules" not in p.parts)


def run_file(path, pytest_args):
    """(path, exit status, pytest's last line, seconds) of one file run alone."""
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(path), *pytest_args],
                          cwd=ROOT, capture_output=True, text=True)
    lines = [line for line in done.stdout.splitlines() if line.strip()]
    last = re.sub(r"=+", "", lines[-1]).strip() if lines else done.stderr.strip().splitlines()[-1:]
    return path, done.returncode, last, time.perf_counter() - started, done.stdout + done.stderr


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("paths", nargs="*", default=[str(TESTS)], help="test files or folders (default: tests/)")
    parser.add_argument("-j", "--jobs", type=int, default=2, help="files run at once (default: 2)")
    parser.add_argument("--show-failures", action="store_true", help="print a failing file's whole output")
    args, pytest_args = parser.parse_known_args(argv)
    pytest_args = [a for a in pytest_args if a != "--"]
    files = test_files(args.paths)
    failed = []
    with concurrent.futures.ThreadPoolExecutor(max(1, args.jobs)) as pool:
        for path, status, last, seconds, output in pool.map(lambda p: run_file(p, pytest_args), files):
            ok = status in PASSING
            print(f"{'ok  ' if ok else 'FAIL'} {path.relative_to(ROOT)}: {last} ({seconds:.1f} s)", flush=True)
            if not ok:
                failed.append(path)
                if args.show_failures:
                    print(output, flush=True)
    print(f"files: {len(files) - len(failed)} passed, {len(failed)} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
