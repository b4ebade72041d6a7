"""One clip in, many animations out (Zheng §3.3, §3.4, §4.2): walks, splicing, assembly, checks.

The input may be several clips of one mesh (``Request.clips``, a :class:`~skinsynth.pipeline.inputs.clips.Clips`;
None: one clip): frames, walks and targets use the global frame numbers, the motion graphs play
on only inside a clip and cross between clips by their transitions (j = −(c + 1) continues at
clip c's first frame), splicing blends every seam by the clip-aware rule (:mod:`.splicing`), and
the statistics count coverage per clip and transitions per pair of clips
(:func:`.motion_graph.walk_statistics`). One clip takes exactly today's path (``clips`` None).

Per bone component: a motion graph over the input frames (:mod:`.motion_graph`) with frames that
collide with the obstacles removed; walks (random, or through targeted frames); splicing
(:mod:`.splicing`). Several components are merged through their cut nodes (:mod:`.assembly`).
Animations whose frames collide after splicing, or that repeat an earlier one more than
``min_difference`` allows, are replaced by fresh walks.

Animations are made in batches of ``BATCH`` with their own random streams
``default_rng([seed, batch])``, so the result depends on the seed alone — not on ``jobs`` or on
how the work is split — and batches can run in parallel worker processes (:mod:`.execution`:
forked workers write their bone motions straight into one anonymous shared mapping that becomes
the result; pickling ~600 MB of float32 motions per thousand animations back through pipes cost
more than a third of the run).
"""

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from .assembly import assemble, cut_bones, merge_order
from .collisions import build_obstacles, colliding, vertex_subset
from .contact.ground import ground_floored, keep_contact, lowest_range, support, support_without
from ..mesh.contact_measures import LIMB_CUT, LIMB_HELD
from .contact.patches import patch_vertices
from .contact.planting import lowest_samples, plant_feet, plant_rig
from .deformation_gradients import gradient_operator
from ..errors import OptionError
from ..runtime.execution import concatenate_rows, run_batches
from ..runtime.rows import unique_rows
from .graph import ComponentAnalysis
from ..rig.skeleton import held_rig, hold_joints, reach_with_legs
from .held_poses import HeldPoses
from .motion_graph import MotionGraph, constrained_walks, diversity_filter, random_walks, walk_statistics
from .splicing import splice_local
from .transitions import Transitions, bone_centroids

BATCH = 250
MAX_ROUNDS = 20
#: Rounds a ``--min-difference`` request may take before it is refused (issue 34: near the clip's
#: variety the old rounds drew 2·10⁵ candidates over 90 s before finishing). Each replacement round
#: is sized by the last round's yield (:func:`_replacements`), so a request the clip can meet is
#: met in two or three; :func:`check_diversity_reachable` plays one round fewer on walks alone.
DIVERSITY_ROUNDS = 4
#: The most animations one replacement round draws, as a multiple of the count asked.
REPLACEMENT_CAP = 8
#: The revision of :func:`make_batch`'s output for given inputs: raised whenever a change of code
#: changes it, so a cluster run never reuses a shard older code made (the shard key holds it).
#: 2: replacement rounds ask for twice as many animations each round (:func:`_replacements`).
#: 3: the merged rig keeps the input's support (``Request.contact``, :mod:`.contact`).
#: 4: replacement rounds are sized by the last round's yield and bounded (:data:`DIVERSITY_ROUNDS`).
#: 5: an input with ground contacts has its plants kept (``Request.plants``, :mod:`.planting`) and its
#: merges prefer legs whose contacts agree with the body's (:func:`.assembly.assemble`).
#: 6: with contacts, swinging feet kept no lower than the input's, short gaps between plants bridged,
#: long plants' limb corrections leaking, reaching 2 hops, and the band's floor at the contacts'
#: ground (its lowest points from the plants).
#: 7: walks avoid transitions into frames they played in the last 2 s (:mod:`.motion_graph`, ``fresh``).
#: 8: a plant holds its foot's orientation from frame to frame, turned up to 35° (:mod:`.planting`).
#: 9: a plant's limb correction is let go where the input's foot lifts inside a bridged gap, and past
#: its hold only what exceeds 0.1 of the height leaks (:mod:`.planting`).
#: 10: walks enter a trap of the motion graph only in their last 2 s, and start outside it
#: (:meth:`.motion_graph.MotionGraph.trapped`).
#: 11: a large limb correction's spring out of a plant is slowed (:data:`.planting.EDGE_ACCEL`), and
#: both edges of a gap between plants keep their steps (:func:`.planting_loops.blend_edges_row`).
#: 12: every plant correction within the same limit (a plant starts from what the last one's spring
#: leaves, planted steps and turns capped, releases, root and lift widened: :mod:`.planting`, 6.).
#: 13: plants made by each limb's joints within the input's ranges (:mod:`.limb_reach`), kept to the
#: capture's shapes (:mod:`.limb_shape`), transitions that tear refused (:mod:`.seam_shape`), turns'
#: holds leaking past 5°, and past its hold what exceeds 0.015 of the height leaks (:mod:`.planting`).
BATCH_REVISION = 13


def component_from_file(data, rest, contacts=False):
    """ComponentAnalysis from a graph file's component record (``formats.graph_file.ComponentRecord``;
    the eq. 9 operator is rebuilt from the stored key-vertex data: cheap and exactly what
    build-graph computed). contacts: walk only the transitions that keep the input's ground contacts
    (the record's ``contact_agrees``, when it has one: :func:`.planting.contact_transitions`)."""
    local = np.asarray(data.local_bones, dtype=np.int64)
    reference = int(data.reference)
    operator = gradient_operator(local, reference, rest, data.key_vertices, data.key_bones, data.key_weights,
                                 data.weight_gradients, ridge=float(data.ridge))
    transitions = Transitions(reference=reference, bones=[int(b) for b in data.bones],
                              local_bones=[int(b) for b in local], q=data.reduced_coordinates,
                              basis=data.basis, singular=data.singular, r=data.reference_motion,
                              alpha=float(data.alpha), beta=float(data.beta),
                              D=data.costs, threshold=float(data.threshold),
                              pairs=np.asarray(data.transitions, dtype=np.int64).reshape(-1, 2),
                              costs=data.transition_costs)
    if contacts:
        from .contact.planting import contact_transitions

        transitions = contact_transitions(transitions, getattr(data, "contact_agrees", None))
    return ComponentAnalysis(bones=[int(b) for b in data.bones], transitions=transitions,
                             key=np.asarray(data.key_vertices), key_bones=np.asarray(data.key_bones),
                             key_weights=np.asarray(data.key_weights),
                             key_gradients=np.asarray(data.weight_gradients),
                             strain=np.asarray(data.rotation_strain), operator=operator)


def synthesis_components(skin, records, single_component=False, graph_options=None, clips=None, walk_clips=None,
                         contacts=None):
    """The components synthesize walks: each of a graph file's component records
    (:func:`component_from_file`), or with ``single_component`` (and more than one in the file)
    the whole rig analysed again as one (:func:`.graph.build_graph` with the file's
    ``graph_options``, a :class:`.graph_options.GraphOptions`). ``skin``: rest_vertices (V, 3),
    faces, bone_indices and bone_weights (V, K), rotations (F, B, 3, 3), translations (F, B, 3);
    clips, walk_clips: the input's clips and those the graph let walks play, for an analysis made
    again (:func:`.graph.build_graph`); contacts: the input's ground contacts when the synthesis
    keeps them (None: ``--no-contact``, or none found): the components then walk only the
    transitions that keep them (a graph file's ``contact_agrees``; an analysis made again marks
    them as build-graph did, :func:`.planting.mark_contact_jumps`)."""
    if single_component and len(records) > 1:
        from .graph import build_graph  # networkx: only imported when needed
        from .graph_options import GraphOptions

        options = (graph_options or GraphOptions()).analysis_options()
        options["single_component"] = True
        components = build_graph(skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights, skin.rotations,
                                 skin.translations, **options, clips=clips, walk_clips=walk_clips).components
        if contacts is not None:
            from .contact.planting import contact_transitions, mark_contact_jumps

            mark_contact_jumps(components, contacts, skin.bone_indices, skin.bone_weights, clips)
            for component in components:
                component.transitions = contact_transitions(component.transitions, component.contact_agrees)
        return components
    return [component_from_file(record, skin.rest_vertices, contacts is not None) for record in records]


def avoid_obstacles(request, skin, meshes, ground_plane=False):
    """Set ``request.obstacles`` (Zheng §3.4) from obstacle meshes [(vertices (N, 3), faces (T, 3))]
    and, with ``ground_plane``, the plane of the clip's lowest point about ``request.up_axis``, and
    ``request.forbidden`` (F,): the input frames (examples (F, V, 3) of ``skin``) that collide.
    Splices may dip a hair below the clip's lowest point: 0.1 % of the rest pose's size is allowed."""
    up = request.up_axis
    ground = (up, float(skin.examples[..., up].min())) if ground_plane else None
    request.obstacles = build_obstacles(meshes, ground=ground, tolerance=1e-3 * float(np.ptp(skin.rest_vertices)))
    subset = vertex_subset(skin.rest_vertices.shape[0])
    request.forbidden = colliding(request.obstacles, skin.examples[:, subset])


def batch_sizes(count, first=0):
    """[(batch id, animations)] of ``count`` animations in batches of :data:`BATCH`, ids from
    ``first``: how :func:`synthesize` splits each round's work."""
    return [(first + b, min(BATCH, count - b * BATCH)) for b in range(-(-count // BATCH))]


def skin_tree(skin):
    """The skin's :class:`~skinsynth.pipeline.rig.joint_tree.JointTree`: a jointed skin's own skeleton,
    or a free fit's, found from its joints (``skin``: rest_vertices, faces, weights, rotations,
    translations, skeleton)."""
    from ..rig.joint_tree import skin_joint_tree

    skeleton = None if skin.skeleton is None else (skin.skeleton["parents"], skin.skeleton["joints"])
    return skin_joint_tree(skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights, skin.rotations,
                           skin.translations, skeleton)


def keep_input_support(request, skin):
    """Set ``request.support``, what the merged rig keeps (:mod:`.contact`): the support vertices
    of ``skin``'s fit and, as the range of lowest points, the input frames' own (examples
    (F, V, 3)) along ``request.up_axis``. Made once here, not again in every batch. With several
    clips F is all of them, so the band spans every clip's frames (a collapse's lying pose
    included: a walk may play it)."""
    request.support = support(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations,
                              skin.translations, request.up_axis, ground=lowest_range(skin.examples, request.up_axis))


def keep_input_plants(request, skin, contacts, components):
    """Set ``request.plants`` (:class:`.planting.PlantRig`), what the output's plants need from
    the input's ground contacts (a :class:`.contact_patches.ContactPatches` or the graph file's
    record of it, with at least one patch), made once here, not in every batch: they replace the
    vertical shift of :func:`keep_input_support` (:mod:`.planting`). ``skin``: the fit (rest
    vertices, weights, rotations, translations, fps) and its input frames (examples); components:
    the synthesis's. The band :func:`keep_input_support` set, if it did, then keeps its floor at
    the contacts' ground (:func:`.contact.ground_floored`)."""
    from ..inputs.clips import Clips

    clips = request.clips or Clips.single(skin.rotations.shape[0])
    patches = patch_vertices(contacts)
    bones = [c.bones for c in components]
    from .contact.planting import warm_up

    if request.tree is None:
        request.tree = skin_tree(skin)
    if request.envelope is None and request.shape_check:
        request.envelope = skin_envelope(skin)
    sampled = lowest_samples(skin.rest_vertices, skin.examples, patches, request.up_axis)  # (P, S), −1 padded
    request.plants = plant_rig(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations,
                               skin.translations, skin.examples, patches, np.asarray(contacts.planted, bool), contacts.ground,
                               clips.starts, skin.fps, bones, request.tree, request.up_axis, samples=sampled,
                               envelope=request.envelope)
    request.plants.window, request.plants.spread_velocity = request.window, request.spread_velocity
    request.plants.clips = request.clips  # the splice's: the plants' target heights are spliced alike
    warm_up(request.plants)  # the compiled loops loaded here, once, not in every forked worker
    if request.support is not None:  # the band's floor: the ground the contacts stand on (contact.GROUND_TOLERANCE)
        request.support = ground_floored(request.support, contacts.ground)
        # the band's lowest points after the plants: the plant loop's own (its patches' sample
        # vertices), with those of the other support vertices
        request.support_beyond_plants = support_without(request.support, sampled[sampled >= 0])


def prepare_synthesis(request, graph, meshes=(), ground_plane=False, single_component=False):
    """The components a synthesis of ``graph`` walks (a graph file as read,
    ``formats.graph_file.GraphFile``: its skin, component records, recorded options, the clips
    /graph lets walks play and the input's ground contacts; :func:`synthesis_components`), and
    ``request`` made ready for them: with ``request.contact`` the input's support kept
    (:func:`keep_input_support`) and its ground contacts, if any, kept (:func:`keep_input_plants`);
    the obstacle ``meshes`` and with ``ground_plane`` the input's lowest plane avoided
    (:func:`avoid_obstacles`)."""
    from .graph_options import GraphOptions

    skin = graph.skin
    contacts = graph.contacts if graph.contacts is not None and graph.contacts.count else None
    if request.contact:
        keep_input_support(request, skin)
    if meshes or ground_plane:
        avoid_obstacles(request, skin, meshes, ground_plane)
    walk_clips = graph.graph.get("@clips")
    components = synthesis_components(skin, graph.components, single_component, GraphOptions.recorded(graph.options),
                                      request.clips, None if walk_clips is None else [str(n) for n in walk_clips],
                                      contacts=contacts if request.contact else None)
    if request.contact and contacts is not None:
        keep_input_plants(request, skin, contacts, components)
    if request.shape_check:
        refuse_tearing(request, skin, components)
    return components


def refuse_tearing(request, skin, components):
    """Each component walks only the transitions whose splice keeps the body whole
    (:mod:`.seam_shape`), in place (its ``transitions`` cut, ``shape_refused`` the number refused,
    ``shape_kept_all`` whether it kept them all for want of walks), unless that leaves it under
    :data:`.seam_shape.KEEP_PLAYABLE` of the frames it could play for ever from. ``skin``: the fit
    and its capture (examples, faces) the shape is measured against."""
    from .contact.planting import contact_transitions
    from .seam_shape import KEEP_PLAYABLE, tearing_transitions

    if request.envelope is None:
        request.envelope = skin_envelope(skin)
    envelope = request.envelope
    pivots = bone_centroids(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations.shape[1])
    frames = skin.rotations.shape[0]
    for component in components:
        tearing = tearing_transitions(component, skin, envelope, request, pivots, _skinning)
        component.shape_refused, component.shape_kept_all = int(tearing.sum()), False
        if not tearing.any():
            continue
        kept = contact_transitions(component.transitions, ~tearing)
        if _playable(frames, kept, request) < KEEP_PLAYABLE * _playable(frames, component.transitions, request):
            component.shape_refused, component.shape_kept_all = 0, True
            continue
        component.transitions = kept


def _skinning(*bones):
    """Linear blend skinning on the CPU (:func:`skinsynth.gpu.lbs`'s arguments)."""
    from skinsynth.gpu import lbs

    return lbs(*bones, device="cpu")


def skin_envelope(skin):
    """The :class:`..mesh.shape.ShapeEnvelope` of ``skin``'s capture and its fit's playback of it."""
    from .skinned import capture_envelope

    return capture_envelope(skin, _skinning)


def _playable(frames, transitions, request):
    """How many frames a motion graph over ``transitions`` can play for ever from (0: none)."""
    try:
        return motion_graphs([SimpleNamespace(transitions=transitions)], request.never_shown(), request.clips)[0].usable_count
    except OptionError:
        return 0


#: Frames blended on each side of a seam at 24 fps, and the chance per frame that a walk past its
#: shortest segment takes a transition (Request's window and transition_probability): at another
#: frame rate the same time and the same chance per second (:func:`timed_walk_options`).
WINDOW_AT_24 = 4
TRANSITION_PROBABILITY_AT_24 = 0.1
#: The longest default blend window (frames) at a high frame rate (:func:`timed_walk_options`).
LONGEST_WINDOW = 12


def timed_walk_options(fps):
    """{window, transition_probability} at ``fps`` (issue 63): the blend window the same time as
    :data:`WINDOW_AT_24` frames at 24 fps (at least 1 frame, at most :data:`LONGEST_WINDOW`) and the
    chance of a transition the same per second as :data:`TRANSITION_PROBABILITY_AT_24` per frame at
    24 fps. At 24 fps both are the defaults exactly.

    Why a cap: the splice's velocity spreading leaves kinks and a drift that depend on the window's
    frames, not only its time (:mod:`.splicing`, module notes), and not alike on every clip: in
    20 walks of 25 s in-betweened to 96 fps the samba reached 0.92 / 1.35 / 1.76 / 3.42 × its input's
    largest acceleration at windows of 8 / 12 / 16 / 32 frames (1.67 at 4), the crane 1.52 / 1.08 /
    0.96 at 8 / 12 / 16 (at 24 fps with 4: 0.84 and 1.10). 12 keeps both under 1.5; a window in time
    needs a splice whose kinks scale with it (left for later: issue 63's note)."""
    fps = float(fps)
    if fps == 24.0:
        return {"window": WINDOW_AT_24, "transition_probability": TRANSITION_PROBABILITY_AT_24}
    return {"window": min(LONGEST_WINDOW, max(1, int(round(WINDOW_AT_24 * fps / 24.0)))),
            "transition_probability": 1.0 - (1.0 - TRANSITION_PROBABILITY_AT_24) ** (24.0 / fps)}


def synthesis_request(graph, start=None, end=None, targets=(), min_segment=None, up_axis=None, **options):
    """The :class:`Request` of ``options`` (count, frames, seed, … as its fields) on the input of
    ``graph`` (a graph file as read, ``formats.graph_file.GraphFile``), validated
    (:func:`validate_request`): ``start``, ``end`` and ``targets`` [(frame, time)] read against its
    clips (CLIP:FRAME or a global frame, :meth:`~skinsynth.pipeline.inputs.clips.Clips.frame`: an
    OptionError names the option), the shortest segment and the up axis ("Y" or "Z") the file
    recorded unless given, the skin's skeleton; a ``window`` of None (or absent) and the
    ``transition_probability`` the clip's frame rate sets (:func:`timed_walk_options`)."""
    from ..inputs.clips import Clips
    from .motion_graph import default_min_segment

    skin = graph.skin
    options = {**timed_walk_options(skin.fps), **{k: v for k, v in options.items() if v is not None}}
    if up_axis is None:
        up_axis = str(graph.options.get("up_axis", "Y"))
    if min_segment is None:
        min_segment = int(graph.options.get("min_segment", default_min_segment(skin.fps)))
    clips = Clips(skin.clip_names, skin.clip_frames)
    start = None if start is None else clips.frame(start, "--start")
    end = None if end is None else clips.frame(end, "--end")
    targets = [(clips.frame(frame, "--target"), time) for frame, time in targets]
    # one clip: today's path exactly (no clip table handed down)
    held = None
    if getattr(graph, "held_runs", None) is not None and len(graph.held_runs):
        held = HeldPoses(graph.held_runs, max(1, int(graph.held_keep)), skin.rotations.shape[0])
    request = Request(**options, targets=targets, start=start, end=end, min_segment=min_segment, fps=float(skin.fps),
                      up_axis=1 if up_axis == "Y" else 2, clips=clips if len(clips) > 1 else None,
                      skeleton=None if skin.skeleton is None else held_rig(skin.skeleton), held=held)
    validate_request(request, skin.rotations.shape[0])
    return request


@dataclass
class Request:
    """What to make: count animations of ``frames`` frames; targets [(input frame, output time)],
    start/end frames; obstacles (collisions.Obstacles or None) with the input frames that collide
    (forbidden (F,) bool); min_difference; window; spread_velocity; cut_damping (of the cut nodes'
    eq. 9 change, :mod:`.splicing`); transition_probability (per
    frame, once a segment has played min_segment frames: the default 0.1 and 8 give segments of
    about 18 frames, each seam blended over ``window`` frames on each side); seed.

    Window: Zheng blends over the whole segments on each side; here ``window`` frames. The blend
    keeps the input's accelerations inside the window (plus, with ``spread_velocity``, the
    seam's velocity jump spread evenly; :mod:`.splicing`), and an offset built inside a long
    window is bent by the reference bone's rotation. Measured (50 walks × 600 frames, max
    acceleration near seams / the input's, horse-sized tube, seeds 0–2; single / multi-component
    with the defaults otherwise): window 1 → 1.38 / 1.33, 2 → 0.92–1.11 / 1.27–1.35,
    3 → 0.91–1.00 / 1.27–1.28, 4 → 1.07 / 1.34, 8 → 1.29 / 1.34. Without the spread, window 4
    gave 1.18 and window 8 1.75 single-component; without the cut-node damping, multi-component
    gave 1.61–1.81 at window 2 and 2.7–4.6 at windows 4–8. Default 3.

    fps: the input's frame rate (what a stuck walk's two seconds are: :mod:`.walk_measures`).

    tree: the skin's joint tree (:class:`~skinsynth.pipeline.rig.joint_tree.JointTree`, :func:`skin_tree`),
    whose joints the plants turn a limb at (:mod:`.contact.limb_chains`), or None.

    envelope: the capture's :class:`..mesh.shape.ShapeEnvelope` (:func:`skin_envelope`), which the plants'
    limbs (:mod:`.contact.limb_shape`) and the seams (:mod:`.seam_shape`) keep to, or None.

    contact: keep the merged rig's lowest point within the input's range (:mod:`.contact`);
    ``support`` (a :class:`.contact.Support`, from :func:`keep_input_support`: the input frames'
    own range of lowest points), or None: made in each batch from the fit's playback of them.
    plants: the input's ground contacts kept on the output (:class:`.planting.PlantRig`, from
    :func:`keep_input_plants`; None: the input has none, or ``contact`` is off); where set they
    come before the support's vertical shift, which then takes its lowest points from the plants'
    patches and from ``support_beyond_plants`` (the support's vertices outside them).

    clips: the :class:`~skinsynth.pipeline.inputs.clips.Clips` of the input frames when they are several
    clips (frames, targets, start and end are global frame numbers), None for one clip.

    skeleton: a jointed skin's (parents (B,), jointed (B,), joints (B, 3), slides) (``fit-skin
    --skeleton``; :func:`~skinsynth.pipeline.rig.skeleton.held_rig`), or None. Splices, merges and
    plants move bones apart at their joints (on the walker, by 2–9 cm); the last step of each batch
    puts every jointed bone back on its joint (:func:`~skinsynth.pipeline.rig.skeleton.hold_joints`:
    its turn kept, its translation from its parent's), so bone lengths stay constant, and every
    sliding bone within the travel its joint showed in the input. That undoes the plants' limb corrections
    (translations; their root offset stays), so then each planted patch's bone has its joint
    brought back where the plants put it by two-bone inverse kinematics of its shin and thigh
    (:func:`~skinsynth.pipeline.rig.skeleton.reach_with_legs`): on the planted walker the sliding
    contact steps went from 69 % to 3 % (0 % unjointed)."""

    count: int
    frames: int
    seed: int = 0
    targets: list = field(default_factory=list)
    start: int | None = None
    end: int | None = None
    obstacles: object = None
    forbidden: np.ndarray | None = None
    min_difference: float = 0.0
    window: int = 4
    spread_velocity: bool = True
    cut_damping: float = 1e-3
    transition_probability: float = 0.1
    min_segment: int = 12
    blend: str = "bones"
    alignment: str = "ground"
    up_axis: int = 1
    contact: bool = True
    support: object = None
    plants: object = None
    support_beyond_plants: object = None
    clips: object = None
    skeleton: object = None
    fps: float = 24.0
    tree: object = None
    shape_check: bool = True
    envelope: object = None
    held: object = None

    def never_shown(self):
        """(F,) bool or None: the frames no walk may show, those that collide (``forbidden``) and the
        held poses' hidden frames (``held``, a :class:`.held_poses.HeldPoses`: each held pose one place)."""
        if self.held is None:
            return self.forbidden
        hidden = self.held.hidden
        return hidden if self.forbidden is None else hidden | np.asarray(self.forbidden, bool)

    def parameters(self, obstacles, ground_plane, single_component):
        """{name: value} of the request as synthesize's provenance records it, with its
        ``obstacles`` (their paths), ``ground_plane`` and ``single_component``: frames global,
        ``up_axis`` as "X", "Y" or "Z"."""
        return dict(count=self.count, frames=self.frames, seed=self.seed, start_frame=self.start, end_frame=self.end,
                    targets=[list(t) for t in self.targets], obstacles=list(obstacles), ground_plane=ground_plane,
                    min_difference=self.min_difference, single_component=single_component, window=self.window,
                    spread_velocity=self.spread_velocity, cut_damping=self.cut_damping, min_segment=self.min_segment,
                    blend=self.blend, alignment=self.alignment, up_axis="XYZ"[self.up_axis], contact=self.contact,
                    shape_check=self.shape_check)


@dataclass
class Synthesis:
    """F (N, M, B, 3, 3), t (N, M, B, 3) world bone positions (float32); sources (C, N, M) the
    input frame played per component (the walks each animation was assembled from); choice (N, C)
    bookkeeping of the assembly; seams_used (N,) transitions per animation (seams of all
    components, by the clip-aware rule: :meth:`.clips.Clips.seams`);
    distinct: animations whose walks differ from every other; rejected: counts of animations
    replaced (collisions, too similar, failed merges); statistics: per component transitions,
    mean and shortest segment, coverage (and with several clips coverage per clip and
    transitions per pair of clips: :func:`.motion_graph.walk_statistics`); limited (N, M) uint8:
    where the plants could not hold a foot (:data:`..mesh.contact_measures.LIMB_HELD`: a limb held at the edge of
    its joints' range, :data:`..mesh.contact_measures.LIMB_CUT`: its turn cut to keep the skin whole; 0 everywhere without
    plants), what the feet report splits the slide by (:func:`.skinned.measure_feet`)."""

    F: np.ndarray
    t: np.ndarray
    sources: np.ndarray
    choice: np.ndarray
    seams_used: np.ndarray
    distinct: int
    rejected: dict
    statistics: dict = field(default_factory=dict)
    limited: np.ndarray = None


def validate_request(request, input_frames):
    if request.count < 1:
        raise OptionError(f"--count must be at least 1 (got {request.count})")
    if not request.cut_damping >= 0.0:
        raise OptionError(f"--cut-damping must be at least 0 (got {request.cut_damping})")
    if request.min_segment < 1:
        raise OptionError(f"--min-segment must be at least 1 frame (got {request.min_segment})")
    if request.min_segment > max(input_frames, request.frames):  # issue 63: sized work refused before it starts
        raise OptionError(f"--min-segment {request.min_segment} is longer than both the clip ({input_frames} frames) "
                          f"and the animations ({request.frames})")
    if request.window > input_frames:
        raise OptionError(f"--window {request.window} is longer than the clip's {input_frames} frames")
    if request.alignment not in ("ground", "full"):
        raise OptionError(f"--alignment must be ground or full (got {request.alignment!r})")
    if request.blend not in ("bones", "key-vertices"):
        raise OptionError(f"--blend must be bones or key-vertices (got {request.blend!r})")
    if request.window < 0:
        raise OptionError(f"--window must be at least 0 (got {request.window})")
    if request.frames < 1:
        raise OptionError(f"--frames must be at least 1 (got {request.frames})")
    if not 0.0 <= request.min_difference <= 1.0:
        raise OptionError(f"--min-difference must lie in [0, 1] (got {request.min_difference})")
    if request.clips is not None and request.clips.total != input_frames:
        raise ValueError(f"the clips hold {request.clips.total} frames, the input {input_frames}")
    for frame, time in request.targets:
        if not 0 <= frame < input_frames:
            raise OptionError(f"--target {frame}@{time}: the clip has frames 0..{input_frames - 1}")
        if not 0 <= time < request.frames:
            raise OptionError(f"--target {frame}@{time}: output times are 0..{request.frames - 1}")
    for name, frame in (("--start-frame", request.start), ("--end-frame", request.end)):
        if frame is not None and not 0 <= frame < input_frames:
            raise OptionError(f"{name} {frame}: the clip has frames 0..{input_frames - 1}")


def _walks(graph, request, count, rng):
    from .walk_measures import STUCK_SECONDS

    fresh = int(round(STUCK_SECONDS * request.fps))  # walks avoid replaying what they played in 2 s
    if request.targets or request.start is not None or request.end is not None:
        return constrained_walks(graph, count, request.frames, request.targets, rng, start=request.start,
                                 end=request.end, transition_probability=request.transition_probability,
                                 min_segment=request.min_segment, fresh=fresh)
    return random_walks(graph, count, request.frames, rng, transition_probability=request.transition_probability,
                        min_segment=request.min_segment, fresh=fresh)


def make_batch(components, graphs, rotations, translations, rest, bone_indices, bone_weights, request, batch, count):
    """``count`` animations of one batch: (F, t, sources (C, count, M), choice, limited (count, M)
    uint8: :attr:`Synthesis.limited`, rejected dict)."""
    rng = np.random.default_rng([request.seed, batch])
    bones = rotations.shape[1]
    # Components assembly carries onto another through a cut node: their eq. 7 motion cancels.
    carried = {c for c, cut in merge_order([c.bones for c in components]) if cut is not None}
    cut_nodes = cut_bones([c.bones for c in components])
    subset = vertex_subset(rest.shape[0])
    pivots = bone_centroids(rest, bone_indices, bone_weights, bones)
    up = None if request.alignment == "full" else np.eye(3)[request.up_axis]
    kept_F, kept_t, kept_src, kept_choice, kept_limited = [], [], [], [], []
    rejected = {"collisions": 0, "too_similar": 0, "merges": 0}
    need, rounds, held, tries, found = count, 0, request.support, 0, 0
    # Obstacles may reject most walks of a round whatever the variety: they keep the long bound.
    limit = DIVERSITY_ROUNDS if request.min_difference > 0.0 and not request.obstacles else MAX_ROUNDS
    while need > 0:
        if rounds and _out_of_reach(found, tries, need, limit - rounds, REPLACEMENT_CAP * count):
            raise OptionError(f"could not make {count} acceptable animations in {rounds} rounds "
                              f"({rejected}); relax --min-difference or the obstacles")
        rounds += 1
        tries = need if rounds == 1 else _replacements(need, tries, found, REPLACEMENT_CAP * count)
        sources = np.stack([_walks(g, request, tries, rng) for g in graphs])  # (C, tries, M)
        parts = [splice_local(c, rotations, translations, sources[k], window=request.window, dtype=np.float32,
                              reference_motion=k not in carried, spread_velocity=request.spread_velocity,
                              damped_bones=cut_nodes, damping=request.cut_damping,
                              blend=request.blend, pivots=pivots, up=up, clips=request.clips)
                 for k, c in enumerate(components)]
        if len(components) == 1:
            F, t = parts[0].world()
            choice = np.arange(tries)[:, None]
        else:
            agree = None if request.plants is None else (sources, [request.plants.concerning(k, c.bones)
                                                                   for k, c in enumerate(components)])
            F, t, choice, failed = assemble([c.bones for c in components], parts, bones, rng, contacts=agree)
            rejected["merges"] += failed
            # Output a uses walk choice[a, c] of component c: keep the walks actually used.
            sources = np.stack([sources[k, choice[:, k]] for k in range(len(components))])
        lowest = None
        limited = np.zeros(F.shape[:2], np.uint8)
        if request.contact and request.plants is not None:  # the merged bones are final: plant the feet
            lowest = np.empty(F.shape[:2]) if request.support_beyond_plants is not None else None
            at_range, cut = np.zeros(F.shape[:2], np.int64), np.zeros(F.shape[:2], np.int64)
            plant_feet(F, t, sources, request.plants, lowest, at_range, cut)
            limited = ((at_range > 0) * LIMB_HELD + (cut > 0) * LIMB_CUT).astype(np.uint8)
        if request.contact:  # keep the input's range of lowest points (:mod:`.contact`): after the plants, a
            # safety net, zero wherever they kept it (a merge can plant one foot and sink the other)
            if held is None:
                held = support(rest, bone_indices, bone_weights, rotations, translations, request.up_axis)
            if lowest is None:
                keep_contact(F, t, held)
            else:  # the plants' lowest points, and the support's outside their patches
                keep_contact(F, t, request.support_beyond_plants, lowest=lowest)
        if request.skeleton is not None:  # the joints hold again (Request notes), bone lengths constant
            feet = None
            if request.contact and request.plants is not None:  # where the plants put each foot's joint
                feet = np.unique(request.plants.bones[request.plants.anchor_bone])
                targets = np.einsum("nmfxy,fy->nmfx", F[:, :, feet], request.skeleton[2][feet]) + t[:, :, feet]
            hold_joints(F, t, *request.skeleton)
            if feet is not None:  # and the legs reach for it again, by inverse kinematics
                reach_with_legs(F, t, *request.skeleton[:3], feet, targets, slides=request.skeleton[3])
        ok = np.ones(tries, dtype=bool)
        if request.obstacles:
            from skinsynth.gpu import lbs_reference

            for a in range(tries):
                points = lbs_reference(rest[subset], bone_indices[subset], bone_weights[subset], F[a], t[a])
                ok[a] = not colliding(request.obstacles, points).any()
            rejected["collisions"] += int((~ok).sum())
        if not ok.all():  # fancy indexing copies F and t: only when something was dropped
            F, t, choice, sources, limited = F[ok], t[ok], choice[ok], sources[:, ok], limited[ok]
        previous = np.concatenate(kept_src, axis=1) if kept_src else np.zeros((len(graphs), 0, request.frames), int)
        if request.min_difference > 0.0 and F.shape[0]:
            stacked = np.concatenate([previous, sources], axis=1)
            joint = stacked.transpose(1, 0, 2).reshape(stacked.shape[1], -1)
            keep = diversity_filter(joint, request.min_difference)[previous.shape[1]:]
            rejected["too_similar"] += int((~keep).sum())
            if not keep.all():
                F, t, choice, sources, limited = F[keep], t[keep], choice[keep], sources[:, keep], limited[keep]
        take = found = min(need, F.shape[0])
        kept_F.append(F[:take])
        kept_t.append(t[:take])
        kept_src.append(sources[:, :take])
        kept_choice.append(choice[:take])
        kept_limited.append(limited[:take])
        need -= take
    if len(kept_F) == 1:  # the usual case: no second round, no copy
        return [kept_F[0], kept_t[0], kept_src[0], kept_choice[0], kept_limited[0], rejected]
    return [np.concatenate(kept_F), np.concatenate(kept_t), np.concatenate(kept_src, axis=1),
            np.concatenate(kept_choice), np.concatenate(kept_limited), rejected]


def motion_graphs(components, forbidden=None, clips=None):
    """One MotionGraph per component from its candidate transitions (OptionError if a component
    has no infinite walk); ``clips``: the input's several clips (None: one clip)."""
    if clips is None:
        return [MotionGraph.from_transitions(c.transitions, forbidden=forbidden) for c in components]
    return [MotionGraph.from_transitions(c.transitions, forbidden=forbidden, clips=clips) for c in components]


def _run_batches(args, batches, jobs, progress, done_before, remote):
    """make_batch over (batch id, count) pairs (:func:`.execution.run_batches`: here, in worker
    processes when jobs > 1, or on ``remote``'s cluster). Returns one round: [F, t, sources, choice, limited, rejected] of all
    batches in order."""
    total = sum(n for _, n in batches)
    rotations, frames = args[2], args[-1].frames
    shapes = [(total, frames, rotations.shape[1], 3, 3), (total, frames, rotations.shape[1], 3)]
    report = None if progress is None else (lambda rows: progress(done_before + rows))
    (F, t), rests = run_batches(make_batch, args, batches, jobs, shapes, report, remote)
    # int32: the walks are all this process keeps of a cluster run (a million 600-frame animations:
    # 2.4 GB per component instead of 4.8)
    sources = np.concatenate([r[0].astype(np.int32, copy=False) for r in rests], axis=1)
    choice = np.concatenate([r[1] for r in rests])
    limited = np.concatenate([r[2] for r in rests])
    rejected = {key: sum(r[3][key] for r in rests) for key in rests[0][3]}
    return [F, t, sources, choice, limited, rejected]


def _replacements(need, asked, found, cap):
    """Animations a replacement round draws for ``need`` dropped ones, from the last round's yield
    (``found`` kept of ``asked`` drawn): ``3 · need · asked / found`` (the yield only falls as
    kept animations accumulate: fresh walks repeat them ever more often; 3 is the margin for
    that fall, so a request the clip can meet ends in two or three rounds; 1.5 was too little:
    on the test bar at 0.1 each round found about half what it needed), at least ``need``, at
    most ``cap`` (:data:`REPLACEMENT_CAP` × the count asked; ``cap`` after a round that found nothing). Sizing each
    round by the previous one's yield replaced doubling (issue 34): near the clip's variety
    doubling reached its cap late and then drew 10⁵ candidates over 20 rounds."""
    if found <= 0:
        return cap
    return int(min(cap, max(need, -(-3 * need * asked // found))))


def _out_of_reach(found, asked, need, rounds_left, cap):
    """Whether ``rounds_left`` more rounds cannot make up ``need``: none are left, or the last
    round drew its most (``asked`` reached ``cap``) and found ``found``, and each later round
    draws as many and finds no more (fresh walks repeat kept ones ever more often)."""
    return rounds_left <= 0 or (asked >= cap and found * rounds_left < need)


def check_diversity_reachable(graphs, request):
    """OptionError, before any animation is made, when ``request.min_difference`` cannot be met:
    the clip's own variety bounds how many walks differ that much from one another.

    The check plays the run's rounds on walks alone (no splicing, so it costs a small part of
    the run): ``count`` walks per component (paired by index into animations), filtered as
    :func:`synthesize` filters, then replacement rounds sized as the run sizes them
    (:func:`_replacements`), one round fewer than the run may take (:data:`DIVERSITY_ROUNDS`):
    a request the check only just meets keeps a round in hand. Its walks come from their own
    random stream, so it is an estimate of what the run meets: the run's own rounds stay the
    judge (and refuse, after at most :data:`DIVERSITY_ROUNDS` rounds, in the rare case the
    estimate passed and they do not). It stops early once the rounds left cannot make up the
    shortfall (:func:`_out_of_reach`)."""
    if request.min_difference <= 0.0:
        return
    rng = np.random.default_rng([request.seed, 0x6469766572])  # "diver": apart from every batch's stream
    small = max(g.frames for g in graphs) < np.iinfo(np.int16).max  # int16: a quarter of the comparisons' bytes
    kept = np.zeros((0, len(graphs) * request.frames), dtype=np.int16 if small else np.int64)
    need, tries, found, cap = request.count, 0, 0, REPLACEMENT_CAP * request.count
    for round_ in range(DIVERSITY_ROUNDS - 1):
        tries = need if round_ == 0 else _replacements(need, tries, found, cap)  # the run's rule
        walks = np.stack([_walks(g, request, tries, rng) for g in graphs])  # (C, tries, M)
        joint = np.concatenate([kept, walks.transpose(1, 0, 2).reshape(tries, -1).astype(kept.dtype)])
        before = kept.shape[0]
        kept = joint[diversity_filter(joint, request.min_difference, kept_before=before)]
        need, found = request.count - kept.shape[0], kept.shape[0] - before
        if need <= 0:
            return
        if _out_of_reach(found, tries, need, DIVERSITY_ROUNDS - 2 - round_, cap):
            break
    raise OptionError(f"--min-difference {request.min_difference:g}: {round_ + 1} rounds of walks gave "
                      f"{kept.shape[0]} animations of {request.frames} frames that differ this much, not the "
                      f"{request.count} asked (checked before making any: a synthesis takes at most "
                      f"{DIVERSITY_ROUNDS} rounds); lower it or ask for fewer")


def synthesize(components, rotations, translations, rest, bone_indices, bone_weights, request, jobs=1, progress=None,
               remote=None):
    """Make ``request.count`` animations. components: list of ComponentAnalysis. Returns Synthesis.

    With ``remote`` (:class:`.execution.Remote`) the batches run on a Dask cluster and the
    result's F and t are :class:`.execution.StoredRows` (where the workers stored them), not
    arrays; everything else is the same, bit for bit.

    The diversity filter runs within each batch and then once more over all animations kept
    (earlier batches win); animations it drops are replaced by further batches with fresh
    batch ids, so the outcome still depends on the seed alone. ``progress(done)`` is called with
    the number of animations finished after each batch."""
    validate_request(request, rotations.shape[0])
    graphs = motion_graphs(components, request.never_shown(), request.clips)
    check_diversity_reachable(graphs, request)
    args = (components, graphs, rotations, translations, rest, bone_indices, bone_weights, request)
    results, next_batch, need, ask, found, cap = [], 0, request.count, 0, 0, REPLACEMENT_CAP * request.count
    for round_ in range(DIVERSITY_ROUNDS):
        ask = need if round_ == 0 else _replacements(need, ask, found, cap)
        batches = batch_sizes(ask, next_batch)
        next_batch += len(batches)
        done = request.count - need
        results.append(_run_batches(args, batches, jobs,
                                    None if progress is None else (lambda rows: progress(min(request.count, rows))),
                                    done, remote))
        if request.min_difference <= 0.0:
            break
        joint = np.concatenate([r[2] for r in results], axis=1)
        joint = joint.transpose(1, 0, 2).reshape(joint.shape[1], -1)
        keep = diversity_filter(joint, request.min_difference, kept_before=done)
        results[0][5]["too_similar"] += int((~keep).sum())
        surplus = int(keep.sum()) - request.count
        if surplus > 0:  # the last round's extra animations: the first kept ones are taken
            keep[np.flatnonzero(keep)[-surplus:]] = False
        found = int(keep[done:].sum())
        need = request.count - int(keep.sum())
        offset = 0
        for r in results:  # drop the repeats (and the surplus) batch by batch
            mine = keep[offset:offset + r[0].shape[0]]
            offset += r[0].shape[0]
            if not mine.all():
                r[0:5] = [r[0][mine], r[1][mine], r[2][:, mine], r[3][mine], r[4][mine]]
        if need == 0:
            break
        if _out_of_reach(found, ask, need, DIVERSITY_ROUNDS - 1 - round_, cap):
            raise OptionError(f"could not make {request.count} animations that differ by --min-difference "
                              f"{request.min_difference}: {round_ + 1} rounds made {request.count - need}, and the "
                              f"last found only {found} new ones of {ask}; lower it or ask for fewer")
    F = results[0][0] if len(results) == 1 else concatenate_rows([r[0] for r in results])
    t = results[0][1] if len(results) == 1 else concatenate_rows([r[1] for r in results])
    sources = np.concatenate([r[2] for r in results], axis=1)
    choice = np.concatenate([r[3] for r in results])
    limited = np.concatenate([r[4] for r in results])
    rejected = {key: sum(r[5][key] for r in results) for key in results[0][5]}
    clips = request.clips
    if clips is None:
        seams_used = np.sum(sources[..., 1:] != sources[..., :-1] + 1, axis=(0, 2))
        statistics = walk_statistics(sources, rotations.shape[0], fps=request.fps, held=request.held)
    else:
        seams_used = np.sum(clips.seams(sources), axis=(0, 2))
        statistics = walk_statistics(sources, rotations.shape[0], clips=clips, fps=request.fps, held=request.held)
    joint = sources.transpose(1, 0, 2).reshape(sources.shape[1], -1)
    distinct = int(unique_rows(joint).shape[0])
    return Synthesis(F=F, t=t, sources=sources, choice=choice, seams_used=seams_used, distinct=distinct,
                     rejected=rejected, statistics=statistics, limited=limited)
