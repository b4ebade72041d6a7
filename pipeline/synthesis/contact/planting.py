"""Feet that stay planted (issue 35, parts 2 and 3): the input's ground contacts kept on the output.

build-graph finds, per input frame, which patches of the mesh rest on the ground
(:mod:`.contact_patches`), and marks the transitions within a clip that would take a patch from
planted to swinging or back (:func:`mark_contact_jumps`: a synthesis with contacts walks the
others, :func:`contact_transitions`); the merge prefers legs whose contacts agree with the body's
(:func:`.assembly.assemble`). An output frame plays, per bone component, some input frame (its
walk's source), so a patch is *planted* at an output frame where the component that owns it (the
one whose bones carry most of the patch's skin weight) plays a frame where the patch was planted
(:func:`output_states`). A run of planted output frames is a *plant*. During a plant the patch
must do what the input's patch did at those source frames, and nothing else: stay where it
landed (on a treadmill, travel with the belt, as the input's did) and keep the input's height.
The targets are the input frames themselves, not the fit's playback of them (a 20-bone fit of the
samba slides its feet 0.22 % of the height a frame where the dancer slides 0.08 %).

Splicing (a seam's blend) and the multi-component merge (a body from one input frame, legs from
others: Zheng §4.2) break that, and the foot slides. The correction (:func:`plant_feet`): its
targets, compiled in :mod:`.planting_loops` (:func:`plant_targets`, steps 0–6 below, one animation
at a time), and the limbs that make them, compiled in :mod:`.limb_reach` (:func:`reach_targets`):

0. **Plants**: a patch's states at its owner's source frames, a gap of at most :data:`BRIDGE`
   between two plants bridged (the patch follows the input's steps and heights through it).
1. **The feet's turn.** Each patch on bones of its own (:data:`CARRIES`) asks its bone turned, at
   most :data:`MAX_TURN`: at a plant's first frame (and where the input's foot is lifted inside a
   bridged gap) to the orientation the input's patch had at the source frame (the fit's error at the
   patch undone by a Kabsch fit E per input frame, then under the output's heading); at every later frame of the plant to the orientation
   it had one frame before, turned by the input patch's own step into the source frame (under the
   output's heading), as the centroid is moved by its own steps (2.). So a planted foot turns only
   as the input's did: neither a seam's jump in the source frame nor a splice's blend, which
   turns the legs over its window, turns it (on the crane, the planted feet slid 0.56 % of the
   height a frame within 6 frames of a seam, 9 times the input's, when each frame's orientation
   was the input's under the blended heading, a seam's jump spread over σ = ``half_life``). Past
   :data:`HOLD` what the turn holds beyond :data:`TURN_BOUND` leaks (:data:`LIMB_MEMORY`): a plant
   of minutes (the samba's feet are planted 97 % of the time) sums every seam's turn, and held at
   up to 35° the limbs twisted to make it and slid the feet instead (the samba's single component:
   median slide 2.0× the input's; 0.6× with the leak).
2. **The patch's error.** Its centroid c(m) is linear in the bones (Σ_b F_b ā_pb + ω_pb t_b, ā
   and ω the patch's weighted rest positions and weights). Its step c(m) − c(m−1) should be the
   input's own horizontal step into the source frame, carried by the patch bone's map
   A(m) = F_out(m) F_in(src(m))⁻¹ (the identity where the output plays the input unchanged; the
   segment's heading after a seam): the slide error v(m) at each step inside a plant. The height
   error: the input patch's lowest height at the source frame (above its clip's ground, placed on
   the output's), spliced over each seam's window as the splice blends the motion
   (:func:`target_heights`), minus the output patch's lowest point (its skinned sample vertices,
   :func:`lowest_samples`: a tilted foot lands on its toe, not its centroid).
3. **A root offset** (the body travels as its planted feet push it): −mean v(m) over the patches
   stepping inside a plant, smoothed (a Gaussian of σ = ``half_life``) and summed into a
   horizontal offset; a vertical offset, the planted patches' mean height error smoothed the same
   way (normalised: zero far from any plant). Both move every bone.
4. **A limb correction** e_p(m) per patch, what the root leaves, exactly: inside a plant the
   residual slide summed from the plant's first frame (0 there; past :data:`HOLD` what exceeds
   :data:`LIMB_BOUND` leaks, :data:`LIMB_MEMORY`; let go where the input's foot is lifted inside a
   bridged gap, :data:`RELEASE`) and the residual height error.
   The limbs make it (:mod:`.limb_reach`): the patch's centroid moved by e_p and its anchor bone
   turned by step 1's turn, by the joints of its limb (:mod:`.limb_chains`: ankle, knee, hip)
   within the ranges the input shows them in, all that hangs below a joint turning with it; what
   the limb cannot reach slides.
   **The floor**: where a patch is not planted, its lowest point is kept no lower than the input
   patch's at the source frame, the lift it needs dilated and smoothed (a raised cosine over
   ``lift_radius`` frames) and tapered to 0 at the plants, added to its e_p.
5. **Blending in and out** (inertialization, Holden's critically damped spring, for the turn and
   the limb corrections): outside plants each is the decay x(k) = (x₀ + c k) e^(−y k) of its
   value at the nearest plant edge, y = 2 ln 2 / half-life a frame, c chosen so that the first
   step out equals the last step in (frame for frame, not only in continuous time); in a gap
   between two plants the backward spring starts from what the forward one leaves, and the
   forward one's first step gives up what the backward one still holds at the gap's start (both
   are linear in their starts: solved at once, where that is well posed). So a plant's start and
   end carry no velocity jump.
6. **Limits: the plants add no pops** (issue 48). Every correction is bounded by one limit L,
   :data:`EDGE_ACCEL` of the input's largest vertex acceleration (mesh units a frame²; for a turn,
   L over the farthest its turn moves a vertex, :func:`turn_reach`):

   - a spring out of (or into) a plant is slowed so its start adds at most L (y² ‖x₀‖ ≤ L);
   - a plant starts from what the last plant's spring still holds at its first frame (the foot
     lands where that leaves it): a gap too short to let a large correction go within L no longer
     throws it back at the default rate; such a carried correction keeps its age, so past
     :data:`HOLD` its excess over :data:`LIMB_BOUND` leaks;
   - inside a plant a limb sum takes each step's residual, and a turn each step's change, up to
     L / 2y a frame (a spring started with that velocity adds 2 y v ≤ L); a leg that drags its
     foot faster (a merge of walks at different paces: the tempo walker's legs slid up to 15 % of
     its height a frame) makes the foot slide by the rest, where holding it exactly threw the
     limb as the foot lifted (the walk that gets going, seven components: 9.7× the input's largest
     acceleration, 3.5× without contacts; on the real captures the cap binds at 0–2 % of the steps);
   - the root's push is smoothed with a wider Gaussian where the root would accelerate by more than
     L, and a swinging foot's lift over a wider radius where it would (each σ or radius at most
     :data:`HOLD`, three widenings at most).

   Not limited: a bridged gap's release (:data:`RELEASE`). Spread over π √(x / 2L) frames, longer
   than the samba's 2–3-frame lifts, it left part of each sum held: the samba's largest
   acceleration fell from 1.01× to 0.81× the input's (16 × 600, two components) but its feet's
   median slide rose from 1.50× to 1.78× the input's, and 1.01× is inside what issue 48 allows.

   And the limbs: each joint's turn changes its step by at most :data:`.limb_reach.JOINT_ACCEL` L
   over its reach (:func:`.limb_reach._track`), whatever its solution does from one frame to the
   next.

Why a limb's joints, not a shift of its bones (issue 62): the first corrections moved each bone
near a patch by a translation falling off over two hops of the bone graph, and turned the foot's
bones about the patch's centroid. Two neighbouring bones shifted by different amounts shear the skin
between them, and a foot turned about its sole tears at the ankle: 69 % of the dancer's synthesized
frames and 41 % of the samba's were broken (:mod:`..shape`), where the same walks without plants
had none. A skeleton's move keeps every joint and bone length, so the skin bends as the rig bends
it; the limbs' ranges and their acceleration limit keep it to what the input shows.

After the plants, synthesize still keeps the input's range of lowest points (:mod:`.contact`), a
safety net that is zero wherever the plants kept it: a merge can plant one foot and sink the other.
With contacts its floor is the contacts' ground (:func:`.contact.ground_floored`) and its lowest
points are the plant loop's own (the patches' samples, once planted) with the support's others.
Where the input has no contacts there is nothing to plant and this module is not used (the
outputs stay byte-identical). ``synthesize --no-contact`` turns both off, and walks every
transition.
"""


from dataclasses import dataclass

import numpy as np

from .ground import raised_cosine
from ...mesh.contact_measures import character_height
from ...rig.influence import dense_weights
from .limb_chains import plant_chains
from .limb_shape import HALVINGS, limb_seams, no_seams
from .patches import patch_vertices

#: Half-life (seconds) of the blend in and out of a limb correction, and the σ of the root's smoothing.
HALF_LIFE = 0.1
#: Largest turn (degrees) given a planted patch's own bones: a foot that a merge tilted further than
#: this (a shin from another frame) is turned this far only, for turning it all the way tears the ankle.
#: Since a plant holds its foot's orientation from frame to frame (module notes, 1.), the turn also
#: undoes what a splice's blend turns the leg by over its window: on the crane that reached 20° at
#: seams between frames whose feet differ, and the foot then turned with the leg (sliding steps 2.4×
#: the input's share, slide p95 1.57×); at 35°, none and 1.23×, the largest acceleration unchanged
#: (1.13× the input's) and the samba's below 0.9×.
MAX_TURN = 35.0
#: Degrees a plant holds its foot's turn (module notes, 1.) past :data:`HOLD` before what exceeds
#: them leaks, with the time constant :data:`LIMB_MEMORY`, as a limb's summed slide does past
#: :data:`LIMB_BOUND`.
TURN_BOUND = 5.0
#: A bone carries a patch (and is turned with it) when its mean weight on the patch is at least this
#: share of the patch's heaviest bone's (a foot bone, not the shin's few percent at the ankle).
CARRIES = 0.25
#: Longest gap (seconds) between two plants of a patch that the output treats as one plant: a foot
#: lifted for a frame or two (the input's own flicker, or a seam between two plants) keeps its
#: correction instead of ending one plant and starting the next from zero, which within two
#: frames was the samba's largest acceleration (1.5× the input's); the patch follows the input's
#: own steps and heights through the gap, as it would inside a plant.
BRIDGE = 0.2
#: Seconds a plant holds its patch exactly: the residual of each step (what the root's push leaves)
#: is summed into the limb's correction so the foot stays put. Past them, what the sum holds beyond
#: :data:`LIMB_BOUND` leaks, with a time constant of :data:`LIMB_MEMORY` seconds: a systematic
#: residual (two feet whose merged walks err differently, seams inside a plant) summed over a plant
#: of minutes drives the feet apart without bound (the samba's, planted 97 % of the time, gaps
#: bridged: 3.6 heights apart after 3,000 frames; bounded, at most 0.36 H, the input's 0.24 H). A step's stance (the walker's: 0.7 s) is held
#: exactly, however large its correction, while the leg drags the foot no faster than the cap of the
#: module notes' 6.; a correction carried over from the last plant keeps its age.
HOLD = 2.0
#: Time constant (seconds) of the leak past :data:`HOLD`.
LIMB_MEMORY = 1.0
#: Shortest time (seconds) over which a bridged gap lets a limb's summed slide go. Where the input's
#: foot is lifted inside a bridged plant (:data:`BRIDGE`), the sum is released along a raised
#: cosine over the gap (over this long, and then only in part, where the gap is shorter), and the
#: plant's :data:`HOLD` starts again: the foot is in the air, so moving it slides nothing. The
#: samba's feet lift for 2–3 frames every 1.6–3.7 s.
RELEASE = 0.125
#: Share of the input's largest vertex acceleration a limb correction's spring at a plant's edge may
#: add (module notes, 5.): the spring x(k) = (x₀ + c k) e^(−y k) accelerates by y² ‖x₀‖ as it starts,
#: so a large correction let go at :data:`HALF_LIFE` (past :data:`HOLD` it may hold :data:`LIMB_BOUND`
#: of the height) kicked the foot as it lifted: on the crane, 50 × 600, the largest
#: acceleration was 1.57× the input's (1.13× in most animations, at the lift of frame 64) where
#: the same walks without contacts stay at 0.91×. There y is slowed to √(limit / ‖x₀‖): 1.14× at
#: a quarter (1.05× at a tenth). A quarter leaves the limb's own motion as it lifts most of the
#: room under the input's largest, and keeps :data:`HALF_LIFE` for any correction under three
#: quarters of the input's largest acceleration (in mesh units): the usual, small ones. The same
#: limit bounds every other correction (module notes, 6.): why a share of the input's own largest, not
#: a number: it scales with the character's size, frame rate and pace, so one share holds on a walker,
#: a dancer and a horse alike.
EDGE_ACCEL = 0.25
#: Share of the character's height a limb's summed slide may reach past :data:`HOLD` before the part
#: beyond it leaks (:data:`LIMB_MEMORY`). Why a bound, not a leak of the whole sum: a leak moves the
#: planted foot by its share of the sum every frame, a creep on the ground; on the samba's two
#: components (16 × 600) that made the feet slide 1.8× what the input's did. Why this bound, since
#: the limbs make the corrections with their joints (:mod:`.limb_reach`): a sum held for seconds
#: past a few hundredths of the height is one the leg cannot reach within the ranges the input shows
#: (the samba's merged legs: a median correction of 2 % of the height, 9–10 % at the 95th
#: percentile), so the foot is dragged by the leg's range, not held; letting it go over
#: :data:`LIMB_MEMORY` slides it less. On the samba's two components (20 × 600, seed 3) the feet's
#: slide at the 95th percentile was 3.0 / 2.4 / 1.7× the input's, and their sliding share
#: 4.5× at 0.03 and 3.7× at 0.015, at a bound of 0.1 / 0.03 / 0.015 of the height; the dancer's,
#: the crane's and the walker's did not move (their stances are shorter than :data:`HOLD`). Letting
#: go more often costs acceleration where merged legs drag the feet (the planted walker's
#: components, ``test_plants_add_no_acceleration``: 1.86 / 1.79 / 2.56 of the plants' limit added,
#: within the three a leg's joints may add), not on the captures (the samba's largest 0.84× the
#: input's). A share of the height: a correction is a shift of the foot.
LIMB_BOUND = 0.015


@dataclass
class PlantRig:
    """What the output's plants need from the input, made once per synthesis
    (:func:`plant_rig`). P patches, b the bones that move them, Fi input frames, S sample vertices.

    planted (Fi, P) bool; owner (P,) the component owning each patch; bones (b,) ids; rest_terms
    (P, b, 3) ā (each patch's weighted rest centroid per bone) and weight_terms (P, b) ω (each
    patch's mean weight per bone); anchor_bone (P,) the bone carrying most of each patch (slot in
    ``bones``); inverse_in (Fi, P, 3, 3) that bone's inverse input matrix; steps_in (Fi, P, 3) the
    input patch centroid's horizontal step into each frame (0 at a clip's first frame) in that
    bone's frame (F_in⁻¹ Δ); heights_in (Fi, P) the height of its lowest vertex above its clip's
    ground; sample_rest (P, S, 3), sample_bones and sample_weights (P, S, K) the rest positions and
    skin of the vertices that find each patch's lowest point (:func:`lowest_samples`; padding:
    weight 0); ground (Fi,) the ground of each frame's clip; own: per patch the
    bones that carry it and turn with it (:data:`CARRIES`; none where another patch shares one);
    orientation_in (Fi, P, 3, 3) the orientation the anchor bone should have to carry the patch as
    the input's (E R_in); turn_steps_in (Fi, P, 3, 3) its step into each frame, O(f) O(f − 1)ᵀ (the
    identity at a clip's first frame); chains: the :class:`.limb_chains.LimbChains` that make the
    corrections; lever (P,) each patch's size (:func:`patch_levers`); decay y per frame; sigma (frames) of the root's
    smoothing and of a seam's turn; bridge (frames) the longest gap between plants bridged
    (:data:`BRIDGE`); hold and memory (frames): how long a plant is held exactly, and the time
    constant of the leak past it (:data:`HOLD`, :data:`LIMB_MEMORY`); bound (mesh units) what a
    limb's sum may hold past the hold (:data:`LIMB_BOUND`); release (frames) the shortest
    release of a bridged gap (:data:`RELEASE`); edge_limit (mesh units a frame²) what a limb
    correction's spring at a plant's edge may accelerate (:data:`EDGE_ACCEL`), and turn_limit (P,)
    (radians a frame²) a turn's, the same limit over the farthest its turn moves a vertex
    (:func:`turn_reach`; inf for a patch that does not turn); max_turn and turn_bound (radians:
    :data:`MAX_TURN`, :data:`TURN_BOUND`); up_axis; rest (V, 3), bone_indices and bone_weights
    (V, K) the skin; seams: the :class:`.limb_shape.LimbSeams` each limb's turn is checked on (None:
    no check); window, spread_velocity, clips: the splice's (:class:`..synthesis.Request`), which the
    target heights are spliced with (:func:`target_heights`)."""

    planted: np.ndarray
    owner: np.ndarray
    bones: np.ndarray
    rest_terms: np.ndarray
    weight_terms: np.ndarray
    anchor_bone: np.ndarray
    inverse_in: np.ndarray
    steps_in: np.ndarray
    heights_in: np.ndarray
    sample_rest: np.ndarray
    sample_bones: np.ndarray
    sample_weights: np.ndarray
    ground: np.ndarray
    own: list
    orientation_in: np.ndarray
    turn_steps_in: np.ndarray
    chains: object
    lever: np.ndarray
    decay: float
    sigma: float
    bridge: int
    hold: int
    memory: float
    bound: float
    release: int
    edge_limit: float
    turn_limit: np.ndarray
    max_turn: float
    turn_bound: float
    up_axis: int
    rest: np.ndarray = None
    bone_indices: np.ndarray = None
    bone_weights: np.ndarray = None
    seams: object = None
    window: int = 4
    spread_velocity: bool = True
    clips: object = None

    @property
    def lift_radius(self):
        """Frames (⌈σ⌉, at least 1) over which a swinging patch's lift (the floor: module notes)
        is dilated and smoothed, and tapered off at the plants."""
        return max(1, int(np.ceil(self.sigma)))

    def concerning(self, component, bones):
        """The planted states (Fi, p) of the patches a component (its index, its bones) moves:
        those it owns and those whose limb holds one of its bones (a thigh or a shin cut into a
        component of its own decides where its foot goes)."""
        bones = np.asarray(bones, dtype=np.int64)
        reached = np.array([np.isin(limb, bones).any() for limb in self.chains.limb_bones], dtype=bool)
        return self.planted[:, (self.owner == component) | reached]

    def limbs(self):
        """(joints (L, n), patches (L, p)), −1 padded: the limbs the plants move, each a chain's
        joints (parents first) and the patches whose last joint is on it (patches sharing a chain
        are solved together); a patch with no limb is in none."""
        from .limb_chains import parent_top

        chains = self.chains
        tops = sorted({parent_top(chains.parent, int(k)) for k in chains.patch_joint if k >= 0})
        groups = [(np.array([k for k in range(chains.joints) if parent_top(chains.parent, k) == top], np.int64),
                   np.array([p for p, k in enumerate(chains.patch_joint) if k >= 0
                             and parent_top(chains.parent, int(k)) == top], np.int64)) for top in tops]
        joints = np.full((len(groups), max([1] + [g[0].size for g in groups])), -1, np.int64)
        patches = np.full((len(groups), max([1] + [g[1].size for g in groups])), -1, np.int64)
        for l, (j, q) in enumerate(groups):
            joints[l, :j.size], patches[l, :q.size] = j, q
        return joints, patches


def patch_owners(patches, dense, components):
    """(P,) the component (index into ``components``, sorted bone-id lists) carrying most of each
    patch's skin weight; patches: lists of vertex ids; dense (V, B) weights."""
    mass = np.array([[dense[np.asarray(p)][:, c].sum() for c in components] for p in patches]).reshape(len(patches), -1)
    return np.argmax(mass, axis=1).astype(np.int64) if len(components) else np.zeros(len(patches), np.int64)


def plant_rig(rest, bone_indices, bone_weights, rotations, translations, examples, patches, planted, grounds,
              clip_starts, fps, components, tree, up_axis=1, half_life=HALF_LIFE, max_turn=MAX_TURN,
              bridge=BRIDGE, hold=HOLD, limb_memory=LIMB_MEMORY, limb_bound=LIMB_BOUND, release=RELEASE,
              edge_accel=EDGE_ACCEL, samples=None, turn_bound=TURN_BOUND, envelope=None):
    """The :class:`PlantRig` of an input: rest (V, 3), weights (V, K), its fit rotations
    (Fi, B, 3, 3) and translations (Fi, B, 3), and the input frames themselves, examples
    (Fi, V, 3): the plants follow the input, not the fit's playback of it (a 20-bone fit of the
    samba slides its feet 0.22 % of the height a frame where the dancer slides 0.08 %); patches:
    the contact patches' vertex ids (list of P arrays), planted (Fi, P) bool and grounds (C,) each
    clip's ground (:class:`.contact_patches.ContactPatches`); clip_starts (C + 1,); fps;
    components (sorted bone-id lists: the synthesis's, which own the patches); bridge (seconds,
    :data:`BRIDGE`); hold and limb_memory (seconds, :data:`HOLD`, :data:`LIMB_MEMORY`); limb_bound (a
    share of the height, :data:`LIMB_BOUND`); release (seconds, :data:`RELEASE`); edge_accel (a
    share of the input's largest vertex acceleration, :data:`EDGE_ACCEL`); samples:
    the sample vertex ids (P, S) of :func:`lowest_samples` when the caller has them already
    (None: found here); tree: the skin's :class:`~skinsynth.pipeline.rig.joint_tree.JointTree`, which
    the limbs are found on (:func:`.limb_chains.plant_chains`); turn_bound (degrees, :data:`TURN_BOUND`);
    envelope: the capture's :class:`...mesh.shape.ShapeEnvelope`, which the limbs' turns keep to
    (:mod:`.limb_shape`; None: unchecked)."""
    from ...mesh.geometry import largest_acceleration
    from ...rig.rotations import polar_rotation

    rest = np.asarray(rest, dtype=np.float64)
    frames, B = rotations.shape[:2]
    dense = dense_weights(bone_indices, bone_weights, B)
    weight_terms = np.stack([dense[np.asarray(p)].mean(axis=0) for p in patches])  # (P, B)
    rest_terms = np.stack([(dense[np.asarray(p)][:, :, None] * rest[np.asarray(p)][:, None, :]).mean(axis=0)
                           for p in patches])  # (P, B, 3)
    bones = np.flatnonzero(weight_terms.any(axis=0))
    owner = patch_owners(patches, dense, components)
    anchor = np.argmax(weight_terms[:, bones], axis=1)  # slot in bones
    R = np.asarray(rotations, dtype=np.float64)
    T = np.asarray(translations, dtype=np.float64)
    examples = np.asarray(examples, dtype=np.float64)
    centroids = np.stack([examples[:, np.asarray(p)].mean(axis=1) for p in patches], axis=1)  # (Fi, P, 3)
    own = [np.flatnonzero(weight_terms[p] >= CARRIES * weight_terms[p].max()) for p in range(len(patches))]
    # only a patch at the end of a limb turns its bones: where two patches share one (the flank and
    # the shoulder of a horse lying down), turning it for each about its own centroid would fight
    shared = np.bincount(np.concatenate(own), minlength=B) > 1 if own else np.zeros(B, bool)
    own = [bones_p if not shared[bones_p].any() else bones_p[:0] for bones_p in own]
    # E: the turn taking the fit's patch onto the input's, per frame (Kabsch about the centroids; the
    # identity for a patch that does not turn)
    turns = []
    for p, ids in enumerate(patches):
        ids = np.asarray(ids)
        on = np.flatnonzero(dense[ids].any(axis=0))  # the patch's bones (the others add exact zeros)
        fitted = np.einsum("vb,fbij,vj->fvi", dense[ids][:, on], R[:, on], rest[ids]) \
            + np.einsum("vb,fbi->fvi", dense[ids][:, on], T[:, on])
        fitted -= fitted.mean(axis=1, keepdims=True)
        turn = polar_rotation(np.einsum("fvi,fvj->fij", examples[:, ids] - centroids[:, None, p], fitted)) \
            if own[p].size else np.broadcast_to(np.eye(3), (frames, 3, 3))
        turns.append(turn)
    turns = np.stack(turns, axis=1)  # (Fi, P, 3, 3)
    starts = np.asarray(clip_starts, dtype=np.int64)
    first = np.zeros(frames, bool)
    first[starts[:-1]] = True
    steps = np.zeros_like(centroids)
    steps[1:] = centroids[1:] - centroids[:-1]
    steps[first] = 0.0
    steps[..., up_axis] = 0.0  # only the slide is carried: the height has its own target
    clip = np.searchsorted(starts, np.arange(frames), side="right") - 1
    ground = np.asarray(grounds, dtype=np.float64)[clip]
    # the height each patch's lowest point keeps (the input's lowest patch vertex), and the vertices
    # that find the output's lowest point: a merge can tilt a foot further than its turn undoes
    heights = np.stack([examples[:, np.asarray(ids), up_axis].min(axis=1) for ids in patches], axis=1) - ground[:, None]
    samples = lowest_samples(rest, examples, patches, up_axis) if samples is None else np.asarray(samples)
    at = np.maximum(samples, 0)  # padding (−1) reads vertex 0 with weight 0
    sample_weights = np.where(samples[..., None] >= 0, np.asarray(bone_weights, np.float64)[at], 0.0)
    anchor_in = R[:, bones[anchor]]  # (Fi, P, 3, 3)
    edge_limit = edge_accel * largest_acceleration(examples, starts)
    lever = turn_reach(rest, dense, patches, own)
    turn_limit = np.where(lever > 0.0, edge_limit / np.where(lever > 0.0, lever, 1.0), np.inf)
    chains = plant_chains(tree, bones[anchor], [rest[np.asarray(ids)].mean(axis=0) for ids in patches], R, rest,
                          bone_indices, bone_weights)
    inverse_in = np.linalg.inv(anchor_in)
    orientation = turns @ anchor_in
    turn_steps = np.broadcast_to(np.eye(3), orientation.shape).copy()  # identity at a clip's first frame
    turn_steps[1:] = orientation[1:] @ np.swapaxes(orientation[:-1], -1, -2)
    turn_steps[first] = np.eye(3)
    rig = PlantRig(planted=np.asarray(planted, bool), owner=owner, bones=bones, rest_terms=rest_terms[:, bones],
                    weight_terms=weight_terms[:, bones], anchor_bone=anchor, inverse_in=inverse_in,
                    steps_in=(inverse_in @ steps[..., None])[..., 0], heights_in=heights, sample_rest=rest[at],
                    sample_bones=np.asarray(bone_indices)[at], sample_weights=sample_weights, ground=ground,
                    own=own, orientation_in=orientation, turn_steps_in=turn_steps, chains=chains,
                    lever=patch_levers(rest, patches, character_height(rest, up_axis)),
                    decay=2.0 * np.log(2.0) / (half_life * fps), sigma=half_life * fps,
                    bridge=int(round(bridge * fps)), hold=int(round(hold * fps)), memory=limb_memory * fps,
                    bound=limb_bound * character_height(rest, up_axis), release=max(1, int(round(release * fps))),
                    edge_limit=edge_limit, turn_limit=turn_limit,
                    max_turn=np.radians(max_turn), turn_bound=np.radians(turn_bound), up_axis=int(up_axis),
                    rest=rest, bone_indices=np.asarray(bone_indices, np.int64),
                    bone_weights=np.asarray(bone_weights, np.float64))
    if envelope is not None:
        rig.seams = limb_seams(rig.limbs()[0], chains.bone_joint, bone_indices, bone_weights, envelope)
    return rig


#: The least size of a patch the limbs' orientation target assumes, as a share of the height.
LEAST_LEVER = 0.01


def patch_levers(rest, patches, height):
    """(P,) each patch's size at rest: the RMS distance of its vertices from its centroid, at least
    :data:`LEAST_LEVER` of the height. The limbs weigh a patch's turn by it (:mod:`.limb_reach`): a
    turn of one radian misses by as much as the patch's vertices move."""
    rest = np.asarray(rest, dtype=np.float64)
    sizes = [np.sqrt(((rest[np.asarray(ids)] - rest[np.asarray(ids)].mean(axis=0)) ** 2).sum(axis=1).mean())
             for ids in patches]
    return np.maximum(np.array(sizes, dtype=np.float64).reshape(-1), LEAST_LEVER * height)


def turn_reach(rest, dense, patches, own):
    """(P,) how far a turn of each patch's own bones about its rest centroid moves a vertex, per
    radian: the largest of ‖x̄_v − c̄_p‖ Σ_{b own} w_vb over the rest vertices (0 where a patch
    turns no bone). rest (V, 3); dense (V, B) weights; patches: vertex-id lists; own: bone ids each."""
    reach = np.zeros(len(patches))
    for p, ids in enumerate(patches):  # few patches
        if own[p].size:
            share = dense[:, own[p]].sum(axis=1)
            centre = rest[np.asarray(ids)].mean(axis=0)
            reach[p] = float((np.linalg.norm(rest - centre, axis=1) * share).max())
    return reach


def _contiguous(array, dtype=np.float64):
    """One specialisation of the compiled loops: C-ordered arrays of these types."""
    return np.ascontiguousarray(array, dtype=dtype)


@dataclass
class PlantTargets:
    """What keeps the plants of A animations of M frames (:func:`plant_targets`): states (A, P, M)
    bool, the planted states (the gaps of at most :data:`BRIDGE` bridged); each patch's centroid as
    the feet's turns leave it, its anchor bone's turn (axis-angle) and its correction (where the
    centroid goes beyond that and the root's offset) (A, P, M, 3); the root's offset (A, M, 3),
    moving every bone."""

    states: np.ndarray
    centre: np.ndarray
    turn: np.ndarray
    correction: np.ndarray
    root: np.ndarray


def plant_targets(F, t, sources, rig):
    """The :class:`PlantTargets` of the animations F (A, M, B, 3, 3), t (A, M, B, 3) (read only;
    module notes 0–6, :func:`.planting_loops.plant_animations`, compiled, one animation at a time);
    sources (C, A, M) the input frame each component plays."""
    from .planting_loops import plant_animations

    A, M = F.shape[:2]
    P = rig.owner.size
    src = _contiguous(np.moveaxis(sources[rig.owner], 0, 1), np.int64)  # (A, P, M)
    width = max([1] + [bones.size for bones in rig.own])
    own = np.full((P, width), -1, np.int64)
    for p, bones in enumerate(rig.own):  # as slots in rig.bones
        own[p, :bones.size] = np.searchsorted(rig.bones, bones)
    c = _contiguous
    targets = PlantTargets(states=np.zeros((A, P, M), bool), centre=np.zeros((A, P, M, 3)), turn=np.zeros((A, P, M, 3)),
                           correction=np.zeros((A, P, M, 3)), root=np.zeros((A, M, 3)))
    up_columns, lowest_rows = lowest_operator(rig)
    plant_animations(F, t, src, c(target_heights(rig, src, sources[0])), c(rig.planted, np.bool_),
                     c(rig.bones, np.int64), centre_operator(rig.rest_terms, rig.weight_terms), up_columns, lowest_rows,
                     sample_counts(rig), c(rig.anchor_bone, np.int64), c(rig.inverse_in), c(rig.steps_in),
                     c(rig.orientation_in), c(rig.turn_steps_in), own,
                     float(rig.decay), gaussian_weights(rig.sigma), float(rig.sigma),
                     raised_cosine(rig.lift_radius), float(rig.max_turn), int(rig.up_axis), int(rig.bridge),
                     int(rig.hold), float(np.exp(-1.0 / rig.memory)), float(rig.bound), int(rig.release),
                     float(rig.edge_limit), c(rig.turn_limit), float(rig.turn_bound), targets.states, targets.centre,
                     targets.correction,
                     targets.turn, targets.root)
    return targets


def target_heights(rig, src, ground_src):
    """(A, P, M) the height each patch's lowest point keeps at each output frame (module notes, 2.):
    the input patch's at its source frame above its clip's ground (``rig.heights_in``), spliced as
    the splice plays the motion (:func:`..splicing.blend_series` over the same windows: Zheng's 1-D
    Poisson blend of the heights, the seam's velocity jump spread), placed on the ground of the
    clip the first component plays (``ground_src`` (A, M), its sources). src (A, P, M) each patch's
    source frames. The heights themselves jump at a seam between a foot set down and one lifted
    within the contact band, where the splice blends the foot down over its window: asked to keep
    the unspliced heights, the limb lifted the landing foot 2.6 % of the height and dropped it in a
    frame, and its joints, bounded in acceleration, dragged the planted foot (the pivot walker,
    :func:`...inputs.pivot_walker.pivot_walker`: the pivot's ball 1.5 % of the height off its spot)."""
    from ..splicing import blend_series, seam_windows

    P = src.shape[1]
    aim = rig.heights_in[src, np.arange(P)[None, :, None]]
    for owner in np.unique(rig.owner):  # the patches one component moves share its walks and seams
        mine = np.flatnonzero(rig.owner == owner)
        walks = src[:, mine[0]]
        rotations = np.broadcast_to(np.eye(3), (rig.heights_in.shape[0], mine.size, 3, 3))  # heights: no turn
        animation, frame, _, heights = blend_series(rotations, rig.heights_in[:, mine, None], walks,
                                                    seam_windows(walks, rig.window, rig.clips),
                                                    spread_velocity=rig.spread_velocity, clips=rig.clips)
        aim[animation[:, None], mine[None, :], frame[:, None]] = heights[..., 0]
    return aim + rig.ground[ground_src][:, None, :]


def reach_targets(F, t, targets, rig, held=None, cut=None):
    """Make the :class:`PlantTargets` on the animations F, t, in place: each limb turned at its
    joints towards its patches' targets, within their ranges, the plants' acceleration limit and
    the capture's shapes (:func:`.limb_reach.reach_animations`), every bone moved by the root. held,
    cut: None, or (A, M) int64 arrays of zeros, counting at each frame the joints held at the edge
    of their ranges and the limbs whose turn tore the skin and was cut (:mod:`.limb_shape`)."""
    from .limb_reach import COLD_STEPS, JOINT_ACCEL, PRIOR, RANGE_MARGIN, STIFF, WARM_STEPS, reach_animations

    c = _contiguous
    chains, ranges = rig.chains, rig.chains.ranges
    largest = ranges.spread.max(axis=1, initial=0.0)[:, None]
    weight = np.where(largest > 0.0, largest / np.maximum(np.maximum(ranges.spread, STIFF * largest), 1e-300), 1.0)
    frame = np.einsum("kxu,kvx->kuv", ranges.axes, ranges.mean)  # Uᵀ Q̄ᵀ
    limb_joints, limb_patches = rig.limbs()
    seams = no_seams(limb_joints.shape[0]) if rig.seams is None else rig.seams
    reach_animations(F, t, targets.centre, targets.correction, targets.turn, targets.root, limb_joints, limb_patches,
                     c(chains.bone, np.int64), c(chains.body, np.int64), c(chains.point.reshape(-1, 3)),
                     c(chains.parent, np.int64), c(chains.reach), c(ranges.mean.reshape(-1, 3, 3)),
                     c(ranges.axes.reshape(-1, 3, 3)), c(frame.reshape(-1, 3, 3)), c(weight.reshape(-1, 3)),
                     c(ranges.low.reshape(-1, 3)), c(ranges.high.reshape(-1, 3)), c(ranges.seen),
                     float(RANGE_MARGIN), float(PRIOR),
                     c(rig.lever), c(chains.patch_joint, np.int64), c(chains.bone_joint, np.int64), c(rig.bones, np.int64),
                     c(rig.rest_terms), c(rig.weight_terms), int(WARM_STEPS),
                     int(COLD_STEPS), float(JOINT_ACCEL * rig.edge_limit), c(rig.rest), c(rig.bone_indices, np.int64),
                     c(rig.bone_weights), c(seams.vertices, np.int64), c(seams.edges, np.int64), c(seams.lengths),
                     c(seams.one), c(seams.allowance), c(seams.masks, np.int64), c(seams.budget, np.int64), int(HALVINGS),
                     np.zeros(F.shape[:2], np.int64) if held is None else held,
                     np.zeros(F.shape[:2], np.int64) if cut is None else cut)


def plant_feet(F, t, sources, rig, lowest=None, held=None, cut=None):
    """Keep every plant of the animations F (A, M, B, 3, 3), t (A, M, B, 3) on its anchor (module
    notes), in place: :func:`plant_targets`, then :func:`reach_targets`; sources (C, A, M) the input
    frame each component plays. Returns the planted states (A, P, M) bool (the gaps of at most
    :data:`BRIDGE` bridged). lowest: None, or an (A, M) float64 array filled with the lowest of the
    patches' sample vertices once planted (what the band after the plants keeps,
    :func:`.synthesis.make_batch`); held, cut: :func:`reach_targets`'."""
    from .planting_loops import lowest_after

    targets = plant_targets(F, t, sources, rig)
    reach_targets(F, t, targets, rig, held, cut)
    if lowest is not None:
        lowest_after(F, t, _contiguous(rig.bones, np.int64), *lowest_operator(rig), sample_counts(rig), lowest)
    return targets.states


def sample_counts(rig):
    """(P,) int64: how many of each patch's sample vertices are real (the rest is padding)."""
    return _contiguous((rig.sample_weights.sum(axis=2) > 0.0).sum(axis=1), np.int64)


def centre_operator(rest_terms, weight_terms):
    """Q (12b, 3P): the patches' centroids are [F (9b), t (3b)] Q for the bones' entries in a row
    (each F_b row-major, then each t_b): centroid_p = Σ_b F_b ā_pb + ω_pb t_b, one matrix product
    for every frame at once. rest_terms ā (P, b, 3), weight_terms ω (P, b)."""
    P, b = weight_terms.shape
    Q = np.zeros((b, 3, 3, P, 3))  # F_b[i, j] → centroid_p[i] with ā_pbj
    for i in range(3):
        Q[:, i, :, :, i] = np.transpose(rest_terms, (1, 2, 0))
    T = np.zeros((b, 3, P, 3))  # t_b[i] → centroid_p[i] with ω_pb
    for i in range(3):
        T[:, i, :, i] = weight_terms.T
    return np.concatenate([Q.reshape(9 * b, 3 * P), T.reshape(3 * b, 3 * P)])


def lowest_operator(rig):
    """(up_columns (4b,), Q (4b, P·S)): the heights of the patches' sample vertices (linear blend
    skinning, along up) are rows[:, up_columns] Q for a frame's row of :func:`centre_operator`'s
    layout (12b: each F_b row-major, then each t_b); up_columns picks what a height reads, each
    bone's F_b[up, :] (3b, bone after bone) then its t_b[up] (b); patch p's in columns p·S to
    p·S + S, the padding's 0."""
    P, S, K = rig.sample_bones.shape
    b = rig.bones.size
    up = rig.up_axis
    slot = np.zeros(int(max(rig.bones.max(), rig.sample_bones.max())) + 1, np.int64)
    slot[rig.bones] = np.arange(b)
    Q = np.zeros((4 * b, P * S))
    column = np.broadcast_to(np.arange(P * S).reshape(P, S, 1), (P, S, K))
    slots = slot[rig.sample_bones]
    for j in range(3):  # F_b[up, j] x_j, weighted
        np.add.at(Q, (3 * slots + j, column), rig.sample_weights * rig.sample_rest[:, :, None, j])
    np.add.at(Q, (3 * b + slots, column), rig.sample_weights)  # t_b[up], weighted
    bones = np.arange(b)
    up_columns = np.concatenate([(9 * bones[:, None] + 3 * up + np.arange(3)).ravel(), 9 * b + 3 * bones + up])
    return up_columns.astype(np.int64), Q


#: Most vertices per patch that find its lowest point (:func:`lowest_samples`).
SAMPLES = 48


def lowest_samples(rest, examples, patches, up_axis, most=SAMPLES):
    """(P, S) vertex ids per patch, −1 padded: those whose lowest is the patch's lowest point however
    it turns. All of a patch of at most ``most`` vertices; of a larger one, its lowest vertex in each
    input frame and its outermost vertices at rest along eight horizontal directions (a sole's
    corners and heel), at most ``most`` of them (evenly spaced by id)."""
    rest = np.asarray(rest, dtype=np.float64)
    across = [axis for axis in range(3) if axis != up_axis]
    angles = np.arange(8) * np.pi / 4
    directions = np.zeros((8, 3))
    directions[:, across[0]], directions[:, across[1]] = np.cos(angles), np.sin(angles)
    chosen = []
    for ids in patches:
        ids = np.asarray(ids)
        found = np.sort(ids) if ids.size <= most else np.union1d(
            ids[np.argmin(examples[:, ids, up_axis], axis=1)], ids[np.argmax(rest[ids] @ directions.T, axis=0)])
        chosen.append(found[np.linspace(0, found.size - 1, min(most, found.size)).astype(np.int64)])
    table = np.full((len(patches), max(c.size for c in chosen)), -1, np.int64)
    for p, found in enumerate(chosen):
        table[p, :found.size] = found
    return table


def warm_up(rig):
    """Load (or compile) :func:`plant_feet`'s compiled loops for ``rig`` on one animation of two
    frames: a synthesis's workers are forked after it, and would each load them again."""
    B = rig.chains.bone_joint.size
    F = np.broadcast_to(np.eye(3, dtype=np.float32), (1, 2, B, 3, 3)).copy()
    t = np.zeros((1, 2, B, 3), np.float32)
    plant_feet(F, t, np.zeros((int(rig.owner.max()) + 1, 1, 2), np.int64), rig, lowest=np.zeros((1, 2)))


def gaussian_weights(sigma, truncate=4.0):
    """scipy.ndimage's Gaussian weights (2r + 1,), r = int(truncate σ + 0.5), normalised."""
    radius = int(truncate * sigma + 0.5)
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    weights = np.exp(-0.5 * x * x / (sigma * sigma))
    return weights / weights.sum()


def output_states(sources, rig):
    """(A, P, M) bool: patch p is planted at output frame m of animation a where its owner's
    source frame has it planted. sources (C, A, M)."""
    patches = np.arange(rig.owner.size)
    return rig.planted[np.moveaxis(sources[rig.owner], 0, 1), patches[None, :, None]]


#: A component keeps its transitions as they are when refusing the contact jumps would leave it
#: fewer than this share of the frames it could play forever from (the walks' coverage).
KEEP_USABLE = 0.9


def agreeing_transitions(pairs, owned, clips):
    """(M,) bool: which transitions (i, j) (pairs (M, 2), j identified with i; j < 0 a clip's
    start) keep the contact state of every patch in owned (Fi, p) bool: the frame played next,
    counted from the frame it replaces, is planted where frame i is (Zheng's transition from i to
    j + 1, a planted foot never jumps to a swinging one)."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    nxt = clips.targets(pairs[:, 1])
    same = np.where(clips.first_frames()[nxt], nxt, nxt - 1)  # the frame identified with i
    return (owned[pairs[:, 0]] == owned[same]).all(axis=1)


def mark_contact_jumps(components, contacts, bone_indices, bone_weights, clips=None):
    """Mark, on each component (``ComponentAnalysis``: its ``transitions.pairs``), which candidate
    transitions keep the contact state of every patch it owns (the one carrying most of its weight;
    :func:`agreeing_transitions`): ``component.contact_agrees`` (M,) bool, the others being
    refused by a synthesis with contacts (:func:`contact_transitions`), or None where none is
    refused. A transition between clips is a clip's way in or out, which build-graph gives every
    clip (the ground contacts of a gallop and of a collapse never agree), so it is kept; and a
    component keeps all its transitions when refusing them would leave its motion graph under
    :data:`KEEP_USABLE` of the frames it could play forever from. The pairs themselves are left
    as they are: a synthesis without contacts (``--no-contact``) walks every one. contacts: the
    input's :class:`.contact_patches.ContactPatches`. Returns (refused, kept_all) per component:
    how many are refused, and whether the component kept them all for want of walks."""
    from ...inputs.clips import Clips

    frames = contacts.planted.shape[0]
    clips = clips or Clips.single(frames)
    dense = dense_weights(bone_indices, bone_weights, int(np.max(bone_indices)) + 1)
    patches = patch_vertices(contacts)
    owner = patch_owners(patches, dense, [c.bones for c in components])
    report = []
    for k, component in enumerate(components):
        component.contact_agrees = None
        owned = np.asarray(contacts.planted, bool)[:, owner == k]
        pairs = np.asarray(component.transitions.pairs, dtype=np.int64).reshape(-1, 2)
        if owned.shape[1] == 0 or len(pairs) == 0:
            report.append((0, False))
            continue
        within = clips.clip_of(pairs[:, 0]) == clips.clip_of(clips.targets(pairs[:, 1]))
        keep = agreeing_transitions(pairs, owned, clips) | ~within  # a clip's way in and out is kept
        if keep.all():
            report.append((0, False))
            continue
        if _usable(frames, pairs[keep], clips) < KEEP_USABLE * _usable(frames, pairs, clips):
            report.append((0, True))
            continue
        component.contact_agrees = keep
        report.append((int((~keep).sum()), False))
    return report


def contact_transitions(transitions, agrees):
    """``transitions`` (a :class:`.transitions.Transitions`) with only the pairs (and their costs)
    that ``agrees`` (M,) bool marks (:func:`mark_contact_jumps`); as they are for None."""
    if agrees is None:
        return transitions
    import copy

    agrees = np.asarray(agrees, bool)
    kept = copy.copy(transitions)
    kept.pairs = np.asarray(transitions.pairs).reshape(-1, 2)[agrees]
    kept.costs = np.asarray(transitions.costs)[agrees]
    return kept


def _usable(frames, pairs, clips):
    """How many frames a motion graph over ``pairs`` can play forever from (0: none)."""
    from ...errors import OptionError
    from ..motion_graph import MotionGraph

    try:
        return MotionGraph(frames, pairs, None, clips).usable_count
    except OptionError:
        return 0
