"""Pose-space correctives (pipeline.correctives): exact at the examples, learnt where the skin falls
short, played the same by numpy, warp and UsdSkel."""

import numpy as np
import pytest

from skinsynth.gpu import (corrective_offsets, corrective_offsets_reference, dq_skin, dqs_reference,
                           reference_run_puppet, run_puppet)
from skinsynth.pipeline.puppet.correctives import (POWER_GRID, RIDGE_GRID, Model, blend_weights, choose_model,
                                            fit_correctives, rest_offsets)
from skinsynth.pipeline.puppet.puppet import predict_vertices, train_puppet

from rigs import random_skin
from puppet_cases import CONTROLS, bulging_tube, random_dual_quaternions


def test_rest_offsets_make_skinning_reproduce_any_target():
    rng = np.random.default_rng(0)
    rest, idx, w = random_skin(rng, 300, 6, 4)
    dq = random_dual_quaternions(rng, 5, 6)
    targets = rng.normal(size=(5, 300, 3))
    offsets = rest_offsets(rest, idx, w, dq, targets)
    assert np.abs(dqs_reference(rest, idx, w, dq, offsets) - targets).max() < 1e-10


def _train(data, train, correctives):
    return train_puppet(data["vertices"], data["rest"], data["faces"], data["bone_indices"], data["bone_weights"],
                        data["rotations"], data["translations"], CONTROLS, train, global_motion="world",
                        correctives=correctives, skinning="dual-quaternion")  # as run_puppet and UsdSkel play it


def _rms(puppet, data, frames):
    predicted = predict_vertices(puppet, data["vertices"][frames][:, CONTROLS])
    return float(np.sqrt(np.mean(np.sum((predicted - data["vertices"][frames]) ** 2, axis=-1))))


def test_correctives_learn_what_the_skin_cannot_and_are_cross_validated():
    data = bulging_tube()
    train, test = np.arange(0, 40, 2), np.arange(1, 40, 2)
    plain, corrected = _train(data, train, "off"), _train(data, train, "auto")
    assert plain.correctives is None and "off" in plain.correctives_reason
    c = corrected.correctives
    assert c is not None and c.ridge in RIDGE_GRID and c.power in POWER_GRID
    assert "cross-validated" in corrected.correctives_reason
    assert corrected.correctives.offsets.shape == (20,) + data["rest"].shape
    # held out: measured 0.061 without, 0.0002 with
    assert _rms(corrected, data, test) < 0.1 * _rms(plain, data, test)


def test_a_tiny_ridge_reproduces_the_training_examples():
    data = bulging_tube()
    train = np.arange(0, 40, 2)
    puppet = _train(data, train, 1e-9)
    assert puppet.correctives.ridge == 1e-9 and puppet.correctives_reason == "ridge 1e-09, chosen by the user (--correctives)"
    assert _rms(puppet, data, train) < 1e-6 * np.ptp(data["rest"], axis=0).max()


def test_choose_model_prefers_none_then_the_simpler_on_ties():
    off = Model(np.inf)
    assert choose_model({off: 1.0, Model(1e-3): 1.0, Model(1.0): 1.2})[0] is None
    ties = {off: 1.0, Model(1e-3): 0.5, Model(1e-2): 0.5, Model(1e-2, 4.0): 0.5, Model(1e-2, 1.0, True): 0.5}
    assert choose_model(ties)[0] == Model(1e-2)
    model, reason = choose_model({off: 1.0, Model(1e-3, 4.0, True): 0.5, Model(1.0): 0.7})
    assert model == Model(1e-3, 4.0, True) and reason.startswith("ridge 0.001, width 1/2, affine tail")
    assert "without correctives 1" in reason


def test_fit_correctives_refuses_a_bad_ridge():
    from skinsynth.pipeline.errors import OptionError

    for ridge in (0.0, -1.0, np.inf, np.nan):
        with pytest.raises(OptionError, match="--correctives"):
            fit_correctives(np.eye(3), np.zeros((3, 2)), np.zeros((3, 4, 3)), Model(ridge))


def test_the_affine_tail_reproduces_offsets_linear_in_the_controls():
    """With the tail, offsets that are an affine function of the controls are predicted exactly
    anywhere, even far from every example, where the Gaussian part has faded."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(12, 4))
    slope, bias = rng.normal(size=(4, 30)), rng.normal(size=30)
    offsets = (x @ slope + bias).reshape(12, 10, 3)
    kernel = np.exp(-0.5 * np.sum((x[:, None] - x[None]) ** 2, axis=-1))
    c = fit_correctives(kernel, x, offsets, Model(1e-3, 1.0, True))
    far = rng.normal(size=(5, 4)) * 10.0
    xi = np.exp(-0.5 * np.sum((far[:, None] - x[None]) ** 2, axis=-1))
    expected = (far @ slope + bias).reshape(5, 10, 3)
    assert np.abs(np.einsum("fj,jvc->fvc", blend_weights(c, xi, far), c.offsets) - expected).max() < 1e-8


def test_corrective_kernels_match_their_reference(device):
    rng = np.random.default_rng(4)
    w, offsets = rng.normal(size=(9, 12)) * 50.0, rng.normal(size=(12, 70, 3)) * 0.01
    expected = corrective_offsets_reference(w, offsets)
    assert np.abs(corrective_offsets(w, offsets, device=device) - expected).max() < 1e-6 * np.abs(expected).max()
    rest, idx, weights = random_skin(rng, 70, 5, 3)
    dq = random_dual_quaternions(rng, 9, 5)
    got = dq_skin(rest, idx, weights, dq, device=device, rest_offsets=expected)
    assert np.abs(got - dqs_reference(rest, idx, weights, dq, expected)).max() < 1e-5


@pytest.mark.parametrize("threads", [1, 2])
def test_run_puppet_plays_the_correctives(threads, device):
    from skinsynth.pipeline.puppet.playback import host_inputs

    data = bulging_tube()
    puppet = _train(data, np.arange(0, 40, 2), "auto")
    controls = data["vertices"][:, CONTROLS]
    expected = predict_vertices(puppet, controls)
    got = run_puppet(puppet, *host_inputs(puppet, controls), threads=threads, device=device)
    assert np.abs(got - expected).max() < 1e-5 * np.ptp(data["rest"], axis=0).max()


def test_usdskel_plays_the_correctives_as_blend_shapes(tmp_path):
    from skinsynth.formats.usd import read_skel_characters, write_skel_characters
    from skinsynth.pipeline.puppet.playback import world_bones

    data = bulging_tube()
    puppet = _train(data, np.arange(0, 40, 2), "auto")
    controls = data["vertices"][:, CONTROLS]
    rotations, translations, weights = world_bones(puppet, controls)
    path = str(tmp_path / "corrected.usda")
    centres = np.zeros((rotations.shape[1], 3))
    from skinsynth.pipeline.rig.morph_targets import unit_range_pairs

    pairs = unit_range_pairs(puppet.correctives.offsets, np.stack([weights] * 2))
    names = [f"shape_{j:03d}{s}" for j in range(len(pairs[0]) // 2) for s in "pn"]
    write_skel_characters(path, data["rest"], data["faces"], data["bone_indices"], data["bone_weights"],
                          np.stack([rotations] * 2), np.stack([translations, translations + 5.0]), centres, 24.0,
                          skinning="dual-quaternion", blend_shapes=(*pairs, names))
    expected = predict_vertices(puppet, controls)
    from pxr import Usd, UsdSkel

    stage = Usd.Stage.Open(path)  # weights as DCCs want them: ± shape pairs, every weight in [0, 1]
    animation = UsdSkel.Animation(stage.GetPrimAtPath("/characters/character_001/Skeleton/Animation"))
    written = np.array([animation.GetBlendShapeWeightsAttr().Get(f) for f in range(len(controls))])
    assert written.shape[1] == 2 * len(puppet.correctives.offsets) and 0.0 <= written.min() and written.max() <= 1.0
    played = read_skel_characters(path)
    assert [name for name, _ in played] == ["/characters/character_000/Mesh", "/characters/character_001/Mesh"]
    scale = np.ptp(data["rest"], axis=0).max()
    assert np.abs(played[0][1] - expected).max() < 1e-5 * scale
    assert np.abs(played[1][1] - 5.0 - expected).max() < 1e-5 * scale


@pytest.mark.parametrize("tail", [False, True])
@pytest.mark.parametrize("threads", [1, 3])
def test_run_puppet_plays_any_corrective_model_as_its_reference(tail, threads, device):
    import dataclasses

    from random_puppets import random_puppet, random_rigid_frames

    rng = np.random.default_rng(10 + tail)
    puppet = random_puppet(rng, "gaussian")
    n_p, d = puppet.training_controls.shape
    puppet = dataclasses.replace(
        puppet, corrective_weights=rng.normal(size=(n_p, n_p)) * 30.0, corrective_power=4.0,
        corrective_offsets=rng.normal(size=(n_p, 400, 3)) * 0.05,
        corrective_tail=rng.normal(size=(n_p, 4)) if tail else None,
        corrective_axes=np.linalg.qr(rng.normal(size=(d, 3)))[0].T if tail else None)
    samples = 150  # more than one fixed block of the CPU path
    x, c, frames = rng.normal(size=(samples, d)) * 0.3, rng.normal(size=(samples, 4, 3)), random_rigid_frames(rng, samples)
    expected = reference_run_puppet(puppet, x, c, frames)
    got = run_puppet(puppet, x, c, frames, threads=threads, device=device)
    assert np.abs(got - expected).max() < 1e-5 * np.abs(expected).max()
