"""The built-in walker (``pipeline.examples.walker``, ``skinsynth example walker``): an articulated
figure walking in place whose legs are bone components of their own, the test capture for
synthesis keeping the ground when merged components combine leg poses the clip never has."""

import h5py
import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from skinsynth.formats.meshseq import read_mesh_sequence
from skinsynth.pipeline.inputs.examples import WALKER_PARTS, _two_link, walker, walker_contacts

from cli_helpers import assert_ok, assert_user_error, cli

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


@pytest.fixture(scope="module", params=[False, True], ids=["on-the-spot", "planted"])
def chain(tmp_path_factory, request):
    """``skinsynth example walker`` (coarse: 24 frames of two cycles, rings 12, segments 6; on the
    spot, and ``--planted``), then ``fit-skin --bones 12 --seed 0`` and ``build-graph`` with their
    defaults. Returns (folder, planted)."""
    root = tmp_path_factory.mktemp("walker")
    planted = ("--planted",) if request.param else ()
    assert_ok(cli("example", "walker", "-o", root / "w.npz", "--frames", 24, "--rings", 12, "--segments", 6, *planted,
                  "-q"))
    assert_ok(cli("fit-skin", root / "w.npz", "-o", root / "skin.h5", "--bones", 12, "--seed", 0, "-q"))
    assert_ok(cli("build-graph", root / "skin.h5", "-o", root / "graph.h5", "-q"))
    return root, request.param


def test_the_cli_writes_the_walker(chain):
    chain, planted = chain
    sequence = read_mesh_sequence(str(chain / "w.npz"))
    vertices, faces = walker(frames=24, cycles=2, rings=12, segments=6, planted=planted)
    assert np.array_equal(sequence.vertices, vertices) and np.array_equal(sequence.faces, faces)


def test_each_leg_is_a_bone_component_of_its_own(chain):
    chain, _ = chain
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


# The planted walker (``walker(planted=True)``, ``example walker --planted``): it walks forward and
# each stance foot stays exactly still on the ground; ``walker_contacts`` is its closed-form truth.

FEET = ("foot_l", "foot_r")


def foot_slide(vertices, band=0.01):
    """The issue's slide (issue 35): contact vertices are those within ``band`` of the height above
    the ground (y = 0) in two consecutive frames; their horizontal motion per frame over the height.
    Returns (median, 95th percentile, number of contact samples)."""
    height = np.ptp(vertices[0, :, 1])
    near = vertices[..., 1] <= band * height
    both = near[1:] & near[:-1]
    step = np.linalg.norm(np.diff(vertices[..., [0, 2]], axis=0), axis=2) / height
    return float(np.median(step[both])), float(np.percentile(step[both], 95)), int(both.sum())


@pytest.mark.parametrize("kw", [dict(), dict(frames=40, cycles=1, **SMALL), dict(frames=60, cycles=3, start=0.37, **SMALL)])
def test_planted_feet_stay_exactly_still_on_the_ground_in_every_stance(kw):
    vertices, faces = walker(planted=True, **kw)
    contacts = walker_contacts(**{k: kw[k] for k in ("frames", "cycles", "start") if k in kw})
    labels = tube_labels(faces, vertices.shape[1])
    height = np.ptp(vertices[0, :, 1])
    assert 1.5 < height < 1.9
    assert np.abs(vertices[..., 1].min(axis=1)).max() <= 1e-9 * height  # a foot on y = 0 in every frame
    for foot, name in enumerate(FEET):
        part = vertices[:, labels == TUBES.index(name)]
        sole = part[0, :, 1] - part[0, :, 1].min() <= 0.01 * height  # the foot's contact vertices (it is level)
        assert sole.sum() >= 2 * (kw.get("segments", 10) // 5)
        for who, first, last, anchor in contacts.stances:
            if who != foot:
                continue
            plant = part[first:last + 1]
            assert np.abs(plant[:, sole, 1].min(axis=1)).max() <= 1e-6 * height  # on the ground
            assert (plant[..., 1] >= -1e-6 * height).all()  # never through it
            if last > first:  # the contact vertices still (the heel's top follows its shin's weak tie)
                assert np.linalg.norm(np.diff(plant[:, sole], axis=0), axis=2).max() <= 1e-6 * height
            # The anchor is the ground point under the ankle: the sole's middle lies on it (in x, z).
            assert np.allclose(plant[0, sole][:, [0, 2]].mean(axis=0)[0], anchor[0], atol=0.03)
            assert anchor[1] == 0.0 and np.isclose(anchor[0], contacts.ankles[first, foot, 0])
        swing = ~contacts.planted[:, foot]
        assert (part[swing, :, 1].min(axis=1) > 1e-3 * height).all()  # swing feet clear the ground
        assert part[swing, :, 1].min(axis=1).max() > 0.05  # and high at mid-swing
    for tube in ("chest", "pelvis", "head", "leg_l", "leg_r", "arm_l", "arm_r"):
        assert lowest(vertices, labels, tube).min() > 0.03  # nothing else touches the ground


def test_planted_stances_are_the_analytic_intervals():
    # One cycle in 40 frames, stance 0.6: the left foot down at phases [0, 0.6] (frames 0–24), the
    # right half a cycle later (frames 20–40, so 0–4 and 20–39 in the clip).
    contacts = walker_contacts(frames=40, cycles=1)
    assert [(foot, first, last) for foot, first, last, _ in contacts.stances] == [(0, 0, 24), (1, 0, 4), (1, 20, 39)]
    assert contacts.planted[:, 0].sum() == 25 and contacts.planted[:, 1].sum() == 25
    assert contacts.planted.any(axis=1).all()  # always a foot down; both in double support
    assert np.flatnonzero(contacts.planted.all(axis=1)).tolist() == [0, 1, 2, 3, 4, 20, 21, 22, 23, 24]
    # Anchors: each foot's next stance one stride (travel) ahead, the right's midway between the left's.
    (_, _, _, left), (_, _, _, right0), (_, _, _, right1) = contacts.stances
    assert np.isclose(right1[2] - right0[2], contacts.travel)
    assert np.isclose(right1[2] - left[2], contacts.travel / 2)
    assert np.isclose(contacts.travel, 2 * contacts.reach / 0.6)
    assert 0.9 < contacts.travel < 1.2  # about a metre a cycle: a walk
    # The per-frame truth agrees with the intervals, and the ankle sits over its anchor.
    for foot, first, last, anchor in contacts.stances:
        assert np.all(contacts.anchors[first:last + 1, foot] == anchor)
        assert np.allclose(contacts.ankles[first:last + 1, foot], anchor + [0, 0.08, 0], atol=1e-12)
    assert np.isnan(contacts.anchors[~contacts.planted]).all()


def test_planted_swing_is_smooth_and_lands_on_the_next_anchor():
    contacts = walker_contacts(frames=400, cycles=1)  # finely sampled: velocities are differences
    ankles = contacts.ankles
    step = np.diff(ankles, axis=0)
    assert np.linalg.norm(step, axis=2).max() < 0.05  # continuous: no jump at lift-off or landing
    accel = np.linalg.norm(np.diff(step, axis=0), axis=2)
    assert accel.max() < 20 * np.median(accel[accel > 0])  # no velocity jump either
    for foot in range(2):
        lifted = ankles[~contacts.planted[:, foot], foot]
        assert (lifted[:, 1] > 0.08).all() and lifted[:, 1].max() > 0.15  # up to 12 cm of lift


def test_planted_gait_is_cyclic_up_to_its_travel():
    contacts = walker_contacts(frames=40, cycles=2)
    two, _ = walker(frames=40, cycles=2, planted=True, **SMALL)
    one, _ = walker(frames=20, cycles=1, planted=True, **SMALL)
    moved = np.array([0.0, 0.0, contacts.travel])
    assert np.allclose(two[20:], two[:20] + moved, atol=1e-9)  # the frame after one cycle is its first, moved
    assert np.allclose(one, two[:20], atol=1e-9)
    # Played in a loop (the travel taken off), the wrap is a step like any other.
    steps = np.linalg.norm(np.diff(np.concatenate([one, one[:1] + moved]), axis=0), axis=2).max(axis=1)
    assert steps[-1] <= 1.2 * steps[:-1].max() and steps.min() > 0.0
    # The body travels at a steady speed: the mean z of the whole figure a frame (a stride a cycle).
    advance = np.diff(two[:, :, 2].mean(axis=1))
    assert np.isclose(advance.mean(), contacts.travel / 20, rtol=0.05) and advance.std() < 0.5 * advance.mean()


def test_planted_walker_is_the_same_figure_and_its_legs_stay_in_reach():
    planted, faces = walker(planted=True, **SMALL, frames=24)
    on_spot, faces_on_spot = walker(**SMALL, frames=24)
    assert np.array_equal(faces, faces_on_spot) and planted.shape == on_spot.shape
    labels = tube_labels(faces, planted.shape[1])
    # Rigid tubes keep their shape: the head's edge lengths match the walker on the spot.
    head = labels == TUBES.index("head")
    for frame in (0, 7, 13):
        a = np.linalg.norm(planted[frame, head][:, None] - planted[frame, head][None], axis=2)
        b = np.linalg.norm(on_spot[0, head][:, None] - on_spot[0, head][None], axis=2)
        assert np.allclose(a, b, atol=1e-9)
    # The legs stay in reach (inverse kinematics refuses an ankle out of it) over a long walk.
    assert np.isfinite(walker(frames=240, cycles=10, planted=True, start=0.11, **SMALL)[0]).all()


def test_two_link_inverse_kinematics_is_exact():
    rng = np.random.default_rng(0)
    hip = rng.normal(size=(50, 3))
    direction = rng.normal(size=(50, 3)) * [0.3, 1.0, 0.3] - [0, 2, 0]
    ankle = hip + direction / np.linalg.norm(direction, axis=1, keepdims=True) * rng.uniform(0.2, 0.8, (50, 1))
    upper, lower = _two_link(hip, ankle, 0.42, 0.42)
    for rotation in (upper, lower):
        assert np.allclose(rotation @ np.swapaxes(rotation, 1, 2), np.eye(3), atol=1e-12)
        assert np.allclose(np.linalg.det(rotation), 1.0)
    knee = hip + upper @ [0.0, -0.42, 0.0]
    assert np.allclose(knee + lower @ [0.0, -0.42, 0.0], ankle, atol=1e-12)
    # The knee bends forward: ahead (+z) of the straight line from hip to ankle, at its height.
    along = (knee - hip)[:, 1] / (ankle - hip)[:, 1]
    assert (knee[:, 2] > hip[:, 2] + along * (ankle - hip)[:, 2]).all()
    with pytest.raises(ValueError, match="reach"):
        _two_link(hip, hip + [0.0, -0.9, 0.0], 0.42, 0.42)


def test_the_planted_walker_does_not_slide_and_the_one_on_the_spot_does():
    # The measure at the defaults: before, the treadmill's stance foot slides 3.5 % of the
    # height a frame; planted, nothing moves (the swing foot only rises from and sets onto the ground).
    median, p95, samples = foot_slide(walker()[0])
    assert 0.02 < median < 0.06 and samples > 500
    median, p95, samples = foot_slide(walker(planted=True)[0])
    assert p95 <= 1e-9 and samples > 500


def test_the_cli_writes_the_planted_walker(tmp_path):
    assert_ok(cli("example", "walker", "-o", tmp_path / "w.npz", "--frames", 12, "--rings", 8, "--segments", 6,
                  "--planted", "-q"))
    sequence = read_mesh_sequence(str(tmp_path / "w.npz"))
    vertices, faces = walker(frames=12, cycles=2, planted=True, **SMALL)
    assert np.array_equal(sequence.vertices, vertices) and np.array_equal(sequence.faces, faces)
    assert_user_error(cli("example", "bending-bar", "-o", tmp_path / "b.npz", "--planted"), "--planted",
                      folder=tmp_path, keep=["w.npz"])
