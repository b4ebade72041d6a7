"""What ``skinsynth view`` shows, as pure functions on arrays (no server, no files).

A web viewer's mesh has one colour, so a mesh coloured per vertex (an error map, components) is
drawn as one part per colour: :func:`split_by_key` cuts the faces (T, 3) into parts, each with
its own vertex ids and local faces. The rest is what the colours mean:

- skin fit: each face's error level, the mean of its corners' errors quantised into ``steps``
  shades from grey (exact) to red (``scale`` or more), the colours of ``preview --compare``;
- synthesis: each vertex's bone component (the component holding most of its weight), each
  face's (most of its corners'), a colour per component, and the frames where a component's
  source jumps (a seam);
- skin fit of a graph file: the vertices of the input's ground-contact patches planted at the
  shown frame (build-graph's ``/graph/contacts``), drawn in :data:`CONTACT_COLOR`;
- skin fit with a skeleton (``fit-skin --skeleton``): its joints where the bones carry them at the
  shown frame, and a line along each bone from its parent's joint to its own
  (:func:`skeleton_lines`), in :data:`SKELETON_COLOR`;
- puppet: how far the controls lie from the nearest training example (the extrapolation
  indicator), in ``evaluate``'s unit (the largest side of the rest bounding box), and a colour
  for it; a drag session resampled at the file's frame rate (the recorded trajectory).
"""

import numpy as np

from ..rig.extrapolation import (extrapolation_distances, extrapolation_report,  # noqa: F401 (view's public names)
                                 extrapolation_scale)
from .preview import ERROR_HIGH, ERROR_LOW  # grey where exact, red at the scale

#: Component colours (a qualitative palette, repeated past eight components), RGB 0–255.
PALETTE = np.array([[76, 114, 176], [221, 132, 82], [85, 168, 104], [196, 78, 82], [129, 114, 179],
                    [147, 120, 96], [218, 139, 195], [140, 140, 140]], dtype=np.uint8)
#: A component at a seam frame: drawn in this colour (preview marks seams red too).
SEAM_COLOR = np.array([230, 30, 30], dtype=np.uint8)
#: The vertices of a ground-contact patch planted at the shown input frame.
CONTACT_COLOR = np.array([20, 200, 230], dtype=np.uint8)
#: A skin's skeleton drawn over its reconstruction: joints as points, bones as lines.
SKELETON_COLOR = np.array([250, 200, 30], dtype=np.uint8)
#: Extrapolation indicator: green inside the training examples, amber at the scale, red at twice it.
INSIDE, EDGE, OUTSIDE = (np.array(c, dtype=float) for c in ([40, 170, 80], [240, 170, 30], [220, 40, 40]))


def split_by_key(faces, keys):
    """One part per distinct key of faces (T, 3) with keys (T,) ints: [(key, vertex_ids (n,),
    local_faces (t, 3))], keys ascending, vertex_ids ascending, local_faces indexing vertex_ids
    (``vertex_ids[local_faces]`` are the part's faces in the whole mesh's ids, in their order)."""
    faces, keys = np.asarray(faces), np.asarray(keys)
    parts = []
    for key in np.unique(keys):
        chosen = faces[keys == key]
        ids, local = np.unique(chosen, return_inverse=True)
        parts.append((int(key), ids, local.reshape(chosen.shape).astype(np.uint32)))
    return parts


def error_levels(errors, faces, scale, steps):
    """Each face's error level (T,) in 0..steps−1: the mean of its corners' errors (V,) over
    ``scale``, 0 exact, steps−1 at ``scale`` or more (rounded to the nearest shade)."""
    if steps < 2:
        raise ValueError(f"steps must be at least 2 (got {steps})")
    amount = np.clip(np.asarray(errors)[np.asarray(faces)].mean(axis=1) / scale, 0.0, 1.0)
    return np.rint(amount * (steps - 1)).astype(np.int64)


def level_colors(steps):
    """The colours (steps, 3) uint8 of the error levels, grey to red as ``preview --compare``."""
    amount = np.linspace(0.0, 1.0, steps)[:, None]
    return np.rint(((1.0 - amount) * ERROR_LOW + amount * ERROR_HIGH) * 255).astype(np.uint8)


def vertex_errors(fitted, truth):
    """Each vertex's distance (V,) between fitted (V, 3) and truth (V, 3)."""
    return np.linalg.norm(np.asarray(fitted, dtype=float) - np.asarray(truth, dtype=float), axis=-1)


def vertex_components(bone_indices, bone_weights, components):
    """The component (V,) of each vertex: the one whose bones carry most of its weight (ties: the
    lower number). bone_indices, bone_weights (V, K); components: a list of bone-id arrays."""
    bone_indices, bone_weights = np.asarray(bone_indices), np.asarray(bone_weights, dtype=float)
    bones = max(int(bone_indices.max()) + 1, max(int(np.max(c)) + 1 for c in components))
    owner = np.full(bones, -1)
    for number, component in enumerate(components):
        owner[np.asarray(component)] = number
    if (owner[np.unique(bone_indices[bone_weights > 0])] < 0).any():
        raise ValueError("a bone with weight belongs to no component")
    totals = np.zeros((len(bone_indices), len(components)))
    rows = np.repeat(np.arange(len(bone_indices)), bone_indices.shape[1])
    np.add.at(totals, (rows, owner[bone_indices].ravel()), np.where(bone_weights > 0, bone_weights, 0.0).ravel())
    return np.argmax(totals, axis=1)


def face_components(faces, components_of_vertices):
    """Each face's component (T,): the one most of its three corners belong to (all different:
    the lowest)."""
    corners = np.asarray(components_of_vertices)[np.asarray(faces)]  # (T, 3)
    a, b, c = corners.T
    return np.where((a == b) | (a == c), a, np.where(b == c, b, corners.min(axis=1)))


def component_colors(count):
    """A colour (count, 3) uint8 per component."""
    return PALETTE[np.arange(count) % len(PALETTE)]


def seam_frames(sources, clips=None):
    """sources (C, M): the input frame each component plays at each output frame -> (C, M) bool,
    True where a component's source does not play on from its previous one (a transition): not
    the frame after it, or, with ``clips`` (the input's :class:`~skinsynth.pipeline.inputs.clips.Clips`),
    the first frame of a clip (:meth:`Clips.seams`: one clip's last frame then the next one's
    first is a seam too). None: one clip."""
    sources = np.asarray(sources)
    if clips is not None:
        return clips.seams(sources)
    seams = np.zeros(sources.shape, dtype=bool)
    seams[:, 1:] = sources[:, 1:] != sources[:, :-1] + 1
    return seams


def extrapolation(controls, training, unit):
    """(distance, nearest) of controls (n_c, 3) from training (n_p, n_c, 3): one frame of
    :func:`extrapolation_distances`."""
    distances, nearest = extrapolation_distances(np.asarray(controls)[None], training, unit)
    return float(distances[0]), int(nearest[0])


def extrapolation_color(distance, scale):
    """The indicator's colour (3,) uint8: green at 0, amber at ``scale``, red at twice it or more,
    linear in between."""
    amount = float(np.clip(distance / scale if scale > 0 else np.inf, 0.0, 2.0))
    low, high = (INSIDE, EDGE) if amount <= 1.0 else (EDGE, OUTSIDE)
    mix = amount if amount <= 1.0 else amount - 1.0
    return np.rint(low + mix * (high - low)).astype(np.uint8)


def resample_session(times, controls, fps, end=None):
    """A drag session as a trajectory at ``fps``: moves at times (n,) seconds (ascending, the
    first the start of the recording) with controls (n, n_c, 3) -> (F, n_c, 3), frame k holding
    the controls of the last move at or before times[0] + k / fps, frames up to ``end`` (default:
    the last move's time). The page showed each move's mesh until the next move, so frame k plays
    what the page showed at that time."""
    times, controls = np.asarray(times, dtype=float), np.asarray(controls, dtype=float)
    if len(times) == 0:
        raise ValueError("a session needs at least one state")
    end = times[-1] if end is None else max(float(end), times[-1])
    # a frame's time within a microsecond of a move's counts as after it (rounding in k / fps)
    count = int(np.floor((end - times[0]) * fps + 1e-6)) + 1
    at = times[0] + np.arange(count) / fps
    index = np.searchsorted(times, at + 1e-6, side="right") - 1
    return controls[np.clip(index, 0, len(times) - 1)]


def side_by_side(rest_vertices, gap=0.2):
    """The offset (3,) that places a second copy of a mesh (rest_vertices (V, 3)) beside the
    first: along X (horizontal whether Y or Z is up), the rest pose's width plus ``gap`` of it."""
    rest = np.asarray(rest_vertices, dtype=float)
    offset = np.zeros(3)
    offset[0] = (1.0 + gap) * float(np.ptp(rest[:, 0])) or 1.0
    return offset


def planted_vertices(vertices, offsets, planted, frame):
    """The ids (n,) ascending of the vertices of every contact patch planted at input frame
    ``frame``: patches p = vertices[offsets[p]:offsets[p + 1]] (/graph/contacts), planted (F, P)
    bool; none (an empty array) at a frame where no patch is planted."""
    vertices, offsets = np.asarray(vertices, dtype=np.int64), np.asarray(offsets, dtype=np.int64)
    down = np.flatnonzero(np.asarray(planted, dtype=bool)[frame])
    if down.size == 0:
        return np.zeros(0, np.int64)
    return np.unique(np.concatenate([vertices[offsets[p]:offsets[p + 1]] for p in down]))


def skeleton_lines(rotations, translations, joints, parents, jointed):
    """A skeleton at one frame: (points (B, 3), each bone's joint where its bone carries it,
    R_j q_j + t_j; segments (S, 2, 3), for each jointed bone a line from its parent's joint to its
    own: the parent bone between its two joints). rotations (B, 3, 3), translations (B, 3): the
    frame's LBS transforms; joints (B, 3) the rest joints q_j; parents (B,) (−1 for the root bone);
    jointed (B,) bool: the bones drawn from their parent (a fixed or a sliding joint; a free bone,
    hanging from the root with no neighbour, gets no line)."""
    points = np.einsum("bij,bj->bi", np.asarray(rotations, dtype=float), np.asarray(joints, dtype=float)) + translations
    parents = np.asarray(parents, dtype=np.int64)
    lined = np.flatnonzero(np.asarray(jointed, dtype=bool) & (parents >= 0))
    return points, np.stack([points[parents[lined]], points[lined]], axis=1)
