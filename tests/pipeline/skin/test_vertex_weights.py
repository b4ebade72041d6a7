"""The compiled per-vertex weight solve against the batched numpy reference, and thread counts."""

import numba
import numpy as np
import pytest

from skinsynth.pipeline.skin.skin_weights import update_weights

from rigs import random_problem, sweep_problem


@pytest.mark.parametrize("seed, influences, candidates", [(0, 4, None), (1, 2, None), (2, 4, 7), (3, 3, 3),
                                                           (4, 1, None)])
def test_compiled_weights_equal_the_numpy_reference(seed, influences, candidates):
    transforms, data, indices, weights = random_problem(seed)
    reference = update_weights(transforms, data, indices, weights, influences, candidates, solver="numpy")
    compiled = update_weights(transforms, data, indices, weights, influences, candidates, solver="compiled")
    np.testing.assert_array_equal(compiled[0], reference[0])
    np.testing.assert_allclose(compiled[1], reference[1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(compiled[2], reference[2], rtol=1e-9, atol=1e-9 * reference[2].max())
    assert compiled[0].dtype == np.int32 and compiled[1].shape == (data.count, min(influences, 7))
    assert (compiled[1] >= 0).all() and np.allclose(compiled[1].sum(axis=1), 1.0, atol=1e-12)
    assert (np.diff(compiled[1], axis=1) <= 0).all()  # by decreasing weight


def test_exact_lbs_weights_are_recovered():
    transforms, data, indices, weights = random_problem(5, noise=0.0, bones=5)
    _, new_weights, error = update_weights(transforms, data, indices, weights, 5, solver="compiled")
    assert error.max() < 1e-12 * data.squared_norm.max()  # a wrong weight costs O(1)


def test_the_thread_count_changes_nothing():
    transforms, data, indices, weights = random_problem(6, count=3000)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = update_weights(transforms, data, indices, weights, 4, solver="compiled")
        numba.set_num_threads(max(2, threads))
        many = update_weights(transforms, data, indices, weights, 4, solver="compiled")
    finally:
        numba.set_num_threads(threads)
    for a, b in zip(one, many):
        assert a.tobytes() == b.tobytes()


def test_compiled_bone_sweep_equals_the_numpy_sweep_for_any_thread_count():
    from skinsynth.pipeline.skin.bone_transforms import update_bone_transforms
    from skinsynth.pipeline.skin.transform_sweep import sweep_bone_transforms

    start, p, q = sweep_problem(7, frames=20, unused=4)
    reference = update_bone_transforms(start, p, q)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = sweep_bone_transforms(start, p, q)
        numba.set_num_threads(max(2, threads))
        many = sweep_bone_transforms(start, p, q)
    finally:
        numba.set_num_threads(threads)
    np.testing.assert_allclose(one, reference, rtol=0, atol=1e-10)
    assert one.tobytes() == many.tobytes()
    np.testing.assert_array_equal(one[:, 4], start[:, 4])
    rotations = np.delete(one, 4, axis=1)[..., :3]
    np.testing.assert_allclose(rotations @ rotations.transpose(0, 1, 3, 2), np.broadcast_to(np.eye(3), rotations.shape),
                               atol=1e-12)
    assert (np.linalg.det(rotations) > 0).all()


def test_compiled_sums_equal_the_sparse_matrix_sums_for_any_thread_count():
    from skinsynth.pipeline.skin.bone_transforms import weighted_sums
    from skinsynth.pipeline.skin.transform_sweep import sparse_weighted_sums

    transforms, data, indices, weights = random_problem(8)
    indices, weights, _ = update_weights(transforms, data, indices, weights, 3, solver="numpy")
    weights[::7, -1] = 0.0  # unused slots count for nothing
    dense = np.zeros((data.count, transforms.shape[1]))
    np.add.at(dense, (np.arange(data.count)[:, None], indices), weights)
    p, q = weighted_sums(dense, data)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = sparse_weighted_sums(indices, weights, data, transforms.shape[1])
        numba.set_num_threads(max(2, threads))
        many = sparse_weighted_sums(indices, weights, data, transforms.shape[1])
    finally:
        numba.set_num_threads(threads)
    np.testing.assert_allclose(one[0], p, rtol=1e-12, atol=1e-12 * np.abs(p).max())
    np.testing.assert_allclose(one[1], q, rtol=1e-12, atol=1e-12 * np.abs(q).max())
    assert all(a.tobytes() == b.tobytes() for a, b in zip(one, many))
