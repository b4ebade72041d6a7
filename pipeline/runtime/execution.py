"""Execution plumbing: run batches of work, here or in worker processes, and collect them in order.

One interface, :func:`run_batches`, for every algorithm that splits its work into independent
batches (``pipeline.synthesis`` today); how the batches run (one process, a process pool, later a
cluster) is decided here and nowhere else, and never changes the result:

- ``jobs == 1`` (or one batch): in this process, with one BLAS thread (a multi-threaded BLAS may
  split a product's sums differently, so only this makes 1 and N jobs agree bit for bit);
- ``jobs > 1``: a process pool, each worker with one BLAS thread, signals left to the parent
  (which ends its workers when it stops) and, on Linux, death with the parent even when it is
  killed outright. On Linux the workers are forked and write the large outputs straight into one
  anonymous shared mapping the parent's arrays *are* (no pickling back, no copy);
- ``remote`` (a :class:`Remote`): a Dask cluster (``distributed``). Each batch is a task; the
  worker that makes it hands its outcome to ``remote.store`` (e.g. a shard file on a shared file
  system) and returns only the store's handle and the small rest, so nothing large crosses the
  network or stays in this process: the outputs come back as :class:`StoredRows`. Batches
  already stored (``remote.stored``) are not run again. A worker lost mid-task has its tasks
  re-run elsewhere by the scheduler; a batch's outcome depends on its id alone, so a re-run
  stores the same bytes.
"""

import contextlib
import os
import uuid

import numpy as np

_WORKER_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")
#: Output blocks the workers of a forked pool write into, by token (inherited through fork).
_SHARED_OUTPUT = {}


def run_batches(make, args, batches, jobs, output_shapes, progress=None, remote=None):
    """``make(*args, batch, count)`` for each (batch, count) of ``batches``, in order.

    ``make`` (a module-level function, so workers can import it) returns a list whose first
    ``len(output_shapes)`` items are float32 arrays with ``count`` rows; they are written into
    outputs of ``output_shapes`` (total rows first) at the batch's offset. Returns (outputs, the
    rest of each batch's list, in batch order). ``progress(rows done)`` after each batch.
    With ``remote``, the batches run on its cluster and the outputs are :class:`StoredRows`."""
    if remote is not None:
        return _run_remote(make, args, batches, output_shapes, progress, remote)
    with small_pages():
        return _run_here(make, args, batches, jobs, output_shapes, progress)


def _run_here(make, args, batches, jobs, output_shapes, progress):
    """:func:`run_batches` in this process or its forked pool."""
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
                    _end_workers(pool)
                    raise
        finally:
            _SHARED_OUTPUT.pop(token, None)
    else:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):
            for i, (b, n) in enumerate(batches):
                keep(i, n, make(*args, b, n))
    return outputs, rests


@contextlib.contextmanager
def small_pages():
    """Within it, numpy asks no transparent huge pages for its large arrays (its default on Linux
    asks them: ``madvise(MADV_HUGEPAGE)`` on every allocation of 4 MB or more), in this process and
    in the workers it forks; NUMPY_MADVISE_HUGEPAGE, when set, decides instead.

    Batches allocate large arrays, fill them once and free them (a batch of 250 animations ×
    600 frames: some 100 MB each, a dozen of them). Each huge page is zeroed, and found
    contiguous, when first touched: where memory is fragmented the kernel compacts it first, in
    the faulting thread. Measured on a 2-core VM (``synthesize -n 1000 -m 600``, system time of
    the whole command): the samba 3.7–6.2 s with huge pages, 1.9–2.2 s without (wall 7.8–9.3 s →
    6.5–6.8 s); the crane with contacts 3.0–6.2 s → 1.8–2.7 s; user time unchanged. Work that
    reuses its arrays (fitting a skin: 7 % slower without them) keeps numpy's default: this is
    scoped to the batches."""
    try:
        from numpy._core import multiarray
    except ImportError:  # numpy 1.x
        from numpy.core import multiarray
    toggle = getattr(multiarray, "_set_madvise_hugepage", None)
    if toggle is None or "NUMPY_MADVISE_HUGEPAGE" in os.environ:
        yield
        return
    previous = toggle(False)
    try:
        yield
    finally:
        toggle(previous)


def _end_workers(pool):
    """End a process pool's workers at once and let its manager thread finish.

    A worker ended while it was sending a batch's result leaves half a message in the result
    pipe; the pool's manager thread then waits in ``recv`` for the rest, and the interpreter
    waits for that thread at exit: the command hung (1 run in about 45 with a signal near the
    end of the work). The parent holds the pipe's writing end too, so once the workers are gone
    it closes its own: the read ends (EOF), the manager sees a broken pool and ends. It is then
    waited for: a manager still ending when the interpreter exits races Python 3.11's exit hook,
    which wakes every manager through a pipe the manager is closing ("Exception ignored …
    OSError: Bad file descriptor" on stderr after the interrupted line; CPython fixed it in 3.12
    with a lock)."""
    writer = getattr(getattr(pool, "_result_queue", None), "_writer", None)
    processes = list((getattr(pool, "_processes", None) or {}).values())
    for process in processes:
        process.terminate()
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.join(5.0)
    if writer is not None:
        writer.close()
    manager = getattr(pool, "_executor_manager_thread", None)
    if manager is not None and manager.is_alive():
        manager.join(5.0)


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


# --- Dask -------------------------------------------------------------------------------------


def dask_setup(worker):
    """Run by each worker process of a ``local:N`` cluster as it starts (this module is its
    preload): ignore SIGINT there. The workers share the terminal's process group, so a Ctrl-C
    reached every one of them, and each printed its event loop's KeyboardInterrupt traceback
    (about 60 lines) before the command's one line; the command closes its workers itself."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


class StoredRows:
    """Rows of one output that stay where the workers stored them: ``pieces`` [(handle, count)]
    one per batch, ``rows`` (N,) indices into the pieces' rows laid end to end (a selection:
    ``stored[keep]`` is another StoredRows, as ``array[keep]`` is another array), ``tail`` the
    shape of one row."""

    def __init__(self, pieces, tail, rows=None):
        self.pieces, self.tail = list(pieces), tuple(tail)
        total = sum(n for _, n in self.pieces)
        self.rows = np.arange(total, dtype=np.int64) if rows is None else np.asarray(rows, dtype=np.int64)

    @property
    def shape(self):
        return (len(self.rows),) + self.tail

    def __len__(self):
        return len(self.rows)

    def __getitem__(self, keep):
        return StoredRows(self.pieces, self.tail, self.rows[keep])

    def runs(self):
        """[(handle, rows in the piece, first row in the piece, first row here, length)]: the
        selection as runs of consecutive rows of one piece (one per piece when none was dropped)."""
        starts = np.cumsum([0] + [n for _, n in self.pieces])
        piece = np.searchsorted(starts, self.rows, side="right") - 1
        # a run breaks where the piece changes or a row is skipped
        breaks = np.flatnonzero((np.diff(piece) != 0) | (np.diff(self.rows) != 1)) + 1
        runs = []
        for first, end in zip(np.r_[0, breaks], np.r_[breaks, len(self.rows)]):
            if end > first:
                p = int(piece[first])
                handle, rows = self.pieces[p]
                runs.append((handle, int(rows), int(self.rows[first] - starts[p]), int(first), int(end - first)))
        return runs


def concatenate_rows(parts):
    """Rows of ``parts`` one after the other: arrays (np.concatenate) or StoredRows (one
    StoredRows over all their pieces)."""
    if not any(isinstance(p, StoredRows) for p in parts):
        return np.concatenate(parts)
    pieces, rows, at = [], [], 0
    for part in parts:
        pieces += part.pieces
        rows.append(part.rows + at)
        at += sum(n for _, n in part.pieces)
    return StoredRows(pieces, parts[0].tail, np.concatenate(rows))


class Cluster:
    """A Dask client (``.client``) for ``address``: ``local:N`` starts N single-threaded worker
    processes on this machine (closed with this object); anything else names a running
    scheduler (``tcp://host:8786``, as ``dask scheduler`` prints), which must have a worker
    within ``worker_timeout`` seconds. Unreachable or empty: OptionError (one line)."""

    CONNECT_TIMEOUT, WORKER_TIMEOUT = 20.0, 60.0
    #: How long a scheduler (tcp://) may take to answer at all, and after how long the caller is
    #: told that the command is waiting for it (:meth:`starting`).
    ANSWER_TIMEOUT, WAITING_NOTICE = 25.0, 3.0

    def __init__(self, address, preload=(), connect_timeout=CONNECT_TIMEOUT, worker_timeout=WORKER_TIMEOUT,
                 answered=None):
        import logging

        import dask
        from distributed import Client, LocalCluster

        from ..errors import OptionError

        self.address, self._local = address, None
        if address.startswith("local:"):
            count = address[len("local:"):]
            if not count.isdigit() or int(count) < 1:
                raise OptionError(f"--cluster {address}: expected local:N with N ≥ 1 worker processes")
            cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
            if int(count) > 4 * cores:  # each worker is a process of its own (~200 MB): refused before one starts
                raise OptionError(f"--cluster {address}: {count} worker processes on a machine with {cores} cores "
                                  f"(local:N takes at most {4 * cores} here); for more, start a scheduler and "
                                  "workers on other machines (docs/cluster.md)")
            try:
                # the command reports every failure itself, in one line; a worker's own ERROR logs
                # (a heartbeat that found the scheduler closing, on a loaded machine) would add a traceback
                self._local = LocalCluster(n_workers=int(count), threads_per_worker=1, processes=True,
                                           silence_logs=logging.CRITICAL,
                                           preload=list(dask.config.get("distributed.worker.preload", [])) + [__name__],
                                           dashboard_address=":0")  # a free port: 8787 may be another's
            except (RuntimeError, OSError, TimeoutError) as error:  # e.g. a worker process that cannot start
                raise OptionError(f"--cluster {address}: the local cluster did not start ({error})") from None
            self.client = Client(self._local)
            self._preload(preload)
            return
        _check_reachable(address, connect_timeout)
        try:
            self.client = Client(address, timeout=connect_timeout)
        except (OSError, TimeoutError, ValueError) as error:
            raise OptionError(f"--cluster {address}: cannot reach a Dask scheduler there ({error})") from None
        if answered is not None:
            answered()
        try:
            self.client.wait_for_workers(1, timeout=worker_timeout)
        except TimeoutError:
            self.close()
            raise OptionError(f"--cluster {address}: no worker joined the scheduler within {worker_timeout:.0f} s "
                              "(start some with: dask worker ADDRESS)") from None
        self._preload(preload)

    def _preload(self, modules):
        """Import ``modules`` on every worker now (a worker joining later imports them with its
        first task): started in the background, this overlaps the caller's own reading."""
        import importlib

        for module in modules:
            self.client.run(importlib.import_module, module)

    @classmethod
    @contextlib.contextmanager
    def starting(cls, address, preload=(), timeout=None, answer_timeout=None):
        """Start (or reach) the cluster in a thread while the caller goes on; yields a callable
        ``joined(waiting=None)`` that waits for it and returns it (raising what starting raised).
        Closed on leaving.

        The wait is bounded (``timeout``: by default the connection's and the first worker's
        together, and 10 s more) and a signal ends it: the thread is a daemon, so a scheduler
        that accepts a connection and never answers can neither hang the command nor keep it
        from exiting (an executor's thread would be joined at exit). A scheduler (tcp://) must
        answer within ``answer_timeout`` (:attr:`ANSWER_TIMEOUT` by default; ``synthesize
        --cluster-timeout``) of the start, and Dask's client is given as long to connect; then its
        first worker may take the rest. ``waiting(text)``, when given, is called once, with a line
        saying what the command waits for, when a scheduler has not answered
        :attr:`WAITING_NOTICE` seconds after the start (a local cluster starts silently)."""
        import threading
        import time

        from ..errors import OptionError

        answer_timeout = cls.ANSWER_TIMEOUT if answer_timeout is None else answer_timeout
        connect_timeout = max(cls.CONNECT_TIMEOUT, answer_timeout)  # Dask's client may wait as long
        timeout = timeout if timeout is not None else connect_timeout + cls.WORKER_TIMEOUT + 10.0
        remote = not address.startswith("local:")
        answer_timeout = min(timeout, answer_timeout) if remote else timeout
        started, done, answered = {}, threading.Event(), threading.Event()
        began = time.monotonic()

        def start():
            try:
                started["cluster"] = cls(address, preload, connect_timeout=connect_timeout, answered=answered.set)
            except BaseException as error:  # handed to the caller's thread
                started["error"] = error
            finally:
                done.set()

        threading.Thread(target=start, name="skinsynth-cluster", daemon=True).start()

        def joined(waiting=None):
            def left(seconds):
                return max(0.0, began + seconds - time.monotonic())

            if remote and waiting is not None and not done.wait(left(cls.WAITING_NOTICE)):
                waiting(f"waiting for the Dask scheduler at {address} (giving up after {answer_timeout:.0f} s "
                        "without an answer)")
            while not (answered.is_set() or done.is_set()):  # the scheduler's answer
                if not left(answer_timeout):
                    raise OptionError(f"--cluster {address}: no answer within {answer_timeout:.0f} s (is a Dask "
                                      "scheduler listening there?)")
                done.wait(min(left(answer_timeout), 0.1))
            if not done.wait(left(timeout)):  # then its first worker
                raise OptionError(f"--cluster {address}: no answer within {timeout:.0f} s (is a Dask scheduler "
                                  "listening there?)")
            if "error" in started:
                raise started["error"]
            return started["cluster"]

        try:
            yield joined
        finally:
            if address.startswith("local:"):  # its worker processes are ours: let them start, to close them
                done.wait(cls.CONNECT_TIMEOUT)
            if "cluster" in started:
                started["cluster"].close()

    @property
    def workers(self):
        return len(self.client.scheduler_info().get("workers", {}))

    @property
    def dashboard(self):
        """The dashboard's address, or None when the scheduler serves none (no bokeh)."""
        if not hasattr(self, "_dashboard"):
            services = self.client.scheduler_info().get("services", {})
            self._dashboard = self.client.dashboard_link if "dashboard" in services else None
        return self._dashboard

    def close(self):
        self.dashboard  # noqa: B018 (kept for the summary, which is written after the client closes)
        self.client.close()
        if self._local is not None:
            self._local.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _check_reachable(address, timeout):
    """OptionError at once for an address that is not one or where nothing listens (Dask's
    client would retry a refused connection until its timeout)."""
    import socket

    from distributed.comm import get_address_host_port

    from ..errors import OptionError

    try:
        host, port = get_address_host_port(address)
    except ValueError:
        raise OptionError(f"--cluster {address}: not a scheduler address (tcp://HOST:PORT) or local:N") from None
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as error:
        raise OptionError(f"--cluster {address}: cannot reach a Dask scheduler there "
                          f"({error.strerror or error})") from None


class Remote:
    """Batches on a cluster: ``store(batch, count, outcome) -> handle`` runs on the worker that
    made a batch (a module-level function or a partial of one, so it pickles); ``stored``
    {(batch, count): (handle, rest)} the batches stored by an earlier run, reused as they are.
    Counts what ran: ``tasks`` submitted, ``reused`` batches, ``retries`` (tasks the scheduler
    ran again after their worker was lost)."""

    def __init__(self, cluster, store, stored=None):
        self.cluster, self.store, self.stored = cluster, store, dict(stored or {})
        self.tasks = self.reused = self.retries = 0
        self._shipped = None
        self.token = uuid.uuid4().hex[:12]  # task keys unique to this run, whoever else uses the scheduler

    def ship(self, args):
        """``args`` on every worker once (a future), however many rounds use them."""
        if self._shipped is None or self._shipped[0] is not args:
            [future] = self.cluster.client.scatter([args], broadcast=True, hash=False)
            self._shipped = (args, future)
        return self._shipped[1]


class BatchFailed:
    """What a worker returns instead of raising: the exception its batch raised (with the
    worker's traceback as a note), raised again by the client. A task that raises is logged by
    every Dask worker as "Compute Failed" with its traceback, on the stderr the command shares
    with its local workers: a full disk would be seven lines instead of one."""

    def __init__(self, error):
        import traceback

        self.error = error
        try:
            error.add_note("on the worker:\n" + "".join(traceback.format_exception(error)))
        except AttributeError:  # Python < 3.11
            pass


def _stored_batch(make, store, count_outputs, args, batch, count):
    """Worker: make one batch with one BLAS thread (as every other path), store it, return
    (handle, the rest of its outcome), or :class:`BatchFailed`."""
    from threadpoolctl import threadpool_limits

    try:
        with threadpool_limits(limits=1, user_api="blas"), _roomy_allocator():
            outcome = make(*args, batch, count)
            return store(batch, count, outcome), outcome[count_outputs:]
    except Exception as error:
        return BatchFailed(error)


@contextlib.contextmanager
def _roomy_allocator():
    """glibc's malloc, for one batch, keeping freed memory up to 32 MB blocks in its heap.

    Dask's nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536 (to hand memory back to the
    system), which also freezes malloc's adaptive mmap threshold: every temporary array above
    128 kB is then mapped and unmapped afresh, and a batch spent half its time in page faults
    (samba, 250 × 600 frames: 2.2 s alone, 4.2 s with that setting, 1.7–2.2 s with this). The
    memory is handed back after the batch (malloc_trim), as the nanny intends."""
    import ctypes
    import sys

    try:
        libc = ctypes.CDLL("libc.so.6") if sys.platform.startswith("linux") else None
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc: nothing to tune
        yield
        return
    M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
    mallopt(M_MMAP_THRESHOLD, 32 << 20)
    mallopt(M_TRIM_THRESHOLD, 1 << 30)
    try:
        yield
    finally:
        mallopt(M_TRIM_THRESHOLD, int(os.environ.get("MALLOC_TRIM_THRESHOLD_", 128 << 10)))
        libc.malloc_trim(0)


def _run_remote(make, args, batches, output_shapes, progress, remote):
    from distributed import CancelledError, KilledWorker, as_completed

    from ..errors import OptionError

    client = remote.cluster.client
    handles, rests, done, pending = [None] * len(batches), [None] * len(batches), 0, {}
    for i, (b, n) in enumerate(batches):
        if (b, n) in remote.stored:
            handles[i], rests[i] = remote.stored[(b, n)]
            remote.reused += 1
            done += n
    if done and progress is not None:
        progress(done)
    todo = [i for i, hit in enumerate(handles) if hit is None]
    if todo:
        shipped = remote.ship(args)
        for i in todo:
            b, n = batches[i]
            future = client.submit(_stored_batch, make, remote.store, len(output_shapes), shipped, b, n, pure=False,
                                   key=f"skinsynth-batch-{remote.token}-{b}-{n}")
            pending[future] = i
        try:
            for future in as_completed(list(pending)):
                i = pending[future]
                try:
                    result = future.result()
                except (KilledWorker, CancelledError) as error:
                    raise OptionError(f"--cluster: batch {batches[i][0]} was lost ({type(error).__name__}: it ended "
                                      "every worker that ran it, or the scheduler went away); the finished batches "
                                      "are kept: run the command again to go on") from None
                if isinstance(result, BatchFailed):
                    raise result.error
                handles[i], rests[i] = result
                remote.stored[batches[i]] = (handles[i], rests[i])
                done += batches[i][1]
                if progress is not None:
                    progress(done)
            remote.retries += _lost_worker_retries(client, [f.key for f in pending])
        finally:
            client.cancel(list(pending))
        remote.tasks += len(todo)
    pieces = [(h, n) for h, (_, n) in zip(handles, batches)]
    return [StoredRows(pieces, shape[1:]) for shape in output_shapes], rests


def _lost_worker_retries(client, keys):
    """How many times the scheduler ran one of ``keys`` again because its worker was lost
    (0 when the scheduler will not say)."""
    def count(dask_scheduler, keys=tuple(keys)):  # nested: shipped by value, the scheduler needs no skinsynth
        return sum(getattr(dask_scheduler.tasks.get(k), "suspicious", 0) for k in keys)

    try:
        return int(client.run_on_scheduler(count))
    except Exception:  # an older scheduler without the counter: say nothing rather than fail the run
        return 0
