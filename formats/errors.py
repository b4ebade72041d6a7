"""The one exception type for bad input files: it names the file and the problem."""


class FormatError(Exception):
    """A file that cannot be used: missing, unreadable, of the wrong kind, or with bad contents.

    The CLI prints ``str(error)`` as its single error line and exits with status 2.
    """

    def __init__(self, path, problem):
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")

    def __reduce__(self):  # pickled by a cluster worker to the client: rebuilt from its two parts
        return type(self), (self.path, self.problem)


def all_finite(array):
    """Whether a numeric array holds no NaN or inf: one float64 sum first (NaN and inf propagate
    through a sum; a finite sum proves every value finite), much cheaper than
    ``np.isfinite(array).all()`` on the half-gigabyte results synthesize writes; that check only
    where the sum is not finite (a NaN, or finite values whose sum overflows)."""
    import numpy as np

    array = np.asarray(array)
    if array.dtype.kind != "f" or array.size == 0:
        return True
    if np.isfinite(np.add.reduce(array.ravel(), dtype=np.float64)):
        return True
    return bool(np.isfinite(array).all())  # the sum overflowed, or a value is NaN or inf: look


#: skinsynth writes float32 (largest value 3.4e38) and squares distances on the way (float64 sums
#: of squares overflow from 1e154): no input coordinate may reach 1e18, far beyond any real unit,
#: so no result is ever inf and no fit fails to converge on overflowing sums.
MAX_COORDINATE = 1e18


def require_coordinates(path, points, item="point"):
    """FormatError naming ``path``, the frame and the ``item`` unless every coordinate of
    ``points (F, N, 3)`` is finite and below :data:`MAX_COORDINATE` in magnitude."""
    import numpy as np

    points = np.asarray(points)
    peak = np.abs(points).max(axis=(1, 2)) if points.size else np.zeros(0)
    if (peak < MAX_COORDINATE).all():  # NaN compares false: caught here too
        return
    frame = int(np.argmin(peak < MAX_COORDINATE))
    magnitude = np.abs(points[frame]).max(axis=1)
    index = int(np.argmin(magnitude < MAX_COORDINATE))
    value = magnitude[index]
    if not np.isfinite(value) or not np.isfinite(points[frame, index]).all():
        raise FormatError(path, f"non-finite coordinates (NaN or inf) at frame {frame}, {item} {index}")
    raise FormatError(path, f"coordinate {value:.3g} at frame {frame}, {item} {index}: coordinates must stay below "
                            f"{MAX_COORDINATE:.0e} in magnitude (skinsynth squares them and writes float32); "
                            "rescale the input")


def require_finite(path, what, array):
    """FormatError naming ``path`` and ``what`` unless ``array`` is finite: a result that went out
    of range is never written."""
    if not all_finite(array):
        raise FormatError(path, f"not written: {what} holds NaN or inf values (a result out of range: check the "
                                "options and the input that produced it)")


#: A stored array may expand to at most this many times the bytes it occupies in its file (gzip
#: or deflate of real float data stays far below; all zeros reach about 1000×, deflate's own
#: ceiling is 1032×)...
MAX_EXPANSION = 1000
#: ... once it is larger than this (small arrays are read whatever their storage).
SMALL_ARRAY_BYTES = 64 << 20


def declared_size_problem(what, declared, held):
    """A message when ``declared`` bytes are far more than the ``held`` bytes a file stores for
    ``what`` (a small file must never make a reader ask for gigabytes); None when plausible.
    Callers check before allocating, then raise FormatError naming the file."""
    if declared > SMALL_ARRAY_BYTES and declared > MAX_EXPANSION * max(held, 0):
        return (f"{what} declares {declared / 2 ** 30:.1f} GiB but the file holds {held / 2 ** 20:.1f} MiB of it "
                "(a damaged or hostile file)")
    return None
