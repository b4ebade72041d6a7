"""Compiling a stage's numba loops ahead of use (``skinsynth precompile``), and saying what that did.

Each stage that has numba loops names a function that runs them once on tiny arrays of the types
its commands pass (``pipeline.skin.compile_loops``, ``pipeline.view.compile_loops``); with
``cache=True`` numba then writes each specialisation to its cache, where the commands load it
instead of compiling (numba's own rules: ``$NUMBA_CACHE_DIR`` when set, else ``__pycache__``
beside the source, else, when that folder is not writable, numba's user-wide cache folder). An
entry is keyed by the source file (path, modification time, size), the argument types, and the
CPU's name and features, so another CPU, or an edited source, compiles afresh instead of loading
a wrong binary. This module is the bookkeeping they share: which dispatchers a module defines,
how many of their specialisations were compiled or loaded, and what ``precompile`` says of it.
"""

import time


def dispatchers(*modules):
    """Every numba dispatcher (``@numba.njit`` function) defined at module level in ``modules``."""
    from numba.core.dispatcher import Dispatcher

    return [value for module in modules for value in vars(module).values()
            if isinstance(value, Dispatcher) and value.py_func.__module__ == module.__name__]


def _counts(found):
    misses = sum(sum(d.stats.cache_misses.values()) for d in found)
    hits = sum(sum(d.stats.cache_hits.values()) for d in found)
    return misses, hits


def compile_run(stage, modules, exercise):
    """Run ``exercise()`` (the stage's loops on tiny arrays) and report what numba did: a dict with
    ``kind`` "numba", ``name`` the stage, ``functions`` (the dispatchers' names), ``compiled`` (the
    specialisations compiled now, callees included), ``loaded`` (loaded from the cache), ``seconds``,
    ``cache`` (the folders numba used)."""
    found = dispatchers(*modules)
    before = _counts(found)
    start = time.perf_counter()
    exercise()
    seconds = time.perf_counter() - start
    after = _counts(found)
    used = [d for d in found if d.stats.cache_misses or d.stats.cache_hits]
    return {"kind": "numba", "name": stage, "functions": sorted(d.__name__ for d in used),
            "compiled": after[0] - before[0], "loaded": after[1] - before[1], "seconds": seconds,
            "cache": sorted({d.stats.cache_path for d in used if d.stats.cache_path})}


def compiled_line(item):
    """One line of ``skinsynth precompile``'s text for one report (:func:`compile_run`, or
    ``skinsynth.gpu.compile_cpu_kernels``'s ``kind`` "warp"): what, and compiled or loaded in how long."""
    what = f"{item['kind']} {item['name']}"
    if item["kind"] == "numba":
        what += f" ({', '.join(item['functions'])})"
    done = f"compiled {item['compiled']}" if item["compiled"] else "loaded from the cache"
    if item["compiled"] and item["loaded"]:
        done += f", loaded {item['loaded']}"
    return f"{what}: {done} in {item['seconds']:.1f} s"


def compiled_summary(items, seconds):
    """``skinsynth precompile``'s summary (--json) and its text lines, from every report ``items``
    (numba's and warp's) of a run of ``seconds``: how many compiled and loaded, and the caches used."""
    compiled, loaded = sum(i["compiled"] for i in items), sum(i["loaded"] for i in items)
    caches = {kind: sorted({path for i in items if i["kind"] == kind for path in i["cache"]}) for kind in ("numba", "warp")}
    summary = {"items": items, "compiled": compiled, "loaded": loaded, "seconds": seconds,
               "numba_cache": caches["numba"], "warp_cache": caches["warp"]}
    return summary, [f"precompiled in {seconds:.1f} s: {compiled} compiled, {loaded} loaded from the caches",
                     f"numba cache: {', '.join(caches['numba']) or '(none)'}",
                     f"warp cache: {', '.join(caches['warp'])}"]
