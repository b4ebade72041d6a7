"""How the work runs, on the floor every stage may import: the process pool and the Dask cluster
(:mod:`.execution`), and the bookkeeping of loops compiled ahead of use (:mod:`.compiled`)."""
