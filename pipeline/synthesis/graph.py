"""build-graph: everything synthesis needs from one clip, or from several clips of one character
(Zheng §3.2, §3.3, §4.1).

Per bone component (the whole mesh, or the weakly coupled parts separated by cut nodes of the
bone graph): its reference bone and candidate transitions (:mod:`.transitions`), its key
vertices with weight gradients (:mod:`.key_vertices`), the rotation–strain series of the
deformation gradients at those vertices over the clip, and the factorised operator of eq. 9
that turns blended gradients back into local-frame bone positions
(:mod:`.deformation_gradients`). With several clips (:class:`.clips.Clips`) the frames are the
clips in order: transitions are found within and between them (:mod:`.transitions`, module
notes); everything else is per frame or per vertex and needs no clip.
"""

from dataclasses import dataclass, field

import numpy as np

from .deformation_gradients import deformation_gradients, gradient_operator, rotation_strain
from ..errors import ClipError, OptionError
from .key_vertices import gather_weights, key_vertices, vertex_neighbours, weight_gradients
from .graph_options import GraphOptions
from .held_poses import find_held_poses
from .motion_graph import transitions_between
from .transitions import bone_centroids, find_transitions, local_frame_positions


_DEFAULT = GraphOptions()


@dataclass
class ComponentAnalysis:
    """One bone component: bones (sorted ids), transitions (Transitions), key (key vertex ids
    (n,)), key_bones (n, K') (−1 padding), key_weights (n, K'), key_gradients (n, K', 3),
    strain (F, n, 9) rotation–strain coordinates of the local-frame deformation gradients,
    operator (GradientOperator); key data use the component's own weights (renormalised over
    its bones); contact_agrees (M,) bool or None: which of its transitions keep the input's ground
    contacts (:func:`.planting.mark_contact_jumps`; synthesize --contact walks only those)."""

    bones: list
    transitions: object
    key: np.ndarray
    key_bones: np.ndarray
    key_weights: np.ndarray
    key_gradients: np.ndarray
    strain: np.ndarray
    operator: object
    contact_agrees: np.ndarray | None = None


@dataclass
class GraphAnalysis:
    """d (B, B) bone-graph weights (eq. 11); kept_edges (E, 2); cut_nodes: the bones shared by two
    or more components; articulation_points: every cut node of the pruned graph (some end up
    inside a merged component); components; options; clips: the :class:`.clips.Clips` of the
    frames (None: one clip); contacts: the input's :class:`.contact.patches.ContactPatches`
    (None: not looked for); refused: per component, the transitions refused for a contact jump and
    whether it kept them all (:func:`.contact.planting.mark_contact_jumps`), or None (no contacts);
    held: the clip's :class:`.held_poses.HeldPoses` (whole-body stills, each one place in every
    component's graph)."""

    weights: np.ndarray
    kept_edges: np.ndarray
    cut_nodes: list
    articulation_points: list
    components: list
    options: dict = field(default_factory=dict)
    clips: object = None
    contacts: object = None
    refused: list | None = None
    held: object = None

    @property
    def transition_count(self):
        return int(sum(len(c.transitions.pairs) for c in self.components))

    def drawn_transitions(self):
        """Per component, its transitions (n, 2) where a cost matrix draws them: a transition into
        clip c's start (j = −(c+1)) at the column of the frame before that start, c's virtual frame
        (one clip: unchanged, j = −1 stays −1)."""
        drawn = []
        for component in self.components:
            pairs = component.transitions.pairs.copy()
            if self.clips is not None:
                pairs[:, 1] = self.clips.targets(pairs[:, 1]) - 1
            drawn.append(pairs)
        return drawn

    def transitions_between(self):
        """Per component, its transitions by clip left and clip entered: {"a->b": count}
        (:func:`.motion_graph.transitions_between`; one clip: {"clip->clip": all of them})."""
        from ..inputs.clips import Clips

        clips = self.clips
        if clips is None:
            frames = self.components[0].transitions.D.shape[0] if self.components else 1
            clips = Clips.single(frames)
        return [transitions_between(c.transitions.pairs, clips) for c in self.components]


def validate_graph_options(frames, threshold_scale, edge_threshold, svd_threshold, min_gap, min_segment=2,
                           coverage=0.95, posture_weight=1.0):
    if frames < 3:
        raise ClipError(f"the clip has {frames} frames; transitions need at least 3")
    for name, value in (("--threshold-scale", threshold_scale), ("--edge-threshold", edge_threshold),
                        ("--svd-threshold", svd_threshold)):
        if not value > 0.0:
            raise OptionError(f"{name} must be positive (got {value})")
    if min_gap < 1:
        raise OptionError(f"--min-gap must be at least 1 (got {min_gap})")
    if min_segment < 1:
        raise OptionError(f"--min-segment must be at least 1 frame (got {min_segment})")
    if min_segment > frames:  # issue 63: sized work refused before it starts (1e9 ran out of memory)
        raise OptionError(f"--min-segment {min_segment} is longer than the clip's {frames} frames; walks could never "
                          "take a transition")
    if min_gap >= frames:
        raise OptionError(f"--min-gap {min_gap} is not shorter than the clip's {frames} frames")
    if not 0.0 <= coverage <= 1.0:
        raise OptionError(f"--coverage must lie in [0, 1] (got {coverage})")
    if not 0.0 <= posture_weight < np.inf:
        raise OptionError(f"--posture-weight must be finite and at least 0 (got {posture_weight})")


def analyse_component(bones, rest, neighbours, bone_indices, bone_weights, rotations, translations, options,
                      clips=None, walkable=None, held=None, fps=24.0):
    """ComponentAnalysis of one bone component (sorted bone ids); clips: the frames' clips (None:
    one); walkable (F,) bool: the frames transitions may leave and enter (None: all); held: the
    clip's :class:`.held_poses.HeldPoses` (None: none); fps: the clip's frame rate."""
    total = rotations.shape[1]
    transitions = find_transitions(rotations, translations, bone_indices, bone_weights, bones_subset=bones,
                                   svd_threshold=options["svd_threshold"], threshold_scale=options["threshold_scale"],
                                   threshold_reference=options["threshold_reference"], min_gap=options["min_gap"],
                                   spacing=max(1, options["min_segment"] // 2), coverage=options["coverage"],
                                   up=np.eye(3)[options["up_axis"]], pivots=bone_centroids(rest, bone_indices, bone_weights, total),
                                   scale=float(np.ptp(rest, axis=0).max()), posture_weight=options["posture_weight"],
                                   clips=clips, walkable=walkable, spread=4 * options["min_segment"],
                                   segment=options["min_segment"], held=held, fps=fps)
    # The component is synthesised as if it were the whole mesh: its key vertices see only its
    # own bones, weights renormalised over them, so eq. 8 needs no bone from another component
    # and the unit-sum and eq. 15 properties still hold.
    own_weights = np.where(np.isin(bone_indices, bones), bone_weights, 0.0)
    mass = own_weights.sum(axis=1, keepdims=True)
    own_weights = np.divide(own_weights, mass, out=np.zeros_like(own_weights), where=mass > 0.0)
    key = key_vertices(bone_indices, own_weights, total, subset=bones).vertices
    key_bones, gradients = weight_gradients(rest, neighbours, bone_indices, own_weights, key)
    weights = gather_weights(bone_indices, own_weights, key, key_bones)
    r_local, t_local, local_ids = local_frame_positions(rotations, translations, transitions.reference, bones)
    grads = deformation_gradients(r_local, t_local, local_ids, transitions.reference, rest, key, key_bones,
                                  weights, gradients)  # Zheng eq. 8, (F, n, 3, 3)
    operator = gradient_operator(local_ids, transitions.reference, rest, key, key_bones, weights, gradients)
    return ComponentAnalysis(bones=list(bones), transitions=transitions, key=key, key_bones=key_bones,
                             key_weights=weights, key_gradients=gradients, strain=rotation_strain(grads),
                             operator=operator)


def build_graph(rest, faces, bone_indices, bone_weights, rotations, translations,
                threshold_scale=_DEFAULT.threshold_scale, threshold_reference=_DEFAULT.threshold_reference,
                edge_threshold=_DEFAULT.edge_threshold, single_component=_DEFAULT.single_component,
                svd_threshold=_DEFAULT.svd_threshold, min_gap=_DEFAULT.min_gap, min_bones=_DEFAULT.min_bones,
                min_segment=_DEFAULT.min_segment, coverage=_DEFAULT.coverage, up_axis=_DEFAULT.up_axis,
                posture_weight=_DEFAULT.posture_weight, clips=None, walk_clips=None, fps=24.0):
    """Analyse a skin fit for synthesis. rest (V, 3); faces (T, 3); bone_indices/bone_weights
    (V, K); rotations (F, B, 3, 3); translations (F, B, 3). min_segment: the shortest stretch
    walks play between seams (frames); transitions closer than half of it to a cheaper one are
    dropped (:func:`.transitions.select_transitions`, with ``coverage``); up_axis (0, 1, 2) and
    posture_weight: the costs also weigh the reference bone's tilt and height about that axis
    (:func:`.transitions.posture_costs`; 0: Zheng's eq. 5 alone); clips: the
    :class:`.clips.Clips` of the F frames (None: one clip; several: transitions within and between
    them); walk_clips: the names of the clips walks may play (None: every clip; the others, e.g. a
    library of unrelated key poses, get no transition in or out, so no walk reaches them); fps: the
    clip's frame rate (the time the threshold counts a playback step in; held poses last at least
    ``min_segment`` frames, :mod:`.held_poses`). Returns GraphAnalysis."""
    from .bone_graph import bone_components  # networkx: imported when a graph is built, not by synthesize

    validate_graph_options(rotations.shape[0], threshold_scale, edge_threshold, svd_threshold, min_gap, min_segment,
                           coverage, posture_weight)
    bones = rotations.shape[1]
    weights, graph, decomposition = bone_components(bone_indices, bone_weights, bones, edge_threshold=edge_threshold,
                                                    single_component=single_component, min_bones=min_bones)
    neighbours = vertex_neighbours(faces, rest.shape[0])
    walkable = None
    if walk_clips is not None and clips is not None:  # one clip (None): every frame is walked
        walkable = np.zeros(rotations.shape[0], bool)
        walkable[clips.select(walk_clips)] = True
    options = dict(threshold_scale=threshold_scale, threshold_reference=threshold_reference,
                   edge_threshold=edge_threshold, single_component=single_component, svd_threshold=svd_threshold,
                   min_gap=min_gap, min_bones=min_bones, min_segment=int(min_segment), coverage=float(coverage),
                   up_axis=int(up_axis), posture_weight=float(posture_weight),
                   walk_clips=list(clips.names if walk_clips is None or clips is None else
                                   clips.subset(walk_clips).names) if clips is not None else None)
    shown = max(2, int(min_segment))  # a held run shows half a second and lasts at least a second (:mod:`.held_poses`)
    held = find_held_poses(rotations, translations, bone_centroids(rest, bone_indices, bone_weights, bones),
                           float(np.ptp(rest, axis=0).max()), 2 * shown, clips, keep=shown)
    components = [analyse_component([int(b) for b in members], rest, neighbours, bone_indices, bone_weights, rotations,
                                    translations, options, clips, walkable, held, fps)
                  for members in decomposition.components]
    edges = np.array(sorted(graph.edges()), dtype=np.int64).reshape(-1, 2)
    # Only articulation points that still join components matter to synthesis (Alg. 1);
    # others ended up inside a merged block.
    joining = sorted(int(b) for b in decomposition.component_of_cut)
    return GraphAnalysis(weights=weights, kept_edges=edges, cut_nodes=joining,
                         articulation_points=[int(b) for b in decomposition.cut_nodes], components=components,
                         options=options, clips=clips, held=held)


def analyse_fit(skin, options, walk_clips=None):
    """build-graph's analysis of a skin fit (``formats.skin_file.SkinModel``: rest_vertices (V, 3),
    faces, bone_indices and bone_weights (V, K), rotations (F, B, 3, 3), translations (F, B, 3),
    examples (F, V, 3), fps, clip_names and clip_frames) with ``options`` (a
    :class:`.graph_options.GraphOptions`), validated first: :func:`build_graph` over its clips
    (``walk_clips``: the names of those walks may play, None for all; an unknown one is an
    OptionError), then with ``options.contacts`` the input's ground contacts
    (:func:`.contact.patches.find_contacts`) and the transitions that would make a planted patch
    jump to a swinging one (:func:`.contact.planting.mark_contact_jumps`). Returns GraphAnalysis."""
    from ..inputs.clips import Clips
    from .contact.patches import find_contacts, validate_contact_options
    from .contact.planting import mark_contact_jumps

    o = options
    validate_graph_options(skin.rotations.shape[0], o.threshold_scale, o.edge_threshold, o.svd_threshold, o.min_gap,
                           o.min_segment, o.coverage, o.posture_weight)
    validate_contact_options(o.contact_height, o.contact_speed, o.contact_release, o.contact_min_duration,
                             o.contact_min_support)
    clips = Clips(skin.clip_names, skin.clip_frames)
    if walk_clips is not None:
        walk_clips = clips.subset(walk_clips).names
    analysis = build_graph(skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights, skin.rotations,
                           skin.translations, **o.analysis_options(), clips=clips, walk_clips=walk_clips, fps=skin.fps)
    if o.contacts:
        analysis.contacts = find_contacts(skin.examples, skin.faces, skin.fps, o.up_axis, clips,
                                          height=o.contact_height, speed=o.contact_speed, release=o.contact_release,
                                          min_duration=o.contact_min_duration, min_support=o.contact_min_support)
    if analysis.contacts is not None and analysis.contacts.count:  # a planted foot never jumps to a swinging one
        analysis.refused = mark_contact_jumps(analysis.components, analysis.contacts, skin.bone_indices,
                                              skin.bone_weights, clips)
    return analysis


def bone_layout(rest, bone_indices, bone_weights, bones):
    """2-D positions (B, 2) for drawing the bone graph: each bone's weighted rest centroid,
    projected on the rest pose's two principal axes."""
    centred = rest - rest.mean(axis=0)
    axes = np.linalg.svd(centred, full_matrices=False)[2][:2]
    return (bone_centroids(rest, bone_indices, bone_weights, bones) - rest.mean(axis=0)) @ axes.T
