"""The page ``skinsynth view`` serves: a viser server (its web client ships built inside the viser
wheel, so the page loads nothing from the network), its scene, its panel and what each control
does. Interaction glue only: what the colours and distances mean is ``pipeline.view.scenes``,
reading and writing files is ``cli/view.py``'s (through ``formats``).

One page per kind of file, each from a plain description (the ``*View`` records below):

- :class:`PuppetPage`: the mesh, a draggable handle per control point; every move is predicted
  by the ``predict`` callable (``play``'s run-time path on a warm ``DevicePuppet``), on one
  worker thread that always computes the latest controls (moves arriving during a prediction
  are merged into the next one, so the page never lags behind a drag); with a control
  trajectory (``view --controls``, a :class:`TrajectoryView`), a timeline plays it through the
  same path, one frame predicted at a time, a take's markers drawn beside their controls;
- :class:`SkinPage`: examples and fit-skin's reconstruction, the reconstruction coloured by error;
- :class:`SynthesisPage`: one animation at a time, components coloured, seams marked;
- :class:`SequencePage`: any animated meshes.

Meshes are one colour each in viser, so a coloured mesh is sent as one part per colour
(``scenes.split_by_key``).
"""

import html
import socket
import threading
import time
import webbrowser
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Callable

import click
import numpy as np

from skinsynth.pipeline.errors import OptionError
from skinsynth.pipeline.view import scenes

MESH_COLOR = (175, 185, 205)
INPUT_COLOR = (150, 150, 150)
#: Error shades of a skin fit's reconstruction (``scenes.error_levels``): 8 steps grey to red.
ERROR_STEPS = 8
#: The opacity of a skin fit's reconstruction with a skeleton drawn inside it (its joints and bones show through).
SEE_THROUGH = 0.55
#: A synthesis component is drawn in the seam colour for this share of a second after a seam,
#: so that a seam stays visible while playing (at 24 fps: 6 frames).
SEAM_HOLD_SECONDS = 0.25
#: Slider marks for at most this many seams (a long animation's slider stays readable).
MAX_MARKS = 120
#: A motion-capture take's markers (aligned into the puppet's space) and the line from each to its control.
TAKE_MARKER_COLOR, TAKE_LINE_COLOR = (225, 60, 215), (150, 90, 170)


@dataclass
class TrajectoryView:
    """A control trajectory the puppet page plays (``view --controls``): controls (F, n_c, 3)
    world; fps; distances (F,) and nearest (F,) (rows of the training examples): each frame's
    extrapolation, ``scenes.extrapolation_distances`` computed once for every frame; name (the
    file, for the panel); a motion-capture take's markers (F, n_c, 3), aligned into the puppet's
    space, marker i on control i, with their labels (n_c,) and the take's start_time (seconds of
    frame 0); markers None for any other trajectory."""

    controls: np.ndarray
    fps: float
    distances: np.ndarray
    nearest: np.ndarray
    name: str = ""
    markers: np.ndarray = None
    labels: tuple = ()
    start_time: float = 0.0


@dataclass
class PuppetView:
    """A puppet: faces (T, 3); predict: world controls (n_c, 3) -> vertices (V, 3) float32;
    place: world controls (n_c, 3) -> in place (n_c, 3); controls (n_c, 3) the first pose;
    training_frames (n_p,) and training_controls (n_p, n_c, 3) world, training_in_place
    (n_p, n_c, 3); unit (evaluate's: the rest box's largest side); scale (the indicator's colour
    scale, in that unit); fps; up_axis "Y"/"Z"; record_path (the record button's default file);
    save(path, trajectory (F, n_c, 3)); size (the rest box's largest side, for the handles);
    trajectory: a :class:`TrajectoryView` the page plays (it starts on its frame 0), or None."""

    faces: np.ndarray
    predict: Callable
    place: Callable
    controls: np.ndarray
    training_frames: np.ndarray
    training_controls: np.ndarray
    training_in_place: np.ndarray
    unit: float
    scale: float
    fps: float
    up_axis: str
    record_path: str
    save: Callable
    size: float
    trajectory: TrajectoryView = None


@dataclass
class SkinView:
    """A skin fit: faces (T, 3), examples (F, V, 3), fit(frame) -> reconstruction (V, 3), the
    error shown full red (absolute, and as the fraction of the diagonal it was given), fps, up axis;
    contacts: a graph file's input ground contacts (/graph/contacts), None when it has none;
    skeleton: skeleton(frame) -> (joints (B, 3), bones (S, 2, 3)) of the fit (``scenes.skeleton_lines``),
    None for a skin without one."""

    faces: np.ndarray
    examples: np.ndarray
    fit: Callable
    error_scale: float
    error_fraction: float
    fps: float
    up_axis: str
    contacts: tuple = None  # a graph file's ground contacts: (vertices (N,), offsets (P + 1,), planted (F, P))
    skeleton: Callable = None


@dataclass
class SynthesisView:
    """A synthesis: faces (T, 3), rest (V, 3), count animations of frames frames each,
    load(a) -> (frame(m) -> vertices (V, 3), sources (C, M)) reading animation a alone,
    vertex_components (V,), components C, the first animation, fps, up axis; clips: the input's
    :class:`~skinsynth.pipeline.inputs.clips.Clips` when it holds several (seams by the clip-aware rule,
    input frames named CLIP:FRAME), None for one."""

    faces: np.ndarray
    rest: np.ndarray
    count: int
    frames: int
    load: Callable
    vertex_components: np.ndarray
    components: int
    animation: int
    fps: float
    up_axis: str
    clips: object = None


@dataclass
class SequenceView:
    """Animated meshes: parts [(name, vertices (F, V, 3), faces (T, 3))], fps, up axis."""

    parts: list
    fps: float
    up_axis: str


def serve(view, host, port, label, on_listening, open_browser=False):
    """Serve ``view`` at http://host:port until a signal stops it (Ctrl-C: the command's recorded
    signal, ``formats.atomic``); ``on_listening(url, port)`` once the page can be opened.
    OptionError when the port is taken or the host cannot be listened on."""
    from skinsynth.formats.atomic import stop_if_received

    with open_page(view, host, port, label) as (server, _):
        shown = "localhost" if host in ("0.0.0.0", "::") else (f"[{host}]" if ":" in host else host)
        url = f"http://{shown}:{server.get_port()}"
        on_listening(url, server.get_port())
        if open_browser:
            webbrowser.open(url)
        while True:
            time.sleep(0.2)  # a signal's handler raises here (cli.common.raise_interrupted)
            stop_if_received()


@contextmanager
def open_page(view, host="127.0.0.1", port=0, label="skinsynth view"):
    """A viser server at host:port (0: any free port) holding ``view``'s page: yields (server,
    page), both stopped on leaving. What :func:`serve` serves; the tests drive a page through it
    without a browser. OptionError when the port is taken or the host cannot be listened on."""
    check_port(host, port)
    server = _start_server(host, port, label)
    page = None
    try:
        if port and server.get_port() != port:
            raise OptionError(_in_use(host, port))
        server.gui.configure_theme(control_layout="floating", control_width="medium", show_logo=False,
                                   show_share_button=False)
        page = PAGES[type(view)](server, view)
        yield server, page
    finally:
        if page is not None:
            page.close()
        server.stop()


def check_port(host, port):
    """OptionError (one line) unless ``host`` can listen on ``port`` (0: any free port)."""
    try:
        family, kind, _, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    except socket.gaierror as error:
        raise OptionError(f"--host {host}: cannot listen there ({error.strerror})") from None
    with socket.socket(family, kind) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server itself binds
        try:
            probe.bind(address)
        except OSError as error:
            if error.errno in (98, 48, 10048):  # EADDRINUSE (Linux, macOS, Windows)
                raise OptionError(_in_use(host, port)) from None
            raise OptionError(f"--host {host} --port {port}: cannot listen there ({error.strerror})") from None


def _in_use(host, port):
    return f"port {port} on {host} is in use: give another with --port (--port 0 picks a free one)"


def _start_server(host, port, label):
    """A viser server whose own messages (a banner on stdout, "Server stopped") are silenced: the
    command's stdout is its report alone (--json)."""
    import rich
    import viser

    rich.reconfigure(quiet=True)
    return viser.ViserServer(host=host, port=port, label=label, verbose=False)


def _frame_camera(server, points, up_axis):
    """Point the first view at points (N, 3) from a three-quarter front, up_axis "Y" or "Z"."""
    lower, upper = points.min(axis=0), points.max(axis=0)
    centre, radius = (lower + upper) / 2, max(float(np.linalg.norm(upper - lower)) / 2, 1e-6)
    up = np.eye(3)[1 if up_axis == "Y" else 2]
    front = np.array([0.0, 0.0, 1.0]) if up_axis == "Y" else np.array([0.0, -1.0, 0.0])
    direction = 0.55 * np.array([1.0, 0.0, 0.0]) + 0.35 * up + front
    server.scene.set_up_direction("+y" if up_axis == "Y" else "+z")
    server.initial_camera.up = tuple(up)
    server.initial_camera.look_at = tuple(centre)
    server.initial_camera.position = tuple(centre + direction / np.linalg.norm(direction) * 2.2 * radius)


def _warn(message):
    click.echo(f"warning: {message}", err=True)


class Timeline:
    """A frame slider with play/pause at ``fps``; ``show(frame)`` runs for each frame shown,
    one at a time. Playing keeps to the clock: frames a slow ``show`` misses are skipped."""

    def __init__(self, server, frames, fps, show, marks=None):
        self.server, self.frames, self.fps, self.show = server, frames, fps, show
        self.playing, self.lock = False, threading.Lock()
        self.closed, self.wake = threading.Event(), threading.Event()
        self.slider = server.gui.add_slider("frame", min=0, max=max(frames - 1, 1), step=1, initial_value=0,
                                            marks=marks)
        self.button = server.gui.add_button("play", icon=None)
        server.gui.add_markdown(f"{frames} frames at {fps:g} fps")
        self.slider.on_update(lambda _: self._show())
        self.button.on_click(lambda _: self.toggle())
        self.thread = threading.Thread(target=self._loop, daemon=True, name="skinsynth-view-timeline")
        self.thread.start()

    def reset(self, frames, marks=None):
        """A new animation of ``frames`` frames (marks: slider marks), shown from its frame 0."""
        self.frames = frames
        self.slider.max = max(frames - 1, 1)
        self.slider._marks = None if not marks else tuple(_slider_marks(marks))
        if int(self.slider.value) == 0:
            self._show()
        else:
            self.slider.value = 0

    def toggle(self):
        self.playing = not self.playing
        self.button.label = "pause" if self.playing else "play"
        self.wake.set()

    def _show(self):
        """Show the slider's frame. Callbacks run on a thread pool, in any order: each reads the
        slider's value under the lock, so the last one shows the last value set."""
        with self.lock:
            self.show(min(max(int(self.slider.value), 0), self.frames - 1))
        self.server.flush()

    def _loop(self):
        due = time.perf_counter()
        while not self.closed.is_set():
            if not self.playing:
                self.wake.wait(0.2)
                self.wake.clear()
                due = time.perf_counter()
                continue
            due += 1.0 / self.fps
            late = time.perf_counter() - due
            if late < 0:
                self.closed.wait(-late)
                late = 0.0
            step = 1 + int(late * self.fps)  # behind the clock: skip what cannot be shown in time
            due += (step - 1) / self.fps
            try:
                self.slider.value = (int(self.slider.value) + step) % self.frames
            except Exception as error:  # a page error must not end the loop silently
                _warn(f"the timeline stopped: {error}")
                self.playing = False

    def close(self):
        self.closed.set()
        self.wake.set()


def _slider_marks(frames):
    from viser._messages import GuiSliderMark

    return [GuiSliderMark(value=float(f), label=None) for f in frames]


class PuppetPage:
    """The puppet (see the module doc): handles, the extrapolation indicator, reset to a training
    frame, record a drag session; with a trajectory, a timeline playing it (a take's markers
    drawn beside their controls)."""

    def __init__(self, server, view):
        self.server, self.view, self.trajectory = server, view, view.trajectory
        self.lock, self.wake, self.closed = threading.Lock(), threading.Event(), threading.Event()
        self.controls = np.array(view.controls if self.trajectory is None else self.trajectory.controls[0],
                                 dtype=np.float64)
        self.version, self.shown_version = 0, -1
        # the trajectory frame on the slider (its markers are drawn), and whether the controls are still that
        # frame's (no move since: the frame's indicator is the one computed for every frame up front)
        self.frame, self.on_frame = (None, False) if self.trajectory is None else (0, True)
        self.shown_controls, self.shown_frame = self.controls.copy(), None
        self.recording = None  # [(seconds, controls (n_c, 3))] while recording
        vertices = view.predict(self.controls)
        takes = self.trajectory is not None and self.trajectory.markers is not None
        _frame_camera(server, np.concatenate([vertices, self.controls]
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
            self.timeline = Timeline(server, len(trajectory.controls), trajectory.fps, self.show_frame)
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
                    _warn(f"prediction failed: {error}")
                    self.status.content = f"prediction failed: {html.escape(str(error))}"

    def _publish(self, controls, version, frame=None, on_frame=False, vertices=None):
        """Predict ``controls`` and send the mesh, the indicator and the markers' colour; on a
        trajectory's frame (``on_frame``: the controls are frame ``frame``'s) its indicator, computed
        up front, and the handles moved there; a take's markers of frame ``frame``, lines to the
        controls."""
        view, trajectory = self.view, self.trajectory
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
            _warn(f"the session was not saved: {error}")
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


class SkinPage:
    """Examples and reconstruction, side by side or overlaid, the reconstruction coloured by
    each face's error (see-through, with the fit's joints and bones inside, for a skin with a
    skeleton); a frame slider with play/pause."""

    def __init__(self, server, view):
        self.server, self.view = server, view
        self.colors = scenes.level_colors(ERROR_STEPS)
        self.offset = scenes.side_by_side(view.examples[0])
        self.parts = {}
        _frame_camera(server, np.concatenate([view.examples[0], view.examples[0] + self.offset]), view.up_axis)
        self.input = server.scene.add_mesh_simple("/input", view.examples[0], view.faces, color=INPUT_COLOR)
        server.gui.add_markdown(f"**Skin fit**: input (grey) and reconstruction, red at an error of "
                                f"{view.error_fraction:g} of the diagonal or more")
        self.layout = server.gui.add_dropdown("layout", ("side by side", "overlaid"), initial_value="side by side")
        if view.contacts is not None:
            server.gui.add_markdown("ground contacts: the planted patches' vertices of the input frame in cyan")
        if view.skeleton is not None:
            server.gui.add_markdown("skeleton: the fit's joints and bones in yellow, inside the see-through fit")
        self.contact, self.point_size = None, 0.006 * float(np.ptp(view.examples[0], axis=0).max())
        self.info = server.gui.add_markdown("")
        self.timeline = Timeline(server, len(view.examples), view.fps, self.show)
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


class SynthesisPage:
    """One animation at a time (picked by number), each component its colour, red for a quarter
    second after its seams, seams marked on the frame slider."""

    def __init__(self, server, view):
        self.server, self.view = server, view
        self.palette = scenes.component_colors(view.components)
        self.hold = max(1, int(round(SEAM_HOLD_SECONDS * view.fps)))
        keys = scenes.face_components(view.faces, view.vertex_components)
        self.parts = scenes.split_by_key(view.faces, keys)
        _frame_camera(server, view.rest, view.up_axis)
        self.nodes = [server.scene.add_mesh_simple(f"/synthesis/component_{key:03d}", view.rest[ids], local,
                                                   color=tuple(int(c) for c in self.palette[key]))
                      for key, ids, local in self.parts]
        server.gui.add_markdown(f"**Synthesis**: {view.count} animation(s); each component its colour, "
                                "red at its seams")
        self.picker = server.gui.add_number("animation", initial_value=view.animation, min=0, max=view.count - 1,
                                            step=1)
        self.info = server.gui.add_markdown("")
        self.frame_of, self.seams, self.sources = self._load(view.animation)
        self.timeline = Timeline(server, view.frames, view.fps, self.show, marks=self._marks())
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


class SequencePage:
    """Animated meshes (a sequence, play's characters) with a frame slider and play/pause."""

    def __init__(self, server, view):
        self.server, self.view = server, view
        _frame_camera(server, np.concatenate([v[0] for _, v, _ in view.parts]), view.up_axis)
        self.nodes = [server.scene.add_mesh_simple(f"/sequence/part_{n:03d}", vertices[0], faces, color=MESH_COLOR)
                      for n, (_, vertices, faces) in enumerate(view.parts)]
        names = [name for name, _, _ in view.parts if name]
        server.gui.add_markdown("**Sequence**" + (f": {', '.join(names[:8])}" if names else ""))
        frames = min(len(vertices) for _, vertices, _ in view.parts)
        self.timeline = Timeline(server, frames, view.fps, self.show)

    def show(self, frame):
        with self.server.atomic():
            for node, (_, vertices, _) in zip(self.nodes, self.view.parts):
                node.vertices = vertices[frame]

    def close(self):
        self.timeline.close()


PAGES = {PuppetView: PuppetPage, SkinView: SkinPage, SynthesisView: SynthesisPage, SequenceView: SequencePage}
