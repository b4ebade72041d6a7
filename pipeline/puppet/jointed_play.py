"""A puppet played outside its examples (issues 45, 66): where the controls go beyond what the
puppet was trained on, a skeleton follows them by inverse kinematics instead of the kernel CCA's
extrapolation, and carries the nearest examples' own deformation. A jointed skin's skeleton
(``fit-skin --skeleton``), or for a free skin the one its bones keep best (``play`` finds it as
``fit-skin --skeleton`` does before it refits: ``pipeline.skin.free_skin_skeleton``):
the free skin's bones hold their joints within a few per cent of the body, so skinning them on
their joints keeps the body whole (issue 66: the docs' own free samba puppet stretched its arm thin
across the head under the serve, edge strain 2.2× its own samba's at the 99th percentile).

Kernel CCA (Feng §4) is a regression: between its examples it predicts the bones well (and no
better skeleton replaces it: holding its bones on their joints costs the samba 1.4× its held-out
error), beyond them it extrapolates, and a performance unlike the examples (the shared tennis serve
on the samba puppet) stretches the skin: bones turned where no example turned them, off their
joints, their translations from the Poisson solve pulled apart by the controls. So per frame:

1. How far it goes: the extrapolation d, the RMS distance of its controls, in place, to the
   nearest training example over the rest box's largest side (``play --json``'s measure,
   :mod:`skinsynth.pipeline.rig.extrapolation`), against the scale s, the largest gap between
   training examples. The blend α = smoothstep((d − s) / (s/2)) (:data:`BLEND_WIDTH`): 0 inside
   the examples' spread (the kernel CCA's prediction, bit for bit), 1 from 1.5 s (the skeleton),
   the ``view`` indicator's green, amber and red. Whole at 2 s (issue 45), the blend left the
   kernel CCA's tearing in the frames it still weighed most: under the real serve the free samba's
   puppet broke its skin on 69 of 524 frames (an edge stretched past its largest strain in the
   capture by a quarter of its rest length on more than 0.5 % of the edges), the jointed samba's
   on 85, its largest edge strain 2.0× its own samba's (the serve aligned in its still start);
   whole at 1.5 s, 7 and 25, 1.13×. Starting it earlier (at s/2) mended all the free puppet's
   frames but blended held-out frames of the captures themselves, and noisy takes of them: the
   crane's held-out take with noise and gaps played 1.12× the clean controls' error, against
   1.03× (a quarter of s narrower, 5 and 19 broken frames, left for the next turn).
2. The examples it is near: weights over the training examples, w_i ∝ exp(−(d_i² − d_min²) /
   (2 s²)) (the nearest dominates; two at about the same distance share, so the pose never
   jumps when the nearest changes). Their fitted bones (the skin's jointed fit at those frames,
   carried from each example's control frame to this frame's) give the prior pose, and their
   rest offsets — what makes linear blend skinning of those bones reproduce each example exactly
   (:func:`~.correctives.rest_offsets`) — give the deformation, both as the weighted mean.
3. The skeleton towards the controls: inverse kinematics from that prior pose
   (:func:`skinsynth.pipeline.rig.inverse_kinematics.solve_pose`; bones on their joints, lengths
   kept), the prior's weight λ = :data:`SKELETON_PRIOR`.
4. The blend: each bone's rotation R = exp(α log(R_ik R_kccaᵀ)) R_kcca; the root's translation
   and the loose bones' slides mixed linearly and every bone put on its joint, the prediction's
   own joint gaps added back by 1 − α (blending its bones off their joints whole stretched the
   serve's skin 2.7× at the largest); the kernel CCA's correctives by 1 − α, the examples' offsets
   by α; then linear blend skinning.

Frames with α = 0 are left to play's own path; the rest are solved in chunks of :data:`CHUNK`.
"""

from dataclasses import dataclass

import numpy as np

from .alignment import apply_frames
from .correctives import rest_offsets
from .playback import host_inputs, world_bones
from .puppet import in_place
from ..rig.extrapolation import extrapolation_scale, pose_distances
from ..rig.inverse_kinematics import JointedRig, solve_pose
from ..rig.rotations import polar_rotation, rigid_to_dual_quaternion, rotation_exp, rotation_log

#: λ of the skeleton's inverse kinematics (``rig.inverse_kinematics``): how hard the nearest
#: examples' pose holds the bones against the controls (a turn moving a bone's end by 1 cm costs
#: as a control 2 cm off). Measured on the tennis serve on the samba skeleton puppet
#: (docs/mocap.md): 1.0 leaves the controls 4.7 % of the height off (2.0: 6.1 %) but stretches the
#: skin 1.07× / 1.79× its own samba's (p99 / largest; 2.0: 0.97× / 1.15×); 4.0 gains little
#: (0.92× / 1.13×). A relative weight (per bone reach), so it holds for any size and proportions.
SKELETON_PRIOR = 2.0
#: The blend starts at the extrapolation scale (the examples' largest gap) and is whole this share
#: of it later (module notes, 1.).
BLEND_WIDTH = 0.5
#: Frames solved at once (bounds the Jacobians, (CHUNK, 3 n_c, 3 (B + 1 + S)), and the offsets).
CHUNK = 256


@dataclass
class ExamplePoses:
    """What the skeleton path needs of the training examples, made once per puppet (n_p
    examples, B bones, S loose bones, V vertices).

    rig: the :class:`~skinsynth.pipeline.rig.inverse_kinematics.JointedRig` of the skin's skeleton
    on the control vertices; training (n_p, n_c, 3) the examples' controls in place; frame_rotations
    (n_p, 3, 3), frame_translations (n_p, 3) their control frames (world -> in place); rotations
    (n_p, B, 3, 3), root (n_p, 3), slides (n_p, S, 3) the skin's bones at those frames; offsets
    (n_p, V, 3) their exact rest offsets; unit the rest box's largest side; scale the extrapolation
    scale; found: the skeleton was found for a free skin (play's report)."""

    rig: JointedRig
    training: np.ndarray
    frame_rotations: np.ndarray
    frame_translations: np.ndarray
    rotations: np.ndarray
    root: np.ndarray
    slides: np.ndarray
    offsets: np.ndarray
    unit: float
    scale: float
    found: bool = False


def example_poses(puppet, skin, skeleton=None):
    """:class:`ExamplePoses` of a puppet, or None when it has no skeleton. skin: the puppet's skin
    as read (``skeleton``, its /skin/skeleton; ``rotations`` (F, B, 3, 3), ``translations`` (F, B,
    3), ``examples`` (F, V, 3): its fitted bones and frames, of which the puppet's training frames
    are taken); skeleton: a free skin's found one (``parents`` (B,), ``jointed`` (B,), ``joints``
    (B, 3)), where the skin has none of its own."""
    from ..mesh.geometry import largest_side

    skeleton = skin.skeleton if skin.skeleton is not None else skeleton
    if skeleton is None:
        return None
    rotations, translations, examples = skin.rotations, skin.translations, skin.examples

    frames = puppet.train_frames
    controls = np.asarray(examples[frames][:, puppet.control_indices], dtype=np.float64)
    rig = JointedRig(skeleton["parents"], skeleton["jointed"], skeleton["joints"],
                     puppet.rest_vertices[puppet.control_indices], puppet.bone_indices[puppet.control_indices],
                     puppet.bone_weights[puppet.control_indices])
    bones_r = np.asarray(rotations[frames], dtype=np.float64)
    bones_t = np.asarray(translations[frames], dtype=np.float64)
    frame_r, frame_t = in_place(controls, puppet.reference_controls, puppet.global_motion)
    training = apply_frames(frame_r, frame_t, controls)
    offsets = rest_offsets(puppet.rest_vertices, puppet.bone_indices, puppet.bone_weights,
                           rigid_to_dual_quaternion(bones_r, bones_t), np.asarray(examples[frames], np.float64),
                           "linear")
    unit = largest_side(puppet.rest_vertices)
    return ExamplePoses(rig=rig, training=training, frame_rotations=frame_r, frame_translations=frame_t,
                        rotations=bones_r, root=bones_t[:, rig.root], slides=rig.slides(bones_r, bones_t),
                        offsets=offsets, unit=unit, scale=extrapolation_scale(training, unit),
                        found=skin.skeleton is None)


def skeleton_blend(distances, scale):
    """α (N,) of extrapolations distances (N,): smoothstep((d − s) / (w s)), w = :data:`BLEND_WIDTH`:
    0 within s, 1 from (1 + w) s."""
    x = np.clip((np.asarray(distances, dtype=np.float64) - scale) / max(BLEND_WIDTH * scale, 1e-12), 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


@dataclass
class BeyondExamples:
    """The skeleton path's frames of a trajectory of N frames: alpha (N,) each frame's blend; for
    the M frames with α > 0, rows (M,), and the bones and rest offsets to skin them linearly with:
    rotations (M, B, 3, 3), translations (M, B, 3), offsets (M, V, 3) (None when M = 0); found: the
    skeleton was found for a free skin."""

    alpha: np.ndarray
    rows: np.ndarray
    rotations: np.ndarray | None
    translations: np.ndarray | None
    offsets: np.ndarray | None
    found: bool = False


def jointed_frames(puppet, poses, controls, translation_solver=True, prior_weight=SKELETON_PRIOR):
    """The skeleton path for world controls (N, n_c, 3): :class:`BeyondExamples` (module
    docstring)."""
    controls = np.asarray(controls, dtype=np.float64)
    alpha = np.empty(len(controls))
    moving, parts = [], []
    for start in range(0, len(controls), CHUNK):
        chunk = controls[start:start + CHUNK]
        _, placed, world = host_inputs(puppet, chunk)  # in place, and back to the world (n, 4, 4)
        distances = pose_distances(placed, poses.training, poses.unit)  # (n, n_p)
        nearest = distances.min(axis=1)
        alpha[start:start + len(chunk)] = skeleton_blend(nearest, poses.scale)
        rows = np.flatnonzero(alpha[start:start + len(chunk)] > 0.0)
        if rows.size:
            moving.append(start + rows)
            parts.append(_blended_bones(puppet, poses, chunk[rows], world[rows], distances[rows], nearest[rows],
                                        alpha[start + rows], translation_solver, prior_weight))
    if not moving:
        return BeyondExamples(alpha, np.zeros(0, np.int64), None, None, None, poses.found)
    rotations, translations, offsets = (np.concatenate([part[k] for part in parts]) for k in range(3))
    return BeyondExamples(alpha, np.concatenate(moving), rotations, translations, offsets, poses.found)


def _blended_bones(puppet, poses, controls, world, distances, nearest, alpha, translation_solver, prior_weight):
    """(rotations (n, B, 3, 3), translations (n, B, 3), offsets (n, V, 3)) of frames beyond the
    examples (world: their frames' inverse control frames, (n, 4, 4), :func:`.playback.host_inputs`'):
    the examples' pose, the skeleton solved from it, blended with the prediction by α."""
    weights = np.exp(-(distances ** 2 - nearest[:, None] ** 2) / (2.0 * poses.scale ** 2))
    weights /= weights.sum(axis=1, keepdims=True)  # (n, n_p)
    inv_r, inv_t = world[:, :3, :3], world[:, :3, 3]
    # each example's bones carried from its control frame to this one's: inv_f ∘ frame_i
    carried_r = np.einsum("ni,ixy,ibyz->nbxz", weights, poses.frame_rotations, poses.rotations)
    prior_r = polar_rotation(np.einsum("nxy,nbyz->nbxz", inv_r, carried_r))
    in_place_root = np.einsum("ixy,iy->ix", poses.frame_rotations, poses.root) + poses.frame_translations
    prior_root = np.einsum("nxy,ny->nx", inv_r, weights @ in_place_root) + inv_t
    prior_slides = np.einsum("ni,isx->nsx", weights, poses.slides)
    start_t = poses.rig.forward(prior_r, prior_root, prior_slides)
    ik_r, ik_t = solve_pose(poses.rig, prior_r, start_t, controls, prior=(prior_r, prior_root, prior_slides),
                            prior_weight=prior_weight)
    kcca_r, kcca_t, shape_weights = world_bones(puppet, controls, translation_solver)
    a = alpha[:, None, None]
    turn = rotation_exp(a * rotation_log(np.einsum("nbxy,nbzy->nbxz", ik_r, kcca_r)))
    rotations = np.einsum("nbxy,nbyz->nbxz", turn, kcca_r)
    rig = poses.rig
    kcca_root, kcca_slides = kcca_t[:, rig.root], rig.slides(kcca_r, kcca_t)
    gaps = kcca_t - rig.forward(kcca_r, kcca_root, kcca_slides)  # the prediction's joints apart
    translations = rig.forward(rotations, (1.0 - alpha[:, None]) * kcca_root + alpha[:, None] * ik_t[:, rig.root],
                               (1.0 - a) * kcca_slides + a * rig.slides(ik_r, ik_t))
    translations += (1.0 - a) * gaps
    offsets = alpha[:, None, None] * np.einsum("ni,ivx->nvx", weights, poses.offsets)
    if shape_weights is not None:  # the kernel CCA's correctives, by 1 − α
        offsets += np.einsum("ns,svx->nvx", (1.0 - alpha)[:, None] * shape_weights, puppet.correctives.offsets)
    return rotations, translations, offsets


def play_beyond_examples(puppet, poses, controls, vertices, device, translation_solver=True):
    """The frames of controls (N, n_c, 3) beyond the examples replaced in vertices (N, V, 3) (play's
    prediction, float32) by the skeleton path, skinned linearly on ``device``; returns its
    :class:`BeyondExamples` (rig outputs take their bones from it)."""
    from skinsynth.gpu import lbs

    beyond = jointed_frames(puppet, poses, controls, translation_solver)
    for start in range(0, len(beyond.rows), CHUNK):
        part = slice(start, start + CHUNK)
        vertices[beyond.rows[part]] = lbs(puppet.rest_vertices, puppet.bone_indices, puppet.bone_weights,
                                          beyond.rotations[part], beyond.translations[part], device,
                                          rest_offsets=beyond.offsets[part])
    return beyond


def skeleton_summary(alpha, found=False):
    """play's report of the skeleton path: (JSON entry, text line) of the blends α (N,); found: the
    skeleton was found for a free skin."""
    moving = int(np.sum(alpha > 0.0))
    entry = {"frames_beyond": moving, "frames_skeleton": int(np.sum(alpha >= 1.0)), "mean_blend": float(alpha.mean()),
             "prior_weight": SKELETON_PRIOR, "skeleton": "found for the free skin" if found else "the skin's"}
    whose = "a skeleton found for the free skin (the joints its bones keep best)" if found else "the skin's skeleton"
    return entry, (f"skeleton: {moving} of {len(alpha)} frames beyond the examples' spread follow the controls with "
                   f"{whose} ({entry['frames_skeleton']} wholly, mean blend {alpha.mean():.2f}; "
                   "--no-ik plays the kernel CCA's extrapolation)")
