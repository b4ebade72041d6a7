"""Held poses: stretches of a clip where the character stands still (issue 63).

A capture that begins with the performer standing, or pauses in the middle, holds one pose for
tens or hundreds of frames. To a motion graph those frames are one place, not hundreds of
interchangeable ones: counted one by one they pull the playback steps that size the threshold
towards zero (:func:`.transitions.transition_threshold` now measures only the moving frames),
they fill the strongly connected part with copies of one pose, and walks that enter them stand
still for seconds (the samba with 3 s held before it and 2 s inside: 0.15 of its moving poses
per 600-frame animation, against 0.93 as shared).

A *held run* is a stretch of at least ``min_frames`` frames of one clip in which no bone's pivot
(its weighted rest centroid, carried by the bone's transform: :func:`.transitions.bone_centroids`)
moves farther than ``tolerance`` × the character's size from where it is at the run's first
frame. Why these two numbers hold in general: the tolerance is a share of the body's size, so it
holds in any unit and any axis convention (Z up in centimetres is the same run), and at 0.2 %
(3.6 mm on a 1.8 m person) it is far below a stride's or a gesture's displacement yet well above
the fitted bones' jitter on the shared captures; the length is in time (build-graph: a second,
twice the shortest segment walks play, :func:`.motion_graph.default_min_segment`), so the same
pause is found at 12 fps or at 96, and neither the slow ends of a gesture (a limb turning round,
still for a frame or two) nor a beat's half-second pause, part of the motion, is a run (the Dem
Bones bar pauses 12 frames at frame 174: counted as a run, its walks played fewer poses). Runs
are found greedily from each clip's first frame: a run ends at the first frame that leaves its
first frame's tolerance.

The graph then shows ``keep`` + 1 frames of each run (its first ``keep``, half a second, and its last):
walks that reach a held pose show it for ``keep`` frames and go on from its last frame, by a
*skip* (``(first + keep − 1, last − 1)`` as a transition: D ≈ 0, the poses are one) that
:func:`.transitions.select_held` adds, and the frames between are never shown
(:attr:`HeldPoses.hidden`, synthesize's forbidden frames).
"""

from dataclasses import dataclass

import numpy as np

#: The largest distance (share of the character's size) a bone's pivot may move from the run's
#: first frame for the frames to count as one held pose (module notes).
HELD_TOLERANCE = 0.002


@dataclass
class HeldPoses:
    """runs (R, 2) int: the first and last frame of each held run (inclusive, in clip order);
    keep: how many of its first frames a run shows before its skip; frames F."""

    runs: np.ndarray
    keep: int
    frames: int

    @property
    def hidden(self):
        """(F,) bool: the frames of a run that are never shown (past its first ``keep``, before its last)."""
        hidden = np.zeros(self.frames, bool)
        for first, last in self.runs:  # a loop over runs
            hidden[first + self.keep:last] = True
        return hidden

    @property
    def skips(self):
        """(S, 2) int: the transitions (first + keep − 1, last − 1) that carry a walk past a run's
        hidden frames (none for a run too short to hide any)."""
        runs = self.runs.reshape(-1, 2)
        long = runs[:, 1] - runs[:, 0] > self.keep
        return np.stack([runs[long, 0] + self.keep - 1, runs[long, 1] - 1], axis=1).astype(np.int64).reshape(-1, 2)

    @property
    def representative(self):
        """(F,) int: each frame's pose, a run's frames all the run's first: a held pose counts once."""
        rep = np.arange(self.frames)
        for first, last in self.runs.reshape(-1, 2):
            rep[first:last + 1] = first
        return rep

    @property
    def moving(self):
        """(F,) bool: one frame per pose: every frame outside the runs and each run's first."""
        rep = self.representative
        return rep == np.arange(self.frames)


def find_held_poses(rotations, translations, pivots, size, min_frames, clips=None, tolerance=HELD_TOLERANCE,
                    keep=None):
    """The held runs of a clip (module notes). rotations (F, B, 3, 3), translations (F, B, 3),
    pivots (B, 3) the bones' rest pivots; size: the character's size (the rest pose's largest
    extent); min_frames: the shortest run (build-graph: a second of frames, twice its min_segment); clips: the
    :class:`.clips.Clips` of the frames (None: one clip; a run never crosses a clip's end);
    keep (None: ``min_frames``): the frames a run shows before its skip. Returns HeldPoses."""
    rotations = np.asarray(rotations, np.float64)
    frames = rotations.shape[0]
    keep = int(min_frames if keep is None else keep)
    points = np.einsum("fbij,bj->fbi", rotations, np.asarray(pivots, np.float64)) + np.asarray(translations, np.float64)
    limit = float(tolerance) * float(size)
    bounds = [0, frames] if clips is None else clips.starts.tolist()
    starts, ends = bounds[:-1], bounds[1:]
    runs = []
    for start, end in zip(starts, ends):  # a loop over clips, then over runs
        first = start
        while first < end - 1:
            last = _run_end(points, first, end, limit)
            if last - first + 1 >= min_frames:
                runs.append((first, last))
                first = last + 1
            else:
                first += 1
    return HeldPoses(np.asarray(runs, np.int64).reshape(-1, 2), keep, frames)


def _run_end(points, first, end, limit):
    """The last frame before ``end`` whose every pivot lies within ``limit`` of frame ``first``'s,
    searched in windows that double (a moving frame leaves within a frame or two)."""
    window = 8
    looked = first + 1
    while looked < end:
        stop = min(end, looked + window)
        moved = np.linalg.norm(points[looked:stop] - points[first], axis=-1).max(axis=-1)
        leaves = np.flatnonzero(moved > limit)
        if leaves.size:
            return looked + int(leaves[0]) - 1
        looked, window = stop, 2 * window
    return end - 1
