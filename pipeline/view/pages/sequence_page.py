"""Any animated meshes' page (a sequence, play's characters)."""

import numpy as np

from .framing import MESH_COLOR, frame_camera
from .timeline import Timeline


class SequencePage:
    """Animated meshes (a sequence, play's characters) with a frame slider and play/pause."""

    def __init__(self, server, view, warn):
        self.server, self.view = server, view
        frame_camera(server, np.concatenate([v[0] for _, v, _ in view.parts]), view.up_axis)
        self.nodes = [server.scene.add_mesh_simple(f"/sequence/part_{n:03d}", vertices[0], faces, color=MESH_COLOR)
                      for n, (_, vertices, faces) in enumerate(view.parts)]
        names = [name for name, _, _ in view.parts if name]
        server.gui.add_markdown("**Sequence**" + (f": {', '.join(names[:8])}" if names else ""))
        frames = min(len(vertices) for _, vertices, _ in view.parts)
        self.timeline = Timeline(server, frames, view.fps, self.show, warn)

    def show(self, frame):
        with self.server.atomic():
            for node, (_, vertices, _) in zip(self.nodes, self.view.parts):
                node.vertices = vertices[frame]

    def close(self):
        self.timeline.close()

