"""Rotation helpers used everywhere: polar decomposition, quaternions, dual quaternions, axis-angle.

Conventions (the whole project uses them, and docs/format.md states them):
- rotation matrices act on column vectors, ``p' = R @ p + t``;
- quaternions are stored scalar first, ``(w, x, y, z)``; conversion to warp's ``(x, y, z, w)``
  happens only inside ``gpu/``;
- a dual quaternion is 8 numbers, the real quaternion then the dual one, both ``(w, x, y, z)``:
  ``q0 + eps * qe`` with ``qe = 0.5 * (0, t) * q0`` (Kavan et al. 2007, used by Feng §4.3).
"""

import numpy as np


def quaternion_to_matrix(quaternions):
    """quaternions (..., 4), (w, x, y, z), any non-zero length -> rotations (..., 3, 3)."""
    shape = quaternions.shape[:-1]
    q = quaternions.reshape(-1, 4)
    xyzw = np.concatenate([q[:, 1:], q[:, :1]], axis=1)
    from scipy.spatial.transform import Rotation  # here: scipy.spatial costs every command ~0.5 s to import

    return Rotation.from_quat(xyzw).as_matrix().reshape(shape + (3, 3))


def quaternion_multiply(a, b):
    """Hamilton product of (..., 4) quaternions in (w, x, y, z) order."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], axis=-1)


def dual_quaternion_to_rigid(dual_quaternions):
    """dual quaternions (..., 8), not necessarily unit -> (rotations (..., 3, 3), translations (..., 3)).

    The dual quaternion is normalised first (divide both parts by ``|q0|``), as blending
    and regression leave it off the unit sphere.
    """
    q0 = dual_quaternions[..., :4]
    qe = dual_quaternions[..., 4:]
    norm = np.linalg.norm(q0, axis=-1, keepdims=True)
    q0 = q0 / norm
    qe = qe / norm
    conj = q0 * np.array([1.0, -1.0, -1.0, -1.0])
    t = 2.0 * quaternion_multiply(qe, conj)[..., 1:]
    return quaternion_to_matrix(q0), t


def with_translations(dual_quaternions, translations):
    """Unit dual quaternions (..., 8) with their dual part rebuilt from translations (..., 3)."""
    pure = np.concatenate([np.zeros(translations.shape[:-1] + (1,)), translations], axis=-1)
    real = dual_quaternions[..., :4]
    return np.concatenate([real, 0.5 * quaternion_multiply(pure, real)], axis=-1)


def polar_rotation(matrices):
    """Nearest proper rotation to each matrix (the orthogonal polar factor, det = +1).

    matrices (..., 3, 3) -> rotations (..., 3, 3). This is the weighted-Procrustes solution
    when ``matrices`` is a cross-covariance ``sum w (target - mean)(source - mean)^T``.
    """
    u, _, vt = np.linalg.svd(matrices)
    # Flip the last singular direction where the plain product would be a reflection.
    det = np.linalg.det(u @ vt)
    u = u.copy()
    u[..., :, 2] *= np.where(det < 0.0, -1.0, 1.0)[..., None]
    return u @ vt


def _inverse_transpose(m):
    """(3, 3, N) component-major -> (m⁻ᵀ (3, 3, N), det (N,)) from cofactors: elementwise on
    contiguous rows (about 5× faster than the same arithmetic on (N, 3, 3) slices)."""
    c = np.empty_like(m)
    c[0, 0] = m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1]
    c[0, 1] = m[1, 2] * m[2, 0] - m[1, 0] * m[2, 2]
    c[0, 2] = m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]
    c[1, 0] = m[0, 2] * m[2, 1] - m[0, 1] * m[2, 2]
    c[1, 1] = m[0, 0] * m[2, 2] - m[0, 2] * m[2, 0]
    c[1, 2] = m[0, 1] * m[2, 0] - m[0, 0] * m[2, 1]
    c[2, 0] = m[0, 1] * m[1, 2] - m[0, 2] * m[1, 1]
    c[2, 1] = m[0, 2] * m[1, 0] - m[0, 0] * m[1, 2]
    c[2, 2] = m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
    det = m[0, 0] * c[0, 0] + m[0, 1] * c[0, 1] + m[0, 2] * c[0, 2]
    with np.errstate(divide="ignore", invalid="ignore"):  # singular ones are handled by the caller
        c /= det
    return c, det


def polar_decomposition(matrices, iterations=30, tolerance=1e-12):
    """F = U S for many 3×3 matrices with det > 0: (U (…, 3, 3) rotation, S (…, 3, 3) symmetric).

    Scaled Newton iteration U ← ½(γU + (γU)⁻ᵀ), γ = |det U|^(-1/3) (Higham 1986), vectorised over
    all matrices with cofactor inverses in a component-major (3, 3, N) layout: ~20× faster than a
    batched SVD for the near-rotations of synthesised bones. Each matrix stops once its own step
    is below ``tolerance`` and the iteration goes on over the rest only (rotations stop after a
    step or two). Matrices that are singular or reflections (det ≤ 0) go through
    :func:`polar_rotation` (SVD) instead.
    """
    m = np.asarray(matrices, dtype=np.float64)
    shape = m.shape
    flat = m.reshape(-1, 3, 3)
    u = np.ascontiguousarray(flat.transpose(1, 2, 0))  # (3, 3, N)
    inverse_t, det = _inverse_transpose(u)
    scale = np.maximum(np.sum(u * u, axis=(0, 1)), np.finfo(float).tiny) ** 1.5
    good = det > 1e-12 * scale
    active = np.flatnonzero(good)
    current, inverse_t, det = u[:, :, active], inverse_t[:, :, active], det[active]
    for _ in range(iterations):
        if active.size == 0:
            break
        gamma = np.abs(det) ** (-1.0 / 3.0)
        nxt = 0.5 * (gamma * current + inverse_t / gamma)
        u[:, :, active] = nxt
        moving = np.max(np.abs(nxt - current), axis=(0, 1)) >= tolerance
        active, current = active[moving], nxt[:, :, moving]
        inverse_t, det = _inverse_transpose(current)
    u = u.transpose(2, 0, 1)
    if not good.all():
        u[~good] = polar_rotation(flat[~good])
    s = np.swapaxes(u, -1, -2) @ flat
    return u.reshape(shape), (0.5 * (s + np.swapaxes(s, -1, -2))).reshape(shape)


def polar_of_near_rotations(matrices, tolerance=1e-6):
    """:func:`polar_decomposition` that takes matrices already orthonormal to ``tolerance``
    (max |FᵀF − I|) as they are: U = F, S = I, so only the others pay for the Newton iteration.

    Spliced bones are rotations outside the blend windows, rounded to float32 (|FᵀF − I| ~ 1e-7),
    and general affine matrices inside them; taking the former as exact rotations changes U and S
    by at most ``tolerance`` there. matrices (…, 3, 3) -> (U, S), each (…, 3, 3) float64."""
    m = np.asarray(matrices, dtype=np.float64)
    flat = m.reshape(-1, 3, 3)
    columns = np.ascontiguousarray(flat.transpose(1, 2, 0))  # (3, 3, N)
    gram = np.einsum("kin,kjn->ijn", columns, columns)
    gram[[0, 1, 2], [0, 1, 2]] -= 1.0
    stretched = np.flatnonzero(np.max(np.abs(gram), axis=(0, 1)) > tolerance)
    u = flat.copy()
    s = np.broadcast_to(np.eye(3), flat.shape).copy()
    if stretched.size:
        u[stretched], s[stretched] = polar_decomposition(flat[stretched])
    return u.reshape(m.shape), s.reshape(m.shape)


def apply_rigid_into(F_out, t_out, slots, rotation, translation, F, t, rows=None, bones=None, animation_block=16):
    """``F_out[a, :, slots] = rotation[a] F[rows[a], :, bones]`` and ``t_out[a, :, slots] =
    rotation[a] t[rows[a], :, bones] + translation[a]`` for every animation a, in blocks of
    ``animation_block`` animations, computed in the outputs' dtype.

    F_out (A, M, B, 3, 3), t_out (A, M, B, 3); slots (k,) bone slots of the outputs; rotation
    (A, M, 3, 3), translation (A, M, 3); F (A', M, b, 3, 3), t (A', M, b, 3); rows (A,) the
    animation of F per output animation (default the same); bones (k,) the bones of F (default all).
    The products are written out entry by entry over whole blocks (numpy's stacked 3×3 matmul is
    slow per matrix), and stored one bone slot at a time (a fancy-index scatter over all slots
    is several times slower): on float32 outputs this halves the assembly of 1,000 × 600 frames."""
    count = F_out.shape[0]
    dtype = F_out.dtype
    slots = np.asarray(slots)
    bones = np.arange(F.shape[2]) if bones is None else np.asarray(bones)
    whole = slots.size == F_out.shape[2] and np.array_equal(slots, np.arange(slots.size)) \
        and np.array_equal(bones, np.arange(F.shape[2]))
    step = max(1, int(animation_block))
    for a0 in range(0, count, step):
        block = slice(a0, min(count, a0 + step))
        F_local, t_local = (F[block], t[block]) if rows is None else (F[rows[block]], t[rows[block]])
        R = rotation[block].astype(dtype)[:, :, None]  # (n, M, 1, 3, 3)
        c = translation[block].astype(dtype)[:, :, None]  # (n, M, 1, 3)
        F_world = np.empty(F_local.shape[:3] + (3, 3), dtype)
        t_world = np.empty(t_local.shape[:3] + (3,), dtype)
        for i in range(3):
            F_world[..., i, :] = R[..., i, 0, None] * F_local[..., 0, :] + R[..., i, 1, None] * F_local[..., 1, :] \
                + R[..., i, 2, None] * F_local[..., 2, :]
            t_world[..., i] = R[..., i, 0] * t_local[..., 0] + R[..., i, 1] * t_local[..., 1] \
                + R[..., i, 2] * t_local[..., 2] + c[..., i]
        if whole:
            F_out[block], t_out[block] = F_world, t_world
        else:
            for k, slot in zip(bones, slots):
                F_out[block, :, slot], t_out[block, :, slot] = F_world[:, :, k], t_world[:, :, k]


def matrix_to_quaternion(rotations):
    """rotations (..., 3, 3) -> quaternions (..., 4), (w, x, y, z), w >= 0.

    Shepperd's method as scipy's ``Rotation.from_matrix`` computes it (the largest of the trace
    and the diagonal picks the stable formula), in numpy: importing scipy.spatial cost every
    command about 0.3 s."""
    shape = rotations.shape[:-2]
    m = np.asarray(rotations, dtype=np.float64).reshape(-1, 3, 3)
    decision = np.stack([m[:, 0, 0], m[:, 1, 1], m[:, 2, 2], m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]], axis=1)
    choice = np.argmax(decision, axis=1)
    xyzw = np.empty((m.shape[0], 4))
    for i in range(3):
        rows = choice == i
        j, k = (i + 1) % 3, (i + 2) % 3
        mi = m[rows]
        xyzw[rows, i] = 1.0 - decision[rows, 3] + 2.0 * mi[:, i, i]
        xyzw[rows, j] = mi[:, j, i] + mi[:, i, j]
        xyzw[rows, k] = mi[:, k, i] + mi[:, i, k]
        xyzw[rows, 3] = mi[:, k, j] - mi[:, j, k]
    rows = choice == 3
    mi = m[rows]
    xyzw[rows, 0] = mi[:, 2, 1] - mi[:, 1, 2]
    xyzw[rows, 1] = mi[:, 0, 2] - mi[:, 2, 0]
    xyzw[rows, 2] = mi[:, 1, 0] - mi[:, 0, 1]
    xyzw[rows, 3] = 1.0 + decision[rows, 3]
    xyzw /= np.linalg.norm(xyzw, axis=1, keepdims=True)
    wxyz = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
    wxyz *= np.where(wxyz[:, :1] < 0.0, -1.0, 1.0)
    return wxyz.reshape(shape + (4,))


def heading_rotation(rotations, up):
    """The turn about the unit axis ``up`` (3,) within each rotation (..., 3, 3) -> (..., 3, 3):
    the twist Y of the swing-twist split R = Y T, T a rotation about a horizontal axis
    (quaternion (w, v) -> twist (w, (v·up) up), normalised). Undefined only for a half turn
    about a horizontal axis (w = v·up = 0), where it returns the identity."""
    q = matrix_to_quaternion(rotations)
    along = q[..., 1:] @ np.asarray(up, dtype=np.float64)
    angle = 2.0 * np.arctan2(along, q[..., 0])
    return rotation_exp(angle[..., None] * np.asarray(up, dtype=np.float64))


def heading_and_posture(rotations, translations, pivot, up):
    """Split rigid poses into a heading and a posture: P = H ∘ Π.

    rotations (F, 3, 3), translations (F, 3) act on points x ↦ R x + t; pivot (3,) a rest point;
    up (3,) a unit axis. H(f) is the turn of R(f) about up (:func:`heading_rotation`) with the
    ground-plane shift that takes the pivot's ground-plane position to where P(f) takes it;
    Π(f) = H(f)⁻¹ P(f) keeps the tilt and the height. Returns (H_R, H_t, Π_R, Π_t), each (F, …)."""
    up = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
    pivot = np.asarray(pivot, dtype=np.float64)
    H_R = heading_rotation(rotations, up)
    position = rotations @ pivot + translations  # where the pivot goes
    H_t = position - np.outer(position @ up, up) - H_R @ (pivot - (pivot @ up) * up)
    posture_R = np.swapaxes(H_R, -1, -2) @ rotations
    posture_t = np.einsum("fba,fb->fa", H_R, translations - H_t)
    return H_R, H_t, posture_R, posture_t


def rigid_to_dual_quaternion(rotations, translations):
    """rotations (..., 3, 3), translations (..., 3) -> dual quaternions (..., 8)."""
    q0 = matrix_to_quaternion(rotations)
    pure_t = np.concatenate([np.zeros(translations.shape[:-1] + (1,)), translations], axis=-1)
    qe = 0.5 * quaternion_multiply(pure_t, q0)
    return np.concatenate([q0, qe], axis=-1)


def align_hemispheres(quaternions, axis=0):
    """Flip signs along ``axis`` so consecutive quaternions lie in the same hemisphere.

    quaternions (..., 4) or dual quaternions (..., 8): q and -q are the same rotation, but
    regression and blending need one continuous branch (Feng §4.3, Kavan et al. 2007). Each
    element is compared with its already-aligned predecessor along ``axis``; the sign of the
    real part's dot product decides, and a dual quaternion flips as a whole.
    """
    q = np.moveaxis(np.array(quaternions, dtype=np.float64, copy=True), axis, 0)
    for i in range(1, q.shape[0]):
        dot = np.sum(q[i, ..., :4] * q[i - 1, ..., :4], axis=-1)
        q[i] *= np.where(dot < 0.0, -1.0, 1.0)[..., None]
    return np.moveaxis(q, 0, axis)


def rotation_log(rotations):
    """rotations (..., 3, 3) -> axis-angle vectors (..., 3) (the matrix logarithm, Zheng eq. 3)."""
    shape = rotations.shape[:-2]
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(rotations.reshape(-1, 3, 3)).as_rotvec().reshape(shape + (3,))


def rotation_exp(axis_angles):
    """axis-angle vectors (..., 3) -> rotations (..., 3, 3), by Rodrigues' formula, vectorised.

    R = I + a [w]× + b [w]×², a = sin θ / θ, b = (1 − cos θ) / θ², with [w]×² = w wᵀ − θ² I and
    the Taylor series near θ = 0 so small angles keep full precision. Entry by entry on 1-D
    arrays: no small-matrix products, which numpy does slowly one at a time."""
    w = np.asarray(axis_angles, dtype=np.float64)
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    theta2 = x * x + y * y + z * z
    small = theta2 < 1e-8
    safe = np.where(small, 1.0, np.sqrt(theta2))
    a = np.where(small, 1.0 - theta2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    bx, by, bz = b * x, b * y, b * z
    ax, ay, az = a * x, a * y, a * z
    c = 1.0 - b * theta2
    r = np.empty(w.shape[:-1] + (3, 3))
    r[..., 0, 0], r[..., 0, 1], r[..., 0, 2] = bx * x + c, bx * y - az, bx * z + ay
    r[..., 1, 0], r[..., 1, 1], r[..., 1, 2] = bx * y + az, by * y + c, by * z - ax
    r[..., 2, 0], r[..., 2, 1], r[..., 2, 2] = bx * z - ay, by * z + ax, bz * z + c
    return r
