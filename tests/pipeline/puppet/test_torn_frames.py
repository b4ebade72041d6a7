"""The guard that plays torn frames by the skeleton (pipeline/puppet/jointed_play.py, module notes 5.):
which frames are torn, how the skeleton's weight eases in and out around them (each character's clip on
its own), and how the frames played again replace the first pass's."""

import numpy as np
import pytest

from skinsynth.pipeline.mesh.shape import BROKEN_SHARE, MARGIN, shape_envelope
from skinsynth.pipeline.puppet.jointed_play import (CHUNK, TORN_RAMP_SECONDS, TORN_SHARE, BeyondExamples, _merged,
                                                    beyond_shares, smoothstep, torn_floor)


def _grid(n=21):
    """A flat n × n grid of unit squares (V, 3) and its triangles (T, 3)."""
    x, y = np.meshgrid(np.arange(n, dtype=np.float64), np.arange(n, dtype=np.float64))
    vertices = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    corner = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    faces = np.concatenate([np.stack([corner, corner + 1, corner + n], 1), np.stack([corner + 1, corner + n + 1,
                                                                                    corner + n], 1)])
    return vertices, faces


def test_a_frame_is_torn_past_half_the_share_that_breaks_one_in_every_chunk_of_frames():
    rest, faces = _grid()
    envelope = shape_envelope(np.stack([rest, rest * 1.01]), faces)  # the capture stretches every edge 1 %
    frames = np.repeat(rest[None], CHUNK + 40, axis=0)  # more than one chunk
    lifted = np.argsort(np.linalg.norm(rest - rest[220], axis=1))  # vertices nearest the middle first
    # two neighbouring vertices pulled 3 units out of the plane: their 10 edges to the plane strained ≥ 1.2, far
    # past the margin, 0.81 % of the 1,240 (past 0.25 %); a gentle bump (0.3) strains 4.4 % at most
    torn_at, clear_at = CHUNK + 7, 5
    frames[torn_at, lifted[:2], 2] = 3.0
    frames[clear_at, lifted[0], 2] = 0.3
    torn = beyond_shares(envelope, frames) > TORN_SHARE
    assert np.flatnonzero(torn).tolist() == [torn_at]
    assert envelope.beyond_share(frames[[torn_at]])[0] == pytest.approx(10 / 1240)
    assert TORN_SHARE == 0.5 * BROKEN_SHARE and MARGIN == 0.25


def test_the_skeletons_weight_eases_in_and_out_around_a_torn_frame_within_its_clip():
    fps, frames = 50.0, 30
    reach = TORN_RAMP_SECONDS * fps  # 5 frames
    torn = np.zeros(2 * frames, bool)
    torn[[12, frames - 1]] = True  # the first clip's middle and its last frame
    floor = torn_floor(torn, frames, fps)
    first, second = floor[:frames], floor[frames:]
    assert first[12] == 1.0 and first[frames - 1] == 1.0
    np.testing.assert_allclose(first[10:15], smoothstep(1.0 - np.abs(np.arange(10, 15) - 12) / reach))
    assert np.all(first[:12 - int(reach)] == 0.0) and np.all(np.diff(first[:13]) >= 0.0)
    assert np.all(second == 0.0)  # the next character's clip starts untouched by the last frame before it
    assert np.all(torn_floor(np.zeros(frames, bool), frames, fps) == 0.0)
    assert torn_floor(np.eye(1, 5, 2, dtype=bool)[0], 5, 1.0).tolist() == [0.0, 0.0, 1.0, 0.0, 0.0]  # 0.1 s < a frame


def _beyond(alpha, rows, tag):
    m = len(rows)
    return BeyondExamples(np.asarray(alpha, dtype=np.float64), np.asarray(rows), np.full((m, 2, 3, 3), tag),
                          np.full((m, 2, 3), tag), np.full((m, 4, 3), tag))


@pytest.mark.parametrize("first_rows", [[1, 3, 4], []])
def test_frames_played_again_replace_the_first_pass_and_keep_the_rows_in_order(first_rows):
    alpha = np.zeros(7)
    alpha[first_rows] = 0.5
    first = _beyond(alpha, first_rows, 1.0) if first_rows else BeyondExamples(alpha, np.zeros(0, np.int64), None,
                                                                              None, None)
    redo = np.array([0, 3, 5])
    again = _beyond([0.3, 1.0, 0.7], [0, 1, 2], 2.0)
    merged = _merged(first, again, redo)
    expected_rows = sorted(set(first_rows) | {0, 3, 5})
    assert merged.rows.tolist() == expected_rows
    assert merged.alpha[[0, 3, 5]].tolist() == [0.3, 1.0, 0.7]
    kept = [r for r in first_rows if r not in redo]
    assert np.all(merged.alpha[kept] == 0.5)
    tags = dict(zip(merged.rows.tolist(), merged.rotations[:, 0, 0, 0].tolist()))
    assert all(tags[r] == 2.0 for r in redo) and all(tags[r] == 1.0 for r in kept)
    assert merged.offsets.shape == (len(expected_rows), 4, 3)
