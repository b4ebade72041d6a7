"""A Dask worker preload for tests/test_cluster.py (DASK_DISTRIBUTED__WORKER__PRELOAD='["<this file>"]'):
the worker stores the first skinsynth batch it makes as usual and holds every later one before
it is stored, until the worker closes (or HOLD_SECONDS pass), then fails it unstored. While it
holds one, the file named by CLUSTER_HOLD_MARKER exists.

With one worker, a run under this preload has exactly one finished shard for as long as it runs,
and it cannot finish on its own: an interruption sent once that shard is there lands mid-run."""

import os
import time

HOLD_SECONDS = 300.0


def dask_setup(worker):
    from distributed.core import Status

    import skinsynth.formats.synthesis_shards as shards

    write = shards.write_synthesis_shard
    stored = []

    def write_first_only(folder, record, batch, count, outcome):
        if not stored:
            stored.append(batch)
            return write(folder, record, batch, count, outcome)
        open(os.environ["CLUSTER_HOLD_MARKER"], "w").close()
        deadline = time.monotonic() + HOLD_SECONDS
        while worker.status in (Status.running, Status.paused) and time.monotonic() < deadline:
            time.sleep(0.05)
        raise RuntimeError(f"batch {batch} held by tests/cluster_hold.py and not stored")

    # the command ships its store as functools.partial(write_synthesis_shard, …), pickled by name:
    # the worker unpickles it as this module attribute
    shards.write_synthesis_shard = write_first_only
