"""pipeline.mesh.winding (compiled) against its numpy reference, on a multi-shell character and on
points all round it, and against closed forms (inside a closed shell 1, outside 0)."""

import numpy as np

from skinsynth.pipeline.inputs.examples import walker
from skinsynth.pipeline.mesh.winding import winding_numbers
from winding_reference import winding_numbers as reference


def test_the_compiled_winding_numbers_match_the_numpy_reference_on_the_walker():
    vertices, faces = walker(frames=2, rings=8, segments=8)
    rest = vertices[0]
    rng = np.random.default_rng(3)
    low, high = rest.min(axis=0) - 0.1, rest.max(axis=0) + 0.1
    points = np.concatenate([rng.uniform(low, high, size=(300, 3)), rest[::7] * 0.999 + 0.001 * rest.mean(axis=0)])
    compiled, numpy = winding_numbers(points, rest, faces), reference(points, rest, faces)
    np.testing.assert_allclose(compiled, numpy, atol=1e-9)
    assert (np.abs(compiled) > 0.5).any() and (np.abs(compiled) < 0.5).any()  # both sides sampled


def test_a_cube_is_one_inside_and_zero_outside():
    import trimesh

    cube = trimesh.creation.box()
    points = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.1], [2.0, 0.0, 0.0], [0.0, 0.0, -0.9]])
    np.testing.assert_allclose(winding_numbers(points, cube.vertices, cube.faces), [1, 1, 0, 0], atol=1e-12)
