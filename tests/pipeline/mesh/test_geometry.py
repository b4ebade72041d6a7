"""pipeline.geometry against closed forms and against itself taken whole."""

import numpy as np
import pytest

from skinsynth.pipeline.mesh.geometry import largest_acceleration, vertex_normals
from skinsynth.pipeline.inputs.examples import cylinder_mesh


@pytest.mark.parametrize("block_bytes", [1, 5000, 1 << 30])
def test_vertex_normals_in_blocks_of_frames_are_the_normals_taken_whole(block_bytes):
    rest, faces = cylinder_mesh(rings=6, segments=8)
    rng = np.random.default_rng(0)
    vertices = rest + 0.05 * rng.normal(size=(7,) + rest.shape)
    whole = vertex_normals(vertices, faces, block_bytes=1 << 40)
    assert np.array_equal(vertex_normals(vertices, faces, block_bytes=block_bytes), whole)
    # the tube's side points away from its axis (x): the closed form at the rest pose
    side = vertex_normals(rest[None], faces)[0, :-2]
    radial = rest[:-2] * [0.0, 1.0, 1.0]
    assert np.allclose(np.einsum("vi,vi->v", side, radial / np.linalg.norm(radial, axis=1, keepdims=True)) > 0.9, True)


def test_largest_acceleration_is_the_largest_second_difference_inside_each_clip():
    x = np.random.default_rng(0).normal(size=(101, 7, 3))
    x[40:] += 100.0  # the step from clip 0's last frame to clip 1's first is no motion
    brute = max(np.linalg.norm(x[m + 1] - 2 * x[m] + x[m - 1], axis=1).max()
                for m in list(range(1, 39)) + list(range(41, 100)))
    for block in (1, 5, 32, 500):
        assert largest_acceleration(x, [0, 40, 101], block=block) == pytest.approx(brute, rel=1e-12)
    assert largest_acceleration(x) > 10.0 and np.isnan(largest_acceleration(x[:2]))
