"""The records of the skin and synthesis pages built from a fit's arrays (the files are read by
``cli/view.py``): each frame skinned on demand with the reference LBS, the skeleton a jointed fit
carries, the synthesis's vertices coloured by the component that moves them."""

from skinsynth.gpu import lbs_reference

from ...mesh.geometry import bounding_box_diagonal
from ...rig.chain_labels import chain_tops
from .records import SkinView, SynthesisView


def skin_view(skin, error_fraction, contacts=None):
    """The :class:`SkinView` of a skin fit (``formats``' ``SkinFile``: rest, weights, bones
    (F, B, 3, 3) and (F, B, 3), examples (F, V, 3)), errors shaded up to ``error_fraction`` of the
    rest's diagonal; ``contacts``: a graph file's ground contacts (a ``ContactsRecord``) or None."""

    def fit(frame):
        return lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights,
                             skin.rotations[frame:frame + 1], skin.translations[frame:frame + 1])[0]

    return SkinView(faces=skin.faces, examples=skin.examples, fit=fit,
                    error_scale=error_fraction * bounding_box_diagonal(skin.rest_vertices),
                    error_fraction=error_fraction, fps=skin.fps, up_axis=skin.scene.up_axis,
                    contacts=None if contacts is None else (contacts.vertices, contacts.offsets, contacts.planted),
                    skeleton=None if skin.skeleton is None else skeleton_at(skin),
                    chains=None if skin.skeleton is None else chain_tops(skin.skeleton["names"]))


def skeleton_at(skin):
    """frame -> (joints (B, 3), bones (S, 2, 3)) of a jointed skin's skeleton as its fit carries it."""
    from ..scenes import skeleton_lines

    held = skin.skeleton["jointed"] | skin.skeleton["sliding"]  # a sliding bone is in the tree too

    def at(frame):
        return skeleton_lines(skin.rotations[frame], skin.translations[frame], skin.skeleton["joints"],
                              skin.skeleton["parents"], held)
    return at


def synthesis_view(skin, motions, read_sources, owner, components, animation, clips, check_finite):
    """The :class:`SynthesisView` of a synthesis: ``motions`` (F, t) its bone motions, read one
    animation at a time ((count, M, B, 3, 3) and (count, M, B, 3)); ``read_sources(a)`` the input
    frame each component plays (C, M); ``owner`` (V,) each vertex's component of ``components``;
    ``check_finite(what, array)`` refuses a damaged animation (the file's reader's check)."""
    F, t = motions

    def load(a):
        rotations, translations = F[a], t[a]
        check_finite(f"/synthesis animation {a}'s bone motions", rotations)
        check_finite(f"/synthesis animation {a}'s bone motions", translations)
        sources = read_sources(a)

        def frame(m):
            return lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, rotations[m:m + 1],
                                 translations[m:m + 1])[0]
        return frame, sources

    return SynthesisView(faces=skin.faces, rest=skin.rest_vertices, count=int(F.shape[0]), frames=int(F.shape[1]),
                         load=load, vertex_components=owner, components=components, animation=animation,
                         fps=skin.fps, up_axis=skin.scene.up_axis, clips=clips)
