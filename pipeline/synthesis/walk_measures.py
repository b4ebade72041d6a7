"""How much of the clip each walk plays, and whether it got stuck in a loop (issue 48).

A walk on a motion graph whose transitions cluster at the clip's end can reach that end and
stay there: the only ways on lead back a few strides, so it plays the same two-second stretch
again and again. Two measures catch it, each per animation (walks ``sources (N, M)``, the input
frame shown at each output frame):

- :func:`distinct_frames` (N,): how many distinct input frames the walk plays.
- :func:`stuck_loops` (N,): the output frames the walk spends repeating a short loop: a stretch
  of P frames (P at most ``longest`` seconds) played more than ``repeats`` times in a row, i.e.
  ``source[m] == source[m + P]`` for at least ``repeats × P`` consecutive m. A walk with any such
  frames is *stuck* (:func:`stuck_walks`). The defaults (2 s, 3 times) are issue 48's definition:
  a stride or two of walking replayed four times over reads as a loop, not as a walk; a longer
  stretch replayed, or a short one twice, is what any motion graph of one clip does.

Every test is exact on integer frame ids: one pass per period P over all walks at once.
"""

import numpy as np

#: Longest loop (seconds) that counts as stuck, and how many times in a row it must repeat beyond
#: its first play (issue 48: "a stretch shorter than 2 s played more than 3 times in a row").
STUCK_SECONDS = 2.0
STUCK_REPEATS = 3


def distinct_frames(sources):
    """(N,) int: the distinct input frames each walk of sources (N, M) plays."""
    sources = np.sort(np.asarray(sources, np.int64), axis=1)
    if sources.shape[1] == 0:
        return np.zeros(sources.shape[0], np.int64)
    return 1 + np.count_nonzero(sources[:, 1:] != sources[:, :-1], axis=1)


def stuck_loops(sources, fps, longest=STUCK_SECONDS, repeats=STUCK_REPEATS, clip_frames=None):
    """(N,) int: per walk of sources (N, M), the output frames inside a loop of some period P
    (2 ≤ P < ``longest`` × fps frames) repeated more than ``repeats`` times in a row: the frames
    m .. m + (repeats + 1)·P − 1 of every run where ``source[m + k] == source[m + k + P]`` for
    ``repeats × P`` consecutive k (module notes). P = 1 (a frame held) is no loop of a walk, nor is
    P ≥ ``clip_frames`` (None: any P counts): a clip shorter than ``longest`` played whole, over and
    over, is the clip looping, not a walk caught in a part of it (the horse gallop is 2 s long:
    in-betweened to 48 fps it has 95 frames, 1.98 s, and a walk that played it end to end was
    "stuck" where the same walk at 24 fps, 48 frames, 2.0 s, was not)."""
    sources = np.asarray(sources, np.int64)
    count, length = sources.shape
    covered = np.zeros((count, length), bool)
    most = min(int(np.ceil(longest * float(fps))) - 1, length // (repeats + 1))  # shorter than `longest`
    if clip_frames is not None:
        most = min(most, int(clip_frames) - 1)
    for period in range(2, most + 1):
        same = sources[:, period:] == sources[:, :-period]  # (N, M − P)
        need = repeats * period
        if same.shape[1] < need:
            break
        # runs of `need` consecutive matches: a sliding count by cumulative sums
        total = np.concatenate([np.zeros((count, 1), np.int64), np.cumsum(same, axis=1)], axis=1)
        full = (total[:, need:] - total[:, :-need]) == need  # (N, M − P − need + 1): a run starts at m
        if not full.any():
            continue
        # each such start m covers output frames m .. m + need + P − 1
        span = need + period
        starts = np.zeros((count, length + 1), np.int64)
        starts[:, :full.shape[1]] += full
        starts[:, span:] -= full  # width M + 1 − span, as full's
        covered |= np.cumsum(starts, axis=1)[:, :length] > 0
    return covered.sum(axis=1)


def stuck_walks(sources, fps, longest=STUCK_SECONDS, repeats=STUCK_REPEATS, clip_frames=None):
    """(N,) bool: the walks of sources (N, M) that repeat a loop shorter than ``longest`` seconds
    (and than ``clip_frames``) more than ``repeats`` times in a row (:func:`stuck_loops`)."""
    return stuck_loops(sources, fps, longest, repeats, clip_frames) > 0
