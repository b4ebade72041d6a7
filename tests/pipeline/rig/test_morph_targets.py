"""pipeline.morph_targets against closed forms: rank-r correctives need exactly r targets and
reconstruct every played blend; what is never played needs none; more than the maximum is
refused with the count needed; the targets do not depend on the shapes' order or signs; a glTF
rig (pipeline.skeleton) carries them in its axes and across its UV seams."""

import numpy as np
import pytest

from skinsynth.pipeline.rig import morph_targets
from skinsynth.pipeline.rig.morph_targets import MAX_MORPH_TARGETS, corrective_morph_targets


def low_rank(rng, shapes, rank, verts):
    """offsets (shapes, verts, 3) of exactly ``rank``, components of order one."""
    basis = np.linalg.qr(rng.normal(size=(shapes, rank)))[0]
    rows = np.linalg.qr(rng.normal(size=(3 * verts, rank)))[0].T
    return (basis @ np.diag(np.linspace(3.0, 1.0, rank)) @ rows).reshape(shapes, verts, 3), basis


@pytest.mark.parametrize("rank", [1, 3, MAX_MORPH_TARGETS])
def test_rank_r_correctives_need_exactly_r_targets_and_reconstruct_every_played_blend(rank):
    rng = np.random.default_rng(rank)
    offsets, _ = low_rank(rng, 12, rank, 50)
    weights = rng.normal(size=(40, 12))
    targets, target_weights, error = corrective_morph_targets(offsets, weights, diagonal=1.0)
    assert targets.shape == (rank, 50, 3) and target_weights.shape == (40, rank)
    played = np.einsum("fp,pvc->fvc", weights, offsets)
    rebuilt = np.einsum("fk,kvc->fvc", target_weights, targets)
    assert np.abs(rebuilt - played).max() <= 1e-12 and error <= 1e-12
    largest = np.abs(targets.reshape(rank, -1)).argmax(axis=1)
    assert (targets.reshape(rank, -1)[np.arange(rank), largest] > 0).all()  # the sign rule


def test_a_component_no_frame_plays_needs_no_target():
    rng = np.random.default_rng(4)
    offsets, basis = low_rank(rng, 10, 3, 30)  # singular values 3, 2, 1
    weights = rng.normal(size=(25, 10))
    weights -= np.outer(weights @ basis[:, 2], basis[:, 2])  # the last component is never blended in
    targets, target_weights, _ = corrective_morph_targets(offsets, weights, diagonal=1.0)
    assert len(targets) == 2
    np.testing.assert_allclose(np.einsum("fk,kvc->fvc", target_weights, targets),
                               np.einsum("fp,pvc->fvc", weights, offsets), atol=1e-12)
    none, none_weights, error = corrective_morph_targets(np.zeros((4, 30, 3)), rng.normal(size=(6, 4)), 1.0)
    assert none.shape == (0, 30, 3) and none_weights.shape == (6, 0) and error == 0.0


def test_the_tolerance_is_relative_to_the_diagonal_and_the_error_is_the_largest_vertex_distance(monkeypatch):
    rng = np.random.default_rng(5)
    offsets, _ = low_rank(rng, 10, 4, 30)
    offsets[:, :, :] += 1e-4 * rng.normal(size=offsets.shape)  # full rank, small tail
    weights = rng.normal(size=(33, 10))
    monkeypatch.setattr(morph_targets, "_CHUNK_VALUES", 90 * 7)  # 7 frames a chunk: the chunks' maxima combine
    for diagonal, tolerance in ((1.0, 1e-2), (1e3, 1e-5), (1.0, 1e-9)):
        targets, target_weights, error = corrective_morph_targets(offsets, weights, diagonal, tolerance, maximum=10)
        played = np.einsum("fp,pvc->fvc", weights, offsets)
        distance = np.linalg.norm(np.einsum("fk,kvc->fvc", target_weights, targets) - played, axis=2).max()
        assert error == pytest.approx(distance / diagonal, rel=1e-9, abs=1e-13) and error <= tolerance
        fewer = targets[:-1], target_weights[:, :-1]  # one fewer would not do
        assert len(targets) == 0 or np.linalg.norm(np.einsum("fk,kvc->fvc", *fewer[::-1]) - played,
                                                   axis=2).max() > tolerance * diagonal


def test_more_targets_than_the_maximum_are_refused_with_the_count_needed():
    rng = np.random.default_rng(6)
    offsets, _ = low_rank(rng, 12, 11, 40)
    with pytest.raises(ValueError) as refused:
        corrective_morph_targets(offsets, rng.normal(size=(30, 12)), diagonal=1.0)
    message = str(refused.value)
    assert "need 11 morph targets" in message and f"{MAX_MORPH_TARGETS} leave" in message
    assert "--correctives off" in message and ".usdc" in message and "\n" not in message
    targets, _, _ = corrective_morph_targets(offsets, rng.normal(size=(30, 12)), diagonal=1.0, maximum=11)
    assert len(targets) == 11


def test_the_targets_do_not_depend_on_the_shapes_order_or_signs():
    rng = np.random.default_rng(7)
    offsets, _ = low_rank(rng, 9, 4, 20)
    weights = rng.normal(size=(15, 9))
    targets, target_weights, _ = corrective_morph_targets(offsets, weights, 1.0)
    order, signs = rng.permutation(9), np.where(rng.random(9) < 0.5, -1.0, 1.0)
    again, again_weights, _ = corrective_morph_targets(offsets[order] * signs[:, None, None], weights[:, order] * signs,
                                                       1.0)
    np.testing.assert_allclose(again, targets, atol=1e-12)
    np.testing.assert_allclose(again_weights, target_weights, atol=1e-12)


def test_a_rigs_morph_targets_turn_and_scale_as_its_positions_and_follow_its_uv_seams():
    """pipeline.skeleton.gltf_rig: displacements in glTF's axes and metres (Z up, centimetres
    here), and a vertex split at a UV seam carries its original's displacement."""
    from skinsynth.pipeline.rig.skeleton import gltf_rig, to_gltf_axes

    rng = np.random.default_rng(8)
    rest, faces = rng.normal(size=(4, 3)), np.array([[0, 1, 2], [0, 2, 3]])
    face_uvs = np.array([[[0, 0], [1, 0], [1, 1]], [[0.5, 0], [1, 1], [0, 1]]], dtype=float)  # vertex 0: two UVs
    indices, weights = np.zeros((4, 1), dtype=np.int64), np.ones((4, 1))
    targets = rng.normal(size=(2, 4, 3))
    axes = dict(up_axis="Z", meters_per_unit=0.01)
    rotation, scale = to_gltf_axes(**axes)
    rig = gltf_rig(rest, faces, indices, weights, np.zeros((1, 3)), **axes, morph_targets=targets)
    np.testing.assert_allclose(rig["morph_targets"], scale * targets @ rotation.T, atol=1e-15)
    split = gltf_rig(rest, faces, indices, weights, np.zeros((1, 3)), **axes, face_uvs=face_uvs,
                     morph_targets=targets)
    assert split["positions"].shape == (5, 3) and split["morph_targets"].shape == (2, 5, 3)
    np.testing.assert_array_equal(split["morph_targets"][:, 4], rig["morph_targets"][:, 0])
    np.testing.assert_array_equal(split["positions"][4], split["positions"][0])


def test_unit_range_pairs_blend_the_same_with_weights_in_unit_range():
    from skinsynth.pipeline.rig.morph_targets import unit_range_pairs

    rng = np.random.default_rng(4)
    shapes, weights = rng.normal(size=(3, 7, 3)), rng.normal(size=(2, 5, 3))
    weights[..., 2] = 0.0  # a shape no frame uses keeps finite pairs
    pairs, split = unit_range_pairs(shapes, weights)
    assert pairs.shape == (6, 7, 3) and split.shape == (2, 5, 6)
    assert split.min() >= 0.0 and split.max() <= 1.0 + 1e-15
    assert np.all(np.minimum(split[..., 0::2], split[..., 1::2]) == 0.0)
    assert np.abs(np.einsum("cfs,svx->cfvx", split, pairs) - np.einsum("cfs,svx->cfvx", weights, shapes)).max() < 1e-12


def test_played_morph_targets_split_the_weights_per_character_and_name_the_puppet_in_a_refusal():
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.rig.morph_targets import played_morph_targets

    rng = np.random.default_rng(8)
    offsets, _ = low_rank(rng, 6, 2, 40)
    assert played_morph_targets(offsets, None, 1.0, 2, "p.h5") is None  # no correctives
    targets, weights, error = played_morph_targets(offsets, rng.normal(size=(2 * 15, 6)), 1.0, 2, "p.h5")
    assert len(targets) == 2 and [w.shape for w in weights] == [(15, 2), (15, 2)] and error <= 1e-6
    offsets, _ = low_rank(rng, 12, 11, 40)
    with pytest.raises(OptionError, match=r"^p\.h5: .*need 11 morph targets"):
        played_morph_targets(offsets, rng.normal(size=(30, 12)), 1.0, 1, "p.h5")
