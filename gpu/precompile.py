"""Every warp module the CPU path loads, compiled ahead of use (``skinsynth precompile``).

warp compiles a module on its first launch on a device and keeps the object in its kernel cache
(:func:`.runtime.cache_dir`: ``$SKINSYNTH_CACHE_DIR``, else ``~/.cache/skinsynth/warp``), where a
later process loads it in milliseconds. An object is found by the module's content hash and, on
the CPU, a hash of warp's LLVM version and target triple (and the CPU's features when built for
the host's own ISA), so another machine never loads a wrong binary: it compiles its own.

The modules: the puppet's run-time stages (``kernels.puppet``, one module), the control kernel
vectors of each kind (``kernel_vector_kernel``, at the degree puppets are trained with), and each
skinning kernel (``kernels.skinning``: every ``functools.cache``d builder taking ``influences``
and ``corrected``) for each number of influences asked for, with and without rest offsets.
fit-skin's warp kernels (``kernels.skin_fit``) only run with ``--device cuda`` and are not built.
"""

import inspect
import os
import time

from . import runtime
from .puppet_arrays import PuppetArrays
from .validation import KERNEL_KINDS

#: fit-skin's default --max-influences: the K of every skin it writes with at least 4 bones.
DEFAULT_INFLUENCES = (4,)


def _skinning_builders(kernels):
    """The kernel builders of ``kernels.skinning`` specialised on (influences, corrected)."""
    return [value for name, value in sorted(vars(kernels).items())
            if callable(value) and hasattr(value, "cache_info") and not name.startswith("_")
            and list(inspect.signature(value).parameters) == ["influences", "corrected"]]


def cpu_modules(influences=DEFAULT_INFLUENCES):
    """(name, warp Module) of every module the CPU path launches, for skins of ``influences``
    influences per vertex: importing the kernel modules imports and initialises warp."""
    from .kernels import puppet, skinning

    degree = PuppetArrays.__dataclass_fields__["degree"].default
    modules = [("puppet stages", puppet.predict_kernel.module)]
    modules += [(f"kernel vectors ({kind})", puppet.kernel_vector_kernel(kind, degree).module) for kind in KERNEL_KINDS]
    for builder in _skinning_builders(skinning):
        for k in influences:
            for corrected in (False, True):
                kernel = builder(int(k), corrected)
                modules.append((f"{builder.__name__} (K={k}{', rest offsets' if corrected else ''})", kernel.module))
    return modules


def _objects(folder):
    """The compiled objects in warp's cache folder (a set of paths)."""
    found = set()
    for root, _, files in os.walk(folder):
        found.update(os.path.join(root, name) for name in files if name.endswith(".o"))
    return found


def compile_cpu_kernels(influences=DEFAULT_INFLUENCES, done=None):
    """Compile (or load from warp's kernel cache) every module of :func:`cpu_modules` on the CPU,
    one after another; returns one dict per module: ``kind`` "warp", ``name``, ``compiled`` (1 when
    an object was built now, else 0), ``loaded`` (1 when it came from the cache), ``seconds``,
    ``cache`` (the folder); the first module's seconds include importing and initialising warp.
    ``done(report)`` is called as each module is ready."""
    start = time.perf_counter()
    wp = runtime.warp()
    modules = cpu_modules(influences)
    setup = time.perf_counter() - start  # importing and initialising warp, building the kernels' Python side
    folder = runtime.cache_dir()
    reports = []
    for name, module in modules:
        before = _objects(folder)
        start = time.perf_counter()
        wp.load_module(module, device="cpu")
        seconds = time.perf_counter() - start
        if not reports:
            seconds += setup
        built = len(_objects(folder) - before)
        reports.append({"kind": "warp", "name": name, "compiled": built, "loaded": int(not built), "seconds": seconds,
                        "cache": [folder]})
        if done is not None:
            done(reports[-1])
    return reports
