"""A synthesis's page: one animation at a time, each component its colour, seams marked."""

import numpy as np

from .. import scenes
from .framing import frame_camera
from .timeline import Timeline

#: A synthesis component is drawn in the seam colour for this share of a second after a seam,
#: so that a seam stays visible while playing (at 24 fps: 6 frames).
SEAM_HOLD_SECONDS = 0.25
#: Slider marks for at most this many seams (a long animation's slider stays readable).
MAX_MARKS = 120


class SynthesisPage:
    """One animation at a time (picked by number), each component its colour, red for a quarter
    second after its seams, seams marked on the frame slider."""

    def __init__(self, server, view, warn):
        self.server, self.view = server, view
        self.palette = scenes.component_colors(view.components)
        self.hold = max(1, int(round(SEAM_HOLD_SECONDS * view.fps)))
        keys = scenes.face_components(view.faces, view.vertex_components)
        self.parts = scenes.split_by_key(view.faces, keys)
        frame_camera(server, view.rest, view.up_axis)
        self.nodes = [server.scene.add_mesh_simple(f"/synthesis/component_{key:03d}", view.rest[ids], local,
                                                   color=tuple(int(c) for c in self.palette[key]))
                      for key, ids, local in self.parts]
        server.gui.add_markdown(f"**Synthesis**: {view.count} animation(s); each component its colour, "
                                "red at its seams")
        self.picker = server.gui.add_number("animation", initial_value=view.animation, min=0, max=view.count - 1,
                                            step=1)
        self.info = server.gui.add_markdown("")
        self.frame_of, self.seams, self.sources = self._load(view.animation)
        self.timeline = Timeline(server, view.frames, view.fps, self.show, warn, marks=self._marks())
        self.picker.on_update(lambda _: self.pick())
        self.show(0)

    def _load(self, animation):
        frame_of, sources = self.view.load(animation)
        seams = scenes.seam_frames(sources, self.view.clips)  # (C, M)
        held = np.zeros_like(seams)
        for lag in range(self.hold):
            held[:, lag:] |= seams[:, :seams.shape[1] - lag]
        self.animation = animation
        return frame_of, held, sources

    def _marks(self):
        frames = np.flatnonzero(scenes.seam_frames(self.sources, self.view.clips).any(axis=0))
        return [int(f) for f in frames[:MAX_MARKS]] or None

    def pick(self):
        """Show the picked animation from its first frame (read under the timeline's lock: the
        last of several quick picks wins)."""
        with self.timeline.lock:
            animation = int(self.picker.value)
            if not 0 <= animation < self.view.count or animation == self.animation:
                return
            self.frame_of, self.seams, self.sources = self._load(animation)
        self.timeline.reset(self.view.frames, self._marks())

    def show(self, frame):
        vertices = self.frame_of(frame)
        with self.server.atomic():
            for node, (key, ids, _) in zip(self.nodes, self.parts):
                node.vertices = vertices[ids]
                node.color = tuple(int(c) for c in (scenes.SEAM_COLOR if self.seams[key, frame] else self.palette[key]))
            clips = self.view.clips
            played = ", ".join(str(int(s)) if clips is None else clips.label(s) for s in self.sources[:, frame])
            at_seam = [str(c) for c in np.flatnonzero(scenes.seam_frames(self.sources, clips)[:, frame])]
            self.info.content = (f"animation {self.animation}, frame {frame}: input frame(s) {played}"
                                 + (f"; seam in component {', '.join(at_seam)}" if at_seam else ""))

    def close(self):
        self.timeline.close()

