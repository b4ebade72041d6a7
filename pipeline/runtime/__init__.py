"""How the work runs, on the floor every stage may import: the process pool and the Dask cluster
(:mod:`.execution`), the bookkeeping of loops compiled ahead of use (:mod:`.compiled`), and the
memory and disk space a request is checked against before any work (:mod:`.resources`), and an
array's distinct rows, safe under a signal (:mod:`.rows`)."""
