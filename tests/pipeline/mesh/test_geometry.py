"""pipeline.geometry against closed forms and against itself taken whole."""

import numpy as np
import pytest

from skinsynth.pipeline.mesh.geometry import vertex_normals
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
