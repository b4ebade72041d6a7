"""The puppet's page: the mesh, a draggable handle per control point; every move is predicted by
the view's ``predict`` callable (``play``'s run-time path on a warm ``DevicePuppet``), on one
worker thread that always computes the latest controls (moves arriving during a prediction are
merged into the next one, so the page never lags behind a drag); the extrapolation indicator
(``scenes.extrapolation``), reset to a training frame, a drag session recorded. With a control
trajectory (``view --controls``, a :class:`~.records.TrajectoryView`), a timeline plays it through
the same path, one frame predicted at a time, a take's markers drawn beside their controls."""

import html
import threading
import time

import numpy as np

from .. import scenes
from .framing import MESH_COLOR, frame_camera
from .timeline import Timeline

#: A motion-capture take's markers (aligned into the puppet's space) and the line from each to its control.
TAKE_MARKER_COLOR, TAKE_LINE_COLOR = (225, 60, 215), (150, 90, 170)


class PuppetPage:
    """The puppet (see the module doc): handles, the extrapolation indicator, reset to a training
    frame, record a drag session; with a trajectory, a timeline playing it (a take's markers
    drawn beside their controls)."""

    def __init__(self, server, view, warn):
        self.server, self.view, self.trajectory, self.warn = server, view, view.trajectory, warn
        self.lock, self.wake, self.closed = threading.Lock(), threading.Event(), threading.Event()
        self.controls = np.array(view.controls if self.trajectory is None else self.trajectory.controls[0],
                                 dtype=np.float64)
        self.version, self.shown_version = 0, -1
        # the trajectory frame on the slider (its markers are drawn), and whether the controls are still that
        # frame's (no move since: the frame's indicator is the one computed for every frame up front)
        self.frame, self.on_frame = (None, False) if self.trajectory is None else (0, True)
        self.shown_controls, self.shown_frame = self.controls.copy(), None
        self.recording = None  # [(seconds, controls (n_c, 3))] while recording
        vertices = view.predict(self.controls) if self.trajectory is None or self.trajectory.vertices is None \
            else self.trajectory.vertices[0]
        takes = self.trajectory is not None and self.trajectory.markers is not None
        frame_camera(server, np.concatenate([vertices, self.controls]
                                             + ([self.trajectory.markers[0]] if takes else [])), view.up_axis)
        self.mesh = server.scene.add_mesh_simple("/puppet/mesh", vertices, view.faces, color=MESH_COLOR)
        self.handles, self.markers = [], []
        for i, position in enumerate(self.controls):
            handle = server.scene.add_transform_controls(
                f"/puppet/control_{i}", scale=0.12 * view.size, position=tuple(position), disable_rotations=True,
                depth_test=False, line_width=3.0)
            handle.on_update(self._on_move(i))
            self.handles.append(handle)
            self.markers.append(server.scene.add_icosphere(f"/puppet/control_{i}/marker", radius=0.012 * view.size,
                                                           color=(40, 170, 80)))
        self.take_markers = self.take_lines = None
        if takes:  # marker i beside control i, a line between them
            markers = self.trajectory.markers[0]
            self.take_markers = server.scene.add_point_cloud(
                "/puppet/take_markers", np.asarray(markers, dtype=np.float32), TAKE_MARKER_COLOR,
                point_size=0.02 * view.size, point_shape="circle", precision="float32")
            self.take_lines = server.scene.add_line_segments(
                "/puppet/take_lines", _marker_lines(markers, self.controls), TAKE_LINE_COLOR, thickness=1.5,
                thickness_units="screen")
        self._panel(server, view)
        self.worker = threading.Thread(target=self._work, daemon=True, name="skinsynth-view-puppet")
        self._publish(self.controls, self.version, self.frame, self.on_frame, vertices)
        self.worker.start()

    def _panel(self, server, view):
        server.gui.add_markdown("**Puppet**: drag a control point's arrows; the mesh is `play`'s.")
        self.indicator = server.gui.add_html("")
        self.timeline = None
        if self.trajectory is not None:
            trajectory = self.trajectory
            server.gui.add_markdown(
                f"**Trajectory** `{html.escape(trajectory.name)}`: play it, or pause and drag"
                + ("; the take's markers in magenta, a line to each one's control" if self.take_markers else ""))
            self.info = server.gui.add_markdown("")
            self.timeline = Timeline(server, len(trajectory.controls), trajectory.fps, self.show_frame, self.warn)
        frames = [str(int(f)) for f in view.training_frames]
        self.training = server.gui.add_dropdown("training frame", frames, initial_value=frames[0])
        server.gui.add_button("reset to the training frame").on_click(lambda _: self.reset(self.training.value))
        self.record_to = server.gui.add_text("record to", initial_value=view.record_path)
        self.record_button = server.gui.add_button("record")
        self.record_button.on_click(lambda _: self.toggle_record())
        self.status = server.gui.add_markdown("")

    def show_frame(self, frame):
        """Put the controls on the trajectory's frame ``frame`` (the timeline's ``show``); the
        worker predicts its mesh and moves the handles and markers there."""
        with self.lock:
            self.controls = np.array(self.trajectory.controls[frame], dtype=np.float64)
            self.frame, self.on_frame = frame, True
            self.version += 1
        self.wake.set()

    def _on_move(self, index):
        """The handle's callback: on the server's event loop (a coroutine), so that moves are
        taken in the order they came (viser runs plain callbacks on a thread pool, in any order)."""
        async def moved(event):
            self._moved(index, event.target.position)
        return moved

    def _moved(self, index, position):
        with self.lock:
            self.controls[index] = position
            self.on_frame = False
            self.version += 1
        self.wake.set()

    def reset(self, frame):
        """Move every handle to training frame ``frame``'s controls (a string, the dropdown's)."""
        row = int(np.flatnonzero(self.view.training_frames == int(frame))[0])
        with self.lock:
            self.controls = np.array(self.view.training_controls[row], dtype=np.float64)
            self.on_frame = False
            self.version += 1
            controls = self.controls.copy()
        with self.server.atomic():
            for handle, position in zip(self.handles, controls):
                handle.position = tuple(position)
        self.wake.set()

    def settled(self):
        """Whether the page shows the latest controls (no prediction pending)."""
        with self.lock:
            return self.shown_version == self.version

    def _work(self):
        while not self.closed.is_set():
            self.wake.wait(0.5)
            self.wake.clear()
            with self.lock:
                version, controls, frame, on_frame = self.version, self.controls.copy(), self.frame, self.on_frame
            if version != self.shown_version:
                try:
                    self._publish(controls, version, frame, on_frame)
                except Exception as error:  # shown on the page and on stderr; the page stays up
                    self.warn(f"prediction failed: {error}")
                    self.status.content = f"prediction failed: {html.escape(str(error))}"

    def _publish(self, controls, version, frame=None, on_frame=False, vertices=None):
        """Predict ``controls`` and send the mesh, the indicator and the markers' colour; on a
        trajectory's frame (``on_frame``: the controls are frame ``frame``'s) its indicator, computed
        up front, and the handles moved there; a take's markers of frame ``frame``, lines to the
        controls."""
        view, trajectory = self.view, self.trajectory
        if vertices is None and on_frame and trajectory.vertices is not None:
            vertices = trajectory.vertices[frame]  # as play plays it
        vertices = view.predict(controls) if vertices is None else vertices
        if on_frame:
            distance, nearest = float(trajectory.distances[frame]), int(trajectory.nearest[frame])
        else:
            distance, nearest = scenes.extrapolation(view.place(controls), view.training_in_place, view.unit)
        color = scenes.extrapolation_color(distance, view.scale)
        with self.lock:
            latest = version == self.version  # no move since: the handles can be put on these controls
        with self.server.atomic():
            self.mesh.vertices = vertices
            if on_frame and latest:
                for handle, position in zip(self.handles, controls):
                    handle.position = tuple(position)
            for marker in self.markers:
                marker.color = tuple(int(c) for c in color)
            self.indicator.content = _indicator(distance, int(view.training_frames[nearest]), view.scale, color)
            if frame is not None:
                self._trajectory_frame(frame, on_frame, controls)
        self.server.flush()
        with self.lock:
            self.shown_version, self.shown_controls = version, controls
            self.shown_frame = frame if on_frame else None
            if self.recording is not None:
                self.recording.append((time.perf_counter(), controls))

    def _trajectory_frame(self, frame, on_frame, controls):
        """The panel's frame line, and a take's markers of ``frame`` with a line to each control."""
        trajectory = self.trajectory
        seconds = trajectory.start_time + frame / trajectory.fps
        self.info.content = (f"trajectory frame {frame} of {len(trajectory.controls)} ({seconds:.3f} s)"
                             + ("" if on_frame else ", controls moved"))
        if self.take_markers is not None:
            markers = trajectory.markers[frame]
            self.take_markers.points = np.asarray(markers, dtype=np.float32)
            self.take_lines.points = _marker_lines(markers, controls)

    def toggle_record(self):
        """Start recording the poses the page shows, or stop and save them (``record to``) as a
        control trajectory at the puppet's fps (``scenes.resample_session``)."""
        with self.lock:
            states, self.recording = self.recording, (None if self.recording is not None else
                                                       [(time.perf_counter(), self.shown_controls.copy())])
        if states is None:
            self.record_button.label = "stop and save"
            self.status.content = "recording: every pose shown is kept, at the puppet's frame rate"
            return
        self.record_button.label = "record"
        times, controls = zip(*states)
        trajectory = scenes.resample_session(np.array(times), np.stack(controls), self.view.fps,
                                             end=time.perf_counter())
        path = self.record_to.value
        try:
            self.view.save(path, trajectory)
        except Exception as error:  # a bad path: said on the page and on stderr, the page stays up
            self.warn(f"the session was not saved: {error}")
            self.status.content = f"not saved: {html.escape(str(error))}"
            return
        self.status.content = (f"saved `{html.escape(path)}`: {len(trajectory)} frames at {self.view.fps:g} fps "
                               f"(`skinsynth play PUPPET -c {html.escape(path)} -o OUT`)")

    def close(self):
        if self.timeline is not None:
            self.timeline.close()
        self.closed.set()
        self.wake.set()
        self.worker.join(timeout=5.0)


def _marker_lines(markers, controls):
    """Segments (n_c, 2, 3) float32 from each marker (n_c, 3) to its control (n_c, 3)."""
    return np.stack([np.asarray(markers), np.asarray(controls)], axis=1).astype(np.float32)


def _indicator(distance, frame, scale, color):
    """The extrapolation indicator's HTML: a coloured dot, the distance and the nearest frame."""
    r, g, b = (int(c) for c in color)
    return (f'<div class="skinsynth-extrapolation" data-distance="{distance:.6g}" data-frame="{frame}" '
            f'style="font-size:0.85em;padding:0.2em 0">'
            f'<span style="display:inline-block;width:0.9em;height:0.9em;border-radius:50%;'
            f'background:rgb({r},{g},{b});vertical-align:middle;margin-right:0.4em"></span>'
            f'{distance:.4f} from training frame {frame} (largest rest side = 1; amber at {scale:.3g}, '
            f'red at {2 * scale:.3g})</div>')

