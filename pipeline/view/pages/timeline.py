"""The frame slider with play/pause every animated page has (skin fit, synthesis, sequence, a
puppet's trajectory)."""

import threading
import time


class Timeline:
    """A frame slider with play/pause at ``fps``; ``show(frame)`` runs for each frame shown,
    one at a time. Playing keeps to the clock: frames a slow ``show`` misses are skipped;
    ``warn(message)`` if playing stops on an error."""

    def __init__(self, server, frames, fps, show, warn, marks=None):
        self.server, self.frames, self.fps, self.show, self.warn = server, frames, fps, show, warn
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
            if self.closed.is_set() or not self.playing:  # paused or closed while it waited
                continue
            try:
                self.slider.value = (int(self.slider.value) + step) % self.frames
            except Exception as error:  # a page error must not end the loop silently
                if self.closed.is_set():  # the page closed under it: nothing to say
                    break
                self.warn(f"the timeline stopped: {error}")
                self.playing = False

    def close(self):
        """Stop playing and wait for the loop to end, so that no frame is sent once the server
        stops (a frame queued on the closed connection ended the loop with a warning)."""
        self.closed.set()
        self.wake.set()
        if self.thread is not threading.current_thread():
            self.thread.join(timeout=2.0)


def _slider_marks(frames):
    from viser._messages import GuiSliderMark

    return [GuiSliderMark(value=float(f), label=None) for f in frames]
