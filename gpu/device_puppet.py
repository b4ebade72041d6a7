"""A trained puppet's arrays on a warp device, and the per-chunk buffers of its run (host side)."""

import numpy as np

from . import runtime
from .device_arrays import float32_array, float64_array, predictor_columns
from .puppet_arrays import host_arrays
from .skinning import SkinBuffers, skin_arrays
from .validation import check_kind, checked_operator


class DevicePuppet:
    """A puppet's arrays uploaded once to a device (float32), for repeated ``run_puppet`` calls.

    ``DevicePuppet(puppet, device)`` with a ``pipeline.puppet.Puppet`` or
    :class:`~skinsynth.gpu.puppet_arrays.PuppetArrays`. training (n_p, d) and predictor (B, n_p)
    vec8d, bias (B,) vec8d stay float64 (``gpu.kernels.dual_quaternion``); the translation
    operator Γ (B, B) vec3, Q (B, n_c), Π (B, B) and the correctives' offsets (n_p, V) vec3 are
    float32. On the CPU the solve and the correctives' blend are BLAS products
    (``gpu.cpu_blas``): their operands stay on the host as transposed float32 matrices instead.
    """

    def __init__(self, puppet, device="cpu"):
        arrays = host_arrays(puppet)
        check_kind(arrays.kernel)
        self.host = arrays
        self.device = runtime.resolve_device(device)
        wp = runtime.warp()
        from .kernels.dual_quaternion import vec8d

        dev = self.device
        bones = arrays.bones
        rest, idx, w = skin_arrays(arrays.rest_vertices, arrays.bone_indices, arrays.bone_weights, bones)
        self.skin = SkinBuffers(rest, idx, w, dev)
        self.training = float64_array(arrays.training_controls, wp.float64, dev)
        if arrays.predictor.shape != (8 * bones, self.training.shape[0]) or np.shape(arrays.bias) != (8 * bones,):
            raise ValueError(f"predictor must be (8B, n_p) = (8·{bones}, {self.training.shape[0]}) and bias (8B,)")
        self.predictor = float64_array(predictor_columns(arrays.predictor), vec8d, dev)
        self.bias = float64_array(np.reshape(arrays.bias, (bones, 8)), vec8d, dev)
        self.gamma = self.control_operator = self.prior = None
        if arrays.has_solver:
            gamma, q, prior = checked_operator(arrays.rotation_operator, arrays.control_operator,
                                               arrays.prior_operator)
            if gamma.shape[0] != bones:
                raise ValueError(f"the translation operator has {gamma.shape[0]} bones, the predictor {bones}")
            self.gamma = float32_array(gamma, wp.vec3, dev)
            self.control_operator = float32_array(q, wp.float32, dev)
            self.prior = float32_array(prior, wp.float32, dev)
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
                self.corrective_offsets = float32_array(offsets, wp.vec3, dev)

    @property
    def bones(self):
        return self.host.bones

    @property
    def verts(self):
        return self.skin.verts


class Workspace:
    """Per-chunk device buffers of ``run_puppet`` (one per thread), for up to ``samples`` samples:
    xi (n, n_p), raw (n, B) vec8d, unit, final (n, B) vec8, rot (n, B) mat33, trans, solved (n, B)
    vec3, frames (n,) vec8, offsets (n, V) vec3 (with device correctives), out (n, V) vec3 and, for
    linear skinning, matrices (n, B) vec12 (each bone's [R | t])."""

    def __init__(self, samples, puppet, device):
        wp = runtime.warp()
        from .kernels.dual_quaternion import vec8, vec8d

        samples = int(samples)  # chunk bounds may be numpy integers, which warp does not take as a shape
        bones, n_p = puppet.bones, puppet.training.shape[0]
        shape = (samples, bones)
        self.xi = wp.empty((samples, n_p), dtype=wp.float64, device=device)
        self.raw = wp.empty(shape, dtype=vec8d, device=device)
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
        self._matrices = None

    @property
    def out(self):
        """Skinning output buffer (allocated on first use: not needed when writing in place)."""
        if self._out is None:
            wp = runtime.warp()
            self._out = wp.empty(self._out_shape, dtype=wp.vec3, device=self._device)
        return self._out

    @property
    def matrices(self):
        """Each bone's [R | t] (n, B) vec12, for linear skinning (allocated on first use)."""
        if self._matrices is None:
            wp = runtime.warp()
            from .kernels.skinning import vec12

            self._matrices = wp.empty(self.final.shape, dtype=vec12, device=self._device)
        return self._matrices
