"""Multi-component assembly (Zheng §4.2, Alg. 1, eq. 12–14): merge bone components through cut nodes.

Each component is synthesised on its own (its own walk, its own reference bone), so two
components that share a cut node b_c each produce a motion of b_c. They can be put together when
b_c's stretch agrees (eq. 12: D_C = Σ_t ‖S_c,i(t) − S_c,j(t)‖²_F below T_c = 0.05 · max_t ‖S‖²_F,
F = U S polar), by carrying all of C_j rigidly onto C_i's cut node (eq. 13, 14).

Eq. 12 sums ‖S_c,i − S_c,j‖² over all M frames but compares it with T_c = 0.05 × one frame's
‖S‖²; taken literally that rejects every pair of long animations (a difference of 1e-3 per
frame adds up over 600 frames), so the mean over frames is compared instead.

Choices Alg. 1 leaves open: components are merged in breadth-first order of the block–cut tree
from its most central component (the anchor; :func:`merge_order`); for output animation a the
anchor uses its own walk a, and each further component tries ``tries`` of its synthesised
animations in a seeded random order, taking the first that passes eq. 12 (or the closest one,
counted as a rejection, when none does, so every requested animation exists). Pieces of the
mesh that share no bone with each other are assembled the same way, each from its own anchor.
"""

from collections import deque

import numpy as np

from ..rig.rotations import apply_rigid_into, polar_of_near_rotations


def merge_into(F, t, cut, part, pick, bones_j, polar_i=None, polar_j=None, animation_block=16):
    """Carry component j onto the assembled bones through cut node ``cut`` (eq. 13–14), in place.

    F (N, M, B, 3, 3), t (N, M, B, 3): the assembled animations (cut already set); part: the
    :class:`.splicing.SplicedWalks` of component j over its bones ``bones_j`` (sorted ids, cut
    among them), ``pick (N,)`` its walk used for each output animation. polar_i: the cut node's
    (U, S) on the assembled side when already known, polar_j the same of the cut node's *local*
    position in j's walks (all of them). All animations and bones at once.

    With C = the cut's local position in j (polar U_c S), its world position is R_ref C, so the
    eq. 14 turn U_i (R_ref U_c)ᵀ composed with j's own eq. 10 motion R_ref is U_i U_cᵀ: one rigid
    motion takes j's local positions straight to the assembled world.
    """
    bones_j = np.asarray(bones_j)
    where = int(np.searchsorted(bones_j, cut))
    U_i, S_i = polar_of_near_rotations(F[:, :, cut]) if polar_i is None else polar_i
    U_c, S_c = polar_of_near_rotations(part.F[:, :, where]) if polar_j is None else polar_j
    U_c, S_c = U_c[pick], S_c[pick]
    rotation = U_i @ np.swapaxes(U_c, -1, -2)  # (N, M, 3, 3)
    # Eq. 14: t ← turn (t_j − t_j,cut) + t_cut, in local terms rotation (t − t_cut,local) + t_cut.
    translation = t[:, :, cut] - np.einsum("nmab,nmb->nma", rotation, part.t[pick, :, where])
    others = np.flatnonzero(bones_j != cut)
    apply_rigid_into(F, t, bones_j[others], rotation, translation, part.F, part.t, rows=pick, bones=others,
                     animation_block=animation_block)
    F[:, :, cut] = 0.5 * U_i @ (S_i + S_c)  # eq. 13 (translation stays C_i's)


def cut_bones(components):
    """Bone ids shared by two or more components (sorted bone-id lists): the cut nodes."""
    if not components:
        return np.zeros(0, dtype=np.int64)
    counts = np.bincount(np.concatenate([np.asarray(c, dtype=np.int64) for c in components]))
    return np.flatnonzero(counts > 1)


def merge_order(components):
    """[(component index, shared cut node or None)]: per group of components connected through
    cut nodes, its anchor (cut None) and then the rest in breadth-first order from it.

    The anchor is the most central component of its group's block–cut tree (smallest
    eccentricity: the fewest merges to the farthest component), then the one with the most
    bones, then the lowest index. Every merge hangs a component rigidly from its parent's cut
    node, so whatever the anchor does at its seams, and whatever each merge adds, swings the
    components hung further out by their lever arms: a central anchor keeps those chains short
    (measured on a horse-sized tube cut into a 6-piece chain, components assembled from seamless
    walks: max acceleration / the input's 2.48 with the end piece as anchor, 1.27 with a central
    one). Groups (pieces of the mesh that share no bone) come largest first."""
    sets = [set(c) for c in components]
    count = len(components)
    neighbours = [[o for o in range(count) if o != c and sets[c] & sets[o]] for c in range(count)]

    def depths(start):
        depth, queue = {start: 0}, deque([start])
        while queue:
            here = queue.popleft()
            for other in neighbours[here]:
                if other not in depth:
                    depth[other] = depth[here] + 1
                    queue.append(other)
        return depth

    groups, seen = [], set()
    for c in range(count):
        if c not in seen:
            group = sorted(depths(c))
            seen.update(group)
            groups.append(group)
    groups.sort(key=lambda g: (-sum(len(components[c]) for c in g), g[0]))
    order = []
    for group in groups:
        start = min(group, key=lambda c: (max(depths(c).values()), -len(components[c]), c))
        order.append((start, None))
        placed, queue = {start}, deque([start])
        while queue:
            here = queue.popleft()
            for other in neighbours[here]:
                if other not in placed:
                    placed.add(other)
                    order.append((other, min(sets[here] & sets[other])))
                    queue.append(other)
    return order


def assemble(components, parts, bones, rng, tries=32, dtype=np.float32, contacts=None):
    """Merge per-component animations into whole-rig animations.

    components: list of sorted bone-id lists; parts: one :class:`.splicing.SplicedWalks` per
    component (N walks each); bones: B; dtype of the outputs. contacts: None, or (sources
    (C, N, M) the walks, per component the planted states (Fi, p) of the ground-contact patches
    it moves): among the candidates that pass eq. 12, a component that moves patches takes
    the one whose patches are planted at the most frames where the anchor's walk has them
    planted, and swinging where it has them swinging (the legs' contacts agree with the body's
    travel; ties: the first in the seeded order). Returns (F (N, M, B, 3, 3),
    t (N, M, B, 3) (float64 arithmetic, stored in ``dtype``), choice (N, C) the walk used from
    each component, rejected (int): merges that fell back to the closest).
    """
    count, frames = parts[0].F.shape[:2]
    F = np.zeros((count, frames, bones, 3, 3), dtype=dtype)
    t = np.zeros((count, frames, bones, 3), dtype=dtype)
    order = merge_order(components)
    choice = np.zeros((count, len(components)), dtype=np.int64)
    rejected = 0
    anchor = None
    for c, cut in order:
        part = parts[c]
        ids = np.asarray(components[c])
        if cut is None:  # the anchor of a piece of the mesh: eq. 10 as it is
            anchor = c
            apply_rigid_into(F, t, ids, part.rotation, part.translation, part.F, part.t)
            choice[:, c] = np.arange(count)
            continue
        where = int(np.searchsorted(ids, cut))
        # (N, M, 3, 3): the cut node's local position in component c (S is the same in the world).
        U_c, S_c = polar_of_near_rotations(part.F[:, :, where])
        U_a, S_a = polar_of_near_rotations(F[:, :, cut])
        candidates = np.argsort(rng.random((count, count)), axis=1)[:, :tries]  # a seeded order per animation
        # Eq. 12 for every (a, candidate) pair, as a mean over frames: eq. 12 sums over the M frames
        # but T_c is a single frame's ‖S‖², so taken literally it rejects every pair of long
        # animations (module notes). Summed in numpy's fixed pairwise order, one animation at a
        # time, never through BLAS: a BLAS product (a Gram matrix) sums in an order that depends
        # on its thread count, which flipped borderline merges between --jobs 1 and 2.
        flat_a, flat_c = S_a.reshape(count, -1), S_c.reshape(count, -1)
        difference = np.empty(candidates.shape)
        for a in range(count):
            gap = flat_c[candidates[a]] - flat_a[a]
            difference[a] = np.sum(gap * gap, axis=1) / frames
        peak_a = np.max(np.sum(S_a ** 2, axis=(-1, -2)), axis=1)
        peak_c = np.max(np.sum(S_c ** 2, axis=(-1, -2)), axis=1)
        threshold = 0.05 * np.maximum(peak_a[:, None], peak_c[candidates])  # Zheng's T_c
        passing = difference < threshold
        first = np.argmax(passing, axis=1)
        if contacts is not None and contacts[1][c].shape[1]:
            first = np.argmax(np.where(passing, _agreement(contacts, c, anchor, candidates), -1), axis=1)
        closest = np.argmin(difference, axis=1)
        found = passing.any(axis=1)
        pick = candidates[np.arange(count), np.where(found, first, closest)]
        rejected += int((~found).sum())
        choice[:, c] = pick
        merge_into(F, t, cut, part, pick, ids, (U_a, S_a), (U_c, S_c))
    return F, t, choice, rejected


def _agreement(contacts, c, anchor, candidates):
    """(N, tries) int: at how many frames and patches of component c candidate walk
    ``candidates[a, k]`` has c's patches in the contact state the anchor's walk a has them in.
    Each frame's states are one small integer (a bit per patch), so a candidate costs a gather, an
    exclusive or and a table of bit counts per frame, not a comparison per patch."""
    sources, owned = contacts
    states = np.asarray(owned[c], bool)
    patches = states.shape[1]
    frames = sources.shape[2]
    if patches > 16:  # more patches than a 16-bit code: compared one by one
        theirs = states[sources[anchor]]  # (N, M, p)
        return np.stack([(states[sources[c][candidates[:, k]]] == theirs).sum(axis=(1, 2))
                         for k in range(candidates.shape[1])], axis=1)
    code = (states.astype(np.uint16) << np.arange(patches, dtype=np.uint16)).sum(axis=1, dtype=np.uint16)
    differing = np.array([bin(x).count("1") for x in range(1 << patches)], dtype=np.uint8)
    theirs, mine = code[sources[anchor]], code[sources[c]]  # (N, M)
    return frames * patches - np.stack([differing[mine[candidates[:, k]] ^ theirs].sum(axis=1, dtype=np.int64)
                                        for k in range(candidates.shape[1])], axis=1)
