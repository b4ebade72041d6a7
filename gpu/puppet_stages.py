"""The trained puppet's run-time stages (Feng et al. 2008, §6), each as one warp launch (host side).

Every function takes N *samples* (frames × characters, flattened: each sample is independent)
and runs one launch of ``gpu.kernels.puppet`` over all of them: numpy in, float64 numpy out.
The stages, each with its numpy reference in ``gpu.references.puppet``:

1. :func:`kernel_vectors` — ξ = k(x, training) for standardised controls x (N, d), (N, n_p);
2. :func:`predict_dual_quaternions` — d = M ξ + m for all bones at once (Feng §6.1), (N, B, 8);
3. :func:`normalise_dual_quaternions` — unit d, its rotations (N, B, 3, 3) and translations;
4. :func:`solve_translations` — the Poisson translations t = Γ·R + Q·c + Π·t̂ (Feng §6.2);
5. :func:`rigid_transforms` — for linear skinning, each bone's final 3×4 matrix [R | t] (N, B, 3, 4):
   the solver's translation and the world frame composed into its dual quaternion, then turned
   into a matrix, in one launch; ``gpu.skinning.linear_skin`` skins by them;
6. :func:`corrective_offsets` — the pose-space correctives' rest offsets Σ_j w_j O_j
   (``pipeline.correctives``; the blend weights w = A ξ^p + B [1, x Pᵀ] in float64 on the host,
   ``corrective_weights_reference``, the blend in float32), (N, V, 3); then ``gpu.skinning.dq_skin``
   (Kavan et al. 2007; Feng §6.3) skins the rest pose plus those offsets.

``gpu.puppet_run.run_puppet`` runs them all with the arrays staying on the device.
"""

import numpy as np

from . import runtime
from .device_arrays import float32_array, float64_array, predictor_columns
from .validation import check_kind, checked_operator


def kernel_vectors(x, training, kind, offset=0.0, degree=5, device="cpu") -> np.ndarray:
    """ξ (N, n_p) float64 between standardised controls x (N, d) and training (n_p, d); one launch.

    kind "gaussian" exp(-|x-y|²/2), "polynomial" (xᵀy + offset)^degree, "linear" xᵀy.
    """
    check_kind(kind)
    x, training = np.asarray(x), np.asarray(training)
    if x.ndim != 2 or training.ndim != 2 or x.shape[1] != training.shape[1]:
        raise ValueError(f"x (N, d) and training (n_p, d) must share d, got {x.shape} and {training.shape}")
    device = runtime.resolve_device(device)
    wp = runtime.warp()
    from .kernels.puppet import kernel_vector_kernel

    out = wp.empty((x.shape[0], training.shape[0]), dtype=wp.float64, device=device)
    if out.size:
        wp.launch(kernel_vector_kernel(kind, int(degree)), dim=out.shape,
                  inputs=[float64_array(x, wp.float64, device), float64_array(training, wp.float64, device),
                          float(offset)],
                  outputs=[out], device=device)
    return out.numpy()


def predict_dual_quaternions(xi, predictor, bias, device="cpu") -> np.ndarray:
    """d (N, B, 8) float64 = M ξ + m (Feng §6.1): xi (N, n_p), predictor (8B, n_p), bias (8B,)."""
    xi, predictor, bias = np.asarray(xi), np.asarray(predictor), np.asarray(bias)
    if predictor.ndim != 2 or predictor.shape[0] % 8 or xi.ndim != 2 or xi.shape[1] != predictor.shape[1] \
            or bias.shape != (predictor.shape[0],):
        raise ValueError(f"expected xi (N, n_p), predictor (8B, n_p), bias (8B,); got {xi.shape}, "
                         f"{predictor.shape}, {bias.shape}")
    device = runtime.resolve_device(device)
    wp = runtime.warp()
    from .kernels.dual_quaternion import vec8d
    from .kernels.puppet import predict_kernel

    bones = predictor.shape[0] // 8
    out = wp.empty((xi.shape[0], bones), dtype=vec8d, device=device)
    if out.size:
        wp.launch(predict_kernel, dim=out.shape,
                  inputs=[float64_array(xi, wp.float64, device),
                          float64_array(predictor_columns(predictor), vec8d, device),
                          float64_array(bias.reshape(bones, 8), vec8d, device)],
                  outputs=[out], device=device)
    return out.numpy().reshape(xi.shape[0], bones, 8)


def normalise_dual_quaternions(d, device="cpu"):
    """(unit d (N, B, 8), rotations (N, B, 3, 3), translations (N, B, 3)), float64.

    Both parts are divided by |q0|; t = 2 (qe q0*).xyz."""
    d = np.asarray(d)
    if d.ndim != 3 or d.shape[2] != 8:
        raise ValueError(f"dual quaternions must be (N, B, 8), got {d.shape}")
    device = runtime.resolve_device(device)
    wp = runtime.warp()
    from .kernels.dual_quaternion import vec8, vec8d
    from .kernels.puppet import normalise_kernel

    shape = d.shape[:2]
    unit = wp.empty(shape, dtype=vec8, device=device)
    rot = wp.empty(shape, dtype=wp.mat33, device=device)
    trans = wp.empty(shape, dtype=wp.vec3, device=device)
    if unit.size:
        wp.launch(normalise_kernel, dim=shape, inputs=[float64_array(d, vec8d, device)], outputs=[unit, rot, trans],
                  device=device)
    return (unit.numpy().reshape(shape + (8,)).astype(np.float64), rot.numpy().astype(np.float64),
            trans.numpy().astype(np.float64))


def solve_translations(rotations, controls, predicted_translations, rotation_operator, control_operator,
                       prior_operator, device="cpu") -> np.ndarray:
    """Poisson translations t (N, B, 3) float64 (Feng §6.2, ``pipeline.poisson.solve_translations``):

    t[n,b,a] = Σ_k Σ_c Γ[b,k,c] R[n,k,a,c] + Σ_l Q[b,l] c[n,l,a] + Σ_k Π[b,k] t̂[n,k,a].
    rotations (N, B, 3, 3), controls (N, n_c, 3) in place, predicted_translations t̂ (N, B, 3).
    """
    gamma, q, prior = checked_operator(rotation_operator, control_operator, prior_operator)
    rot, c, t_hat = np.asarray(rotations), np.asarray(controls), np.asarray(predicted_translations)
    samples, bones = rot.shape[:2]
    if rot.shape[1:] != (gamma.shape[0], 3, 3) or c.shape != (samples, q.shape[1], 3) or t_hat.shape != (samples, bones, 3):
        raise ValueError(f"expected rotations (N, {gamma.shape[0]}, 3, 3), controls (N, {q.shape[1]}, 3), "
                         f"translations (N, {gamma.shape[0]}, 3); got {rot.shape}, {c.shape}, {t_hat.shape}")
    device = runtime.resolve_device(device)
    wp = runtime.warp()
    from .kernels.puppet import solve_kernel

    out = wp.empty((samples, bones), dtype=wp.vec3, device=device)
    if out.size:
        wp.launch(solve_kernel, dim=out.shape,
                  inputs=[float32_array(rot, wp.mat33, device), float32_array(c, wp.vec3, device),
                          float32_array(t_hat, wp.vec3, device), float32_array(gamma, wp.vec3, device),
                          float32_array(q, wp.float32, device), float32_array(prior, wp.float32, device)],
                  outputs=[out], device=device)
    return out.numpy().astype(np.float64)


def rigid_transforms(dual_quaternions, translations=None, world_frames=None, device="cpu") -> np.ndarray:
    """Each bone's final [R | t] (N, B, 3, 4) float64 (``rigid_transforms_reference``): unit dual
    quaternions (N, B, 8), their translations replaced by ``translations`` (N, B, 3) if given, then
    composed with the rigid world frames (N, 4, 4) if given; the launch ``run_puppet`` makes for a
    linear skinning (``compose_rigid_kernel``)."""
    d = np.asarray(dual_quaternions)
    if d.ndim != 3 or d.shape[2] != 8:
        raise ValueError(f"dual quaternions must be (N, B, 8), got {d.shape}")
    shape = d.shape[:2]
    if translations is not None and np.shape(translations) != shape + (3,):
        raise ValueError(f"translations must be {shape + (3,)}, got {np.shape(translations)}")
    if world_frames is not None and np.shape(world_frames) != (shape[0], 4, 4):
        raise ValueError(f"world frames must be ({shape[0]}, 4, 4), got {np.shape(world_frames)}")
    device = runtime.resolve_device(device)
    wp = runtime.warp()
    from .kernels.dual_quaternion import vec8
    from .kernels.puppet import compose_rigid_kernel, frames_kernel
    from .kernels.skinning import vec12

    out = wp.empty(shape, dtype=vec12, device=device)
    if out.size == 0:
        return np.empty(shape + (3, 4))
    trans = wp.empty((1, 1), dtype=wp.vec3, device=device) if translations is None \
        else float32_array(translations, wp.vec3, device)
    frames = wp.empty(shape[0], dtype=vec8, device=device)
    if world_frames is not None:
        wp.launch(frames_kernel, dim=shape[0], inputs=[float32_array(world_frames, wp.mat44, device)],
                  outputs=[frames], device=device)
    wp.launch(compose_rigid_kernel, dim=shape,
              inputs=[float32_array(d, vec8, device), trans, frames, int(translations is not None),
                      int(world_frames is not None)],
              outputs=[out], device=device)
    return out.numpy().reshape(shape + (3, 4)).astype(np.float64)


def corrective_offsets(blend_weights, offsets, device="cpu") -> np.ndarray:
    """Rest offsets (N, V, 3) float64 of the pose-space correctives, ``corrective_offsets_reference``
    as the device kernel (which the CPU path of ``run_puppet`` replaces by BLAS products).
    blend_weights (N, n_p), offsets (n_p, V, 3)."""
    w, offsets = np.asarray(blend_weights), np.asarray(offsets)
    if w.ndim != 2 or offsets.ndim != 3 or offsets.shape[::2] != (w.shape[1], 3):
        raise ValueError(f"need blend_weights (N, n_p) and offsets (n_p, V, 3); got {w.shape}, {offsets.shape}")
    device = runtime.resolve_device(device)
    wp = runtime.warp()
    from .kernels.puppet import corrective_offsets_kernel

    out = wp.empty((w.shape[0], offsets.shape[1]), dtype=wp.vec3, device=device)
    if out.size:
        wp.launch(corrective_offsets_kernel, dim=out.shape,
                  inputs=[float64_array(w, wp.float64, device), float32_array(offsets, wp.vec3, device)],
                  outputs=[out], device=device)
    return out.numpy().astype(np.float64)
