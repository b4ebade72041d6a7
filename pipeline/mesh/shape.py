"""Whether a body keeps its shape: edge strain against what the capture itself shows (issue 62:
a synthesis's frames; issue 66: a puppet's beyond its examples, ``pipeline.puppet.jointed_play``).

Smooth motion and planted feet say nothing of the body's *shape*: a correction that moves two
neighbouring bones apart creases the skin between them, and acceleration or slide figures do not
see it. The measure is edge by edge, against the capture:

- an edge's **strain** in a frame is |l / l₀ − 1|, its length over its length at rest (the capture's
  first frame) less one;
- its **envelope** is the largest strain it shows in any frame of the capture and in the skin
  fit's playback of any capture frame (the fit's own error is not the synthesis's);
- an edge is **beyond** in an output frame when its strain exceeds its envelope by more than
  :data:`MARGIN` (a quarter of its rest length): far past anything the capture or its fit ever did
  to that edge, not a hair over it;
- a frame is **broken** when more than :data:`BROKEN_SHARE` (0.5 %) of its edges are beyond.

Why per edge and relative to the capture: an edge of a shoulder stretches by half its length in a
raised arm and an edge of a shin by a hundredth, so one threshold for every edge either misses a
torn shin or flags every raised arm; the capture's own strain is the character's own range of
motion, so the measure needs no tuning per character, scale or frame rate (a strain has no
units, and the envelope is over frames, whatever their spacing). Why the margin is a quarter: the
fit's playback of frames it never saw (a synthesis splices and merges them) strains an edge by a
few per cent beyond both envelopes (the shared captures' ``--no-contact`` syntheses: at most
0.3 % of a frame's edges beyond a margin of 0.25); a tear is a strain of the order of one.

Compiled over frames and edges (:func:`_strains`); a caller measures long animations in blocks of frames.
"""

from dataclasses import dataclass

import numba
import numpy as np

from .geometry import mesh_edges

#: How far past its envelope (a share of its rest length) an edge's strain must be to be beyond.
MARGIN = 0.25
#: Share of a frame's edges beyond that makes it broken.
BROKEN_SHARE = 0.005


@dataclass
class ShapeEnvelope:
    """What an output frame's shape is measured against: edges (E, 2) vertex ids, rest_lengths
    (E,) at the capture's first frame, envelope (E,) each edge's largest strain in the capture
    and in the fit's playback of it, margin and broken_share (:data:`MARGIN`,
    :data:`BROKEN_SHARE`)."""

    edges: np.ndarray
    rest_lengths: np.ndarray
    envelope: np.ndarray
    margin: float = MARGIN
    broken_share: float = BROKEN_SHARE

    def beyond(self, vertices):
        """(M, E) bool: which edges are beyond in each frame of vertices (M, V, 3)."""
        return edge_strain(vertices, self.edges, self.rest_lengths) > self.envelope + self.margin

    def beyond_share(self, vertices):
        """(M,): the share of each frame's edges beyond (vertices (M, V, 3))."""
        return self.beyond(vertices).mean(axis=1)

    def broken(self, vertices):
        """(M,) bool: which frames of vertices (M, V, 3) are broken."""
        return self.beyond_share(vertices) > self.broken_share


def edge_strain(vertices, edges, rest_lengths):
    """(M, E): |l / l₀ − 1| of each edge (E, 2) in each frame of vertices (M, V, 3) (or (V, 3): one
    frame); rest_lengths (E,) l₀ (an edge of length 0 at rest counts its length over the mean
    edge's). Compiled (:func:`_strains`): numpy's gathers of both ends took 0.6 s of a synthesis's
    seam check on the horse (25,000 edges, 300 frames)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    if vertices.ndim == 2:
        vertices = vertices[None]
    rest = np.asarray(rest_lengths, dtype=np.float64)
    floor = max(float(rest.mean()) if rest.size else 1.0, 1e-300)
    out = np.empty((vertices.shape[0], len(edges)))
    _strains(np.ascontiguousarray(vertices), np.ascontiguousarray(edges, dtype=np.int64),
             np.where(rest > 0.0, rest, floor), (rest > 0.0).astype(np.float64), out)
    return out


@numba.njit(cache=True, nogil=True)
def _strains(vertices, edges, lengths, one, out):
    """out (M, E) = |‖v_a − v_b‖ / lengths − one| for each edge (a, b) of edges (E, 2) in each frame
    of vertices (M, V, 3)."""
    for m in range(vertices.shape[0]):
        for e in range(edges.shape[0]):
            a, b = edges[e, 0], edges[e, 1]
            x = vertices[m, a, 0] - vertices[m, b, 0]
            y = vertices[m, a, 1] - vertices[m, b, 1]
            z = vertices[m, a, 2] - vertices[m, b, 2]
            out[m, e] = abs(np.sqrt(x * x + y * y + z * z) / lengths[e] - one[e])


def shape_envelope(examples, faces, playback=(), block=64, margin=MARGIN, broken_share=BROKEN_SHARE):
    """The :class:`ShapeEnvelope` of a capture: examples (F, V, 3) its frames (the first is the
    rest), faces (T, 3); playback: further frames whose strain the envelope takes in (the fit's
    playback of the capture: an iterable of (M, V, 3) blocks, or one array)."""
    examples = np.asarray(examples)
    edges = mesh_edges(np.asarray(faces, dtype=np.int64))
    rest_lengths = np.linalg.norm(examples[0, edges[:, 0]].astype(np.float64) - examples[0, edges[:, 1]], axis=-1)
    envelope = np.zeros(len(edges))
    blocks = [examples[s:s + block] for s in range(0, examples.shape[0], block)]
    if isinstance(playback, np.ndarray):
        playback = [playback[s:s + block] for s in range(0, playback.shape[0], block)]
    for frames in (*blocks, *playback):
        if len(frames):
            envelope = np.maximum(envelope, edge_strain(frames, edges, rest_lengths).max(axis=0))
    return ShapeEnvelope(edges=edges, rest_lengths=rest_lengths, envelope=envelope, margin=margin,
                         broken_share=broken_share)
