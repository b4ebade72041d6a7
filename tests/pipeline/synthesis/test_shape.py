"""The shape measure (issue 62: :mod:`skinsynth.pipeline.mesh.shape`): a torn frame is found, the
capture itself never is, and the verdict does not depend on the character's size or frame rate."""

import numpy as np

from skinsynth.pipeline.inputs.examples import bending_bar
from skinsynth.pipeline.mesh.shape import BROKEN_SHARE, MARGIN, edge_strain, shape_envelope


def _bar():
    """A bending bar (24 frames), its faces."""
    vertices, faces = bending_bar(frames=24)
    return vertices.astype(np.float64), faces


def test_edge_strain_by_hand():
    vertices = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 2, 0]], [[0, 0, 0], [1.5, 0, 0], [0, 1, 0]]])
    edges = np.array([[0, 1], [0, 2]])
    np.testing.assert_allclose(edge_strain(vertices, edges, np.array([1.0, 2.0])), [[0.0, 0.0], [0.5, 0.5]])
    # a zero rest length counts the length over the mean edge's
    np.testing.assert_allclose(edge_strain(vertices[1], edges, np.array([0.0, 2.0]))[0], [1.5, 0.5])


def test_the_capture_and_its_playback_are_never_beyond():
    frames, faces = _bar()
    playback = frames + np.random.default_rng(0).normal(scale=1e-3, size=frames.shape)
    envelope = shape_envelope(frames, faces, playback)
    assert not envelope.beyond(frames).any() and not envelope.beyond(playback).any()


def test_a_torn_frame_is_broken_and_its_neighbours_are_not():
    """A frame whose tip is pulled off the bar (every vertex past 90 % of its length moved by a tenth
    of the bar's length, as a bone shifted against its neighbour does) is broken; the same frame moved
    rigidly, or stretched well inside the margin, is not."""
    frames, faces = _bar()
    envelope = shape_envelope(frames, faces)
    frame = frames[10].copy()
    length = float(np.ptp(frames[0], axis=0).max())
    axis = int(np.argmax(np.ptp(frames[0], axis=0)))
    tip = frames[0][:, axis] > frames[0][:, axis].min() + 0.9 * length
    torn = frame.copy()
    torn[tip] += np.array([0.0, 0.1 * length, 0.0])
    share = envelope.beyond_share(torn[None])[0]
    assert share > 2 * BROKEN_SHARE and envelope.broken(torn[None])[0]  # the ring of edges at the tear: 1.7 %
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert envelope.beyond_share((frame @ turn.T + 3.0)[None])[0] == 0.0  # a rigid motion strains nothing
    stretched = frame * (1.0 + 0.5 * MARGIN)  # every edge half the margin past its own
    assert not envelope.broken(stretched[None])[0]


def test_the_verdict_holds_at_any_size_and_frame_rate():
    """Scaled to centimetres and sampled at twice the rate (each step in-betweened), the capture
    gives the same envelope and a torn frame the same share of edges beyond."""
    frames, faces = _bar()
    torn = frames[5].copy()
    torn[: torn.shape[0] // 10] *= 1.6
    share = shape_envelope(frames, faces).beyond_share(torn[None])[0]
    doubled = np.concatenate([np.stack([a, 0.5 * (a + b)]) for a, b in zip(frames[:-1], frames[1:])] + [frames[-1:]])
    envelope = shape_envelope(100.0 * doubled, faces)  # the in-betweens strain an edge a hair more at most
    assert np.all(envelope.envelope >= shape_envelope(frames, faces).envelope - 1e-12)
    assert share > 4 * BROKEN_SHARE
    assert abs(envelope.beyond_share(100.0 * torn[None])[0] - share) <= 0.05 * share
