"""Several clips of one mesh, played one after another in one frame numbering (issue 26).

A stage file's examples may hold several takes of one character (a gallop, a collapse, key
poses): ``vertices (F, V, 3)`` is the clips concatenated in order, and :class:`Clips` says where
each begins. Clip ``c`` holds the global frames ``starts[c] … starts[c+1] − 1``; every array
indexed by frame (bone transforms, sources of a walk, held-out frames) uses the global numbers,
and people name a frame ``clip:frame`` (``collapse:0``, the collapse's first frame).

Conventions every stage shares (each is one function here, so no stage writes its own):

- **Playback stays inside a clip.** Frame ``f`` is followed by ``f + 1`` only when both are in
  the same clip (:meth:`Clips.plays_on`): the gallop's last frame is not followed by the
  collapse's first. Anything that looks at a frame's neighbours (velocities, finite
  differences, blend windows) looks within its clip.
- **A transition (i, j) plays j + 1 after i** (:mod:`.synthesis.motion_graph`). ``j ≥ 0`` is a
  frame that is not the last of its clip. "Continue at the first frame of clip c" is the
  virtual frame before that clip, ``j = −(c + 1)`` (:meth:`Clips.virtual_frame`); with one clip
  this is the ``j = −1`` every graph file already holds, so a one-clip file reads the same.
- **A seam** is an output frame whose source does not play on from the one before
  (:meth:`Clips.seams`): ``source[k] ≠ source[k−1] + 1``, or ``source[k]`` begins a clip.
- **Names** are short words (letters, digits, ``_``, ``.``, ``-``) and distinct, since they
  appear in ``clip:frame@time`` and ``--clips a,b``.
"""

import re
from dataclasses import dataclass

import numpy as np

from ..errors import OptionError

NAME_PATTERN = re.compile(r"^[A-Za-z0-9_.\-]+$")


@dataclass(frozen=True)
class Clips:
    """Clip names (C,) and frame counts (C,) (each ≥ 1) of a frame sequence, in order."""

    names: tuple
    frames: tuple

    def __post_init__(self):
        names, frames = tuple(str(n) for n in self.names), tuple(int(f) for f in self.frames)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "frames", frames)
        if not names or len(names) != len(frames):
            raise ValueError(f"clips need one frame count per name (got {len(names)} names, {len(frames)} counts)")
        if min(frames) < 1:
            raise ValueError(f"every clip needs at least one frame (got {list(frames)})")
        bad = [n for n in names if not NAME_PATTERN.match(n)]
        if bad:
            raise ValueError(f"clip name {bad[0]!r} must be letters, digits, '_', '.' or '-'")
        if len(set(names)) != len(names):
            raise ValueError(f"clip names must differ (got {list(names)})")

    @classmethod
    def single(cls, frames, name="clip"):
        """One clip of ``frames`` frames."""
        return cls((name,), (int(frames),))

    def __len__(self):
        return len(self.names)

    @property
    def total(self):
        """F: the frames of every clip together."""
        return int(sum(self.frames))

    @property
    def starts(self):
        """(C + 1,) int64: clip c is frames starts[c] … starts[c+1] − 1."""
        return np.concatenate([[0], np.cumsum(self.frames)]).astype(np.int64)

    def clip_of(self, frames):
        """The clip of each global frame (any int array shape) -> int64 of the same shape."""
        return np.searchsorted(self.starts, np.asarray(frames, np.int64), side="right") - 1

    def first_frames(self):
        """(F,) bool: frames that begin a clip."""
        mask = np.zeros(self.total, bool)
        mask[self.starts[:-1]] = True
        return mask

    def last_frames(self):
        """(F,) bool: frames that end a clip."""
        mask = np.zeros(self.total, bool)
        mask[self.starts[1:] - 1] = True
        return mask

    def plays_on(self):
        """(F,) bool: frame f is followed by f + 1 in playback (f is not the last of its clip)."""
        return ~self.last_frames()

    def index(self, name, option="clip"):
        """The position of the clip called ``name``; an unknown name is an OptionError listing them."""
        try:
            return self.names.index(name)
        except ValueError:
            raise OptionError(f"{option}: no clip named {name!r}; the clips are {', '.join(self.names)}") from None

    def frame(self, text, option="frame"):
        """A global frame from ``clip:frame`` (the clip's own frame number; negative counts from
        its end) or a plain global frame number. Out of range or unknown: OptionError."""
        text = str(text).strip()
        name, _, number = text.rpartition(":")
        try:
            local = int(number)
        except ValueError:
            raise OptionError(f"{option} {text!r}: expected CLIP:FRAME (clips: {', '.join(self.names)}) "
                              "or a frame number") from None
        if not name:
            if not -self.total <= local < self.total:
                raise OptionError(f"{option} {text}: outside the {self.total} frames")
            return local % self.total
        clip = self.index(name, f"{option} {text!r}")
        count = self.frames[clip]
        if not -count <= local < count:
            raise OptionError(f"{option} {text}: clip {name!r} has frames 0..{count - 1}")
        return int(self.starts[clip] + local % count)

    def label(self, frame):
        """``clip:frame`` of a global frame (a plain number when there is only one clip)."""
        frame = int(frame)
        if len(self) == 1:
            return str(frame)
        clip = int(self.clip_of(frame))
        return f"{self.names[clip]}:{frame - int(self.starts[clip])}"

    def select(self, names, option="--clips"):
        """Global frame ids (increasing) of the named clips (an iterable of names, or one
        comma-separated string); None or empty selects every frame."""
        if names is None or names == "" or names == ():
            return np.arange(self.total)
        if isinstance(names, str):
            names = [n for n in names.split(",") if n.strip()]
        chosen = sorted({self.index(n.strip(), option) for n in names})
        starts = self.starts
        return np.concatenate([np.arange(starts[c], starts[c + 1]) for c in chosen]).astype(np.int64)

    def subset(self, names, option="--clips"):
        """The :class:`Clips` of the named clips, in file order (their frames renumbered from 0);
        an unknown name is an OptionError naming ``option`` and the clips."""
        chosen = sorted({self.index(n, option) for n in names})
        return Clips(tuple(self.names[c] for c in chosen), tuple(self.frames[c] for c in chosen))

    # --- transitions and walks ---------------------------------------------------------------

    @staticmethod
    def virtual_frame(clip):
        """j of a transition that continues at the first frame of ``clip`` (module notes)."""
        return -(int(clip) + 1)

    def targets(self, j):
        """The frame a transition (i, j) plays next, for j (any int array shape): j + 1 for
        j ≥ 0, the first frame of clip −j − 1 for j < 0."""
        j = np.asarray(j, np.int64)
        clip = np.clip(-j - 1, 0, len(self) - 1)
        return np.where(j >= 0, j + 1, self.starts[clip])

    def transition_j(self, target):
        """The j a transition into ``target`` (any int array shape) names: target − 1, or the
        virtual frame before its clip when ``target`` begins one. Inverse of :meth:`targets`."""
        target = np.asarray(target, np.int64)
        first = self.first_frames()[target]
        return np.where(first, -(self.clip_of(target) + 1), target - 1)

    def valid_j(self, j):
        """(…) bool: j names a transition's frame: a virtual frame −1 … −C, or a frame ≥ 0 that
        is followed by j + 1 in its clip."""
        j = np.asarray(j, np.int64)
        inside = (j >= 0) & (j < self.total)
        plays = self.plays_on()[np.where(inside, j, 0)]
        return (inside & plays) | ((j < 0) & (j >= -len(self)))

    def continues(self, sources):
        """(…, M − 1) bool over walks ``sources (…, M)``: output frame k + 1 plays on from k
        (same clip, next frame); False marks a seam."""
        sources = np.asarray(sources, np.int64)
        step = sources[..., 1:] == sources[..., :-1] + 1
        return step & ~self.first_frames()[np.clip(sources[..., 1:], 0, self.total - 1)]

    def seams(self, sources):
        """(…, M) bool: output frames that are seams (never the first)."""
        sources = np.asarray(sources, np.int64)
        seams = np.zeros(sources.shape, bool)
        seams[..., 1:] = ~self.continues(sources)
        return seams
