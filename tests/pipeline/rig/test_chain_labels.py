"""Chains named from the geometry alone (issue 44): the walker's true rig named as its parts are, its
mirror image with left and right swapped, the same names however it faces or whichever axis is up,
and no names where the tree has no two legs."""

import numpy as np
import pytest

from skinsynth.pipeline.inputs.examples import WALKER_PARTS, walker
from skinsynth.pipeline.rig.chain_labels import _paths, chain_labels, named_chains, trunk_names
from skinsynth.pipeline.rig.rotations import rotation_exp

TRUE_NAMES = {"pelvis": "body", "chest": "spine_01", "thigh_l": "leg_l_01", "shin_l": "leg_l_02",
              "foot_l": "leg_l_03", "thigh_r": "leg_r_01", "shin_r": "leg_r_02", "foot_r": "leg_r_03",
              "arm_l": "arm_l_01", "arm_r": "arm_r_01"}


@pytest.fixture(scope="module")
def true_walker():
    vertices, faces, rig = walker(rig=True)
    indices = np.argsort(-rig.weights, axis=1, kind="stable")[:, :4]
    return vertices, rig, indices, np.take_along_axis(rig.weights, indices, axis=1)


def _names(true_walker, transform=np.eye(3), up_axis=1):
    vertices, rig, indices, weights = true_walker
    return chain_labels(rig.parents, rig.joints @ transform.T, rig.rest @ transform.T, indices, weights, up_axis,
                        vertices @ transform.T)


def test_the_walkers_true_rig_is_named_as_its_parts(true_walker):
    """The walker faces +z with y up, its left at +x (examples.walker)."""
    assert dict(zip(WALKER_PARTS, _names(true_walker))) == TRUE_NAMES
    assert named_chains(_names(true_walker)) == {"arm_l": 1, "arm_r": 1, "leg_l": 3, "leg_r": 3, "spine": 1}


def test_a_mirrored_walker_swaps_left_and_right(true_walker):
    swapped = {part: name.replace("_l_", "_x_").replace("_r_", "_l_").replace("_x_", "_r_")
               for part, name in TRUE_NAMES.items()}
    assert dict(zip(WALKER_PARTS, _names(true_walker, np.diag([-1.0, 1.0, 1.0])))) == swapped


@pytest.mark.parametrize("turn", [0.7, 2.0, -2.6])
def test_the_names_do_not_depend_on_where_the_walker_faces(true_walker, turn):
    facing = rotation_exp(np.array([0.0, turn, 0.0]))
    assert dict(zip(WALKER_PARTS, _names(true_walker, facing))) == TRUE_NAMES


def test_a_z_up_walker_is_named_the_same(true_walker):
    y_to_z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # y up → z up, +z forward → +y
    assert dict(zip(WALKER_PARTS, _names(true_walker, y_to_z, up_axis=2))) == TRUE_NAMES


def test_a_tree_without_two_legs_names_no_chain(true_walker):
    vertices, rig, indices, weights = true_walker
    lifted = vertices.copy()
    legs = np.isin(np.argmax(rig.weights, axis=1), [WALKER_PARTS.index(p) for p in ("foot_r", "shin_r", "thigh_r")])
    lifted[:, legs, 1] += 0.5  # the right leg never comes near the ground
    assert chain_labels(rig.parents, rig.joints, rig.rest, indices, weights, 1, lifted) is None


def test_legs_whose_tops_do_not_stand_above_their_feet_name_no_chain(true_walker):
    """Nothing is named rather than named wrong: a leg whose top (its first bone's joint) stands
    barely above its foot (the hips' joints put at 5 % of their height) is no leg a body stands on."""
    vertices, rig, indices, weights = true_walker
    low = rig.joints.copy()
    low[[WALKER_PARTS.index("thigh_l"), WALKER_PARTS.index("thigh_r")], 1] *= 0.05
    assert chain_labels(rig.parents, low, vertices[0], indices, weights, 1, vertices) is None
    assert chain_labels(rig.parents, rig.joints, vertices[0], indices, weights, 1, vertices) is not None


def test_an_uneven_tree_mirrored_swaps_left_and_right_bone_for_bone(true_walker):
    """A tree that is not its own mirror image (the right arm hung from the pelvis, the left from the
    chest): mirrored, every bone gets its name with the other side, the trunk's included (the spine
    runs to where both arms branch, not to where the arm found first does: the samba's fitted tree,
    mirrored, named one trunk bone hips_01 one way and spine_01 the other before)."""
    vertices, rig, indices, weights = true_walker
    parents = rig.parents.copy()
    parents[WALKER_PARTS.index("arm_r")] = WALKER_PARTS.index("pelvis")
    mirror = np.diag([-1.0, 1.0, 1.0])
    names = chain_labels(parents, rig.joints, vertices[0], indices, weights, 1, vertices)
    mirrored = chain_labels(parents, rig.joints @ mirror, vertices[0] @ mirror, indices, weights, 1, vertices @ mirror)
    assert names[WALKER_PARTS.index("arm_r")] == "arm_r_01" and names[WALKER_PARTS.index("arm_l")].startswith("arm_l")
    assert mirrored == [n.replace("_l_", "_x_").replace("_r_", "_l_").replace("_x_", "_r_") for n in names]


def test_a_trunk_that_forks_is_numbered_by_depth_each_name_once():
    """Front and hind legs branching off two trunk bones at one depth (0 → 1 → 2 and 0 → 3): numbered
    along each path both 1 and 3 would be spine_01 (the elephant's fit wrote such a file, which every
    reader refused); over both at once by depth, then id: 1, 3, 2."""
    parents = np.array([-1, 0, 1, 0, 2])
    names = ["body", "chain_01_joint_00", "chain_01_joint_01", "chain_02_joint_00", "leg_01"]
    named = trunk_names(names, _paths(parents), [(2, "spine"), (3, "spine")])
    assert named == ["body", "spine_01", "spine_03", "spine_02", "leg_01"]


def test_a_foot_with_a_bone_hanging_from_it_is_still_a_foot(true_walker):
    """Issue 65: the tree a free fit's joints give may hang a bone from a foot (Zheng's dancer,
    27 bones: a calf bone hung from one foot, so only one grounded leaf, and nothing was named).
    The walker's left shin hung from its left foot, and kept clear of the ground as the dancer's
    calf is (its skin raised 20 cm in the frames the feet are found on): the foot is still found (no
    grounded bone below it), the leg named thigh → foot, the shin left with its place name."""
    vertices, rig, indices, weights = true_walker
    thigh, shin, foot = (WALKER_PARTS.index(p) for p in ("thigh_l", "shin_l", "foot_l"))
    parents = rig.parents.copy()
    parents[foot], parents[shin] = thigh, foot
    frames = vertices.copy()
    frames[:, np.argmax(rig.weights, axis=1) == shin, 1] += 0.2
    names = dict(zip(WALKER_PARTS, chain_labels(parents, rig.joints, rig.rest, indices, weights, 1, frames)))
    assert names["thigh_l"] == "leg_l_01" and names["foot_l"] == "leg_l_02" and names["shin_l"].startswith("chain_")
    assert {part: name for part, name in names.items() if part not in ("thigh_l", "shin_l", "foot_l")} == \
        {part: name for part, name in TRUE_NAMES.items() if part not in ("thigh_l", "shin_l", "foot_l")}


def test_frames_lying_down_make_no_feet(true_walker):
    """Issue 65 (a lying pose that stands up; the horse collapse): the walker's frames followed by as
    many of it lying on its left side, its left arm on the floor. Counted over every frame, that arm
    touches the ground often enough to be a foot and nothing was named; the feet are found in the
    frames it stands in (at least ``UPRIGHT`` of its tallest frame's height), so it keeps its names."""
    from skinsynth.pipeline.rig import chain_labels as labels

    vertices, rig, indices, weights = true_walker
    on_its_side = vertices @ rotation_exp(np.array([0.0, 0.0, -np.pi / 2])).T  # its left (+x) down
    on_its_side[..., 1] -= on_its_side[..., 1].min(axis=1, keepdims=True)
    frames = np.concatenate([vertices, on_its_side])
    names = chain_labels(rig.parents, rig.joints, rig.rest, indices, weights, 1, frames)
    assert dict(zip(WALKER_PARTS, names)) == TRUE_NAMES
    every = labels.UPRIGHT
    try:
        labels.UPRIGHT = 0.0  # every frame counted: the rule this one replaced
        assert chain_labels(rig.parents, rig.joints, rig.rest, indices, weights, 1, frames) is None
    finally:
        labels.UPRIGHT = every


def test_flat_legs_are_no_legs(true_walker):
    """A sheet cut like a figure (the walker flattened to no depth) has two grounded ends and a top,
    but no limbs: a leg's skin is round its bones (``LIMB_THICKNESS``). The Houdini cloth sheet,
    fitted from more bones, was named as a biped with legs of 7 and 11 bones before."""
    vertices, rig, indices, weights = true_walker
    flat = np.diag([1.0, 1.0, 0.0])
    assert chain_labels(rig.parents, rig.joints @ flat, rig.rest @ flat, indices, weights, 1, vertices @ flat) is None


def test_legs_that_slide_are_no_legs(true_walker):
    """A soft body's bones slide on each other (the simulated cow: every joint sliding): legs turn at
    their joints, so a tree whose legs' bones mostly slide names nothing (the cow's was named a biped)."""
    vertices, rig, indices, weights = true_walker
    jointed = rig.parents >= 0
    assert chain_labels(rig.parents, rig.joints, rig.rest, indices, weights, 1, vertices, jointed=jointed) is not None
    legs = [WALKER_PARTS.index(p) for p in ("thigh_l", "shin_l", "thigh_r", "shin_r")]
    jointed[legs] = False
    assert chain_labels(rig.parents, rig.joints, rig.rest, indices, weights, 1, vertices, jointed=jointed) is None


@pytest.mark.parametrize("kind,part", [("quadruped", "head"), ("humanoid", "head")])
def test_a_head_turned_aside_at_rest_is_still_the_head(kind, part):
    """Issue 65: the rest pose a fit picks may have the head turned or tilted aside (a grazing
    quadruped's neck turned, a dancer leaning): its end is no longer on the line between the legs.
    The generated characters' true trees, posed with the head aside, keep their names: a quadruped's
    head and tail are the ends farthest ahead and behind its legs (posed where its head stands
    farthest aside), a biped's head the highest end between its shoulders (``CENTRE_BAND``, a fifth
    of the width; posed where its head stands nearest 0.13 of the width aside, as Zheng's dancer's,
    which was taken for no end and its chest named an arm at a tenth: far from either bound)."""
    from skinsynth.pipeline.inputs.characters import character
    from skinsynth.pipeline.rig.influence import bone_centroids

    vertices, faces, rig = character(kind, frames_per_motion=24)
    indices = np.argsort(-rig.weights, axis=1, kind="stable")[:, :4]
    weights = np.take_along_axis(rig.weights, indices, axis=1)
    head = rig.body.index(part)
    posed = np.einsum("fbij,bj->fbi", rig.rotations, rig.body.joints) + rig.translations  # (F, B, 3)
    centres = np.stack([bone_centroids(frame, indices, weights, len(rig.body.names)) for frame in vertices])
    if kind == "quadruped":
        frame = int(np.argmax(np.abs(centres[:, head, 0])))
    else:  # the head's offset from the hips' middle across them, over the width along that line
        thighs = posed[:, [rig.body.index("thigh_l"), rig.body.index("thigh_r")]]
        across = thighs[:, 0] - thighs[:, 1]
        across[:, 1] = 0.0
        across /= np.linalg.norm(across, axis=1, keepdims=True)
        aside = np.abs(np.einsum("fx,fx->f", centres[:, head] - thighs.mean(axis=1), across))
        width = np.ptp(np.einsum("fvx,fx->fv", vertices, across), axis=1)
        frame = int(np.argmin(np.abs(aside / width - 0.13)))
        assert 0.12 < aside[frame] / width[frame] < 0.14
    joints = posed[frame]
    names = chain_labels(rig.body.parents, joints, vertices[frame], indices, weights, 1, vertices, faces=faces)
    assert names == list(rig.names)


def test_the_names_do_not_depend_on_how_the_clip_is_sampled(true_walker):
    """The feet are counted over shares of the frames the body stands in: the walker played at twice
    its rate (frames in-betweened) or after three seconds held still is named the same."""
    vertices, rig, indices, weights = true_walker
    doubled = np.empty((2 * len(vertices) - 1,) + vertices.shape[1:])
    doubled[0::2], doubled[1::2] = vertices, (vertices[:-1] + vertices[1:]) / 2.0
    still = np.concatenate([np.repeat(vertices[:1], 72, axis=0), vertices])
    for frames in (doubled, still):
        assert dict(zip(WALKER_PARTS, chain_labels(rig.parents, rig.joints, rig.rest, indices, weights, 1, frames))) \
            == TRUE_NAMES
