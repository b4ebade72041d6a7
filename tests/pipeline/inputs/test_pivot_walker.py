"""The pivot walker (``pipeline.inputs.pivot_walker``, ``skinsynth example walker --pivot``): the planted
walker turning 180° on the ball of its left foot, the generated truth for plants that pivot (issue 64)."""

import numpy as np
import pytest

from skinsynth.formats.meshseq import read_mesh_sequence
from skinsynth.pipeline.inputs.examples import walker
from skinsynth.pipeline.inputs.pivot_walker import pivot_walker

from cli_helpers import assert_ok, assert_user_error, cli

SMALL = dict(rings=8, segments=6)


def _horizontal(points):
    """(F − 1,) horizontal length of each frame-to-frame step of points (F, 3), Y up."""
    step = np.diff(points, axis=0)
    return np.hypot(step[:, 0], step[:, 2])


def test_the_ball_stays_exactly_still_while_the_body_turns_about_it():
    vertices, faces, truth, rig = pivot_walker(rig=True)
    assert vertices.shape == (192, 1248, 3) and truth.planted.shape == (192, 2)
    left = truth.planted[:, 0]
    still = left[:-1] & left[1:]
    assert np.abs(_horizontal(truth.balls[:, 0])[still]).max() < 1e-12  # the pivot never moves
    assert truth.turning.sum() > 40 and (still | ~truth.turning[:-1]).all()  # every turn on a planted left foot
    # it turns 180° a pivot, and the sole sweeps round the ball (the heel moves, the ball does not)
    assert np.degrees(truth.heading[-1] - truth.heading[0]) == pytest.approx(4 * 180.0, abs=1e-6)
    foot = np.flatnonzero(rig.weights[:, 4] == 1.0)  # foot_l's own vertices
    heel = foot[np.argmin(rig.rest[foot, 2] + 10.0 * rig.rest[foot, 1])]
    turning = still & truth.turning[:-1]
    assert _horizontal(vertices[:, heel])[turning].max() > 0.02 * 1.76
    # the sole is on the floor in every frame the left foot rests, lifted while it steps in place
    sole = vertices[:, foot, 1].min(axis=1)
    assert np.abs(sole[left]).max() < 1e-12 and sole[~left].min() > 0.0
    # LBS from the rig gives the vertices exactly
    lbs = np.einsum("vk,fkvb->fvb", rig.weights,
                    np.einsum("fkab,vb->fkva", rig.rotations, rig.rest) + rig.translations[:, :, None])
    np.testing.assert_allclose(lbs, vertices, atol=1e-12)


def test_two_pivots_make_a_whole_turn_and_the_clip_loops():
    vertices, _, truth = pivot_walker(pivots=4, frames_per_pivot=24, **SMALL)
    np.testing.assert_allclose(vertices[48:], vertices[:48], atol=1e-12)  # two half turns: back where it began
    np.testing.assert_allclose(vertices[24], vertices[0] * [-1, 1, -1] + 2 * truth.balls[0, 0] * [1, 0, 1], atol=1e-12)


def test_the_swinging_foot_is_clear_of_the_contact_band_whenever_it_moves_sideways():
    """The right foot swings round while the body turns: it leaves the floor (3.5 % of the height)
    before it moves sideways, so a contact finder never sees a foot sliding on the floor."""
    vertices, _, truth, rig = pivot_walker(rig=True)
    foot = np.flatnonzero(rig.weights[:, 7] == 1.0)  # foot_r
    moving = _horizontal(vertices[:, foot].mean(axis=1)) > 1e-4
    height = vertices[:-1, foot, 1].min(axis=1)
    assert moving.any() and height[moving].min() > 0.02 * 1.76
    assert (~truth.planted[:-1, 1] | ~moving).all()


def test_the_same_figure_as_the_planted_walker():
    vertices, faces, _ = pivot_walker(pivots=1, frames_per_pivot=12, **SMALL)
    _, walker_faces = walker(frames=2, planted=True, **SMALL)
    np.testing.assert_array_equal(faces, walker_faces)
    assert np.ptp(vertices[0, :, 1]) == pytest.approx(1.76, abs=0.05)
    with pytest.raises(ValueError):
        pivot_walker(frames_per_pivot=8)


def test_the_cli_writes_the_pivot_walker(tmp_path):
    out = tmp_path / "pivot.npz"
    result = assert_ok(cli("example", "walker", "--pivot", "-o", out, "--cycles", 2, "--fps", 12, "--rings", 8,
                           "--segments", 6, "--json"))
    sequence = read_mesh_sequence(str(out))
    assert sequence.vertices.shape[0] == 2 * 24 and sequence.fps == 12
    assert '"pivot": true' in result.output
    expected, _, _ = pivot_walker(pivots=2, frames_per_pivot=24, **SMALL)
    np.testing.assert_allclose(sequence.vertices, expected, atol=1e-5)
    assert_user_error(cli("example", "walker", "--pivot", "--planted", "-o", tmp_path / "x.npz"), "--pivot")
    assert_user_error(cli("example", "walker", "--pivot", "--fps", 4, "-o", tmp_path / "x.npz"), "12 frames")
    assert not (tmp_path / "x.npz").exists()
