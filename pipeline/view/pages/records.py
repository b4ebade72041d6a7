"""What each page of ``skinsynth view`` shows, as plain records the command fills in (reading
files is ``cli/view.py``'s): :class:`PuppetView` (with a :class:`TrajectoryView` it plays),
:class:`SkinView`, :class:`SynthesisView`, :class:`SequenceView`. Arrays and callables only: no
server, no file."""

from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass
class TrajectoryView:
    """A control trajectory the puppet page plays (``view --controls``): controls (F, n_c, 3)
    world; fps; distances (F,) and nearest (F,) (rows of the training examples): each frame's
    extrapolation, ``scenes.extrapolation_distances`` computed once for every frame; name (the
    file, for the panel); a motion-capture take's markers (F, n_c, 3), aligned into the puppet's
    space, marker i on control i, with their labels (n_c,) and the take's start_time (seconds of
    frame 0); markers None for any other trajectory; vertices (F, V, 3) float32: every frame as
    ``play`` plays it (its skeleton beyond the examples, its torn frames mended), shown on the
    trajectory's frames (None: each predicted as shown)."""

    controls: np.ndarray
    fps: float
    distances: np.ndarray
    nearest: np.ndarray
    name: str = ""
    markers: np.ndarray = None
    labels: tuple = ()
    start_time: float = 0.0
    vertices: np.ndarray = None


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
    None for a skin without one; chains: {chain name: its first bone} where its chains are named
    (``leg_l`` at its thigh's joint)."""

    faces: np.ndarray
    examples: np.ndarray
    fit: Callable
    error_scale: float
    error_fraction: float
    fps: float
    up_axis: str
    contacts: tuple = None  # a graph file's ground contacts: (vertices (N,), offsets (P + 1,), planted (F, P))
    skeleton: Callable = None
    chains: dict = None


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
