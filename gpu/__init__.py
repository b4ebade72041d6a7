"""skinsynth.gpu: warp kernels with numpy references, and the device choice.

Public API (resolved lazily, so importing this package neither imports nor initialises warp):
lbs, lbs_reference, dqs_reference, resolve_device, available_devices, DeviceError.
"""

import importlib

_EXPORTS = {
    "lbs": "skinning",
    "lbs_reference": "skinning",
    "dqs_reference": "skinning",
    "resolve_device": "runtime",
    "available_devices": "runtime",
    "DeviceError": "runtime",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    globals()[name] = value  # later look-ups skip this hook
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
