"""Feet that stay planted (issue 35, part 3: :mod:`skinsynth.pipeline.synthesis.contact.planting`).

The planted walker (``walker(planted=True)``: its feet truly rest, level and still, on y = 0 during
stance; :func:`~skinsynth.pipeline.inputs.examples.walker_contacts` is the closed-form truth) is fitted and
analysed once per module; its syntheses are checked on the skinned vertices of each contact patch,
never on the module's own linear centroids. The small functions are checked by hand.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from skinsynth.formats.graph_file import read_graph
from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.inputs.clips import Clips
from skinsynth.pipeline.inputs.examples import walker_contacts
from skinsynth.pipeline.synthesis import Request, keep_input_plants, synthesis_components
from skinsynth.pipeline.synthesis.contact.planting import (KEEP_USABLE, agreeing_transitions, output_states, plant_feet,
                                                   plant_targets, reach_targets, mark_contact_jumps, contact_transitions)
from skinsynth.pipeline.synthesis.contact.planting_loops import blend_edges_row

from planting_reference import _blend_edges, _shifted, plant_targets_reference
from skinsynth.pipeline.synthesis.synthesis import synthesize

UP = 1


# ---------------------------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def walker_graph(tmp_path_factory):
    """The planted walker fitted (20 bones) and analysed (the default graph: several components),
    with what the checks need: H (the rest pose's extent along Y), the patches' vertex ids, the
    input fit's skinned patch centroids (Fi, P, 3) and the truly planted frames (Fi, P) of each
    patch's foot (walker_contacts)."""
    from cli_helpers import assert_ok, cli

    folder = tmp_path_factory.mktemp("planting")
    assert_ok(cli("example", "walker", "--planted", "-o", folder / "w.npz"))
    # The default fit (contact-weighted), seed 0. Its graph's single-component walks put a seam
    # inside a stance between a foot set down and one lifting within the contact band; the plants
    # held it to 0.03 % of the height once their height targets were spliced as the motion is
    # (planting.target_heights), 0.8 % before (the target dropped in a frame, and the joints,
    # bounded in acceleration, dragged the foot), which is why this fixture fitted --no-contacts.
    assert_ok(cli("fit-skin", folder / "w.npz", "-o", folder / "s.h5", "--bones", 20, "--seed", 0))
    assert_ok(cli("build-graph", folder / "s.h5", "-o", folder / "g.h5"))
    graph = read_graph(str(folder / "g.h5"))
    skin, contacts = graph.skin, graph.contacts
    assert len(graph.components) > 1 and contacts.count == 2  # the default graph: several components, two soles
    patches = [np.asarray(contacts.vertices[contacts.offsets[p]:contacts.offsets[p + 1]]) for p in
               range(contacts.count)]
    H = float(np.ptp(skin.rest_vertices[:, UP]))
    fitted = lbs_reference(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations.astype(float),
                           skin.translations.astype(float))
    centroids = np.stack([fitted[:, p].mean(axis=1) for p in patches], axis=1)  # (Fi, P, 3)
    truth = walker_contacts()
    frames = skin.rotations.shape[0]
    assert truth.planted.shape[0] == frames
    feet = [int(np.argmax([(truth.planted[:, f] == np.asarray(contacts.planted)[:, p]).mean() for f in range(2)]))
            for p in range(contacts.count)]
    assert sorted(feet) == [0, 1]  # one patch per foot
    return SimpleNamespace(graph=graph, skin=skin, contacts=contacts, patches=patches, H=H, centroids=centroids,
                           truly=truth.planted[:, feet], min_segment=int(graph.options.get("min_segment", 12)))


_SETUPS = {}


def _setup(w, single):
    """(components, plant rig) of the walker's synthesis, made once per mode."""
    key = (id(w), single)
    if key not in _SETUPS:
        components = synthesis_components(w.skin, w.graph.components, single, None, None, contacts=w.contacts)
        req = Request(count=1, frames=10, min_segment=w.min_segment)
        keep_input_plants(req, w.skin, w.contacts, components)
        _SETUPS[key] = (components, req.plants)
    return _SETUPS[key]


def _synthesize(w, single, seed, plants=True, count=8, frames=600):
    """A synthesis of the walker with its plants kept (plants=True) or with neither plants nor
    the support kept (the uncorrected bones). Returns (Synthesis, rig)."""
    components, rig = _setup(w, single)
    req = Request(count=count, frames=frames, seed=seed, min_segment=w.min_segment)
    if plants:
        req.plants = rig
    else:
        req.contact = False
    s = w.skin
    return synthesize(components, s.rotations, s.translations, s.rest_vertices, s.bone_indices, s.bone_weights,
                      req), rig


def _unlimited(rig):
    """The plant rig with its acceleration limits off (edge and turn limits infinite: every plant
    held exactly, every spring at the default rate, :data:`.planting.EDGE_ACCEL`)."""
    import dataclasses

    return dataclasses.replace(rig, edge_limit=np.inf, turn_limit=np.full_like(rig.turn_limit, np.inf))


def _patch_centroids(w, F, t):
    """(M, P, 3) skinned centroids of the patches for one animation's bones F (M, B, 3, 3), t (M, B, 3)."""
    s = w.skin
    return np.stack([lbs_reference(s.rest_vertices[p], s.bone_indices[p], s.bone_weights[p], F.astype(float),
                                   t.astype(float)).mean(axis=1) for p in w.patches], axis=1)


def _patch_lowest(w, F, t):
    """(M, P) the lowest skinned vertex of each patch for one animation's bones."""
    s = w.skin
    return np.stack([lbs_reference(s.rest_vertices[p], s.bone_indices[p], s.bone_weights[p], F.astype(float),
                                   t.astype(float))[..., UP].min(axis=1) for p in w.patches], axis=1)


def _runs(mask):
    """[(first, stop)] of the runs of True in a 1-D bool array."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], np.asarray(mask, np.int8), [0]])))
    return list(zip(edges[::2], edges[1::2]))


def _horizontal_drift(points):
    """Largest horizontal distance of points (n, 3) from the first."""
    d = points - points[0]
    d[:, UP] = 0.0
    return float(np.linalg.norm(d, axis=1).max())


def _input_plant_drift(w):
    """The input's own largest horizontal drift of a patch over one of its (detected) plants."""
    planted = np.asarray(w.contacts.planted, bool)
    return max(_horizontal_drift(w.centroids[b:e, p]) for p in range(planted.shape[1]) for b, e in
               _runs(planted[:, p]))


# ---------------------------------------------------------------------------------------------- 1. plants hold


def test_plants_hold_on_the_planted_walker(walker_graph):
    """plant_feet on the walks of a single-component synthesis (its bones before the plants): each
    stance foot stands still, to rounding, and at the input's height (within a seam's blend window
    at the input's heights as the splice blends them, :func:`.planting.target_heights`), to a
    tenth of a percent of the height."""
    from skinsynth.pipeline.synthesis.contact.planting import target_heights
    from skinsynth.pipeline.synthesis.splicing import seam_windows

    w = walker_graph
    r, rig = _synthesize(w, True, seed=0, plants=False)
    aim = target_heights(rig, np.moveaxis(r.sources[rig.owner], 0, 1), r.sources[0])  # (A, P, M)
    states = plant_feet(r.F, r.t, r.sources, rig)  # (A, P, M); F and t corrected in place
    np.testing.assert_array_equal(states, output_states(r.sources, rig))
    assert states.shape == (8, 2, 600)
    assert 0.3 < states.mean() < 0.95  # feet are planted much of the time, not always
    ground = float(np.asarray(w.contacts.ground)[0])
    in_drift = _input_plant_drift(w)  # the detected plants include touch-down and lift-off frames (~1e-3 H)
    plants = stance_runs = 0
    worst_stance = worst_plant = worst_height = worst_height_rig = 0.0
    for a in range(r.F.shape[0]):
        c = _patch_centroids(w, r.F[a], r.t[a])  # (M, P, 3)
        low = _patch_lowest(w, r.F[a], r.t[a])  # (M, P)
        for p in range(2):
            src = r.sources[rig.owner[p], a]
            windows = seam_windows(src[None], rig.window)
            blended = np.zeros(src.size, bool)  # the frames a seam's blend moves
            for left, right in zip(windows.left, windows.right):
                blended[left + 1:right] = True
            for b, e in _runs(states[a, p]):
                plants += 1
                worst_plant = max(worst_plant, _horizontal_drift(c[b:e, p]))
                # the height: the patch's lowest vertex where the input's was at the source frames
                # (the input frames themselves, above its ground, placed on the output's: one clip, the same)
                target = w.skin.examples[src[b:e]][:, w.patches[p], UP].min(axis=1) - ground + float(rig.ground[0])
                away = ~blended[b:e]
                if away.any():
                    worst_height = max(worst_height, float(np.abs(low[b:e, p] - target)[away].max()))
                worst_height_rig = max(worst_height_rig, float(np.abs(low[b:e, p] - aim[a, p, b:e]).max()))
            # where the source frame is a true stance frame (walker_contacts) the foot stands still
            for b, e in _runs(states[a, p] & w.truly[src, p]):
                stance_runs += 1
                worst_stance = max(worst_stance, _horizontal_drift(c[b:e, p]))
    assert plants > 100 and stance_runs > 100
    H = w.H
    assert worst_stance < 1e-3 * H, worst_stance / H  # measured ~1e-6 H
    assert worst_plant < in_drift + 1e-3 * H, (worst_plant / H, in_drift / H)
    # measured 1.0e-3 H: where a seam's blend window ends, the joints (bounded in acceleration)
    # follow the spliced heights' kink a frame late
    assert worst_height < 2.5e-3 * H, worst_height / H
    assert worst_height_rig < 2.5e-3 * H, worst_height_rig / H


def test_plants_hold_the_merged_walker_as_far_as_its_legs_reach(walker_graph):
    """The planted walker cut into six components: its merge drags a stance foot 0.65 of the height
    at the median over a stance (legs of one frame on a body of another). Its limbs turn at their
    joints and within their ranges to hold it, and hold what they can reach: measured 0.21 H at the
    median (0.02 H with the acceleration limits off), the rest slides rather than the body tearing
    (test_large_corrections_keep_every_joint_and_the_shape)."""
    w = walker_graph
    r, rig = _synthesize(w, False, seed=0, plants=False)
    F, t = r.F.copy(), r.t.copy()
    states = plant_feet(F, t, r.sources, rig)
    corrected, uncorrected = [], []
    for a in range(F.shape[0]):
        c, c0 = _patch_centroids(w, F[a], t[a]), _patch_centroids(w, r.F[a], r.t[a])
        for p in range(2):
            for b, e in _runs(states[a, p] & w.truly[r.sources[rig.owner[p], a], p]):
                corrected.append(_horizontal_drift(c[b:e, p]))
                uncorrected.append(_horizontal_drift(c0[b:e, p]))
    assert np.median(uncorrected) > 0.4 * w.H
    assert np.median(corrected) < 0.5 * np.median(uncorrected), (np.median(corrected) / w.H, np.median(uncorrected) / w.H)


def test_large_corrections_keep_every_joint_and_the_shape(walker_graph):
    """Issue 62 on the walker cut into six components, whose merge asks its plants for the largest
    corrections (a stance foot dragged 0.65 of the height): every bone a plant moves is moved
    rigidly, all the bones hung below one joint by the same motion (so their lengths and the skin
    between them are kept), every limb joint's two bones carry its point as far apart as before (to
    1e-6 of the height: the joints hold), and the body keeps its shape against the capture
    (:mod:`skinsynth.pipeline.mesh.shape`: no broken frame, no frame past 2 % of its edges)."""
    from skinsynth.gpu import lbs
    from skinsynth.pipeline.synthesis.skinned import capture_envelope

    w = walker_graph
    r, rig = _synthesize(w, False, seed=1, plants=False, count=6, frames=300)
    F, t = r.F.copy(), r.t.copy()
    plant_feet(F, t, r.sources, rig)
    H, chains = w.H, rig.chains
    F0, t0, F1, t1 = (np.asarray(x, dtype=np.float64) for x in (r.F, r.t, F, t))
    motion = F1 @ np.linalg.inv(F0)  # each bone's map x ↦ motion x + shift, frame by frame
    shift = t1 - np.einsum("amkij,amkj->amki", motion, t0)
    np.testing.assert_allclose(motion @ np.swapaxes(motion, -1, -2), np.broadcast_to(np.eye(3), motion.shape), atol=1e-5)
    for k in range(chains.joints):
        group = np.flatnonzero(chains.bone_joint == k)
        assert group.size and np.abs(motion[:, :, group] - motion[:, :, group[:1]]).max() < 1e-5
        assert np.abs(shift[:, :, group] - shift[:, :, group[:1]]).max() < 1e-5 * H

        def gap(F_, t_):  # (A, M) how far apart the joint's two bones carry its point
            body, bone, point = chains.body[k], chains.bone[k], chains.point[k]
            return np.linalg.norm(F_[:, :, body] @ point + t_[:, :, body] - F_[:, :, bone] @ point - t_[:, :, bone],
                                  axis=-1)

        np.testing.assert_allclose(gap(F1, t1), gap(F0, t0), atol=1e-6 * H)
    assert np.abs(t1 - t0).max() > 0.05 * H  # large corrections were made
    envelope = capture_envelope(w.skin, lambda *bones: lbs(*bones, device="cpu"))
    s = w.skin
    shares = np.concatenate([envelope.beyond_share(lbs(s.rest_vertices, s.bone_indices, s.bone_weights, F[a], t[a],
                                                       device="cpu")) for a in range(F.shape[0])])
    assert (shares > envelope.broken_share).mean() == 0.0 and shares.max() < 0.02, shares.max()


def test_without_plants_the_merged_feet_slide(walker_graph):
    """What test_plants_hold checks is no given: the multi-component merge left alone slides the
    planted feet by far more than its bound (measured ~0.9 H)."""
    w = walker_graph
    r, rig = _synthesize(w, False, seed=0, plants=False, count=4)
    states = output_states(r.sources, rig)
    worst = 0.0
    for a in range(r.F.shape[0]):
        c = _patch_centroids(w, r.F[a], r.t[a])
        for p in range(2):
            src = r.sources[rig.owner[p], a]
            for b, e in _runs(states[a, p] & w.truly[src, p]):
                worst = max(worst, _horizontal_drift(c[b:e, p]))
    assert worst > 0.05 * w.H, worst / w.H


# ---------------------------------------------------------------------------------------------- 2. no transition


@pytest.mark.parametrize("single", [False, True], ids=["components", "single-component"])
@pytest.mark.parametrize("start,frames", [(0, 48), (5, 30), (20, 25)])
def test_input_played_straight_is_left_alone(walker_graph, single, start, frames):
    w = walker_graph
    components, rig = _setup(w, single)
    C = len(components)
    assert (C > 1) != single
    F = w.skin.rotations[None, start:start + frames].astype(np.float32)
    t0 = w.skin.translations[None, start:start + frames].astype(np.float32)
    t = t0.copy()
    sources = np.broadcast_to(np.arange(start, start + frames), (C, 1, frames)).copy()
    states = plant_feet(F, t, sources, rig)
    planted = np.asarray(w.contacts.planted, bool)[start:start + frames].T  # (P, n)
    assert planted.any()
    np.testing.assert_array_equal(states[0], planted)
    assert np.abs(t.astype(np.float64) - t0).max() <= 1e-4 * w.H  # the limbs reach targets of 4e-6 H to 2e-5 H


# ---------------------------------------------------------------------------------------------- 3. plant edges


def _edge_jumps(w, single, seeds, count=8, frames=600, plant=plant_feet):
    """The largest change of the correction's per-frame velocity (skinned patch centroid, corrected
    minus uncorrected) at any plant's first or last frame, over ``seeds``; the correction made by
    plant_feet on a copy of the uncorrected bones. Also checks, single-component (where the walks
    with and without plants are the same), that synthesize's own corrected bones are those."""
    worst = 0.0
    for seed in seeds:
        r, rig = _synthesize(w, single, seed, plants=False, count=count, frames=frames)
        F, t = r.F.copy(), r.t.copy()  # plant_feet turns the feet (F) and moves them (t) in place
        states = plant(F, t, r.sources, rig)
        np.testing.assert_array_equal(states, output_states(r.sources, rig))
        if single:
            planted, _ = _synthesize(w, single, seed, plants=True, count=count, frames=frames)
            np.testing.assert_array_equal(planted.sources, r.sources)
            assert np.abs(planted.t - t).max() <= 1e-6 * w.H
            assert np.abs(planted.F - F).max() <= 1e-6
        for a in range(count):
            correction = _patch_centroids(w, F[a], t[a]) - _patch_centroids(w, r.F[a], r.t[a])  # (M, P, 3)
            jump = np.zeros((frames, 2))
            jump[1:-1] = np.linalg.norm(np.diff(correction, 2, axis=0), axis=-1)
            for p in range(2):
                for b, e in _runs(states[a, p]):
                    edges = [m for m in (b, e - 1) if 0 < m < frames - 1]
                    if edges:
                        worst = max(worst, float(jump[edges, p].max()))
    return worst


def _planted_by_reference(F, t, sources, rig):
    """:func:`plant_feet` with the numpy reference's targets (planting_reference), made by the
    limbs (:func:`reach_targets`); returns the planted states."""
    targets = plant_targets_reference(F, t, sources, rig)
    reach_targets(F, t, targets, rig)
    return targets.states


def _input_acceleration(w):
    return float(np.linalg.norm(np.diff(w.skin.examples, 2, axis=0), axis=-1).max())


def test_no_velocity_jump_at_plant_edges_single_component(walker_graph):
    w = walker_graph
    worst = _edge_jumps(w, True, seeds=(0, 1, 2))
    assert worst <= _input_acceleration(w), worst / _input_acceleration(w)  # measured 3e-5 of it


def test_no_velocity_jump_at_plant_edges_components(walker_graph):
    """The walker cut into six components: the merge moves its feet up to 0.26 H a frame before
    any planting, and the feet's turn (smoothed over seams) is not matched step for step at the
    edges, so the edge jumps reach about 1.03x the input's largest acceleration (seeds 0-2), not
    the issue's 1.0x: bounded here at 1.5x (issue 35 keeps this open; 5x without the blend)."""
    w = walker_graph
    worst = _edge_jumps(w, False, seeds=(0, 1, 2))
    assert worst <= 1.5 * _input_acceleration(w), worst / _input_acceleration(w)


# ---------------------------------------------------------------------------------------------- 4. by hand


def _edge_masks(state):
    state = np.asarray(state, bool)[None, None]
    stepping = state & _shifted(state, 1, False)
    first = state & ~_shifted(state, 1, False)
    last = state & ~_shifted(state, -1, False)
    return state, stepping, first, last


def _one_plant(decay=0.3, M=40, b=12, e=22):
    """A (1, 1, M, 3) correction planted on frames b … e − 1 (values inside, zero outside)."""
    state = np.zeros(M, bool)
    state[b:e] = True
    rng = np.random.default_rng(3)
    inside = np.cumsum(rng.normal(size=(e - b, 3)), axis=0) + np.array([0.5, -1.0, 2.0])
    correction = np.zeros((1, 1, M, 3))
    correction[0, 0, b:e] = inside
    before = correction.copy()
    _blend_edges(correction, *_edge_masks(state), decay)
    return before, correction, b, e, decay


def _spring(x0, step, k, y):
    """The closed form of one edge's decay: x(0) = x0, x(1) − x(0) = step, then (x0 + c k) e^(−y k)."""
    c = (x0 + step) * np.exp(y) - x0
    return (x0 + c * k) * np.exp(-y * k)


def test_blend_edges_inside_unchanged_outside_closed_form():
    before, after, b, e, y = _one_plant()
    M = after.shape[2]
    x = before[0, 0]
    np.testing.assert_array_equal(after[0, 0, b:e], x[b:e])
    # forward from the last frame: x0 its value, its last step carried across the edge
    x0, v0 = x[e - 1], x[e - 1] - x[e - 2]
    k = np.arange(1, M - e + 1)[:, None]
    np.testing.assert_allclose(after[0, 0, e:], _spring(x0, v0, k, y), rtol=1e-12, atol=1e-12)
    # backward from the first frame, time reversed: the step from the second frame back to the first
    x0, v0 = x[b], x[b] - x[b + 1]
    k = np.arange(b, 0, -1)[:, None]
    np.testing.assert_allclose(after[0, 0, :b], _spring(x0, v0, k, y), rtol=1e-12, atol=1e-12)


def test_blend_edges_step_across_an_edge_is_the_last_step_inside():
    """Per frame, not only in continuous time: the first step out equals the last step in."""
    for y in (0.58, 0.2, 0.02):
        before, after, b, e, _ = _one_plant(decay=y, M=60, b=20, e=30)
        c = after[0, 0]
        np.testing.assert_allclose(c[e] - c[e - 1], c[e - 1] - c[e - 2], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(c[b - 1] - c[b], c[b] - c[b + 1], rtol=1e-9, atol=1e-12)


def test_blend_edges_gap_between_plants_meets_both():
    """Two plants with a short gap: the gap's curve leaves the first plant with its last step and
    reaches the second with its first step (the forward tail's leftover taken into account)."""
    M, y = 40, 0.58
    state = np.zeros((1, 1, M), bool)
    state[0, 0, 5:15] = state[0, 0, 21:35] = True
    rng = np.random.default_rng(3)
    values = np.cumsum(rng.normal(size=(1, 1, M, 3)), axis=2)
    correction = np.where(state[..., None], values, 0.0)
    stepping = state & _shifted(state, 1, False)
    first = state & ~_shifted(state, 1, False)
    last = state & ~_shifted(state, -1, False)
    _blend_edges(correction, state, stepping, first, last, y)
    c = correction[0, 0]
    np.testing.assert_allclose(c[20] - c[21], c[21] - c[22], rtol=1e-9, atol=1e-9)  # into the second plant
    np.testing.assert_array_equal(c[21:35], values[0, 0, 21:35])


def test_blend_edges_decays_to_zero_and_is_continuous():
    before, after, b, e, y = _one_plant(decay=0.3, M=120, b=30, e=45)
    c = after[0, 0]
    x = before[0, 0]
    scale = np.abs(x[b:e]).max()
    assert np.abs(c[:3]).max() < 1e-2 * scale and np.abs(c[-3:]).max() < 1e-2 * scale  # decayed far out
    assert np.abs(c[-1]).max() < np.abs(c[e + 20]).max() < np.abs(c[e + 5]).max()
    # value: the first frame outside is where the edge's value and step lead, to O(y) of the step
    for edge, out, inner in ((e - 1, e, e - 2), (b, b - 1, b + 1)):
        x0, v0 = c[edge], c[edge] - c[inner]
        jump = np.linalg.norm((c[out] - c[edge]) - v0)  # change of the per-frame velocity across the edge
        hard = np.linalg.norm((0.0 - c[edge]) - v0)  # what zero outside (no blend) would give
        assert jump <= y * (np.linalg.norm(x0) + np.linalg.norm(v0)) + 1e-12
        assert jump < 0.5 * hard
        assert np.linalg.norm(c[out] - c[edge]) < 2 * np.linalg.norm(v0) + y * np.linalg.norm(x0)


def test_blend_edges_per_frame_step_matched_at_default_decay():
    from skinsynth.pipeline.synthesis.contact.planting import HALF_LIFE

    y = 2 * np.log(2) / (HALF_LIFE * 24)
    _, after, b, e, _ = _one_plant(decay=y)
    c = after[0, 0]
    for edge, out, inner in ((e - 1, e, e - 2), (b, b - 1, b + 1)):
        v0 = c[edge] - c[inner]
        assert np.linalg.norm((c[out] - c[edge]) - v0) <= 0.05 * np.linalg.norm(v0)


def test_agreeing_transitions_by_hand():
    planted = np.zeros((10, 2), bool)
    planted[:5, 0] = True  # patch 0: frames 0-4
    planted[3:8, 1] = True  # patch 1: frames 3-7
    clips = Clips.single(10)
    pairs = np.array([[3, 4],  # both agree (T, T) / (T, T)
                      [1, 2],  # (T, F) / (T, F)
                      [2, 3],  # patch 1: F at 2, T at 3
                      [5, 4],  # j identified with i: frame 4 vs 5 differ for patch 0
                      [9, 8],  # (F, F) / (F, F)
                      [9, -1],  # back to frame 0: patch 0 F at 9, T at 0
                      [2, -1],  # frame 2 vs frame 0: (T, F) both
                      [6, 7]])  # (F, T) both
    expected = [True, True, False, False, True, False, True, True]
    np.testing.assert_array_equal(agreeing_transitions(pairs, planted, clips), expected)
    # one patch alone
    np.testing.assert_array_equal(agreeing_transitions(pairs, planted[:, :1], clips),
                                  [True, True, True, False, True, False, True, True])
    # several clips: j = -2 continues at the second clip's first frame (5)
    two = Clips(("a", "b"), (5, 5))
    np.testing.assert_array_equal(agreeing_transitions([[4, -2], [6, -2], [0, -1]], planted[:, :1], two),
                                  [False, True, True])


def _component(bones, pairs):
    return SimpleNamespace(bones=list(bones), transitions=SimpleNamespace(
        pairs=np.asarray(pairs, np.int64).reshape(-1, 2), costs=np.arange(len(pairs), dtype=float)))


def _contacts(planted, patches):
    verts = np.concatenate(patches)
    offsets = np.concatenate([[0], np.cumsum([len(p) for p in patches])])
    return SimpleNamespace(planted=np.asarray(planted, bool), vertices=verts, offsets=offsets, count=len(patches))


def test_mark_contact_jumps_refuses_disagreeing_when_walks_remain():
    frames = 20
    planted = np.zeros((frames, 1), bool)
    planted[:12] = True
    planted[18:] = True
    # 6 vertices: 0-2 on bone 0 (the patch), 3-5 on bone 1
    idx = np.array([[0], [0], [0], [1], [1], [1]])
    w = np.ones((6, 1))
    contacts = _contacts(planted, [np.array([0, 1, 2])])
    owner = _component([0], [[19, -1], [15, -1]])  # 19 → 0 agrees (T, T); 15 → 0 does not (F, T)
    other = _component([1], [[15, -1], [5, 3]])  # owns no patch: left alone
    report = mark_contact_jumps([owner, other], contacts, idx, w)
    assert report == [(1, False), (0, False)]  # every frame still reaches the loop 19 → 0
    np.testing.assert_array_equal(owner.contact_agrees, [True, False])
    np.testing.assert_array_equal(owner.transitions.pairs, [[19, -1], [15, -1]])  # marked, not removed
    assert other.contact_agrees is None
    kept = contact_transitions(owner.transitions, owner.contact_agrees)
    np.testing.assert_array_equal(kept.pairs, [[19, -1]])
    np.testing.assert_array_equal(kept.costs, [0.0])
    assert contact_transitions(other.transitions, None) is other.transitions
    np.testing.assert_array_equal(other.transitions.pairs, [[15, -1], [5, 3]])


def test_mark_contact_jumps_keeps_all_when_too_few_frames_remain():
    frames = 20
    planted = np.zeros((frames, 1), bool)
    planted[:12] = True
    idx = np.array([[0], [0], [0], [1], [1], [1]])
    w = np.ones((6, 1))
    contacts = _contacts(planted, [np.array([0, 1, 2])])
    # 19 → 0 is the only loop: refusing it leaves no infinite walk (0 of 20 usable frames)
    lone = _component([0], [[19, -1]])
    # 4 → 0 loops over 5 frames, 19 → 0 (refused) over all 20: 5 < KEEP_USABLE × 20
    short = _component([0, 1], [[4, -1], [19, -1]])
    assert 5 < KEEP_USABLE * frames
    before = [c.transitions.pairs.copy() for c in (lone, short)]
    report = mark_contact_jumps([lone], contacts, idx, w)
    assert report == [(0, True)] and lone.contact_agrees is None
    np.testing.assert_array_equal(lone.transitions.pairs, before[0])
    report = mark_contact_jumps([short], contacts, idx, w)
    assert report == [(0, True)] and short.contact_agrees is None
    np.testing.assert_array_equal(short.transitions.pairs, before[1])


def test_output_states_by_hand():
    planted = np.array([[1, 0], [1, 1], [0, 1], [0, 0]], bool)  # (Fi = 4, P = 2)
    rig = SimpleNamespace(planted=planted, owner=np.array([1, 0]))  # patch 0 owned by component 1
    sources = np.array([[[0, 1, 2, 3], [3, 2, 1, 0]],  # component 0, animations 0 and 1
                        [[2, 2, 1, 0], [0, 3, 3, 1]]])  # component 1
    states = output_states(sources, rig)
    expected = np.array([[[0, 0, 1, 1],  # animation 0, patch 0: planted[[2, 2, 1, 0], 0]
                          [0, 1, 1, 0]],  # patch 1: planted[[0, 1, 2, 3], 1]
                         [[1, 0, 0, 1],  # animation 1, patch 0: planted[[0, 3, 3, 1], 0]
                          [0, 1, 1, 0]]], bool)  # patch 1: planted[[3, 2, 1, 0], 1]
    np.testing.assert_array_equal(states, expected)


# ---------------------------------------------------------------------------------------------- 5. compiled = numpy


@pytest.mark.parametrize("single,hold", [(False, None), (True, None), (False, 4)],
                         ids=["components", "single-component", "components-leaking"])
def test_compiled_loops_match_the_numpy_reference(walker_graph, single, hold):
    """plant_targets (numba, one animation at a time) against the numpy reference of the same steps
    on whole arrays, on uncorrected walker syntheses: states, centroids, turns, corrections, root. ``hold``: frames a plant
    is held exactly before what its limb correction sums beyond a bound leaks (the walker's stances
    are shorter than the default's 2 s: 4 frames, a bound of 0.2 % of the height, and gaps of up
    to 12 frames bridged, each let go over at least 5, make them leak and release)."""
    import dataclasses

    w = walker_graph
    r, rig = _synthesize(w, single, 5, plants=False, count=6, frames=300)
    if hold is not None:
        rig = dataclasses.replace(rig, hold=hold, bound=0.002 * w.H, bridge=12, release=5)
    targets = plant_targets(r.F, r.t, r.sources, rig)
    reference = plant_targets_reference(r.F, r.t, r.sources, rig)
    np.testing.assert_array_equal(targets.states, reference.states)
    for name in ("centre", "correction", "root"):
        assert np.abs(getattr(targets, name) - getattr(reference, name)).max() <= 1e-5 * w.H, name
    assert np.abs(targets.turn - reference.turn).max() <= 1e-5
    if not single:  # the merged walker's feet slide: it did correct something
        assert np.abs(targets.correction).max() > 1e-3 * w.H
    if hold is not None:  # bridged gaps were released, and the bound made a difference
        assert (targets.states & ~output_states(r.sources, rig)).any()
        free = plant_targets(r.F, r.t, r.sources, dataclasses.replace(rig, bound=np.inf))
        assert np.abs(free.correction - targets.correction).max() > 1e-4 * w.H


def test_compiled_blend_matches_the_numpy_reference():
    rng = np.random.default_rng(11)
    M = 90
    state = rng.random(M) < 0.6
    state[:3] = True  # a plant from the first frame, and one to the last
    state[-2:] = True
    values = np.where(state[:, None], np.cumsum(rng.normal(size=(M, 3)), axis=0), 0.0)
    expected = values[None, None].copy()
    _blend_edges(expected, *_edge_masks(state), 0.4)
    np.testing.assert_allclose(blend_edges_row(values.copy(), state, 0.4), expected[0, 0], rtol=1e-12, atol=1e-12)


def test_swinging_patches_are_asked_no_lower_than_the_input(walker_graph):
    """The floor: at every frame a patch swings (away from its plants by the taper's radius), the
    plants ask its lowest point no lower than the input patch's lowest at the source frame (its
    lowest, the root's vertical offset and its correction's); the six-component walker's merged
    legs sink the uncorrected feet 14 % of the height below it, so the check can fail. (What the
    limbs make of it within their ranges: test_large_corrections_keep_every_joint_and_the_shape.)"""
    from planting_reference import turned_lowest

    w = walker_graph
    r, rig = _synthesize(w, False, 7, plants=False, count=4, frames=400)
    rig = _unlimited(rig)  # a lift that would kick a foot is widened (the defaults)
    targets = plant_targets(r.F, r.t, r.sources, rig)
    low = turned_lowest(r.F, r.t, r.sources, rig)  # (A, P, M) the patches' lowest, the feet turned
    radius = rig.lift_radius
    worst_before, worst_asked = 0.0, 0.0
    for a in range(r.F.shape[0]):
        for p in range(rig.owner.size):
            src = r.sources[rig.owner[p], a]
            want = rig.heights_in[src, p] + rig.ground[0]
            planted = np.flatnonzero(targets.states[a, p])
            far = np.ones(r.F.shape[1], bool) if not planted.size else \
                np.abs(np.arange(r.F.shape[1])[:, None] - planted[None]).min(axis=1) >= radius
            asked = low[a, p] + targets.root[a, :, UP] + targets.correction[a, p, :, UP]
            worst_before = max(worst_before, float((want - low[a, p])[far].max()))
            worst_asked = max(worst_asked, float((want - asked)[far].max()))
    assert worst_asked <= 1e-4 * w.H
    assert worst_before >= 1e-2 * w.H  # measured 14 % of the height


def test_bridge_gaps_by_hand_and_against_the_reference():
    """A gap of at most ``longest`` frames between two plants is filled; a longer one, and the
    frames before the first plant or after the last, are not."""
    from planting_reference import _bridged

    from skinsynth.pipeline.synthesis.contact.planting_loops import bridge_gaps

    state = np.array([0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 0], bool)
    expected = np.array([0, 1, 1, 1, 1, 1, 0, 0, 0, 1, 0], bool)
    np.testing.assert_array_equal(bridge_gaps(state.copy(), 2), expected)
    np.testing.assert_array_equal(bridge_gaps(state.copy(), 0), state)
    rng = np.random.default_rng(4)
    states = rng.random((3, 2, 50)) < 0.6
    for longest in (0, 1, 3, 6):
        bridged = np.stack([[bridge_gaps(row.copy(), longest) for row in patch] for patch in states])
        np.testing.assert_array_equal(bridged, _bridged(states, longest))


def _largest_acceleration(w, F, t, every=2):
    """The largest vertex acceleration (second difference) of one animation's bones, over every
    ``every``-th vertex."""
    s = w.skin
    v = lbs_reference(s.rest_vertices[::every], s.bone_indices[::every], s.bone_weights[::every], F.astype(float),
                      t.astype(float))
    return float(np.linalg.norm(v[2:] - 2.0 * v[1:-1] + v[:-2], axis=2).max())


def test_plants_add_no_acceleration(walker_graph):
    """Property over random walks and merges of the planted walker (its components: the single
    component's plants, near exact, added nothing in these walks): in no animation do the plants
    raise the largest vertex acceleration by more than three times their limit
    (:data:`.planting.EDGE_ACCEL` of the input's largest: each capped step, slowed spring, widened
    root or lift adds at most about the limit, and each of a leg's three joints follows its solution
    within it at its reach, :mod:`.limb_reach`; here 2.6 limits, 1.9 with a tenth of the height
    held past the hold, :data:`.planting.LIMB_BOUND`). The merged legs drag the feet so
    fast that the limits-off rig, holding them, adds 35 limits in one of these four (so the check
    can fail)."""
    w = walker_graph
    r, rig = _synthesize(w, False, 7, plants=False, count=4, frames=600)
    without = [_largest_acceleration(w, r.F[a], r.t[a]) for a in range(r.F.shape[0])]  # the same walks, no plants
    added, added_unlimited = [], []
    for limits, out in ((rig, added), (_unlimited(rig), added_unlimited)):
        F, t = r.F.copy(), r.t.copy()
        plant_feet(F, t, r.sources, limits)
        out.extend(_largest_acceleration(w, F[a], t[a]) - without[a] for a in range(F.shape[0]))
    assert max(added) <= 3.0 * rig.edge_limit, max(added) / rig.edge_limit
    assert max(added_unlimited) >= 10.0 * rig.edge_limit, max(added_unlimited) / rig.edge_limit


def test_limits_closed_form():
    """Each limit by hand (limit L, default rate y): a step's residual is taken up to L / (2y); a
    step in the root's push is
    smoothed until the root accelerates by at most L; a floor lift is widened until its second
    difference is at most L; and a plant starts from what the last one's spring leaves."""
    from skinsynth.pipeline.synthesis.contact.planting_loops import (_carried, _taken_share, edge_decay, floor_lift,
                                                                    gaussian_kernel, raised_cosine_kernel, smooth_push)
    from scipy.ndimage import gaussian_filter1d
    from skinsynth.pipeline.synthesis.contact.ground import raised_cosine

    L, y, up = 0.01, 0.578, 1
    assert _taken_share(np.array([0.003, 0.0, 0.004]), np.zeros(3), up, L / (2 * y)) == 1.0  # 0.005 < 0.00865
    share = _taken_share(np.array([0.03, 0.0, 0.04]), np.zeros(3), up, L / (2 * y))
    assert share == pytest.approx(L / (2 * y) / 0.05)
    impulse = np.zeros(41)
    impulse[20] = 1.0  # scipy's own weights: its filter's response to an impulse
    np.testing.assert_allclose(gaussian_kernel(2.4), gaussian_filter1d(impulse, 2.4, mode="constant")[10:31], rtol=1e-12)
    np.testing.assert_allclose(raised_cosine_kernel(5), raised_cosine(5), rtol=1e-13)
    push = np.zeros((200, 3))
    push[100:, 0] = 0.2  # the feet start pushing at 0.2 a frame
    kept = push.copy()
    assert smooth_push(kept, gaussian_kernel(2.4), 2.4, up, np.inf, 48.0) == 2.4  # no limit: σ kept
    sigma = smooth_push(push, gaussian_kernel(2.4), 2.4, up, L, 48.0)
    assert sigma > 2.4 and np.abs(np.diff(push[:, 0])).max() <= L * 1.0001
    assert np.abs(np.diff(kept[:, 0])).max() > 3 * L
    need, state, out = np.zeros(120), np.zeros(120, bool), np.zeros(120)
    need[50:60] = 0.5
    state[:20] = state[100:] = True
    floor_lift(need, state, 3, raised_cosine_kernel(3), L, 48, out)
    assert np.abs(np.diff(out, 2)).max() <= L and out[50:60].min() >= 0.5 - 1e-12  # lifted all the way, gently
    values = np.zeros((30, 3))
    values[:10, 0] = 0.1 * np.arange(10)  # a plant whose correction grows 0.1 a frame to 0.9
    state = np.zeros(30, bool)
    state[:10] = True
    acc = np.zeros(3)
    assert _carried(values, state, 14, 9, y, L, up, acc, 7) == 12
    rate = edge_decay(values[9], y, L)
    assert rate == pytest.approx(np.sqrt(L / 0.9))
    c = (0.9 + 0.1) * np.exp(rate) - 0.9  # the spring x(k) = (x0 + c k) e^(−y k), first step the last one's
    assert acc[0] == pytest.approx((0.9 + 5 * c) * np.exp(-5 * rate)) and acc[1] == acc[2] == 0.0


def test_a_planted_foot_turns_only_as_the_inputs_did(walker_graph):
    """Inside a plant the foot's bone is asked to keep its orientation from frame to frame, turned
    only by the input's own step (the walker's planted feet do not turn at all), whatever the seams
    and the merge do to the leg (on the merged walker they turn the planted feet's bones by 5–9° a
    frame, at the median). Where they turn it further than MAX_TURN from what it holds, the foot
    goes with them: measured, most of the steps inside plants are asked to hold within 0.2°. (The
    limbs make the turn at their joints, within their ranges: test_limb_reach.)"""
    from skinsynth.pipeline.rig.rotations import rotation_exp, rotation_log

    w = walker_graph
    r, rig = _synthesize(w, False, 3, plants=False, count=8, frames=300)
    rig = _unlimited(rig)  # the defaults cap a planted turn's step (a faster leg turns the foot with it)
    targets = plant_targets(r.F, r.t, r.sources, rig)
    states = targets.states
    src = np.moveaxis(r.sources[rig.owner], 0, 1)  # (A, P, M)

    def steps(bones):  # (A, M − 1) angle of each frame-to-frame turn
        return np.linalg.norm(rotation_log(bones[:, 1:] @ np.swapaxes(bones[:, :-1], -1, -2)), axis=-1)

    for p in range(rig.owner.size):
        anchor = rig.bones[rig.anchor_bone[p]]
        now = r.F[:, :, anchor].astype(float)
        asked = rotation_exp(targets.turn[:, p]) @ now
        inside = states[:, p, 1:] & states[:, p, :-1]  # the steps inside a plant
        own = np.linalg.norm(rotation_log(rig.turn_steps_in[src[:, p, 1:], p]), axis=-1)  # the input's own step
        held = np.abs(steps(asked) - own)[inside] < np.radians(0.2)
        assert np.median(steps(now)[inside]) > np.radians(2.0)  # the walks and merges do turn them
        assert held.mean() > 0.6, held.mean()


def test_a_synthesis_says_where_its_plants_could_not_hold_a_foot(walker_graph):
    """Issue 62: ``Synthesis.limited`` flags each output frame where a limb was held at the edge of
    its joints' range (1) or had its turn cut to keep the skin (2), for the feet report
    (:func:`.measures.limits_summary`). The planted walker's merged legs reach past their ranges in
    a third of the frames; the same synthesis without plants flags none."""
    from skinsynth.pipeline.mesh.contact_measures import LIMB_CUT, LIMB_HELD

    w = walker_graph
    planted, rig = _synthesize(w, False, 5, count=4, frames=300)
    assert planted.limited.shape == (4, 300) and planted.limited.dtype == np.uint8
    assert set(np.unique(planted.limited)) <= {0, LIMB_HELD, LIMB_CUT, LIMB_HELD | LIMB_CUT}
    assert 0.02 < np.mean(planted.limited & LIMB_HELD > 0) < 0.6  # 0.35 here
    assert np.any(planted.limited & LIMB_CUT)  # 7 % of the frames here
    plain, _ = _synthesize(w, False, 5, plants=False, count=4, frames=300)
    assert not plain.limited.any()


def test_a_large_correction_is_let_go_no_faster_than_its_limit_and_both_edges_keep_their_steps():
    # a plant holding a large correction (1.0, at rest) until frame 19, then a gap, then a plant whose
    # small correction moves; the spring out starts with y² ‖x₀‖ = 0.334 at y = 0.578 a frame
    decay = 0.578
    limit = decay ** 2 / 8

    def blended(gap, limit):
        M = 20 + gap + 20
        state = np.zeros(M, bool)
        state[:20] = True
        state[20 + gap:] = True
        values = np.zeros((M, 3))
        values[:20] = [1.0, 0.0, 0.0]
        values[20 + gap:, 1] = 0.03 + 0.001 * np.arange(20)
        out = blend_edges_row(values.copy(), state, decay, limit)
        expected = values[None, None].copy()
        _blend_edges(expected, *_edge_masks(state), decay, limit)
        np.testing.assert_allclose(out, expected[0, 0], rtol=1e-12, atol=1e-12)  # compiled = reference
        if gap > 3:  # leaving: the last step inside (well posed: κ < 0.5)
            np.testing.assert_allclose(out[20] - out[19], out[19] - out[18], atol=1e-12)
        np.testing.assert_allclose(out[20 + gap] - out[19 + gap], out[21 + gap] - out[20 + gap], atol=1e-12)
        return np.linalg.norm(np.diff(out, 2, axis=0), axis=1).max()

    for gap in (12, 40):
        assert blended(gap, limit) < 0.75 * blended(gap, np.inf)
    # over a long gap each spring starts within its limit (a discrete second difference averages the
    # spring's own, at most y² ‖x₀‖); the default one kicks twice as hard or more
    assert blended(40, limit) <= 1.05 * limit < 0.5 * blended(40, np.inf)
    # a gap too short for slowed springs (κ ≥ 0.5) keeps the default rate, entering as the next plant does
    assert blended(3, limit) == blended(3, np.inf)
    # an input that never accelerates (limit 0) or is too short to say (NaN) bounds nothing
    assert blended(40, 0.0) == blended(40, np.nan) == blended(40, np.inf)
