"""A skin fit's page (a skin file, or the skin a controls or graph file carries): the examples
beside fit-skin's reconstruction, the reconstruction coloured by error (``scenes.error_levels``);
a graph file's ground contacts, a fit's skeleton."""

import numpy as np

from .. import scenes
from .framing import frame_camera
from .timeline import Timeline

INPUT_COLOR = (150, 150, 150)
#: Error shades of a skin fit's reconstruction (``scenes.error_levels``): 8 steps grey to red.
ERROR_STEPS = 8
#: The opacity of a skin fit's reconstruction with a skeleton drawn inside it (its joints and bones show through).
SEE_THROUGH = 0.55


class SkinPage:
    """Examples and reconstruction, side by side or overlaid, the reconstruction coloured by
    each face's error (see-through, with the fit's joints and bones inside, for a skin with a
    skeleton); a frame slider with play/pause."""

    def __init__(self, server, view, warn):
        self.server, self.view = server, view
        self.colors = scenes.level_colors(ERROR_STEPS)
        self.offset = scenes.side_by_side(view.examples[0])
        self.parts = {}
        frame_camera(server, np.concatenate([view.examples[0], view.examples[0] + self.offset]), view.up_axis)
        self.input = server.scene.add_mesh_simple("/input", view.examples[0], view.faces, color=INPUT_COLOR)
        server.gui.add_markdown(f"**Skin fit**: input (grey) and reconstruction, red at an error of "
                                f"{view.error_fraction:g} of the diagonal or more")
        self.layout = server.gui.add_dropdown("layout", ("side by side", "overlaid"), initial_value="side by side")
        if view.contacts is not None:
            server.gui.add_markdown("ground contacts: the planted patches' vertices of the input frame in cyan")
        if view.skeleton is not None:
            server.gui.add_markdown("skeleton: the fit's joints and bones in yellow, inside the see-through fit"
                                    + (", each named chain labelled at its first joint" if view.chains else ""))
        self.contact, self.point_size = None, 0.006 * float(np.ptp(view.examples[0], axis=0).max())
        self.info = server.gui.add_markdown("")
        self.timeline = Timeline(server, len(view.examples), view.fps, self.show, warn)
        self.layout.on_update(lambda _: self.timeline._show())
        self.show(0)

    def show(self, frame):
        view = self.view
        truth, fitted = view.examples[frame], np.asarray(view.fit(frame), dtype=np.float64)
        errors = scenes.vertex_errors(fitted, truth)
        levels = scenes.error_levels(errors, view.faces, view.error_scale, ERROR_STEPS)
        overlaid = self.layout.value == "overlaid"
        offset = np.zeros(3) if overlaid else self.offset
        with self.server.atomic():
            self.input.vertices = truth
            self.input.wireframe = overlaid
            present = set()
            for level, ids, local in scenes.split_by_key(view.faces, levels):
                present.add(level)
                self.parts[level] = self.server.scene.add_mesh_simple(
                    f"/fit/level_{level}", fitted[ids] + offset, local, color=tuple(int(c) for c in self.colors[level]),
                    opacity=None if view.skeleton is None else SEE_THROUGH)
            for level in [k for k in self.parts if k not in present]:
                self.parts.pop(level).remove()
            self._contacts(frame, truth)
            self._skeleton(frame, offset)
            self.info.content = (f"frame {frame}: RMS error {np.sqrt(np.mean(errors ** 2)):.4g}, "
                                 f"largest {errors.max():.4g}")

    def _skeleton(self, frame, offset):
        """The fit's joints (points) and bones (lines) at ``frame``, over the reconstruction."""
        if self.view.skeleton is None:
            return
        joints, bones = self.view.skeleton(frame)
        color = tuple(int(c) for c in scenes.SKELETON_COLOR)
        self.server.scene.add_point_cloud("/fit_joints", joints + offset, color, point_size=2 * self.point_size,
                                          point_shape="circle")
        if len(bones):
            self.server.scene.add_line_segments("/fit_bones", bones + offset, color, thickness=self.point_size / 2)
        for chain, bone in (self.view.chains or {}).items():  # each named chain at its first joint
            self.server.scene.add_label(f"/chains/{chain}", chain, position=joints[bone] + offset)

    def _contacts(self, frame, truth):
        """The planted contact vertices of input frame ``frame`` as cyan points on the input."""
        if self.view.contacts is None:
            return
        ids = scenes.planted_vertices(*self.view.contacts, frame)
        if ids.size == 0:
            if self.contact is not None:
                self.contact.remove()
                self.contact = None
            return
        self.contact = self.server.scene.add_point_cloud(
            "/input_contacts", truth[ids], tuple(int(c) for c in scenes.CONTACT_COLOR), point_size=self.point_size)

    def close(self):
        self.timeline.close()

