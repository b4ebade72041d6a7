"""Multi-component assembly (Zheng §4.2, Alg. 1, eq. 12–14): merge bone components through cut nodes.

Each component is synthesised on its own (its own walk, its own reference bone), so two
components that share a cut node b_c each produce a motion of b_c. They can be put together when
b_c's stretch agrees (eq. 12: D_C = Σ_t ‖S_c,i(t) − S_c,j(t)‖²_F below T_c = 0.05 · max_t ‖S‖²_F,
F = U S polar), by carrying all of C_j rigidly onto C_i's cut node (eq. 13, 14).

Eq. 12 sums ‖S_c,i − S_c,j‖² over all M frames but compares it with T_c = 0.05 × one frame's
‖S‖²; taken literally that rejects every pair of long animations (a difference of 1e-3 per
frame adds up over 600 frames), so the mean over frames is compared instead.

Choices Alg. 1 leaves open: components are merged in breadth-first order of the block–cut tree
from the component with the most bones (the anchor); for output animation a the anchor uses its
own walk a, and each further component tries ``tries`` of its synthesised animations in a
seeded random order, taking the first that passes eq. 12 (or the closest one, counted as a
rejection, when none does, so every requested animation exists). Components that share no bone
with the rest are independent pieces of the mesh and are copied as they are.
"""

from collections import deque

import numpy as np

from .rotations import polar_decomposition


def merge_into(F, t, cut, F_j, t_j, bones_j, polar_i=None, polar_j=None):
    """Carry component j onto the assembled bones through cut node ``cut`` (eq. 13–14), in place.

    F (N, M, B, 3, 3), t (N, M, B, 3): the assembled animations (cut already set); F_j
    (N, M, b_j, 3, 3), t_j (N, M, b_j, 3): the animations of component j chosen for them, over
    its bones ``bones_j`` (sorted ids, cut among them). All animations and bones at once.
    polar_i / polar_j: the cut node's (U, S) on each side when already known.
    """
    bones_j = np.asarray(bones_j)
    where = int(np.searchsorted(bones_j, cut))
    U_i, S_i = polar_decomposition(F[:, :, cut]) if polar_i is None else polar_i
    U_j, S_j = polar_decomposition(F_j[:, :, where]) if polar_j is None else polar_j
    turn = U_i @ np.swapaxes(U_j, -1, -2)  # (N, M, 3, 3)
    others = np.flatnonzero(bones_j != cut)
    F[:, :, bones_j[others]] = turn[:, :, None] @ F_j[:, :, others]  # eq. 14
    t[:, :, bones_j[others]] = (np.einsum("nmab,nmkb->nmka", turn, t_j[:, :, others] - t_j[:, :, where, None])
                                + t[:, :, cut, None])
    F[:, :, cut] = 0.5 * U_i @ (S_i + S_j)  # eq. 13 (translation stays C_i's)


def merge_order(components):
    """[(component index, shared cut node or None)] in breadth-first order from the largest."""
    sets = [set(c) for c in components]
    start = max(range(len(components)), key=lambda c: (len(components[c]), -c))
    order, seen, queue = [(start, None)], {start}, deque([start])
    while queue:
        here = queue.popleft()
        for other in range(len(components)):
            if other not in seen:
                shared = sets[here] & sets[other]
                if shared:
                    seen.add(other)
                    order.append((other, min(shared)))
                    queue.append(other)
    order += [(c, None) for c in range(len(components)) if c not in seen]
    return order


def assemble(components, animations, bones, rng, tries=32):
    """Merge per-component animations into whole-rig animations.

    components: list of sorted bone-id lists; animations: list of (F (N, M, b, 3, 3), t (N, M, b, 3))
    per component; bones: B. Returns (F (N, M, B, 3, 3), t (N, M, B, 3), choice (N, C) the
    animation used from each component, rejected (int): merges that fell back to the closest).
    """
    count, frames = animations[0][0].shape[:2]
    F = np.zeros((count, frames, bones, 3, 3))
    t = np.zeros((count, frames, bones, 3))
    order = merge_order(components)
    choice = np.zeros((count, len(components)), dtype=np.int64)
    rejected = 0
    first = order[0][0]
    ids = np.asarray(components[first])
    F[:, :, ids], t[:, :, ids] = animations[first]
    choice[:, first] = np.arange(count)
    for c, cut in order[1:]:
        F_c, t_c = animations[c]
        ids = np.asarray(components[c])
        if cut is None:  # an independent piece of the mesh
            F[:, :, ids], t[:, :, ids] = F_c, t_c
            choice[:, c] = np.arange(count)
            continue
        where = int(np.searchsorted(ids, cut))
        U_c, S_c = polar_decomposition(F_c[:, :, where])  # (N, M, 3, 3) the cut node in component c
        U_a, S_a = polar_decomposition(F[:, :, cut])
        candidates = np.argsort(rng.random((count, count)), axis=1)[:, :tries]  # a seeded order per animation
        # Eq. 12 for every (a, candidate) pair from Gram matrices: ‖Sa−Sc‖² = ‖Sa‖² + ‖Sc‖² − 2⟨Sa, Sc⟩.
        flat_a, flat_c = S_a.reshape(count, -1), S_c.reshape(count, -1)
        inner = flat_a @ flat_c.T
        norm_a, norm_c = np.sum(flat_a ** 2, axis=1), np.sum(flat_c ** 2, axis=1)
        rows = np.arange(count)[:, None]
        # Mean over frames: eq. 12 sums over the M frames but T_c is a single frame's ‖S‖², so taken
        # literally it rejects every pair of long animations (documented in the module notes).
        difference = np.maximum(norm_a[:, None] + norm_c[None, :] - 2.0 * inner, 0.0)[rows, candidates] / frames
        peak_a = np.max(np.sum(S_a ** 2, axis=(-1, -2)), axis=1)
        peak_c = np.max(np.sum(S_c ** 2, axis=(-1, -2)), axis=1)
        threshold = 0.05 * np.maximum(peak_a[:, None], peak_c[candidates])  # Zheng's T_c
        passing = difference < threshold
        first = np.argmax(passing, axis=1)
        closest = np.argmin(difference, axis=1)
        found = passing.any(axis=1)
        pick = candidates[np.arange(count), np.where(found, first, closest)]
        rejected += int((~found).sum())
        choice[:, c] = pick
        merge_into(F, t, cut, F_c[pick], t_c[pick], ids, (U_a, S_a), (U_c[pick], S_c[pick]))
    return F, t, choice, rejected
