"""A Dask worker preload for tests/contracts/test_cluster.py (DASK_DISTRIBUTED__WORKER__PRELOAD):
the worker stores its first skinsynth batch as usual; before its second it meets the fault that
CLUSTER_FAULT names:

- ``deleted``: the shard folder is removed (as by a user mid-run), then the write goes ahead;
- ``full``: the write fails as on a full disk (OSError ENOSPC naming the shard).
"""

import errno
import os
import shutil


def dask_setup(worker):
    import skinsynth.formats.synthesis_shards as shards

    write = shards.write_synthesis_shard
    calls = []

    def write_then_fail(folder, record, batch, count, outcome):
        calls.append(batch)
        if len(calls) == 2:
            if os.environ["CLUSTER_FAULT"] == "deleted":
                shutil.rmtree(folder)
            else:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), os.path.join(folder, f"batch_{batch:06d}.h5"))
        return write(folder, record, batch, count, outcome)

    # the command ships its store as functools.partial(write_synthesis_shard, …), pickled by name
    shards.write_synthesis_shard = write_then_fail
