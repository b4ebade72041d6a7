"""skinsynth view in a real browser: the command serves the page as a subprocess (--port 0 --json
--no-open, the URL read from its stdout), headless Chromium (Debian's ``chromium``, driven by
Playwright) opens it, and what the page holds is read from the page's side: every websocket frame
the page receives is decoded as viser's client decodes it (zstd-compressed msgpack, then the raw
array buffers) and replayed into the page's scene (nodes and their props) and panel.

Moving a control: the page's own websocket (opened by viser's client in a Web Worker; an init
script wraps ``Worker`` so that the worker keeps its sockets in ``self.__sockets``) sends the
messages the handle's gizmo sends when dragged (drag start, TransformControlsUpdateMessage with
the handle's new position, drag end), so the position is known exactly. A real mouse drag of the
gizmo is exercised too (its position is read back from the message the page sent).
"""

import json
import os
import pathlib
import queue
import shutil
import signal
import struct
import subprocess
import sys
import threading
import time
from contextlib import contextmanager

import h5py
import msgspec
import numpy as np
import pytest
import zstandard

from cli_helpers import assert_ok, assert_user_error, cli

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
LAUNCH_ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
SKINSYNTH = shutil.which("skinsynth", path=os.path.dirname(sys.executable)) or "skinsynth"
WAIT = 60.0  # seconds any one thing on the page may take before the test fails
START = 300.0  # seconds the command may take to listen (a puppet's warp kernels compile on a cold cache)

#: Runs before the page's scripts: every Web Worker starts by wrapping WebSocket, keeping its sockets.
WORKER_SOCKETS = (pathlib.Path(__file__).resolve().parents[1] / "contracts" / "js" / "worker_sockets.js").read_text()


def _browser_problem():
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "Playwright for Python is not installed (pip install -e '.[test]')"
    if CHROMIUM is None:
        return ("no chromium on PATH: install the Debian package (apt-get install chromium; make test does it "
                "when run as root with apt-get)")
    return None


pytestmark = pytest.mark.skipif(_browser_problem() is not None, reason=str(_browser_problem()))


@pytest.fixture(scope="module")
def browser():
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        yield chromium
        chromium.close()


@pytest.fixture(scope="module")
def files(stage_files, tmp_path_factory):
    stages = stage_files(frames=24, bones=4, iterations=8, cycles=2, controls=("--count", 6), puppet=(),
                         graph=("--min-segment", 4))
    root = stages.copy_to(tmp_path_factory.mktemp("view"))
    assert_ok(cli("synthesize", root / "graph.h5", "-o", root / "bones.h5", "-n", 3, "-m", 30, "--device", "cpu",
                  "-q"))
    return root


# -- the command as a server ----------------------------------------------------------------------

@contextmanager
def serving(path, *options, cwd=None):
    """Run ``skinsynth view PATH --no-open --json --port 0 OPTIONS``; yields (its JSON summary, the
    process). Always stopped (SIGINT, then killed if it does not end)."""
    process = subprocess.Popen([SKINSYNTH, "view", str(path), "--no-open", "--json", "--port", "0", *options],
                               cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines = queue.Queue()
    threading.Thread(target=lambda: lines.put(process.stdout.readline()), daemon=True).start()
    try:
        try:
            line = lines.get(timeout=START)
        except queue.Empty:
            raise AssertionError(f"skinsynth view printed no URL within {START} s") from None
        assert line, f"skinsynth view ended (exit {process.wait(WAIT)}): {process.stderr.read()}"
        yield json.loads(line), process
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
            try:
                process.wait(15)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        process.stdout.close()
        process.stderr.close()


# -- the page, read from its side -----------------------------------------------------------------

def decode_frame(payload):
    """A websocket frame from viser's server: [inner size, compressed size (uint64 LE), zstd msgpack,
    8-byte aligned raw buffers]; returns its messages with every array placeholder resolved."""
    inner_size, compressed = struct.unpack_from("<QQ", payload, 0)
    inner = msgspec.msgpack.decode(zstandard.ZstdDecompressor().decompress(payload[16:16 + compressed],
                                                                           max_output_size=inner_size))
    buffers, offset = [], 16 + compressed
    for length in inner["binaryBufferLengths"]:
        offset += (8 - offset % 8) % 8
        buffers.append(bytes(payload[offset:offset + length]))
        offset += length

    def resolve(value):
        if isinstance(value, dict) and "__binary_index" in value and "dtype" in value:
            return np.frombuffer(buffers[value["__binary_index"]], dtype=value["dtype"])
        if isinstance(value, dict):
            return {k: resolve(v) for k, v in value.items()}
        if isinstance(value, list):
            return [resolve(v) for v in value]
        return value

    return [resolve(m) for m in inner["messages"]]


class Page:
    """A browser tab on the page: the frames it received, replayed into its scene and panel."""

    def __init__(self, browser, url, size=(1000, 700)):
        self.page = browser.new_page(viewport={"width": size[0], "height": size[1]})
        self.page.add_init_script(WORKER_SOCKETS)
        self.frames, self.sent, self.workers = [], [], []
        self.external = []
        self.page.on("request", lambda r: None if r.url.startswith(url) or r.url.startswith(("blob:", "data:"))
                     else self.external.append(r.url))
        self.page.on("worker", lambda worker: self.workers.append(worker))
        self.page.on("websocket", self._socket)
        self.page.goto(url)
        self.wait(lambda: self.socket_ready(), "the page's websocket")
        # the server takes a client's messages once its camera is known: the first one the page sends
        self.wait(lambda: any(msgspec.msgpack.decode(d).get("type") == "ViewerCameraMessage" for d in self.sent),
                  "the page's camera")

    def _socket(self, ws):
        ws.on("framereceived", lambda data: self.frames.append(data) if isinstance(data, bytes) else None)
        ws.on("framesent", lambda data: self.sent.append(data) if isinstance(data, bytes) else None)

    def socket_ready(self):
        return any(w.evaluate("self.__sockets ? self.__sockets.filter(s => s.readyState === 1).length : 0")
                   for w in self.workers)

    def wait(self, condition, what, timeout=WAIT):
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                raise AssertionError(f"waited {timeout} s for {what}")
            self.page.wait_for_timeout(25)

    def messages(self, start=0):
        return [m for frame in list(self.frames)[start:] for m in decode_frame(frame)]

    def scene(self, start=0):
        """{node name: props} after replaying the frames received (from frame ``start``)."""
        nodes = {}
        for m in self.messages(start):
            kind, name = m["type"], m.get("name")
            if kind.endswith("Message") and "props" in m and name is not None:
                nodes[name] = dict(m["props"], visible=True)
            elif kind == "SceneNodeUpdateMessage" and name in nodes:
                nodes[name].update(m["updates"])
            elif kind == "SetSceneNodeVisibilityMessage" and name in nodes:
                nodes[name]["visible"] = m["visible"]
            elif kind == "RemoveSceneNodeMessage":
                for other in [n for n in nodes if n == name or n.startswith(name + "/")]:
                    del nodes[other]
        return nodes

    def panel(self):
        """{label or uuid: props} of the GUI after replaying every frame."""
        by_uuid = {}
        for m in self.messages():
            if m["type"].startswith("Gui") and "props" in m and "uuid" in m:
                by_uuid[m["uuid"]] = dict(m["props"], uuid=m["uuid"])
            elif m["type"] == "GuiUpdateMessage" and m["uuid"] in by_uuid:
                by_uuid[m["uuid"]].update(m["updates"])
        return by_uuid

    def gui(self, label):
        found = [p for p in self.panel().values() if p.get("label") == label]
        assert found, f"no {label!r} in the panel"
        return found[-1]

    def texts(self):
        """The text of every HTML and markdown element of the panel."""
        return [str(p.get("content", p.get("_markdown", ""))) for p in self.panel().values()]

    def html(self, class_name):
        return [text for text in self.texts() if class_name in text][-1]

    def vertices(self, name, scene=None):
        return np.asarray((scene or self.scene())[name]["vertices"], dtype=np.float64).reshape(-1, 3)

    def send(self, message):
        """Send ``message`` (a dict, msgpack-encoded as viser's client does) through the page's socket."""
        data = list(msgspec.msgpack.encode(message))
        for worker in self.workers:
            if worker.evaluate("bytes => { const s = (self.__sockets || []).find(s => s.readyState === 1);"
                               " if (!s) return false; s.send(new Uint8Array(bytes)); return true; }", data):
                return
        raise AssertionError("no open websocket in the page's workers")

    def drag(self, name, position):
        """What the handle ``name`` sends when dragged to ``position`` (3,)."""
        self.send({"type": "TransformControlsDragStartMessage", "name": name, "owner": ""})
        self.send({"type": "TransformControlsUpdateMessage", "name": name, "wxyz": [1.0, 0.0, 0.0, 0.0],
                   "position": [float(p) for p in position], "owner": ""})
        self.send({"type": "TransformControlsDragEndMessage", "name": name, "owner": ""})

    def updates(self, name, start=0):
        """The vertices (V, 3) of every mesh ``name`` received from frame ``start`` on, in order."""
        found = []
        for m in self.messages(start):
            props = m.get("updates", m.get("props", {})) if m.get("name") == name else {}
            if "vertices" in props:
                found.append(np.asarray(props["vertices"], dtype=np.float64).reshape(-1, 3))
        return found

    def next_mesh(self, name, start):
        """The vertices (V, 3) of the last update of mesh ``name`` in the frames from ``start`` on, once
        one came."""
        def updated():
            return any(m.get("name") == name and "vertices" in m.get("updates", m.get("props", {}))
                       for m in self.messages(start))
        self.wait(updated, f"a new {name} mesh")
        return self.vertices(name)

    def press(self, name):
        """Click the panel's button ``name``: a click event dispatched to the button itself, once it
        is visible and enabled. (A mouse click first waits for the button to hold still over two
        animation frames: the page draws every frame, which under software GL (swiftshader) makes
        that wait cost seconds; one forced past it can land while the panel still moves.)"""
        button = self.page.get_by_role("button", name=name, exact=True)
        button.wait_for(state="visible", timeout=WAIT * 1000)
        self.wait(button.is_enabled, f"the {name!r} button enabled")
        button.dispatch_event("click")

    def close(self):
        self.page.close()


def non_blank(png, box=None):
    """Share of a screenshot's pixels that differ from its most common colour (the background);
    ``box``: only those in this rectangle ({x, y, width, height} in CSS pixels, as Playwright's
    bounding_box gives it; the screenshot's scale is one device pixel to one CSS pixel)."""
    import io

    from PIL import Image

    image = Image.open(io.BytesIO(png)).convert("RGB")
    if box is not None:
        image = image.crop((round(box["x"]), round(box["y"]), round(box["x"] + box["width"]),
                            round(box["y"] + box["height"])))
    pixels = np.asarray(image).reshape(-1, 3).astype(np.int64)
    colors = (pixels[:, 0] << 16) | (pixels[:, 1] << 8) | pixels[:, 2]  # one integer a colour
    return float(np.mean(colors != np.argmax(np.bincount(colors))))


def played(files, tmp_path, puppet, controls, name="t", *extra):
    """``skinsynth play`` of a control trajectory (F, n_c, 3): its vertices (F, V, 3)."""
    np.save(tmp_path / f"{name}.npy", np.asarray(controls, dtype=np.float64))
    assert_ok(cli("play", puppet, "-c", tmp_path / f"{name}.npy", "-o", tmp_path / f"{name}.h5", "--device", "cpu",
                  "-q", *extra))
    return h5py.File(tmp_path / f"{name}.h5")["vertices"][()].reshape(len(controls), -1, 3)


def puppet_facts(path):
    from skinsynth.formats.puppet_file import read_puppet
    from skinsynth.pipeline.mesh.geometry import bounding_box_diagonal

    record, _, skin = read_puppet(path)
    controls = skin.examples[record.train_frames][:, record.control_indices]
    return record, skin, controls, bounding_box_diagonal(skin.rest_vertices)


# -- the puppet ------------------------------------------------------------------------------------

def test_a_moved_control_gives_the_mesh_play_writes(files, browser, tmp_path):
    record, skin, training, diagonal = puppet_facts(files / "puppet.h5")
    with serving(files / "puppet.h5", "--device", "cpu") as (summary, _):
        assert summary["kind"] == "puppet" and summary["url"].startswith("http://127.0.0.1:")
        page = Page(browser, summary["url"])
        try:
            page.wait(lambda: "/puppet/mesh" in page.scene(), "the puppet's mesh")
            first = page.vertices("/puppet/mesh")
            assert np.abs(first - played(files, tmp_path, files / "puppet.h5", training[:1], "first")[0]).max() \
                <= 1e-5 * diagonal
            controls = training[0].copy()
            controls[2] += np.array([0.08, -0.05, 0.04]) * diagonal
            start = len(page.frames)
            page.drag("/puppet/control_2", controls[2])
            shown = page.next_mesh("/puppet/mesh", start)
            expected = played(files, tmp_path, files / "puppet.h5", controls[None])[0]
            assert np.abs(shown - first).max() > 1e-3 * diagonal  # the move moved the mesh
            assert np.abs(shown - expected).max() <= 1e-5 * diagonal
            page.page.wait_for_timeout(500)  # let the canvas draw it
            shot = page.page.screenshot()  # one capture (each costs seconds under software GL)
            assert non_blank(shot, page.page.locator("canvas").first.bounding_box()) > 0.02
            assert non_blank(shot) > 0.05
            assert page.external == []  # nothing from the network: the client is served by the command
        finally:
            page.close()


def test_a_real_mouse_drag_moves_the_mesh_to_plays(files, browser, tmp_path):
    """The gizmo dragged with the mouse: the position the page sent (decoded from its frames) played
    by play gives the mesh the page then holds."""
    record, skin, training, diagonal = puppet_facts(files / "puppet.h5")
    with serving(files / "puppet.h5", "--device", "cpu") as (summary, _):
        page = Page(browser, summary["url"], size=(900, 700))
        try:
            page.wait(lambda: "/puppet/mesh" in page.scene(), "the puppet's mesh")
            page.page.wait_for_timeout(1500)  # the first frames drawn
            moved = _drag_some_gizmo(page, training[0])
            if moved is None:
                pytest.skip("no gizmo arrow under the probed screen points at this camera (drag by message is "
                            "tested above)")
            name, position = moved
            index = int(name.rsplit("_", 1)[1])
            controls = training[0].copy()
            controls[index] = position
            page.page.wait_for_timeout(500)
            expected = played(files, tmp_path, files / "puppet.h5", controls[None])[0]
            assert np.abs(page.vertices("/puppet/mesh") - expected).max() <= 1e-5 * diagonal
        finally:
            page.close()


def _on_canvas(page, positions):
    """Where the scene points positions (n, 3) are on the canvas, as fractions (n, 2) of its width
    and height: projected by the last camera the page sent (viser's ViewerCameraMessage: the
    camera's pose in the world, OpenCV axes, +Z forward; its vertical field of view in radians)."""
    camera = [m for m in map(msgspec.msgpack.decode, page.sent) if m.get("type") == "ViewerCameraMessage"][-1]
    w, x, y, z = camera["wxyz"]
    rotation = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    seen = (np.asarray(positions, dtype=np.float64) - camera["position"]) @ rotation  # in the camera's axes
    focal = 0.5 / np.tan(0.5 * camera["fov"])  # in canvas heights
    aspect = camera["image_width"] / camera["image_height"]
    return np.stack([0.5 + focal * seen[:, 0] / seen[:, 2] / aspect, 0.5 + focal * seen[:, 1] / seen[:, 2]], axis=1)


def _drag_some_gizmo(page, handles):
    """Press the mouse at points around the handles' screen positions (handles (n, 3)), nearest
    first, until a drag makes the page send a TransformControlsUpdateMessage; (handle name, its
    last position sent) or None."""
    canvas = page.page.locator("canvas").first.bounding_box()
    grid = np.array([(x, y) for y in np.linspace(0.3, 0.7, 9) for x in np.linspace(0.3, 0.7, 9)])
    near = np.linalg.norm(grid[:, None] - _on_canvas(page, handles)[None], axis=2).min(axis=1)
    for order, (fx, fy) in enumerate(grid[np.argsort(near, kind="stable")]):
        x, y = canvas["x"] + fx * canvas["width"], canvas["y"] + fy * canvas["height"]
        before = len(page.sent)
        page.page.mouse.move(x, y)
        page.page.mouse.down()
        for step in range(1, 6):
            page.page.mouse.move(x + 12 * step, y - 6 * step)
        page.page.mouse.up()
        page.page.wait_for_timeout(150)
        updates = [msgspec.msgpack.decode(d) for d in page.sent[before:]]
        updates = [u for u in updates if u.get("type") == "TransformControlsUpdateMessage"]
        if updates:
            return updates[-1]["name"], np.array(updates[-1]["position"])
    return None


def test_extrapolation_indicator_and_reset_to_a_training_frame(files, browser, tmp_path):
    record, skin, training, diagonal = puppet_facts(files / "puppet.h5")
    with serving(files / "puppet.h5", "--device", "cpu") as (summary, _):
        page = Page(browser, summary["url"])
        try:
            page.wait(lambda: any("skinsynth-extrapolation" in text for text in page.texts()), "the indicator")
            assert 'data-distance="0"' in page.html("skinsynth-extrapolation")  # at a training example
            controls = training[0].copy()
            controls[0] += np.array([1.5, 0.0, 0.0]) * diagonal  # far out: a pose never trained on
            start = len(page.frames)
            page.drag("/puppet/control_0", controls[0])
            page.next_mesh("/puppet/mesh", start)
            from skinsynth.pipeline.view.scenes import OUTSIDE

            assert page.scene()["/puppet/control_0/marker"]["color"] == list(OUTSIDE.astype(int))
            distance = float(page.html("skinsynth-extrapolation").split('data-distance="')[1].split('"')[0])
            assert distance > 2 * summary["extrapolation_scale"]
            start = len(page.frames)
            page.press("reset to the training frame")
            shown = page.next_mesh("/puppet/mesh", start)
            page.wait(lambda: 'data-distance="0"' in page.html("skinsynth-extrapolation"), "the indicator at 0")
            expected = played(files, tmp_path, files / "puppet.h5", training[:1])[0]
            assert np.abs(page.vertices("/puppet/mesh") - expected).max() <= 1e-5 * diagonal
            assert shown is not None
        finally:
            page.close()


def test_a_recorded_session_played_by_play_is_what_the_page_showed(files, browser, tmp_path):
    record, skin, training, diagonal = puppet_facts(files / "puppet.h5")
    session = tmp_path / "session.csv"
    with serving(files / "puppet.h5", "--device", "cpu", "--record", session) as (summary, _):
        page = Page(browser, summary["url"])
        try:
            page.wait(lambda: "/puppet/mesh" in page.scene(), "the puppet's mesh")
            shown = [page.vertices("/puppet/mesh")]
            page.press("record")
            page.wait(lambda: any(p.get("label") == "stop and save" for p in page.panel().values()),
                      "the record button")
            rng = np.random.default_rng(0)
            for step in range(5):
                start = len(page.frames)
                i = int(rng.integers(len(training[0])))
                page.drag(f"/puppet/control_{i}", training[0][i] + rng.normal(scale=0.05 * diagonal, size=3))
                shown.append(page.next_mesh("/puppet/mesh", start))
                page.page.wait_for_timeout(150)  # each pose stays on the page for several frames at 24 fps
            page.press("stop and save")
            page.wait(session.exists, "the saved session")
        finally:
            page.close()
    baked = tmp_path / "session.h5"
    assert_ok(cli("play", files / "puppet.h5", "-c", session, "-o", baked, "--device", "cpu", "-q"))
    frames = h5py.File(baked)["vertices"][()]
    assert len(frames) >= 2 * len(shown)  # at 24 fps, each pose held ≥ 150 ms
    # every frame played is a mesh the page showed, in the order shown, and every one shown is played
    matches = [int(np.argmin([np.abs(f - s).max() for s in shown])) for f in frames]
    assert all(np.abs(f - shown[m]).max() <= 1e-5 * diagonal for f, m in zip(frames, matches))
    assert matches == sorted(matches) and set(matches) == set(range(len(shown)))


# -- a trajectory, a motion-capture take ------------------------------------------------------------

def until(condition, what, timeout=WAIT):
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"waited {timeout} s for {what}")
        time.sleep(0.01)


def shown_distance(content):
    return float(content.split('data-distance="')[1].split('"')[0])


def test_a_trajectory_plays_play_s_frames_and_their_indicator(files, tmp_path):
    """view --controls .npy, the page driven without a browser (``open_page``): each frame the
    slider shows is play's of that frame (frame 7, far beyond the examples, on the skeleton found
    for the free skin, as play poses it; --no-ik, the kernel CCA's prediction as play --no-ik),
    the handles on its controls, its indicator the one ``extrapolation_distances`` gives every frame."""
    from skinsynth.cli.view import puppet_view
    from skinsynth.pipeline.view import open_page
    from skinsynth.pipeline.mesh.geometry import largest_side
    from skinsynth.pipeline.puppet import host_inputs, puppet_from_record
    from skinsynth.pipeline.view import extrapolation_color, extrapolation_distances

    record, skin, training, diagonal = puppet_facts(files / "puppet.h5")
    rng = np.random.default_rng(3)
    trajectory = training[np.arange(12) % len(training)] + rng.normal(scale=0.04 * diagonal,
                                                                      size=(12, *training.shape[1:]))
    trajectory[7] += 0.5 * diagonal * (rng.random(trajectory[7].shape) - 0.5)  # one frame far off the training poses
    expected = played(files, tmp_path, files / "puppet.h5", trajectory, "trajectory")  # writes trajectory.npy
    extrapolated = played(files, tmp_path, files / "puppet.h5", trajectory, "no_ik", "--no-ik")
    assert np.abs(expected[7] - extrapolated[7]).max() > 0.01 * diagonal  # frame 7 is on the skeleton
    alone, _ = puppet_view(files / "puppet.h5", device="cpu", controls_path=tmp_path / "trajectory.npy", ik=False)
    assert np.abs(alone.trajectory.vertices - extrapolated).max() <= 1e-5 * diagonal
    view, details = puppet_view(files / "puppet.h5", device="cpu", controls_path=tmp_path / "trajectory.npy")
    assert details["trajectory"]["frames"] == 12 and details["trajectory"]["fps"] == skin.fps
    puppet = puppet_from_record(record)
    distances, nearest = extrapolation_distances(host_inputs(puppet, trajectory)[1], host_inputs(puppet, training)[1],
                                                 largest_side(skin.rest_vertices))
    assert np.array_equal(view.trajectory.distances, distances) and np.array_equal(view.trajectory.nearest, nearest)
    assert distances[7] > 2 * view.scale > distances.min()  # the indicator tells frames apart
    warned = []  # the page's warnings (a failed prediction, the timeline stopped): none
    with open_page(view, warn=warned.append) as (_, page):
        for frame in (0, 7, 11, 3):
            if frame:
                page.timeline.slider.value = frame  # as the page's slider does
            until(lambda: page.settled() and page.shown_frame == frame, f"frame {frame} shown")
            assert np.abs(page.mesh.vertices - expected[frame]).max() <= 1e-5 * diagonal
            assert np.allclose([h.position for h in page.handles], trajectory[frame], rtol=0, atol=1e-12)
            assert shown_distance(page.indicator.content) == float(f"{distances[frame]:.6g}")
            color = extrapolation_color(distances[frame], view.scale)
            assert all(tuple(m.color) == tuple(int(c) for c in color) for m in page.markers)
            assert page.info.content.startswith(f"trajectory frame {frame} of 12")
        page.timeline.toggle()  # play: frames go by, each play's prediction
        until(lambda: page.shown_frame not in (None, 3), "the timeline playing on")
        page.timeline.toggle()
        until(lambda: page.settled(), "the paused frame")
        frame = int(page.timeline.slider.value)
        assert page.shown_frame == frame and np.abs(page.mesh.vertices - expected[frame]).max() <= 1e-5 * diagonal
    assert warned == []


def test_a_take_plays_with_its_markers_beside_their_controls(files, browser, tmp_path):
    """view --controls take.c3d (a marker layout on the puppet's controls), in the browser: the
    --json summary holds the take's, each frame's mesh is play's of the take, one marker point per
    control at the aligned markers of the frame and a line from each to its control; a drag on a
    paused frame moves off the take (the indicator computed for the new controls)."""
    from c3d_writing import write_c3d
    from skinsynth.cli.marker_take import take_controls
    from skinsynth.pipeline.puppet import puppet_from_record

    record, skin, training, diagonal = puppet_facts(files / "puppet.h5")
    controls = np.asarray(record.control_indices)
    labels = [f"M{i}" for i in range(len(controls))]
    layout = tmp_path / "layout.json"
    layout.write_text(json.dumps({label: int(v) for label, v in zip(labels, controls)}))
    # the examples' control vertices as a take: Z up, millimetres, twice the frame rate
    frames = skin.examples[:, controls]
    dense = np.concatenate([np.stack([a, (a + b) / 2]) for a, b in zip(frames[:-1], frames[1:])] + [frames[-1:]])
    points = dense[..., [0, 2, 1]] * np.array([1.0, -1.0, 1.0]) * 1000.0
    take = tmp_path / "take.c3d"
    write_c3d(take, labels, points, 2 * skin.fps, units="mm")
    from skinsynth.cli.marker_take import TAKE_DEFAULTS
    from skinsynth.cli.view import view

    # what view's options give take_controls: their defaults, the layout given
    options = {**{p.name: p.default for p in view.params if p.name in TAKE_DEFAULTS}, "marker_layout": str(layout)}
    expected_take = take_controls(take, puppet_from_record(record), record, skin, options, files / "puppet.h5")
    baked = tmp_path / "take.h5"
    assert_ok(cli("play", files / "puppet.h5", "-c", take, "--markers", layout, "-o", baked, "--device", "cpu",
                  "-q"))
    expected = h5py.File(baked)["vertices"][()].reshape(len(expected_take.controls), -1, 3)
    with serving(files / "puppet.h5", "--device", "cpu", "-c", take, "--markers", layout) as (summary, _):
        assert summary["trajectory"]["frames"] == len(expected_take.controls) == len(expected)
        assert summary["trajectory"]["fps"] == expected_take.fps
        assert summary["trajectory"]["take"] == json.loads(json.dumps(expected_take.summary))
        page = Page(browser, summary["url"])
        try:
            page.wait(lambda: "/puppet/take_markers" in page.scene(), "the take's markers")
            for frame in (0, len(expected) - 3):
                if frame:
                    start = len(page.frames)
                    page.send({"type": "GuiUpdateMessage", "uuid": page.gui("frame")["uuid"],
                               "updates": {"value": frame}})
                    page.next_mesh("/puppet/mesh", start)
                scene = page.scene()
                assert np.abs(page.vertices("/puppet/mesh", scene) - expected[frame]).max() <= 1e-5 * diagonal
                markers = np.asarray(scene["/puppet/take_markers"]["points"], dtype=np.float64).reshape(-1, 3)
                assert markers.shape == (len(controls), 3)  # one marker per control
                assert np.abs(markers - expected_take.markers[frame]).max() <= 1e-6 * diagonal
                lines = np.asarray(scene["/puppet/take_lines"]["points"], dtype=np.float64).reshape(-1, 2, 3)
                assert np.abs(lines[:, 0] - expected_take.markers[frame]).max() <= 1e-6 * diagonal
                assert np.abs(lines[:, 1] - expected_take.controls[frame]).max() <= 1e-6 * diagonal
                assert any(f"trajectory frame {frame} of {len(expected)}" in text for text in page.texts())
            moved = expected_take.controls[frame].copy()  # paused: a drag still moves the mesh
            moved[1] += np.array([0.05, 0.1, -0.05]) * diagonal
            start = len(page.frames)
            page.drag("/puppet/control_1", moved[1])
            shown = page.next_mesh("/puppet/mesh", start)
            assert np.abs(shown - played(files, tmp_path, files / "puppet.h5", moved[None], "moved")[0]).max() \
                <= 1e-5 * diagonal
            page.wait(lambda: any("controls moved" in text for text in page.texts()), "the frame line")
            lines = np.asarray(page.scene()["/puppet/take_lines"]["points"], dtype=np.float64).reshape(-1, 2, 3)
            assert np.abs(lines[1, 1] - moved[1]).max() <= 1e-6 * diagonal
            assert page.external == []
        finally:
            page.close()


def test_a_bad_trajectory_is_refused_in_one_line(files, tmp_path):
    np.save(tmp_path / "five.npy", np.zeros((3, 5, 3)))
    (tmp_path / "bad.csv").write_text("frame,point,x,y,z\n0,0,1,2\n")
    (tmp_path / "garbage.c3d").write_bytes(b"not a c3d file at all" * 50)
    puppet = files / "puppet.h5"
    assert_user_error(cli("view", puppet, "--no-open", "--controls", tmp_path / "five.npy"), "five.npy",
                      "5 control points per frame")
    assert_user_error(cli("view", puppet, "--no-open", "-c", tmp_path / "bad.csv"), "bad.csv")
    assert_user_error(cli("view", puppet, "--no-open", "-c", tmp_path / "missing.npy"), "missing.npy", "no such file")
    record, _, _, _ = puppet_facts(puppet)
    (tmp_path / "layout.json").write_text(json.dumps({f"M{i}": int(v) for i, v in enumerate(record.control_indices)}))
    assert_user_error(cli("view", puppet, "--no-open", "-c", tmp_path / "garbage.c3d", "--markers",
                          tmp_path / "layout.json"), "garbage.c3d")
    assert_user_error(cli("view", files / "skin.h5", "--no-open", "-c", tmp_path / "five.npy"),
                      "--controls plays a trajectory on a puppet")
    assert_user_error(cli("view", puppet, "--no-open", "--retarget", "absolute"),
                      "--retarget applies to a motion-capture take")


# -- skin fit, synthesis, sequences ----------------------------------------------------------------

def triangles(node):
    vertices = np.asarray(node["vertices"], dtype=np.float64).reshape(-1, 3)
    return vertices[np.asarray(node["faces"]).reshape(-1, 3)]


def same_triangles(a, b, tolerance):
    """Whether two triangle sets (T, 3, 3) are the same multiset, up to ``tolerance``: each of a's
    has one of b's within it (nearest neighbours of the nine coordinates), no two the same. (A sort
    of coordinates rounded to the tolerance flipped on values a hair from a rounding boundary.)"""
    from scipy.spatial import cKDTree

    if a.shape != b.shape:
        return False
    distance, nearest = cKDTree(b.reshape(len(b), -1)).query(a.reshape(len(a), -1))
    return bool(distance.max() <= 2 * tolerance and np.unique(nearest).size == len(a))


def test_skin_view_shows_examples_and_the_coloured_reconstruction(files, browser):
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.gpu import lbs_reference
    from skinsynth.pipeline.mesh.geometry import bounding_box_diagonal
    from skinsynth.pipeline.view.scenes import level_colors

    skin = read_skin(files / "skin.h5")
    diagonal = bounding_box_diagonal(skin.rest_vertices)
    fitted = lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations, skin.translations)
    with serving(files / "skin.h5", "--error-scale", "0.002") as (summary, _):
        assert summary["kind"] == "skin" and summary["frames"] == len(skin.examples)
        page = Page(browser, summary["url"])
        try:
            page.wait(lambda: "/input" in page.scene(), "the input mesh")
            for frame in (0, 7):
                if frame:
                    start = len(page.frames)
                    slider = page.gui("frame")
                    page.send({"type": "GuiUpdateMessage", "uuid": slider["uuid"], "updates": {"value": frame}})
                    page.next_mesh("/input", start)
                    page.page.wait_for_timeout(200)
                scene = page.scene()
                assert np.abs(page.vertices("/input", scene) - skin.examples[frame]).max() <= 1e-6 * diagonal
                parts = {name: node for name, node in scene.items() if name.startswith("/fit/")}
                shown = np.concatenate([triangles(node) for node in parts.values()])
                offset = np.array([1.2 * np.ptp(skin.examples[0][:, 0]), 0.0, 0.0])
                expected = fitted[frame][skin.faces] + offset
                assert same_triangles(shown, expected, 1e-6 * diagonal)
                # each face in the shade of its corners' mean error (brute force)
                colors = level_colors(8)
                errors = np.linalg.norm(fitted[frame] - skin.examples[frame], axis=1)
                for name, node in parts.items():
                    level = int(name.rsplit("_", 1)[1])
                    assert node["color"] == list(colors[level])
                    for triangle in triangles(node)[:20]:
                        corners = [int(np.argmin(np.abs(fitted[frame] + offset - c).sum(axis=1))) for c in triangle]
                        mean = errors[corners].mean() / (0.002 * diagonal)
                        assert round(min(mean, 1.0) * 7) == level
            assert len({int(n.rsplit("_", 1)[1]) for n in parts}) >= 2  # the colours tell errors apart
            assert non_blank(page.page.screenshot()) > 0.05
        finally:
            page.close()


def test_synthesis_view_picks_an_animation_and_colours_components(files, browser):
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.gpu import lbs_reference
    from skinsynth.pipeline.mesh.geometry import bounding_box_diagonal

    skin = read_skin(files / "bones.h5")
    diagonal = bounding_box_diagonal(skin.rest_vertices)
    with h5py.File(files / "bones.h5") as f:
        F, t, sources = f["synthesis/bone_matrices"][()], f["synthesis/bone_translations"][()], \
            f["synthesis/sources"][()]
    with serving(files / "bones.h5", "--animation", "1") as (summary, _):
        assert summary["kind"] == "synthesis" and summary["animations"] == 3
        page = Page(browser, summary["url"])
        try:
            page.wait(lambda: any(n.startswith("/synthesis/") for n in page.scene()), "the components")
            for animation in (1, 2):
                if animation == 2:
                    start = len(page.frames)
                    picker = page.gui("animation")
                    page.send({"type": "GuiUpdateMessage", "uuid": picker["uuid"], "updates": {"value": 2}})
                    page.wait(lambda: any("animation 2, frame 0" in text for text in page.texts()), "animation 2")
                    page.page.wait_for_timeout(200)
                scene = page.scene()
                parts = [node for name, node in scene.items() if name.startswith("/synthesis/component_")]
                assert len(parts) == sources.shape[0]  # one colour per component
                assert len({tuple(p["color"]) for p in parts}) == len(parts)
                expected = lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, F[animation, :1],
                                         t[animation, :1])[0][skin.faces]
                shown = np.concatenate([triangles(p) for p in parts])
                assert same_triangles(shown, expected, 1e-6 * diagonal)
                seams = np.flatnonzero(np.any(sources[:, animation, 1:] != sources[:, animation, :-1] + 1, axis=0)) + 1
                marks = page.gui("frame").get("_marks") or []
                assert sorted(int(m["value"]) for m in marks) == sorted(seams.tolist())
        finally:
            page.close()


@pytest.mark.parametrize("name", ["bar.npz", "played.h5"])
def test_a_sequence_plays(files, browser, name, tmp_path):
    path = files / name
    if name == "played.h5":
        path = tmp_path / name
        assert_ok(cli("play", files / "puppet.h5", "-c", files / "bar.npz", "-o", path, "--instances", 2,
                      "--device", "cpu", "-q"))
        with h5py.File(path) as f:
            sequences = list(f["vertices"][()])
    else:
        with np.load(path) as archive:
            sequences = [archive["vertices"]]
    with serving(path) as (summary, _):
        assert summary["kind"] == "sequence" and summary["meshes"] == len(sequences)
        page = Page(browser, summary["url"])
        try:
            page.wait(lambda: "/sequence/part_000" in page.scene(), "the sequence")
            for n, vertices in enumerate(sequences):
                assert np.abs(page.vertices(f"/sequence/part_{n:03d}") - vertices[0]).max() < 1e-5
            start = len(page.frames)
            page.press("play")
            page.wait(lambda: len(page.updates("/sequence/part_000", start)) >= 5, "five frames played")
            page.press("pause")
            page.page.wait_for_timeout(300)
            # every mesh received is a frame of the sequence, exactly (the bar repeats its cycle: the
            # frames it equals), and the frames go forward, a few at most at a time
            count = len(sequences[0])
            shown = [{k for k, v in enumerate(sequences[0]) if np.abs(u - v).max() < 1e-5}
                     for u in page.updates("/sequence/part_000", start)]
            assert len(shown) >= 5 and all(shown), shown
            forward = [any((b - a) % count == 1 for a in now for b in after) for now, after in zip(shown, shown[1:])]
            assert np.mean(forward) >= 0.5, shown  # (a busy machine skips frames to keep to the clock)
            # paused: the page holds the slider's frame
            assert np.abs(page.vertices("/sequence/part_000") - sequences[0][int(page.gui("frame")["value"])]).max() \
                < 1e-5
        finally:
            page.close()


# -- the command's own contract ---------------------------------------------------------------------

def test_bad_input_is_one_line(files, tmp_path):
    (tmp_path / "notes.txt").write_text("not a mesh")
    assert_user_error(cli("view", tmp_path / "notes.txt", "--no-open"), "notes.txt", "unknown extension")
    with np.load(files / "bar.npz") as one:
        np.savez(tmp_path / "still.npz", vertices=one["vertices"][:1], faces=one["faces"])
    assert_user_error(cli("view", tmp_path / "still.npz", "--no-open"), "still.npz", "an animation needs")
    assert_user_error(cli("view", files / "controls.h5", "--no-open", "--error-scale", "0"), "--error-scale")
    assert_user_error(cli("view", files / "bones.h5", "--no-open", "--animation", "7"), "--animation 7")
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert_user_error(cli("view", files / "bar.npz", "--no-open", "--port", port), f"port {port}", "in use")


def test_any_host_warns_and_ctrl_c_stops_cleanly(files):
    with serving(files / "bar.npz", "--host", "0.0.0.0") as (summary, process):
        assert summary["url"].startswith("http://localhost:")
        import urllib.request

        with urllib.request.urlopen(summary["url"], timeout=WAIT) as response:  # it listens
            assert response.status == 200 and b"<html" in response.read(2000).lower()
        process.send_signal(signal.SIGINT)
        assert process.wait(15) == 130
        stdout, stderr = process.stdout.read(), process.stderr.read()
    assert stdout == ""  # --json: the one line read above, nothing else
    lines = stderr.splitlines()
    assert lines[0].startswith("warning: --host 0.0.0.0: anyone") and "network" in lines[0]
    assert lines[1:] == ["skinsynth: interrupted (SIGINT); no output written"], stderr


def test_skin_view_draws_a_skeleton_inside_the_see_through_fit(jointed_skins, browser):
    """fit-skin --skeleton: the fit's joints (points) and bones (lines) at the shown frame, over the
    reconstruction, which is see-through; a skin without a skeleton has neither (the test above)."""
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.rig.chain_labels import chain_tops
    from skinsynth.pipeline.view.scenes import side_by_side, skeleton_lines

    skin = read_skin(jointed_skins / "free.h5")
    skeleton = skin.skeleton
    offset = side_by_side(skin.examples[0])
    with serving(jointed_skins / "free.h5") as (summary, _):
        page = Page(browser, summary["url"])
        try:
            page.wait(lambda: "/fit_joints" in page.scene(), "the skeleton's joints")
            scene = page.scene()
            held = skeleton["jointed"] | skeleton["sliding"]  # fixed and sliding joints: every bone but the root
            joints, bones = skeleton_lines(skin.rotations[0], skin.translations[0], skeleton["joints"],
                                           skeleton["parents"], held)
            shown = np.asarray(scene["/fit_joints"]["points"], dtype=np.float64).reshape(-1, 3)
            scale = np.ptp(skin.examples[0], axis=0).max()
            assert np.abs(shown - (joints + offset)).max() <= 2e-3 * scale  # points are sent as float16
            lines = np.asarray(scene["/fit_bones"]["points"], dtype=np.float64).reshape(-1, 2, 3)
            assert skeleton["sliding"].any() and len(lines) == int(held.sum()) == skin.bones - 1
            assert np.abs(lines - (bones + offset)).max() <= 1e-5 * scale
            assert all(node["opacity"] < 1 for name, node in scene.items() if name.startswith("/fit/"))
            tops = chain_tops(skeleton["names"])  # each named chain labelled (issue 44)
            assert {"leg_l", "leg_r"} <= set(tops)
            assert {n: node["text"] for n, node in scene.items() if n.startswith("/chains/")} == {
                f"/chains/{chain}": chain for chain in tops}
        finally:
            page.close()
