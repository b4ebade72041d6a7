"""Control-point trajectories for ``play``: CSV, .npy, or the control vertices of a mesh sequence.

- CSV: a header ``frame,point,x,y,z`` then one row per (frame, point); every frame 0..F−1 must
  give every point 0..n_c−1 exactly once (any row order).
- ``.npy``: an array (F, n_c, 3).
- anything ``read_mesh_sequence`` reads (folder, glob, USD, .npz/.h5): the control vertices'
  positions are taken from it, as Feng et al. do with their test sequences.

:func:`write_control_trajectories` writes the first two (``skinsynth view``'s recorded sessions).
"""

import os

import numpy as np

from .errors import FormatError, require_coordinates

def _check(path, controls, count):
    if controls.ndim != 3 or controls.shape[2] != 3:
        raise FormatError(path, f"control trajectories must have shape (frames, points, 3), got {controls.shape}")
    if controls.shape[0] < 1:
        raise FormatError(path, "no frames")
    if controls.shape[1] != count:
        raise FormatError(path, f"{controls.shape[1]} control points per frame, but the puppet has {count}")
    require_coordinates(path, controls)
    return controls


def _read_csv(path, count):
    try:
        with open(path, encoding="utf-8") as handle:
            header = handle.readline().strip().lower().replace(" ", "")
            if header != "frame,point,x,y,z":
                raise FormatError(path, f"the first line must be the header frame,point,x,y,z (got {header[:40]!r})")
            rows = np.loadtxt(handle, delimiter=",", ndmin=2)
    except (OSError, UnicodeDecodeError) as error:
        raise FormatError(path, f"cannot read: {error}") from None
    except ValueError as error:
        raise FormatError(path, f"not numeric CSV rows: {error}") from None
    if rows.size == 0:
        raise FormatError(path, "no rows after the header")
    if rows.shape[1] != 5:
        raise FormatError(path, f"rows must have 5 columns (frame,point,x,y,z), got {rows.shape[1]}")
    frame, point = rows[:, 0], rows[:, 1]
    if not (np.all(frame == np.round(frame)) and np.all(point == np.round(point))) or frame.min() < 0 or point.min() < 0:
        raise FormatError(path, "frame and point must be non-negative integers")
    frame, point = frame.astype(np.int64), point.astype(np.int64)
    if point.max() >= count:
        raise FormatError(path, f"point {point.max()} does not exist: the puppet has {count} control points (0..{count - 1})")
    frames = int(frame.max()) + 1
    # Every frame gives every point once, so the rows bound the frames: check before allocating
    # (a lone row numbered 100000000 asked for gigabytes).
    if frames > rows.shape[0]:  # each frame needs at least one row: the table stays ≤ rows × points
        raise FormatError(path, f"{rows.shape[0]} rows cannot hold frames 0..{frames - 1} ({frames * count} rows "
                                f"for {count} points): frames are missing; every frame needs each point exactly once")
    seen = np.zeros((frames, count), dtype=np.int64)
    np.add.at(seen, (frame, point), 1)
    if (seen != 1).any():
        f, p = np.argwhere(seen != 1)[0]
        state = "missing" if seen[f, p] == 0 else "given twice"
        raise FormatError(path, f"frame {f}, point {p} is {state}: every frame needs each point exactly once")
    controls = np.empty((frames, count, 3))
    controls[frame, point] = rows[:, 2:]
    return controls


def read_control_trajectories(spec, count, control_indices, vertex_count):
    """Control positions (F, n_c, 3) from a CSV, .npy or mesh sequence (see module doc)."""
    from .meshseq import read_mesh_sequence

    ext = os.path.splitext(str(spec))[1].lower()
    if ext == ".csv":
        return _check(spec, _read_csv(spec, count), count)
    if ext == ".npy":
        try:
            # Memory-mapped first: the header's shape is checked against the file's size before
            # anything is allocated (a small file declaring a huge array is refused, not loaded).
            controls = np.load(spec, allow_pickle=False, mmap_mode="r")
        except FileNotFoundError:
            raise FormatError(spec, "no such file") from None
        except (OSError, ValueError) as error:
            raise FormatError(spec, f"not a numpy .npy array: {error}") from None
        return _check(spec, np.asarray(controls, dtype=np.float64), count)
    sequence = read_mesh_sequence(spec)
    if sequence.vertices.shape[1] != vertex_count:
        raise FormatError(spec, f"{sequence.vertices.shape[1]} vertices per frame, but the puppet's mesh has "
                                f"{vertex_count}: control vertices can only be taken from the same mesh")
    return _check(spec, sequence.vertices[:, control_indices], count)


def write_control_trajectories(path, controls):
    """Write controls (F, n_c, 3) as a trajectory file :func:`read_control_trajectories` reads
    back exactly: CSV ``frame,point,x,y,z`` (17 significant digits) or ``.npy``, by the
    extension; atomically (a failed write leaves nothing). Raises ValueError for another
    extension or a folder that does not exist."""
    from .atomic import atomic_output

    lower = str(path).lower()
    if not lower.endswith((".csv", ".npy")):
        raise ValueError(f"{path}: a control trajectory is written as .csv or .npy")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise ValueError(f"{path}: the folder {folder} does not exist")
    controls = np.asarray(controls, dtype=np.float64)
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as handle:
            if lower.endswith(".npy"):
                np.save(handle, controls)
            else:
                frames, points = controls.shape[:2]
                rows = np.column_stack([np.repeat(np.arange(frames), points), np.tile(np.arange(points), frames),
                                        controls.reshape(-1, 3)])
                handle.write(b"frame,point,x,y,z\n")
                np.savetxt(handle, rows, fmt=["%d", "%d", "%.17g", "%.17g", "%.17g"], delimiter=",")
