"""What ``skinsynth preview`` shows: panels of meshes in a grid, one camera framing them all (or one
per panel following a travelling character),
captions in a corner, rendered frame by frame (:mod:`.render`).

A panel is one animated mesh: ``vertices (M, V, 3)``, ``faces (T, 3)``, a title, optional
per-vertex colours ``(M, V, 3)`` (an error map), and a caption per frame (the source frame;
for a synthesis, the input frame each component plays, with the seams marked). A source frame
is named ``clip:frame`` (``collapse:12``) when the input holds several clips
(:meth:`~skinsynth.pipeline.inputs.clips.Clips.label`), else by its number.
"""

from dataclasses import dataclass, field

import numpy as np

from .rasteriser import frame_bounds, ground_layer, render

ERROR_LOW = np.array([0.72, 0.74, 0.80])
ERROR_HIGH = np.array([0.85, 0.12, 0.10])


@dataclass
class Panel:
    vertices: np.ndarray
    faces: np.ndarray
    title: str
    colors: np.ndarray | None = None
    captions: list = field(default_factory=list)
    marked: np.ndarray | None = None  # (M,) bool: frames whose caption is marked (a seam)


def frame_captions(clips, frames, prefix="frame"):
    """A caption per global frame of ``frames`` (M,) of an input of ``clips``: "frame 7", or
    "frame gallop:7" when it holds several clips."""
    return [f"{prefix} {clips.label(f)}" for f in np.asarray(frames).tolist()]


def walk_captions(clips, sources):
    """(captions [M], seams (M,) bool) of a synthesized animation whose C components play the
    input frames ``sources (C, M)`` of ``clips``: each frame names the input frame of every
    component; a seam is a frame where any component's source does not play on from the one
    before, a jump into another clip's first frame included (:meth:`Clips.seams`)."""
    sources = np.asarray(sources, dtype=np.int64)
    seams = np.any(clips.seams(sources), axis=0)
    captions = [f"frame {m} · input {', '.join(clips.label(s) for s in sources[:, m].tolist())}"
                + (" · seam" if seams[m] else "") for m in range(sources.shape[1])]
    return captions, seams


def error_colors(predicted, truth, scale):
    """Per-vertex colours (M, V, 3): grey where the prediction is exact, red at ``scale`` or more."""
    amount = np.clip(np.linalg.norm(predicted - truth, axis=-1) / scale, 0.0, 1.0)[..., None]
    return ERROR_LOW + amount * (ERROR_HIGH - ERROR_LOW)


def compared_panels(truth, approximation, faces, truth_title, title, error_scale, rest, captions=()):
    """Two panels side by side: ``truth`` (M, V, 3), and ``approximation`` (M, V, 3) coloured by
    each vertex's error (:func:`error_colors`, red at ``error_scale`` of the bounding-box diagonal
    of the rest pose ``rest`` (V, 3))."""
    from ..mesh.geometry import bounding_box_diagonal

    scale = error_scale * bounding_box_diagonal(rest)
    return [Panel(truth, faces, truth_title, captions=list(captions)),
            Panel(approximation, faces, f"{title} (red: error >= {error_scale:g} of the diagonal)",
                  colors=error_colors(approximation, truth, scale), captions=list(captions))]


def skin_panels(skin, clip=None, examples=False, compare=False, error_scale=0.01):
    """The panels of a skin fit (``formats.skin_file.SkinModel``: examples (F, V, 3), rest pose,
    weights, bones, clips): fit-skin's reconstruction of its examples, the examples themselves
    (``examples``), or both with the reconstruction coloured by its error (``compare``,
    :func:`compared_panels`); ``clip``: one clip's frames only (None: every frame; an unknown
    clip is an OptionError). Each frame's caption names its input frame."""
    from skinsynth.gpu import lbs_reference

    from ..inputs.clips import Clips

    clips = Clips(skin.clip_names, skin.clip_frames)
    frames = clips.select(None if clip is None else [clip], "--clip")  # (M,) global frame ids
    captions = frame_captions(clips, frames)
    shown = skin.examples[frames] if clip is not None else skin.examples
    if examples:
        return [Panel(shown, skin.faces, "input", captions=captions)]
    rotations, translations = (skin.rotations, skin.translations) if clip is None else \
        (skin.rotations[frames], skin.translations[frames])
    fitted = lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, rotations, translations)
    if not compare:
        return [Panel(fitted, skin.faces, "fit-skin reconstruction", captions=captions)]
    return compared_panels(shown, fitted, skin.faces, "input", "reconstruction", error_scale, skin.rest_vertices,
                           captions)


#: Framings of a preview: ``fixed`` one camera frames every panel's whole animation; ``follow``
#: each panel's camera tracks its character's ground position; ``auto`` follows when a character
#: travels more than its own size (:func:`travels`), else stays fixed.
FRAMINGS = ("auto", "follow", "fixed")
#: σ (seconds) of the Gaussian that smooths a followed character's ground track: a walk's sway
#: and bob stay on screen as motion (a camera locked to the centroid would shake with every
#: step), while a camera half a second behind still keeps a runner in frame.
FOLLOW_SMOOTHING = 0.5


def travels(vertices):
    """Whether a character travels more than its own size: the ground-plane path of its centroid
    (the extent of its positions) against the largest extent of its mesh in one frame.
    vertices (M, V, 3); the up axis counts too (a fall is no travel to follow, but it is a small
    share of a fall's extent)."""
    centroids = vertices.mean(axis=1)
    size = float(np.ptp(vertices, axis=1).max())
    return float(np.linalg.norm(np.ptp(centroids, axis=0))) > size


def ground_track(vertices, up_axis, sigma):
    """(M, 3) the character's smoothed ground position: its centroid per frame, Gaussian-smoothed
    over ``sigma`` frames, its up coordinate 0. vertices (M, V, 3). The ends are padded by point
    reflection (2 x_0 − x_k), so a character moving at constant velocity is tracked exactly to the
    last frame (holding the ends would leave the camera behind a runner)."""
    from scipy.ndimage import gaussian_filter1d

    track = vertices.mean(axis=1)
    count = track.shape[0]
    if sigma > 0 and count > 1:
        pad = min(count - 1, int(4.0 * sigma + 0.5))
        padded = np.concatenate([2.0 * track[:1] - track[pad:0:-1], track,
                                 2.0 * track[-1:] - track[-2:-pad - 2:-1]])
        track = gaussian_filter1d(padded, sigma, axis=0, mode="nearest")[pad:pad + count]
    track[:, up_axis] = 0.0
    return track


class Preview:
    """Frames of ``panels`` side by side (``columns`` per row), each ``size`` = (W, H) pixels, the
    ground under the lowest point. ``frames`` (M,) which frames to show; ``preset``, ``smooth``,
    ``up_axis`` (1 Y, 2 Z). ``framing`` (:data:`FRAMINGS`): one camera framing every panel's
    whole animation (or, where the panels' characters stand apart, one per panel centred on its
    own: :meth:`_fixed_cameras`), or a camera per panel that follows its character's ground track
    (:func:`ground_track`, smoothed over :data:`FOLLOW_SMOOTHING` s at ``fps``), framing the
    character's own extent about that track (the ground's checks then the character's size,
    so the travel shows)."""

    def __init__(self, panels, size=(640, 480), frames=None, preset="three-quarter", smooth=True, up_axis=1,
                 columns=None, framing="auto", fps=24.0):
        self.panels, self.size, self.smooth, self.up_axis = panels, size, smooth, up_axis
        count = min(p.vertices.shape[0] for p in panels)
        self.frames = np.arange(count) if frames is None else np.asarray(frames)
        self.columns = columns or min(len(panels), 4)
        self.preset = preset
        shown = [p.vertices[:count] for p in panels]
        self.follow = framing == "follow" or (framing == "auto" and any(travels(v[self.frames]) for v in shown))
        boxes = [(v[self.frames].reshape(-1, 3).min(axis=0), v[self.frames].reshape(-1, 3).max(axis=0)) for v in shown]
        lower, upper = np.min([low for low, _ in boxes], axis=0), np.max([high for _, high in boxes], axis=0)
        self.level = float(lower[up_axis])
        width, height = size
        if self.follow:
            self.tracks = [ground_track(v, up_axis, FOLLOW_SMOOTHING * fps) for v in shown]
            about = np.concatenate([(v[self.frames] - track[self.frames, None]).reshape(-1, 3)
                                    for v, track in zip(shown, self.tracks)])
            self.extent = about.min(axis=0), about.max(axis=0)  # the characters about their tracks
            self.cell = max(float(np.ptp(v[self.frames], axis=1).max()) for v in shown)  # a character's size
            self.camera = None
        else:
            self.cameras = self._fixed_cameras(boxes, lower, upper)

    def _fixed_cameras(self, boxes, lower, upper):
        """[(camera, ground layer)] per panel, framing: one camera for all, framing every panel's whole
        animation, where their characters share a place (a prediction beside its truth, animations of
        one synthesis); where they stand apart (a crowd laid out on a grid: their boxes do not
        overlap), one camera per panel, as far away for every panel (the largest box) and centred on
        its own character, so a crowd of 16 shows 16 characters each its panel's height, not 16
        panels of the whole grid (dancers 20 pixels tall). boxes: each panel's (lowest, highest)
        corner over the frames shown; lower, upper: all of theirs."""
        width, height = self.size
        apart = len(boxes) > 1 and not any(np.all(boxes[i][0] <= boxes[j][1]) and np.all(boxes[j][0] <= boxes[i][1])
                                           for i in range(len(boxes)) for j in range(i + 1, len(boxes)))
        if not apart:
            camera = frame_bounds(lower, upper, self.preset, up_axis=self.up_axis, aspect=width / height)
            ground = ground_layer(camera, width, height, self.level, self.up_axis, float(np.max(upper - lower)))
            return [(camera, ground)] * len(boxes)
        half = np.max([high - low for low, high in boxes], axis=0) / 2.0
        cameras = []
        for low, high in boxes:
            centre = (low + high) / 2.0
            camera = frame_bounds(centre - half, centre + half, self.preset, up_axis=self.up_axis,
                                  aspect=width / height)
            cameras.append((camera, ground_layer(camera, width, height, self.level, self.up_axis,
                                                 float(2.0 * half.max()))))
        return cameras

    def view(self, panel, m):
        """(camera, ground layer) that show ``panel`` (its index) at frame m."""
        if not self.follow:
            return self.cameras[panel]
        width, height = self.size
        centre = self.tracks[panel][m]
        camera = frame_bounds(centre + self.extent[0], centre + self.extent[1], self.preset, up_axis=self.up_axis,
                              aspect=width / height)
        return camera, ground_layer(camera, width, height, self.level, self.up_axis, self.cell)

    def __len__(self):
        return len(self.frames)

    def __getitem__(self, n):
        """Frame n: (rows·H, columns·W, 3) uint8."""
        width, height = self.size
        rows = -(-len(self.panels) // self.columns)
        out = np.full((rows * height, self.columns * width, 3), 255, np.uint8)
        m = int(self.frames[n])
        for k, panel in enumerate(self.panels):
            colors = None if panel.colors is None else panel.colors[m]
            camera, ground = self.view(k, m)
            image = render(panel.vertices[m], panel.faces, camera, width, height, smooth=self.smooth,
                           ground=ground, up_axis=self.up_axis, vertex_colors=colors)
            caption = panel.captions[m] if panel.captions else f"frame {m}"
            marked = panel.marked is not None and bool(panel.marked[m])
            image = _caption(image, f"{panel.title}\n{caption}" if panel.title else caption, marked)
            r, c = divmod(k, self.columns)
            out[r * height:(r + 1) * height, c * width:(c + 1) * width] = image
        return out

    def __iter__(self):
        return (self[n] for n in range(len(self)))


def preview_summary(output, frames, panels, size, seconds, fps, follow=False):
    """preview's summary (the --json object) and text lines: ``frames`` frames of ``panels``
    panels of ``size`` (width, height) rendered into ``output`` in ``seconds``, to play at ``fps``;
    ``follow``: the cameras followed the characters (:class:`Preview`)."""
    summary = {"output": output, "frames": int(frames), "panels": panels, "size": list(size),
               "seconds": round(seconds, 3), "frames_per_second": round(frames / max(seconds, 1e-9), 1),
               "fps": float(fps), "framing": "follow" if follow else "fixed"}
    return summary, [f"wrote {output}: {frames} frames of {panels} panel(s) at {size[0]}×{size[1]}, "
                     f"{summary['frames_per_second']} frames/s" + (", the camera following" if follow else "")]


def _caption(image, text, marked=False):
    """``text`` in the top-left corner (dark, or red when ``marked``), on a light box."""
    from PIL import Image, ImageDraw, ImageFont

    picture = Image.fromarray(image)
    draw = ImageDraw.Draw(picture)
    font = ImageFont.load_default()
    box = draw.multiline_textbbox((8, 6), text, font=font)
    draw.rectangle((box[0] - 4, box[1] - 3, box[2] + 4, box[3] + 3), fill=(255, 255, 255))
    draw.multiline_text((8, 6), text, fill=(200, 20, 20) if marked else (20, 20, 30), font=font)
    return np.asarray(picture)
