"""The one place that imports and initialises warp, and turns device requests into warp names.

Importing warp costs ~0.8 s and initialising it prints a banner and (without a GPU) a CUDA
driver warning from native code, so both happen lazily, once, on the first kernel use.
"""

import contextlib
import os
import re
import sys
import threading

_SPEC = re.compile(r"^(auto|cpu|cuda(?::(\d+))?)$")
_lock = threading.Lock()
_warp = None


class DeviceError(Exception):
    """A device request that cannot be honoured; ``str(error)`` is one line for the user.

    The CLI prints it and exits with status 2.
    """


def cache_dir() -> str:
    """Folder for warp's compiled kernels: $SKINSYNTH_CACHE_DIR, else the user's cache folder."""
    if os.environ.get("SKINSYNTH_CACHE_DIR"):
        return os.path.abspath(os.environ["SKINSYNTH_CACHE_DIR"])
    root = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(root, "skinsynth", "warp")


@contextlib.contextmanager
def _stderr_to_devnull():
    """Silence file descriptor 2: native code writes there directly, past sys.stderr."""
    sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no fd 2 at all (daemonised): nothing to hide it from
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def warp():
    """The warp module, initialised with skinsynth's cache folder and quiet output."""
    global _warp
    with _lock:
        if _warp is None:
            import warp as wp

            # config must be set before init: the cache folder is fixed by wp.init()
            wp.config.kernel_cache_dir = cache_dir()
            if hasattr(wp.config, "log_level"):  # warp >= 1.19 deprecates `quiet` for this
                wp.config.log_level = wp.LOG_WARNING
            else:
                wp.config.quiet = True
            with _stderr_to_devnull():
                wp.init()
            _warp = wp
    return _warp


def available_devices() -> list[str]:
    """Warp device names usable here, e.g. ["cpu"] or ["cpu", "cuda:0", "cuda:1"]."""
    return [d.alias for d in warp().get_devices()]


def resolve_device(spec: str = "auto") -> str:
    """Warp device name for `auto|cpu|cuda|cuda:N`; auto is cuda:0 when warp sees a GPU, else cpu.

    Raises DeviceError for an unknown spelling or a device that is not present.
    """
    match = _SPEC.match(str(spec).strip().lower())
    if match is None:
        raise DeviceError(f"--device {spec}: unknown device (expected auto, cpu, cuda or cuda:N)")
    name, ordinal = match.group(1), match.group(2)
    wp = warp()
    found = available_devices()
    listed = ", ".join(found) or "no device"
    count = wp.get_cuda_device_count()
    if name == "auto":
        return "cuda:0" if count else "cpu"
    if name == "cpu":
        if "cpu" not in found:
            raise DeviceError(f"--device cpu: warp's CPU backend is unavailable (warp found {listed})")
        return "cpu"
    if count == 0:
        raise DeviceError(f"--device {name}: no CUDA device is available (warp found only {listed})")
    if ordinal is None:
        return wp.get_device("cuda").alias  # warp's current CUDA device, normally cuda:0
    if int(ordinal) >= count:
        raise DeviceError(f"--device {name}: only {count} CUDA device(s) (warp found {listed})")
    return f"cuda:{int(ordinal)}"
