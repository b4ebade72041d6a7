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
3. Around each seam (:func:`seam_windows`, :func:`blend_rotation_strain`): the rotation-strain
   coordinates d of every key vertex are re-solved over a window by the 1D Poisson equation
   d̃(m−1) − 2 d̃(m) + d̃(m+1) = g(m) at each free frame m, g(m) the second difference of the input
   series at source[m] with *its own* input neighbours (so the jump itself is never a second
   difference), and Dirichlet values at the two frames just outside the free run: d̃ = d(source)
   there (those frames keep their exact positions). The matrix is the same for all 9n
   coordinates, so every window of every animation is one diagonal block of one symmetric
   positive-definite tridiagonal system (the negated Laplacian, zero couplings between windows)
   with 9n right-hand sides: one ``scipy.linalg.solveh_banded`` call (LAPACK ptsv, O(L·9n)) for
   all windows, or one per group of whole windows when they hold more than ``block_frames``
   frames (memory bound; the blocks are independent, so the result is the same).
4. Blended d̃ → D̃ (:func:`rotation_strain_to_matrix`) → eq. 9 for the local positions of the
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

Input-clip ends: g at input frame 0 or F−1 has no neighbour on one side; it uses the second
difference of frame 1 or F−2 (the nearest complete one). With fewer than 3 input frames g = 0.

Branch cut: d's rotation part is an axis-angle vector (angle in [0, π]); a key vertex whose
local rotation crosses π flips its vector, and the blend sees that as a jump (the limitation
:func:`.transitions.bone_coordinate_matrix` shares). Local-frame key-vertex rotations are
normally far from π.

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

from .deformation_gradients import rotation_strain_to_matrix
from .rotations import apply_rigid
from .transitions import local_frame_positions


def walk_sources(sources, frames):
    """Validate walks: ``sources`` (A, M) or (M,) ints in [0, frames) -> int64 (A, M).

    Every seam must land on a frame ≥ 1 (a seam k plays source[k] = j + 1 after identifying j
    with source[k−1], so j = source[k] − 1 must exist).
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
    seam = sources[:, 1:] != sources[:, :-1] + 1
    if np.any(seam & (sources[:, 1:] == 0)):
        a, k = np.argwhere(seam & (sources[:, 1:] == 0))[0]
        raise ValueError(f"animation {a} jumps to input frame 0 at output frame {k + 1}: a transition (i, j) "
                         "continues at j + 1 ≥ 1")
    return sources


def walk_seams(sources):
    """Seams of walks (A, M): ``(animation (S,), k (S,))``, sorted by animation then k."""
    sources = np.asarray(sources)
    animation, k = np.nonzero(sources[:, 1:] != sources[:, :-1] + 1)
    return animation.astype(np.int64), (k + 1).astype(np.int64)


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


def seam_windows(sources, window=8):
    """Windows around every seam of walks (A, M), clipped as in the module notes -> SeamWindows."""
    sources = np.asarray(sources)
    if int(window) != window or window < 0:
        raise ValueError(f"window must be a non-negative integer, got {window}")
    window = int(window)
    frames = sources.shape[1]
    animation, k = walk_seams(sources)
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


def reference_alignment(R_ref, t_ref, sources):
    """Output reference-bone poses along walks by Zheng eq. 7.

    R_ref (F, 3, 3), t_ref (F, 3): the input reference bone; sources (A, M) validated walks.
    Returns (R̃ (A, M, 3, 3), t̃ (A, M, 3)) = G_k ∘ P(source[k]), G the accumulated rigid offsets
    (identity before the first seam; at a seam k with i = source[k−1], j = source[k] − 1,
    G ← G ∘ P(i) ∘ P(j)⁻¹).
    """
    R_ref = np.asarray(R_ref, dtype=np.float64)
    t_ref = np.asarray(t_ref, dtype=np.float64)
    count, frames = sources.shape
    animation, k = walk_seams(sources)
    # G is constant between seams: compose it once per seam (a loop over the seam rank, batched
    # over animations), then look it up per frame by segment number.
    is_seam = np.zeros((count, frames), dtype=bool)
    is_seam[animation, k] = True
    segment = np.cumsum(is_seam, axis=1)  # (A, M) segment number of each output frame
    segments = int(segment[:, -1].max()) if frames else 0
    rel_R = np.broadcast_to(np.eye(3), (count, segments, 3, 3)).copy()
    rel_t = np.zeros((count, segments, 3))
    if k.size:
        i = sources[animation, k - 1]
        j = sources[animation, k] - 1
        # P(i) ∘ P(j)⁻¹ = (R_i R_jᵀ, t_i − R_i R_jᵀ t_j): Zheng eq. 7's fixed rigid transform.
        rel = R_ref[i] @ np.swapaxes(R_ref[j], -1, -2)
        rank = segment[animation, k] - 1
        rel_R[animation, rank] = rel
        rel_t[animation, rank] = t_ref[i] - np.einsum("sab,sb->sa", rel, t_ref[j])
    G_R = np.empty((count, segments + 1, 3, 3))
    G_t = np.empty((count, segments + 1, 3))
    G_R[:, 0], G_t[:, 0] = np.eye(3), 0.0
    for r in range(segments):
        G_R[:, r + 1] = G_R[:, r] @ rel_R[:, r]
        G_t[:, r + 1] = np.einsum("aij,aj->ai", G_R[:, r], rel_t[:, r]) + G_t[:, r]
    rows = np.arange(count)[:, None]
    R_out = G_R[rows, segment] @ R_ref[sources]
    t_out = np.einsum("amij,amj->ami", G_R[rows, segment], t_ref[sources]) + G_t[rows, segment]
    return R_out, t_out


def nearest_branch(w, reference):
    """The axis-angle vector of the same rotation as w (…, 3) closest to ``reference`` (…, 3).

    A rotation by θ about k is also one by θ − 2π about k (and θ + 2π): near θ = π the principal
    vectors of two similar rotations can point in opposite directions, which a blend would read
    as a jump of ~2π. Of w and w ∓ 2π k, the closer to the reference is w − 2π k exactly when
    k·(w − reference) > π (and w + 2π k when it is < −π): one dot product, no candidates stacked."""
    theta = np.sqrt(np.sum(w * w, axis=-1, keepdims=True))
    axis = np.divide(w, theta, out=np.zeros_like(w), where=theta > 0.0)
    along = np.sum(axis * (w - reference), axis=-1, keepdims=True)
    shift = np.where(along > np.pi, -2.0 * np.pi, np.where(along < -np.pi, 2.0 * np.pi, 0.0))
    return w + shift * axis


def strain_second_differences(strain):
    """g of the module notes: strain (F, n, 9) -> (F, n, 9) second differences d(f−1) − 2d(f) +
    d(f+1), frames 0 and F−1 copying frames 1 and F−2; zero with fewer than 3 frames. The
    neighbours' rotation vectors are taken on the branch nearest to d(f)'s (:func:`nearest_branch`)."""
    strain = np.asarray(strain, dtype=np.float64)
    g = np.zeros_like(strain)
    if strain.shape[0] >= 3:
        before = strain[:-2].copy()
        after = strain[2:].copy()
        before[..., :3] = nearest_branch(before[..., :3], strain[1:-1, ..., :3])
        after[..., :3] = nearest_branch(after[..., :3], strain[1:-1, ..., :3])
        g[1:-1] = before - 2.0 * strain[1:-1] + after
        g[0] = g[1]
        g[-1] = g[-2]
    return g


def seam_velocity_jumps(strain, sources, windows, win):
    """δ (W, n, 9) of windows ``win``: the input's velocity into the frame played after the seam,
    d(j+1) − d(j), minus the velocity the left segment would have gone on with, d(i+1) − d(i);
    0 where i is the clip's last frame (nothing says how it would have gone on, and an exact loop
    closing there must stay exact). Rotation vectors are differenced on one branch."""
    a, k = windows.animation[win], windows.seam[win]
    frames = strain.shape[0]
    i, after = sources[a, k - 1], sources[a, k]
    ahead = np.minimum(i + 1, frames - 1)

    def velocity(to, since):
        step = strain[to] - strain[since]
        step[..., :3] = nearest_branch(strain[to][..., :3], strain[since][..., :3]) - strain[since][..., :3]
        return step

    jumps = velocity(after, after - 1) - velocity(ahead, ahead - 1)
    jumps[i + 1 >= frames] = 0.0
    return jumps


def blend_rotation_strain(strain, sources, windows, select=None, second=None, spread_velocity=True):
    """Poisson-blended rotation-strain coordinates at the free frames of windows (step 3).

    strain (F, n, 9) the input series; sources (A, M); windows a :class:`SeamWindows`;
    ``select`` the windows to solve (default all); ``second`` precomputed
    :func:`strain_second_differences` (optional); ``spread_velocity``: add δ/(R − L + 1) to every
    free frame's g (module notes). Returns ``(animation (L,), frame (L,), d̃ (L, n, 9))`` in
    :meth:`SeamWindows.frames` order. One banded Cholesky solve (``solveh_banded``) of the stacked
    block-tridiagonal system −Δ d̃ = −g + boundary values, with all n·9 coordinates as right-hand
    sides.
    """
    strain = np.asarray(strain, dtype=np.float64)
    second = strain_second_differences(strain) if second is None else second
    animation, frame, owner, first, last = windows.frames(select)
    size, shape = frame.size, strain.shape[1:]
    if size == 0:
        return animation, frame, np.zeros((0,) + shape)
    # −Δ: 2 on the diagonal, −1 between consecutive free frames of one window (upper form).
    bands = np.empty((2, size))
    bands[1] = 2.0
    bands[0] = np.where(first, 0.0, -1.0)
    rhs = -second[sources[animation, frame]]
    if spread_velocity:  # the seam's velocity jump as an even extra acceleration over the window
        win_all = owner[first]
        jumps = seam_velocity_jumps(strain, sources, windows, win_all)  # (W, n, 9)
        span = (windows.right[win_all] - windows.left[win_all] + 1).astype(float)
        rhs -= (jumps / span[:, None, None])[np.searchsorted(win_all, owner)]
    # Dirichlet ends: the fixed frames keep the input values of their source frames. The right
    # end's rotation vectors are carried along the window's source frames onto the branch that
    # continues the left end's, so a window never interpolates across a 2π wrap.
    win = owner[first]
    left_values = strain[sources[windows.animation[win], windows.left[win]]]  # (W, n, 9)
    right_values = _continued(strain, sources, windows, win, left_values)
    rhs[first] += left_values
    rhs[last] += right_values[np.searchsorted(win, owner[last])]
    if size == 1:  # LAPACK ptsv refuses an empty off-diagonal
        solved = rhs.reshape(1, -1) / 2.0
    else:
        solved = scipy.linalg.solveh_banded(bands, rhs.reshape(size, -1), lower=False, check_finite=False)
    return animation, frame, solved.reshape((size,) + shape)


def _continued(strain, sources, windows, win, left_values):
    """Right-end values of windows ``win`` with rotation vectors unwrapped from the left end along
    the source frames between them (a loop over the window length, batched over windows)."""
    a, lo, hi = windows.animation[win], windows.left[win], windows.right[win]
    current = left_values[..., :3].copy()
    for offset in range(1, int((hi - lo).max()) + 1 if win.size else 0):
        active = lo + offset <= hi
        frame = np.minimum(lo + offset, hi)
        step = strain[sources[a, frame]][..., :3]
        current = np.where(active[:, None, None], nearest_branch(step, current), current)
    out = strain[sources[a, hi]].copy()
    out[..., :3] = current
    return out


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


def apply_rigid_into(F_out, t_out, slots, rotation, translation, F, t, rows=None, bones=None, animation_block=16):
    """``F_out[a, :, slots] = rotation[a] F[rows[a], :, bones]`` and ``t_out[a, :, slots] =
    rotation[a] t[rows[a], :, bones] + translation[a]`` for every animation a, in blocks of
    ``animation_block`` animations (float64 arithmetic, stored in the outputs' dtype).

    F_out (A, M, B, 3, 3), t_out (A, M, B, 3); slots (k,) bone slots of the outputs; rotation
    (A, M, 3, 3), translation (A, M, 3); F (A', M, b, 3, 3), t (A', M, b, 3); rows (A,) the
    animation of F per output animation (default the same); bones (k,) the bones of F (default all)."""
    count, frames = F_out.shape[:2]
    slots = np.asarray(slots)
    all_bones = bones is None or np.array_equal(bones, np.arange(F.shape[2]))
    bones = np.arange(F.shape[2]) if bones is None else np.asarray(bones)
    whole = slots.size == F_out.shape[2] and np.array_equal(slots, np.arange(slots.size))
    step = max(1, int(animation_block))
    for a0 in range(0, count, step):
        block = slice(a0, min(count, a0 + step))
        n = block.stop - a0
        # Views where possible: gathers copy (rows picks other walks, bones drops the cut).
        F_local, t_local = (F[block], t[block]) if rows is None else (F[rows[block]], t[rows[block]])
        if not all_bones:
            F_local, t_local = F_local[:, :, bones], t_local[:, :, bones]
        F_local = F_local.reshape(n * frames, bones.size, 3, 3)
        t_local = t_local.reshape(n * frames, bones.size, 3)
        F_world, t_world = apply_rigid(rotation[block].reshape(-1, 3, 3), translation[block].reshape(-1, 3),
                                       F_local, t_local)
        F_world = F_world.reshape(n, frames, bones.size, 3, 3)
        t_world = t_world.reshape(n, frames, bones.size, 3)
        if whole:
            F_out[block], t_out[block] = F_world, t_world
        else:
            F_out[block, :, slots], t_out[block, :, slots] = F_world, t_world


def splice(component, rotations, translations, sources, window=8, dtype=np.float64, anchored=True,
           block_frames=8192, animation_block=16, spread_velocity=True, damped_bones=(), damping=0.0):
    """World bone positions of A walks of one bone component (Zheng §3.3; module notes):
    :func:`splice_local` then eq. 10. Returns ``(F_world (A, M, b, 3, 3), t_world (A, M, b, 3))``
    in the order of ``component.bones``; the reference bone's F is a rotation, the others'
    general affine matrices inside windows and the source's rotations elsewhere."""
    spliced = splice_local(component, rotations, translations, sources, window=window, dtype=dtype,
                           anchored=anchored, block_frames=block_frames, spread_velocity=spread_velocity,
                           damped_bones=damped_bones, damping=damping)
    return spliced.world(animation_block=animation_block)


def splice_local(component, rotations, translations, sources, window=8, dtype=np.float64, anchored=True,
                 block_frames=8192, reference_motion=True, spread_velocity=True, damped_bones=(), damping=0.0):
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
    windows = seam_windows(sources, window)
    b = bones.size

    R_ref = t_ref = None
    if reference_motion:
        R_ref, t_ref = reference_alignment(rotations[:, reference], translations[:, reference], sources)  # eq. 7
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
    F_win, t_win = _blend_local(operator, strain, F_in, t_in, signatures, unique, anchored, block_frames,
                                spread_velocity, damped_bones, damping)
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
    keys, first, inverse_used = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse[used] = inverse_used.reshape(-1)
    count = keys.shape[0]
    unique = SeamWindows(animation=np.arange(count, dtype=np.int64), seam=(windows.seam[used] - left)[first],
                         left=np.zeros(count, np.int64), right=length[first] - 1)
    return np.maximum(keys, 0), unique, inverse


def _blend_local(operator, strain, F_in, t_in, signatures, unique, anchored, block_frames, spread_velocity,
                 damped_bones, damping):
    """Steps 3–4 for the distinct windows: local positions of the local bones at their free frames,
    ``(F_local (L, b−1, 3, 3), t_local (L, b−1, 3))`` in :meth:`SeamWindows.frames` order."""
    second = strain_second_differences(strain)
    D_in = rotation_strain_to_matrix(strain)  # (F, n, 3, 3): the input gradients, as the strain has them
    constant = operator.constant.reshape(-1, 3, 3)
    total = int(unique.counts.sum())
    F_local = np.empty((total,) + F_in.shape[1:])
    t_local = np.empty((total,) + t_in.shape[1:])
    at = 0
    for select in _window_blocks(unique.counts, max(1, int(block_frames))):
        animation, frame, d_tilde = blend_rotation_strain(strain, signatures, unique, select, second,
                                                          spread_velocity)
        D_tilde = rotation_strain_to_matrix(d_tilde)  # (L, n, 3, 3)
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
