"""Splicing walks of one bone component into output bone positions (Zheng §3.3, eq. 7–10).

A walk is ``source (M,)``: the input frame played at each output frame. Consecutive output
frames either follow playback (``source[k] = source[k−1] + 1``) or take a transition (i, j):
``source[k−1] = i``, ``source[k] = j + 1`` — frame j is identified with frame i (Zheng's
S_{a→i} then S_{j→b}) and playback goes on after j. A *seam* is an output index k with
``source[k] ≠ source[k−1] + 1``; ``source[0]`` may be any frame. :func:`splice` turns A walks of
the same length into world bone positions, all at once:

1. Reference bone (eq. 7, :func:`reference_alignment`): each segment of the walk is the input
   reference-bone motion moved by one rigid transform G, the identity before the first seam; at
   a seam G ← G ∘ P(i) ∘ P(j)⁻¹ (P(f) the input reference pose of frame f), so frame j's pose
   lands on the output pose of frame i and the output goes on with the input's own step j → j+1.
   G only changes at seams, so it is composed once per seam (a loop over the seam rank, batched
   over all animations) and looked up per frame by segment number.
   The reference bone stays rigid (a product of rotations).
2. Non-reference bones away from seams: their local-frame positions (eq. 2) are the source
   frame's, exactly.
3. Around each seam (:func:`seam_windows`, :func:`blend_gradients`): the key vertices'
   deformation gradients, in rotation-strain form D = U S, are re-solved over a window by the 1D
   Poisson equation of Zheng §3.3: d̃(m−1) − 2 d̃(m) + d̃(m+1) = g(m) at each free frame m, g(m)
   the second difference of the input at source[m] with *its own* input neighbours, Dirichlet
   values d̃ = d(source) at the two frames just outside the free run (they keep their exact
   positions). It is solved for the correction e = d̃ − d(source) (the same equation, moved):
   e = 0 at both ends and e'' = h, where h vanishes except next to the seam — h(k−1) =
   d(i+1) − d(j+1) and h(k) = d(j) − d(i) (i = source[k−1], j = source[k] − 1), the only places
   where the source series' own neighbours are not its neighbours in the output. The rotation
   part is a rotation, not a vector: its differences are the small relative rotations
   log(U(i+1) U(j+1)ᵀ) and log(U(j) U(i)ᵀ), and the blend applies exp(e) on the left of
   U(source). Blending the axis-angle vectors Φ(U) themselves (as before) broke where a key
   vertex's local rotation nears π, which real captures do (the samba's reached 3.14 rad): the
   branch cut flipped vectors inside windows and eq. 9 turned the garbage into bones stretched
   3.8× (a 17× acceleration spike). The matrix is the same for all 9n coordinates, so every
   window of every animation is one diagonal block of one symmetric positive-definite
   tridiagonal system (the negated Laplacian, zero couplings between windows) with 9n
   right-hand sides: one ``scipy.linalg.solveh_banded`` call (LAPACK ptsv, O(L·9n)) for all
   windows, or one per group of whole windows when they hold more than ``block_frames`` frames
   (memory bound; the blocks are independent, so the result is the same).
4. Blended D̃ → eq. 9 for the local positions of the
   non-reference bones at every free frame, one :meth:`GradientOperator.solve` per block. By
   default (``anchored=True``) eq. 9 is solved for the *change*: p̃ = p(source) + G⁺(D̃ − D(source)),
   D(source) the input gradients of the source frame. With G of full column rank this is the
   plain least-squares solution of G p = d̃ − c (to rounding); where G is rank-deficient (a
   bone direction the key vertices do not see, e.g. hard weights), the plain solve would set
   the unseen directions to 0 inside the windows and jump back to the input values outside;
   the anchored solve keeps the source's values there, so the window edges stay continuous and
   an unchanged d̃ gives back the source positions exactly. ``anchored=False`` is the plain
   solve. From here on local positions are general affine 3×3 (Zheng eq. 9).
5. World positions (eq. 10): F_b = R̃_r F_b→r, t_b = R̃_r t_b→r + t̃_r; the reference bone is
   F = R̃_r, t = t̃_r.

Windows (:func:`seam_windows`): seam k blends the ``window`` output frames before it
(k−window … k−1) and the ``window`` frames from it on (k … k+window−1); the Dirichlet frames are
L = k−window−1 and R = k+window. Clipping:

- at the animation ends, L ≥ 0 and R ≤ M−1 (frame 0 and frame M−1 stay fixed, so a seam at
  k = 1 blends only its right side and one at k = M−1 only its left side);
- between two seams k₁ < k₂ whose windows would overlap or touch (gap g = k₂ − k₁ ≤ 2·window),
  the two windows share one Dirichlet frame k₁ + ⌊g/2⌋: seam k₁ gets ⌊g/2⌋ frames on its right,
  seam k₂ gets g − 1 − ⌊g/2⌋ on its left. So every window is bounded by fixed frames and no
  frame belongs to two windows; with seams one frame apart (g = 1) the shared fixed frame is the
  one-frame segment itself and each seam blends on its outer side only. ``window=0`` blends
  nothing (eq. 7 only; the local positions jump at each seam).

Velocity jump (``spread_velocity``, default on; not in Zheng, who leave g open): with g the
input's own second differences, the output takes the left segment's velocity v_L = d(i+1) − d(i)
across the seam and keeps the right segment's accelerations after it, so the right side runs
off by δ = v_R − v_L (v_R = d(j+1) − d(j)) and the Dirichlet frames pull it back with kinks of
about δ/2 at both window ends, whatever the window's length — a longer window only adds a
longer drift, which the reference bone's rotation bends (measured rougher). Spreading δ as an
even extra acceleration δ/(R − L + 1) over the window's free frames turns the left velocity into
the right one gradually, and the end kinks shrink with the window: measured on a horse-sized
tube (max acceleration near seams / the input's), window 4: 1.18 → 1.07, window 8:
1.75 → 1.29. This is still a 1D Poisson equation per coordinate, with a different guidance
field.

Cut nodes (``damped_bones``, ``damping``): a component's cut node sits at its border, where
only the key vertices on this side see it, so eq. 9 determines it poorly: on a horse-sized tube
cut into six components the solved cut node took 10–22 % spurious stretch inside windows, and
assembly reads its stretch (eq. 12–13) and its rotation (eq. 14, which swings every bone hung
from it). The synthesizer therefore damps the change of the cut nodes (a Tikhonov term μ‖Δp_b‖²
on their 12 numbers, μ relative to the mean diagonal of G₀ᵀG₀); the parent component places the
cut node anyway. Single-component synthesis has no cut node and is unaffected.

Input-clip ends: where i is the clip's last frame there is no d(i+1); i then goes on with its
own last step (:func:`seam_guidance`). The wrap, a transition (i, −1) (:mod:`.transitions`:
"after i, continue at frame 0"; here source[k] = 0), mirrors it at the other end: j = −1 is the
virtual frame before the clip's start, frame 0 gone on backwards with its own first step, the
same constant-velocity extrapolation the costs compare. Eq. 7 needs its reference pose,
H(−1) = H(0) H(1)⁻¹ H(0) (so the segment's frame 0 follows the output's frame i with the
input's own first step H(0)⁻¹ H(1)); the blend needs its series, U(−1) := U(0) U(1)ᵀ U(0) (a
relative rotation, not a vector) and S(−1) := 2 S(0) − S(1). For motion at constant velocity
through the wrap (frames F−2, F−1, 0, 1 one step apart) both guidance terms and the velocity
jump vanish and the splice is the clip's periodic continuation exactly.

Several clips (``clips``, a :class:`~skinsynth.pipeline.inputs.clips.Clips`; None is one clip of all
the frames, the code path and the numbers above): the frames are the clips one after another,
and every rule above holds per clip (:mod:`skinsynth.pipeline.inputs.clips` states the conventions).
A seam is where the source does not play on (:meth:`Clips.seams`), so playing one clip's last
frame and then the next clip's first (consecutive numbers) is a seam, blended, not playback. Its
transition is j = :meth:`Clips.transition_j` of the frame played, source[k]: source[k] − 1, or,
where source[k] begins clip c, the virtual frame j = −(c + 1) before it, clip c's first frame
gone on backwards with its own first step (the pose H(j) and the series U(j), S(j) as for
j = −1 above, from that clip's first two frames). "The frame after i" never reads across a clip's
end: where i is the last frame of its clip it goes on with its own last step. Formulas below
that write j + 1 mean the frame played, source[k] (the two differ only for j < 0).

Distinct windows (:func:`distinct_windows`): everything steps 3–4 compute for a window — the
blend, D̃, the eq. 9 solve — depends on the window's source frames left … right alone (local
positions are in the reference bone's frame; the rigid offset G of eq. 7 only enters at step 5).
A seam between two long segments has the same source frames wherever a walk takes that
transition, so windows are deduplicated by their source frames and each distinct one is solved
once: with ~20 candidate transitions and thousands of walks, a few hundred solves instead of
~10⁵ (measured: 250 walks × 600 frames of a 22-bone tube, 9.0 s → 1.1 s). The result is the
same as solving every window (tested against the per-window solve).

Local form: :func:`splice_local` returns :class:`SplicedWalks` — the reference bone's world
poses and every bone's position in its frame — and :meth:`SplicedWalks.world` applies eq. 10;
multi-component assembly composes its own rigid turn with eq. 10 first and touches the local
arrays once (:mod:`.assembly`).

Memory, dtype: the local positions F (A, M, b, 3, 3) and t (A, M, b, 3) take A·M·b·48 bytes in
float32 (the synthesizer's choice; all arithmetic stays float64 and is rounded once when stored,
and once more when eq. 10 is applied), the reference poses (A, M, 3, 3) float64. Per block of
about ``block_frames`` distinct-window frames ≈ block_frames·n·360 bytes (n key vertices), and
eq. 10 works on ``animation_block`` animations at a time (≈ animation_block·M·b·200 bytes).
"""

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .deformation_gradients import rotation_times_strain
from ..runtime.rows import unique_rows
from ..rig.rotations import apply_rigid_into, heading_and_posture, rotation_exp, rotation_log
from .transitions import local_frame_positions


def walk_sources(sources, frames):
    """Validate walks: ``sources`` (A, M) or (M,) ints in [0, frames) -> int64 (A, M).

    A seam k plays source[k] = j + 1 after identifying j with source[k−1]; a seam onto frame 0
    is the wrap, j = −1, the virtual frame before the clip's start (module notes). Which seams a
    walk may take is the motion graph's business (:mod:`.motion_graph`), not this check's.
    """
    sources = np.asarray(sources)
    if sources.ndim == 1:
        sources = sources[None]
    if sources.ndim != 2 or sources.shape[1] == 0:
        raise ValueError(f"sources must be (A, M) with M ≥ 1, got shape {sources.shape}")
    if not np.issubdtype(sources.dtype, np.integer):
        raise ValueError(f"sources must be integers, got {sources.dtype}")
    sources = sources.astype(np.int64)
    if sources.size and (sources.min() < 0 or sources.max() >= frames):
        raise ValueError(f"sources must lie in 0..{frames - 1}, got {sources.min()}..{sources.max()}")
    return sources


def walk_seams(sources, clips=None):
    """Seams of walks (A, M): ``(animation (S,), k (S,))``, sorted by animation then k; with
    ``clips`` also where a walk plays on into the next clip (:meth:`Clips.seams`)."""
    sources = np.asarray(sources)
    if clips is None:
        animation, k = np.nonzero(sources[:, 1:] != sources[:, :-1] + 1)
    else:
        animation, k = np.nonzero(~clips.continues(sources))
    return animation.astype(np.int64), (k + 1).astype(np.int64)


def seam_transitions(sources, animation, k, clips=None):
    """The transition (i, j) taken at seams ``(animation (S,), k (S,))`` of walks (A, M), and the
    frame played there: ``(i (S,), j (S,), target (S,))``, i = source[k−1], target = source[k],
    j = target − 1, or with ``clips`` :meth:`Clips.transition_j` (the virtual frame −(c + 1)
    where the target begins clip c)."""
    i, target = sources[animation, k - 1], sources[animation, k]
    j = target - 1 if clips is None else clips.transition_j(target)
    return i, j, target


def walk_clips(clips, frames):
    """``clips`` checked against ``frames`` input frames: None (one clip) stays None."""
    if clips is not None and clips.total != frames:
        raise ValueError(f"the clips hold {clips.total} frames, the input {frames}")
    return clips


@dataclass
class SeamWindows:
    """Blend windows of all seams (module notes): per seam s, ``animation[s]``, the seam's output
    index ``seam[s]`` and its Dirichlet frames ``left[s] < seam[s] ≤ right[s]``; the free (blended)
    frames are left+1 … right−1 (none when right = left + 1)."""

    animation: np.ndarray
    seam: np.ndarray
    left: np.ndarray
    right: np.ndarray

    @property
    def counts(self):
        """Free frames per window (S,)."""
        return self.right - self.left - 1

    def frames(self, select=None):
        """Free frames of the windows ``select`` (default all), stacked window by window:
        ``(animation (L,), frame (L,), owner (L,) index into the windows, first (L,), last (L,))``."""
        index = np.arange(self.seam.size) if select is None else np.asarray(select, dtype=np.int64)
        count = self.counts[index]
        owner = np.repeat(index, count)
        start = np.repeat(np.cumsum(count) - count, count)
        offset = np.arange(owner.size) - start
        frame = self.left[owner] + 1 + offset
        return (self.animation[owner], frame, owner, offset == 0, offset == self.counts[owner] - 1)


def seam_windows(sources, window=8, clips=None):
    """Windows around every seam of walks (A, M), clipped as in the module notes -> SeamWindows;
    ``clips``: the seams are :meth:`Clips.seams` (None: one clip)."""
    sources = np.asarray(sources)
    if int(window) != window or window < 0:
        raise ValueError(f"window must be a non-negative integer, got {window}")
    window = int(window)
    frames = sources.shape[1]
    animation, k = walk_seams(sources, clips)
    count = k.size
    first = np.ones(count, bool)
    first[1:] = animation[1:] != animation[:-1]
    last = np.ones(count, bool)
    last[:-1] = animation[:-1] != animation[1:]
    gap_before = np.zeros(count, np.int64)
    gap_before[1:] = k[1:] - k[:-1]
    gap_after = np.zeros(count, np.int64)
    gap_after[:-1] = k[1:] - k[:-1]
    wide = 2 * window + 1  # a segment of ≥ wide frames keeps both half-windows whole
    left = np.where(first, np.maximum(k - window - 1, 0),
                    np.where(gap_before >= wide, k - window - 1, k - gap_before + gap_before // 2))
    right = np.where(last, np.minimum(k + window, frames - 1),
                     np.where(gap_after >= wide, k + window, k + gap_after // 2))
    return SeamWindows(animation=animation, seam=k, left=left.astype(np.int64), right=right.astype(np.int64))


def reference_alignment(R_ref, t_ref, sources, up=None, pivot=None, window=0, spread_velocity=True, clips=None):
    """Output reference-bone poses along walks: Zheng eq. 7, or its ground-plane form.

    R_ref (F, 3, 3), t_ref (F, 3): the input reference bone; sources (A, M) validated walks.
    Returns (R̃ (A, M, 3, 3), t̃ (A, M, 3)) = G_k ∘ H(source[k]) ∘ Π(source[k]), G the
    accumulated offsets (identity before the first seam; at a seam k with i = source[k−1],
    j = source[k] − 1, G ← G ∘ H(i) ∘ H(j)⁻¹; j = −1, the wrap, uses H(−1) = H(0) H(1)⁻¹ H(0),
    module notes). ``clips``: several clips (module notes): j = −(c + 1) where source[k] begins
    clip c, H(j) = H(s) H(s+1)⁻¹ H(s) of its first frame s.

    ``up=None`` is Zheng's eq. 7: H(f) = P(f), the input reference pose, and Π = identity, so each
    segment is moved by a full rigid transform; its height and tilt errors add up seam after seam
    (on the horse gallop, 3,000 frames ended 0.7 of its height outside the input's range of
    lowest points, and turned over). With ``up`` a unit axis (3,), as in motion graphs (Kovar et
    al. 2002), H(f) is the *heading* of P(f): its turn about ``up`` (:func:`.rotations.heading_rotation`)
    and the ground-plane position of the bone's ``pivot`` (3,) (its rest centroid); Π(f) =
    H(f)⁻¹ P(f) is the rest, tilt and height, which stay the input's. G is then a turn about up
    and a ground-plane shift, so nothing accumulates off the ground. Π jumps at a seam (Π(i) vs
    Π(j)); it is blended over the ``window`` frames on each side like the bones
    (:func:`blend_rigid` about the pivot, ``spread_velocity`` alike).
    """
    R_ref = np.asarray(R_ref, dtype=np.float64)
    t_ref = np.asarray(t_ref, dtype=np.float64)
    count, frames = sources.shape
    if up is None:
        H_R, H_t = R_ref, t_ref
    else:
        pivot = np.zeros(3) if pivot is None else np.asarray(pivot, dtype=np.float64)
        H_R, H_t, posture_R, posture_t = heading_and_posture(R_ref, t_ref, pivot, up)
    animation, k = walk_seams(sources, clips)
    # G is constant between seams: compose it once per seam (a loop over the seam rank, batched
    # over animations), then look it up per frame by segment number.
    is_seam = np.zeros((count, frames), dtype=bool)
    is_seam[animation, k] = True
    segment = np.cumsum(is_seam, axis=1)  # (A, M) segment number of each output frame
    segments = int(segment[:, -1].max()) if frames else 0
    rel_R = np.broadcast_to(np.eye(3), (count, segments, 3, 3)).copy()
    rel_t = np.zeros((count, segments, 3))
    if k.size:
        i, j, _ = seam_transitions(sources, animation, k, clips)
        # H(j) for j < 0 too: index j + C of the poses with the virtual frames −C … −1 first.
        before_R, before_t = _frames_before_starts(H_R, H_t, clips)
        H_jR = np.concatenate([before_R[::-1], H_R])[j + before_R.shape[0]]
        H_jt = np.concatenate([before_t[::-1], H_t])[j + before_t.shape[0]]
        # H(i) ∘ H(j)⁻¹ = (R_i R_jᵀ, t_i − R_i R_jᵀ t_j): Zheng eq. 7's fixed rigid transform.
        rel = H_R[i] @ np.swapaxes(H_jR, -1, -2)
        rank = segment[animation, k] - 1
        rel_R[animation, rank] = rel
        rel_t[animation, rank] = H_t[i] - np.einsum("sab,sb->sa", rel, H_jt)
    G_R = np.empty((count, segments + 1, 3, 3))
    G_t = np.empty((count, segments + 1, 3))
    G_R[:, 0], G_t[:, 0] = np.eye(3), 0.0
    for r in range(segments):
        G_R[:, r + 1] = G_R[:, r] @ rel_R[:, r]
        G_t[:, r + 1] = np.einsum("aij,aj->ai", G_R[:, r], rel_t[:, r]) + G_t[:, r]
    rows = np.arange(count)[:, None]
    R_out = G_R[rows, segment] @ H_R[sources]
    t_out = np.einsum("amij,amj->ami", G_R[rows, segment], H_t[sources]) + G_t[rows, segment]
    if up is None:
        return R_out, t_out
    # The posture Π: the source's, blended across each seam's window.
    P_R, P_t = posture_R[sources], posture_t[sources]
    windows = seam_windows(sources, window, clips)
    if windows.counts.sum():
        a, m, rotation, translation = blend_rigid(posture_R[:, None], posture_t[:, None], pivot[None], sources,
                                                  windows, spread_velocity=spread_velocity, clips=clips)
        P_R[a, m], P_t[a, m] = rotation[:, 0], translation[:, 0]
    return R_out @ P_R, np.einsum("amij,amj->ami", R_out, P_t) + t_out


def _frame_before_start(R, t):
    """The rigid pose of the virtual frame −1 of poses R (F, 3, 3), t (F, 3) (x ↦ R x + t):
    P(0) P(1)⁻¹ P(0), frame 0 gone on backwards with its first step -> (R (3, 3), t (3,)); a
    one-frame clip stands still (P(0))."""
    if R.shape[0] < 2:
        return R[0].copy(), t[0].copy()
    back = R[0] @ R[1].T  # P(0) P(1)⁻¹ = (R0 R1ᵀ, t0 − R0 R1ᵀ t1)
    return back @ R[0], back @ (t[0] - t[1]) + t[0]


def _frames_before_starts(R, t, clips=None):
    """The virtual frame before each clip's start (:func:`_frame_before_start` of the clip's own
    poses; j = −(c + 1) is row c) -> (R (C, 3, 3), t (C, 3)); ``clips`` None: one clip."""
    if clips is None:
        before_R, before_t = _frame_before_start(R, t)
        return before_R[None], before_t[None]
    starts = clips.starts
    pairs = [_frame_before_start(R[a:b], t[a:b]) for a, b in zip(starts[:-1], starts[1:])]  # a loop over clips
    return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])


def gradient_series(strain):
    """The input's key-vertex gradients as the blend uses them: strain (F, n, 9) ->
    ``(U (F, n, 3, 3) rotations, S (F, n, 6) stretches)``, U = exp(Φ) whatever branch Φ is on."""
    strain = np.asarray(strain, dtype=np.float64)
    return rotation_exp(strain[..., :3]), strain[..., 3:].copy()


def seam_guidance(U, S, sources, windows, win, clips=None):
    """The two non-zero guidance terms of each window's correction (module notes, step 3):
    ``(h_left (W, n, 3+k), h_right (W, n, 3+k))`` at output frames k−1 and k of windows ``win``
    and the seam's velocity jump δ (W, n, 3+k) = v_R − v_L, v the one-frame steps ``j → j+1``
    and ``i → i+1``,
    rotation part first, for a series of rotations U (F, n, 3, 3) and linear coordinates S
    (F, n, k). With i = source[k−1], j = source[k] − 1: h_left = [log(U(i+1) U(j+1)ᵀ),
    S(i+1) − S(j+1)], h_right = [log(U(j) U(i)ᵀ), S(j) − S(i)]; where i is the clip's last frame
    it goes on with its own last step: U(i+1) := U(i) U(i−1)ᵀ U(i), S(i+1) := 2 S(i) − S(i−1)
    (the old rule, "goes on as j does", put the whole velocity change at the seam: 1.8× the
    input's acceleration on a synthetic chain, where this gives 0.9×). Where j = −1 (the wrap,
    source[k] = 0) frame 0 likewise goes on backwards with its own first step: U(−1) :=
    U(0) U(1)ᵀ U(0), S(−1) := 2 S(0) − S(1). With ``clips`` (module notes) each clip is such a
    clip: i's last frame is the last of its clip, and j = −(c + 1), where source[k] begins clip
    c, is that clip's first frame gone on backwards; j + 1 above is then source[k]."""
    a, k = windows.animation[win], windows.seam[win]
    frames = U.shape[0]
    i, j, target = seam_transitions(sources, a, k, clips)
    last = i + 1 >= frames if clips is None else clips.last_frames()[i]
    starts = np.array([0, frames], np.int64) if clips is None else clips.starts
    i1 = np.minimum(i + 1, frames - 1)
    U_next, S_next = U[i1].copy(), S[i1].copy()
    if last.any():  # past the clip's end: i goes on with its own last step (constant velocity)
        clip_start = starts[np.searchsorted(starts, i[last], side="right") - 1]  # a one-frame clip stands still
        p = np.maximum(i[last] - 1, clip_start)
        U_next[last] = U[i[last]] @ np.swapaxes(U[p], -1, -2) @ U[i[last]]
        S_next[last] = 2.0 * S[i[last]] - S[p]
    before = j < 0
    U_j, S_j = U[np.maximum(j, 0)], S[np.maximum(j, 0)]  # fancy indexing: copies
    for clip in range(starts.size - 1):  # before clip c's start: its first frame goes on backwards
        here = before & (j == -(clip + 1))
        if here.any():
            start = int(starts[clip])
            second = min(start + 1, int(starts[clip + 1]) - 1)
            U_j[here] = U[start] @ np.swapaxes(U[second], -1, -2) @ U[start]
            S_j[here] = 2.0 * S[start] - S[second]

    def difference(Up, Sp, Uq, Sq):  # p ⊖ q: the rotation taking q to p (spatial), and the linear difference
        return np.concatenate([rotation_log(Up @ np.swapaxes(Uq, -1, -2)), Sp - Sq], axis=-1)

    # δ from the two one-frame steps (small rotations), not from h: h's rotations are wrapped
    # into (−π, π] one by one, so their sum can be off by 2π where i and j are far apart.
    velocity_jump = difference(U[target], S[target], U_j, S_j) - difference(U_next, S_next, U[i], S[i])
    return (difference(U_next, S_next, U[target], S[target]), difference(U_j, S_j, U[i], S[i]), velocity_jump)


def blend_series(U, S, sources, windows, select=None, spread_velocity=True, clips=None):
    """Poisson-blended rotations and linear coordinates at the free frames of windows (step 3).

    U (F, n, 3, 3) rotations, S (F, n, k) linear coordinates of n items per input frame (bones'
    local rotations and translations, or key vertices' :func:`gradient_series`); sources (A, M);
    windows a :class:`SeamWindows`; ``select`` the windows to solve (default all);
    ``spread_velocity``: the seam's velocity jump spread evenly over the window (module notes);
    ``clips``: several clips (module notes; None: one). Returns ``(animation (L,), frame (L,),
    rotations (L, n, 3, 3), linear (L, n, k))`` in :meth:`SeamWindows.frames` order: exp(e_rot) U(source) and S(source) + e_lin, e the
    correction of step 3. One banded Cholesky solve (``solveh_banded``) of the stacked
    block-tridiagonal system −Δe = −h with all n·(3+k) coordinates as right-hand sides."""
    animation, frame, owner, first, last = windows.frames(select)
    size = frame.size
    n, width = U.shape[1], 3 + S.shape[-1]
    src = sources[animation, frame]
    if size == 0:
        return animation, frame, U[src], S[src]
    win = owner[first]  # the windows, in order, each once
    at = np.searchsorted(win, owner)  # window rank of every free frame
    h_left, h_right, jump = seam_guidance(U, S, sources, windows, win, clips)
    rhs = np.zeros((size, n, width))
    if spread_velocity:  # δ as an even extra acceleration
        span = (windows.right[win] - windows.left[win] + 1).astype(float)
        rhs -= (jump / span[:, None, None])[at]
    seam = windows.seam[owner]
    rhs[frame == seam - 1] -= h_left[at[frame == seam - 1]]
    rhs[frame == seam] -= h_right[at[frame == seam]]
    # −Δ: 2 on the diagonal, −1 between consecutive free frames of one window (upper form);
    # e = 0 at both Dirichlet frames, so no boundary terms.
    bands = np.empty((2, size))
    bands[1] = 2.0
    bands[0] = np.where(first, 0.0, -1.0)
    if size == 1:  # LAPACK ptsv refuses an empty off-diagonal
        e = rhs / 2.0
    else:
        e = scipy.linalg.solveh_banded(bands, rhs.reshape(size, -1), lower=False,
                                       check_finite=False).reshape(size, n, width)
    return animation, frame, rotation_exp(e[..., :3]) @ U[src], S[src] + e[..., 3:]


def blend_rigid(R, t, pivots, sources, windows, select=None, spread_velocity=True, clips=None):
    """:func:`blend_series` of rigid transforms x ↦ R x + t about their ``pivots``: the rotation
    and the position each takes its pivot to are blended, so a transform that turns a lot while
    its pivot barely moves stays put there (blending R and t apart turns about the origin and
    swings what lies far from it). R (F, n, 3, 3), t (F, n, 3), pivots (n, 3). Returns
    ``(animation (L,), frame (L,), R̃ (L, n, 3, 3), t̃ (L, n, 3))``."""
    animation, frame, rotation, position = blend_series(R, np.einsum("fbij,bj->fbi", R, pivots) + t, sources,
                                                        windows, select, spread_velocity, clips)
    return animation, frame, rotation, position - np.einsum("lbij,bj->lbi", rotation, pivots)


def _window_blocks(counts, block_frames):
    """Group the windows (in order) that have free frames by where their first frame falls:
    ⌊offset / block_frames⌋ over the stacked free frames, so a group holds at most block_frames
    frames plus one window's."""
    start = np.cumsum(counts) - counts
    keep = np.flatnonzero(counts > 0)
    group = start[keep] // block_frames
    cuts = np.flatnonzero(np.diff(group)) + 1
    return np.split(keep, cuts) if keep.size else []


@dataclass
class SplicedWalks:
    """A walks of one component spliced, in the local form of Zheng eq. 10.

    ``rotation (A, M, 3, 3)``, ``translation (A, M, 3)``: the reference bone's output poses
    (eq. 7, float64; None when not asked for); ``F (A, M, b, 3, 3)``, ``t (A, M, b, 3)``: every
    bone of the component in the reference bone's frame, in ``component.bones`` order, the
    reference itself at (I, 0).
    World positions are the rigid motion applied to the local ones (:meth:`world`); keeping the
    two apart lets assembly compose its own rigid turn with the reference's before touching the
    (large) local arrays once."""

    rotation: np.ndarray
    translation: np.ndarray
    F: np.ndarray
    t: np.ndarray

    def world(self, dtype=None, animation_block=16):
        """Eq. 10 for every frame: ``(F_world (A, M, b, 3, 3), t_world (A, M, b, 3))``."""
        if self.rotation is None:
            raise ValueError("these walks were spliced without the reference motion (reference_motion=False)")
        dtype = self.F.dtype if dtype is None else dtype
        F_out = np.empty(self.F.shape, dtype=dtype)
        t_out = np.empty(self.t.shape, dtype=dtype)
        apply_rigid_into(F_out, t_out, np.arange(self.F.shape[2]), self.rotation, self.translation, self.F, self.t,
                         animation_block=animation_block)
        return F_out, t_out


def splice(component, rotations, translations, sources, window=8, dtype=np.float64, anchored=True,
           block_frames=8192, animation_block=16, spread_velocity=True, damped_bones=(), damping=0.0, blend="bones",
           pivots=None, clips=None):
    """World bone positions of A walks of one bone component (Zheng §3.3; module notes):
    :func:`splice_local` then eq. 10. Returns ``(F_world (A, M, b, 3, 3), t_world (A, M, b, 3))``
    in the order of ``component.bones``; the reference bone's F is a rotation, the others'
    general affine matrices inside windows and the source's rotations elsewhere."""
    spliced = splice_local(component, rotations, translations, sources, window=window, dtype=dtype,
                           anchored=anchored, block_frames=block_frames, spread_velocity=spread_velocity,
                           damped_bones=damped_bones, damping=damping, blend=blend, pivots=pivots, clips=clips)
    return spliced.world(animation_block=animation_block)


def splice_local(component, rotations, translations, sources, window=8, dtype=np.float64, anchored=True,
                 block_frames=8192, reference_motion=True, spread_velocity=True, damped_bones=(), damping=0.0,
                 blend="bones", pivots=None, up=None, clips=None):
    """Splice A walks of one bone component (Zheng §3.3; module notes) -> :class:`SplicedWalks`.

    component: a :class:`.graph.ComponentAnalysis` (bones, transitions.reference,
    transitions.local_bones, strain (F, n, 9), operator); rotations (F, B, 3, 3), translations
    (F, B, 3): the input skin fit (all B bones; the component's are used); sources (A, M) (or (M,),
    taken as A = 1) input frame per output frame; window: blend frames on each side of a seam;
    dtype of the local positions; anchored: eq. 9 solved for the change from the source positions
    (default) or plainly; block_frames: memory bound (module notes); reference_motion: False
    skips eq. 7 (``rotation`` and ``translation`` are then None) for a component that assembly
    carries onto another through a cut node, where the reference's own motion cancels;
    spread_velocity: the seam's velocity jump spread over the window (module notes);
    damped_bones, damping: with the anchored solve, those bones' change from the source pulled
    towards 0 (:meth:`.deformation_gradients.GradientOperator.solve_damped`; module notes).
    blend: "bones" (each bone's rotation and where it takes its pivot, blended in the reference
    bone's frame: bones stay rigid) or "key-vertices" (Zheng eq. 8–9, affine bones); pivots
    (B, 3): each bone's rest point its blend turns about (default the origin; the synthesizer
    passes the bones' rest centroids); up: None for Zheng's eq. 7, or the up axis (3,) for its
    ground-plane form (:func:`reference_alignment`); clips: a :class:`~skinsynth.pipeline.inputs.clips.Clips`
    of the F input frames when they are several clips (seams, transitions and the frames before
    and after each clip per clip: module notes), None for one clip.
    """
    bones = np.asarray(component.bones, dtype=np.int64)
    reference = int(component.transitions.reference)
    local_bones = np.asarray(component.transitions.local_bones, dtype=np.int64)
    operator = component.operator
    strain = np.asarray(component.strain, dtype=np.float64)
    rotations = np.asarray(rotations, dtype=np.float64)
    translations = np.asarray(translations, dtype=np.float64)
    frames = rotations.shape[0]
    if rotations.shape[2:] != (3, 3) or translations.shape != rotations.shape[:2] + (3,):
        raise ValueError(f"rotations {rotations.shape} and translations {translations.shape} do not match "
                         "(F, B, 3, 3) and (F, B, 3)")
    if strain.shape[0] != frames:
        raise ValueError(f"the component's strain series has {strain.shape[0]} frames, the fit {frames}")
    if operator is None:
        raise ValueError("the component has no eq. 9 operator")
    if not np.array_equal(np.asarray(operator.bone_ids), local_bones):
        raise ValueError("the operator's bones differ from the component's local bones")
    sources = walk_sources(sources, frames)
    clips = walk_clips(clips, frames)
    windows = seam_windows(sources, window, clips)
    b = bones.size

    R_ref = t_ref = None
    if reference_motion:
        pivot = None if pivots is None else np.asarray(pivots, dtype=np.float64)[reference]
        R_ref, t_ref = reference_alignment(rotations[:, reference], translations[:, reference], sources, up=up,
                                           pivot=pivot, window=window, spread_velocity=spread_velocity,
                                           clips=clips)  # eq. 7
    F_in, t_in, ids = local_frame_positions(rotations, translations, reference, bones)  # eq. 2, (F, b−1, …)
    if not np.array_equal(np.asarray(ids), local_bones):
        raise ValueError("the component's local bones are not its bones without the reference")
    at_local = np.searchsorted(bones, local_bones)
    # All b bones in the reference frame, the reference itself at (I, 0): eq. 10 then gives it
    # F = R̃_r, t = t̃_r exactly (products with 0 and 1 are exact).
    F_all = np.broadcast_to(np.eye(3), (frames, b, 3, 3)).astype(dtype)
    t_all = np.zeros((frames, b, 3), dtype=dtype)
    F_all[:, at_local] = F_in
    t_all[:, at_local] = t_in
    # Step 2: the source frames' local positions (window frames overwritten below).
    spliced = SplicedWalks(rotation=R_ref, translation=t_ref, F=F_all[sources], t=t_all[sources])

    # Steps 3–4 at the window frames, once per distinct window (module notes: memoised windows).
    if local_bones.size == 0 or windows.counts.sum() == 0:
        return spliced
    signatures, unique, inverse = distinct_windows(sources, windows)
    pivots = np.zeros((rotations.shape[1], 3)) if pivots is None else np.asarray(pivots, dtype=np.float64)
    F_win, t_win = _blend_local(operator, strain, F_in, t_in, signatures, unique, anchored, block_frames,
                                spread_velocity, damped_bones, damping, blend, pivots[local_bones], clips)
    start = np.cumsum(unique.counts) - unique.counts  # first row of each distinct window in F_win
    used = np.flatnonzero(windows.counts > 0)
    animation, frame, owner, _, _ = windows.frames(used)
    row = start[inverse[owner]] + (frame - windows.left[owner] - 1)
    step = max(1, int(block_frames))
    for lo in range(0, row.size, step):
        a, k, r = animation[lo:lo + step, None], frame[lo:lo + step, None], row[lo:lo + step]
        spliced.F[a, k, at_local[None, :]] = F_win[r]
        spliced.t[a, k, at_local[None, :]] = t_win[r]
    return spliced


def distinct_windows(sources, windows):
    """Windows with free frames, deduplicated by their source frames (module notes).

    Returns ``(signatures (U, W) int64, unique SeamWindows over them, inverse (S,))``: row u of
    ``signatures`` is the source frames left … right of a distinct window (padded with 0), the
    ``unique`` windows are ``left = 0, right = its length − 1`` on row u, and ``inverse[s]`` is the
    distinct window of window s (−1 for windows without free frames)."""
    used = np.flatnonzero(windows.counts > 0)
    inverse = np.full(windows.seam.size, -1, dtype=np.int64)
    if used.size == 0:
        empty = np.zeros(0, np.int64)
        return np.zeros((0, 1), np.int64), SeamWindows(empty, empty, empty, empty), inverse
    left, right = windows.left[used], windows.right[used]
    length = right - left + 1
    offset = np.arange(int(length.max()))
    valid = offset[None, :] < length[:, None]
    frame = np.where(valid, left[:, None] + offset[None, :], 0)
    # −1 past the end keeps windows of different lengths apart.
    keys = np.where(valid, sources[windows.animation[used][:, None], frame], -1)
    keys, first, inverse_used = unique_rows(keys, return_index=True, return_inverse=True)
    inverse[used] = inverse_used.reshape(-1)
    count = keys.shape[0]
    unique = SeamWindows(animation=np.arange(count, dtype=np.int64), seam=(windows.seam[used] - left)[first],
                         left=np.zeros(count, np.int64), right=length[first] - 1)
    return np.maximum(keys, 0), unique, inverse


def _blend_local(operator, strain, F_in, t_in, signatures, unique, anchored, block_frames, spread_velocity,
                 damped_bones, damping, blend="bones", pivots=None, clips=None):
    """Steps 3–4 for the distinct windows: local positions of the local bones at their free frames,
    ``(F_local (L, b−1, 3, 3), t_local (L, b−1, 3))`` in :meth:`SeamWindows.frames` order.
    pivots (b−1, 3): the rest points the bones blend about (``blend="bones"``); clips: the input's
    (the windows' source frames are global frames; None: one clip)."""
    if blend != "bones":
        U, S = gradient_series(strain)
        D_in = rotation_times_strain(U, S)  # (F, n, 3, 3): the input gradients
        constant = operator.constant.reshape(-1, 3, 3)
    total = int(unique.counts.sum())
    F_local = np.empty((total,) + F_in.shape[1:])
    t_local = np.empty((total,) + t_in.shape[1:])
    at = 0
    for select in _window_blocks(unique.counts, max(1, int(block_frames))):
        if blend == "bones":
            _, frame, F_block, t_block = blend_rigid(F_in, t_in, pivots, signatures, unique, select, spread_velocity,
                                                     clips)
        else:
            animation, frame, rotation, linear = blend_series(U, S, signatures, unique, select, spread_velocity,
                                                              clips)
            D_tilde = rotation_times_strain(rotation, linear)
            src = signatures[animation, frame]
            if anchored:
                D_tilde -= D_in[src]
                D_tilde += constant
                dF, dt = operator.solve_damped(D_tilde, damped_bones, damping)  # G⁺(D̃ − D(source))
                F_block, t_block = F_in[src] + dF, t_in[src] + dt
            else:
                F_block, t_block = operator.solve(D_tilde)  # Zheng eq. 9
        F_local[at:at + frame.size], t_local[at:at + frame.size] = F_block, t_block
        at += frame.size
    return F_local, t_local
