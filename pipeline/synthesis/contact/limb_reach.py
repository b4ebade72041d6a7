"""A planted foot moved as a skeleton moves it: inverse kinematics of its limb's joints (issue 62),
compiled, frame by frame.

The plants (:mod:`.planting`) decide where each patch should be at each output frame: its centroid
``centre`` moved by ``shift`` (the limb's correction), its anchor bone turned by ``turn``, the whole
body moved by the root's offset. This module makes the limb do it with its joints
(:mod:`.limb_chains`): each joint k of a limb turns everything on its limb side by a rotation ρ_k
about the joint's point, so x ↦ A_k x + g_k with, down the chain, A_k = A_p ρ_k and
g_k = A_p (P_k − ρ_k P_k) + g_p (P_k the joint's point where the body-side bone carries it, A_p, g_p
its parent joint's). Two bones on either side of a joint carry its point to the same place, so the
skin between them bends as the rig bends it and never shears; bone lengths are kept exactly.

**The solve.** Each frame minimises, over the turns of a limb's joints (a foot's patches together),

    Σ_p ‖c_p(ρ) − (c_p + e_p)‖² + (ℓ_p ‖log(A T_pᵀ)‖)²  +  Σ_k (λ ℓ_k ‖D_k (z_k − z⁰_k)‖)²

(c_p the patch's centroid Σ_b F_b ā_pb + ω_pb t_b, each bone's part moved by its last joint's map,
as the patch itself moves; e_p the shift; T_p the turn; A the anchor bone's last joint's turn;
ℓ_p the patch's size, so a turn weighs as the patch's vertices move), by Gauss–Newton from the last frame's turns (:data:`WARM_STEPS`; :data:`COLD_STEPS` from
rest). z_k are the joint's coordinates: the logarithm of its bone's rotation relative to its
parent's, about the mean the input shows, along the principal axes of the turns the input shows
(:class:`.limb_chains.JointRange`), of the joint as turned (:func:`_coordinates`, exact at every
step); z⁰_k the frame's own, uncorrected; each step moves them by C_k A_pᵀ ε_k (C_k = U_kᵀ Q̄_kᵀ R_kᵀ,
R_k the body-side bone's rotation: a turn of the limb side in the joint's coordinates, to first
order, as Gauss–Newton needs). The prior weighs each axis by
D_k = max_i s_ki / max(s_ki, :data:`STIFF` · max_i s_ki) (s_k the spreads along the axes): a turn
along a joint's own hinge costs λ ℓ_k per radian (ℓ_k the reach of its limb side) and a turn across
it up to 1/:data:`STIFF` times as much, so a knee bends and does not twist, and a limb's correction
goes to the joints that move most in the input. λ = :data:`PRIOR` is small: where a patch can be
reached it is reached, and the prior chooses among the ways to reach it.

**The range** (issue 62: within the joint ranges the input itself shows). Along each axis a joint
may go :data:`RANGE_MARGIN` beyond the least and largest coordinate the input shows, or as far as the
uncorrected frame already has it; beyond that a stiff spring (:data:`RANGE_STIFFNESS`) holds it at the
edge, inside the same solve, so the solution moves smoothly with its targets and the foot misses
what the limb cannot reach: a foot may slide a little, the body never breaks.

**The skin.** A solution within every joint's range can still be a combination of turns the input
never shows, which strains the skin blended at a joint (a horse's hips turned to plant a foot of
another clip). Each frame's solution is checked on the limb's seams before it is followed
(:mod:`.limb_shape`) and halved, or let go, where it would tear them.

**No pops.** A target the limb can barely reach can swing the solution from one frame to the next
(a straight knee: a small change of the target, a large turn of the hip). What is applied is each
joint's turn as it follows the solution with bounded acceleration (:func:`_track`, in its body-side
bone's frame, where a held correction stays still): the step of its turn changes by at most
:data:`JOINT_ACCEL` × the plants' limit over the joint's reach (radians a frame²), the same limit
that bounds the plants' other corrections (:data:`.planting.EDGE_ACCEL`). On the dancer's four
components, unfollowed solutions threw the feet at 3.2× the input's largest acceleration (1.26×
followed); on the samba's single component the feet's slide at the 95th percentile is 1.5 times
what it is unfollowed, and the largest acceleration 2.4 times smaller.

Every workspace array is made once per limb (:func:`reach_animations`), not per frame.
"""

import numba
import numpy as np

from .limb_shape import seam_tears
from .planting_loops import _mul, _rotation_exp, _rotation_log

#: λ: the prior's weight (module notes). A turn that moves the limb's far end by 1 cm costs as a miss
#: of λ cm: at 0.05 a reachable patch lands within a few thousandths of its shift.
PRIOR = 0.05
#: The least spread along a joint's axes the prior assumes, as a share of its largest (module notes):
#: a turn across a hinge costs at most 1/STIFF times one along it.
STIFF = 0.1
#: How far (radians) past the range the input shows a joint may turn along each principal axis
#: (module notes). 5°: the range of a joint over a clip of a few seconds is a sample of its motion.
RANGE_MARGIN = np.radians(5.0)
#: The spring at a joint's range: a turn beyond it costs as a miss of RANGE_STIFFNESS × its reach per
#: radian (a degree past the range as a miss of a sixth of the limb's length at 10): the range holds
#: to a fraction of a degree against any target.
RANGE_STIFFNESS = 10.0
#: What a joint's turn may add to the acceleration at its reach, as a multiple of the plants' own
#: limit (:data:`.planting.EDGE_ACCEL` of the input's largest vertex acceleration). A trade of slide
#: for acceleration (20 × 600, seed 3): at 1.5 the dancer's four components slid 2.64 / 3.74 / 2.45×
#: the input's (median / p95 / share; 3.20 / 4.25 / 2.68× at 1) with a smaller worst acceleration
#: (1.32×; 1.39×), but the merged walker's worst rose from 1.29× to 1.54× the input's, the cow's
#: from 1.12× to 1.29×, and the horse's clips broke 0.51 % of their frames (0.40 %); at 1/3 the
#: dancer's feet slid 9× the input's.
JOINT_ACCEL = 1.0
#: Gauss–Newton steps of a frame solved from the last frame's turns, and from rest.
WARM_STEPS = 1
COLD_STEPS = 6


@numba.njit(cache=True, nogil=True)
def _matvec(a, v, out):
    """out = a v (3 × 3, 3)."""
    for i in range(3):
        out[i] = a[i, 0] * v[0] + a[i, 1] * v[1] + a[i, 2] * v[2]


@numba.njit(cache=True, nogil=True)
def _forward(rho, parent, pivot, A, g, now):
    """A (n, 3, 3), g (n, 3): each joint's map x ↦ A x + g of its limb side, from its turn rho (n, 3, 3)
    and its parent's (module notes; parent (n,), −1 at the chain's top, parents first); now (n, 3)
    its point (pivot (n, 3), uncorrected) where its parent's map takes it."""
    for i in range(rho.shape[0]):
        p = parent[i]
        for x in range(3):
            if p >= 0:
                now[i, x] = A[p, x, 0] * pivot[i, 0] + A[p, x, 1] * pivot[i, 1] + A[p, x, 2] * pivot[i, 2] + g[p, x]
                for y in range(3):
                    A[i, x, y] = A[p, x, 0] * rho[i, 0, y] + A[p, x, 1] * rho[i, 1, y] + A[p, x, 2] * rho[i, 2, y]
            else:
                now[i, x] = pivot[i, x]
                for y in range(3):
                    A[i, x, y] = rho[i, x, y]
        for x in range(3):  # g = A_p (P − ρ P) + g_p = now − A P
            g[i, x] = now[i, x] - (A[i, x, 0] * pivot[i, 0] + A[i, x, 1] * pivot[i, 1] + A[i, x, 2] * pivot[i, 2])


@numba.njit(cache=True, nogil=True)
def _cholesky_solve(H, b, size):
    """Solve H x = b for the first ``size`` rows, x written into b (H symmetric positive definite,
    overwritten by its factor)."""
    for j in range(size):
        total = H[j, j]
        for k in range(j):
            total -= H[j, k] * H[j, k]
        H[j, j] = np.sqrt(max(total, 1e-300))
        for i in range(j + 1, size):
            total = H[i, j]
            for k in range(j):
                total -= H[i, k] * H[j, k]
            H[i, j] = total / H[j, j]
    for i in range(size):
        total = b[i]
        for k in range(i):
            total -= H[i, k] * b[k]
        b[i] = total / H[i, i]
    for i in range(size - 1, -1, -1):
        total = b[i]
        for k in range(i + 1, size):
            total -= H[k, i] * b[k]
        b[i] = total / H[i, i]


@numba.njit(cache=True, nogil=True)
def _coordinates(Rb, rho, Rl, mean, axes, out, work, work2, vec):
    """out (3,): a joint's coordinates z = Uᵀ log(Q̄ᵀ R_bᵀ ρ R_l) for its body-side bone's rotation Rb
    (3, 3), its limb side's Rl, a turn rho of the limb side, and the joint's mean Q̄ and axes U (3, 3)
    (work, work2 (3, 3), vec (3,): workspace)."""
    _mul(rho, Rl, work)
    for x in range(3):
        for y in range(3):
            work2[x, y] = Rb[0, x] * work[0, y] + Rb[1, x] * work[1, y] + Rb[2, x] * work[2, y]
    for x in range(3):
        for y in range(3):
            work[x, y] = mean[0, x] * work2[0, y] + mean[1, x] * work2[1, y] + mean[2, x] * work2[2, y]
    _rotation_log(work, vec)
    for i in range(3):
        out[i] = axes[0, i] * vec[0] + axes[1, i] * vec[1] + axes[2, i] * vec[2]


@numba.njit(cache=True, nogil=True)
def _track(goal, last, velocity, most):
    """Follow ``goal`` (3,) from ``last`` (3,), which moved by ``velocity`` (3,) the frame before,
    changing that step by at most ``most`` (both updated in place): towards the goal as fast as it
    can still stop there, so it neither overshoots nor pops. A goal that moves slower than that is
    followed exactly."""
    if not most < np.inf:  # no limit: the goal itself
        for d in range(3):
            velocity[d] = goal[d] - last[d]
            last[d] = goal[d]
        return
    gap = np.sqrt((goal[0] - last[0]) ** 2 + (goal[1] - last[1]) ** 2 + (goal[2] - last[2]) ** 2)
    # the largest step from which steps shrinking by ``most`` stop within the gap: u²/2a + u/2 = gap
    speed = np.sqrt(0.25 * most * most + 2.0 * most * gap) - 0.5 * most
    scale = 1.0 if gap <= speed else speed / gap
    change = 0.0
    for d in range(3):
        change += ((goal[d] - last[d]) * scale - velocity[d]) ** 2
    change = np.sqrt(change)
    cut = 1.0 if change <= most else most / change
    for d in range(3):
        step = velocity[d] + ((goal[d] - last[d]) * scale - velocity[d]) * cut
        last[d] += step
        velocity[d] = step


@numba.njit(cache=True, nogil=True)
def _unseen_joints(joints, rho, Rb, Rl, mean, axes, seen, z0, margin, z, work, work2, vec):
    """The joints of a limb turned by rho (n, 3, 3) farther than ``margin`` (radians) from their
    uncorrected pose z0 (n, 3) and from every pose the input shows them in (seen (K, S, 3), their
    coordinates in S input frames), as bits (i + 1 for joint i; 0: none). A joint within it bends
    its skin as the capture or its fit bends it: its seams need no check (:mod:`.limb_shape`).
    z (3,), work, work2 (3, 3), vec (3,): workspace."""
    limit = margin * margin
    unseen = 0
    for i in range(joints.shape[0]):
        k = joints[i]
        _coordinates(Rb[i], rho[i], Rl[i], mean[k], axes[k], z, work, work2, vec)
        near = (z[0] - z0[i, 0]) ** 2 + (z[1] - z0[i, 1]) ** 2 + (z[2] - z0[i, 2]) ** 2 <= limit
        f = 0
        while not near and f < seen.shape[1]:
            near = (z[0] - seen[k, f, 0]) ** 2 + (z[1] - seen[k, f, 1]) ** 2 + (z[2] - seen[k, f, 2]) ** 2 <= limit
            f += 1
        if not near:
            unseen |= 1 << (i + 1)
    return unseen


@numba.njit(cache=True, nogil=True)
def _kept(F, t, a, m, logs, applied, parent, point, A, g, now, halvings, measured, maps, rest, bone_indices,
          bone_weights, seam_vertices, seam_edges, seam_lengths, seam_one, seam_allowance, seam_masks, sides, unseen,
          budget, before, after, strain0):
    """The share of a limb's turns (logs (n, 3): each joint's, world axis-angle) that tears at most
    ``budget`` of its seams (:func:`.limb_shape.seam_tears`): 1, halved up to ``halvings`` times,
    or 0. applied, A, g, now: left as that share's turns and maps (:func:`_forward` about the
    joints' points ``point``); measured: the frame's own strain already measured (by a first call);
    the seams measured: those spanning the ``unseen`` joints (:func:`.limb_shape.seam_tears`)."""
    keep = 1.0
    for trial in range(halvings + 2):
        if trial > 0:
            keep = 0.5 ** trial if trial <= halvings else 0.0
        for i in range(logs.shape[0]):
            _rotation_exp(keep * logs[i, 0], keep * logs[i, 1], keep * logs[i, 2], applied[i])
        _forward(applied, parent, point, A, g, now)
        if keep == 0.0 or seam_tears(F, t, a, m, A, g, maps, rest, bone_indices, bone_weights, seam_vertices, seam_edges,
                                     seam_lengths, seam_one, seam_allowance, seam_masks, sides, unseen, before, after,
                                     strain0, measured or trial > 0) <= budget:
            break
    return keep


@numba.njit(cache=True, nogil=True)
def reach_limb(F, t, a, m, joints, parent, local, patches, patch_joint, joint_bone, joint_body, joint_point,
               joint_reach, range_mean, range_axes, range_frame, range_weight, range_low, range_high, range_seen, margin,
               prior,
               centre, shift, turn, lever, rho, warm, steps, bone_joint, limb_bones, part_bones, part_rest, part_weight,
               at, last, velocity, most, point, Rb, Rl, C, z0, A, g, now, applied, H, b, parts, X, W, on, m3a, m3b, m3c,
               v3a, v3b, v3c, v3d, v3e, maps, rest, bone_indices, bone_weights, seam_vertices, seam_edges, seam_lengths,
               seam_one, seam_allowance, seam_masks, sides, budget, halvings, before, after, strain0, logs):
    """One limb at output frame m of animation a (module notes), F, t in place: its joints (n,) (ids,
    parents first; parent (n,) in the limb, local (K,) each joint's place in it, −1 elsewhere) turned
    so that its patches (ids, each with its last joint patch_joint (P,)) reach their targets (pivot,
    shift (P, 3), turn (P, 3, 3) at this frame; lever (P,)), within their ranges; every bone whose
    last chain joint is one of them (bone_joint (B,)) moved. rho (n, 3, 3): the solved turns, the last
    frame's on entry when ``warm`` (the identity otherwise, and with ``steps`` 0: the joints let
    go). What is applied is each joint's turn as :func:`_track` follows it (last, velocity (n, 3): its
    last applied turn's log in its body-side bone's frame and that log's last step, updated; most
    (n,): the largest change of step, radians a frame²). A turn that tears the limb's seams
    (:func:`.limb_shape.seam_tears`: maps (B,) each bone's joint in the limb, −1: none; rest (V, 3),
    bone_indices, bone_weights (V, K) the skin; seam_* one limb's :class:`.limb_shape.LimbSeams`
    rows) beyond ``budget`` edges is halved up to ``halvings`` times, then let go. The rest:
    workspace. Returns (the number of joints held at the edge of their range, whether the turn was
    cut)."""
    n = joints.shape[0]
    for i in range(n):
        k = joints[i]
        body = joint_body[k]
        for x in range(3):
            point[i, x] = (F[a, m, body, x, 0] * joint_point[k, 0] + F[a, m, body, x, 1] * joint_point[k, 1]
                           + F[a, m, body, x, 2] * joint_point[k, 2] + t[a, m, body, x])
            for y in range(3):
                Rb[i, x, y] = F[a, m, body, x, y]
                Rl[i, x, y] = F[a, m, joint_bone[k], x, y]
                if not warm or steps == 0:
                    rho[i, x, y] = 1.0 if x == y else 0.0
        for u in range(3):  # C = Uᵀ Q̄ᵀ R_bᵀ: a turn of the limb side (world) in the joint's coordinates
            for v in range(3):
                C[i, u, v] = (range_frame[k, u, 0] * Rb[i, v, 0] + range_frame[k, u, 1] * Rb[i, v, 1]
                              + range_frame[k, u, 2] * Rb[i, v, 2])
        for x in range(3):
            for y in range(3):
                m3c[x, y] = 1.0 if x == y else 0.0
        _coordinates(Rb[i], m3c, Rl[i], range_mean[k], range_axes[k], z0[i], m3a, m3b, v3a)
    for q in range(patches.shape[0]):  # each patch's parts, F_b ā_pb + ω_pb t_b, as the frame has them
        p = patches[q]
        for k in range(part_bones.shape[0]):
            bone = part_bones[k]
            for x in range(3):
                parts[q, k, x] = (F[a, m, bone, x, 0] * part_rest[p, k, 0] + F[a, m, bone, x, 1] * part_rest[p, k, 1]
                                  + F[a, m, bone, x, 2] * part_rest[p, k, 2] + part_weight[p, k] * t[a, m, bone, x])
    size = 3 * n
    held = 0  # joints at the edge of their range, at the last step
    for step in range(steps):
        _forward(rho, parent, point, A, g, now)
        for u in range(size):
            b[u] = 0.0
            for v in range(size):
                H[u, v] = 0.0
        for q in range(patches.shape[0]):
            p = patches[q]
            # the patch's centroid Σ_b F_b ā_pb + ω_pb t_b, each bone's part moved by its last joint
            # in this limb (parts[q, k]: the part as the frame has it; at[k] its joint, −1: none); X_i,
            # W_i: the parts each joint i moves, summed, and their weight
            for i in range(n):
                W[i] = 0.0
                for d in range(3):
                    X[i, d] = 0.0
            for d in range(3):
                v3a[d] = 0.0
            for k in range(part_bones.shape[0]):
                if part_weight[p, k] <= 0.0:
                    continue
                i = at[k]
                if i >= 0:
                    _matvec(A[i], parts[q, k], v3b)
                    for d in range(3):
                        v3b[d] += part_weight[p, k] * g[i, d]
                else:
                    for d in range(3):
                        v3b[d] = parts[q, k, d]
                for d in range(3):
                    v3a[d] += v3b[d]
                while i >= 0:
                    W[i] += part_weight[p, k]
                    for d in range(3):
                        X[i, d] += v3b[d]
                    i = parent[i]
            for d in range(3):  # v3b: the centroid's miss
                v3b[d] = v3a[d] - centre[p, d] - shift[p, d]
            end = local[patch_joint[p]]
            for u in range(3):  # the anchor's turn: log(A Tᵀ), weighed by the patch's size
                for v in range(3):
                    m3a[u, v] = A[end, u, 0] * turn[p, v, 0] + A[end, u, 1] * turn[p, v, 1] + A[end, u, 2] * turn[p, v, 2]
            _rotation_log(m3a, v3c)
            w2 = lever[p] * lever[p]
            for i in range(n):
                on[i] = False
            i = end
            while i >= 0:
                on[i] = True
                i = parent[i]
            for i in range(n):  # a turn ε_i about joint i's point moves the centroid by −[X_i − W_i now_i]× ε_i
                for d in range(3):
                    v3d[d] = X[i, d] - W[i] * now[i, d]
                for j in range(n):
                    for d in range(3):
                        v3e[d] = X[j, d] - W[j] * now[j, d]
                    dot = v3d[0] * v3e[0] + v3d[1] * v3e[1] + v3d[2] * v3e[2]
                    turns = w2 if on[i] and on[j] else 0.0  # and the anchor by ε_i, if it is below joint i
                    for u in range(3):  # [li]×ᵀ [lj]× = (li·lj) I − lj liᵀ
                        for v in range(3):
                            H[3 * i + u, 3 * j + v] += ((dot + turns) if u == v else 0.0) - v3e[u] * v3d[v]
                turns = w2 if on[i] else 0.0
                b[3 * i + 0] += v3d[1] * v3b[2] - v3d[2] * v3b[1] + turns * v3c[0]
                b[3 * i + 1] += v3d[2] * v3b[0] - v3d[0] * v3b[2] + turns * v3c[1]
                b[3 * i + 2] += v3d[0] * v3b[1] - v3d[1] * v3b[0] + turns * v3c[2]
        for i in range(n):  # the prior and the range, on the joint's coordinates z ≈ z⁰ + C log ρ
            k = joints[i]
            _coordinates(Rb[i], rho[i], Rl[i], range_mean[k], range_axes[k], v3a, m3a, m3b, v3d)
            pi = parent[i]
            for u in range(3):  # m3c = C A_pᵀ: how z moves with a turn ε of the joint
                for v in range(3):
                    if pi >= 0:
                        m3c[u, v] = C[i, u, 0] * A[pi, v, 0] + C[i, u, 1] * A[pi, v, 1] + C[i, u, 2] * A[pi, v, 2]
                    else:
                        m3c[u, v] = C[i, u, v]
            beyond = False
            for u in range(3):
                w = prior * joint_reach[k] * range_weight[k, u]
                residual = w * w * (v3a[u] - z0[i, u])
                weight = w * w
                low = min(range_low[k, u] - margin, z0[i, u])
                high = max(range_high[k, u] + margin, z0[i, u])
                if v3a[u] > high or v3a[u] < low:  # beyond the range: a stiff spring back to its edge
                    beyond = True
                    wall = RANGE_STIFFNESS * joint_reach[k]
                    weight += wall * wall
                    residual += wall * wall * (v3a[u] - (high if v3a[u] > high else low))
                for v in range(3):
                    for x in range(3):
                        H[3 * i + v, 3 * i + x] += weight * m3c[u, v] * m3c[u, x]
                    b[3 * i + v] += m3c[u, v] * residual
            if beyond and step == steps - 1:
                held += 1
        _cholesky_solve(H, b, size)
        for i in range(n):  # ρ ← A_pᵀ exp(−δ) A_p ρ
            _rotation_exp(-b[3 * i], -b[3 * i + 1], -b[3 * i + 2], m3a)
            pi = parent[i]
            if pi >= 0:
                _mul(m3a, A[pi], m3b)
                for u in range(3):
                    for v in range(3):
                        m3a[u, v] = A[pi, 0, u] * m3b[0, v] + A[pi, 1, u] * m3b[1, v] + A[pi, 2, u] * m3b[2, v]
            _mul(m3a, rho[i], m3b)
            for u in range(3):
                for v in range(3):
                    rho[i, u, v] = m3b[u, v]
    kept = 1.0  # the solution, kept to the capture's shapes (:mod:`.limb_shape`) before it is followed
    for i in range(n):
        _rotation_log(rho[i], logs[i])
    unseen = 0
    if steps > 0:
        unseen = _unseen_joints(joints, rho, Rb, Rl, range_mean, range_axes, range_seen, z0, margin, v3a, m3a, m3b, v3d)
    if unseen:
        kept = _kept(F, t, a, m, logs, applied, parent, point, A, g, now, halvings, False, maps, rest, bone_indices,
                     bone_weights, seam_vertices, seam_edges, seam_lengths, seam_one, seam_allowance, seam_masks, sides,
                     unseen, budget, before, after, strain0)
    for i in range(n):  # followed in the body-side bone's frame, where a held correction stays still
        for d in range(3):
            v3b[d] = kept * (Rb[i, 0, d] * logs[i, 0] + Rb[i, 1, d] * logs[i, 1] + Rb[i, 2, d] * logs[i, 2])
        _track(v3b, last[i], velocity[i], most[i])
        _matvec(Rb[i], last[i], v3a)
        _rotation_exp(v3a[0], v3a[1], v3a[2], applied[i])
    _forward(applied, parent, point, A, g, now)
    for q in range(limb_bones.shape[0]):
        bone = limb_bones[q]
        i = local[bone_joint[bone]]
        for x in range(3):
            for y in range(3):
                m3a[x, y] = A[i, x, 0] * F[a, m, bone, 0, y] + A[i, x, 1] * F[a, m, bone, 1, y] + A[i, x, 2] * F[a, m, bone, 2, y]
            v3a[x] = A[i, x, 0] * t[a, m, bone, 0] + A[i, x, 1] * t[a, m, bone, 1] + A[i, x, 2] * t[a, m, bone, 2] + g[i, x]
        for x in range(3):
            for y in range(3):
                F[a, m, bone, x, y] = m3a[x, y]
            t[a, m, bone, x] = v3a[x]
    return held, kept < 1.0


@numba.njit(cache=True, nogil=True)
def reach_animations(F, t, centres, correction, turned_by, root, limb_joints, limb_patches, joint_bone, joint_body,
                     joint_point, joint_parent, joint_reach, range_mean, range_axes, range_frame, range_weight,
                     range_low, range_high, range_seen, margin, prior, lever, patch_joint, bone_joint, part_bones, part_rest,
                     part_weight, warm_steps, cold_steps, limit, rest, bone_indices, bone_weights, seam_vertices,
                     seam_edges, seam_lengths, seam_one, seam_allowance, seam_masks, budget, halvings, held, cut):
    """The plants made, in place, on animations F (A, M, B, 3, 3), t (A, M, B, 3): at each frame each
    limb (limb_joints (L, n), limb_patches (L, p), −1 padded; the :class:`.limb_chains.LimbChains`
    tables) turned by :func:`reach_limb` so that its patches reach their pivots (A, P, M, 3) moved by
    their corrections (A, P, M, 3) and turned by turned_by (A, P, M, 3) (axis-angle), then every
    bone moved by the root (A, M, 3). Each joint's turn changes its step by at most ``limit`` (mesh
    units a frame²: an added acceleration) over its reach (:func:`_track`). A limb whose targets
    are all 0 at a frame, and whose joints are let go, is left as it is. A turn that tears its limb's
    seams (rest (V, 3), bone_indices, bone_weights (V, K); seam_* (L, …) a :class:`.limb_shape.LimbSeams`
    of the limbs, ``budget`` its) is halved up to ``halvings`` times, then let go. held (A, M)
    counts the joints at the edge of their range, cut (A, M) the limbs whose turn was cut."""
    A, M, B = F.shape[0], F.shape[1], F.shape[2]
    P = centres.shape[1]
    K = joint_bone.shape[0]
    shift = np.zeros((P, 3))
    turn = np.zeros((P, 3, 3))
    centre = np.zeros((P, 3))
    for l in range(limb_joints.shape[0]):
        n = 0
        while n < limb_joints.shape[1] and limb_joints[l, n] >= 0:
            n += 1
        c = 0
        while c < limb_patches.shape[1] and limb_patches[l, c] >= 0:
            c += 1
        if n == 0 or c == 0:
            continue
        joints = limb_joints[l, :n].copy()
        patches = limb_patches[l, :c].copy()
        local = np.full(K, -1, np.int64)
        for i in range(n):
            local[joints[i]] = i
        count = 0
        for bone in range(B):
            if bone_joint[bone] >= 0 and local[bone_joint[bone]] >= 0:
                count += 1
        limb_bones = np.empty(count, np.int64)
        count = 0
        for bone in range(B):
            if bone_joint[bone] >= 0 and local[bone_joint[bone]] >= 0:
                limb_bones[count] = bone
                count += 1
        parent = np.empty(n, np.int64)
        most = np.empty(n)
        for i in range(n):
            parent[i] = local[joint_parent[joints[i]]] if joint_parent[joints[i]] >= 0 else -1
            most[i] = limit / joint_reach[joints[i]] if limit > 0.0 else np.inf
        rho, Rb, Rl = np.empty((n, 3, 3)), np.empty((n, 3, 3)), np.empty((n, 3, 3))
        C, A3, applied = np.empty((n, 3, 3)), np.empty((n, 3, 3)), np.empty((n, 3, 3))
        last, velocity, point = np.zeros((n, 3)), np.zeros((n, 3)), np.empty((n, 3))
        z0, g, now = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
        H = np.empty((3 * n, 3 * n))
        b = np.empty(3 * n)
        m3a, m3b, m3c = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
        v3a, v3b, v3c, v3d, v3e = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
        parts = np.empty((c, part_bones.shape[0], 3))
        X, W, on = np.empty((n, 3)), np.empty(n), np.empty(n, np.bool_)
        maps = np.full(B, -1, np.int64)  # each bone's joint in this limb
        for bone in limb_bones:
            maps[bone] = local[bone_joint[bone]]
        before, after = np.empty((seam_vertices.shape[1], 3)), np.empty((seam_vertices.shape[1], 3))
        strain0 = np.empty(seam_edges.shape[1])
        sides = np.empty(n, np.int64)  # the maps a seam spanning each joint has: its own and its parent's (or the body's)
        for i in range(n):
            sides[i] = (1 << (i + 1)) | (1 << (parent[i] + 1) if parent[i] >= 0 else 1)
        logs = np.empty((n, 3))
        at = np.full(part_bones.shape[0], -1, np.int64)  # each part's last joint in this limb
        for k in range(part_bones.shape[0]):
            if bone_joint[part_bones[k]] >= 0:
                at[k] = local[bone_joint[part_bones[k]]]
        for a in range(A):
            last[:, :] = 0.0
            velocity[:, :] = 0.0
            warm = False
            for m in range(M):
                moving = False
                for q in range(c):
                    p = patches[q]
                    for d in range(3):
                        moving = moving or correction[a, p, m, d] != 0.0 or turned_by[a, p, m, d] != 0.0
                if not moving:
                    warm = False
                    settled = True
                    for i in range(n):
                        for d in range(3):
                            settled = settled and last[i, d] == 0.0 and velocity[i, d] == 0.0
                    if settled:
                        continue
                for q in range(c):
                    p = patches[q]
                    for d in range(3):
                        centre[p, d] = centres[a, p, m, d]
                        shift[p, d] = correction[a, p, m, d]
                    _rotation_exp(turned_by[a, p, m, 0], turned_by[a, p, m, 1], turned_by[a, p, m, 2], turn[p])
                steps = 0
                if moving:
                    steps = warm_steps if warm else cold_steps
                joints_held, turn_cut = reach_limb(F, t, a, m, joints, parent, local, patches, patch_joint, joint_bone, joint_body,
                                         joint_point, joint_reach, range_mean, range_axes, range_frame, range_weight,
                                         range_low, range_high, range_seen, margin, prior, centre, shift, turn, lever,
                                         rho, warm,
                                         steps, bone_joint, limb_bones, part_bones, part_rest, part_weight, at, last,
                                         velocity, most, point, Rb, Rl, C, z0, A3, g, now, applied, H, b, parts, X, W,
                                         on, m3a, m3b, m3c, v3a, v3b, v3c, v3d, v3e, maps, rest, bone_indices,
                                         bone_weights, seam_vertices[l], seam_edges[l], seam_lengths[l], seam_one[l],
                                         seam_allowance[l], seam_masks[l], sides, budget[l], halvings, before, after,
                                         strain0, logs)
                held[a, m] += joints_held
                cut[a, m] += turn_cut
                warm = moving
    for a in range(A):
        for m in range(M):
            for bone in range(B):
                for d in range(3):
                    t[a, m, bone, d] += root[a, m, d]
