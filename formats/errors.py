"""The one exception type for bad input files: it names the file and the problem."""


class FormatError(Exception):
    """A file that cannot be used: missing, unreadable, of the wrong kind, or with bad contents.

    The CLI prints ``str(error)`` as its single error line and exits with status 2.
    """

    def __init__(self, path, problem):
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


def all_finite(array):
    """Whether a numeric array holds no NaN or inf, in one float64 sum (NaN and inf propagate
    through a sum; a sum of finite float32 values cannot overflow float64): much cheaper than
    ``np.isfinite(array).all()`` on the half-gigabyte results synthesize writes."""
    import numpy as np

    array = np.asarray(array)
    if array.dtype.kind not in "fc" or array.size == 0:
        return True
    return bool(np.isfinite(np.add.reduce(array.ravel(), dtype=np.complex128 if array.dtype.kind == "c"
                                          else np.float64)))


def require_finite(path, what, array):
    """FormatError naming ``path`` and ``what`` unless ``array`` is finite: a result that went out
    of range is never written."""
    if not all_finite(array):
        raise FormatError(path, f"not written: {what} holds NaN or inf values (a result out of range: check the "
                                "options and the input that produced it)")
