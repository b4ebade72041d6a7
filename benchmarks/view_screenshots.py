"""The screenshots of ``skinsynth view`` in docs/ (view_puppet.png, view_skin.png,
view_synthesis.png), taken by the headless browser the tests drive, so they stay current.

The built-in walker (``skinsynth example walker``: its legs are bone components of their own) is
fitted, made a puppet and synthesized with the CLI into ``--work``; each page is served by
``skinsynth view``, opened in headless Chromium at 1280×800 and captured once it drew:

- puppet: a control moved (the message its gizmo sends) off the training examples, so the
  indicator shows a distance;
- skin fit: played for a second, paused (side by side, the reconstruction coloured by error at
  ``--error-scale 0.00005``: the walker is skinned data, fitted almost exactly);
- synthesis: animation 1 at a frame typed into the slider's field, one with no seam just before
  it (each component in its colour; the seams marked on the slider).

The page's "software WebGL" notice (headless Chromium draws without a GPU) is hidden.

    python benchmarks/view_screenshots.py [--out docs] [--work build/view-screenshots]
"""

import argparse
import os
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from datasets import run  # noqa: E402
from view import CHROMIUM, LAUNCH_ARGS, move_template, open_page, start_view, stop_view  # noqa: E402

HIDE_NOTICE = ".mantine-Notifications-root, .mantine-Notification-root { display: none !important; }"


def build(work):
    """The walker's stage files in ``work`` (made once)."""
    os.makedirs(work, exist_ok=True)
    steps = [("walker.npz", ["example", "walker", "-o", "walker.npz"]),
             ("skin.h5", ["fit-skin", "walker.npz", "-o", "skin.h5", "--bones", "12", "--seed", "0"]),
             ("controls.h5", ["select-controls", "skin.h5", "-o", "controls.h5", "--count", "8"]),
             ("puppet.h5", ["train-kcca", "controls.h5", "-o", "puppet.h5"]),
             ("graph.h5", ["build-graph", "skin.h5", "-o", "graph.h5"]),
             ("bones.h5", ["synthesize", "graph.h5", "-o", "bones.h5", "-n", "4", "-m", "96", "--seed", "0"])]
    for name, command in steps:
        if not os.path.exists(os.path.join(work, name)):
            run([*command, "-q"], work)


def capture(browser, path, png, prepare, *options):
    process, summary = start_view(path, *options)
    try:
        page, workers = open_page(browser, summary["url"], size=(1280, 800))
        try:
            page.add_style_tag(content=HIDE_NOTICE)
            page.wait_for_timeout(1500)
            prepare(page, workers)
            page.wait_for_timeout(1500)
            page.screenshot(path=png)
        finally:
            page.close()
    finally:
        stop_view(process)
    print(f"wrote {png}")


def play_a_second(page, workers):
    page.get_by_role("button", name="play", exact=True).click()
    page.wait_for_timeout(1000)
    page.get_by_role("button", name="pause", exact=True).click()


def calm_frame(synthesis, animation, hold=6):
    """A frame of the animation whose components play on, no seam in the ``hold`` frames before it
    (so every component shows its own colour), after a seam (so the slider shows marks behind it)."""
    import numpy as np

    from skinsynth.formats.synthesis_file import read_sources
    from skinsynth.pipeline.view import seam_frames

    seams = seam_frames(read_sources(synthesis, [animation])[:, 0]).any(axis=0)
    calm = [m for m in range(hold, len(seams)) if not seams[m - hold + 1:m + 1].any() and seams[:m].any()]
    frame = calm[len(calm) // 2] if calm else len(seams) // 2

    def prepare(page, workers):
        field = page.locator(".mantine-NumberInput-input").last  # the frame slider's own number field
        field.fill(str(int(frame)))
        field.press("Enter")
    return prepare


def move_a_control(puppet):
    import numpy as np

    from skinsynth.formats.puppet_file import read_puppet

    record, _, skin = read_puppet(puppet)
    start = skin.examples[record.train_frames[0], record.control_indices]
    size = float(np.ptp(skin.rest_vertices, axis=0).max())

    def prepare(page, workers):
        template, offsets = move_template("/puppet/control_1")
        data = bytearray(template)
        for offset, value in zip(offsets, start[1] + np.array([0.12, 0.1, 0.05]) * size):
            data[offset:offset + 8] = np.float64(value).byteswap().tobytes()
        for worker in workers:
            worker.evaluate("bytes => { const s = (self.__sockets || []).find(s => s.readyState === 1);"
                            " if (s) s.send(new Uint8Array(bytes)); }", list(data))
    return prepare


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs"))
    parser.add_argument("--work", default=str(ROOT / "build" / "view-screenshots"))
    opts = parser.parse_args()
    work, out = os.path.abspath(opts.work), os.path.abspath(opts.out)
    build(work)
    # Served from the work folder by relative names, as a user would: the page shows the record
    # button's default file (puppet.session.csv), not a path of this machine.
    os.chdir(work)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        try:
            capture(browser, "puppet.h5", os.path.join(out, "view_puppet.png"), move_a_control("puppet.h5"),
                    "--device", "cpu")
            capture(browser, "skin.h5", os.path.join(out, "view_skin.png"), play_a_second, "--error-scale", "0.00005")
            capture(browser, "bones.h5", os.path.join(out, "view_synthesis.png"), calm_frame("bones.h5", 1),
                    "--animation", "1")
        finally:
            browser.close()


if __name__ == "__main__":
    main()
