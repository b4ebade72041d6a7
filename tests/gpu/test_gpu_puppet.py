"""The puppet's run time in skinsynth.gpu: each stage on every warp device (the ``device`` fixture)
against its numpy reference, and the whole path against pipeline.puppet.predict_vertices for a
trained puppet."""

import numpy as np
import pytest

import skinsynth.gpu as gpu
from skinsynth.gpu import puppet_run, skinning
from skinsynth.gpu.validation import KERNEL_KINDS
from skinsynth.pipeline.puppet.playback import host_inputs

from rigs import random_skin
from random_puppets import random_dual_quaternions, random_puppet, random_rigid_frames, random_rotations, relative_error

TOL = 1e-5


@pytest.mark.parametrize("kind", KERNEL_KINDS)
@pytest.mark.parametrize("samples", [1, 7, 50])
def test_kernel_vectors(kind, samples, device):
    rng = np.random.default_rng(samples)
    x, training = rng.normal(size=(samples, 24)) * 0.2, rng.normal(size=(38, 24)) * 0.2
    expected = gpu.kernel_vectors_reference(x, training, kind, offset=0.3, degree=5)
    got = gpu.kernel_vectors(x, training, kind, offset=0.3, degree=5, device=device)
    assert relative_error(got, expected) < TOL


def test_kernel_vectors_other_degree(device):
    rng = np.random.default_rng(3)
    x, training = rng.normal(size=(5, 6)) * 0.3, rng.normal(size=(9, 6)) * 0.3
    got = gpu.kernel_vectors(x, training, "polynomial", offset=0.1, degree=3, device=device)
    assert relative_error(got, (x @ training.T + 0.1) ** 3) < TOL


@pytest.mark.parametrize("samples", [1, 13, 100])
def test_predict_dual_quaternions(samples, device):
    rng = np.random.default_rng(samples)
    bones, n_p = 11, 27
    xi, predictor, bias = rng.random((samples, n_p)), rng.normal(size=(8 * bones, n_p)), rng.normal(size=8 * bones)
    got = gpu.predict_dual_quaternions(xi, predictor, bias, device=device)
    assert got.shape == (samples, bones, 8)
    assert relative_error(got, gpu.predict_dual_quaternions_reference(xi, predictor, bias)) < TOL
    # row b·8 + m of M is bone b's m-th number
    assert np.allclose(got[0, 3, 5], predictor[29] @ xi[0] + bias[29], rtol=1e-5)


def test_predictions_with_large_cancelling_coefficients_stay_exact(device):
    """Nearly repeated training poses give predictors whose entries reach 1e4 and cancel (the
    horse's): d = M ξ + m must keep float64's precision, not float32's (which lost 3e-3)."""
    rng = np.random.default_rng(7)
    bones, n_p, samples = 6, 24, 30
    xi = np.exp(-rng.random((samples, n_p)))
    twin = rng.normal(size=(8 * bones, n_p // 2)) * 2.5e4
    predictor = np.concatenate([twin, -twin * (1.0 + 1e-4)], axis=1)  # columns of twin poses nearly cancel
    bias = random_dual_quaternions(rng, 1, bones, flip=False).reshape(-1)
    raw = gpu.predict_dual_quaternions(xi, predictor, bias, device=device)
    expected = gpu.predict_dual_quaternions_reference(xi, predictor, bias)
    assert np.abs(raw - expected).max() < 1e-9 * np.abs(predictor).max()
    unit = gpu.normalise_dual_quaternions(raw, device=device)[0]
    assert np.abs(unit - gpu.normalise_dual_quaternions_reference(expected)[0]).max() < 1e-6


@pytest.mark.parametrize("samples", [1, 40])
def test_normalise_dual_quaternions(samples, device):
    rng = np.random.default_rng(samples)
    d = random_dual_quaternions(rng, samples, 9) * rng.uniform(0.5, 2.0, size=(samples, 9, 1))
    got = gpu.normalise_dual_quaternions(d, device=device)
    expected = gpu.normalise_dual_quaternions_reference(d)
    for g, e in zip(got, expected):
        assert relative_error(g, e) < TOL


@pytest.mark.parametrize("samples", [1, 17])
def test_solve_translations(samples, device):
    rng = np.random.default_rng(samples)
    bones, n_c = 12, 5
    args = (random_rotations(rng, (samples, bones)), rng.normal(size=(samples, n_c, 3)),
            rng.normal(size=(samples, bones, 3)), rng.normal(size=(bones, bones, 3)), rng.normal(size=(bones, n_c)),
            rng.normal(size=(bones, bones)) * 1e-3)
    got = gpu.solve_translations(*args, device=device)
    assert relative_error(got, gpu.solve_translations_reference(*args)) < TOL
    # the index convention, spelled out for one entry
    rot, c, t_hat, gamma, q, prior = args
    n, b, a = samples - 1, 7, 2
    entry = (sum(gamma[b, k, cc] * rot[n, k, a, cc] for k in range(bones) for cc in range(3))
             + q[b] @ c[n, :, a] + prior[b] @ t_hat[n, :, a])
    assert np.isclose(got[n, b, a], entry, rtol=1e-4, atol=1e-5 * np.abs(got).max())


@pytest.mark.parametrize("influences", [1, 2, 3, 4])
@pytest.mark.parametrize("samples", [1, 6])
def test_dq_skin(influences, samples, device):
    rng = np.random.default_rng(10 * influences + samples)
    rest, idx, w = random_skin(rng, 500, 13, influences)
    dq = random_dual_quaternions(rng, samples, 13, scale=1.7)  # non-unit and sign-flipped
    expected = gpu.dqs_reference(rest, idx, w, dq)
    got = gpu.dq_skin(rest, idx, w, dq, device=device)
    assert relative_error(got, expected) < TOL


def test_dq_skin_hemisphere_rule_matters(device):
    # Two bones with nearly the same rotation but opposite signs: without the sign rule the blend
    # cancels. The kernel must agree with the reference (and be rigid when both bones agree).
    rng = np.random.default_rng(1)
    rest, idx, w = random_skin(rng, 200, 2, 2)
    idx[:] = [0, 1]
    one = random_dual_quaternions(rng, 1, 1, flip=False)
    dq = np.concatenate([one, -one], axis=1)
    got = gpu.dq_skin(rest, idx, w, dq, device=device)
    rigid = gpu.dq_skin(rest, idx[:, :1], np.ones((200, 1)), one, device=device)
    assert relative_error(got, rigid) < TOL


def test_dq_skin_chunks(monkeypatch, device):
    monkeypatch.setattr(skinning, "_DEVICE_CHUNK", 1000)  # 3 samples per launch over 300 vertices
    rng = np.random.default_rng(5)
    rest, idx, w = random_skin(rng, 300, 7, 3)
    dq = random_dual_quaternions(rng, 10, 7)
    assert relative_error(gpu.dq_skin(rest, idx, w, dq, device=device), gpu.dqs_reference(rest, idx, w, dq)) < TOL


@pytest.mark.parametrize("influences", [1, 2, 3, 4])
@pytest.mark.parametrize("corrected", [False, True])
def test_linear_skin(influences, corrected, device):
    # the puppet's linear kernel (bone matrices blended per vertex, then applied) against
    # lbs_reference, by rigid and by affine bone matrices, with and without rest offsets
    rng = np.random.default_rng(10 * influences + corrected)
    samples, bones = 6, 13
    rest, idx, w = random_skin(rng, 500, bones, influences)
    rigid = np.concatenate([random_rotations(rng, (samples, bones)), rng.normal(size=(samples, bones, 3, 1)) * 2],
                           axis=-1)
    offsets = rng.normal(size=(samples, 500, 3)) * 0.1 if corrected else None
    for matrices in (rigid, rng.normal(size=(samples, bones, 3, 4))):
        expected = gpu.lbs_reference(rest, idx, w, matrices[..., :3], matrices[..., 3], offsets)
        got = gpu.linear_skin(rest, idx, w, matrices, device=device, rest_offsets=offsets)
        assert relative_error(got, expected) < TOL


def test_linear_skin_chunks_and_bad_input(monkeypatch, device):
    monkeypatch.setattr(skinning, "_DEVICE_CHUNK", 1000)  # 3 samples per launch over 300 vertices
    rng = np.random.default_rng(6)
    rest, idx, w = random_skin(rng, 300, 7, 3)
    matrices = rng.normal(size=(10, 7, 3, 4))
    expected = gpu.lbs_reference(rest, idx, w, matrices[..., :3], matrices[..., 3])
    assert relative_error(gpu.linear_skin(rest, idx, w, matrices, device=device), expected) < TOL
    assert gpu.linear_skin(rest, idx, w, matrices[:0], device=device).shape == (0, 300, 3)
    with pytest.raises(ValueError, match="bone matrices must be"):
        gpu.linear_skin(rest, idx, w, matrices[..., :3], device=device)


@pytest.mark.parametrize("solver", [True, False])
@pytest.mark.parametrize("framed", [True, False])
def test_rigid_transforms(solver, framed, device):
    # the composing launch of a linear run: dual quaternions (signs flipped at random), the
    # solver's translations, the world frames, composed on the device as dual quaternions and
    # against the reference's composition of matrices
    rng = np.random.default_rng(1 + solver + 2 * framed)
    samples, bones = 11, 9
    dq = random_dual_quaternions(rng, samples, bones)
    trans = rng.normal(size=(samples, bones, 3)) if solver else None
    frames = random_rigid_frames(rng, samples) if framed else None
    got = gpu.rigid_transforms(dq, trans, frames, device=device)
    expected = gpu.rigid_transforms_reference(dq, trans, frames)
    assert got.shape == (samples, bones, 3, 4)
    assert relative_error(got, expected) < TOL
    # the convention spelled out for one bone: [R | t] moves p to R p + t
    _, rot, t = gpu.normalise_dual_quaternions_reference(dq)
    if solver:
        t = trans
    p, n, b = rng.normal(size=3), samples - 1, 4
    moved = rot[n, b] @ p + t[n, b]
    if framed:
        moved = frames[n, :3, :3] @ moved + frames[n, :3, 3]
    assert np.allclose(got[n, b, :, :3] @ p + got[n, b, :, 3], moved, atol=1e-5 * np.abs(moved).max())
    assert gpu.rigid_transforms(dq[:0], device=device).shape == (0, bones, 3, 4)
    with pytest.raises(ValueError, match="world frames must be"):
        gpu.rigid_transforms(dq, None, frames[:, :3] if framed else np.zeros((2, 4, 4)), device=device)


@pytest.mark.parametrize("kind", KERNEL_KINDS)
@pytest.mark.parametrize("solver", [True, False])
@pytest.mark.parametrize("framed", [True, False])
def test_run_puppet_matches_reference(kind, solver, framed, device):
    rng = np.random.default_rng(len(kind) + 2 * solver + 4 * framed)
    puppet = random_puppet(rng, kind)
    samples = 9
    x = rng.normal(size=(samples, 12)) * 0.3
    c = rng.normal(size=(samples, 4, 3))
    frames = random_rigid_frames(rng, samples) if framed else None
    expected = gpu.reference_run_puppet(puppet, x, c, frames, translation_solver=solver)
    got = gpu.run_puppet(puppet, x, c, frames, translation_solver=solver, device=device)
    assert relative_error(got, expected) < TOL


def test_run_puppet_chunks_threads_and_out(monkeypatch, device):
    rng = np.random.default_rng(7)
    puppet = random_puppet(rng, "gaussian", influences=3)
    samples = 23
    x, c, frames = rng.normal(size=(samples, 12)) * 0.3, rng.normal(size=(samples, 4, 3)), random_rigid_frames(rng, samples)
    expected = gpu.reference_run_puppet(puppet, x, c, frames)
    device_puppet = gpu.DevicePuppet(puppet, device)
    monkeypatch.setattr(puppet_run, "_DEVICE_CHUNK", 2000)  # 5 samples per chunk over 400 vertices
    for threads in (1, 2, 3):
        assert relative_error(gpu.run_puppet(device_puppet, x, c, frames, threads=threads), expected) < TOL
    out = np.zeros((samples, 400, 3), dtype=np.float32)
    timings = {}
    assert gpu.run_puppet(device_puppet, x, c, frames, out=out, timings=timings) is out
    assert relative_error(out.astype(np.float64), expected) < TOL
    assert {"kernel_vectors", "predict", "solve_translations", "skin"} <= set(timings)


@pytest.mark.parametrize("samples", [3, 17])
def test_run_puppet_takes_any_sample_count_over_threads(samples, device):
    # Thread bounds are numpy integers; a chunk smaller than the step used one as warp's shape.
    rng = np.random.default_rng(samples)
    puppet = random_puppet(rng, "gaussian", influences=3)
    x, c, frames = rng.normal(size=(samples, 12)) * 0.3, rng.normal(size=(samples, 4, 3)), random_rigid_frames(rng, samples)
    expected = gpu.reference_run_puppet(puppet, x, c, frames)
    assert relative_error(gpu.run_puppet(puppet, x, c, frames, threads=2, device=device), expected) < TOL


def test_run_puppet_rejects_bad_input():
    rng = np.random.default_rng(2)
    puppet = random_puppet(rng, "linear", solver=False)
    x = rng.normal(size=(3, 12))
    with pytest.raises(ValueError, match="translation operator"):
        gpu.run_puppet(puppet, x, None, translation_solver=True)
    with pytest.raises(ValueError, match="world_frames"):
        gpu.run_puppet(puppet, x, None, np.eye(4)[None], translation_solver=False)
    with pytest.raises(ValueError, match="standardised_controls"):
        gpu.run_puppet(puppet, x[:, :5], None, translation_solver=False)


@pytest.fixture(scope="module")
def trained_puppet():
    from skinsynth.pipeline.inputs.examples import synthetic_lbs
    from skinsynth.pipeline.puppet.puppet import train_puppet

    data = synthetic_lbs(bones=5, frames=24, rings=16, segments=8)
    return data, train_puppet(data["vertices"], data["rest"], data["faces"], data["bone_indices"],
                              data["bone_weights"], data["rotations"], data["translations"], [3, 30, 60, 90, 110, 125],
                              np.arange(24), global_motion="control-frame", skinning="dual-quaternion")


@pytest.mark.parametrize("solver", [True, False])
def test_run_puppet_matches_predict_vertices(trained_puppet, solver, device):
    from skinsynth.pipeline.puppet.puppet import predict_vertices

    data, puppet = trained_puppet
    rng = np.random.default_rng(0)
    # the training frames, and the same motions carried elsewhere (the world frames matter)
    controls = data["vertices"][:, puppet.control_indices]
    turn = random_rotations(rng, (controls.shape[0],))
    moved = np.einsum("fab,fnb->fna", turn, controls) + rng.normal(size=(controls.shape[0], 1, 3)) * 3.0
    controls = np.concatenate([controls, moved])
    expected = predict_vertices(puppet, controls, translation_solver=solver)
    x, placed, frames = host_inputs(puppet, controls)
    got = gpu.run_puppet(puppet, x, placed, frames, translation_solver=solver, device=device)
    assert relative_error(got, expected) < TOL
    reference = gpu.reference_run_puppet(puppet, x, placed, frames, translation_solver=solver)
    assert relative_error(reference, expected) < 1e-10


def with_correctives(rng, puppet):
    """The PuppetArrays ``puppet`` with random pose-space correctives (blend weights A ξ)."""
    import dataclasses

    n_p, verts = puppet.training_controls.shape[0], puppet.rest_vertices.shape[0]
    return dataclasses.replace(puppet, corrective_weights=rng.normal(size=(n_p, n_p)) * 0.5,
                               corrective_offsets=rng.normal(size=(n_p, verts, 3)) * 0.05)


@pytest.mark.parametrize("solver", [True, False])
@pytest.mark.parametrize("framed", [True, False])
@pytest.mark.parametrize("corrected", [False, True])
@pytest.mark.parametrize("threads", [1, 3])
def test_run_puppet_linear_matches_reference(solver, framed, corrected, threads, device):
    rng = np.random.default_rng(1 + solver + 2 * framed + 4 * corrected)
    puppet = random_puppet(rng, "gaussian", influences=3)
    if corrected:
        puppet = with_correctives(rng, puppet)
    samples = 70  # more than one fixed block of the CPU correctives over 3 threads
    x, c = rng.normal(size=(samples, 12)) * 0.3, rng.normal(size=(samples, 4, 3))
    frames = random_rigid_frames(rng, samples) if framed else None
    expected = gpu.reference_run_puppet(puppet, x, c, frames, translation_solver=solver, skinning="linear")
    got = gpu.run_puppet(puppet, x, c, frames, translation_solver=solver, device=device, threads=threads,
                         skinning="linear")
    assert relative_error(got, expected) < TOL
    out = np.zeros((samples, 400, 3), dtype=np.float32)  # on the CPU skinned in place (correctives too)
    assert gpu.run_puppet(puppet, x, c, frames, translation_solver=solver, device=device, threads=threads,
                          out=out, skinning="linear") is out
    assert relative_error(out.astype(np.float64), expected) < TOL
    # the skinning matters: dual quaternions give other vertices
    dq = gpu.reference_run_puppet(puppet, x, c, frames, translation_solver=solver)
    assert relative_error(dq, expected) > 1e-3


def test_run_puppet_linear_chunks_and_timings(monkeypatch, device):
    rng = np.random.default_rng(11)
    puppet = with_correctives(rng, random_puppet(rng, "polynomial", influences=4))
    samples = 23
    x, c, frames = rng.normal(size=(samples, 12)) * 0.3, rng.normal(size=(samples, 4, 3)), random_rigid_frames(rng, samples)
    expected = gpu.reference_run_puppet(puppet, x, c, frames, skinning="linear")
    monkeypatch.setattr(puppet_run, "_DEVICE_CHUNK", 2000)  # 5 samples per chunk over 400 vertices
    timings = {}
    got = gpu.run_puppet(gpu.DevicePuppet(puppet, device), x, c, frames, timings=timings, threads=2,
                         skinning="linear")
    assert relative_error(got, expected) < TOL
    assert {"compose", "skin"} <= set(timings)
    assert "rigid" not in timings  # each bone's [R | t] is made in the composing launch


def test_run_puppet_rejects_an_unknown_skinning():
    rng = np.random.default_rng(2)
    puppet = random_puppet(rng, "linear", solver=False)
    x = rng.normal(size=(3, 12))
    for run in (gpu.run_puppet, gpu.reference_run_puppet):
        with pytest.raises(ValueError, match="skinning must be one of"):
            run(puppet, x, None, translation_solver=False, skinning="lbs")


def random_pipeline_puppet(rng, global_motion, solver=True, corrected=False, skinning="linear"):
    """A ``pipeline.puppet.Puppet`` around :func:`random_puppet`'s arrays (n_c = 4 controls)."""
    from skinsynth.pipeline.puppet.correctives import Correctives
    from skinsynth.pipeline.puppet.kcca import ControlKernel, KccaRegression
    from skinsynth.pipeline.puppet.poisson import TranslationOperator
    from skinsynth.pipeline.puppet.puppet import Puppet

    arrays = random_puppet(rng, "gaussian", solver=solver)
    if corrected:
        arrays = with_correctives(rng, arrays)
    bones, n_p, d = arrays.bones, *arrays.training_controls.shape
    return Puppet(
        rest_vertices=arrays.rest_vertices, bone_indices=arrays.bone_indices, bone_weights=arrays.bone_weights,
        control_indices=np.arange(4), reference_controls=rng.normal(size=(4, 3)), global_motion=global_motion,
        kernel=ControlKernel(kind="gaussian", mean=rng.normal(size=d), scale=4.0),
        training_controls=arrays.training_controls,
        regression=KccaRegression(predictor=arrays.predictor.reshape(bones, 8, n_p), bias=arrays.bias.reshape(bones, 8),
                                  correlations=np.ones((bones, 1)), regularization=np.full(bones, 1e-2)),
        translations=TranslationOperator(arrays.rotation_operator, arrays.control_operator,
                                         arrays.prior_operator) if solver else None,
        beta=1.0, train_frames=np.arange(n_p),
        correctives=Correctives(arrays.corrective_weights, arrays.corrective_offsets, 1e-3) if corrected else None,
        skinning=skinning)


@pytest.mark.parametrize("global_motion", ["control-frame", "world"])
@pytest.mark.parametrize("solver", [True, False])
@pytest.mark.parametrize("corrected", [False, True])
def test_linear_reference_run_matches_predict_vertices(global_motion, solver, corrected):
    from skinsynth.pipeline.puppet.puppet import predict_vertices

    rng = np.random.default_rng(3 + solver + 2 * corrected)
    puppet = random_pipeline_puppet(rng, global_motion, solver, corrected)
    controls = rng.normal(size=(12, 4, 3)) * 2.0
    expected = predict_vertices(puppet, controls, translation_solver=solver, skinning="linear")
    x, placed, frames = host_inputs(puppet, controls)
    got = gpu.reference_run_puppet(puppet, x, placed, frames, translation_solver=solver, skinning="linear")
    assert relative_error(got, expected) < 1e-12


@pytest.mark.parametrize("solver", [True, False])
def test_run_puppet_linear_matches_predict_vertices(trained_puppet, solver, device):
    from skinsynth.pipeline.puppet.puppet import predict_vertices

    data, puppet = trained_puppet
    controls = data["vertices"][:, puppet.control_indices]
    expected = predict_vertices(puppet, controls, translation_solver=solver, skinning="linear")
    got = gpu.run_puppet(puppet, *host_inputs(puppet, controls), translation_solver=solver, device=device,
                         skinning="linear")
    assert relative_error(got, expected) < TOL


@pytest.mark.parametrize("skinning", ["dual-quaternion", "linear"])
def test_play_characters_plays_both_skinnings_on_the_device(skinning, device):
    from skinsynth.pipeline.puppet.playback import play_characters
    from skinsynth.pipeline.puppet.puppet import predict_vertices

    rng = np.random.default_rng(5)
    puppet = random_pipeline_puppet(rng, "control-frame", corrected=True, skinning=skinning)
    controls = rng.normal(size=(20, 4, 3)) * 2.0
    vertices, seconds, _ = play_characters(puppet, controls, device, skinning, threads=2)
    assert vertices.dtype == np.float32 and seconds > 0.0
    expected = predict_vertices(puppet, controls, skinning=skinning)
    assert relative_error(vertices.astype(np.float64), expected) < TOL


def test_the_kernels_sit_below_the_pipeline():
    """Layers point one way (cli → pipeline → gpu): no module of gpu/ (its subpackages too) imports
    the pipeline or climbs out of gpu with a relative import, not even inside a function."""
    import ast
    import pathlib

    import skinsynth.gpu

    root = pathlib.Path(skinsynth.gpu.__file__).parent
    for path in root.rglob("*.py"):
        depth = len(path.relative_to(root).parts) - 1  # 0 for gpu/x.py, 1 for gpu/kernels/x.py
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                names, level = [node.module or ""], node.level
            elif isinstance(node, ast.Import):
                names, level = [alias.name for alias in node.names], 0
            else:
                continue
            assert level <= depth + 1 and not [n for n in names if "pipeline" in n], (path.name, level, names)
