"""Motion graph over the frames of one clip (or several clips of one character), random and
constrained walks (Zheng §3.4).

Walk semantics (fixed by the team). An input clip has F frames. A candidate transition (i, j)
(:func:`.transitions.candidate_transitions`) means: after playing frame i, frame j is identified
with frame i and playback continues at j + 1. The frame graph therefore has the edges
``i → i+1`` (playback, i < F−1) and ``i → j+1`` for each transition (i, j) with j + 1 < F. j
may be −1, the virtual frame before the clip's start (:mod:`.transitions`, the wrap): (i, −1)
continues at frame 0, the edge ``i → 0``, and it is the only way a walk reaches frame 0 other
than by starting there (a clip of one cycle loops by (F−1, −1)). An output animation of M
frames is ``source (M,)``: the input frame shown at each output frame, consecutive entries
joined by an edge. Seams are the output indices k with ``source[k] ≠ source[k−1] + 1``; the
transition used there is ``(source[k−1], source[k] − 1)`` (j = −1 where source[k] = 0).

Several clips (:class:`.clips.Clips`, ``clips=`` everywhere here; None is one clip, the graph
above unchanged): the F frames are the clips in order, in one numbering. Playback ``i → i+1``
exists only inside a clip (a clip's last frame plays on nowhere: walks leave it by a transition
or end there); a transition (i, j) enters ``Clips.targets(j)``: j + 1 for j ≥ 0 (j never a
clip's last frame, :meth:`.clips.Clips.valid_j`), the first frame of clip c for j = −(c+1); a
seam is :meth:`.clips.Clips.seams` (also a step from one clip's last frame onto the next clip's
first, which is never playback), its transition ``(source[k−1], Clips.transition_j(source[k]))``.
Edges are sorted by (i, frame entered), which for one clip is (i, j): the same walks per seed.

Contents:

- :class:`MotionGraph`: the graph, forbidden frames removed, and the *usable* frames (those from
  which an arbitrarily long walk exists), as CSR arrays.
- :func:`random_walks`: many walks at once, vectorised over walks (a loop over output frames).
- :func:`constrained_walks`: targeted frames (Zheng §3.4: input frame f at output time T), by
  exact-length reachability between consecutive targets.
- :func:`overlap`, :func:`diversity_filter`: Zheng's "compare the current path with existing
  results" test, as a greedy filter.
- :func:`seams`: seam indices and the transitions used, per walk.

Choices the paper leaves open, made here:

- Only played frames matter: a transition (i, j) plays i then j + 1; frame j itself is never
  shown, so forbidding j does not remove the transition (forbidding i or j + 1 does). Duplicate
  transitions and (i, i) (= playback) are dropped; (i, j) with j = F − 1 has no edge (playback
  would continue past the clip's end).
- Walk policy: at each step a walk that has played at least ``min_segment`` frames since its
  last seam (the first output frame starts a segment) takes a transition with probability
  ``transition_probability`` if one is allowed, uniformly among the allowed ones; otherwise it
  plays on, unless playing on is not allowed, in which case it must take a transition.
- Loops avoided (``fresh`` output frames, synthesize: the 2 s of a stuck walk,
  :mod:`.walk_measures`; 0: off): a walk taking a transition chooses, uniformly, among the
  allowed ones that enter a frame it has not played in the last ``fresh`` frames, or, where it has
  played all of them, among those whose frame it played longest ago; and a walk that replays a
  loop shorter than ``fresh`` a second time in a row (every frame played again ``period`` frames
  after it was last, for two periods) takes the first transition out of it (into a frame older
  than the loop) instead of waiting for the ``transition_probability`` draw, once its segment
  has played half of ``min_segment`` (the spacing build-graph keeps between transitions): a
  trap's only exits can lie just after its entry (the samba's arm component looped frames
  140–172, entered at 140 and 150, its exits at 141 and 150), so such a segment may be as short
  as half of ``min_segment``, where a stuck walk would otherwise replay one loop to its end. So a
  loop is replayed at most a third time, and that only where no transition leads out of it.
  Without this, on the 48-frame horse gallop 15 of 16 walks repeated a loop under 2 s more than
  three times in a row: the clip's last frame has one way back, a cycle earlier, and walks left
  that cycle by a 10 % draw at three frames of it.
- Traps as endings (with ``fresh`` > 0, free-ended walks not already in one, e.g. after a target
  inside one): a state from which endless walks exist
  but none comes back to the largest strongly connected part of the (frame, segment position)
  graph (:meth:`MotionGraph.trapped`) is entered only within a walk's last ``fresh`` steps, and
  walks start where they can reach that part (:meth:`MotionGraph.start_frames`); the exact-length
  sets enforce it like any other constraint (:func:`_backward_sets`' ``early``). Motion graphs
  keep walks on their largest strongly connected part (Kovar et al. 2002 prune the rest); a trap's
  frames are kept here as endings, as dead-end tails are. On the samba's arm component frames
  127–172 are poses no earlier frame comes within 10 T_c of (the cheapest way back costs 10.5
  T_c), and the one way back the frame graph showed (141 → 113, then 115 → 70) needs a two-frame
  segment: walks past frame 105 never came back, and long walks played a median 55 of the
  component's 173 frames (115 with this rule). Tie-breaks and sizes as
  :func:`recurrent_frames`; with no trap, walks are bit for bit what they were.
- "Allowed" moves come from exact-length reachability: a move is allowed only if the walk can
  still be completed from the new state within the remaining output frames (and, for a
  constrained interval, end on its target at its time). The search runs on states
  (frame, frames played in the current segment, capped at ``min_segment``), so ``min_segment``
  is a hard constraint whenever it can be met (*strict* walks); a walk in a state from which it
  cannot be met (e.g. it starts two frames before a dead end) follows the plain frame graph
  (*relaxed*), still preferring to play on while its segment is short, and becomes strict again
  as soon as its state allows. So segments shorter than ``min_segment`` occur only where no walk
  can avoid them.
- This is not uniform sampling over paths: within the set of states that lie on some valid
  path the walk makes the same local random choices as an unconstrained walk. Zheng's
  multi-start bidirectional search is realised as backward sets from the end (which decide the
  moves) and forward sets from the start (which only serve to explain failures: at which output
  times the target *could* be reached).
- :func:`random_walks` starts inside the usable frames and may end in a dead-end tail.
  :func:`constrained_walks` by default may
  pass through non-forbidden frames outside the usable set (dead-end tails, e.g. the clip's
  last frames) when the exact-length search shows the walk still completes, so a target can be
  e.g. the clip's last frame; ``usable_only=True`` restricts it to the usable frames too.
- An interval with a free start (output frames before the first target) starts uniformly among
  the frames from which the first target can be reached on time (preferring strict ones); an
  interval with a free end (after the last target) is a random walk of the remaining length.
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..inputs.clips import Clips
from ..errors import ClipError, OptionError
from ..runtime.rows import unique_rows

NO_CYCLE_MESSAGE = ("the clip has no repeated states at this threshold: no transition leads back; "
                    "run build-graph again with a larger --threshold-scale")


@dataclass
class _Moves:
    """Frame-level moves of the non-forbidden graph: playback ``play_ok (F,)`` (i + 1 in i's
    clip, both allowed) and transitions in CSR form ``t_indptr (F+1,)``, ``t_target (E,)`` the
    frame entered (j + 1, or the first frame of clip −j − 1 for j < 0), ``t_pairs (E, 2)`` = (i, j),
    sorted by (i, frame entered) (for one clip, by (i, j))."""

    play_ok: np.ndarray
    t_indptr: np.ndarray
    t_target: np.ndarray
    t_pairs: np.ndarray


def default_min_segment(fps):
    """Half a second of frames (at least 2): the shortest stretch between seams that still reads
    as motion rather than a jitter of splices."""
    return max(2, int(round(0.5 * float(fps))))


class MotionGraph:
    """The frame graph of one clip (see the module docstring for the walk semantics).

    ``MotionGraph(frames, transitions, forbidden=None, clips=None)``: frames F; transitions
    (T, 2) int pairs (i, j) (candidate transitions), i in 0..F−1 and j in −C..F−1 (−(c+1):
    continue at the first frame of clip c; with one clip, −1: continue at frame 0); forbidden
    (F,) bool, frames never to be shown (removed with their edges); clips: the
    :class:`.clips.Clips` of the F frames (None: one clip), playback f → f + 1 only inside a clip
    and a pair whose j does not play on in its clip (:meth:`.clips.Clips.valid_j`, e.g. a clip's
    last frame) dropped. Raises :class:`OptionError` when no arbitrarily long walk exists.

    Attributes: ``frames`` F; ``transitions`` (T', 2) the distinct transitions whose played
    frames i, j + 1 are in range and not forbidden, sorted; ``forbidden`` (F,) bool;
    ``usable`` (F,) bool, the frames from which an arbitrarily long walk exists (they can reach
    a cycle); ``dead_ends`` (F,) bool, non-forbidden frames that are not usable;
    ``indptr (F+1,)``, ``indices`` the successors of each frame in the usable subgraph (CSR,
    empty rows for unusable frames; each usable frame has at least one successor); ``clips``
    (as given, None for one clip).
    """

    def __init__(self, frames, transitions, forbidden=None, clips=None):
        frames = int(frames)
        if frames < 1:
            raise OptionError(f"a motion graph needs at least one frame (got {frames})")
        if clips is not None and clips.total != frames:
            raise ValueError(f"the clips hold {clips.total} frames, the graph {frames}")
        layout = Clips.single(frames) if clips is None else clips
        pairs = np.asarray(transitions, dtype=np.int64).reshape(-1, 2) if np.size(transitions) else \
            np.zeros((0, 2), np.int64)
        if pairs.size and (pairs[:, 0].min() < 0 or pairs[:, 1].min() < -len(layout) or pairs.max() >= frames):
            virtual = "(−1: continue at frame 0)" if len(layout) == 1 else \
                "(−(c+1): continue at the first frame of clip c)"
            raise OptionError(f"transitions (i, j) must pair a frame i in 0..{frames - 1} with j in "
                              f"−{len(layout)}..{frames - 1} {virtual}")
        if forbidden is None:
            forbidden = np.zeros(frames, bool)
        forbidden = np.asarray(forbidden, dtype=bool)
        if forbidden.shape != (frames,):
            raise ValueError(f"forbidden must have shape ({frames},), got {forbidden.shape}")
        self.frames = frames
        self.clips = clips
        self.forbidden = forbidden.copy()
        allowed = ~forbidden

        # transitions i → (frame entered) between shown frames; drop (i, i) (= playback) and any
        # j that does not play on in its clip (one clip: j = F−1)
        pairs = unique_rows(pairs)
        keep = layout.valid_j(pairs[:, 1]) & (pairs[:, 0] != pairs[:, 1])
        pairs = pairs[keep]
        pairs = pairs[allowed[pairs[:, 0]] & allowed[layout.targets(pairs[:, 1])]]
        entered = layout.targets(pairs[:, 1])
        order = np.lexsort((entered, pairs[:, 0]))  # by (i, frame entered): np.unique's (i, j) for one clip
        pairs, entered = pairs[order], entered[order]
        self.transitions = pairs
        self._moves = _Moves(
            play_ok=np.concatenate([allowed[:-1] & allowed[1:] & layout.plays_on()[:-1], [False]]),
            t_indptr=np.searchsorted(pairs[:, 0], np.arange(frames + 1)).astype(np.int64),
            t_target=entered,
            t_pairs=pairs)

        src, dst = self._edges(allowed)
        self.usable = _infinite_walk_nodes(frames, src, dst) & allowed
        self.dead_ends = allowed & ~self.usable
        if not allowed.any():
            raise OptionError(f"every one of the clip's {frames} frames collides with the obstacles or the ground "
                              "plane: there is nothing left to play")
        if not self.usable.any():
            detail = f" ({frames} frames, {len(pairs)} transitions"
            if forbidden.any():
                detail += f", {int(forbidden.sum())} forbidden frames"
            raise ClipError(NO_CYCLE_MESSAGE + detail + ")")
        src, dst = self._edges(self.usable)
        self.indptr, self.indices = _csr(frames, src, dst)
        self._state_cache = {}
        self._backward_cache = {}

    @classmethod
    def from_transitions(cls, result, forbidden=None, clips=None):
        """From a :class:`.transitions.Transitions` result (F from its D, its candidate pairs;
        clips: given, else the result's own, if it has any)."""
        clips = getattr(result, "clips", None) if clips is None else clips
        return cls(result.D.shape[0], result.pairs, forbidden, clips)

    def frame_name(self, frame):
        """How messages name an input frame: ``CLIP:FRAME`` with several clips, else its number."""
        return str(int(frame)) if self.clips is None else self.clips.label(frame)

    @property
    def usable_count(self):
        """How many frames are usable."""
        return int(self.usable.sum())

    @property
    def usable_frames(self):
        """The usable frame ids, increasing."""
        return np.flatnonzero(self.usable)

    def start_frames(self, segment=1, fresh=0):
        """Where :func:`random_walks` start: the usable frames; when ``fresh`` > 0 (walks avoid loops
        and play traps as endings only) and the graph has a trap (:meth:`trapped`) for strict walks
        (``segment`` = min_segment) or in the frame graph, only those from which a strict walk
        starting there reaches the largest part, unless that leaves none. So a walk never starts
        past a one-way event; it may start on a lead-in to the part (frames before it that nothing
        returns to), which it plays once. Starting only on the part, as Kovar et al. 2002 do, was
        tried (issue 63) and left: on the planted walker cut into six components its walks put
        legs on bodies that drag a stance foot 0.17 of the height, and the plants, holding it,
        dragged it 0.24 (0.65 and 0.21 as the walks start now)."""
        frames = self.usable_frames
        if fresh > 0:
            strict_returning, strict_trapped = self._parts(False, segment)
            plain_returning, plain_trapped = self._parts(False, 1)
            if strict_trapped.any() or plain_trapped.any():
                keep = strict_returning.reshape(self.frames, segment)[frames, 0] & plain_returning[frames]
                if keep.any():
                    frames = frames[keep]
        return frames

    def describe(self):
        """One line for logs: frames, transitions, usable frames and why the others are not."""
        text = f"{self.frames} frames, {len(self.transitions)} transition(s): {self.usable_count} usable"
        extra = []
        if self.forbidden.any():
            extra.append(f"{int(self.forbidden.sum())} forbidden")
        if self.dead_ends.any():
            extra.append(f"{int(self.dead_ends.sum())} dead ends that cannot reach a cycle")
        return text + (f" ({', '.join(extra)})" if extra else "")

    def successors(self, frame):
        """Successors of ``frame`` in the usable subgraph (sorted)."""
        return self.indices[self.indptr[frame]:self.indptr[frame + 1]]

    def has_edges(self, a, b, usable_only=False):
        """Whether a → b is an edge, elementwise over integer arrays a, b (any equal shapes).

        Edges of the non-forbidden frame graph (``usable_only``: of the usable subgraph)."""
        a = np.asarray(a, np.int64)
        b = np.asarray(b, np.int64)
        inside = (a >= 0) & (a < self.frames) & (b >= 0) & (b < self.frames)
        ac, bc = np.where(inside, a, 0), np.where(inside, b, 0)
        mask = self.usable if usable_only else ~self.forbidden
        ok = inside & mask[ac] & mask[bc]
        play = (bc == ac + 1) & self._moves.play_ok[ac]
        keys = self._moves.t_pairs[:, 0] * self.frames + self._moves.t_target
        pos = np.searchsorted(keys, ac * self.frames + bc)  # keys are sorted: pairs sorted by (i, j)
        trans = (pos < keys.size) & (keys[np.minimum(pos, max(keys.size - 1, 0))] == ac * self.frames + bc) \
            if keys.size else np.zeros(ac.shape, bool)
        return ok & (play | trans)

    def _edges(self, mask):
        """(src, dst) of all edges between frames in ``mask``."""
        m = self._moves
        play = np.flatnonzero(m.play_ok & mask & np.roll(mask, -1))
        t_src = m.t_pairs[:, 0]
        use = mask[t_src] & mask[m.t_target]
        return (np.concatenate([play, t_src[use]]), np.concatenate([play + 1, m.t_target[use]]))

    def _state_matrix(self, usable_only, segment):
        """Sparse adjacency (n, n), n = F · segment, of the (frame, segment-position) states.

        State (v, s), s = min(frames played in the current segment, segment) − 1. Playback:
        (v, s) → (v+1, min(s+1, segment−1)); transitions only from s = segment−1, to (w, 0).
        Restricted to usable or non-forbidden frames. Returns (matrix, allowed states (n,))."""
        key = (bool(usable_only), int(segment))
        if key not in self._state_cache:
            mask = self.usable if usable_only else ~self.forbidden
            m, F = self._moves, self.frames
            play = np.flatnonzero(m.play_ok & mask & np.roll(mask, -1))
            use = mask[m.t_pairs[:, 0]] & mask[m.t_target]
            matrix = _state_graph(F, play, m.t_pairs[use, 0], m.t_target[use], segment, np.float32)
            self._state_cache[key] = (matrix, np.repeat(mask, segment))
        return self._state_cache[key]

    def trapped(self, usable_only, segment):
        """States (F · segment,) bool, (frame, segment position) as :meth:`_state_matrix`, that lie
        on endless walks none of which comes back to the largest strongly connected part of the
        state graph: a trap (a part a walk enters and never leaves), not a dead end (those end)."""
        return self._parts(usable_only, segment)[1]

    def _parts(self, usable_only, segment):
        """(returning, trapped), each (F · segment,) bool: the states from which the largest
        strongly connected part of the state graph can be reached, and :meth:`trapped`. Cached."""
        from scipy.sparse.csgraph import breadth_first_order

        key = ("parts", bool(usable_only), int(segment))
        if key not in self._state_cache:
            matrix, allowed = self._state_matrix(usable_only, segment)
            n = matrix.shape[0]  # its edges join allowed states only (:meth:`_state_matrix`)
            main = _largest_part(matrix, segment) & allowed
            # every state that reaches the main part: a search backwards from all of it at once
            # (node n, a source joined to each main state, on the reversed edges)
            reverse = sp.bmat([[matrix.T, sp.csr_matrix((n, 1), dtype=np.float32)],
                               [sp.csr_matrix(main.astype(np.float32)[None, :]), sp.csr_matrix((1, 1))]],
                              format="csr")
            reached = np.zeros(n + 1, bool)
            reached[breadth_first_order(reverse, n, directed=True, return_predecessors=False)] = True
            returning = reached[:n] & allowed
            src, dst = matrix.nonzero()
            self._state_cache[key] = (returning, _infinite_walk_nodes(n, src, dst) & allowed & ~returning)
        return self._state_cache[key]

    def _backward(self, usable_only, segment, end_frame, length, late=None):
        """:func:`_backward_sets` of the (frame, segment-position) states, (length+1, F, segment)
        bool, for walks of ``length`` steps ending at ``end_frame`` (None: anywhere allowed);
        ``late`` (steps; None: no limit): the :meth:`trapped` states only within the last ``late``
        steps. Cached, since every batch of walks asks for the same ones."""
        key = (bool(usable_only), int(segment), None if end_frame is None else int(end_frame), int(length),
               None if late is None else int(late))
        if key not in self._backward_cache:
            _, allowed1 = self._state_matrix(usable_only, 1)
            end1 = allowed1.copy() if end_frame is None else np.arange(self.frames) == end_frame
            matrix, allowed = self._state_matrix(usable_only, segment)
            early = None if late is None else allowed & ~self.trapped(usable_only, segment)
            sets = _backward_sets(matrix, allowed, np.repeat(end1, segment), length, early, late)
            self._backward_cache[key] = sets.reshape(length + 1, self.frames, segment)
        return self._backward_cache[key]


def recurrent_frames(frames, transitions, clips=None, segment=1, hidden=None):
    """Frames (F,) bool in the largest strongly connected part of the frame graph (playback
    i → i+1 and i → j+1 per transition (i, j), j + 1 < F, j = −1 included): the frames a long walk can keep
    coming back to (of equally large parts, the first scipy labels). ``clips`` (None: one clip):
    playback only inside a clip, (i, −(c+1)) enters clip c's first frame, pairs whose j does not
    play on in its clip are left out (:meth:`.clips.Clips.valid_j`).

    ``segment`` (frames, 1: the frame graph): the walks' ``min_segment``. A walk may take a
    transition only after playing ``segment`` frames since its last seam, so the part counted is
    that of the (frame, frames played in the segment) states (:meth:`MotionGraph._state_matrix`),
    projected onto frames: a transition whose frame i lies fewer than ``segment`` frames after
    every way in cannot be taken by a strict walk. On the samba's arm component every way back from
    its late frames to its early ones left from frame 115, two frames after the only way in, so the
    late part was a trap the frame graph did not show (walks played a median 32 % of its frames).

    ``hidden`` (F,) bool (None: none): frames never shown (a held pose's, :mod:`.held_poses`),
    left out with every edge that touches them."""
    frames, segment = int(frames), max(1, int(segment))
    if frames == 0:
        return np.zeros(0, bool)
    matrix = _state_graph(frames, *_frame_edges(frames, transitions, clips, hidden), segment, np.int8)
    return _largest_part(matrix, segment).reshape(frames, segment).any(axis=1)


def _frame_edges(frames, transitions, clips, hidden):
    """(play (n,), leave (m,), enter (m,)): the frame graph's playback steps f → f + 1 and its
    transitions' frames left and entered (:func:`recurrent_frames`), none touching a ``hidden`` frame."""
    layout = Clips.single(frames) if clips is None else clips
    pairs = np.asarray(transitions, dtype=np.int64).reshape(-1, 2)
    pairs = pairs[layout.valid_j(pairs[:, 1])]
    play = np.flatnonzero(layout.plays_on()[:-1])
    enter = layout.targets(pairs[:, 1])
    if hidden is not None:
        hidden = np.asarray(hidden, bool)
        play = play[~hidden[play] & ~hidden[play + 1]]
        kept = ~hidden[pairs[:, 0]] & ~hidden[enter]
        pairs, enter = pairs[kept], enter[kept]
    return play, pairs[:, 0], enter


def frames_off_part(frames, transitions, clips=None, segment=1, hidden=None):
    """Where the frames off the largest strongly connected part lie (issue 63; the graph of
    :func:`recurrent_frames`): ``(on, after, before)``, each (F,) bool: on the part; reached from
    it but with no way back (the far side of a one-way event: walks play them once, at their end);
    leading into it but never reached from it (a lead-in: a walk plays them only where it starts
    on them, once: :meth:`MotionGraph.start_frames`). A frame off the part that is neither is cut off from it (hidden frames included)."""
    from scipy.sparse.csgraph import breadth_first_order

    frames, segment = int(frames), max(1, int(segment))
    matrix = _state_graph(frames, *_frame_edges(frames, transitions, clips, hidden), segment, np.int8)
    main = _largest_part(matrix, segment)
    n = matrix.shape[0]

    def reached(graph):  # every state reached from the part along graph's edges: one search from a joined source
        joined = sp.bmat([[graph, sp.csr_matrix((n, 1), dtype=np.int8)],
                          [sp.csr_matrix(main.astype(np.int8)[None, :]), sp.csr_matrix((1, 1), dtype=np.int8)]],
                         format="csr")
        out = np.zeros(n + 1, bool)
        out[breadth_first_order(joined, n, directed=True, return_predecessors=False)] = True
        return out[:n].reshape(frames, segment).any(axis=1)

    on = main.reshape(frames, segment).any(axis=1)
    forward, backward = reached(matrix.tocsr()), reached(matrix.T.tocsr())  # along the edges, and against them
    return on, forward & ~on, backward & ~on & ~forward


def _state_graph(frames, play, leave, enter, segment, dtype):
    """Sparse adjacency (n, n), n = frames · segment, of the (frame, segment position) states:
    state (v, s), s = min(frames played in the current segment, segment) − 1; playback from each
    frame in ``play``: (v, s) → (v+1, min(s+1, segment−1)); transitions ``leave`` → ``enter``
    (frames) only from s = segment − 1, to (w, 0)."""
    s = np.arange(segment)
    src = np.concatenate([(play[:, None] * segment + s).ravel(), leave * segment + segment - 1])
    dst = np.concatenate([((play[:, None] + 1) * segment + np.minimum(s + 1, segment - 1)).ravel(), enter * segment])
    n = frames * segment
    return sp.csr_matrix((np.ones(src.size, dtype), (src, dst)), shape=(n, n))


def _largest_part(matrix, segment):
    """States (n,) bool of the largest strongly connected part of a (frame, segment-position)
    state graph (n = F · segment), by the frames it holds (a frame's states may lie in several
    parts); of equally large parts, the first scipy labels."""
    from scipy.sparse.csgraph import connected_components

    count, labels = connected_components(matrix, directed=True, connection="strong")
    frames = matrix.shape[0] // segment
    held = np.unique(labels.reshape(frames, segment) + count * np.arange(frames)[:, None]) % count
    sizes = np.bincount(held, minlength=count)
    return labels == np.flatnonzero(sizes == sizes.max())[0]


def random_walks(graph, count, frames, rng, start=None, transition_probability=0.5, min_segment=4, fresh=0):
    """``count`` random walks of ``frames`` output frames -> sources (count, frames) int64.

    Walks start inside ``graph.usable`` and stay there, except that one may end in a dead-end
    tail when its last frames fit in it (on the Dem Bones example the 56 frames after the last
    transition were otherwise never played: 86 % of the clip). start: a usable frame where every walk starts, or None
    for starts drawn uniformly over the usable frames. rng: a numpy Generator (same state, same
    walks). See the module docstring for the policy (``transition_probability``,
    ``min_segment``, ``fresh``). Vectorised over walks: one numpy step per output frame.
    """
    count, frames = _check_sizes(count, frames)
    segment = max(1, int(min_segment))
    if start is not None:
        start = _check_frame(graph, start, "start frame", usable_only=True)
        first = np.full(count, start, np.int64)
    else:
        first = rng.choice(graph.start_frames(segment, fresh), size=count)
    # usable_only=False: a walk may run into a dead end (the clip's last frames past its last
    # transition) when its remaining length fits, so those frames are played too, as endings.
    path, _ = _walk_interval(graph, False, first, np.zeros(count, np.int64), None, frames - 1, rng,
                             transition_probability, segment, None, None, fresh)
    return path


def constrained_walks(graph, count, frames, targets, rng, start=None, end=None, transition_probability=0.5,
                      min_segment=4, usable_only=False, fresh=0):
    """``count`` walks of ``frames`` output frames through targeted frames (Zheng §3.4).

    targets: iterable of ``(input_frame, output_time)``: input frame f must be shown at output
    time T (0 ≤ T < frames). start / end: shorthand for the targets (start, 0) and
    (end, frames − 1). The output time axis is split at the targets; each interval between two
    targets is filled by exact-length reachability (backward sets over (frame, time) states,
    O(length · edges)) and a forward random walk restricted to states on some valid path; before
    the first target the start frame is free, after the last the end is free. Raises
    :class:`OptionError` naming the target when it cannot be reached in time, when two targets
    ask different frames at one time, or when a target is forbidden (or, with ``usable_only``,
    a dead end). Returns sources (count, frames) int64.
    """
    count, frames = _check_sizes(count, frames)
    segment = max(1, int(min_segment))
    wanted = [(f, t) for f, t in targets] if targets is not None else []
    if start is not None:
        wanted.append((start, 0))
    if end is not None:
        wanted.append((end, frames - 1))
    by_time = {}
    for f, t in wanted:
        t = int(t)
        if not 0 <= t < frames:
            raise OptionError(f"target output time {t} is outside 0..{frames - 1}")
        f = _check_frame(graph, f, "target input frame", usable_only, f" at output time {t}")
        if by_time.setdefault(t, f) != f:
            raise OptionError(f"output time {t} is targeted at two input frames, {by_time[t]} and {f}")
    fixed = sorted((t, f) for t, f in by_time.items())

    sources = np.empty((count, frames), np.int64)
    since = np.zeros(count, np.int64)
    if not fixed:  # no targets: free start and free end
        path, _ = _walk_interval(graph, usable_only, None, since, None, frames - 1, rng, transition_probability,
                                 segment, None, None, fresh)
        return path
    t0, f0 = fixed[0]
    if t0 > 0:  # free start, fixed end
        path, since = _walk_interval(graph, usable_only, None, since, f0, t0, rng, transition_probability,
                                     segment, None, (f0, t0), fresh)
        sources[:, :t0 + 1] = path
    else:
        sources[:, 0] = f0
    for (ta, fa), (tb, fb) in zip(fixed[:-1], fixed[1:]):
        path, since = _walk_interval(graph, usable_only, sources[:, ta], since, fb, tb - ta, rng,
                                     transition_probability, segment, (fa, ta), (fb, tb), fresh)
        sources[:, ta:tb + 1] = path
    tl, fl = fixed[-1]
    if tl < frames - 1:  # fixed start, free end
        path, since = _walk_interval(graph, usable_only, sources[:, tl], since, None, frames - 1 - tl, rng,
                                     transition_probability, segment, (fl, tl), None, fresh)
        sources[:, tl:] = path
    return sources


def overlap(a, b):
    """The fraction of output frames at which walks a (M,) and b (M,) show the same input frame."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError(f"walks must be equal-length 1-D arrays, got {a.shape} and {b.shape}")
    return float(np.mean(a == b)) if a.size else 1.0


def diversity_filter(sources, min_difference, block_elements=1 << 24, kept_before=0):
    """Greedy diversity filter -> keep mask (N,) bool.

    sources (N, M). Walks are visited in order; walk n is kept unless its :func:`overlap` with an
    earlier *kept* walk exceeds ``1 − min_difference`` (so ``min_difference = 0`` keeps all,
    ``1`` keeps only walks that never show the same frame at the same time as a kept one).
    Pairwise equality counts are computed in blocks of rows against all kept rows (about
    ``block_elements`` comparisons per block), then resolved greedily inside the block.
    ``kept_before``: the first rows are known to be kept already (an earlier call's result): they
    are not compared with one another again.
    """
    sources = np.asarray(sources)
    if sources.ndim != 2:
        raise ValueError(f"sources must be (N, M), got {sources.shape}")
    if not 0.0 <= min_difference <= 1.0:
        raise OptionError(f"min_difference must lie in [0, 1] (got {min_difference})")
    n, m = sources.shape
    keep = np.zeros(n, bool)
    if n == 0:
        return keep
    # overlap > 1 − d  ⇔  equal count > (1 − d) M; compare integers to avoid round-off
    limit = (1.0 - min_difference) * m
    kept_rows = sources[:kept_before]
    keep[:kept_before] = True
    start = kept_before
    while start < n:
        block = max(1, min(n - start, block_elements // max(1, (kept_rows.shape[0] + 64) * m)))
        rows = sources[start:start + block]
        if kept_rows.shape[0]:
            eq_prev = (rows[:, None, :] == kept_rows[None, :, :]).sum(axis=2)  # (b, K)
            alive = ~(eq_prev > limit).any(axis=1)
        else:
            alive = np.ones(len(rows), bool)
        eq_in = (rows[:, None, :] == rows[None, :, :]).sum(axis=2)  # (b, b)
        block_keep = np.zeros(len(rows), bool)
        for r in range(len(rows)):
            if alive[r] and not (eq_in[r, :r][block_keep[:r]] > limit).any():
                block_keep[r] = True
        keep[start:start + len(rows)] = block_keep
        kept_rows = np.concatenate([kept_rows, rows[block_keep]])
        start += len(rows)
    return keep


def seams(sources, clips=None):
    """Seams of walks: for sources (M,) a tuple ``(indices (S,), pairs (S, 2))``, the output
    indices k with source[k] ≠ source[k−1] + 1 and the transitions (source[k−1], source[k] − 1)
    used there (j = −1 for a seam onto frame 0: the wrap); for sources (N, M) a list of such
    tuples, one per walk. ``clips`` (None: one clip): the seams :meth:`.clips.Clips.seams`
    finds (also a step from a clip's last frame onto the next clip's first), the transition
    ``(source[k−1], Clips.transition_j(source[k]))`` (j = −(c+1) onto clip c's first frame)."""
    sources = np.asarray(sources, np.int64)
    if sources.ndim == 1:
        return seams(sources[None], clips)[0]
    out = []
    if clips is not None:
        seam = clips.seams(sources)
        for row, mask in zip(sources, seam):
            k = np.flatnonzero(mask)
            out.append((k, np.stack([row[k - 1], clips.transition_j(row[k])], axis=1).reshape(-1, 2)))
        return out
    for row in sources:
        k = np.flatnonzero(row[1:] != row[:-1] + 1) + 1
        out.append((k, np.stack([row[k - 1], row[k] - 1], axis=1)))
    return out


def transitions_between(pairs, clips):
    """How many transitions (i, j) (pairs (T, 2)) leave each clip for each clip -> {"a->b": count}
    over every ordered pair of clip names (within a clip: "a->a"), in clip order; the clip
    entered is j's own clip (for j ≥ 0), or clip c for j = −(c+1)."""
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    count = len(clips)
    j = pairs[:, 1]
    entered = np.where(j >= 0, clips.clip_of(np.maximum(j, 0)), np.clip(-j - 1, 0, count - 1))
    tally = np.bincount(clips.clip_of(pairs[:, 0]) * count + entered, minlength=count * count)
    return {f"{a}->{b}": int(tally[x * count + y]) for x, a in enumerate(clips.names)
            for y, b in enumerate(clips.names)}


def walk_statistics(sources, frames, clips=None, fps=None, held=None):
    """What walks of C components make of the clip: sources (C, N, M) -> dict of (C,) lists:
    ``transitions`` (seams in all N walks), ``mean_segment_frames`` (output frames per segment,
    the partial first and last segments included), ``shortest_segment`` (frames of the shortest
    segment between two seams; M where no walk has two seams), ``coverage`` (the share of the
    clip's ``frames`` input frames that some walk plays). With ``clips`` (:class:`.clips.Clips`
    of the ``frames`` frames) seams are :meth:`.clips.Clips.seams`, and two more lists:
    ``coverage_per_clip`` ({clip name: the share of its frames some walk plays}) and
    ``transitions_between`` ({"a->b": seams from a frame of clip a onto a frame of clip b},
    every ordered pair, within a clip "a->a"; they sum to ``transitions``). Per animation, also
    ``distinct_frames`` ((N,) lists: the distinct input frames each walk plays) and, with ``fps``,
    ``stuck`` (how many walks repeat a loop shorter than 2 s more than 3 times in a row):
    :mod:`.walk_measures`; ``distinct_poses`` ((N,) lists) counts a held pose once (``held``, a
    :class:`.held_poses.HeldPoses`; None: as ``distinct_frames``)."""
    from .walk_measures import distinct_frames, stuck_walks

    sources = np.asarray(sources)
    count, length = sources.shape[1:]
    out = {"transitions": [], "mean_segment_frames": [], "shortest_segment": [], "coverage": [],
           "distinct_frames": [], "distinct_poses": []}
    pose = np.arange(frames) if held is None else held.representative
    poses = int(frames) if held is None else int(held.moving.sum())  # the clip's poses, a held pose once
    if fps is not None:
        out["stuck"] = []
    if clips is not None:
        out.update(coverage_per_clip=[], transitions_between=[])
    for walks in sources:
        seam = walks[:, 1:] != walks[:, :-1] + 1 if clips is None else ~clips.continues(walks)
        total = int(seam.sum())
        animation, k = np.nonzero(seam)
        gaps = np.diff(k)[animation[1:] == animation[:-1]]  # between consecutive seams of one walk
        out["transitions"].append(total)
        out["mean_segment_frames"].append(float(walks.size / (total + count)) if count else 0.0)
        out["shortest_segment"].append(int(gaps.min()) if gaps.size else int(length))
        played = np.unique(walks)
        out["coverage"].append(float(played.size / frames))
        out["distinct_frames"].append(distinct_frames(walks).tolist())
        out["distinct_poses"].append(distinct_frames(pose[walks]).tolist())
        if fps is not None:
            out["stuck"].append(int(stuck_walks(walks, fps, clip_frames=poses).sum()))
        if clips is not None:
            shown = np.bincount(clips.clip_of(played), minlength=len(clips))
            out["coverage_per_clip"].append({name: float(shown[c] / clips.frames[c])
                                             for c, name in enumerate(clips.names)})
            used = np.stack([walks[animation, k], clips.transition_j(walks[animation, k + 1])], axis=1)
            out["transitions_between"].append(transitions_between(used, clips))
    return out


# --------------------------------------------------------------------------------------------
# internals


def _check_sizes(count, frames):
    count, frames = int(count), int(frames)
    if count < 0 or frames < 1:
        raise OptionError(f"need count ≥ 0 walks of at least 1 frame (got {count} × {frames})")
    return count, frames


def _check_frame(graph, frame, what, usable_only, where=""):
    frame = int(frame)
    if not 0 <= frame < graph.frames:
        raise OptionError(f"{what} {frame}{where} is outside the clip's frames 0..{graph.frames - 1}")
    if graph.forbidden[frame]:
        raise OptionError(f"{what} {graph.frame_name(frame)}{where} is a forbidden frame")
    if usable_only and not graph.usable[frame]:
        raise OptionError(f"{what} {graph.frame_name(frame)}{where} is a dead end: no arbitrarily long walk leaves it "
                          f"({graph.describe()})" + ("; constrained walks accept it with usable_only=False"
                                                     if what.startswith("target") else ""))
    return frame


def _csr(n, src, dst):
    order = np.lexsort((dst, src))
    src, dst = src[order], dst[order]
    return np.searchsorted(src, np.arange(n + 1)).astype(np.int64), dst.astype(np.int64)


def _infinite_walk_nodes(n, src, dst):
    """Nodes with an infinite walk (they reach a cycle): iterated pruning of dead ends, O(n + e)."""
    out_degree = np.bincount(src, minlength=n)
    r_indptr, r_indices = _csr(n, dst, src)  # predecessors
    alive = np.ones(n, bool)
    stack = list(np.flatnonzero(out_degree == 0))
    while stack:
        v = stack.pop()
        alive[v] = False
        for u in r_indices[r_indptr[v]:r_indptr[v + 1]]:
            out_degree[u] -= 1
            if out_degree[u] == 0:
                stack.append(u)
    return alive


def _backward_sets(matrix, allowed, end_states, length, early=None, late=0):
    """B (length+1, n) bool: B[t] = states from which ``end_states`` is reached in exactly
    length − t steps through allowed states; with ``early`` (n,) bool, through those while more
    than ``late`` steps remain."""
    b = np.empty((length + 1, matrix.shape[0]), bool)
    b[length] = end_states & allowed
    for t in range(length - 1, -1, -1):
        b[t] = (matrix @ b[t + 1].astype(np.float32) > 0) & (allowed if early is None or length - t <= late else early)
    return b


def _reachable_times(matrix, allowed, start_states, target_states, horizon):
    """Output offsets 0..horizon at which some walk from ``start_states`` is in ``target_states``."""
    x = start_states & allowed
    transpose = matrix.T.tocsr()
    times = []
    for t in range(horizon + 1):
        if (x & target_states).any():
            times.append(t)
        x = (transpose @ x.astype(np.float32) > 0) & allowed
    return times


def _unreachable_message(graph, usable_only, begin, finish, length):
    """Why no walk joins ``begin`` (frame, time) or a free start to ``finish`` or a free end."""
    matrix, allowed = graph._state_matrix(usable_only, 1)
    where = "among the usable frames" if usable_only else "avoiding forbidden frames" if graph.forbidden.any() \
        else ""
    if finish is None:
        fa, ta = begin
        return (f"no walk of {length} more output frames continues from input frame {graph.frame_name(fa)} at "
                f"output time {ta}"
                f"{' ' + where if where else ''}: every path runs into a dead end ({graph.describe()})")
    fb, tb = finish
    if begin is None:
        origin, start_states, t_origin = "any start frame at output time 0", allowed.copy(), 0
    else:
        fa, ta = begin
        origin, start_states, t_origin = (f"input frame {graph.frame_name(fa)} at output time {ta}",
                                          np.zeros(graph.frames, bool), ta)
        start_states[fa] = True
    target = np.zeros(graph.frames, bool)
    target[fb] = True
    horizon = length + 2 * graph.frames
    times = [t_origin + t for t in _reachable_times(matrix, allowed, start_states, target, horizon)]
    if times:
        shown = ", ".join(str(t) for t in times[:8]) + (", ..." if len(times) > 8 else "")
        hint = f"from there it can be shown at output times {shown}"
    else:
        hint = f"it is never reachable from there (within {horizon} frames)"
    return (f"input frame {graph.frame_name(fb)} cannot be reached at output time {tb} from {origin}"
            f"{' ' + where if where else ''} ({length} frames later); {hint}")


def _walk_interval(graph, usable_only, first, since, end_frame, length, rng, p, segment, begin, finish, fresh=0):
    """Walks over one interval of ``length`` steps -> (path (count, length+1), since (count,)).

    first: start frames (count,) or None (free start, drawn here); since: per walk, the segment
    position s (frames played in the current segment − 1, ≥ 0) at the first frame; end_frame: the
    frame required after ``length`` steps or None (free end). begin / finish: (frame, time) of
    the targets, for error messages."""
    F = graph.frames
    moves = graph._moves
    late = fresh if fresh > 0 and end_frame is None else None  # traps only as endings (module notes) ...
    if late is not None and first is not None:  # ... unless the walks start in one (a target there)
        s0 = np.minimum(np.asarray(since, np.int64), segment - 1)
        first_states = np.asarray(first, np.int64) * segment + s0
        if graph.trapped(usable_only, 1)[first].any() or graph.trapped(usable_only, segment)[first_states].any():
            late = None
    plain = graph._backward(usable_only, 1, end_frame, length, late)[:, :, 0]  # (L+1, F)
    strict = graph._backward(usable_only, segment, end_frame, length, late)  # (L+1, F, segment)

    if first is None:
        count = since.size
        candidates = np.flatnonzero(strict[0, :, 0])
        if candidates.size == 0:
            candidates = np.flatnonzero(plain[0])
        if candidates.size == 0:
            raise OptionError(_unreachable_message(graph, usable_only, begin, finish, length))
        first = rng.choice(candidates, size=count)
        since = np.zeros(count, np.int64)
    else:
        first = np.asarray(first, np.int64)
        if not plain[0, first].all():
            raise OptionError(_unreachable_message(graph, usable_only, begin, finish, length))
    count = first.size
    cur = first.copy()
    if fresh > 0:  # per walk, the output time each frame was last played (never: far in the past)
        walk_ids = np.arange(count)
        played = np.full((count, F), -(fresh + 1) * 4, np.int64)
        played[walk_ids, cur] = 0
        degree = max(1, int(np.diff(moves.t_indptr).max()))
        half = (segment + 1) // 2 - 1  # s at which a segment has played half of min_segment
        period = np.full(count, fresh + 1, np.int64)  # the loop a walk is replaying (none: > fresh)
        run = np.zeros(count, np.int64)  # ... and for how many frames in a row
    s = np.minimum(since, segment - 1)
    path = np.empty((count, length + 1), np.int64)
    path[:, 0] = cur
    last = segment - 1
    t_indptr, t_target = moves.t_indptr, moves.t_target
    play_ok = moves.play_ok
    # Valid transition edges as running counts over the edge list, for every step at once: strict
    # walks may only transition at the end of a full segment and must land where a full segment
    # still fits. The uniforms are drawn in one call (the same stream as one call per step).
    running = np.zeros((length, t_target.size + 1), np.int64)
    np.cumsum(strict[1:, t_target, 0], axis=1, out=running[:, 1:])
    uniforms = rng.random((length, 2, count))
    for t in range(length):
        strict_next, plain_next = strict[t + 1], plain[t + 1]
        relaxed = np.flatnonzero(~strict[t, cur, s])  # usually empty: handled on the side
        nxt_play = np.minimum(cur + 1, F - 1)
        s_play = np.minimum(s + 1, last)
        can_play = play_ok[cur] & strict_next[nxt_play, s_play]
        lo, hi = t_indptr[cur], t_indptr[cur + 1]
        cs_s = running[t]
        cnt = np.where(s == last, cs_s[hi] - cs_s[lo], 0)
        loose = np.zeros(count, bool)  # walks choosing among the plain graph's edges this step
        if relaxed.size:
            cs_p = np.concatenate([[0], np.cumsum(plain_next[t_target])])
            can_play[relaxed] = play_ok[cur[relaxed]] & plain_next[nxt_play[relaxed]]
            # A relaxed walk that must move takes, where it can, a transition that makes it
            # strict again: else it can fall back into the same trap at every turn.
            back = cs_s[hi[relaxed]] - cs_s[lo[relaxed]]
            loose[relaxed] = back == 0
            cnt[relaxed] = np.where(back > 0, back, cs_p[hi[relaxed]] - cs_p[lo[relaxed]])
        u = uniforms[t]
        take = ((cnt > 0) & (s == last) & (u[0] < p)) | ~can_play
        if fresh > 0:  # a walk replaying one loop a second time leaves it at its first way out
            in_loop = (period < fresh) & (run >= 2 * period)
            looping = np.flatnonzero(in_loop & (s >= half) & ~take)
            if looping.size:  # an edge into a frame older than the loop, where a full segment fits
                _, valid, age = _edge_ages(looping, lo, hi, t_target, strict_next[:, 0], plain_next, loose, played,
                                           t + 1, degree)
                out = looping[(valid & (age > period[looping, None])).any(axis=1)]
                take[out], cnt[out] = True, 1
            # ... and takes no drawn transition back into it where it can play on (out of it, where its
            # only way out is playback: the samba at 12 fps replayed frames 70–80 four times in a row)
            back = np.flatnonzero(in_loop & take & can_play)
            if back.size:
                _, valid, age = _edge_ages(back, lo, hi, t_target, strict_next[:, 0], plain_next, loose, played,
                                           t + 1, degree)
                take[back[~(valid & (age > period[back, None])).any(axis=1)]] = False
        movers = np.flatnonzero(take)
        if movers.size:
            if (cnt[movers] == 0).any():  # cannot happen: every state in the sets has a valid move
                raise RuntimeError("internal error: a walk has no valid move")
            if fresh > 0:
                edge = _fresh_edges(movers, lo, hi, t_target, strict_next[:, 0], plain_next, loose, played, t + 1,
                                    fresh, u[1, movers], degree)
            else:
                rank = np.minimum((u[1, movers] * cnt[movers]).astype(np.int64), cnt[movers] - 1)
                edge = np.searchsorted(cs_s, cs_s[lo[movers]] + rank + 1) - 1  # the rank-th valid edge
                if loose[movers].any():
                    plain_movers = loose[movers]
                    edge[plain_movers] = np.searchsorted(cs_p, cs_p[lo[movers[plain_movers]]] + rank[plain_movers] + 1) - 1
            nxt_play[movers] = t_target[edge]
            s_play[movers] = 0
        cur, s = nxt_play, s_play
        path[:, t + 1] = cur
        if fresh > 0:
            age = t + 1 - played[walk_ids, cur]  # a loop's period, when the walk replays one
            again = age == period
            run = np.where(again, run + 1, 1)
            period = np.where(again, period, age)
            played[walk_ids, cur] = t + 1
    return path, s


def _edge_ages(movers, lo, hi, target, strict_ok, plain_ok, loose, played, now, degree):
    """Each mover's transition edges ``(edges (n, degree)`` indices into ``target`` (padding: its
    first), ``valid (n, degree)`` (strict ones, or the plain graph's for a ``loose`` walk, as the
    uniform choice counts them), ``age (n, degree)``: output frames since the walk last played the
    frame each enters (−1 where not valid))."""
    edges = lo[movers, None] + np.arange(degree)
    inside = edges < hi[movers, None]
    edges = np.where(inside, edges, lo[movers, None])
    frames = target[edges]
    valid = inside & np.where(loose[movers, None], plain_ok[frames], strict_ok[frames])
    return edges, valid, np.where(valid, now - played[movers[:, None], frames], -1)


def _fresh_edges(movers, lo, hi, target, strict_ok, plain_ok, loose, played, now, fresh, u, degree):
    """The transition each mover takes when walks avoid loops (``fresh`` > 0 output frames): among
    its valid edges (:func:`_edge_ages`), those entering a frame it has not played in the last
    ``fresh`` output frames, or, where every one has been, those whose frame it played longest
    ago; the u-th of them (u (n,) uniform). Edges as indices into ``target``."""
    edges, valid, age = _edge_ages(movers, lo, hi, target, strict_ok, plain_ok, loose, played, now, degree)
    oldest = age.max(axis=1, keepdims=True)
    preferred = valid & ((age > fresh) | (age == oldest))
    count = preferred.sum(axis=1)
    rank = np.minimum((u * count).astype(np.int64), count - 1)
    slot = np.argmax(np.cumsum(preferred, axis=1) > rank[:, None], axis=1)
    return edges[np.arange(movers.size), slot]
