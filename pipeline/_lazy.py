"""Public names of a package resolved from its private modules on first use (PEP 562), so that
importing a stage package imports none of its heavy modules (numba, scipy, networkx)."""

import importlib


def lazy_exports(package, exports):
    """``(__getattr__, __dir__)`` for ``package`` (its ``__name__``): ``exports`` maps each public
    name to the module (relative to the package) that defines it."""
    namespace = importlib.import_module(package).__dict__

    def __getattr__(name):
        if name not in exports:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f".{exports[name]}", package), name)
        namespace[name] = value  # later look-ups skip this hook
        return value

    def __dir__():
        return sorted(set(namespace) | set(exports))

    return __getattr__, __dir__
