"""Distinct rows of a 2-D array, sorted lexicographically: ``np.unique(rows, axis=0)`` without
its structured-dtype view.

numpy's ``unique(axis=0)`` views each row as one structured element and sorts those; a signal
(SIGINT/SIGTERM/SIGHUP, turned into an exception by the command's handler) that lands while
numpy compares them surfaces as numpy's "Cannot compare structured arrays" TypeError instead of
the interrupt, so a stopped command reported the wrong thing. ``np.lexsort`` over the columns
sorts plain numbers in C and lets the signal through after it returns.
"""
import numpy as np


def unique_rows(rows, return_index=False, return_inverse=False):
    """The distinct rows of ``rows (N, C)`` in lexicographic order, as ``np.unique(rows, axis=0)``.

    ``return_index``: the first row of ``rows`` holding each (a stable sort keeps rows in their
    order within a group); ``return_inverse (N,)``: which distinct row each row is. Returns the
    array, or a tuple with those that were asked for, in numpy's order.
    """
    rows = np.asarray(rows)
    if rows.ndim != 2:
        raise ValueError(f"rows must be 2-D, got shape {rows.shape}")
    n = rows.shape[0]
    order = np.lexsort(rows.T[::-1]) if rows.shape[1] else np.arange(n)
    ordered = rows[order]
    starts = np.ones(n, dtype=bool)
    if n:
        starts[1:] = np.any(ordered[1:] != ordered[:-1], axis=1)
    unique = ordered[starts]
    extra = []
    if return_index:
        extra.append(order[starts])
    if return_inverse:
        inverse = np.empty(n, dtype=np.intp)
        inverse[order] = np.cumsum(starts) - 1
        extra.append(inverse)
    return (unique, *extra) if extra else unique
