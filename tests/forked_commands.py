"""Many short ``skinsynth`` commands, each run in a child forked from one interpreter that has
imported the command line (and the readers the commands load) once.

Each child sees what a fresh process would: its own file descriptors 1 and 2 (what C++ libraries
print straight to fd 2 is captured with Python's own stderr), ``sys.argv``, its exit status. What
it shares with its siblings is only what the parent imported before forking. A test that checks
one-line errors over dozens of damaged inputs pays one interpreter start instead of dozens
(about 0.6 s each with USD, h5py and scipy loaded). Tests of process-level behaviour (signals,
process groups, a closed stdout, the interpreter's own start) must keep real processes.
"""

import json
import subprocess
import sys
from typing import NamedTuple

#: The parent: imports, then forks one child per command line read from stdin (JSON, one a line),
#: printing each one's {"returncode", "stderr"} as a JSON line.
_PARENT = r"""
import importlib, json, os, sys, tempfile
from skinsynth.cli.main import main
for module in json.loads(sys.argv[1]):
    importlib.import_module(module)
for line in sys.stdin:
    arguments = json.loads(line)
    with tempfile.TemporaryFile() as stderr:
        pid = os.fork()
        if pid == 0:
            os.dup2(stderr.fileno(), 2)
            os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
            os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
            sys.argv = ["skinsynth", *arguments]
            code = 1
            try:
                main()
                code = 0
            except SystemExit as error:
                code = error.code if isinstance(error.code, int) else (0 if error.code is None else 1)
            except BaseException:
                import traceback
                traceback.print_exc()
            finally:
                for stream in (sys.stdout, sys.stderr):
                    try:
                        stream.flush()
                    except BaseException:
                        pass
                os._exit(code)
        status = os.waitpid(pid, 0)[1]
        stderr.seek(0)
        said = stderr.read().decode(errors="replace")
    code = os.WEXITSTATUS(status) if os.WIFEXITED(status) else -os.WTERMSIG(status)
    print(json.dumps({"returncode": code, "stderr": said}), flush=True)
"""


class Ended(NamedTuple):
    """What a command left: its exit status (−N: killed by signal N) and what it wrote to fd 2."""

    returncode: int
    stderr: str


class ForkedCommands:
    """The parent interpreter, started once; :meth:`run` runs one command line (the arguments
    after ``skinsynth``) in a child and waits for it. ``preload``: modules the parent imports first
    (the readers the commands load, e.g. ``skinsynth.formats.usd``); ``kwargs`` go to Popen (cwd,
    env). A context manager: the parent ends on leaving."""

    def __init__(self, preload=(), **kwargs):
        self._parent = subprocess.Popen([sys.executable, "-c", _PARENT, json.dumps(list(preload))],
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                        text=True, **kwargs)

    def run(self, arguments):
        self._parent.stdin.write(json.dumps([str(a) for a in arguments]) + "\n")
        self._parent.stdin.flush()
        line = self._parent.stdout.readline()
        assert line, f"the parent ended (exit {self._parent.wait()}): {self._parent.stderr.read()[-3000:]}"
        return Ended(**json.loads(line))

    def close(self):
        self._parent.stdin.close()
        try:
            self._parent.wait(60)
        finally:
            if self._parent.poll() is None:
                self._parent.kill()
                self._parent.wait()
            self._parent.stdout.close()
            self._parent.stderr.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def run_forked(commands, preload=(), **kwargs):
    """[Ended] of each command line, run one after the other (:class:`ForkedCommands`)."""
    with ForkedCommands(preload, **kwargs) as parent:
        return [parent.run(command) for command in commands]
