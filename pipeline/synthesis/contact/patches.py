"""Ground contacts found on the input (issue 35, part 1): per input frame, which patches of the
mesh rest on the ground.

The ground, per clip: a low percentile of the clip's per-frame lowest heights along the up axis
(:func:`...mesh.contact_measures.clip_ground`, the ground the feet are measured against), not a fixed axis value, so a clip shot a little above or below 0, or
one whose lowest point dips through the floor for a frame, still finds its floor.

A vertex is *in contact* at a frame when it is near that ground and slow:

- it **enters** contact where its height above the ground is at most ``height`` × H and its speed
  at most ``speed`` × H per second (H: the character's height, the largest extent along up of an
  input frame);
- it **stays** in contact while both stay within ``release`` × those thresholds (hysteresis: a
  foot that wobbles about the threshold does not flicker);
- speeds are central differences within a clip (one-sided at its first and last frames), never
  across a clip's end, and the state starts afresh at each clip's first frame.

The vertices ever in contact are grouped into *patches*: connected parts of the mesh (its faces'
edges between those vertices; a hoof, a sole, a side the body lies on). A patch is *planted* at a
frame where any of its vertices is in contact; its plants (runs of planted frames within a clip)
shorter than ``min_duration`` seconds are dropped, and a patch left with none is no patch.

A ground bears the body's weight, so it bears it often: a clip's plants are kept only when, in that
clip, some patch is planted in at least ``min_support`` of its frames (else the clip has none). A part
that merely pauses at its lowest (a hanging curtain's hem at the bottom of its swing: 8 % of the
vellum sheet's frames) is no ground contact; feet and hooves are planted far more often (the
samba 100 %, the horse's gallop, with its flight, 17 %).

A capture that never rests on a ground (a swinging bar, a falling cloth) finds no patch and
build-graph stores nothing (its graph file stays byte-identical). Pure numpy and scipy: one
pass over the frames (vectorised over the candidate vertices) for the hysteresis, the rest whole
arrays.
"""

from dataclasses import dataclass

import numpy as np

from ...inputs.clips import Clips
from ...errors import OptionError
from ...mesh.geometry import vertex_normals
from ...mesh.contact_measures import clip_ground
from ..graph_options import GraphOptions

_DEFAULT = GraphOptions()

#: Least |cos| between a contact vertex's normal and the up axis: a surface that faces the ground (a
#: sole, a hoof, a side lying down), not one that meets it edge-on (a hanging sheet's hem).
FACING = 0.5


@dataclass
class ContactPatches:
    """vertices (N,) int64, the vertices of every patch, patch by patch (increasing within one);
    offsets (P + 1,) int64: patch p is vertices[offsets[p]:offsets[p + 1]]; planted (F, P) bool per
    input frame; ground (C,) float64, each clip's ground height along up; height (H, the
    thresholds' unit); options ({name: value} the thresholds found them with)."""

    vertices: np.ndarray
    offsets: np.ndarray
    planted: np.ndarray
    ground: np.ndarray
    height: float
    options: dict

    @property
    def count(self):
        return int(self.offsets.size - 1)

    def patch(self, p):
        return patch_vertices(self)[p]

    def plants(self, clips=None):
        """[(patch, first, last)] every plant (inclusive global frames), by patch then frame."""
        clips = clips or Clips.single(self.planted.shape[0])
        return [(p, a, b) for p in range(self.count) for a, b in runs(self.planted[:, p], clips)]


def patch_vertices(contacts):
    """[vertex ids (n_p,)] of every patch of ``contacts`` (a :class:`ContactPatches`, or the graph
    file's record of one: anything with vertices, offsets and count)."""
    return [contacts.vertices[contacts.offsets[p]:contacts.offsets[p + 1]] for p in range(contacts.count)]


def validate_contact_options(height, speed, release, min_duration, min_support=_DEFAULT.contact_min_support):
    for name, value in (("--contact-height", height), ("--contact-speed", speed)):
        if not 0.0 < value < np.inf:
            raise OptionError(f"{name} must be positive and finite (got {value})")
    if not 1.0 <= release < np.inf:
        raise OptionError(f"--contact-release must be at least 1 (got {release})")
    if not 0.0 <= min_duration < np.inf:
        raise OptionError(f"--contact-min-duration must be finite and at least 0 seconds (got {min_duration})")
    if not 0.0 <= min_support <= 1.0:
        raise OptionError(f"--contact-min-support must be a share of the frames, 0 to 1 (got {min_support})")


def runs(state, clips):
    """[(first, last)] inclusive runs of True in state (F,), split at every clip's start."""
    state = np.asarray(state, bool)
    starts = state & (~np.concatenate([[False], state[:-1]]) | clips.first_frames())
    ends = state & (~np.concatenate([state[1:], [False]]) | clips.last_frames())
    return list(zip(np.flatnonzero(starts).tolist(), np.flatnonzero(ends).tolist()))


def largest_extent(vertices, up_axis):
    """H: the largest extent along up of any frame of vertices (F, V, 3) (1.0 if they are flat)."""
    up = np.asarray(vertices)[..., up_axis]
    return float((up.max(axis=1) - up.min(axis=1)).max()) or 1.0


def find_contacts(vertices, faces, fps, up_axis=1, clips=None, height=_DEFAULT.contact_height,
                  speed=_DEFAULT.contact_speed, release=_DEFAULT.contact_release,
                  min_duration=_DEFAULT.contact_min_duration, min_support=_DEFAULT.contact_min_support):
    """The :class:`ContactPatches` of the input frames vertices (F, V, 3) of a mesh with faces
    (T, 3) at ``fps``; clips: the :class:`.clips.Clips` of the F frames (None: one clip). height:
    share of H above the ground a vertex enters contact within; speed: share of H per second it
    enters below; release (≥ 1): the factor on both that it leaves contact beyond; min_duration:
    the shortest plant kept, in seconds; min_support: the least share (0 … 1) of a clip's frames in
    which some patch must be planted, or the clip keeps no plant (a ground bears the body often; module notes)."""
    validate_contact_options(height, speed, release, min_duration, min_support)
    vertices = np.asarray(vertices, dtype=np.float64)
    frames = vertices.shape[0]
    clips = clips or Clips.single(frames)
    starts = clips.starts
    options = dict(height=float(height), speed=float(speed), release=float(release),
                   min_duration=float(min_duration), min_support=float(min_support))
    H = largest_extent(vertices, up_axis)
    heights = vertices[..., up_axis]
    ground = np.array([clip_ground(vertices[a:b], up_axis) for a, b in zip(starts[:-1], starts[1:])])
    above = heights - np.repeat(ground, clips.frames)[:, None]  # (F, V)
    candidates = np.flatnonzero((above <= release * height * H).any(axis=0))
    empty = ContactPatches(vertices=np.zeros(0, np.int64), offsets=np.zeros(1, np.int64),
                           planted=np.zeros((frames, 0), bool), ground=ground, height=H, options=options)
    if candidates.size == 0:
        return empty
    above = above[:, candidates]
    moving = np.full(above.shape, np.inf)  # speed per second; a clip of one frame has none (never slow)
    belts = np.zeros((len(clips), 3))
    for c, (a, b) in enumerate(zip(starts[:-1], starts[1:])):
        if b - a >= 2:
            step = np.gradient(vertices[a:b, candidates], axis=0) * fps
            step[..., up_axis] = 0.0  # the slide: a planted foot may bob within the height band
            near = above[a:b] <= height * H
            if near.any():  # the ground's own travel: 0 under a capture that travels, the belt's under a treadmill
                belts[c] = np.median(step[near], axis=0)
            moving[a:b] = np.linalg.norm(step - belts[c], axis=-1)
    flat = np.abs(_vertex_normals(vertices, faces, candidates)[..., up_axis]) >= FACING
    enter = (above <= height * H) & (moving <= speed * H) & flat
    stay = (above <= release * height * H) & (moving <= release * speed * H) & flat
    contact = np.zeros_like(enter)
    first = clips.first_frames()
    state = np.zeros(candidates.size, bool)
    for f in range(frames):  # hysteresis: one step per frame, every vertex at once
        state = enter[f] if first[f] else np.where(state, stay[f], enter[f])
        contact[f] = state
    touched = contact.any(axis=0)
    if not touched.any():
        return empty
    members = candidates[touched]
    contact = contact[:, touched]
    labels = _mesh_parts(faces, members, vertices.shape[1])
    parts = labels.max() + 1
    planted = np.zeros((frames, parts), bool)
    for p in range(parts):  # few patches: any of a patch's vertices in contact
        planted[:, p] = contact[:, labels == p].any(axis=1)
    shortest = max(1, int(np.ceil(min_duration * fps - 1e-9)))
    for p in range(parts):
        for a, b in runs(planted[:, p], clips):
            if b - a + 1 < shortest:
                planted[a:b + 1, p] = False
    for a, b in zip(starts[:-1], starts[1:]):  # a ground bears weight often: a pause at the lowest is no plant
        if planted[a:b].any(axis=1).mean() < min_support:
            planted[a:b] = False
    kept = np.flatnonzero(planted.any(axis=0))
    if kept.size == 0:
        return empty
    groups = [members[labels == p] for p in kept]
    return ContactPatches(vertices=np.concatenate(groups).astype(np.int64),
                          offsets=np.concatenate([[0], np.cumsum([g.size for g in groups])]).astype(np.int64),
                          planted=planted[:, kept], ground=ground, height=H, options=options)


def _mesh_parts(faces, members, count):
    """Connected parts of the mesh restricted to the vertices ``members`` (sorted ids): a label
    (0 … parts − 1) per member, parts numbered by their smallest vertex."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    faces = np.asarray(faces, dtype=np.int64)
    local = np.full(count, -1, np.int64)
    local[members] = np.arange(members.size)
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]).reshape(-1, 2)
    edges = local[edges]
    edges = edges[(edges >= 0).all(axis=1)]
    n = members.size
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[1].astype(np.int64)


def _vertex_normals(vertices, faces, members):
    """Unit area-weighted normals (F, N, 3) of the vertices ``members`` (sorted ids) in every
    frame of vertices (F, V, 3): :func:`~skinsynth.pipeline.mesh.geometry.vertex_normals` of the part of
    the mesh made of the faces that touch them (a member's normal depends on those faces alone)."""
    faces = np.asarray(faces, dtype=np.int64)
    inside = np.zeros(vertices.shape[1], bool)
    inside[members] = True
    touching = faces[inside[faces].any(axis=1)]
    used = np.unique(touching)
    normals = vertex_normals(vertices[:, used], np.searchsorted(used, touching))
    return normals[:, np.searchsorted(used, members)]