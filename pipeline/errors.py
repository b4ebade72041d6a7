"""Errors the algorithms raise for requests no data can satisfy (the CLI maps them to exit 2)."""


class OptionError(ValueError):
    """An option value that cannot work with the given data, e.g. more bones than vertices."""
