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

5. The body kept whole (issue 66): the blend is not the only place the kernel CCA tears the skin.
   A frame with more than :data:`TORN_SHARE` of its edges strained a quarter of their rest length
   past both what the capture does to them and what the puppet does to them playing the capture's
   own frames (:mod:`skinsynth.pipeline.mesh.shape`'s envelope, as a synthesis is measured), and
   farther from the training poses than any of the capture's held-out frames (and than s/2:
   :data:`GUARD_REACH`), is given the skeleton by each of :data:`GUARD_LEVELS` in turn until it is
   whole (as little as mends it), eased in and out over :data:`TORN_RAMP_SECONDS` so no frame
   pops. Under the real serve the jointed samba puppet broke 25 of 524 frames at α < 1 (at 0.6–1.3
   s from the examples), the free one (pose-space correctives on) 2; guarded, none (the largest
   share of a frame's edges beyond, 0.41 % and 0.36 %, against the 0.5 % that breaks one), each
   moved 0.4–2.4 % of the diagonal.

   Why the puppet's own play is in the envelope: a frame the puppet plays as well as it can is not
   torn by the performance (without it a puppet that reproduces its capture only roughly, the
   walker of the tests trained on 8 of 32 frames, or the samba without correctives, whose own samba
   strains 77 of 175 frames past the capture's envelope, had its held-out frames handed to the
   skeleton at 2–3× their error). Why only past the held-out frames: nearer, the pose is one the
   puppet interpolates, and a tear there is its controls' doing (a marker filled far off), which the
   skeleton cannot mend: it follows the same controls with a whole limb in the wrong place (the
   cow's and the dancer's takes with gaps, torn at 0.16–0.6 s: worst frames 3–11× the clean
   controls' worst). Such frames, and any the skeleton leaves broken, are named in play's report
   (:func:`skeleton_summary`).

Frames with α = 0 are left to play's own path; the rest are solved in chunks of :data:`CHUNK`.
"""

from dataclasses import dataclass, field

import numpy as np

from .alignment import apply_frames
from .correctives import rest_offsets
from .playback import host_inputs, world_bones
from .puppet import in_place
from ..mesh.shape import BROKEN_SHARE, shape_envelope
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
#: A frame with more than this share of its edges beyond the capture's envelope (module notes, 5.)
#: is played by the skeleton wholly: half the share that makes a frame broken
#: (:data:`~skinsynth.pipeline.mesh.shape.BROKEN_SHARE`, issue 66's measure), so a frame left to the
#: blend is clear of broken, not a hair under it.
TORN_SHARE = 0.5 * BROKEN_SHARE
#: ... and is farther from the nearest training pose than this share of the extrapolation scale s
#: (halfway to the largest gap between examples) and than any of the capture's held-out frames
#: (module notes, 5.): 0.57–0.97 s on the shared human and soft captures, 4 s on the horse's
#: gallop (47 frames). Nearer, the kernel CCA interpolates, and a tear is its controls' doing.
GUARD_REACH = 0.5
#: The skeleton's weight a torn frame is given, in turn, until it is whole: as little of the skeleton
#: as mends the tear, so the frame moves as little from the prediction as it can.
GUARD_LEVELS = (0.25, 0.5, 1.0)
#: The skeleton's weight rises to a torn frame over this long before it and falls over as long
#: after (seconds; smoothstep): a few frames at any rate (2.4 at 24 fps), so the pose never jumps
#: between frames, and short enough to leave the frames around it the blend's.
TORN_RAMP_SECONDS = 0.1
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
    scale; found: the skeleton was found for a free skin (play's report); envelope: the capture's
    :class:`~skinsynth.pipeline.mesh.shape.ShapeEnvelope` (module notes, 5.); held_reach: how far
    (over the scale) the capture's held-out frames go from the training poses, the farthest."""

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
    envelope: object = None
    held_reach: float = 0.0


def example_poses(puppet, skin, skeleton=None, device="cpu"):
    """:class:`ExamplePoses` of a puppet, or None when it has no skeleton. skin: the puppet's skin
    as read (``skeleton``, its /skin/skeleton; ``rotations`` (F, B, 3, 3), ``translations`` (F, B,
    3), ``examples`` (F, V, 3): its fitted bones and frames, of which the puppet's training frames
    are taken; the envelope is of them all); skeleton: a free skin's found one (``parents`` (B,),
    ``jointed`` (B,), ``joints`` (B, 3)), where the skin has none of its own; device: where the
    puppet plays the capture's frames for the envelope (module notes, 5.)."""
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
    scale = extrapolation_scale(training, unit)
    envelope, held_reach = _capture_envelope(puppet, skin, training, unit, scale, device)
    return ExamplePoses(rig=rig, training=training, frame_rotations=frame_r, frame_translations=frame_t,
                        rotations=bones_r, root=bones_t[:, rig.root], slides=rig.slides(bones_r, bones_t),
                        offsets=offsets, unit=unit, scale=scale, found=skin.skeleton is None, envelope=envelope,
                        held_reach=held_reach)


def _capture_envelope(puppet, skin, training, unit, scale, device):
    """(the :class:`~skinsynth.pipeline.mesh.shape.ShapeEnvelope` of the skin's capture (examples
    (F, V, 3), faces) and of the puppet's own play of it, every frame's control vertices: what the
    capture does to each edge, and what this puppet does to it where it plays as well as it can;
    the farthest the held-out frames go from the training poses (training (n_p, n_c, 3) in place),
    over the extrapolation scale: 0 when none is held out)."""
    from .playback import DevicePlayer

    examples = np.asarray(skin.examples)
    controls = examples[:, puppet.control_indices].astype(np.float64)
    own = DevicePlayer(puppet, device).play(controls)
    held = np.setdiff1d(np.arange(len(examples)), puppet.train_frames)
    reach = 0.0
    if held.size:
        _, placed, _ = host_inputs(puppet, controls[held])
        reach = float(pose_distances(placed, training, unit).min(axis=1).max()) / max(scale, 1e-300)
    return shape_envelope(examples, skin.faces, own), reach


def skeleton_blend(distances, scale):
    """α (N,) of extrapolations distances (N,): smoothstep((d − s) / (w s)), w = :data:`BLEND_WIDTH`:
    0 within s, 1 from (1 + w) s."""
    return smoothstep((np.asarray(distances, dtype=np.float64) - scale) / max(BLEND_WIDTH * scale, 1e-12))


def smoothstep(x):
    """3x² − 2x³ of x clipped to [0, 1]: 0 below 0, 1 above 1, its slope 0 at both."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


@dataclass
class BeyondExamples:
    """The skeleton path's frames of a trajectory of N frames: alpha (N,) each frame's blend; for
    the M frames with α > 0, rows (M,), and the bones and rest offsets to skin them linearly with:
    rotations (M, B, 3, 3), translations (M, B, 3), offsets (M, V, 3) (None when M = 0); found: the
    skeleton was found for a free skin; reach (N,): each frame's distance to the nearest training
    pose over the extrapolation scale (d / s); torn: the frames the blend tore, played by the
    skeleton wholly (module notes, 5.); broken: the frames left broken
    (:meth:`~skinsynth.pipeline.mesh.shape.ShapeEnvelope.broken`), wherever they are."""

    alpha: np.ndarray
    rows: np.ndarray
    rotations: np.ndarray | None
    translations: np.ndarray | None
    offsets: np.ndarray | None
    found: bool = False
    reach: np.ndarray | None = None
    torn: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    broken: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))


def jointed_frames(puppet, poses, controls, translation_solver=True, prior_weight=SKELETON_PRIOR, floor=None):
    """The skeleton path for world controls (N, n_c, 3): :class:`BeyondExamples` (module
    docstring); floor (N,): each frame's least α (:func:`torn_floor`), or None."""
    controls = np.asarray(controls, dtype=np.float64)
    alpha, reach = np.empty(len(controls)), np.empty(len(controls))
    moving, parts = [], []
    for start in range(0, len(controls), CHUNK):
        chunk = controls[start:start + CHUNK]
        _, placed, world = host_inputs(puppet, chunk)  # in place, and back to the world (n, 4, 4)
        distances = pose_distances(placed, poses.training, poses.unit)  # (n, n_p)
        nearest = distances.min(axis=1)
        part = slice(start, start + len(chunk))
        reach[part] = nearest / poses.scale
        alpha[part] = skeleton_blend(nearest, poses.scale) if floor is None \
            else np.maximum(skeleton_blend(nearest, poses.scale), floor[part])
        rows = np.flatnonzero(alpha[part] > 0.0)
        if rows.size:
            moving.append(start + rows)
            parts.append(_blended_bones(puppet, poses, chunk[rows], world[rows], distances[rows], nearest[rows],
                                        alpha[start + rows], translation_solver, prior_weight))
    if not moving:
        return BeyondExamples(alpha, np.zeros(0, np.int64), None, None, None, poses.found, reach)
    rotations, translations, offsets = (np.concatenate([part[k] for part in parts]) for k in range(3))
    return BeyondExamples(alpha, np.concatenate(moving), rotations, translations, offsets, poses.found, reach)


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


def play_beyond_examples(puppet, poses, controls, vertices, device, translation_solver=True, clip_frames=None,
                         fps=None):
    """The frames of controls (N, n_c, 3) beyond the examples replaced in vertices (N, V, 3) (play's
    prediction, float32) by the skeleton path, skinned linearly on ``device``, then the frames it
    leaves torn by the skeleton wholly (module notes, 5.; controls: clips of ``clip_frames`` each,
    None one clip, at ``fps``; None: no such guard); returns its :class:`BeyondExamples` (rig
    outputs take their bones from it)."""
    beyond = jointed_frames(puppet, poses, controls, translation_solver)
    _skinned(puppet, beyond, vertices, np.arange(len(controls)), device)
    if fps is None or poses.envelope is None:
        return beyond
    share = beyond_shares(poses.envelope, vertices)
    torn = (share > TORN_SHARE) & (beyond.reach > max(GUARD_REACH, poses.held_reach))
    levels, pending = np.zeros(len(controls)), torn.copy()
    for level in GUARD_LEVELS:  # as little of the skeleton as keeps each torn frame whole
        if not pending.any():
            break
        levels[pending] = np.maximum(levels[pending], level)
        floor = torn_floor(levels, clip_frames or len(controls), fps)
        redo = np.flatnonzero(floor > beyond.alpha)
        if not redo.size:  # the frames still torn are the skeleton's wholly already
            break
        again = jointed_frames(puppet, poses, controls[redo], translation_solver, floor=floor[redo])
        _skinned(puppet, again, vertices, redo, device)
        beyond = _merged(beyond, again, redo)
        share[redo] = beyond_shares(poses.envelope, vertices[redo])
        pending &= share > TORN_SHARE
    beyond.torn = np.flatnonzero(torn)
    beyond.broken = np.flatnonzero(share > poses.envelope.broken_share)
    return beyond


def _skinned(puppet, beyond, vertices, frames, device):
    """Skin ``beyond``'s rows (of the trajectory whose frames are vertices[frames]) linearly into vertices."""
    from skinsynth.gpu import lbs

    for start in range(0, len(beyond.rows), CHUNK):
        part = slice(start, start + CHUNK)
        vertices[frames[beyond.rows[part]]] = lbs(puppet.rest_vertices, puppet.bone_indices, puppet.bone_weights,
                                                  beyond.rotations[part], beyond.translations[part], device,
                                                  rest_offsets=beyond.offsets[part])


def beyond_shares(envelope, vertices):
    """(N,): the share of each frame's edges beyond the envelope
    (:class:`~skinsynth.pipeline.mesh.shape.ShapeEnvelope`) in vertices (N, V, 3), in chunks of frames."""
    return np.concatenate([envelope.beyond_share(vertices[start:start + CHUNK])
                           for start in range(0, len(vertices), CHUNK)] or [np.zeros(0)])


def torn_floor(levels, clip_frames, fps):
    """The skeleton's least α (N,) around torn frames (levels (N,): each frame's α, 0 where it is
    not torn; bools for 1) of clips ``clip_frames`` long at ``fps``: a torn frame's level there,
    easing (smoothstep) to 0 at :data:`TORN_RAMP_SECONDS` from it, the largest where several reach;
    each clip on its own (a crowd's characters follow one another in the trajectory)."""
    reach = max(TORN_RAMP_SECONDS * fps, 1.0)
    clips = np.asarray(levels, dtype=np.float64).reshape(-1, clip_frames)
    times = np.arange(clip_frames)
    floor = np.zeros(clips.shape)
    for clip in np.flatnonzero(clips.any(axis=1)):  # clips, never vertices
        torn = np.flatnonzero(clips[clip])
        ease = smoothstep(1.0 - np.abs(times[:, None] - torn[None, :]) / reach)  # (frames, torn)
        floor[clip] = (ease * clips[clip, torn][None, :]).max(axis=1)
    return floor.reshape(-1)


def _merged(beyond, again, redo):
    """``beyond`` with the frames ``redo`` (into its trajectory) replaced by ``again``'s (all of them
    with α > 0)."""
    keep = ~np.isin(beyond.rows, redo)
    rows = np.concatenate([beyond.rows[keep], redo[again.rows]])
    order = np.argsort(rows, kind="stable")

    def joined(old, new):
        return np.concatenate([old[keep], new])[order] if old is not None else new[order]

    alpha = beyond.alpha.copy()
    alpha[redo] = again.alpha
    return BeyondExamples(alpha, rows[order], joined(beyond.rotations, again.rotations),
                          joined(beyond.translations, again.translations), joined(beyond.offsets, again.offsets),
                          beyond.found, beyond.reach)


def skeleton_summary(beyond):
    """play's report of the skeleton path (:class:`BeyondExamples`): (JSON entry, text lines)."""
    alpha = beyond.alpha
    moving = int(np.sum(alpha > 0.0))
    entry = {"frames_beyond": moving, "frames_skeleton": int(np.sum(alpha >= 1.0)), "mean_blend": float(alpha.mean()),
             "prior_weight": SKELETON_PRIOR, "skeleton": "found for the free skin" if beyond.found else "the skin's",
             "frames_torn": len(beyond.torn), "frames_broken": [int(f) for f in beyond.broken]}
    whose = "a skeleton found for the free skin (the joints its bones keep best)" if beyond.found \
        else "the skin's skeleton"
    lines = [f"skeleton: {moving} of {len(alpha)} frames beyond the examples' spread follow the controls with "
             f"{whose} ({entry['frames_skeleton']} wholly, mean blend {alpha.mean():.2f}, {len(beyond.torn)} of them "
             "because the blend tore the skin; --no-ik plays the kernel CCA's extrapolation)"]
    if len(beyond.broken):
        inside = beyond.broken[beyond.reach[beyond.broken] < GUARD_REACH]
        lines.append(f"warning: {len(beyond.broken)} frame(s) tear the skin (frames {_frame_list(beyond.broken)}: more "
                     f"than {BROKEN_SHARE:.1%} of their edges strained a quarter of their length past anything the "
                     "capture and the puppet's own play of it show)" + (
                         f"; {len(inside)} of them within the examples' spread, where the controls disagree with one "
                         "another (a marker filled far off: see the take's filled frames)" if len(inside) else "") + (
                         "; beyond the examples, the performance goes where the puppet's examples never went: a "
                         "capture with such poses among them plays it whole" if len(inside) < len(beyond.broken)
                         else ""))
    return entry, lines


def _frame_list(frames, shown=8):
    """'a, b, c, … (N in all)' of frame numbers."""
    text = ", ".join(str(int(f)) for f in frames[:shown])
    return text + (f", … ({len(frames)} in all)" if len(frames) > shown else "")
