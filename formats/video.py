"""Writing rendered frames: H.264 .mp4 (imageio-ffmpeg, which ships its own ffmpeg), .gif, or a
.png contact sheet of evenly spaced frames. Each file is written whole (atomic_output)."""

import os

import numpy as np

from .atomic import atomic_output
from .errors import FormatError

SUFFIXES = (".mp4", ".gif", ".png")


def write_frames(path, frames, count, fps, sheet_columns=4, sheet_frames=12):
    """Write ``count`` frames (an iterable of (H, W, 3) uint8 images) to ``path`` by its suffix.

    .png: a contact sheet of ``sheet_frames`` evenly spaced frames, ``sheet_columns`` wide (the
    iterable is still consumed in order, skipped frames cost their rendering only when asked:
    pass a lazy sequence to skip them)."""
    suffix = str(path).lower()[-4:]
    if suffix not in SUFFIXES:
        raise FormatError(path, f"unknown output type; expected {', '.join(SUFFIXES)}")
    if suffix == ".png":
        return _write_sheet(path, frames, count, sheet_columns, sheet_frames)
    with atomic_output(path, interruptible=True) as tmp:
        if suffix == ".mp4":
            _write_mp4(tmp, frames, fps)
        else:
            _write_gif(tmp, frames, fps)


def _write_mp4(path, frames, fps):
    """H.264 yuv420p (what every player reads; it wants even sizes, so an odd last row or column
    is dropped) at constant rate factor 15, through imageio-ffmpeg's own ffmpeg binary.

    ffmpeg is driven here rather than through imageio-ffmpeg's writer, which ignores ffmpeg's
    exit status (a full disk left a truncated file without its index, "written") and lets its
    messages through to the user: ffmpeg's log is kept and its failure is one error. It runs in
    its own session, so a Ctrl-C to the terminal's process group reaches this process only,
    which stops ffmpeg itself."""
    import subprocess
    import tempfile

    process = log = None
    try:
        for image in frames:
            if process is None:
                height, width = image.shape[0] - image.shape[0] % 2, image.shape[1] - image.shape[1] % 2
                log = tempfile.TemporaryFile()
                command = [_ffmpeg(), "-nostdin", "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24",
                           "-s", f"{width}x{height}", "-r", f"{float(fps):.6g}", "-i", "-", "-an",
                           "-c:v", "libx264", "-pix_fmt", "yuv420p", "-crf", "15", "-f", "mp4", path]
                process = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=log,
                                           start_new_session=True)
            try:
                process.stdin.write(np.ascontiguousarray(image[:height, :width]).tobytes())
            except BrokenPipeError:  # ffmpeg stopped: its status and log say why
                break
        if process is not None:
            _finish(process, log, path)
    finally:
        if process is not None and process.poll() is None:  # interrupted, or a frame failed to render
            process.kill()
            process.wait()
        if log is not None:
            log.close()


def _finish(process, log, path):
    """Close ffmpeg's input, wait for it, and raise what it failed with (OSError ENOSPC for a
    full disk, so the writer reports it as every full disk is reported)."""
    import errno

    try:
        process.stdin.close()
    except BrokenPipeError:
        pass
    if process.wait() == 0:
        return
    log.seek(0)
    said = " ".join(log.read().decode(errors="replace").split())[-300:]
    if "no space left" in said.lower():
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), path)
    raise FormatError(path, f"ffmpeg could not encode the video (exit status {process.returncode}): "
                            f"{said or 'no message'}")


def _ffmpeg():
    """imageio-ffmpeg's ffmpeg. Its first call runs ``ffmpeg -version`` to check the binary;
    SIGINT and SIGTERM are blocked meanwhile (the mask is inherited by the check's process, so a
    Ctrl-C to the process group cannot kill it and be taken for a missing binary) and arrive as
    soon as the check is done."""
    import signal
    import threading

    import imageio_ffmpeg

    if threading.current_thread() is not threading.main_thread():
        return imageio_ffmpeg.get_ffmpeg_exe()
    held = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        return imageio_ffmpeg.get_ffmpeg_exe()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _write_gif(path, frames, fps):
    from PIL import Image

    images = [Image.fromarray(image).quantize(colors=256, method=Image.Quantize.MEDIANCUT) for image in frames]
    images[0].save(path, save_all=True, append_images=images[1:], duration=max(20, int(round(1000.0 / fps))),
                   loop=0, optimize=False)


def sheet_indices(count, sheet_frames):
    """Which of ``count`` frames a contact sheet shows: ``sheet_frames`` evenly spaced, ends included."""
    return np.unique(np.round(np.linspace(0, count - 1, min(sheet_frames, count))).astype(int))


def _write_sheet(path, frames, count, columns, sheet_frames):
    from PIL import Image

    images = list(frames)
    rows = -(-len(images) // columns)
    height, width = images[0].shape[:2]
    sheet = np.full((rows * height, min(columns, len(images)) * width, 3), 255, np.uint8)
    for n, image in enumerate(images):
        r, c = divmod(n, columns)
        sheet[r * height:(r + 1) * height, c * width:(c + 1) * width] = image
    with atomic_output(path) as tmp:
        Image.fromarray(sheet).save(tmp, format="PNG")
