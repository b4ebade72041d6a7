"""pipeline.mesh.crossing (compiled) against closed forms on a box, and against the winding
number's verdict along segments into the walker's body."""

import numpy as np
import trimesh

from skinsynth.pipeline.inputs.examples import walker
from skinsynth.pipeline.mesh.crossing import last_crossings
from skinsynth.pipeline.mesh.winding import triangle_corners, winding_numbers


def test_segments_cross_a_box_where_its_faces_are():
    box = trimesh.creation.box()  # [-0.5, 0.5]^3
    corners = triangle_corners(box.vertices, box.faces)
    starts = np.array([[2.0, 0.1, 0.2], [2.0, 0.1, 0.2], [2.0, 3.0, 0.0], [0.1, 0.1, 0.1], [0.0, -2.0, 0.3]])
    ends = np.array([[0.0, 0.1, 0.2], [-2.0, 0.1, 0.2], [-2.0, 3.0, 0.0], [0.2, -0.1, 0.0], [0.0, 0.0, 0.3]])
    # into the box (x = 0.5 at t = 0.75), through it (last at x = -0.5, t = 0.625), past it, inside it, into it
    np.testing.assert_allclose(last_crossings(starts, ends, corners), [0.75, 0.625, -1.0, -1.0, 0.75], atol=1e-12)


def test_past_the_last_crossing_the_winding_number_is_the_ends():
    vertices, faces = walker(frames=1, rings=8, segments=10)
    rest = vertices[0]
    rng = np.random.default_rng(5)
    centre, spread = rest.mean(axis=0), np.ptp(rest, axis=0)
    starts = centre + rng.uniform(-1.0, 1.0, size=(200, 3)) * spread
    ends = rest[rng.integers(0, len(rest), 200)] * 0.98 + 0.02 * centre
    crossing = last_crossings(starts, ends, triangle_corners(rest, faces))
    hit = crossing >= 0.0
    assert hit.sum() > 100
    after = starts[hit] + (crossing[hit] + 0.5 * (1.0 - crossing[hit]))[:, None] * (ends[hit] - starts[hit])
    before = starts[hit] + (crossing[hit] - 1e-6)[:, None] * (ends[hit] - starts[hit])
    w_after, w_end = winding_numbers(after, rest, faces), winding_numbers(ends[hit], rest, faces)
    np.testing.assert_allclose(w_after, w_end, atol=1e-6)  # no surface between the crossing and the end
    assert (np.abs(winding_numbers(before, rest, faces) - w_end) > 0.5).all()  # ... and one at it
