"""What a file holding animation gives to export (a skin's examples, a synthesis's animations, a
played file's characters): a plain record of its animations, read on demand, and how each splits
into the clips it holds. ``cli/export.py`` fills it in from the file's reader."""

import numpy as np


class AnimationSource:
    """What a file holds to export: ``count`` animations of ``frames`` frames named ``names``,
    ``vertices(a)`` (frames, V, 3) of one, and where there is a skeleton (``skin``)
    ``motions(a)``: its bone rotations (frames, B, 3, 3) and translations (frames, B, 3).
    ``clips``: a skin's example frames, (names (C,), frame counts (C,)) of the clips they hold
    end to end, or None (a synthesis, a played file)."""

    def __init__(self, path, what, names, frames, rest_vertices, faces, fps, scene, vertices, motions=None,
                 skin=None, clips=None):
        self.path, self.what, self.names, self.frames = path, what, names, frames
        self.rest_vertices, self.faces, self.fps, self.scene = rest_vertices, faces, fps, scene
        self.vertices, self.motions, self.skin, self.clips = vertices, motions, skin, clips

    def part_names(self, a):
        """The names of the glTF animations animation ``a`` becomes (:meth:`parts`)."""
        return [self.names[a]] if self.clips is None or len(self.clips[0]) < 2 else list(self.clips[0])

    def parts(self, a):
        """(name, rotations, translations) of each glTF animation (or bone-texture clip) animation
        ``a`` becomes: one per clip, named after it, when it holds several; else the one named
        ``names[a]``."""
        return self._split(a, *self.motions(a))

    def vertex_parts(self, a):
        """(name, vertices) of each texture of a folder animation ``a`` becomes, split as :meth:`parts`."""
        return self._split(a, self.vertices(a))

    def _split(self, a, *arrays):
        """[(name, *arrays' frames)] per clip of animation ``a`` (one entry when it holds one clip)."""
        if self.clips is None or len(self.clips[0]) < 2:
            return [(self.names[a], *arrays)]
        ends = np.cumsum(self.clips[1])
        return [(name, *(x[end - count:end] for x in arrays)) for name, count, end in zip(*self.clips, ends)]

    @property
    def count(self):
        return len(self.names)

    @property
    def has_skeleton(self):
        return self.skin is not None
