"""The trained puppet's run-time stages (Feng et al. 2008, §6) as warp kernels, one thread per
(sample n, column) of each output; the numpy references are in ``gpu.references.puppet``, the
launches in ``gpu.puppet_stages`` and ``gpu.puppet_run``.

The kernel vectors ξ and the raw predictions M ξ + m are float64 (M's entries reach 1e4–1e7 and
cancel: float32 lost 1.7e-3 of the horse's diagonal); from the normalised dual quaternions on,
float32 (values of order one).
"""

import functools

from .. import runtime
from .dual_quaternion import dq_dual, dq_pack, dq_real, vec8, vec8d
from .skinning import vec12

wp = runtime.warp()


@functools.cache
def kernel_vector_kernel(kind: str, degree: int):
    """ξ (N, n_p) = k(x, training) for the control kernel ``kind`` (one of
    ``validation.KERNEL_KINDS``) and the polynomial's ``degree``, both compile-time constants."""
    gaussian, polynomial = kind == "gaussian", kind == "polynomial"

    @wp.kernel(module="unique")
    def kernel_vector_kernel(
        x: wp.array2d(dtype=wp.float64),
        training: wp.array2d(dtype=wp.float64),
        offset: wp.float64,
        xi: wp.array2d(dtype=wp.float64),
    ):
        n, j = wp.tid()
        acc = wp.float64(0.0)
        for c in range(x.shape[1]):
            if wp.static(gaussian):
                diff = x[n, c] - training[j, c]
                acc += diff * diff
            else:
                acc += x[n, c] * training[j, c]
        if wp.static(gaussian):
            xi[n, j] = wp.exp(wp.float64(-0.5) * acc)
        elif wp.static(polynomial):
            base = acc + offset
            value = wp.float64(1.0)
            for _ in range(degree):
                value *= base
            xi[n, j] = value
        else:
            xi[n, j] = acc

    return kernel_vector_kernel


@wp.kernel
def predict_kernel(
    xi: wp.array2d(dtype=wp.float64),
    predictor: wp.array2d(dtype=vec8d),  # (B, n_p): bone b's column j of M
    bias: wp.array(dtype=vec8d),  # (B,)
    d: wp.array2d(dtype=vec8d),  # (N, B)
):
    """d = M ξ + m (Feng §6.1), all bones at once."""
    n, b = wp.tid()
    acc = bias[b]
    for j in range(xi.shape[1]):
        acc += xi[n, j] * predictor[b, j]
    d[n, b] = acc


@wp.kernel
def normalise_kernel(
    d: wp.array2d(dtype=vec8d),  # raw, float64: normalised before rounding to float32
    unit: wp.array2d(dtype=vec8),
    rotations: wp.array2d(dtype=wp.mat33),
    translations: wp.array2d(dtype=wp.vec3),
):
    """Unit d (both parts divided by |q0|), its rotation and translation t = 2 (qe q0*).xyz."""
    n, b = wp.tid()
    v = d[n, b]
    inv = wp.float64(1.0) / wp.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3])
    u = vec8(wp.float32(v[0] * inv), wp.float32(v[1] * inv), wp.float32(v[2] * inv), wp.float32(v[3] * inv),
             wp.float32(v[4] * inv), wp.float32(v[5] * inv), wp.float32(v[6] * inv), wp.float32(v[7] * inv))
    q0 = dq_real(u)
    qe = dq_dual(u)
    unit[n, b] = u
    rotations[n, b] = wp.quat_to_matrix(q0)
    p = qe * wp.quat(-q0[0], -q0[1], -q0[2], q0[3])  # qe q0*
    translations[n, b] = 2.0 * wp.vec3(p[0], p[1], p[2])


@wp.kernel
def solve_kernel(
    rotations: wp.array2d(dtype=wp.mat33),  # (N, B)
    controls: wp.array2d(dtype=wp.vec3),  # (N, n_c)
    predicted: wp.array2d(dtype=wp.vec3),  # (N, B)
    gamma: wp.array2d(dtype=wp.vec3),  # (B, B): Γ[b, k, :]
    control_operator: wp.array2d(dtype=wp.float32),  # (B, n_c)
    prior: wp.array2d(dtype=wp.float32),  # (B, B)
    translations: wp.array2d(dtype=wp.vec3),  # (N, B)
):
    """The Poisson translations t = Γ·R + Q·c + Π·t̂ (Feng §6.2)."""
    n, b = wp.tid()
    acc = wp.vec3(0.0)
    for k in range(rotations.shape[1]):
        acc += rotations[n, k] @ gamma[b, k] + prior[b, k] * predicted[n, k]
    for l in range(controls.shape[1]):
        acc += control_operator[b, l] * controls[n, l]
    translations[n, b] = acc


@wp.kernel
def frames_kernel(frames: wp.array(dtype=wp.mat44), out: wp.array(dtype=vec8)):
    """Rigid homogeneous transforms (N,) mat44 -> unit dual quaternions (N,) vec8."""
    n = wp.tid()
    m = frames[n]
    r = wp.mat33(m[0, 0], m[0, 1], m[0, 2], m[1, 0], m[1, 1], m[1, 2], m[2, 0], m[2, 1], m[2, 2])
    q0 = wp.normalize(wp.quat_from_matrix(r))
    t = wp.quat(m[0, 3], m[1, 3], m[2, 3], 0.0)
    out[n] = dq_pack(q0, 0.5 * (t * q0))


@wp.func
def composed(
    unit: wp.array2d(dtype=vec8),
    translations: wp.array2d(dtype=wp.vec3),
    frames: wp.array(dtype=vec8),
    use_translations: int,
    use_frames: int,
    n: int,
    b: int,
):
    """Sample n's final dual quaternion of bone b: the solver's translation (if any), then the
    world frame (if any)."""
    v = unit[n, b]
    q0 = dq_real(v)
    qe = dq_dual(v)
    if use_translations != 0:
        t = translations[n, b]
        qe = 0.5 * (wp.quat(t[0], t[1], t[2], 0.0) * q0)
    if use_frames != 0:
        f = frames[n]
        f0 = dq_real(f)
        # (f0 + ε fe)(q0 + ε qe) = f0 q0 + ε (f0 qe + fe q0)
        qe = f0 * qe + dq_dual(f) * q0
        q0 = f0 * q0
    return dq_pack(q0, qe)


@wp.kernel
def compose_kernel(
    unit: wp.array2d(dtype=vec8),  # (N, B)
    translations: wp.array2d(dtype=wp.vec3),  # (N, B), read when use_translations
    frames: wp.array(dtype=vec8),  # (N,), read when use_frames
    use_translations: int,
    use_frames: int,
    out: wp.array2d(dtype=vec8),
):
    """Final per-bone dual quaternion (:func:`composed`), for dual-quaternion skinning."""
    n, b = wp.tid()
    out[n, b] = composed(unit, translations, frames, use_translations, use_frames, n, b)


@wp.kernel
def compose_rigid_kernel(
    unit: wp.array2d(dtype=vec8),  # (N, B)
    translations: wp.array2d(dtype=wp.vec3),  # (N, B), read when use_translations
    frames: wp.array(dtype=vec8),  # (N,), read when use_frames
    use_translations: int,
    use_frames: int,
    out: wp.array2d(dtype=vec12),
):
    """Final per-bone rigid transform, for linear-blend skinning (``blended_lbs_kernel``): the
    composed dual quaternion (:func:`composed`, unit up to float32 rounding) as the 3×4 matrix
    [R | t], R the rotation of its real part q0 and t = 2 (qe q0*).xyz, in the same launch."""
    n, b = wp.tid()
    v = composed(unit, translations, frames, use_translations, use_frames, n, b)
    q0 = dq_real(v)
    p = dq_dual(v) * wp.quat(-q0[0], -q0[1], -q0[2], q0[3])  # qe q0*
    r = wp.quat_to_matrix(q0)
    out[n, b] = vec12(r[0, 0], r[0, 1], r[0, 2], 2.0 * p[0],
                      r[1, 0], r[1, 1], r[1, 2], 2.0 * p[1],
                      r[2, 0], r[2, 1], r[2, 2], 2.0 * p[2])


@wp.kernel
def corrective_offsets_kernel(w: wp.array2d(dtype=wp.float64), offsets: wp.array2d(dtype=wp.vec3),
                              out: wp.array2d(dtype=wp.vec3)):
    """Σ_j w_j O_j (N, V) in float32 (offsets are small; w, which can be large and cancel, is
    computed in float64 on the host). Used off the CPU; the CPU path is a BLAS product
    (``gpu.cpu_blas``)."""
    n, i = wp.tid()
    acc = wp.vec3()
    for j in range(w.shape[1]):
        acc += wp.float32(w[n, j]) * offsets[j, i]
    out[n, i] = acc
