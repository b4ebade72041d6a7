"""A rig that keeps its joints: the skinning decomposition constrained to a skeleton (Le & Deng
2014, §5: skeleton-constrained SSDR).

Every bone j has a world rotation R_j(f). A *jointed* bone turns about its joint q_j (rest
position) with its parent p: the joint goes where the parent takes it, so its translation is not
free, t_j = t_p + (R_p − R_j) q_j. The root and the free bones (no rigid neighbour: cloth, a prop,
:mod:`.joints`) are *anchors* with translations of their own. Unrolled along the chain from a
bone's anchor, every vertex of the linear blend skin is

    v_i(f) = Σ_a s_ia t_a(f) + Σ_k R_k(f) a_ik                                   (forward kinematics)

with s_ia the weight of vertex i on the bones hanging from anchor a (through joints), and

    a_ik = w_ik r_i − [k jointed] W_ik q_k + Σ_{c: jointed child of k} W_ic q_c

where W_ik = Σ_{j below or at k, through joints} w_ij (:func:`chain_coefficients`). The error is
quadratic in the translations and, bone by bone, an orthogonal Procrustes problem in each R_k
with no translation: R_k = polar(Σ_i e_i a_ikᵀ), e_i the vertex minus everything else's part. So a
fit alternates (:func:`fit_jointed`), each step exact for its block:

1. the anchors' translations (one A×A solve per frame, all frames at once);
2. each bone's rotation in turn, parents first (the sums Σ_i a_im a_ikᵀ and Σ_i v_i(f) a_ikᵀ are
   formed once per weight update, so a sweep costs O(F B²), not O(F V B)); then
   :data:`NEWTON_STEPS` Levenberg–Marquardt steps on every bone's rotation and every anchor's
   translation of a frame at once (the chain couples each bone to its ancestors, where bone by
   bone updates crawl: from bones turned 0.05 rad off an exactly jointed skin, sweeps alone left
   6e-4 of the diagonal after 60 iterations, these steps reach 1e-8 in two), each frame keeping
   its step only where its error falls;
3. the joints: with the rotations and weights fixed, every vertex is linear in the joints and
   the anchors' translations, so they are one least-squares solve (the translations eliminated
   per frame), pulled towards where :mod:`.joints` found them in the directions the motion
   leaves free (a hinge's axis: ``stiffness``, :func:`_solve_joints`), then, given the mesh,
   any joint the solve took out of the body put back in (:func:`.joints.inside_mesh`, towards
   where it was found): a projected alternation, the joints inside throughout;
4. the weights against the rig's world transforms, as :mod:`.skin_fit` does (Le & Deng's
   constrained decomposition refits them too).

With the joints fixed (``move_joints=False``) the error never rises. The projection replaced a
second phase (the joints free, then those outside put back in and the rig refitted with them
fixed): measured (``benchmarks/skeleton.py``'s bones, RMSE over the free fit's, jointed-fit
seconds, two phases → projected) horse gallop 1.373 → 1.385 (3.8 → 3.8 s), samba 1.061 → 1.074
(25 → 16.5 s), crane 1.166 → 1.193 (20.8 → 9.4 s), elephant 1.48 → 1.478 (18.6 → 17.3 s), horse
collapse 1.093 → 1.132 (5.8 → 2.5 s), and the collapse's last joint outside the body came in (12
of 12 inside, 11 before): the second phase restarted from joints moved after the fit had settled
on them, and spent as many iterations again getting back. The world transforms
(R_j, t_j) are ordinary LBS bones, so every later stage reads the result as any skin.
"""

import copy
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np
from threadpoolctl import threadpool_limits

from ..rig.influence import dense_weights
from ..rig.rotations import polar_rotation, rotation_exp
from ..rig.skeleton import hold_joints
from .bone_transforms import Trajectories
from .skin_fit import SkinFit
from .joints import inside_mesh
from .rig_normal_equations import normal_equations
from .skin_weights import update_weights
from .transform_sweep import sparse_weighted_sums

#: Pull of the joint solve towards the joints found, in the directions a joint's motion leaves
#: free, as a share of its block's largest eigenvalue (:func:`_solve_joints`).
JOINT_STIFFNESS = 1e-3
#: The same pull in every direction, as a share of that eigenvalue.
JOINT_FLOOR = 1e-3
#: Halvings of the segment to the skin when an iteration's joint solve takes a joint out of the
#: body and the skin's last crossing does not put it in (:func:`.joints.inside_mesh`, a mesh with
#: holes; 12 when a skeleton is found): 1/64 of the way, then a quarter of the rest in. The same
#: fits to 1e-3 of their RMSE as 12 (each halving tests the joints against every triangle).
PROJECTION_STEPS = 6
#: Levenberg–Marquardt steps on all of a frame's bones together after each iteration's sweeps: the
#: chain couples every bone to its ancestors, where one-bone-at-a-time updates crawl (module notes).
#: Two, not four, since one sweep an iteration: the five captures of ``benchmarks/skeleton.py``
#: fit as well or better (RMSE over the free fit's 1.385 → 1.365 horse, 1.195 → 1.191 collapse,
#: 1.245 → 1.244 crane, 1.331 → 1.326 samba, 1.480 → 1.473 elephant) in 9 % less time together.
NEWTON_STEPS = 2
#: Runs of frames whose rotations are fitted at once on threads of their own (frames are
#: independent for fixed weights and joints; numpy lets go of the interpreter in its products and
#: solves): the same rotations, bit for bit, as one run. Two on two cores: the crane's rotation
#: step 65 → 39 ms, the horse collapse's 16 → 12.5 ms; four were slower there (20.9 ms), the
#: interpreter's share between the calls then the bound.
FRAME_BLOCKS = 2
#: The fit stops once its last three iterations together improved the RMSE by at most this share.
#: The alternation of weights and transforms crawls near the end (as the free fit's does; with
#: the joints held it crawls just the same): at 0.1 % the captures of ``benchmarks/skeleton.py``
#: took 35–40 iterations where 0.2 % takes 18–29 (16–38 on the bar, the sheet and the walker), for
#: RMSEs over the free fit's within 1.1 % of 0.1 %'s (horse gallop 1.369 → 1.373, collapse 1.193 →
#: 1.199, crane 1.244 → 1.253, elephant 1.457 → 1.473, samba, bar and sheet the same to 0.001).
TOLERANCE = 2e-3


def chain_masks(parents, jointed):
    """(below (B, B) bool: below[j, k] when bone j hangs from k through joints, j == k included;
    anchors (A,) int64: the root and the free bones, in bone order)."""
    parents, jointed = np.asarray(parents), np.asarray(jointed, dtype=bool)
    bones = parents.size
    below = np.eye(bones, dtype=bool)
    for j in range(bones):  # walk up each bone's chain (B × depth steps; B is small)
        k = j
        while jointed[k]:
            k = parents[k]
            below[j, k] = True
    return below, np.flatnonzero(~jointed)


def _joint_terms(parents, jointed, joints):
    """E (B, B·3): a (V, B, 3) of :func:`chain_coefficients` is (w ⊗ r) + W E, row c of E holding
    q_c under each bone k that c is a jointed child of, less q_k under k itself where k is jointed."""
    parents, jointed = np.asarray(parents), np.asarray(jointed, dtype=bool)
    bones = parents.size
    terms = np.zeros((bones, bones, 3))
    child = np.flatnonzero(jointed)
    terms[child, parents[child]] += joints[child]
    terms[child, child] -= joints[child]
    return terms.reshape(bones, bones * 3)


def chain_coefficients(rest, weights, parents, jointed, joints):
    """(s (V, A), a (V, B, 3)): each anchor's translation and each bone's rotation coefficient in
    every vertex (module notes); weights (V, B) dense, joints (B, 3)."""
    below, anchors = chain_masks(parents, jointed)
    carried = weights @ below.astype(np.float64)  # W (V, B)
    a = (weights[:, :, None] * np.asarray(rest, np.float64)[:, None, :]).reshape(len(rest), -1)
    a += carried @ _joint_terms(parents, jointed, joints)
    return carried[:, anchors], a.reshape(len(rest), len(parents), 3)


def world_transforms(rotations, anchor_translations, parents, jointed, joints):
    """(rotations (F, B, 3, 3), translations (F, B, 3)): the LBS bones of a jointed rig, its
    anchors' translations (F, A, 3) given (anchors in bone order)."""
    _, anchors = chain_masks(parents, jointed)
    translations = np.zeros(rotations.shape[:2] + (3,))
    translations[:, anchors] = anchor_translations
    return rotations, hold_joints(rotations, translations, np.asarray(parents), np.asarray(jointed, dtype=bool), joints)


class _Products:
    """The vertex sums of one weight update, from which every joint placement's sums follow.

    The chain coefficients are a = (w ⊗ r) + W E with only E (B, B·3) depending on the joints
    (:func:`_joint_terms`), and s = W's anchor columns, W = w ``below``; so the products over the
    vertices that the sweeps, the Levenberg–Marquardt steps and the joint solve need are those of
    (w ⊗ r) and w with each other and with the examples: the free fit's weighted sums
    (:func:`.transform_sweep.sparse_weighted_sums`, over each vertex's few weights), formed once
    per weight update (:meth:`sums` then costs O(F B²) for any joints; forming a (V, B, 3) array
    and its products for each joint placement, twice an iteration, was 45 % of the elephant's
    jointed fit)."""

    def __init__(self, data, indices, weights, parents, jointed):
        """data: the examples' :class:`.bone_transforms.Trajectories`; indices, weights (V, K)."""
        below, self.anchors = chain_masks(parents, jointed)
        below = below.astype(np.float64)  # W = w below (V, B)
        self.parents, self.jointed = np.asarray(parents), np.asarray(jointed, dtype=bool)
        self.frames, bones = data.frames, len(self.parents)
        # Σ_i w_ij v_i(f) ũ_iᵀ (B, F, 3, 4) and Σ_i w_ij w_ik ũ_i ũ_iᵀ (B, B, 4, 4), ũ the homogeneous rest
        moment, second = sparse_weighted_sums(indices, weights, data, bones)
        self.turned_gram = second[:, :, :3, :3].transpose(0, 2, 1, 3).reshape(bones * 3, bones * 3)  # (B·3, B·3)
        self.carried_turned = below.T @ second[:, :, 3, :3].reshape(bones, bones * 3)  # Wᵀ (w ⊗ r) (B, B·3)
        self.carried_gram = below.T @ second[:, :, 3, 3] @ below  # WᵀW (B, B)
        self.vertices_turned = moment[..., :3].transpose(1, 2, 0, 3).reshape(self.frames * 3, bones * 3)  # (F·3, B·3)
        self.vertices_carried = moment[..., 3].transpose(1, 2, 0).reshape(self.frames * 3, bones) @ below  # (F·3, B)

    def sums(self, joints):
        """:class:`_Sums` of the chain coefficients at ``joints`` (B, 3)."""
        return _Sums(self, _joint_terms(self.parents, self.jointed, joints))


class _Sums:
    """What the sweeps and the Levenberg–Marquardt steps need from the vertices (:class:`_Products`)."""

    def __init__(self, products, terms):
        """products: a :class:`_Products`; terms: its joints' E (B, B·3) (:func:`_joint_terms`).
        gram (B, B, 3, 3): [k, m] = Σ_i a_ik a_imᵀ (gram_flat (B·3, B·3): the same, [(k, y), (m, z)]);
        cross (F, B, 3, 3): Σ_i v_i(f) a_ikᵀ; anchor_gram (A, A); anchor_cross (A, B, 3): Σ_i s_ia a_ik;
        anchor_vertices (F, A, 3): Σ_i s_ia v_i(f)."""
        frames, anchors = products.frames, products.anchors
        bones = len(products.parents)
        mixed = products.carried_turned.T @ terms  # (B·3, B·3): (w ⊗ r)ᵀ W E
        self.gram_flat = products.turned_gram + mixed + mixed.T + terms.T @ products.carried_gram @ terms
        self.gram = self.gram_flat.reshape(bones, 3, bones, 3).transpose(0, 2, 1, 3)
        cross = products.vertices_turned + products.vertices_carried @ terms  # (F·3, B·3)
        self.cross = cross.reshape(frames, 3, bones, 3).transpose(0, 2, 1, 3)
        self.anchor_gram = products.carried_gram[np.ix_(anchors, anchors)]
        self.anchor_cross = (products.carried_turned[anchors]
                             + products.carried_gram[anchors] @ terms).reshape(anchors.size, bones, 3)
        self.anchor_vertices = products.vertices_carried[:, anchors].reshape(frames, 3, -1).transpose(0, 2, 1)

    def frames(self, rows):
        """These sums for the frames ``rows`` alone (the frame-free sums shared)."""
        part = copy.copy(self)
        part.cross, part.anchor_vertices = self.cross[rows], self.anchor_vertices[rows]
        return part


def _solve_translations(sums, R):
    """Least-squares anchor translations (F, A, 3) for rotations R (F, B, 3, 3)."""
    rhs = sums.anchor_vertices - np.einsum("fkxy,aky->fax", R, sums.anchor_cross)
    return np.linalg.solve(sums.anchor_gram + 1e-12 * np.eye(len(sums.anchor_gram)), rhs)


def _sweep_rotations(sums, R, T, order):
    """One pass of exact per-bone Procrustes updates (module notes, step 2), in ``order``."""
    R = R.copy()
    frames, bones = R.shape[:2]
    T_rows = np.swapaxes(T, 1, 2)  # (F, 3, A)
    for k in order:  # Σ_m R_m G_mk as one product over (m, y): einsum's loops took most of a jointed fit
        others = R.transpose(0, 2, 1, 3).reshape(frames, 3, 3 * bones) @ sums.gram[:, k].reshape(3 * bones, 3)
        target = sums.cross[:, k] - T_rows @ sums.anchor_cross[:, k] - others + R[:, k] @ sums.gram[k, k]
        R[:, k] = polar_rotation(target)
    return R


def _solve_joints(products, R, joints, found, stiffness=JOINT_STIFFNESS):
    """The joints (B, 3) that, with the anchors' translations, best fit for fixed rotations and
    weights (module notes, step 3): the translations eliminated per frame, one (3J × 3J) solve,
    pulled towards ``found`` (B, 3) by ``stiffness`` × each joint's largest eigenvalue in the
    directions its motion leaves free and :data:`JOINT_FLOOR` × it in every direction.
    ``products``: the weights' :class:`_Products`."""
    anchors, parents = products.anchors, products.parents
    child = np.flatnonzero(products.jointed)
    if child.size == 0:
        return joints
    frames, bones = R.shape[:2]
    D = R[:, parents[child]] - R[:, child]  # (F, J, 3, 3)
    gram = products.carried_gram  # WᵀW: s = W's anchor columns
    N = gram[np.ix_(anchors, anchors)] + 1e-12 * np.eye(anchors.size)
    P = gram[np.ix_(anchors, child)]  # sᵀ W_J (A, J)
    eliminated = np.linalg.solve(N, P)  # N⁻¹P (A, J)
    K = gram[np.ix_(child, child)] - P.T @ eliminated  # (J, J)
    # Σ_i M_ic r_i(f), (J, F, 3), M = W_J − s N⁻¹P (V, J), r_i(f) the vertex less the bones' rotations
    # of the rest pose: Mᵀ v(f) less (Mᵀ (w ⊗ rest)) R(f), both from the weight update's products.
    turned = products.carried_turned[child] - eliminated.T @ products.carried_turned[anchors]  # (J, B·3)
    seen = (products.vertices_carried[:, child] - products.vertices_carried[:, anchors] @ eliminated).T  # (J, F·3)
    projected = (seen - turned @ R.transpose(1, 3, 0, 2).reshape(bones * 3, frames * 3)).reshape(child.size, frames, 3)
    rhs = np.einsum("fcyx,cfy->cx", D, projected)
    count = child.size
    flat = D.transpose(0, 2, 1, 3).reshape(frames * 3, count * 3)  # [(f, y), (c, x)]
    lhs = (flat.T @ flat) * np.kron(K, np.ones((3, 3)))
    # Each joint's pull towards where it was found: ``stiffness`` × its block's largest eigenvalue
    # in the directions its motion leaves free (a hinge's axis: λ_max·I − block), plus
    # JOINT_FLOOR × that eigenvalue in every direction; so the solve moves joints across their
    # hinges, where the fit sees them, not along the axis, where it would only follow noise
    # (on the horse: up to 0.3 of the diagonal, out of the body).
    blocks = lhs.reshape(count, 3, count, 3)[np.arange(count), :, np.arange(count), :]  # (J, 3, 3)
    largest = np.linalg.eigvalsh(blocks)[:, -1]
    pull = np.zeros_like(lhs)
    for c in range(count):
        pull[3 * c:3 * c + 3, 3 * c:3 * c + 3] = (stiffness * (largest[c] * np.eye(3) - blocks[c])
                                                  + (JOINT_FLOOR * largest[c] + 1e-12) * np.eye(3))
    solved = np.linalg.solve(lhs + pull, rhs.ravel() + pull @ found[child].ravel())
    joints = joints.copy()
    joints[child] = solved.reshape(count, 3)
    return joints


def _frame_energies(sums, squared, R, T):
    """Σ_i ‖v_i(f) − model_i(f)‖² per frame (F,), from the sums alone; ``squared`` (F,) is
    Σ_i ‖v_i(f)‖². (The contractions over bones are matrix products, :func:`_turned_rows`, or
    einsum left to pick them, ``optimize=True``: einsum's own loops took half of a jointed fit's time.)"""
    cross = (np.einsum("fax,fax->f", T, sums.anchor_vertices) + np.einsum("fkxy,fkxy->f", R, sums.cross))
    rows, turned = _turned_rows(sums, R)
    model = (np.einsum("ab,fax,fbx->f", sums.anchor_gram, T, T)
             + 2.0 * np.einsum("fax,fkxy,aky->f", T, R, sums.anchor_cross, optimize=True)
             + np.einsum("fxq,fxq->f", turned, rows))  # Σ_km tr(R_k G_km R_mᵀ)
    return squared - 2.0 * cross + model


def _turned_rows(sums, R):
    """(rows (F, 3, B·3): R laid out [f, x, (k, y)] = R_k[x, y]; Σ_k R_k G_km (F, 3, B·3): [f, x, (m, z)])."""
    frames, bones = R.shape[:2]
    rows = R.transpose(0, 2, 1, 3).reshape(frames, 3, bones * 3)
    return rows, rows @ sums.gram_flat


def _gauss_newton(sums, squared, R, T, damping, before):
    """One Levenberg–Marquardt step on every bone's rotation and every anchor's translation of
    each frame at once (frames are independent for fixed weights and joints; the normal equations
    :func:`.rig_normal_equations.normal_equations`): R_k ← exp(ω_k) R_k,
    t_a ← t_a + δ_a; a frame keeps the step only where its error falls, and its ``damping`` (F,)
    is divided by 3 there, multiplied by 10 elsewhere. ``before`` (F,): the frames' energies at
    (R, T) (:func:`_frame_energies`). Returns (R, T, damping, the energies at the R, T returned)."""
    frames, bones = R.shape[:2]
    anchors = T.shape[1]
    n = 3 * (bones + anchors)
    H, g = np.empty((frames, n, n)), np.empty((frames, n))
    normal_equations(*(np.ascontiguousarray(x) for x in (R, sums.gram_flat, sums.anchor_cross, sums.anchor_gram,
                                                         sums.cross, sums.anchor_vertices, T)), H, g)
    diagonal = np.einsum("fii->fi", H)  # a view: the damping goes onto it in place (no (F, n, n) copies)
    diagonal += damping[:, None] * (diagonal + 1e-12 * diagonal.mean(axis=1, keepdims=True))
    step = np.linalg.solve(H, g[..., None])[..., 0]
    omega = step[:, :3 * bones].reshape(frames, bones, 3)
    R_new = rotation_exp(omega) @ R
    T_new = T + step[:, 3 * bones:].reshape(frames, anchors, 3)
    after = _frame_energies(sums, squared, R_new, T_new)
    better = after < before
    R = np.where(better[:, None, None, None], R_new, R)
    T = np.where(better[:, None, None], T_new, T)
    return R, T, np.where(better, damping / 3.0, damping * 10.0), np.where(better, after, before)


def _fit_rotations(sums, squared, R, order, sweeps):
    """Module notes' steps 1–2 on some frames (their :meth:`_Sums.frames`, ``squared`` (F,), R (F,
    B, 3, 3)): ``sweeps`` passes of translations and rotations, then :data:`NEWTON_STEPS`
    Levenberg–Marquardt steps. Returns (R, the anchors' translations (F, A, 3))."""
    T = _solve_translations(sums, R)
    for _ in range(sweeps):
        R = _sweep_rotations(sums, R, T, order)
        T = _solve_translations(sums, R)
    damping, energies = np.full(len(R), 1e-3), _frame_energies(sums, squared, R, T)
    for _ in range(NEWTON_STEPS):
        R, T, damping, energies = _gauss_newton(sums, squared, R, T, damping, energies)
    return R, T


class _State:
    """A jointed fit in progress: rotations R (F, B, 3, 3), weights, joints (B, 3)."""

    def __init__(self, rotations, indices, weights, joints):
        self.R, self.indices, self.weights, self.joints = rotations, indices, weights, joints

    def products(self, data, skeleton):
        """The :class:`_Products` of the current weights."""
        return _Products(data, self.indices, self.weights, skeleton.parents, skeleton.jointed)


def _iterate(state, vertices, rest, skeleton, data, found, max_influences, iterations, sweeps, tolerance, patience,
             move_joints, stiffness, history, progress, faces, pool):
    """Iterations of module notes' steps 1–4 on ``state`` until the stopping rule (with ``faces``,
    the joints kept inside the mesh), the rotations of :data:`FRAME_BLOCKS` runs of frames fitted
    on ``pool``'s threads; appends each RMSE to ``history``; returns what stopped it."""
    frames, count = vertices.shape[:2]
    order = skeleton.order()
    first = len(history)
    squared = np.einsum("fvx,fvx->f", vertices, vertices)
    blocks = np.array_split(np.arange(frames), min(FRAME_BLOCKS, frames))
    for iteration in range(1, iterations + 1):
        products = state.products(data, skeleton)
        sums = products.sums(state.joints)
        turned = pool.map(lambda rows: _fit_rotations(sums.frames(rows), squared[rows], state.R[rows], order, sweeps),
                          blocks)
        state.R, T = (np.concatenate(parts) for parts in zip(*turned))
        if move_joints:
            state.joints = _solve_joints(products, state.R, state.joints, found, stiffness)
            if faces is not None:  # back inside the body (module notes, step 3)
                state.joints = inside_mesh(state.joints, found[:, None], rest, faces, steps=PROJECTION_STEPS)[0]
            T = _solve_translations(products.sums(state.joints), state.R)
        world_R, world_t = world_transforms(state.R, T, skeleton.parents, skeleton.jointed, state.joints)
        transforms = np.concatenate([world_R, world_t[..., None]], axis=-1)
        state.indices, state.weights, error = update_weights(transforms, data, state.indices, state.weights,
                                                             max_influences)
        history.append(float(np.sqrt(error.sum() / (frames * count))))
        if progress is not None:
            progress(len(history), history[-1])
        if iteration > patience and history[-1 - patience] - history[-1] <= tolerance * history[-1 - patience]:
            return f"converged: the last {patience} iterations improved the RMSE by ≤ {tolerance:.2%}"
    return f"iteration limit ({iterations})" if len(history) > first else "no iterations"


@threadpool_limits.wrap(limits=1, user_api="blas")
def fit_jointed(vertices, rest, bone_indices, bone_weights, rotations, skeleton, faces=None, max_influences=4,
                iterations=40, sweeps=1, tolerance=TOLERANCE, patience=3, stiffness=JOINT_STIFFNESS, move_joints=True,
                progress=None):
    """Refit a skin's bones and weights so that every joint of ``skeleton`` holds (module notes).

    vertices (F, V, 3) the examples; rest (V, 3); bone_indices / bone_weights (V, K) and
    rotations (F, B, 3, 3): the free fit it starts from; skeleton: a :class:`.joints.Skeleton`.
    Each iteration: ``sweeps`` passes of translations and rotations (one: with the
    Levenberg–Marquardt steps after them, three gave the same fits, RMSE over the free fit's within
    0.001 on the five captures of ``benchmarks/skeleton.py``, and took 4–18 % longer), then the
    joints (step 4; not with
    ``move_joints=False``, where every step is exact for its block and the error never rises),
    then the weights. Stops once the last ``patience`` iterations together improved the RMSE by at
    most ``tolerance`` (relative; :data:`TOLERANCE`), else after ``iterations``. With ``faces`` (T, 3) every joint the
    joint solve takes out of the body is put back in at once (:func:`.joints.inside_mesh`, towards
    where it was found; module notes). ``progress(iteration, rmse)`` after each iteration.
    Returns (a :class:`.skin_fit.SkinFit` whose rotations and translations are the rig's world
    transforms, every joint held to rounding; the skeleton with the fitted joints)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    rest = np.asarray(rest, dtype=np.float64)
    frames, count = vertices.shape[:2]
    found = np.asarray(skeleton.joints, np.float64)
    data = Trajectories(vertices, rest)
    state = _State(np.array(rotations, dtype=np.float64), np.asarray(bone_indices, np.int32),
                   np.asarray(bone_weights, np.float64), found.copy())
    history = []
    options = (max_influences, iterations, sweeps, tolerance, patience)
    with ThreadPoolExecutor(FRAME_BLOCKS) as pool:
        stopped = _iterate(state, vertices, rest, skeleton, data, found, *options, move_joints, stiffness, history,
                           progress, faces, pool)
    T = _solve_translations(state.products(data, skeleton).sums(state.joints), state.R)
    world_R, world_t = world_transforms(state.R, T, skeleton.parents, skeleton.jointed, state.joints)
    dense = dense_weights(state.indices, state.weights, skeleton.bones)
    fitted = SkinFit(rest_vertices=rest.copy(), bone_indices=state.indices, bone_weights=state.weights,
                     rotations=world_R, translations=world_t, rmse=history[-1], error_history=history,
                     iterations=len(history), converged=stopped.startswith("converged"), stopped=stopped,
                     labels=np.argmax(dense, axis=1), bones_without_weight=int((dense.sum(axis=0) <= 0.0).sum()))
    return fitted, replace(skeleton, joints=state.joints)


def _segments(skeleton):
    """(starts (S, 3), ends (S, 3), owners (S,)): each bone's segments, from its joint to each of its
    children's joints (a bone without children: its joint alone)."""
    joints, parents = np.asarray(skeleton.joints, np.float64), np.asarray(skeleton.parents)
    starts, ends, owners = [], [], []
    for bone in range(skeleton.bones):
        children = np.flatnonzero(parents == bone)
        for end in (children if children.size else [bone]):
            starts.append(joints[bone])
            ends.append(joints[end])
            owners.append(bone)
    return np.array(starts), np.array(ends), np.array(owners)


def segment_distances(points, skeleton):
    """(P, B): each point's squared distance to the nearest segment of each bone (:func:`_segments`)."""
    points = np.asarray(points, dtype=np.float64)
    starts, ends, owners = _segments(skeleton)
    direction = ends - starts
    length = np.maximum(np.einsum("sx,sx->s", direction, direction), 1e-300)
    out = np.full((len(points), skeleton.bones), np.inf)
    for s in range(len(starts)):  # one pass per segment (about B), every point at once
        u = np.clip((points - starts[s]) @ direction[s] / length[s], 0.0, 1.0)
        distance = np.sum((points - starts[s] - u[:, None] * direction[s]) ** 2, axis=1)
        out[:, owners[s]] = np.minimum(out[:, owners[s]], distance)
    return out


def fit_given_skeleton(vertices, rest, faces, skeleton, max_influences=4, iterations=40, seed=0, progress=None):
    """A rig fitted under a skeleton the user brings (Dem Bones with a given hierarchy).

    The clip's own jointed rig first: a free fit of as many bones (:func:`.skin_fit.fit_skin`,
    ``seed``), its skeleton found (:func:`.joints.find_skeleton`) and fitted (:func:`fit_jointed`).
    Each of its bones is then given to one of the skeleton's, one to one, at the least total
    cost: the squared distance from the bone's weighted rest centroid to the skeleton bone's
    segments (its joint to its children's joints) plus that between the two joints. Last,
    :func:`fit_jointed` from there with the joints kept where the skeleton has them.
    vertices (F, V, 3) with ``rest`` (V, 3) among them (the skeleton's bind pose), faces (T, 3).

    Measured on the horse gallop under its own found skeleton (exported as UsdSkel): 1.04× that
    rig's error. Cheaper starts left it at 1.20× (the free fit matched by centroids alone: some
    bones went to a neighbour's segments) and 1.21× (each vertex to its nearest segment, 88
    iterations). Returns what :func:`fit_jointed` does."""
    from scipy.optimize import linear_sum_assignment

    from ..rig.influence import bone_centroids
    from .joints import find_skeleton
    from .skin_fit import fit_skin

    vertices = np.asarray(vertices, dtype=np.float64)
    rest = np.asarray(rest, dtype=np.float64)
    rest_frame = int(np.argmin(np.sum((vertices - rest) ** 2, axis=(1, 2))))
    free = fit_skin(vertices, skeleton.bones, max_influences=max_influences, rest_frame=rest_frame, seed=seed)
    found = find_skeleton(rest, faces, free.bone_indices, free.bone_weights, free.rotations, free.translations)
    own, own_skeleton = fit_jointed(vertices, rest, free.bone_indices, free.bone_weights, free.rotations, found,
                                    faces=faces, max_influences=max_influences, iterations=iterations,
                                    progress=progress)
    centres = bone_centroids(rest, own.bone_indices, own.bone_weights, skeleton.bones)
    cost = (segment_distances(centres, skeleton)
            + np.sum((own_skeleton.joints[:, None] - np.asarray(skeleton.joints)[None]) ** 2, axis=2))
    rows, columns = linear_sum_assignment(cost)
    given = np.empty(skeleton.bones, dtype=np.int64)
    given[rows] = columns  # the clip's bone r becomes the skeleton's bone given[r]
    rotations = np.empty_like(own.rotations)
    rotations[:, given] = own.rotations
    return fit_jointed(vertices, rest, given[own.bone_indices].astype(np.int32), own.bone_weights, rotations,
                       skeleton, max_influences=max_influences, iterations=iterations, move_joints=False,
                       progress=progress)
