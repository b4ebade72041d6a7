"""The built-in walker (``pipeline.examples.walker``, ``skinsynth example walker``): an articulated
figure walking in place whose legs are bone components of their own, the test capture for
synthesis keeping the ground when merged components combine leg poses the clip never has."""

import h5py
import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from skinsynth.formats.meshseq import read_mesh_sequence
from skinsynth.pipeline.examples import WALKER_PARTS, walker

from cli_helpers import assert_ok, cli

#: The walker's tubes in mesh order (its docstring): connected pieces of the mesh, in order.
TUBES = ("chest", "pelvis", "head", "leg_l", "foot_l", "arm_l", "leg_r", "foot_r", "arm_r")
SMALL = dict(rings=8, segments=6)  # coarse tubes: the shapes are what the tests look at


def tube_labels(faces, count):
    """(V,) index into TUBES of each vertex: the connected pieces of the mesh, numbered by their
    first vertex, i.e. in the order the walker concatenates its tubes."""
    adjacency = coo_matrix((np.ones(faces.size), (faces.ravel(), np.roll(faces, 1, axis=1).ravel())),
                           shape=(count, count))
    pieces, labels = connected_components(adjacency, directed=False)
    assert pieces == len(TUBES)
    return labels


def lowest(vertices, labels, tube):
    """(F,) the lowest height of one tube per frame."""
    return vertices[:, labels == TUBES.index(tube), 1].min(axis=1)


def test_shapes_types_and_a_closed_mesh_of_nine_tubes():
    vertices, faces = walker(frames=12, **SMALL)
    assert vertices.dtype == np.float64 and faces.dtype == np.int64
    assert vertices.ndim == 3 and vertices.shape[0] == 12 and vertices.shape[2] == 3
    assert faces.ndim == 2 and faces.shape[1] == 3
    assert np.isfinite(vertices).all()
    count = vertices.shape[1]
    assert faces.min() == 0 and faces.max() == count - 1 and np.unique(faces).size == count  # every vertex used
    labels = tube_labels(faces, count)
    # Closed tubes: every edge is shared by exactly two faces, once in each direction.
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    assert np.unique(edges, axis=0).shape[0] == edges.shape[0]
    assert {tuple(e) for e in edges.tolist()} == {tuple(e) for e in edges[:, ::-1].tolist()}
    # The default size: 1,248 vertices, two cycles in 48 frames.
    full, full_faces = walker()
    assert full.shape == (48, 1248, 3) and full_faces.shape[1] == 3
    assert np.bincount(labels).min() >= 4 * SMALL["segments"]
    assert len(WALKER_PARTS) == 10


def test_deterministic():
    a, fa = walker(frames=10, **SMALL)
    b, fb = walker(frames=10, **SMALL)
    assert np.array_equal(a, b) and np.array_equal(fa, fb)


def test_the_stance_foot_stays_on_the_ground_while_the_other_swings():
    # One cycle in 40 frames: frame 12 is mid-stance of the left leg (right mid-swing), frame 32
    # of the right (left mid-swing); the left heel strikes at frame 0, the right at frame 20.
    vertices, faces = walker(frames=40, cycles=1, **SMALL)
    labels = tube_labels(faces, vertices.shape[1])
    y = vertices[..., 1]
    height = np.ptp(y[0])
    assert 1.6 < height < 1.9  # about 1.75 m tall, Y up
    floor = y.min(axis=1)
    assert np.abs(floor).max() <= 1e-9 * height  # the lowest point on y = 0 in every frame
    left, right = lowest(vertices, labels, "foot_l"), lowest(vertices, labels, "foot_r")
    # The lowest point is always a foot: one is planted, within 1 mm of the ground.
    assert np.all(np.minimum(left, right) <= 1e-3)
    assert left[12] <= 1e-3 and right[12] > 0.1  # left stance: the right foot high in its swing
    assert right[32] <= 1e-3 and left[32] > 0.1
    for foot in (left, right):
        assert np.mean(foot <= 1e-3) >= 0.5  # on the ground for most of the cycle (stance ~60 %)
        assert np.mean(foot > 0.05) >= 0.15  # and clearly off it in swing
    for tube in ("chest", "pelvis", "head", "leg_l", "leg_r", "arm_l", "arm_r"):
        assert lowest(vertices, labels, tube).min() > 0.03  # nothing else touches the ground


def test_the_pelvis_bobs_lowest_at_double_support_highest_at_mid_stance():
    vertices, faces = walker(frames=40, cycles=1, **SMALL)
    labels = tube_labels(faces, vertices.shape[1])
    pelvis = lowest(vertices, labels, "pelvis")  # the pelvis tube's bottom, rigid with the pelvis
    for half in (slice(0, 20), slice(20, 40)):  # a step of each leg, from its heel strike
        step = pelvis[half]
        assert np.argmax(step) in range(10, 15)  # mid-stance, 0.3 of the cycle (12 frames) on
        assert np.argmin(step) in range(0, 4)  # double support, the first 0.1 of the cycle
    assert 0.03 < np.ptp(pelvis) < 0.08  # a bob of a few centimetres


def test_legs_swing_in_antiphase_and_the_arms_against_them():
    vertices, faces = walker(frames=40, cycles=1, **SMALL)
    labels = tube_labels(faces, vertices.shape[1])
    z = vertices[..., 2]

    def ahead(tube):  # mean forward (+z) position of a tube per frame
        return z[:, labels == TUBES.index(tube)].mean(axis=1)

    legs = ahead("foot_l") - ahead("foot_r")
    arms = ahead("arm_l") - ahead("arm_r")
    assert legs[0] > 0.3 and legs[20] < -0.3  # the leading foot at each heel strike
    assert np.corrcoef(legs, arms)[0, 1] < -0.9  # each arm swings back as its leg goes forward
    # The two legs are the same motion half a cycle apart, mirrored in x.
    mirrored = vertices[:, labels == TUBES.index("leg_r")] * np.array([-1.0, 1.0, 1.0])
    assert np.allclose(np.roll(mirrored, 20, axis=0).mean(axis=1),
                       vertices[:, labels == TUBES.index("leg_l")].mean(axis=1), atol=0.02)


def test_whole_cycles_loop():
    two, _ = walker(frames=40, cycles=2, **SMALL)
    one, _ = walker(frames=20, cycles=1, **SMALL)
    assert np.allclose(two[:20], two[20:], atol=1e-9)  # frame 0 ≈ the frame one cycle later
    assert np.allclose(one, two[:20], atol=1e-9)
    # Played in a loop, the wrap from the last frame to the first is a step like any other.
    steps = np.linalg.norm(np.diff(np.concatenate([one, one[:1]]), axis=0), axis=2).max(axis=1)
    assert steps[-1] <= 1.2 * steps[:-1].max()
    assert steps.min() > 0.0


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    """``skinsynth example walker`` (coarse: 24 frames of two cycles, rings 12, segments 6), then
    ``fit-skin --bones 12 --seed 0`` and ``build-graph`` with their defaults."""
    root = tmp_path_factory.mktemp("walker")
    assert_ok(cli("example", "walker", "-o", root / "w.npz", "--frames", 24, "--rings", 12, "--segments", 6, "-q"))
    assert_ok(cli("fit-skin", root / "w.npz", "-o", root / "skin.h5", "--bones", 12, "--seed", 0, "-q"))
    assert_ok(cli("build-graph", root / "skin.h5", "-o", root / "graph.h5", "-q"))
    return root


def test_the_cli_writes_the_walker(chain):
    sequence = read_mesh_sequence(str(chain / "w.npz"))
    vertices, faces = walker(frames=24, cycles=2, rings=12, segments=6)
    assert np.array_equal(sequence.vertices, vertices) and np.array_equal(sequence.faces, faces)


def test_each_leg_is_a_bone_component_of_its_own(chain):
    sequence = read_mesh_sequence(str(chain / "w.npz"))
    labels = tube_labels(sequence.faces, sequence.vertices.shape[1])
    with h5py.File(chain / "graph.h5") as f:
        graph = f["graph"]
        count = int(graph.attrs["components"])
        components = [set(graph[f"component_{k:03d}"]["bones"][()].tolist()) for k in range(count)]
        transitions = [len(graph[f"component_{k:03d}"]["transitions"][()]) for k in range(count)]
        cut_nodes = set(graph["cut_nodes"][()].tolist())
        indices, weights = f["skin/bone_indices"][()], f["skin/bone_weights"][()]
        rest = f["mesh/rest_vertices"][()]
    assert count >= 3 and len(components) == count and all(n > 0 for n in transitions)

    def bones_of(mask):
        """The bones that carry most (> 1/2) of the weight of some vertex in ``mask``."""
        return set(indices[mask][weights[mask] > 0.5].tolist())

    lower = rest[:, 1] < np.median(rest[labels == TUBES.index("leg_l"), 1])  # shins and feet
    shin_foot = {side: bones_of(((labels == TUBES.index(f"leg_{side}")) & lower)
                                | (labels == TUBES.index(f"foot_{side}"))) for side in "lr"}
    upper_body = bones_of(np.isin(labels, [TUBES.index(t) for t in ("chest", "head", "arm_l", "arm_r")]))
    assert shin_foot["l"] and shin_foot["r"] and not shin_foot["l"] & shin_foot["r"]
    legs = []
    for side, other in (("l", "r"), ("r", "l")):
        # One component holds the whole shin and foot, and nothing of the other leg or the upper body.
        owners = [k for k, bones in enumerate(components) if shin_foot[side] <= bones]
        assert len(owners) == 1, (side, components)
        leg = components[owners[0]]
        assert not leg & shin_foot[other] and not leg & upper_body, (side, components)
        assert leg & cut_nodes  # hung from the rest of the rig through a cut node, not a piece apart
        legs.append(owners[0])
    assert legs[0] != legs[1]
