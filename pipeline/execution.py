"""Execution plumbing: run batches of work, here or in worker processes, and collect them in order.

One interface, :func:`run_batches`, for every algorithm that splits its work into independent
batches (``pipeline.synthesis`` today); how the batches run (one process, a process pool, later a
cluster) is decided here and nowhere else, and never changes the result:

- ``jobs == 1`` (or one batch): in this process, with one BLAS thread (a multi-threaded BLAS may
  split a product's sums differently, so only this makes 1 and N jobs agree bit for bit);
- ``jobs > 1``: a process pool, each worker with one BLAS thread, signals left to the parent
  (which ends its workers when it stops) and, on Linux, death with the parent even when it is
  killed outright. On Linux the workers are forked and write the large outputs straight into one
  anonymous shared mapping the parent's arrays *are* (no pickling back, no copy).
"""

import contextlib

import numpy as np

_WORKER_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")
#: Output blocks the workers of a forked pool write into, by token (inherited through fork).
_SHARED_OUTPUT = {}


def run_batches(make, args, batches, jobs, output_shapes, progress=None):
    """``make(*args, batch, count)`` for each (batch, count) of ``batches``, in order.

    ``make`` (a module-level function, so workers can import it) returns a list whose first
    ``len(output_shapes)`` items are float32 arrays with ``count`` rows; they are written into
    outputs of ``output_shapes`` (total rows first) at the batch's offset. Returns (outputs, the
    rest of each batch's list, in batch order). ``progress(rows done)`` after each batch."""
    offsets = np.cumsum([0] + [n for _, n in batches])
    parallel = jobs > 1 and len(batches) > 1
    context = _pool_context() if parallel else None
    token = None
    if context is not None:
        import mmap

        token = f"{id(args)}-{id(batches)}"
        block = mmap.mmap(-1, max(1, 4 * sum(int(np.prod(shape)) for shape in output_shapes)))  # MAP_SHARED
        outputs = _SHARED_OUTPUT[token] = _shared_arrays(block, output_shapes)
    else:
        outputs = [np.empty(shape, np.float32) for shape in output_shapes]
    rests, done = [], 0

    def keep(i, n, outcome):
        """Batch i's outcome in place (its outputs are None when a worker wrote them already)."""
        nonlocal done
        head, rest = outcome[:len(outputs)], outcome[len(outputs):]
        for target, part in zip(outputs, head):
            if part is not None:
                target[offsets[i]:offsets[i] + n] = part
        rests.append(rest)
        done += n
        if progress is not None:
            progress(done)

    if parallel:
        from concurrent.futures import ProcessPoolExecutor

        try:
            with ProcessPoolExecutor(max_workers=jobs, initializer=_worker_setup, mp_context=context) as pool:
                try:
                    with _signals_blocked():  # workers are forked here
                        futures = [pool.submit(_batch_for_parent, make, len(outputs), token, int(offsets[i]), args,
                                               b, n) for i, (b, n) in enumerate(batches)]
                    for i, (future, (_, n)) in enumerate(zip(futures, batches)):
                        keep(i, n, future.result())
                except BaseException:  # stopped (a signal) or failed: end the workers now, not after their batch
                    for process in list(getattr(pool, "_processes", {}).values()):
                        process.terminate()
                    pool.shutdown(wait=False, cancel_futures=True)
                    raise
        finally:
            _SHARED_OUTPUT.pop(token, None)
    else:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):
            for i, (b, n) in enumerate(batches):
                keep(i, n, make(*args, b, n))
    return outputs, rests


def _batch_for_parent(make, count_outputs, token, offset, args, batch, count):
    """Worker: ``make``, with its outputs written into the parent's shared block ``token`` (they
    are most of a batch's bytes; pickling them back costs more than making them) and the rest
    returned; with ``token`` None, everything is returned."""
    result = make(*args, batch, count)
    if token is None:
        return result
    for target, part in zip(_SHARED_OUTPUT[token], result[:count_outputs]):
        target[offset:offset + count] = part
    return [None] * count_outputs + list(result[count_outputs:])


def _shared_arrays(buffer, shapes):
    """float32 arrays of ``shapes`` laid end to end in ``buffer``."""
    arrays, at = [], 0
    for shape in shapes:
        arrays.append(np.ndarray(shape, dtype=np.float32, buffer=buffer, offset=at * 4))
        at += int(np.prod(shape))
    return arrays


def _pool_context():
    """The fork context on Linux (workers then inherit the shared output block), else None (the
    platform's default start method, results back through the pool: fork is unsafe on macOS)."""
    import multiprocessing
    import sys

    return multiprocessing.get_context("fork") if sys.platform.startswith("linux") else None


def _worker_setup():
    """Worker initialiser: signals left to the parent, which ends its workers when it stops (it
    forks them with these signals blocked, so none arrives before this runs); on Linux, death
    with the parent even when it is killed outright (no orphan keeps computing); one BLAS thread
    (each process already has a core; more would oversubscribe)."""
    import signal
    import sys

    for name in _WORKER_SIGNALS:
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_DFL if name == "SIGTERM" else signal.SIG_IGN)
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {getattr(signal, n) for n in _WORKER_SIGNALS if hasattr(signal, n)})
    if sys.platform.startswith("linux"):
        import ctypes

        PR_SET_PDEATHSIG = 1
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")


@contextlib.contextmanager
def _signals_blocked():
    """Block SIGINT/SIGTERM/SIGHUP in this thread while workers are forked (they inherit the
    mask and unblock once their own handlers are set); arrivals meanwhile are delivered after."""
    import signal

    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {getattr(signal, n) for n in _WORKER_SIGNALS
                                                         if hasattr(signal, n)})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
