"""fit-skin's warp kernels (``--device cuda``), run on every warp device (the ``device`` fixture)
against the numpy references."""

import numpy as np
import pytest

from skinsynth.gpu import sweep_bone_transforms_warp
from skinsynth.pipeline.skin.bone_transforms import update_bone_transforms
from skinsynth.pipeline.skin.skin_fit import fit_skin
from skinsynth.pipeline.skin.skin_weights import update_weights

from cli_helpers import assert_user_error, cli
from rigs import random_problem, sweep_problem


def test_the_weight_kernel_equals_the_numpy_reference(device):
    transforms, data, indices, weights = random_problem(11)
    reference = update_weights(transforms, data, indices, weights, 4, solver="numpy")
    warp = update_weights(transforms, data, indices, weights, 4, device=device)
    np.testing.assert_array_equal(warp[0], reference[0])
    np.testing.assert_allclose(warp[1], reference[1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(warp[2], reference[2], rtol=1e-9, atol=1e-9 * reference[2].max())


def test_the_weight_kernel_without_sparsification_and_with_all_bones(device):
    transforms, data, indices, weights = random_problem(12, bones=4)
    for influences, candidates in ((4, None), (2, 4)):
        reference = update_weights(transforms, data, indices, weights, influences, candidates, solver="numpy")
        warp = update_weights(transforms, data, indices, weights, influences, candidates, device=device)
        np.testing.assert_array_equal(warp[0], reference[0])
        np.testing.assert_allclose(warp[1], reference[1], rtol=0, atol=1e-9)


def test_the_sweep_kernel_equals_the_numpy_sweep(device):
    start, p, q = sweep_problem(13, frames=16, unused=2)
    np.testing.assert_allclose(sweep_bone_transforms_warp(start, p, q, device), update_bone_transforms(start, p, q),
                               rtol=0, atol=1e-10)


def test_a_fit_on_a_warp_device_is_the_cpu_fit(device):
    from skinsynth.pipeline.inputs.examples import bending_bar

    vertices, _ = bending_bar(frames=24, rings=12, segments=8)
    numba_fit = fit_skin(vertices, 4, iterations=8, seed=1)
    warp_fit = fit_skin(vertices, 4, iterations=8, seed=1, device=device)
    np.testing.assert_array_equal(warp_fit.bone_indices, numba_fit.bone_indices)
    np.testing.assert_allclose(warp_fit.bone_weights, numba_fit.bone_weights, atol=1e-8)
    np.testing.assert_allclose(warp_fit.rotations, numba_fit.rotations, atol=1e-8)
    assert abs(warp_fit.rmse - numba_fit.rmse) <= 1e-8 * numba_fit.rmse


def test_bones_on_a_rig_on_a_warp_device_are_the_cpu_solve(device):
    from skinsynth.pipeline.inputs.examples import synthetic_lbs
    from skinsynth.pipeline.skin.skin_fit import fit_bones_to_rig

    truth = synthetic_lbs(bones=5, frames=10, seed=4, rings=16, segments=6)
    rig = (truth["vertices"], truth["rest"], truth["bone_indices"], truth["bone_weights"], 5)
    numba_fit = fit_bones_to_rig(*rig, iterations=6, tolerance=0.0)
    warp_fit = fit_bones_to_rig(*rig, iterations=6, tolerance=0.0, device=device)
    np.testing.assert_allclose(warp_fit.rotations, numba_fit.rotations, atol=1e-8)
    np.testing.assert_allclose(warp_fit.translations, numba_fit.translations, atol=1e-8)
    assert abs(warp_fit.rmse - numba_fit.rmse) <= 1e-8 * numba_fit.rmse


def test_an_absent_gpu_is_one_line(tmp_path):
    from skinsynth.gpu import available_devices
    from skinsynth.pipeline.inputs.examples import bending_bar
    from skinsynth.formats.meshseq import write_array_sequence

    if any(d.startswith("cuda") for d in available_devices()):
        pytest.skip("a GPU is present: --device cuda is not refused")
    vertices, faces = bending_bar(frames=6, rings=6, segments=6)
    write_array_sequence(tmp_path / "bar.npz", vertices, faces, 24.0)
    assert_user_error(cli("fit-skin", tmp_path / "bar.npz", "-o", tmp_path / "skin.h5", "--bones", 2, "--device", "cuda"),
                      "--device cuda", folder=tmp_path, keep=["bar.npz"])
