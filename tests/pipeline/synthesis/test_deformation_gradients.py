import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skinsynth.pipeline.synthesis.deformation_gradients import (deformation_gradients, gradient_operator, pack_positions,
                                                      rotation_strain, rotation_strain_to_matrix)
from skinsynth.pipeline.inputs.examples import synthetic_lbs
from skinsynth.pipeline.synthesis.key_vertices import gather_weights, key_vertices, vertex_neighbours, weight_gradients
from skinsynth.pipeline.rig.rotations import rotation_log

from mesh_cases import irregular_sphere, random_sparse_weights


def local_frame(rotations, translations, reference):
    """Zheng eq. 2: positions of every bone in the reference bone's frame."""
    rr = rotations[:, reference]
    local_r = np.swapaxes(rr, -1, -2)[:, None] @ rotations
    local_t = np.einsum("fba,fkb->fka", rr, translations - translations[:, reference, None])
    return local_r, local_t


def key_setup(rest, faces, idx, w, bones):
    kv = key_vertices(idx, w, bones)
    key_bones, grads = weight_gradients(rest, vertex_neighbours(faces, rest.shape[0]), idx, w, kv.vertices)
    return kv.vertices, key_bones, gather_weights(idx, w, kv.vertices, key_bones), grads


def lbs_case(bones=6, max_influences=4, **kwargs):
    model = synthetic_lbs(bones=bones, max_influences=max_influences, **kwargs)
    idx, w = model["bone_indices"], model["bone_weights"]
    key, key_bones, key_weights, grads = key_setup(model["rest"], model["faces"], idx, w, bones)
    reference = int(np.argmax(np.bincount(idx.ravel(), weights=w.ravel(), minlength=bones)))
    ids = np.array([b for b in range(bones) if b != reference])
    local_r, local_t = local_frame(model["rotations"], model["translations"], reference)
    return dict(model=model, key=key, key_bones=key_bones, key_weights=key_weights, grads=grads,
                reference=reference, ids=ids, R=local_r[:, ids], t=local_t[:, ids])


def test_rotation_strain_round_trip():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(200, 3, 3)) + 2.0 * np.eye(3)
    d[np.linalg.det(d) < 0] *= -1.0
    assert np.all(np.linalg.det(d) > 0)
    coords = rotation_strain(d)
    assert coords.shape == (200, 9)
    assert np.abs(rotation_strain_to_matrix(coords) - d).max() < 1e-12
    # A pure rotation is (Φ(R), identity strain); a stretch is (0, its upper triangle).
    r = Rotation.random(10, random_state=1).as_matrix()
    assert np.allclose(rotation_strain(r)[:, :3], rotation_log(r), atol=1e-12)
    assert np.allclose(rotation_strain(r)[:, 3:], [1, 0, 0, 1, 0, 1], atol=1e-12)
    s = np.array([[2.0, 0.1, 0.2], [0.1, 1.5, 0.3], [0.2, 0.3, 1.2]])
    assert np.allclose(rotation_strain(s), [0, 0, 0, 2.0, 0.1, 0.2, 1.5, 0.3, 1.2], atol=1e-12)
    # det < 0: U stays a proper rotation, S takes the negative eigenvalue; still invertible.
    flipped = -d[:20]
    assert np.all(np.linalg.det(flipped) < 0)
    assert np.abs(rotation_strain_to_matrix(rotation_strain(flipped)) - flipped).max() < 1e-12
    # Batched over arbitrary leading axes.
    assert rotation_strain(d.reshape(4, 50, 3, 3)).shape == (4, 50, 9)


def test_eq8_is_the_jacobian_of_lbs_with_linear_weights():
    # With weights linear in space the LBS map x ↦ Σ_b w_b(x)(F_b x + t_b) is smooth in 3D and
    # recovered gradients are exact, so eq. 8 must equal its Jacobian (central differences).
    rest, faces = irregular_sphere(200, seed=3)
    a = np.array([[0.10, 0.05, -0.02], [-0.04, 0.08, 0.03], [-0.06, -0.13, -0.01]])
    c = np.array([0.4, 0.3, 0.3])
    idx = np.tile(np.arange(3), (rest.shape[0], 1))
    w = rest @ a.T + c
    key, key_bones, key_weights, grads = key_setup(rest, faces, idx, w, 3)
    rng = np.random.default_rng(0)
    f = np.eye(3) + 0.3 * rng.normal(size=(1, 3, 3, 3))
    t = rng.normal(size=(1, 3, 3))
    D = deformation_gradients(f, t, np.arange(3), None, rest, key, key_bones, key_weights, grads)[0]

    def lbs(x):
        return np.einsum("b,bij,j->i", x @ a.T + c, f[0], x) + (x @ a.T + c) @ t[0]

    h = 1e-5
    for row, v in enumerate(key):
        jac = np.stack([(lbs(rest[v] + h * e) - lbs(rest[v] - h * e)) / (2 * h) for e in np.eye(3)], axis=1)
        assert np.abs(D[row] - jac).max() < 1e-8


@pytest.mark.parametrize("mesh", ["tube", "sphere"])
def test_affine_motion_gives_its_matrix(mesh):
    if mesh == "tube":
        model = synthetic_lbs(bones=6, max_influences=4)
        rest, faces, idx, w = model["rest"], model["faces"], model["bone_indices"], model["bone_weights"]
        bones = 6
    else:
        rest, faces = irregular_sphere(300, seed=7)
        idx, w = random_sparse_weights(rest.shape[0], 8, 4, seed=7)
        bones = 8
    key, key_bones, key_weights, grads = key_setup(rest, faces, idx, w, bones)
    rng = np.random.default_rng(1)
    f = np.eye(3) + 0.5 * rng.normal(size=(5, 3, 3))
    t = rng.normal(size=(5, 3))
    # Every bone at {F, t} (no reference bone): D_i = F at every key vertex (Zheng eq. 15).
    all_r = np.repeat(f[:, None], bones, axis=1)
    all_t = np.repeat(t[:, None], bones, axis=1)
    D = deformation_gradients(all_r, all_t, np.arange(bones), None, rest, key, key_bones, key_weights, grads)
    assert np.abs(D - f[:, None]).max() < 1e-10
    # In the reference bone's frame a rigid motion of the whole mesh is the identity everywhere.
    reference = 0
    rot = Rotation.random(5, random_state=2).as_matrix()
    local_r, local_t = local_frame(np.repeat(rot[:, None], bones, 1), np.repeat(t[:, None], bones, 1), reference)
    ids = np.arange(1, bones)
    D = deformation_gradients(local_r[:, ids], local_t[:, ids], ids, reference, rest, key, key_bones,
                              key_weights, grads)
    assert np.abs(D - np.eye(3)).max() < 1e-10


@pytest.mark.parametrize("bones,influences", [(6, 4), (8, 3), (4, 2)])
def test_operator_matches_eq8_and_solve_recovers_bones(bones, influences):
    case = lbs_case(bones, influences)
    args = (case["ids"], case["reference"], case["model"]["rest"], case["key"], case["key_bones"],
            case["key_weights"], case["grads"])
    D = deformation_gradients(case["R"], case["t"], *args)
    op = gradient_operator(*args)
    n, count = case["key"].shape[0], case["ids"].shape[0]
    assert op.matrix.shape == (9 * n, 12 * count)
    # d = G p + c (Zheng eq. 9 form of eq. 8), through the sparse matrix directly.
    p = pack_positions(case["R"], case["t"])
    d = (op.matrix @ p.T).T + op.constant
    assert np.abs(d.reshape(D.shape) - D).max() < 1e-10
    assert np.abs(op.apply(case["R"], case["t"]) - D).max() < 1e-10
    # Full column rank on this model, so the least-squares solve returns the true positions.
    assert op.rank() == 12 * count
    assert np.linalg.matrix_rank(op.matrix.toarray()) == 12 * count
    f_local, t_local = op.solve(D)
    assert f_local.shape == case["R"].shape and t_local.shape == case["t"].shape
    assert np.abs(f_local - case["R"]).max() < 1e-8
    assert np.abs(t_local - case["t"]).max() < 1e-8
    # Many frames at once equals frame by frame.
    one = op.solve(D[3:4])
    assert np.allclose(one[0][0], f_local[3], atol=1e-12) and np.allclose(one[1][0], t_local[3], atol=1e-12)


def test_solve_via_rotation_strain_round_trip():
    # The synthesis path: D -> d (blended elsewhere) -> D̃ -> bones.
    case = lbs_case(6, 4, seed=3)
    args = (case["ids"], case["reference"], case["model"]["rest"], case["key"], case["key_bones"],
            case["key_weights"], case["grads"])
    D = deformation_gradients(case["R"], case["t"], *args)
    f_local, t_local = gradient_operator(*args).solve(rotation_strain_to_matrix(rotation_strain(D)))
    assert np.abs(f_local - case["R"]).max() < 1e-8 and np.abs(t_local - case["t"]).max() < 1e-8


def test_rank_deficient_model_is_regularised():
    # Hard (one-influence) weights: a bone's weight gradient vanishes where its key vertex is, so
    # its translation is not determined by the key vertices; the ridge keeps the solve finite.
    case = lbs_case(6, 1)
    args = (case["ids"], case["reference"], case["model"]["rest"], case["key"], case["key_bones"],
            case["key_weights"], case["grads"])
    D = deformation_gradients(case["R"], case["t"], *args)
    op = gradient_operator(*args)
    assert op.rank() < 12 * case["ids"].shape[0]
    f_local, t_local = op.solve(D)
    assert np.all(np.isfinite(f_local)) and np.all(np.isfinite(t_local))
    # D lies in the range of G + c, so the solution reproduces it even if it is not unique.
    assert np.abs(op.apply(f_local, t_local) - D).max() < 1e-8


def test_bad_bone_lists_are_refused():
    case = lbs_case(6, 4)
    rest = case["model"]["rest"]
    with pytest.raises(ValueError, match="reference"):
        deformation_gradients(case["R"], case["t"], np.arange(5), 0, rest, case["key"], case["key_bones"],
                              case["key_weights"], case["grads"])
    with pytest.raises(ValueError, match="neither"):
        gradient_operator(case["ids"][:-1], case["reference"], rest, case["key"], case["key_bones"],
                          case["key_weights"], case["grads"])


def test_damped_solve_pins_the_damped_bones_and_solves_the_rest():
    case = lbs_case(6, 4)
    args = (case["ids"], case["reference"], case["model"]["rest"], case["key"], case["key_bones"],
            case["key_weights"], case["grads"])
    op = gradient_operator(*args)
    D = deformation_gradients(case["R"], case["t"], *args)
    F0, t0 = op.solve(D)
    F1, t1 = op.solve_damped(D, [], 1.0)  # nothing damped: the plain solve
    assert np.array_equal(F0, F1) and np.array_equal(t0, t1)
    F2, t2 = op.solve_damped(D, case["ids"][:2], 0.0)  # no damping: the plain solve
    assert np.array_equal(F0, F2) and np.array_equal(t0, t2)
    # A huge damping pins the damped bones at 0; the others are the least-squares solution with
    # those columns removed (brute force with a dense lstsq).
    damped = case["ids"][:2]
    F3, t3 = op.solve_damped(D, damped, 1e12)
    assert np.abs(F3[:, :2]).max() < 1e-6 and np.abs(t3[:, :2]).max() < 1e-6
    G = op.matrix.toarray()
    keep = np.repeat(~np.isin(case["ids"], damped), 12)
    rhs = (D.reshape(D.shape[0], -1) - op.constant).T
    p = np.linalg.lstsq(G[:, keep], rhs, rcond=None)[0].T.reshape(D.shape[0], -1, 12)
    assert np.abs(F3[:, 2:] - p[..., :9].reshape(F3[:, 2:].shape)).max() < 1e-5
    assert np.abs(t3[:, 2:] - p[..., 9:]).max() < 1e-5
    # A moderate damping lies in between: the damped bones move less than in the plain solve.
    F4, _ = op.solve_damped(D, damped, 1e-1)
    assert np.abs(F4[:, :2]).max() < np.abs(F0[:, :2]).max()
