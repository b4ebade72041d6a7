"""Timing helper shared by the benchmarks."""

import statistics
import time


def median_seconds(fn, repeats):
    """Median wall time of ``repeats`` calls of fn, after one warm-up call (kernel compile or
    cache load, memory faulted in)."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)
