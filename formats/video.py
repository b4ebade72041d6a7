"""Writing rendered frames: H.264 .mp4 (imageio-ffmpeg, which ships its own ffmpeg), .gif, or a
.png contact sheet of evenly spaced frames. Each file is written whole (atomic_output)."""

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
    with atomic_output(path) as tmp:
        if suffix == ".mp4":
            _write_mp4(tmp, frames, fps)
        else:
            _write_gif(tmp, frames, fps)


def _write_mp4(path, frames, fps):
    import imageio_ffmpeg

    writer = None
    try:
        for image in frames:
            if writer is None:
                height, width = image.shape[:2]
                # yuv420p (what every player reads) wants even sizes
                writer = imageio_ffmpeg.write_frames(path, (width - width % 2, height - height % 2), fps=float(fps),
                                                     codec="libx264", pix_fmt_out="yuv420p", quality=7,
                                                     macro_block_size=1, ffmpeg_log_level="error")
                writer.send(None)
            writer.send(np.ascontiguousarray(image[:height - height % 2, :width - width % 2]))
    finally:
        if writer is not None:
            writer.close()


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
