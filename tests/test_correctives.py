"""Pose-space correctives (pipeline.correctives): exact at the examples, learnt where the skin falls
short, played the same by numpy, warp and UsdSkel."""

import numpy as np
import pytest

from skinsynth.gpu import dqs_reference, puppet_kernels as pk
from skinsynth.pipeline.correctives import RIDGE_GRID, choose_ridge, fit_correctives, rest_offsets
from skinsynth.pipeline.examples import synthetic_lbs
from skinsynth.pipeline.puppet import predict_vertices, train_puppet
from skinsynth.pipeline.rotations import rigid_to_dual_quaternion

from rigs import random_skin

CONTROLS = np.array([3, 30, 60, 90, 110, 125])


def random_dual_quaternions(rng, frames, bones):
    from scipy.spatial.transform import Rotation

    rotations = Rotation.random(frames * bones, random_state=rng).as_matrix().reshape(frames, bones, 3, 3)
    return rigid_to_dual_quaternion(rotations, rng.normal(size=(frames, bones, 3)))


def test_rest_offsets_make_skinning_reproduce_any_target():
    rng = np.random.default_rng(0)
    rest, idx, w = random_skin(rng, 300, 6, 4)
    dq = random_dual_quaternions(rng, 5, 6)
    targets = rng.normal(size=(5, 300, 3))
    offsets = rest_offsets(rest, idx, w, dq, targets)
    assert np.abs(dqs_reference(rest, idx, w, dq, offsets) - targets).max() < 1e-10


def bulging_tube(frames=40):
    """An LBS tube whose four bones follow a smooth one-parameter motion (a walk-like cycle),
    plus a bulge no bone motion makes: vertices near the middle move along their own radial
    direction by an amount that depends on the pose (the case skinning cannot fit)."""
    from skinsynth.pipeline.rotations import rotation_exp

    data = synthetic_lbs(bones=4, frames=2, rings=16, segments=8, seed=3)
    rng = np.random.default_rng(1)
    phase = np.linspace(0.0, 2.0 * np.pi, frames, endpoint=False)
    pose = np.stack([np.sin(phase), np.cos(2.0 * phase)], axis=1)  # (F, 2)
    rotations = rotation_exp(np.einsum("fp,pbc->fbc", pose, rng.normal(size=(2, 4, 3)) * 0.3))
    translations = np.einsum("fp,pbc->fbc", pose, rng.normal(size=(2, 4, 3)) * 0.2)
    rest, idx, w = data["rest"], data["bone_indices"], data["bone_weights"]
    moved = np.einsum("fvkab,vb->fvka", rotations[:, idx], rest) + translations[:, idx]
    vertices = np.einsum("fvka,vk->fva", moved, w)
    radial = rest * np.array([0.0, 1.0, 1.0])
    radial /= np.maximum(np.linalg.norm(radial, axis=1, keepdims=True), 1e-9)  # 0 on the axis
    envelope = np.exp(-((rest[:, 0] - 2.0) / 0.8) ** 2)
    amount = 0.2 * pose[:, 0] * pose[:, 1]
    data.update(vertices=vertices + amount[:, None, None] * envelope[None, :, None] * radial[None],
                rotations=rotations, translations=translations)
    return data


def _train(data, train, correctives):
    return train_puppet(data["vertices"], data["rest"], data["faces"], data["bone_indices"], data["bone_weights"],
                        data["rotations"], data["translations"], CONTROLS, train, global_motion="world",
                        correctives=correctives)


def _rms(puppet, data, frames):
    predicted = predict_vertices(puppet, data["vertices"][frames][:, CONTROLS])
    return float(np.sqrt(np.mean(np.sum((predicted - data["vertices"][frames]) ** 2, axis=-1))))


def test_correctives_learn_what_the_skin_cannot_and_are_cross_validated():
    data = bulging_tube()
    train, test = np.arange(0, 40, 2), np.arange(1, 40, 2)
    plain, corrected = _train(data, train, "off"), _train(data, train, "auto")
    assert plain.correctives is None and "off" in plain.correctives_reason
    assert corrected.correctives is not None and corrected.correctives.ridge in RIDGE_GRID
    assert "cross-validated" in corrected.correctives_reason
    assert corrected.correctives.offsets.shape == (20,) + data["rest"].shape
    # held out: measured 0.061 without, 0.0002 with
    assert _rms(corrected, data, test) < 0.1 * _rms(plain, data, test)


def test_a_tiny_ridge_reproduces_the_training_examples():
    data = bulging_tube()
    train = np.arange(0, 40, 2)
    puppet = _train(data, train, 1e-9)
    assert puppet.correctives.ridge == 1e-9 and "user" in puppet.correctives_reason
    assert _rms(puppet, data, train) < 1e-6 * np.ptp(data["rest"], axis=0).max()


def test_choose_ridge_prefers_none_then_the_smoother_on_ties():
    assert choose_ridge({np.inf: 1.0, 1e-3: 1.0, 1.0: 1.2})[0] is None
    assert choose_ridge({np.inf: 1.0, 1e-3: 0.5, 1e-2: 0.5, 1.0: 0.7})[0] == 1e-2
    ridge, reason = choose_ridge({np.inf: 1.0, 1e-3: 0.5, 1.0: 0.7})
    assert ridge == 1e-3 and "off 1" in reason


def test_fit_correctives_refuses_a_bad_ridge():
    from skinsynth.pipeline.errors import OptionError

    for ridge in (0.0, -1.0, np.inf, np.nan):
        with pytest.raises(OptionError, match="--correctives"):
            fit_correctives(np.eye(3), np.zeros((3, 4, 3)), ridge)


def test_corrective_kernels_match_their_reference_on_the_cpu():
    rng = np.random.default_rng(4)
    xi, weights, offsets = rng.random((9, 12)), rng.normal(size=(12, 12)) * 50.0, rng.normal(size=(12, 70, 3)) * 0.01
    expected = pk.corrective_offsets_reference(xi, weights, offsets)
    assert np.abs(pk.corrective_offsets(xi, weights, offsets) - expected).max() < 1e-6 * np.abs(expected).max()
    rest, idx, w = random_skin(rng, 70, 5, 3)
    dq = random_dual_quaternions(rng, 9, 5)
    got = pk.dq_skin(rest, idx, w, dq, rest_offsets=expected)
    assert np.abs(got - dqs_reference(rest, idx, w, dq, expected)).max() < 1e-5


@pytest.mark.parametrize("threads", [1, 2])
def test_run_puppet_plays_the_correctives(threads):
    from skinsynth.pipeline.playback import host_inputs

    data = bulging_tube()
    puppet = _train(data, np.arange(0, 40, 2), "auto")
    controls = data["vertices"][:, CONTROLS]
    expected = predict_vertices(puppet, controls)
    got = pk.run_puppet(puppet, *host_inputs(puppet, controls), threads=threads)
    assert np.abs(got - expected).max() < 1e-5 * np.ptp(data["rest"], axis=0).max()


def test_usdskel_plays_the_correctives_as_blend_shapes(tmp_path):
    from skinsynth.formats.usd import read_skel_characters, write_skel_characters
    from skinsynth.pipeline.playback import world_bones

    data = bulging_tube()
    puppet = _train(data, np.arange(0, 40, 2), "auto")
    controls = data["vertices"][:, CONTROLS]
    rotations, translations, weights = world_bones(puppet, controls)
    path = str(tmp_path / "corrected.usda")
    centres = np.zeros((rotations.shape[1], 3))
    write_skel_characters(path, data["rest"], data["faces"], data["bone_indices"], data["bone_weights"],
                          np.stack([rotations] * 2), np.stack([translations, translations + 5.0]), centres, 24.0,
                          skinning="dual-quaternion", blend_shapes=(puppet.correctives.offsets, np.stack([weights] * 2)))
    expected = predict_vertices(puppet, controls)
    played = read_skel_characters(path)
    assert [name for name, _ in played] == ["/characters/character_000/Mesh", "/characters/character_001/Mesh"]
    scale = np.ptp(data["rest"], axis=0).max()
    assert np.abs(played[0][1] - expected).max() < 1e-5 * scale
    assert np.abs(played[1][1] - 5.0 - expected).max() < 1e-5 * scale
