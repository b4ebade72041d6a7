"""The limbs the plants turn (issue 62: :mod:`skinsynth.pipeline.synthesis.contact.limb_chains`) and the
joint tree they are found on (:mod:`skinsynth.pipeline.rig.joint_tree`): the tree's balance, its
rooting, a limb's side cut where the bones share least skin, and the walker's legs."""

import numpy as np
import pytest

from skinsynth.pipeline.rig.joint_tree import balance_bone, rooted_at, skin_joint_tree
from skinsynth.pipeline.synthesis.contact.limb_chains import LIMB_SHARE, joint_ranges, limb_chains, limb_side, plant_chains
from skinsynth.pipeline.rig.rotations import rotation_exp


def test_balance_bone_does_not_depend_on_the_root():
    """A heavy trunk (1) between a light head (0) and two light legs (2, 3): the tree balances at the
    trunk however it is rooted."""
    mass = np.array([1.0, 10.0, 1.0, 1.0])
    assert balance_bone(np.array([-1, 0, 1, 1]), mass) == 1
    assert balance_bone(np.array([1, 2, -1, 1]), mass) == 1  # rooted at a leg
    assert balance_bone(np.array([-1, 0, 1, 2]), np.array([1.0, 1.0, 1.0, 10.0])) == 3  # a chain, heavy at its end


def test_rooted_at_reverses_the_path_and_keeps_each_joint_with_its_pair():
    parents = np.array([-1, 0, 1, 1])
    joints = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]])  # bone b's joint with its parent
    new_parents, new_joints = rooted_at(parents, joints, 2)
    np.testing.assert_array_equal(new_parents, [1, 2, -1, 1])
    np.testing.assert_array_equal(new_joints[[0, 1, 3]], [[1, 0, 0], [2, 0, 0], [3, 0, 0]])


def _split_calf():
    """A body (0), a thigh (1), a calf split into front (2) and back (3) bones that share most of
    their skin, and a foot (4); the tree hangs both calves from the thigh and the foot from the back.
    Returns (parents, mass, pairs, contact)."""
    parents = np.array([-1, 0, 1, 1, 3])
    mass = np.array([60.0, 10.0, 5.0, 5.0, 5.0])
    pairs = np.array([[0, 1], [1, 2], [1, 3], [2, 3], [3, 4], [2, 4]])
    contact = np.array([50.0, 20.0, 20.0, 200.0, 30.0, 30.0])
    return parents, mass, pairs, contact


def test_a_limb_side_takes_the_bones_that_share_its_skin():
    parents, mass, pairs, contact = _split_calf()
    np.testing.assert_array_equal(limb_side(4, 3, 0, [], pairs, contact, 5), [4])  # the ankle turns the foot
    # the knee turns both calves and the foot: the tree hangs the front calf from the thigh, but
    # turning the back one alone would tear 200 units of shared skin
    np.testing.assert_array_equal(limb_side(3, 1, 0, [[4]], pairs, contact, 5), [2, 3, 4])
    np.testing.assert_array_equal(limb_side(1, 0, 0, [[2, 3, 4]], pairs, contact, 5), [1, 2, 3, 4])


def test_limb_chains_stop_where_the_limb_meets_the_body():
    """From the foot up: ankle, knee and hip (the leg, 25 of 85 units of skin, under a third); the
    body's own side is never a limb. With a smaller share the chain stops below the hip."""
    parents, mass, pairs, contact = _split_calf()
    bone, body, parent, sides = limb_chains(parents, mass, [4], pairs, contact)
    np.testing.assert_array_equal(bone, [1, 3, 4])  # parents first
    np.testing.assert_array_equal(body, [0, 1, 3])
    np.testing.assert_array_equal(parent, [-1, 0, 1])
    np.testing.assert_array_equal(sides.astype(int), [[0, 1, 1, 1, 1], [0, 0, 1, 1, 1], [0, 0, 0, 0, 1]])
    assert mass[sides[0]].sum() <= LIMB_SHARE * mass.sum()
    bone, _, _, _ = limb_chains(parents, mass, [4], pairs, contact, limb_share=0.2)
    np.testing.assert_array_equal(bone, [3, 4])


def test_joint_ranges_of_a_hinge():
    """A knee bending about x between 0 and 1.2 rad over the frames (and the thigh turning
    anyhow): its largest axis is x, its spread across it none, its range the bend's about the mean."""
    frames = 50
    rng = np.random.default_rng(3)
    thigh = rotation_exp(rng.normal(scale=0.5, size=(frames, 3)))
    bend = np.linspace(0.0, 1.2, frames)
    shin = thigh @ rotation_exp(np.outer(bend, [1.0, 0.0, 0.0]))
    ranges = joint_ranges(np.stack([thigh, shin], axis=1), np.array([0]), np.array([1]))
    axis = ranges.axes[0][:, 2]  # eigh: ascending, the largest spread last
    assert abs(abs(axis[0]) - 1.0) < 1e-9 and ranges.spread[0, :2].max() < 1e-9
    np.testing.assert_allclose(ranges.high[0, 2] - ranges.low[0, 2], 1.2, atol=1e-9)
    np.testing.assert_allclose(ranges.spread[0, 2], bend.std(), atol=1e-9)


@pytest.fixture(scope="module")
def walker_fit(tmp_path_factory):
    """The planted walker fitted with 10 bones (one per part) and its ground contacts."""
    from cli_helpers import assert_ok, cli
    from skinsynth.formats.graph_file import read_graph

    folder = tmp_path_factory.mktemp("limbs")
    assert_ok(cli("example", "walker", "--planted", "-o", folder / "w.npz"))
    assert_ok(cli("fit-skin", folder / "w.npz", "-o", folder / "s.h5", "--bones", 10, "--seed", 0))
    assert_ok(cli("build-graph", folder / "s.h5", "-o", folder / "g.h5"))
    return read_graph(str(folder / "g.h5"))


def test_the_walkers_limbs_are_its_legs(walker_fit):
    """Each sole's limb turns only bones that carry its own leg (below the hip, on its side) and takes
    the whole leg: foot, shin and thigh, under a third of the skin."""
    from skinsynth.pipeline.rig.influence import dense_weights

    skin, contacts = walker_fit.skin, walker_fit.contacts
    B = skin.rotations.shape[1]
    dense = dense_weights(skin.bone_indices, skin.bone_weights, B)
    rest = skin.rest_vertices
    patches = [np.asarray(contacts.vertices[contacts.offsets[p]:contacts.offsets[p + 1]]) for p in range(contacts.count)]
    anchors = [int(np.argmax(dense[p].mean(axis=0))) for p in patches]
    tree = skin_joint_tree(rest, skin.faces, skin.bone_indices, skin.bone_weights, skin.rotations, skin.translations)
    chains = plant_chains(tree, anchors, [rest[p].mean(axis=0) for p in patches], skin.rotations, rest,
                          skin.bone_indices, skin.bone_weights)
    height = float(np.ptp(rest[:, 1]))
    heaviest = skin.bone_indices[np.arange(rest.shape[0]), np.argmax(skin.bone_weights, axis=1)]
    for p, patch in enumerate(patches):
        side = np.sign(rest[patch, 0].mean())
        carried = np.isin(heaviest, chains.limb_bones[p])
        assert carried.any()
        assert (rest[carried, 1] < 0.6 * height).all() and (np.sign(rest[carried, 0]) == side).all()
        leg = (rest[:, 1] < 0.45 * height) & (np.sign(rest[:, 0]) == side)  # below the knee's height and more
        assert carried[leg].mean() > 0.95
        assert dense[:, chains.limb_bones[p]].sum() < LIMB_SHARE * dense.sum()
        k, depth = chains.patch_joint[p], 0
        while k >= 0:
            k, depth = chains.parent[k], depth + 1
        assert depth >= 2  # at least an ankle (or knee) and a hip
