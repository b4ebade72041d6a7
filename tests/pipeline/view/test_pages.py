"""The web page's package (pipeline/view/pages/) without a server: it imports no viser until a
server starts (nor click, formats or cli, ever), a page's errors reach the ``warn`` it was given,
the indicator's HTML carries what the browser tests read. The pages themselves are driven in tests/cli/test_view.py."""

import subprocess
import sys
import textwrap
import threading
import time

import numpy as np

from skinsynth.pipeline.view.pages import puppet_page
from skinsynth.pipeline.view.pages.timeline import Timeline


def test_importing_the_pages_imports_no_viser_click_formats_or_cli():
    code = """
        import importlib, pathlib, sys
        import skinsynth.pipeline.view as view
        import skinsynth.pipeline.view.pages as pages
        for name in pages.__all__:
            getattr(pages, name)
        for name in ("serve", "open_page", "PuppetView", "TrajectoryView", "SkinView", "SynthesisView", "SequenceView"):
            getattr(view, name)
        for path in sorted(pathlib.Path(pages.__file__).parent.glob("*.py")):
            importlib.import_module(f"skinsynth.pipeline.view.pages.{path.stem}".removesuffix(".__init__"))
        print(sorted(name for name in sys.modules if name.split(".")[0] in ("viser", "click")))
        print(sorted(name for name in sys.modules if name.startswith(("skinsynth.formats", "skinsynth.cli"))))
        """
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, check=True)
    assert done.stdout == b"[]\n[]\n"


class _Control:
    """A slider or button of a fake server's panel; a slider whose value cannot be set with ``fails``."""

    def __init__(self, fails=None):
        self.label, self.fails, self._value = "", fails, 0

    @property
    def value(self):
        return self._value

    @value.setter
    def value(self, value):
        if self.fails:
            raise RuntimeError(self.fails)
        self._value = value

    def on_update(self, callback):
        pass

    on_click = on_update


class _Panel:
    def __init__(self, fails):
        self.fails = fails

    def add_slider(self, *args, **kwargs):
        return _Control(self.fails)

    def add_button(self, *args, **kwargs):
        return _Control()

    def add_markdown(self, *args, **kwargs):
        return _Control()


class _Server:
    def __init__(self, fails=None):
        self.gui = _Panel(fails)

    def flush(self):
        pass


def test_a_timeline_that_stops_on_an_error_says_so_through_warn():
    warned, said = [], threading.Event()
    timeline = Timeline(_Server(fails="the page went away"), 10, 100.0, lambda frame: None,
                        lambda message: (warned.append(message), said.set()))
    try:
        timeline.toggle()
        assert said.wait(10.0)
        deadline = time.monotonic() + 10.0
        while timeline.playing and time.monotonic() < deadline:
            time.sleep(0.01)
        assert warned == ["the timeline stopped: the page went away"] and not timeline.playing
    finally:
        timeline.close()


def test_the_indicator_carries_the_distance_and_the_nearest_frame():
    text = puppet_page._indicator(0.0123456789, 7, 0.05, np.array([220.0, 40.0, 40.0]))
    assert 'data-distance="0.0123457" data-frame="7"' in text and "background:rgb(220,40,40)" in text
    assert "amber at 0.05, red at 0.1" in text


def test_marker_lines_run_from_each_marker_to_its_control():
    markers, controls = np.arange(6.0).reshape(2, 3), -np.arange(6.0).reshape(2, 3)
    lines = puppet_page._marker_lines(markers, controls)
    assert lines.dtype == np.float32 and lines.shape == (2, 2, 3)
    assert np.array_equal(lines[:, 0], markers) and np.array_equal(lines[:, 1], controls)



class _Stopping(_Control):
    """A slider whose frames take 2 ms on their way and are refused once ``stopped`` is set (a
    viser server that has stopped)."""

    def __init__(self, stopped, sent):
        super().__init__()
        self.stopped, self.sent = stopped, sent

    @_Control.value.setter
    def value(self, value):
        time.sleep(0.002)
        if self.stopped.is_set():
            raise RuntimeError("Queued a GuiUpdateMessage on a closed connection")
        self._value = value
        self.sent.append(value)


def test_a_timeline_closed_while_playing_sends_nothing_after_and_says_nothing():
    """Closing a playing timeline waits for its loop, so no frame goes to a stopped server
    (``server.open_page`` closes the page, then stops the server): a frame on its way as the server
    stopped ended the loop with "the timeline stopped: …", a warning for a user who closed the page
    while it played (and a flaky view test)."""
    stopped, sent, warned = threading.Event(), [], []
    server = _Server()
    server.gui.add_slider = lambda *args, **kwargs: _Stopping(stopped, sent)
    for _ in range(10):  # the race, several times over
        stopped.clear()
        sent.clear()
        timeline = Timeline(server, 50, 1000.0, lambda frame: None, warned.append)
        timeline.toggle()
        deadline = time.monotonic() + 10.0
        while not sent and time.monotonic() < deadline:
            time.sleep(0.001)
        timeline.close()
        stopped.set()
        time.sleep(0.01)
        assert sent and not timeline.thread.is_alive()
    assert warned == []
