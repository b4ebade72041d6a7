"""The one exception type for bad input files: it names the file and the problem."""


class FormatError(Exception):
    """A file that cannot be used: missing, unreadable, of the wrong kind, or with bad contents.

    The CLI prints ``str(error)`` as its single error line and exits with status 2.
    """

    def __init__(self, path, problem):
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")
