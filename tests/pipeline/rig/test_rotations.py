import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skinsynth.pipeline.rig.rotations import (align_hemispheres, dual_quaternion_to_rigid, matrix_to_quaternion,
                                          polar_rotation, quaternion_multiply, quaternion_to_matrix,
                                          rigid_to_dual_quaternion, rotation_exp, rotation_log)


@pytest.fixture
def rotations():
    return Rotation.random(50, random_state=3).as_matrix()


def test_polar_rotation_is_nearest_proper_rotation(rotations):
    rng = np.random.default_rng(0)
    noisy = rotations + 0.05 * rng.normal(size=rotations.shape)
    r = polar_rotation(noisy)
    assert np.allclose(r @ np.swapaxes(r, -1, -2), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(r), 1.0)
    # Reflections are turned into the closest proper rotation, not returned.
    reflected = rotations @ np.diag([1.0, 1.0, -1.0])
    assert np.all(np.linalg.det(polar_rotation(reflected)) > 0)
    # Brute force: no random rotation is closer in Frobenius norm than the polar factor.
    candidates = Rotation.random(2000, random_state=1).as_matrix()
    best = np.linalg.norm(candidates - noisy[0], axis=(1, 2)).min()
    assert np.linalg.norm(r[0] - noisy[0]) <= best + 1e-12


def test_quaternion_round_trip_and_product(rotations):
    q = matrix_to_quaternion(rotations)
    assert np.all(q[:, 0] >= 0)
    assert np.allclose(quaternion_to_matrix(q), rotations)
    # The Hamilton product composes rotations: R(a*b) = R(a) R(b).
    ab = quaternion_multiply(q[:25], q[25:])
    assert np.allclose(quaternion_to_matrix(ab), rotations[:25] @ rotations[25:])


def test_dual_quaternion_round_trip_transforms_points(rotations):
    rng = np.random.default_rng(1)
    t = rng.normal(size=(50, 3))
    dq = rigid_to_dual_quaternion(rotations, t)
    r2, t2 = dual_quaternion_to_rigid(3.0 * dq)  # not unit: normalised on the way back
    assert np.allclose(r2, rotations) and np.allclose(t2, t)
    # Acting on a point as q0 p q0* + 2 qe q0* matches R p + t.
    p = rng.normal(size=(50, 3))
    q0, qe = dq[:, :4], dq[:, 4:]
    conj = q0 * np.array([1, -1, -1, -1])
    pure = np.concatenate([np.zeros((50, 1)), p], axis=1)
    moved = quaternion_multiply(quaternion_multiply(q0, pure), conj)[:, 1:] + 2 * quaternion_multiply(qe, conj)[:, 1:]
    assert np.allclose(moved, np.einsum("nab,nb->na", rotations, p) + t)


def test_align_hemispheres_gives_continuous_signs():
    angles = np.linspace(0, 6.0, 40)
    r = rotation_exp(angles[:, None] * np.array([0.0, 0.0, 1.0]))
    q = matrix_to_quaternion(r)  # w >= 0 forces a jump once the angle passes pi
    assert np.max(np.abs(np.diff(q, axis=0))) > 1.0
    aligned = align_hemispheres(q[:, None, :], axis=0)[:, 0]
    assert np.max(np.abs(np.diff(aligned, axis=0))) < 0.1
    assert np.allclose(quaternion_to_matrix(aligned), r)


def test_log_exp_inverse(rotations):
    assert np.allclose(rotation_exp(rotation_log(rotations)), rotations)
    small = np.random.default_rng(2).uniform(-1, 1, size=(20, 3))
    assert np.allclose(rotation_log(rotation_exp(small)), small)


def test_polar_decomposition_matches_scipy_and_near_rotations_shortcut(rotations):
    import scipy.linalg

    from skinsynth.pipeline.rig.rotations import apply_rigid_into, polar_decomposition, polar_of_near_rotations

    rng = np.random.default_rng(1)
    stretched = rotations @ (np.eye(3) + 0.1 * rng.normal(size=(50, 3, 3)))
    stretched = stretched[np.linalg.det(stretched) > 0]
    U, S = polar_decomposition(stretched[None])  # any leading shape
    U, S = U[0], S[0]
    for m, u, s in zip(stretched, U, S):
        u_ref, s_ref = scipy.linalg.polar(m)
        assert np.abs(u - u_ref).max() < 1e-10 and np.abs(s - s_ref).max() < 1e-10
    # Rotations rounded to float32 are taken as they are (U = F, S = I); stretched ones are solved.
    mixed = np.concatenate([rotations.astype(np.float32), stretched.astype(np.float32)])
    U, S = polar_of_near_rotations(mixed)
    assert np.array_equal(U[:50], mixed[:50].astype(np.float64))
    assert np.array_equal(S[:50], np.broadcast_to(np.eye(3), (50, 3, 3)))
    U_ref, S_ref = polar_decomposition(mixed[50:])
    assert np.array_equal(U[50:], U_ref) and np.array_equal(S[50:], S_ref)
    # apply_rigid_into: R F and R t + c for chosen bones of chosen walks into chosen slots, against a
    # plain loop, across animation blocks.
    R = rotations[:48].reshape(4, 12, 3, 3)
    c = rng.normal(size=(4, 12, 3))
    F = rng.normal(size=(3, 12, 4, 3, 3))
    t = rng.normal(size=(3, 12, 4, 3))
    rows, bones, slots = np.array([2, 0, 2, 1]), np.array([3, 1]), np.array([5, 0])
    F_out, t_out = np.zeros((4, 12, 6, 3, 3)), np.zeros((4, 12, 6, 3))
    apply_rigid_into(F_out, t_out, slots, R, c, F, t, rows=rows, bones=bones, animation_block=3)
    for a in range(4):
        for m in range(12):
            for bone, slot in zip(bones, slots):
                assert np.allclose(F_out[a, m, slot], R[a, m] @ F[rows[a], m, bone], atol=1e-14)
                assert np.allclose(t_out[a, m, slot], R[a, m] @ t[rows[a], m, bone] + c[a, m], atol=1e-14)
    assert not F_out[:, :, [1, 2, 3, 4]].any()


def test_matrix_to_quaternion_is_scipys_shepperd_method():
    rotations = Rotation.random(5000, random_state=3).as_matrix()
    rotations[:4] = [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])]
    xyzw = Rotation.from_matrix(rotations).as_quat()
    expected = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
    expected *= np.where(expected[:, :1] < 0.0, -1.0, 1.0)
    np.testing.assert_allclose(matrix_to_quaternion(rotations.reshape(50, 100, 3, 3)).reshape(-1, 4), expected,
                               rtol=0, atol=1e-15)
