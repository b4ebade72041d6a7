"""Benchmark ``skinsynth view`` on a puppet in a real browser: control moves per second and
move-to-mesh latency (issue 24's goal at face size: ≥ 30 updates/s, ≤ 50 ms).

The command serves the puppet (a subprocess, ``--device cpu``); headless Chromium (Debian's
``chromium`` through Playwright, software WebGL) opens the page, whose client keeps its websocket in
a Web Worker (an init script wraps ``Worker`` so the worker keeps its sockets, each with a listener
ahead of the client's, which hands each frame's buffer over to the page). In that worker, the
page sends the message the control's gizmo sends when dragged (``TransformControlsUpdateMessage``,
control 0 moving on a small circle) and times, with the worker's clock, the arrival of the frame
that carries the new mesh (the first frame of at least V × 12 bytes after the send; it also
carries the markers' colours and the indicator). So the latency is send → the page holds the
mesh (its decode and draw follow on the page's main thread, which draws all the while).

Two measurements per puppet, one JSON line each:

- ``closed``: ``--moves`` moves, each sent once the previous one's mesh arrived: latency median
  and 90th percentile, and ``updates_per_s`` = moves / total time;
- ``drag``: moves sent at ``--rate`` Hz (a mouse drag) for ``--seconds``: ``meshes_per_s``, the
  meshes the page received per second (moves arriving during a prediction are merged into the
  next one), and the latency of the last move's mesh.

Puppets (built once with the CLI into ``--work``, default build/bench-view): ``samba`` (the
vlasic_samba capture, 22 bones, 8 controls, ``--train-frames every:4``; skipped without the real
data) and ``face`` (a stand-in of the face's size: the bending bar with 1483 rings × 16 segments,
23,730 vertices, fitted with 260 bones in 10 iterations; ``--face-rings``/``--face-bones`` make it
smaller), and
with ``--only bar`` a small bar (a quick check of the script itself).

    python benchmarks/view.py [--only samba|face|bar] [--moves 100] [--rate 60] [--seconds 5]
                              [--work DIR] [--face-rings 1483] [--face-bones 260] [--face-frames 96]
                              [--face-iterations 10]
"""

import argparse
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

ROOT = pathlib.Path(__file__).resolve().parents[1]
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
LAUNCH_ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
#: Runs before the page's scripts: every Web Worker starts by wrapping WebSocket, keeping its sockets.
WORKER_SOCKETS = (ROOT / "tests" / "contracts" / "js" / "worker_sockets.js").read_text()

#: In the page's worker: send moves (the template's position floats overwritten) and time the meshes.
MOVES = r"""
async ({template, offsets, base, radius, mode, count, rate, seconds, minBytes}) => {
  const socket = self.__sockets.find(s => s.readyState === 1);
  const now = () => performance.timeOrigin + performance.now();
  const bytes = new Uint8Array(template), view = new DataView(bytes.buffer);
  const arrivals = [];
  let waiting = null;
  const listener = (size) => {
    if (size < minBytes) return;
    const t = now();
    arrivals.push(t);
    if (waiting) { const w = waiting; waiting = null; w(t); }
  };
  self.__onFrame = listener;
  const send = (k) => {
    const a = 2 * Math.PI * k / 25;
    const p = [base[0] + radius * Math.cos(a), base[1] + radius * Math.sin(a), base[2] + 0.3 * radius * Math.sin(2 * a)];
    offsets.forEach((o, i) => view.setFloat64(o, p[i], false));
    socket.send(bytes.slice());
  };
  const sleep = (ms) => new Promise(r => setTimeout(r, ms));
  const next = (ms) => new Promise((resolve, reject) => {
    waiting = resolve; setTimeout(() => reject(new Error("no mesh within " + ms + " ms")), ms); });
  try {
    if (mode === "closed") {
      const latencies = [];
      const start = now();
      for (let k = 1; k <= count; k++) {
        const t0 = now(), arrived = next(10000);
        send(k);
        latencies.push((await arrived) - t0);
      }
      return {latencies, total: now() - start};
    }
    const start = now();
    let k = 0, last = 0;
    while (now() - start < seconds * 1000) {
      last = now(); send(++k);
      await sleep(Math.max(0, start + k * 1000 / rate - now()));
    }
    const end = now();
    for (let i = 0; i < 1000 && !arrivals.some(t => t >= last); i++) await sleep(5);
    const after = arrivals.find(t => t >= last);
    const tail = after === undefined ? null : after - last;
    return {sent: k, meshes: arrivals.filter(t => t >= start && t <= end).length, seconds: (end - start) / 1000,
            last_latency: tail};
  } finally {
    self.__onFrame = null;
  }
}
"""


def open_page(browser, url, size=(1280, 800)):
    """A page on ``url`` whose worker keeps its sockets, once the server knows the client (its
    first camera message sent); returns (page, workers)."""
    import msgspec

    page = browser.new_page(viewport={"width": size[0], "height": size[1]})
    page.add_init_script(WORKER_SOCKETS)
    workers, sent = [], []
    page.on("worker", lambda worker: workers.append(worker))
    page.on("websocket", lambda ws: ws.on("framesent", lambda d: sent.append(d) if isinstance(d, bytes) else None))
    page.goto(url)
    for _ in range(2400):
        if any(msgspec.msgpack.decode(d).get("type") == "ViewerCameraMessage" for d in sent):
            break
        page.wait_for_timeout(25)
    else:
        raise RuntimeError(f"{url}: the page never connected")
    return page, workers


def start_view(path, *options):
    """``skinsynth view PATH --no-open --json --port 0`` as a subprocess: (process, its summary)."""
    exe = shutil.which("skinsynth", path=os.path.dirname(sys.executable)) or "skinsynth"
    process = subprocess.Popen([exe, "view", str(path), "--no-open", "--json", "--port", "0", *options],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines = queue.Queue()
    threading.Thread(target=lambda: lines.put(process.stdout.readline()), daemon=True).start()
    try:
        line = lines.get(timeout=600)
    except queue.Empty:
        line = ""
    if not line:
        stop_view(process)
        raise RuntimeError(f"skinsynth view {path} did not start: {process.stderr.read()[-800:]}")
    return process, json.loads(line)


def stop_view(process):
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(15)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def move_template(name):
    """The gizmo's message as msgpack, and the byte offsets of its three position floats."""
    import msgspec

    sentinels = (1.0123456789e300, 2.0123456789e300, 3.0123456789e300)
    data = msgspec.msgpack.encode({"type": "TransformControlsUpdateMessage", "name": name,
                                   "wxyz": [1.0, 0.0, 0.0, 0.0], "position": list(sentinels), "owner": ""})
    return list(data), [data.index(struct.pack(">d", s)) for s in sentinels]


def build_puppets(work, only, face_rings, face_segments, face_bones, face_frames, face_iterations):
    """(name, puppet path) of each puppet measured, made with the CLI into ``work`` when missing."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from datasets import SHARED_DATA, run

    work = os.path.abspath(work)
    os.makedirs(work, exist_ok=True)
    wanted = []
    if only in (None, "samba"):
        capture = SHARED_DATA / "vlasic_samba" / "vlasic_samba.npz"
        if capture.exists():
            wanted.append(("samba", str(capture), 22, (), ()))
        else:
            print(json.dumps({"puppet": "samba", "skipped": f"no capture at {capture}"}), flush=True)
    if only in (None, "face"):
        wanted.append(("face", ("bending-bar", face_rings, face_segments, face_frames), face_bones, (),
                       ("--iterations", str(face_iterations))))
    if only == "bar":
        wanted.append(("bar", ("bending-bar", 10, 8, 48), 4, ("--count", "6"), ()))
    for name, source, bones, control_args, fit_args in wanted:
        puppet = os.path.join(work, f"{name}.puppet.h5")
        if not os.path.exists(puppet):
            if isinstance(source, tuple):
                _, rings, segments, frames = source
                capture = os.path.join(work, f"{name}.npz")
                run(["example", "bending-bar", "-o", capture, "--rings", str(rings), "--segments", str(segments),
                     "--frames", str(frames), "--cycles", "2", "-q"], work)
                source = capture
            skin, controls = os.path.join(work, f"{name}.skin.h5"), os.path.join(work, f"{name}.controls.h5")
            run(["fit-skin", source, "-o", skin, "--bones", str(bones), "--seed", "0", *fit_args, "-q"], work)
            run(["select-controls", skin, "-o", controls, *(control_args or ("--count", "8")), "-q"], work)
            run(["train-kcca", controls, "-o", puppet, "--train-frames", "every:4", "-q"], work)
        yield name, puppet


def measure(browser, name, puppet, opts):
    import h5py
    import numpy as np

    from skinsynth.formats.puppet_file import read_puppet

    record, _, skin = read_puppet(puppet)
    base = skin.examples[record.train_frames[0], record.control_indices[0]]
    radius = 0.03 * float(np.ptp(skin.rest_vertices, axis=0).max())
    vertices = int(skin.rest_vertices.shape[0])
    with h5py.File(puppet) as f:
        correctives = "correctives" in f
    facts = {"puppet": name, "vertices": vertices, "bones": int(skin.bones),
             "controls": int(len(record.control_indices)), "training_examples": int(len(record.train_frames)),
             "correctives": correctives, "skinning": record.skinning,
             "cpu_cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()}
    template, offsets = move_template("/puppet/control_0")
    process, summary = start_view(puppet, "--device", "cpu")
    try:
        page, workers = open_page(browser, summary["url"])
        try:
            page.wait_for_timeout(1000)  # the first mesh drawn
            worker = next(w for w in workers if w.evaluate("(self.__sockets || []).length"))
            args = dict(template=template, offsets=offsets, base=[float(b) for b in base], radius=radius,
                        minBytes=vertices * 12, count=opts.moves, rate=opts.rate, seconds=opts.seconds)
            worker.evaluate(MOVES, dict(args, mode="closed", count=5))  # warm-up
            closed = worker.evaluate(MOVES, dict(args, mode="closed"))
            latencies = np.array(closed["latencies"])
            print(json.dumps({**facts, "mode": "closed", "moves": opts.moves,
                              "latency_ms_median": round(float(np.median(latencies)), 2),
                              "latency_ms_p90": round(float(np.percentile(latencies, 90)), 2),
                              "latency_ms_max": round(float(latencies.max()), 2),
                              "updates_per_s": round(1000.0 * opts.moves / closed["total"], 1),
                              "goal": "face: >= 30 updates/s, <= 50 ms"}), flush=True)
            drag = worker.evaluate(MOVES, dict(args, mode="drag"))
            print(json.dumps({**facts, "mode": "drag", "rate_hz": opts.rate,
                              "sent_per_s": round(drag["sent"] / drag["seconds"], 1),
                              "meshes_per_s": round(drag["meshes"] / drag["seconds"], 1),
                              "last_move_latency_ms": None if drag["last_latency"] is None
                              else round(drag["last_latency"], 2)}), flush=True)
        finally:
            page.close()
    finally:
        stop_view(process)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=["samba", "face", "bar"])
    parser.add_argument("--moves", type=int, default=100)
    parser.add_argument("--rate", type=float, default=60.0)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--work", default=str(ROOT / "build" / "bench-view"))
    parser.add_argument("--face-rings", type=int, default=1483)
    parser.add_argument("--face-segments", type=int, default=16)
    parser.add_argument("--face-bones", type=int, default=260)
    parser.add_argument("--face-frames", type=int, default=96)
    parser.add_argument("--face-iterations", type=int, default=10,
                        help="fit-skin iterations of the face stand-in (its fit's quality does not change the speed)")
    opts = parser.parse_args()
    if CHROMIUM is None:
        print(json.dumps({"skipped": "no chromium on PATH (apt-get install chromium)"}))
        return
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        try:
            for name, puppet in build_puppets(opts.work, opts.only, opts.face_rings, opts.face_segments,
                                              opts.face_bones, opts.face_frames, opts.face_iterations):
                measure(browser, name, puppet, opts)
        finally:
            browser.close()


if __name__ == "__main__":
    main()
