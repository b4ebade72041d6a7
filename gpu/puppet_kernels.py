"""The trained puppet's run-time path (Feng et al. 2008, §6) as warp kernels, with numpy references.

Every function takes N *samples* (frames × characters, flattened: each sample is independent)
and runs one launch over all of them (per chunk, where device memory must stay bounded).
Numpy in, float64 numpy out. On the device the kernel vectors ξ and the raw predictions M ξ + m
are float64 (M's entries reach 1e4–1e7 and cancel: float32 lost 1.7e-3 of the horse's diagonal);
from the normalised dual quaternions on, float32 (values of order one). The stages, each with
its numpy reference:

1. :func:`kernel_vectors` — ξ = k(x, training) for standardised controls x (N, d), (N, n_p);
2. :func:`predict_dual_quaternions` — d = M ξ + m for all bones at once (Feng §6.1), (N, B, 8);
3. :func:`normalise_dual_quaternions` — unit d, its rotations (N, B, 3, 3) and translations;
4. :func:`solve_translations` — the Poisson translations t = Γ·R + Q·c + Π·t̂ (Feng §6.2);
5. :func:`corrective_offsets` — the pose-space correctives' rest offsets Σ_j w_j O_j
   (``pipeline.correctives``; the blend weights w = A ξ^p + B [1, x Pᵀ] in float64 on the host,
   :func:`corrective_weights_reference`, the blend in float32), (N, V, 3);
   :func:`dq_skin` — dual-quaternion skinning (Kavan et al. 2007; Feng §6.3) of the rest pose
   plus those offsets, (N, V, 3);
6. :func:`run_puppet` — all of it on the device, arrays staying on the device between stages,
   and a per-sample rigid world transform folded into every bone's dual quaternion before
   skinning (so the skinning writes world positions directly). :func:`reference_run_puppet` is
   the same in numpy (it applies the world transforms to the skinned vertices instead).

Conventions as in ``pipeline.rotations``: dual quaternions are 8 numbers, real then dual part,
each (w, x, y, z) scalar first; that layout is kept on the device too (a ``vec8`` per bone), and
converted to warp's (x, y, z, w) ``wp.quat`` only inside kernels.

The host side of the run time stays in numpy: aligning the controls (``pipeline.puppet.in_place``)
and standardising them; ``pipeline.playback.host_inputs`` does both for a ``Puppet`` and world controls.
"""

import functools
import threading
import time
from dataclasses import dataclass

import numpy as np

from . import runtime
from .dual_quaternions import dual_quaternion_to_rigid, with_translations
from .skinning import _checked, dqs_reference

KERNEL_KINDS = ("gaussian", "polynomial", "linear")
# Samples per chunk in run_puppet / dq_skin: at most 2**24 skinned vertices (a 192 MiB float32
# output buffer) per launch, so any N × V fits in bounded device memory.
_DEVICE_CHUNK = 1 << 24


# ----------------------------------------------------------------------------------------------
# numpy references of the single stages (the pipeline's own computations call these)


def kernel_vectors_reference(x, training, kind, offset=0.0, degree=5):
    """ξ (N, n_p) float64 between standardised controls x (N, d) and training (n_p, d) (what
    ``pipeline.kcca.ControlKernel.matrix`` computes): "gaussian" exp(-|x-y|²/2), "polynomial"
    (xᵀy + offset)^degree, "linear" xᵀy."""
    _check_kind(kind)
    x, training = np.asarray(x, dtype=np.float64), np.asarray(training, dtype=np.float64)
    if kind == "linear":
        return x @ training.T
    if kind == "polynomial":
        return (x @ training.T + offset) ** degree
    sq = np.sum(x * x, axis=1)[:, None] + np.sum(training * training, axis=1)[None, :] - 2.0 * x @ training.T
    return np.exp(-0.5 * np.maximum(sq, 0.0))


def predict_dual_quaternions_reference(xi, predictor, bias):
    """d (N, B, 8) = M ξ + m with M (8B, n_p) (row b·8 + m is bone b's m-th number), m (8B,)."""
    predictor = np.asarray(predictor, dtype=np.float64)
    bones = predictor.shape[0] // 8
    return (np.einsum("bmn,fn->fbm", predictor.reshape(bones, 8, -1), np.asarray(xi, dtype=np.float64))
            + np.asarray(bias, dtype=np.float64).reshape(bones, 8))


def normalise_dual_quaternions_reference(d):
    """(unit d (N, B, 8), rotations (N, B, 3, 3), translations (N, B, 3)), dividing by |q0|."""
    d = np.asarray(d, dtype=np.float64)
    unit = d / np.linalg.norm(d[..., :4], axis=-1, keepdims=True)
    rotations, translations = dual_quaternion_to_rigid(unit)
    return unit, rotations, translations


def solve_translations_reference(rotations, controls, predicted_translations, rotation_operator,
                                 control_operator, prior_operator):
    """Feng §6.2's translations t = Γ·R + Q·c + Π·t̂ (N, B, 3): rotations (N, B, 3, 3), controls
    (N, n_c, 3) in place, predicted t̂ (N, B, 3); Γ (B, B, 3), Q (B, n_c), Π (B, B)."""
    return (np.einsum("bkc,fkac->fba", np.asarray(rotation_operator, dtype=np.float64), rotations, optimize=True)
            + np.einsum("bl,fla->fba", np.asarray(control_operator, dtype=np.float64), controls)
            + np.einsum("bk,fka->fba", np.asarray(prior_operator, dtype=np.float64), predicted_translations))


# ----------------------------------------------------------------------------------------------
# the puppet's arrays


@dataclass(frozen=True)
class PuppetArrays:
    """What the run time needs of a trained puppet, as plain arrays (host, float64).

    rest_vertices (V, 3); bone_indices, bone_weights (V, K) (zero weight = padding slot);
    training_controls (n_p, d) standardised; kernel one of KERNEL_KINDS with its offset and
    degree (polynomial); predictor (8B, n_p) with row b·8 + m the m-th dual-quaternion number of
    bone b, bias (8B,); the translation operator (``pipeline.poisson.TranslationOperator``):
    rotation_operator Γ (B, B, 3), control_operator Q (B, n_c), prior_operator Π (B, B), or all
    None for a puppet trained without the solver; the pose-space correctives
    (``pipeline.correctives.Correctives``): corrective_weights A (n_p, n_p), corrective_power p,
    corrective_tail B (n_p, 1 + r) and corrective_axes P (r, d) (or None), corrective_offsets
    O (n_p, V, 3); all None without correctives.
    """

    rest_vertices: np.ndarray
    bone_indices: np.ndarray
    bone_weights: np.ndarray
    training_controls: np.ndarray
    kernel: str
    predictor: np.ndarray
    bias: np.ndarray
    rotation_operator: np.ndarray | None = None
    control_operator: np.ndarray | None = None
    prior_operator: np.ndarray | None = None
    offset: float = 0.0
    degree: int = 5
    corrective_weights: np.ndarray | None = None
    corrective_offsets: np.ndarray | None = None
    corrective_power: float = 1.0
    corrective_tail: np.ndarray | None = None
    corrective_axes: np.ndarray | None = None

    @classmethod
    def from_puppet(cls, puppet):
        """From a ``pipeline.puppet.Puppet``."""
        reg, ops, corr = puppet.regression, puppet.translations, puppet.correctives
        bones = reg.predictor.shape[0]
        return cls(rest_vertices=puppet.rest_vertices, bone_indices=puppet.bone_indices,
                   bone_weights=puppet.bone_weights, training_controls=puppet.training_controls,
                   kernel=puppet.kernel.kind, offset=float(puppet.kernel.offset), degree=int(puppet.kernel.degree),
                   predictor=reg.predictor.reshape(bones * 8, -1), bias=reg.bias.reshape(bones * 8),
                   rotation_operator=None if ops is None else ops.rotation_operator,
                   control_operator=None if ops is None else ops.control_operator,
                   prior_operator=None if ops is None else ops.prior_operator,
                   corrective_weights=None if corr is None else corr.weights,
                   corrective_offsets=None if corr is None else corr.offsets,
                   corrective_power=1.0 if corr is None else corr.power,
                   corrective_tail=None if corr is None else corr.tail,
                   corrective_axes=None if corr is None else corr.axes)

    @property
    def bones(self):
        return self.predictor.shape[0] // 8

    @property
    def has_solver(self):
        return self.rotation_operator is not None

    @property
    def has_correctives(self):
        return self.corrective_weights is not None


def corrective_weights_reference(xi, x, weights, power=1.0, tail=None, axes=None):
    """Blend weights w (N, n_p) float64 of the pose-space correctives: ``A ξ^p + B [1, x Pᵀ]`` for
    kernel vectors ξ (N, n_p) and standardised controls x (N, d); weights A (n_p, n_p), tail B
    (n_p, 1 + r) and axes P (r, d), or None for no affine tail."""
    w = (np.asarray(xi, dtype=np.float64) ** power) @ np.asarray(weights).T
    if tail is not None:
        tail = np.asarray(tail)
        w += tail[:, 0] + (np.asarray(x, dtype=np.float64) @ np.asarray(axes).T) @ tail[:, 1:].T
    return w


def corrective_offsets_reference(blend_weights, offsets):
    """Rest offsets (N, V, 3) Σ_j w_j O_j of blend weights w (N, n_p) and offsets O (n_p, V, 3)."""
    return np.einsum("nj,jvc->nvc", blend_weights, offsets)


def _corrective_weights(arrays, xi, x):
    return corrective_weights_reference(xi, x, arrays.corrective_weights, arrays.corrective_power,
                                        arrays.corrective_tail, arrays.corrective_axes)


def _as_arrays(puppet):
    if isinstance(puppet, (PuppetArrays, DevicePuppet)):
        return puppet
    return PuppetArrays.from_puppet(puppet)


def _check_inputs(arrays, standardised_controls, controls_in_place, world_frames, translation_solver):
    x = np.asarray(standardised_controls, dtype=np.float64)
    samples = x.shape[0]
    if x.ndim != 2 or x.shape[1] != arrays.training_controls.shape[1]:
        raise ValueError(f"standardised_controls must be (N, {arrays.training_controls.shape[1]}), got {x.shape}")
    c = None
    if translation_solver:
        if not arrays.has_solver:
            raise ValueError("this puppet has no translation operator (trained without the solver)")
        n_c = arrays.control_operator.shape[1]
        c = np.asarray(controls_in_place, dtype=np.float64)
        if c.shape != (samples, n_c, 3):
            raise ValueError(f"controls_in_place must be ({samples}, {n_c}, 3), got {c.shape}")
    f = None
    if world_frames is not None:
        f = np.asarray(world_frames, dtype=np.float64)
        if f.shape != (samples, 4, 4):
            raise ValueError(f"world_frames must be ({samples}, 4, 4) or None, got {f.shape}")
    return x, c, f


def reference_run_puppet(puppet, standardised_controls, controls_in_place, world_frames=None,
                         translation_solver=True):
    """numpy reference of :func:`run_puppet` (same arguments, no device): vertices (N, V, 3).

    Composes the stage references; the world frames are applied to the skinned vertices, as
    ``pipeline.puppet.predict_vertices`` does (the device version folds them into the bones).
    """
    arrays = _as_arrays(puppet)
    if isinstance(arrays, DevicePuppet):
        arrays = arrays.host
    x, c, f = _check_inputs(arrays, standardised_controls, controls_in_place, world_frames, translation_solver)
    xi = kernel_vectors_reference(x, arrays.training_controls, arrays.kernel, arrays.offset, arrays.degree)
    d, rot, trans = normalise_dual_quaternions_reference(
        predict_dual_quaternions_reference(xi, arrays.predictor, arrays.bias))
    if translation_solver:
        trans = solve_translations_reference(rot, c, trans, arrays.rotation_operator, arrays.control_operator,
                                             arrays.prior_operator)
        d = with_translations(d, trans)
    offsets = None
    if arrays.has_correctives:
        offsets = corrective_offsets_reference(_corrective_weights(arrays, xi, x), arrays.corrective_offsets)
    placed = dqs_reference(arrays.rest_vertices, arrays.bone_indices, arrays.bone_weights, d, offsets)
    if f is None:
        return placed
    return np.einsum("nab,nvb->nva", f[:, :3, :3], placed) + f[:, None, :3, 3]


# ----------------------------------------------------------------------------------------------
# kernels (built on first use, so importing this module does not import warp)


def _check_kind(kind):
    if kind not in KERNEL_KINDS:
        raise ValueError(f"kernel kind must be one of {', '.join(KERNEL_KINDS)}, got {kind!r}")


@functools.cache
def _vec8():
    wp = runtime.warp()
    return wp.types.vector(length=8, dtype=wp.float32)


@functools.cache
def _vec8d():
    """Raw predictions d = M ξ + m stay in float64: M's entries reach 1e4–1e7 on real puppets
    (nearly repeated training poses, wide kernels) and cancel in the sum, which float32 turned
    into dual-quaternion errors of 3e-3 (1.7e-3 of the horse's diagonal)."""
    wp = runtime.warp()
    return wp.types.vector(length=8, dtype=wp.float64)


@functools.cache
def _funcs():
    """Device helpers on (w, x, y, z, w, x, y, z) vec8 dual quaternions."""
    wp = runtime.warp()
    vec8 = _vec8()

    @wp.func
    def dq_real(d: vec8):
        return wp.quat(d[1], d[2], d[3], d[0])

    @wp.func
    def dq_dual(d: vec8):
        return wp.quat(d[5], d[6], d[7], d[4])

    @wp.func
    def dq_pack(q0: wp.quat, qe: wp.quat):
        return vec8(q0[3], q0[0], q0[1], q0[2], qe[3], qe[0], qe[1], qe[2])

    return dq_real, dq_dual, dq_pack


@functools.cache
def _kernel_vector_kernel(kind: str, degree: int):
    wp = runtime.warp()
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


@functools.cache
def _predict_kernel():
    wp = runtime.warp()
    vec8d = _vec8d()

    @wp.kernel(module="unique")
    def predict_kernel(
        xi: wp.array2d(dtype=wp.float64),
        predictor: wp.array2d(dtype=vec8d),  # (B, n_p): bone b's column j of M
        bias: wp.array(dtype=vec8d),  # (B,)
        d: wp.array2d(dtype=vec8d),  # (N, B)
    ):
        n, b = wp.tid()
        acc = bias[b]
        for j in range(xi.shape[1]):
            acc += xi[n, j] * predictor[b, j]
        d[n, b] = acc

    return predict_kernel


@functools.cache
def _normalise_kernel():
    wp = runtime.warp()
    vec8 = _vec8()
    dq_real, dq_dual, dq_pack = _funcs()

    vec8d = _vec8d()

    @wp.kernel(module="unique")
    def normalise_kernel(
        d: wp.array2d(dtype=vec8d),  # raw, float64: normalised before rounding to float32
        unit: wp.array2d(dtype=vec8),
        rotations: wp.array2d(dtype=wp.mat33),
        translations: wp.array2d(dtype=wp.vec3),
    ):
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

    return normalise_kernel


@functools.cache
def _solve_kernel():
    wp = runtime.warp()

    @wp.kernel(module="unique")
    def solve_kernel(
        rotations: wp.array2d(dtype=wp.mat33),  # (N, B)
        controls: wp.array2d(dtype=wp.vec3),  # (N, n_c)
        predicted: wp.array2d(dtype=wp.vec3),  # (N, B)
        gamma: wp.array2d(dtype=wp.vec3),  # (B, B): Γ[b, k, :]
        control_operator: wp.array2d(dtype=wp.float32),  # (B, n_c)
        prior: wp.array2d(dtype=wp.float32),  # (B, B)
        translations: wp.array2d(dtype=wp.vec3),  # (N, B)
    ):
        n, b = wp.tid()
        acc = wp.vec3(0.0)
        for k in range(rotations.shape[1]):
            acc += rotations[n, k] @ gamma[b, k] + prior[b, k] * predicted[n, k]
        for l in range(controls.shape[1]):
            acc += control_operator[b, l] * controls[n, l]
        translations[n, b] = acc

    return solve_kernel


@functools.cache
def _frames_kernel():
    """Rigid homogeneous transforms (N,) mat44 -> unit dual quaternions (N,) vec8."""
    wp = runtime.warp()
    vec8 = _vec8()
    _, _, dq_pack = _funcs()

    @wp.kernel(module="unique")
    def frames_kernel(frames: wp.array(dtype=wp.mat44), out: wp.array(dtype=vec8)):
        n = wp.tid()
        m = frames[n]
        r = wp.mat33(m[0, 0], m[0, 1], m[0, 2], m[1, 0], m[1, 1], m[1, 2], m[2, 0], m[2, 1], m[2, 2])
        q0 = wp.normalize(wp.quat_from_matrix(r))
        t = wp.quat(m[0, 3], m[1, 3], m[2, 3], 0.0)
        out[n] = dq_pack(q0, 0.5 * (t * q0))

    return frames_kernel


@functools.cache
def _compose_kernel():
    """Final per-bone dual quaternion: the solver's translation (if any), then the world frame (if any)."""
    wp = runtime.warp()
    vec8 = _vec8()
    dq_real, dq_dual, dq_pack = _funcs()

    @wp.kernel(module="unique")
    def compose_kernel(
        unit: wp.array2d(dtype=vec8),  # (N, B)
        translations: wp.array2d(dtype=wp.vec3),  # (N, B), read when use_translations
        frames: wp.array(dtype=vec8),  # (N,), read when use_frames
        use_translations: int,
        use_frames: int,
        out: wp.array2d(dtype=vec8),
    ):
        n, b = wp.tid()
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
        out[n, b] = dq_pack(q0, qe)

    return compose_kernel


@functools.cache
def _skin_kernel(influences: int, corrected: bool = False):
    # K is a compile-time constant so the slot loop unrolls (as the LBS kernel). Slots come sorted
    # by weight, largest first (stable, so ties keep the first, as argmax does): slot 0 is the
    # pivot, whose sign is never flipped, so no extra gather. Padding slots point at bone 0 with
    # weight 0. The normalisation is folded into one scale: with the blend (a0, av; ae, aev) and
    # n² = a0² + |av|², dqs_reference's p + 2 v0 × (v0 × p + w0 p) + 2 (w0 ve − we v0 + v0 × ve)
    # on the normalised blend equals p + (2/n²) (av × (av × p + a0 p + aev) + a0 aev − ae av):
    # no square root (1.5× faster on the CPU than normalising first).
    wp = runtime.warp()
    vec8 = _vec8()

    @wp.kernel(module="unique")
    def dq_skin_kernel(
        rest: wp.array(dtype=wp.vec3),
        bone_indices: wp.array2d(dtype=wp.int32),  # (V, K), slot 0 the largest weight
        bone_weights: wp.array2d(dtype=wp.float32),
        dual_quaternions: wp.array2d(dtype=vec8),  # (n, B)
        offsets: wp.array2d(dtype=wp.vec3),  # (n, V) rest offsets, read only when corrected
        out: wp.array2d(dtype=wp.vec3),  # (n, V)
    ):
        f, i = wp.tid()
        pivot = dual_quaternions[f, bone_indices[i, 0]]
        acc = bone_weights[i, 0] * pivot
        for k in range(1, influences):
            q = dual_quaternions[f, bone_indices[i, k]]
            dot = q[0] * pivot[0] + q[1] * pivot[1] + q[2] * pivot[2] + q[3] * pivot[3]
            w = bone_weights[i, k]
            acc += wp.where(dot < 0.0, -w, w) * q
        scale = 2.0 / (acc[0] * acc[0] + acc[1] * acc[1] + acc[2] * acc[2] + acc[3] * acc[3])
        a0 = acc[0]
        av = wp.vec3(acc[1], acc[2], acc[3])
        aev = wp.vec3(acc[5], acc[6], acc[7])
        p = rest[i]
        if wp.static(corrected):
            p = p + offsets[f, i]
        out[f, i] = p + scale * (wp.cross(av, wp.cross(av, p) + a0 * p + aev) + a0 * aev - acc[4] * av)

    return dq_skin_kernel


@functools.cache
def _corrective_kernel():
    # Σ_j w_j O_j in float32 (offsets are small; w, which can be large and cancel, is computed in
    # float64 on the host). Used off the CPU; the CPU path is a BLAS product (_run_chunk).
    wp = runtime.warp()

    @wp.kernel(module="unique")
    def corrective_offsets_kernel(w: wp.array2d(dtype=wp.float64), offsets: wp.array2d(dtype=wp.vec3),
                                  out: wp.array2d(dtype=wp.vec3)):
        n, i = wp.tid()
        acc = wp.vec3()
        for j in range(w.shape[1]):
            acc += wp.float32(w[n, j]) * offsets[j, i]
        out[n, i] = acc

    return corrective_offsets_kernel


# ----------------------------------------------------------------------------------------------
# single-stage warp functions (numpy in, float64 numpy out)


def _f32(wp, values, dtype, device):
    return wp.array(np.ascontiguousarray(values, dtype=np.float32), dtype=dtype, device=device)


def _f64(wp, values, dtype, device):
    return wp.array(np.ascontiguousarray(values, dtype=np.float64), dtype=dtype, device=device)


def kernel_vectors(x, training, kind, offset=0.0, degree=5, device="cpu") -> np.ndarray:
    """ξ (N, n_p) float64 between standardised controls x (N, d) and training (n_p, d); one launch.

    kind "gaussian" exp(-|x-y|²/2), "polynomial" (xᵀy + offset)^degree, "linear" xᵀy.
    """
    _check_kind(kind)
    x, training = np.asarray(x), np.asarray(training)
    if x.ndim != 2 or training.ndim != 2 or x.shape[1] != training.shape[1]:
        raise ValueError(f"x (N, d) and training (n_p, d) must share d, got {x.shape} and {training.shape}")
    device = runtime.resolve_device(device)
    wp = runtime.warp()
    out = wp.empty((x.shape[0], training.shape[0]), dtype=wp.float64, device=device)
    if out.size:
        wp.launch(_kernel_vector_kernel(kind, int(degree)), dim=out.shape,
                  inputs=[_f64(wp, x, wp.float64, device), _f64(wp, training, wp.float64, device), float(offset)],
                  outputs=[out], device=device)
    return out.numpy()


def _predictor_columns(predictor):
    """M (8B, n_p) -> (B, n_p, 8) float64, so each bone's column j is one vec8d."""
    predictor = np.asarray(predictor)
    bones = predictor.shape[0] // 8
    return np.ascontiguousarray(predictor.reshape(bones, 8, -1).transpose(0, 2, 1), dtype=np.float64)


def predict_dual_quaternions(xi, predictor, bias, device="cpu") -> np.ndarray:
    """d (N, B, 8) float64 = M ξ + m (Feng §6.1): xi (N, n_p), predictor (8B, n_p), bias (8B,)."""
    xi, predictor, bias = np.asarray(xi), np.asarray(predictor), np.asarray(bias)
    if predictor.ndim != 2 or predictor.shape[0] % 8 or xi.ndim != 2 or xi.shape[1] != predictor.shape[1] \
            or bias.shape != (predictor.shape[0],):
        raise ValueError(f"expected xi (N, n_p), predictor (8B, n_p), bias (8B,); got {xi.shape}, "
                         f"{predictor.shape}, {bias.shape}")
    device = runtime.resolve_device(device)
    wp, vec8d = runtime.warp(), _vec8d()
    bones = predictor.shape[0] // 8
    out = wp.empty((xi.shape[0], bones), dtype=vec8d, device=device)
    if out.size:
        wp.launch(_predict_kernel(), dim=out.shape,
                  inputs=[_f64(wp, xi, wp.float64, device), _f64(wp, _predictor_columns(predictor), vec8d, device),
                          _f64(wp, bias.reshape(bones, 8), vec8d, device)],
                  outputs=[out], device=device)
    return out.numpy().reshape(xi.shape[0], bones, 8)


def normalise_dual_quaternions(d, device="cpu"):
    """(unit d (N, B, 8), rotations (N, B, 3, 3), translations (N, B, 3)), float64.

    Both parts are divided by |q0|; t = 2 (qe q0*).xyz."""
    d = np.asarray(d)
    if d.ndim != 3 or d.shape[2] != 8:
        raise ValueError(f"dual quaternions must be (N, B, 8), got {d.shape}")
    device = runtime.resolve_device(device)
    wp, vec8 = runtime.warp(), _vec8()
    shape = d.shape[:2]
    unit = wp.empty(shape, dtype=vec8, device=device)
    rot = wp.empty(shape, dtype=wp.mat33, device=device)
    trans = wp.empty(shape, dtype=wp.vec3, device=device)
    if unit.size:
        wp.launch(_normalise_kernel(), dim=shape, inputs=[_f64(wp, d, _vec8d(), device)], outputs=[unit, rot, trans],
                  device=device)
    return (unit.numpy().reshape(shape + (8,)).astype(np.float64), rot.numpy().astype(np.float64),
            trans.numpy().astype(np.float64))


def _check_operator(rotation_operator, control_operator, prior_operator):
    gamma, q, prior = (np.asarray(a) for a in (rotation_operator, control_operator, prior_operator))
    bones = gamma.shape[0]
    if gamma.shape != (bones, bones, 3) or q.ndim != 2 or q.shape[0] != bones or prior.shape != (bones, bones):
        raise ValueError(f"expected Γ (B, B, 3), Q (B, n_c), Π (B, B); got {gamma.shape}, {q.shape}, {prior.shape}")
    return gamma, q, prior


def solve_translations(rotations, controls, predicted_translations, rotation_operator, control_operator,
                       prior_operator, device="cpu") -> np.ndarray:
    """Poisson translations t (N, B, 3) float64 (Feng §6.2, ``pipeline.poisson.solve_translations``):

    t[n,b,a] = Σ_k Σ_c Γ[b,k,c] R[n,k,a,c] + Σ_l Q[b,l] c[n,l,a] + Σ_k Π[b,k] t̂[n,k,a].
    rotations (N, B, 3, 3), controls (N, n_c, 3) in place, predicted_translations t̂ (N, B, 3).
    """
    gamma, q, prior = _check_operator(rotation_operator, control_operator, prior_operator)
    rot, c, t_hat = np.asarray(rotations), np.asarray(controls), np.asarray(predicted_translations)
    samples, bones = rot.shape[:2]
    if rot.shape[1:] != (gamma.shape[0], 3, 3) or c.shape != (samples, q.shape[1], 3) or t_hat.shape != (samples, bones, 3):
        raise ValueError(f"expected rotations (N, {gamma.shape[0]}, 3, 3), controls (N, {q.shape[1]}, 3), "
                         f"translations (N, {gamma.shape[0]}, 3); got {rot.shape}, {c.shape}, {t_hat.shape}")
    device = runtime.resolve_device(device)
    wp = runtime.warp()
    out = wp.empty((samples, bones), dtype=wp.vec3, device=device)
    if out.size:
        wp.launch(_solve_kernel(), dim=out.shape,
                  inputs=[_f32(wp, rot, wp.mat33, device), _f32(wp, c, wp.vec3, device),
                          _f32(wp, t_hat, wp.vec3, device), _f32(wp, gamma, wp.vec3, device),
                          _f32(wp, q, wp.float32, device), _f32(wp, prior, wp.float32, device)],
                  outputs=[out], device=device)
    return out.numpy().astype(np.float64)


def _skin_arrays(rest_vertices, bone_indices, bone_weights, bones):
    """Validated rest, indices (padding -> 0) and weights, numpy, each vertex's slots sorted by
    weight, largest first (stably: the first largest is slot 0, the pivot of dqs_reference)."""
    rest, idx, w, _, _ = _checked(rest_vertices, bone_indices, bone_weights, np.zeros((0, bones, 3, 3)),
                                  np.zeros((0, bones, 3)))
    order = np.argsort(-w, axis=1, kind="stable")
    return rest, np.take_along_axis(idx, order, axis=1), np.take_along_axis(w, order, axis=1)


class _SkinBuffers:
    """Rest, skinning weights and pivots on the device."""

    def __init__(self, rest, idx, w, device):
        wp = runtime.warp()
        self.verts, self.influences = idx.shape
        self.rest = _f32(wp, rest, wp.vec3, device)
        self.idx = wp.array(idx.astype(np.int32), dtype=wp.int32, device=device)
        self.w = _f32(wp, w, wp.float32, device)

    def launch(self, dual_quaternions, out, device, offsets=None):
        """Skin into out (n, V); offsets (n, V) vec3 added to the rest pose first, or None."""
        wp = runtime.warp()
        corrected = offsets is not None
        if not corrected:
            offsets = wp.empty((1, 1), dtype=wp.vec3, device=device)
        wp.launch(_skin_kernel(self.influences, corrected), dim=out.shape,
                  inputs=[self.rest, self.idx, self.w, dual_quaternions, offsets], outputs=[out], device=device)


def corrective_offsets(blend_weights, offsets, device="cpu") -> np.ndarray:
    """Rest offsets (N, V, 3) float64 of the pose-space correctives, ``corrective_offsets_reference``
    as the device kernel (which the CPU path of :func:`run_puppet` replaces by BLAS products).
    blend_weights (N, n_p), offsets (n_p, V, 3)."""
    w, offsets = np.asarray(blend_weights), np.asarray(offsets)
    if w.ndim != 2 or offsets.ndim != 3 or offsets.shape[::2] != (w.shape[1], 3):
        raise ValueError(f"need blend_weights (N, n_p) and offsets (n_p, V, 3); got {w.shape}, {offsets.shape}")
    device = runtime.resolve_device(device)
    wp = runtime.warp()
    out = wp.empty((w.shape[0], offsets.shape[1]), dtype=wp.vec3, device=device)
    if out.size:
        wp.launch(_corrective_kernel(), dim=out.shape,
                  inputs=[_f64(wp, w, wp.float64, device), _f32(wp, offsets, wp.vec3, device)], outputs=[out],
                  device=device)
    return out.numpy().astype(np.float64)


def dq_skin(rest_vertices, bone_indices, bone_weights, dual_quaternions, device="cpu", rest_offsets=None) -> np.ndarray:
    """Dual-quaternion skinning, vertices (N, V, 3) float64: ``dqs_reference`` in one launch over
    (samples, vertices) per chunk of at most 2**24 vertex-samples. dual_quaternions (N, B, 8);
    rest_offsets (N, V, 3), optional: added to the rest pose of each sample first."""
    dq = np.asarray(dual_quaternions)
    if dq.ndim != 3 or dq.shape[2] != 8:
        raise ValueError(f"dual quaternions must be (N, B, 8), got {dq.shape}")
    rest, idx, w = _skin_arrays(rest_vertices, bone_indices, bone_weights, dq.shape[1])
    samples, verts = dq.shape[0], rest.shape[0]
    out = np.empty((samples, verts, 3))
    if rest_offsets is not None and np.shape(rest_offsets) != (samples, verts, 3):
        raise ValueError(f"rest_offsets must be ({samples}, {verts}, 3), got {np.shape(rest_offsets)}")
    if out.size == 0:
        return out
    device = runtime.resolve_device(device)
    wp, vec8 = runtime.warp(), _vec8()
    skin = _SkinBuffers(rest, idx, w, device)
    dq_d = _f32(wp, dq, vec8, device)
    step = max(1, _DEVICE_CHUNK // verts)
    buf = wp.empty((min(step, samples), verts), dtype=wp.vec3, device=device)
    offsets = None if rest_offsets is None else _f32(wp, rest_offsets, wp.vec3, device)
    for n0 in range(0, samples, step):
        n = min(step, samples - n0)
        skin.launch(dq_d[n0 : n0 + n], buf[:n], device, None if offsets is None else offsets[n0 : n0 + n])
        out[n0 : n0 + n] = buf[:n].numpy()
    return out


# ----------------------------------------------------------------------------------------------
# the whole run-time path


class DevicePuppet:
    """A puppet's arrays uploaded once to a device (float32), for repeated :func:`run_puppet` calls.

    ``DevicePuppet(puppet, device)`` with a ``pipeline.puppet.Puppet`` or :class:`PuppetArrays`.
    """

    def __init__(self, puppet, device="cpu"):
        arrays = _as_arrays(puppet)
        if isinstance(arrays, DevicePuppet):
            arrays = arrays.host
        _check_kind(arrays.kernel)
        self.host = arrays
        self.device = runtime.resolve_device(device)
        wp = runtime.warp()
        dev = self.device
        bones = arrays.bones
        rest, idx, w = _skin_arrays(arrays.rest_vertices, arrays.bone_indices, arrays.bone_weights, bones)
        self.skin = _SkinBuffers(rest, idx, w, dev)
        self.training = _f64(wp, arrays.training_controls, wp.float64, dev)
        if arrays.predictor.shape != (8 * bones, self.training.shape[0]) or np.shape(arrays.bias) != (8 * bones,):
            raise ValueError(f"predictor must be (8B, n_p) = (8·{bones}, {self.training.shape[0]}) and bias (8B,)")
        self.predictor = _f64(wp, _predictor_columns(arrays.predictor), _vec8d(), dev)
        self.bias = _f64(wp, np.reshape(arrays.bias, (bones, 8)), _vec8d(), dev)
        self.gamma = self.control_operator = self.prior = None
        if arrays.has_solver:
            gamma, q, prior = _check_operator(arrays.rotation_operator, arrays.control_operator,
                                              arrays.prior_operator)
            if gamma.shape[0] != bones:
                raise ValueError(f"the translation operator has {gamma.shape[0]} bones, the predictor {bones}")
            self.gamma = _f32(wp, gamma, wp.vec3, dev)
            self.control_operator = _f32(wp, q, wp.float32, dev)
            self.prior = _f32(wp, prior, wp.float32, dev)
            # On the CPU the solve is three matrix products, which BLAS does ~6x faster than the
            # scalar kernel: keep the operators as transposed float32 matrices for that.
            self.host_operators = (np.ascontiguousarray(gamma.reshape(bones, -1).T, dtype=np.float32),
                                   np.ascontiguousarray(q.T, dtype=np.float32),
                                   np.ascontiguousarray(prior.T, dtype=np.float32))
        self.corrective_offsets = None
        if arrays.has_correctives:
            n_p = self.training.shape[0]
            weights, offsets = np.asarray(arrays.corrective_weights), np.asarray(arrays.corrective_offsets)
            if weights.shape != (n_p, n_p) or offsets.shape != (n_p, self.skin.verts, 3):
                raise ValueError(f"corrective weights must be ({n_p}, {n_p}) and offsets ({n_p}, "
                                 f"{self.skin.verts}, 3), got {weights.shape} and {offsets.shape}")
            if dev == "cpu":  # the blend is a BLAS product there
                self.host_offsets = np.ascontiguousarray(offsets.reshape(n_p, -1), dtype=np.float32)
            else:
                self.corrective_offsets = _f32(wp, offsets, wp.vec3, dev)

    @property
    def bones(self):
        return self.host.bones

    @property
    def verts(self):
        return self.skin.verts


class _Workspace:
    """Per-chunk device buffers of run_puppet (one per thread)."""

    def __init__(self, samples, puppet, device):
        wp, vec8 = runtime.warp(), _vec8()
        samples = int(samples)  # chunk bounds may be numpy integers, which warp does not take as a shape
        bones, n_p = puppet.bones, puppet.training.shape[0]
        shape = (samples, bones)
        self.xi = wp.empty((samples, n_p), dtype=wp.float64, device=device)
        self.raw = wp.empty(shape, dtype=_vec8d(), device=device)
        self.unit = wp.empty(shape, dtype=vec8, device=device)
        self.rot = wp.empty(shape, dtype=wp.mat33, device=device)
        self.trans = wp.empty(shape, dtype=wp.vec3, device=device)
        self.solved = wp.empty(shape, dtype=wp.vec3, device=device)
        self.final = wp.empty(shape, dtype=vec8, device=device)
        self.frames = wp.empty(samples, dtype=vec8, device=device)
        self.offsets = None
        if puppet.corrective_offsets is not None:
            self.offsets = wp.empty((samples, puppet.verts), dtype=wp.vec3, device=device)
        self._out_shape, self._device, self._out = (samples, puppet.verts), device, None

    @property
    def out(self):
        """Skinning output buffer (allocated on first use: not needed when writing in place)."""
        if self._out is None:
            wp = runtime.warp()
            self._out = wp.empty(self._out_shape, dtype=wp.vec3, device=self._device)
        return self._out


_timings_lock = threading.Lock()


def _solve_with_blas(operators, rotations, controls, predicted, out):
    """t = Γ·R + Q·c + Π·t̂ as float32 matrix products into ``out`` (n, B, 3) (CPU views of the
    device arrays, so nothing is copied back). Rows of each product are (sample, axis a)."""
    gamma_t, control_t, prior_t = operators
    n, bones = rotations.shape[:2]
    r = rotations.transpose(0, 2, 1, 3).reshape(n * 3, bones * 3)  # row (n, a), column (k, c)
    t = r @ gamma_t
    t += np.asarray(controls, dtype=np.float32).transpose(0, 2, 1).reshape(n * 3, -1) @ control_t
    t += predicted.transpose(0, 2, 1).reshape(n * 3, bones) @ prior_t
    out[...] = t.reshape(n, 3, bones).transpose(0, 2, 1)


def _run_chunk(puppet, space, x, c, f, out, device, timings=None, offsets_host=None):
    """Run the whole path for one chunk of n samples: numpy inputs in, skinned (n, V, 3) into `out`.
    offsets_host: on the CPU, the chunk's corrective offsets (n, V, 3) float32, already computed
    (:func:`_cpu_corrective_offsets`; may be ``out`` itself: each vertex is read, then written)."""
    wp = runtime.warp()
    host = puppet.host
    n = x.shape[0]
    stamp = [time.perf_counter()]

    def mark(name):
        if timings is not None:
            wp.synchronize_device(device)
            now = time.perf_counter()
            with _timings_lock:
                timings[name] = timings.get(name, 0.0) + now - stamp[0]
            stamp[0] = now

    x_d = _f64(wp, x, wp.float64, device)
    solve = c is not None
    if f is not None:
        wp.launch(_frames_kernel(), dim=n, inputs=[_f32(wp, f, wp.mat44, device)], outputs=[space.frames[:n]],
                  device=device)
    mark("upload")
    xi, raw, unit, rot, trans = space.xi[:n], space.raw[:n], space.unit[:n], space.rot[:n], space.trans[:n]
    bones = puppet.bones
    wp.launch(_kernel_vector_kernel(host.kernel, int(host.degree)), dim=(n, xi.shape[1]),
              inputs=[x_d, puppet.training, float(host.offset)], outputs=[xi], device=device)
    mark("kernel_vectors")
    wp.launch(_predict_kernel(), dim=(n, bones), inputs=[xi, puppet.predictor, puppet.bias], outputs=[raw],
              device=device)
    mark("predict")
    wp.launch(_normalise_kernel(), dim=(n, bones), inputs=[raw], outputs=[unit, rot, trans], device=device)
    mark("normalise")
    if solve and device == "cpu":
        _solve_with_blas(puppet.host_operators, rot.numpy(), c, trans.numpy(), space.solved[:n].numpy())
        mark("solve_translations")
    elif solve:
        wp.launch(_solve_kernel(), dim=(n, bones),
                  inputs=[rot, _f32(wp, c, wp.vec3, device), trans, puppet.gamma, puppet.control_operator, puppet.prior],
                  outputs=[space.solved[:n]], device=device)
        mark("solve_translations")
    wp.launch(_compose_kernel(), dim=(n, bones),
              inputs=[unit, space.solved[:n], space.frames[:n], int(solve), int(f is not None)],
              outputs=[space.final[:n]], device=device)
    mark("compose")
    offsets = None
    if offsets_host is not None:
        offsets = wp.array(offsets_host, dtype=wp.vec3, device="cpu", copy=False)
    elif puppet.corrective_offsets is not None:
        offsets = space.offsets[:n]
        w = _corrective_weights(host, xi.numpy(), x)  # small (n, n_p), float64 on the host
        wp.launch(_corrective_kernel(), dim=offsets.shape, inputs=[_f64(wp, w, wp.float64, device),
                                                                   puppet.corrective_offsets],
                  outputs=[offsets], device=device)
        mark("correctives")
    direct = (device == "cpu" and out.dtype == np.float32 and out.flags.c_contiguous)
    if direct:  # skin straight into the caller's float32 buffer: no copy at all on the CPU
        target = wp.array(out.reshape(n, -1, 3), dtype=wp.vec3, device="cpu", copy=False)
    else:
        target = space.out[:n]
    puppet.skin.launch(space.final[:n], target, device, offsets)
    mark("skin")
    if not direct:
        out[...] = target.numpy()
    mark("download")


#: Samples per block of the CPU correctives' matrix products. BLAS rounds a row differently
#: depending on where it sits in a product, so the blocks are fixed (rows kR…kR+R−1 of the
#: whole run, one BLAS thread) whatever the chunks and threads: byte-identical output.
_CORRECTIVE_ROWS = 64


def _cpu_corrective_offsets(puppet, x, out, threads):
    """Corrective rest offsets of all samples into out (N, V, 3) float32: per fixed block, ξ
    and the blend weights in float64 (numpy), then Σ_j w_j O_j as one float32 product (80× the
    corrective kernel's speed on the CPU; the kernel serves CUDA). Blocks go round-robin to
    ``threads``."""
    host = puppet.host
    flat = out.reshape(out.shape[0], -1)
    starts = range(0, x.shape[0], _CORRECTIVE_ROWS)

    def work(first):
        for start in starts[first::threads]:
            stop = start + _CORRECTIVE_ROWS
            xi = kernel_vectors_reference(x[start:stop], host.training_controls, host.kernel, host.offset, host.degree)
            w = _corrective_weights(host, xi, x[start:stop])
            np.matmul(w.astype(np.float32), puppet.host_offsets, out=flat[start:stop])

    _in_threads(work, [(t,) for t in range(min(threads, len(starts)))])


def _in_threads(work, arguments):
    """work(*a) for each a of arguments, each in its own Python thread (one BLAS thread each:
    the threads already hold the cores, and one BLAS thread keeps products byte-identical)."""
    from threadpoolctl import threadpool_limits

    errors = []

    def guarded(*a):
        try:
            work(*a)
        except BaseException as exc:  # re-raised in the caller's thread
            errors.append(exc)

    with threadpool_limits(limits=1, user_api="blas"):
        if len(arguments) == 1:
            work(*arguments[0])
        else:
            pool = [threading.Thread(target=guarded, args=a) for a in arguments]
            for t in pool:
                t.start()
            for t in pool:
                t.join()
    if errors:
        raise errors[0]


def run_puppet(puppet, standardised_controls, controls_in_place=None, world_frames=None, translation_solver=True,
               device="cpu", out=None, threads=1, timings=None) -> np.ndarray:
    """The trained puppet's whole run-time path on a device: vertices (N, V, 3).

    puppet: a ``pipeline.puppet.Puppet``, :class:`PuppetArrays` or :class:`DevicePuppet` (uploaded
    once; its device wins over ``device``). Per sample n (frames × characters, flattened):
    standardised_controls (N, d) the in-place control vector, standardised
    (``puppet.kernel.standardise``); controls_in_place (N, n_c, 3) the in-place control points
    (needed only with the translation solver); world_frames (N, 4, 4) rigid column-vector
    homogeneous transforms from the in-place result to the world, or None for in-place output.
    ``pipeline.playback.host_inputs`` computes all three from world controls.

    Stages (all on the device, arrays stay there between launches): ξ, d = M ξ + m,
    normalise, [t = Γ·R + Q·c + Π·t̂], rebuild each bone's dual quaternion with t and compose
    it with the sample's world frame, dual-quaternion skinning. Samples go in chunks of at most
    2**24 skinned vertices.

    out: optional (N, V, 3) array to fill (float32 avoids the float64 conversion; on the CPU a
    C-contiguous float32 ``out`` is written in place by the kernel); returned. Default: a new
    float64 array. threads: on the CPU, split the samples over this many Python threads (warp
    releases the GIL during CPU launches; each thread runs the whole path on its slice).
    timings: optional dict, accumulates seconds per stage (synchronises after each stage).
    """
    dev_puppet = puppet if isinstance(puppet, DevicePuppet) else DevicePuppet(puppet, device)
    device = dev_puppet.device
    x, c, f = _check_inputs(dev_puppet.host, standardised_controls, controls_in_place, world_frames,
                            translation_solver)
    samples, verts = x.shape[0], dev_puppet.verts
    if out is None:
        out = np.empty((samples, verts, 3))
    elif out.shape != (samples, verts, 3):
        raise ValueError(f"out must be ({samples}, {verts}, 3), got {out.shape}")
    if samples == 0:
        return out
    threads = max(1, min(int(threads), samples)) if device == "cpu" else 1
    step = max(1, min(_DEVICE_CHUNK // verts, -(-samples // threads)))
    offsets = None
    if device == "cpu" and dev_puppet.host.has_correctives:
        direct = out.dtype == np.float32 and out.flags.c_contiguous
        offsets = out if direct else np.empty((samples, verts, 3), dtype=np.float32)
        _cpu_corrective_offsets(dev_puppet, x, offsets, threads)

    def work(lo, hi):
        space = _Workspace(min(step, hi - lo), dev_puppet, device)
        for n0 in range(lo, hi, step):
            n1 = min(n0 + step, hi)
            _run_chunk(dev_puppet, space, x[n0:n1], None if c is None else c[n0:n1],
                       None if f is None else f[n0:n1], out[n0:n1], device, timings,
                       None if offsets is None else offsets[n0:n1])

    if threads == 1:
        work(0, samples)
        return out
    bounds = np.linspace(0, samples, threads + 1).astype(int)
    # Each thread already has a core: a multi-threaded BLAS in the translation solve would
    # oversubscribe them (measured: 2,000 → 2,250 face frames/s with one BLAS thread each).
    _in_threads(work, [(lo, hi) for lo, hi in zip(bounds[:-1], bounds[1:]) if hi > lo])
    return out
