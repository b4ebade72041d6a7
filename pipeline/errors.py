"""Errors the algorithms raise for requests no data can satisfy (the CLI maps them to exit 2)."""


class OptionError(ValueError):
    """An option value that cannot work with the given data, e.g. more bones than vertices."""


class ClipError(OptionError):
    """What the input clip itself cannot give, e.g. too few frames for a transition, no repeated
    state to loop on: the command's one line names the file the clip came from."""
