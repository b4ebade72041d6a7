"""Helpers for tests that drive the ``skinsynth`` command line in-process."""

import os
import traceback

from click.testing import CliRunner

from skinsynth.cli.main import main


def cli(*args):
    """Run ``skinsynth ARGS`` in-process; stdout and stderr come back separately."""
    return CliRunner().invoke(main, [str(a) for a in args], prog_name="skinsynth")


def assert_ok(result):
    assert result.exit_code == 0, f"exit {result.exit_code}\nstdout: {result.stdout}\nstderr: {result.stderr}" + (
        "" if result.exc_info is None or isinstance(result.exception, SystemExit)
        else "\n" + "".join(traceback.format_exception(*result.exc_info)))
    return result


def assert_user_error(result, *needles, folder=None, keep=()):
    """Exit 2, exactly one stderr line holding every needle, no traceback, nothing new in ``folder``."""
    detail = f"exit {result.exit_code}\nstdout: {result.stdout!r}\nstderr: {result.stderr!r}"
    # An exception escaping the command would be caught by CliRunner (exit 1) instead of printed.
    assert isinstance(result.exception, SystemExit), detail + f"\nexception: {result.exception!r}"
    assert result.exit_code == 2, detail
    lines = result.stderr.splitlines()
    assert len(lines) == 1, detail
    assert "Traceback" not in result.output, detail
    assert lines[0].startswith("skinsynth: error: "), detail
    for needle in needles:
        assert needle in lines[0], f"{needle!r} not in {lines[0]!r}"
    assert result.stdout == "", detail
    if folder is not None:
        assert_folder_holds(folder, keep)
    return lines[0]


def assert_folder_holds(folder, names=()):
    """The folder holds exactly ``names``: no output, and no ``.*.tmp*`` file left by a writer."""
    assert sorted(os.listdir(folder)) == sorted(names)

