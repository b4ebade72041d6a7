"""Inverse kinematics of a jointed rig towards skinned points: every bone turned so that points
skinned by the rig (a puppet's control vertices) reach their targets, its joints held and its
lengths kept, the turns pulled towards a prior pose where the points leave them free.

The rig is ``fit-skin --skeleton``'s: parents (B,), jointed (B,) and joints q (B, 3), with bone
transforms x ↦ R_b x + t_b. A jointed bone's translation follows from its rotation and its parent's
(:func:`~skinsynth.pipeline.rig.skeleton.hold_joints`: t_b = t_p + (R_p − R_b) q_b); the root and
the free bones carry their own. So the unknowns of a frame are each bone's world rotation and the
translation of each chain's top (the root, the free bones). Along a chain a point skinned to bone
b sits at T_b(v) = R_b (v − q_b) + R_p (q_b − q_p) + … + R_c q_k + t_c, with c the chain's top: a
turn ω_a of any bone a on the way, R_a ← exp(ω_a) R_a, moves it by ω_a × R_a y_a (y_a that term's
vector), a shift of t_c moves it one for one.

Each frame's Gauss–Newton step minimises

    Σ_p ‖Σ_k w_pk T_{b_pk}(v_p) − x_p‖² + Σ_b (λ ℓ_b)² ‖log(R_b R̄_bᵀ)‖²

(points v_p (P, 3) with their skin (P, K), targets x_p, prior rotations R̄_b): a marker's squared
distance against the squared arc its bone's far end would travel, ℓ_b the bone's reach (from its
joint to the farthest of its points or its children's joints, at least :data:`LEAST_REACH` of the
rig's size), and λ = :data:`PRIOR_WEIGHT`. The prior is what a marker set cannot say — the turn
of a limb about itself, the bones no marker rides — and it keeps the step well posed; its weight
is relative (a turn that moves a bone's end by 1 cm costs as a marker 1 cm × λ away), so it holds
for any character's size and proportions. Frames are solved together (batched normal equations).
"""

import numpy as np

from .rotations import polar_rotation, rotation_exp, rotation_log
from .skeleton import depth_first, slide_offsets

#: λ: a prior turn's cost against a marker's distance (see the module docstring). 0.3: a marker
#: set pulls a bone three times as hard as the prior holds it back; a bone its markers fix well
#: follows them to within a few per cent of the miss, and an unseen twist stays at the prior.
PRIOR_WEIGHT = 0.3
#: Least reach of a bone, as a share of the rig's size (a bone with no points and no children).
LEAST_REACH = 0.05
#: Gauss–Newton steps per solve (each one a batched solve of the frames' normal equations).
ITERATIONS = 6


def _skew(u):
    """Cross-product matrices (..., 3, 3) of vectors u (..., 3): [u]× y = u × y."""
    s = np.zeros(u.shape + (3,))
    s[..., 0, 1], s[..., 0, 2], s[..., 1, 2] = -u[..., 2], u[..., 1], -u[..., 0]
    s[..., 1, 0], s[..., 2, 0], s[..., 2, 1] = u[..., 2], -u[..., 1], u[..., 0]
    return s


class JointedRig:
    """The arrays a solve needs, made once per rig and point set.

    parents (B,), jointed (B,) bool, joints (B, 3); points (P, 3) rest positions, point_bones and
    point_weights (P, K). ``loose`` (S,): the bones other than the root that do not hold their
    joint (free or sliding), whose slides s (in the parent's frame: t_b = t_p + R_p (q_b + s_b) −
    R_b q_b, :func:`~skinsynth.pipeline.rig.skeleton.slide_offsets`) are unknowns after the B
    turns and the root's shift. The Jacobian's terms, T of them, one per point, bone of its skin
    and bone up that bone's chain to the root: ``term_point``, ``term_bone``, ``term_weight``,
    ``term_vector`` (T, 3) the rest part of y and ``term_slide`` (T,) the loose bone whose slide
    adds to it (−1: none)."""

    def __init__(self, parents, jointed, joints, points, point_bones, point_weights):
        parents = np.asarray(parents, dtype=np.int64)
        self.parents, self.jointed = parents, np.asarray(jointed, dtype=bool) & (parents >= 0)
        self.joints = np.asarray(joints, dtype=np.float64)
        self.order = depth_first(parents)
        self.root = int(self.order[0])
        self.loose = np.flatnonzero(~self.jointed & (parents >= 0))
        slot = np.full(len(parents), -1)
        slot[self.loose] = np.arange(len(self.loose))
        points = np.asarray(points, dtype=np.float64)
        terms = []
        for p in range(len(points)):
            for bone, weight in zip(np.asarray(point_bones)[p], np.asarray(point_weights)[p]):
                if weight <= 0.0:
                    continue
                at, bone, child = points[p], int(bone), -1
                while True:
                    start = self.joints[bone] if bone != self.root else 0.0
                    terms.append((p, bone, float(weight), child, *(at - start)))
                    if bone == self.root:
                        break
                    at, bone, child = self.joints[bone], int(parents[bone]), int(slot[bone])
        terms = np.array(terms).reshape(-1, 7)
        self.term_point, self.term_bone = terms[:, 0].astype(np.int64), terms[:, 1].astype(np.int64)
        self.term_weight, self.term_slide, self.term_vector = terms[:, 2], terms[:, 3].astype(np.int64), terms[:, 4:]
        self.points, self.point_bones, self.point_weights = points, np.asarray(point_bones), np.asarray(point_weights)
        self.reach = self._reaches(points)

    def _reaches(self, points):
        """ℓ (B,): each bone's reach from its joint (from the origin for the root)."""
        size = float(np.ptp(np.vstack([points, self.joints]), axis=0).max()) or 1.0
        reach = np.zeros(len(self.parents))
        for p in range(len(points)):
            for bone in self.point_bones[p][self.point_weights[p] > 0]:
                reach[bone] = max(reach[bone], np.linalg.norm(points[p] - self.joints[bone]))
        for bone in range(len(self.parents)):
            if self.parents[bone] >= 0:
                parent = self.parents[bone]
                reach[parent] = max(reach[parent], np.linalg.norm(self.joints[bone] - self.joints[parent]))
        return np.maximum(reach, LEAST_REACH * size)

    def slides(self, rotations, translations):
        """The loose bones' slides (..., S, 3) in bones (..., B, 3, 3), (..., B, 3)."""
        return slide_offsets(rotations, translations, self.parents, self.joints, self.loose)

    def forward(self, rotations, root, slides):
        """Translations (F, B, 3) of every bone, parents first: the root's ``root`` (F, 3), every
        other bone on its joint, moved by its slide (the loose bones': slides (F, S, 3))."""
        out = np.empty(rotations.shape[:2] + (3,))
        out[:, self.root] = root
        offsets = np.zeros(rotations.shape[:2] + (3,))
        offsets[:, self.loose] = slides
        for bone in self.order[1:]:
            parent = self.parents[bone]
            out[:, bone] = (out[:, parent] + np.einsum("fxy,fy->fx", rotations[:, parent], self.joints[bone]
                                                       + offsets[:, bone])
                            - rotations[:, bone] @ self.joints[bone])
        return out

    def skinned_points(self, rotations, translations):
        """The points (F, P, 3) skinned by bones (F, B, 3, 3), (F, B, 3)."""
        moved = (np.einsum("fpkxy,py->fpkx", rotations[:, self.point_bones], self.points)
                 + translations[:, self.point_bones])
        return np.einsum("fpkx,pk->fpx", moved, self.point_weights)

    def jacobian(self, rotations, slides):
        """∂ points / ∂ (turns (B, 3), the root's shift (3), slides (S, 3)): (F, 3P, 3 (B + 1 + S))."""
        frames, bones, count = len(rotations), len(self.parents), len(self.points)
        vectors = np.broadcast_to(self.term_vector, (frames,) + self.term_vector.shape).copy()
        slid = self.term_slide >= 0
        vectors[:, slid] += slides[:, self.term_slide[slid]]
        turned = np.einsum("ftxy,fty->ftx", rotations[:, self.term_bone], vectors)
        blocks = np.zeros((frames, count, bones + 1 + len(self.loose), 3, 3))
        weight = self.term_weight[:, None, None]
        np.add.at(blocks, (slice(None), self.term_point, self.term_bone), -weight * _skew(turned))  # ω × u
        at_root = self.term_bone == self.root
        np.add.at(blocks, (slice(None), self.term_point[at_root], bones), weight[at_root] * np.eye(3))
        # a loose bone's slide moves its subtree by R_p s: the term of its parent carries it
        np.add.at(blocks, (slice(None), self.term_point[slid], bones + 1 + self.term_slide[slid]),
                  weight[slid] * rotations[:, self.term_bone[slid]])
        return blocks.transpose(0, 1, 3, 2, 4).reshape(frames, 3 * count, 3 * (bones + 1 + len(self.loose)))


def solve_pose(rig, rotations, translations, targets, prior=None, prior_weight=PRIOR_WEIGHT, iterations=ITERATIONS):
    """The rig turned towards the targets: (rotations (F, B, 3, 3), translations (F, B, 3)),
    every jointed bone on its joint.

    rig: :class:`JointedRig`; rotations, translations (F, B, 3, 3), (F, B, 3): the start; targets
    (F, P, 3) where the points should go; prior: (rotations (F, B, 3, 3), root (F, 3), slides
    (F, S, 3)) the pose the unknowns are pulled to (None: the start's). Gauss–Newton on the
    module's energy, ``iterations`` steps; each step's turns are applied as exp(ω) R, then
    re-orthonormalised; the root's shift and the slides are pulled with weight λ² (per length²)."""
    rotations = polar_rotation(np.asarray(rotations, dtype=np.float64))
    translations = np.asarray(translations, dtype=np.float64)
    root, slides = translations[:, rig.root].copy(), rig.slides(rotations, translations)
    if prior is None:
        prior = rotations.copy(), root.copy(), slides.copy()
    prior_rotations, prior_root, prior_slides = prior
    translations = rig.forward(rotations, root, slides)
    frames, bones, loose = len(rotations), len(rig.parents), len(rig.loose)
    stiffness = np.full(3 * (bones + 1 + loose), prior_weight ** 2)
    stiffness[:3 * bones] = np.repeat((prior_weight * rig.reach) ** 2, 3)
    for _ in range(iterations):
        residual = (rig.skinned_points(rotations, translations) - targets).reshape(frames, -1)
        drift = np.concatenate([rotation_log(np.einsum("fbxy,fbzy->fbxz", rotations, prior_rotations)),  # log(R R̄ᵀ)
                                (root - prior_root)[:, None], slides - prior_slides], axis=1).reshape(frames, -1)
        jac = rig.jacobian(rotations, slides)
        normal = np.einsum("fri,frj->fij", jac, jac) + np.diag(stiffness)
        gradient = np.einsum("fri,fr->fi", jac, residual) + stiffness * drift
        step = -np.linalg.solve(normal, gradient[..., None])[..., 0].reshape(frames, -1, 3)
        rotations = polar_rotation(np.einsum("fbxy,fbyz->fbxz", rotation_exp(step[:, :bones]), rotations))
        root, slides = root + step[:, bones], slides + step[:, bones + 1:]
        translations = rig.forward(rotations, root, slides)
    return rotations, translations

