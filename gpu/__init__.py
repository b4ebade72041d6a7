"""skinsynth.gpu: warp kernels with numpy references, and the device choice.

Public API (resolved lazily, so importing this package neither imports nor initialises warp):
lbs, lbs_reference, dqs_reference, vertex_dual_quaternions, resolve_device, available_devices, DeviceError; the puppet's
run-time path (puppet_kernels): kernel_vectors, predict_dual_quaternions, normalise_dual_quaternions,
solve_translations, corrective_offsets, dq_skin, run_puppet, reference_run_puppet, PuppetArrays, DevicePuppet, and the
stage references *_reference; fit-skin's two warp solves (skin_fit_kernels):
solve_vertex_weights_warp, sweep_bone_transforms_warp; and the quaternion and dual-quaternion
arithmetic its references share with pipeline.rotations (dual_quaternions, numpy only):
quaternion_to_matrix, quaternion_multiply, dual_quaternion_to_rigid, with_translations.
"""

import importlib

_EXPORTS = {
    "lbs": "skinning",
    "lbs_reference": "skinning",
    "dqs_reference": "skinning",
    "vertex_dual_quaternions": "skinning",
    "kernel_vectors": "puppet_kernels",
    "predict_dual_quaternions": "puppet_kernels",
    "normalise_dual_quaternions": "puppet_kernels",
    "solve_translations": "puppet_kernels",
    "dq_skin": "puppet_kernels",
    "corrective_offsets": "puppet_kernels",
    "corrective_offsets_reference": "puppet_kernels",
    "corrective_weights_reference": "puppet_kernels",
    "run_puppet": "puppet_kernels",
    "reference_run_puppet": "puppet_kernels",
    "PuppetArrays": "puppet_kernels",
    "DevicePuppet": "puppet_kernels",
    "kernel_vectors_reference": "puppet_kernels",
    "predict_dual_quaternions_reference": "puppet_kernels",
    "normalise_dual_quaternions_reference": "puppet_kernels",
    "solve_translations_reference": "puppet_kernels",
    "solve_vertex_weights_warp": "skin_fit_kernels",
    "sweep_bone_transforms_warp": "skin_fit_kernels",
    "quaternion_to_matrix": "dual_quaternions",
    "quaternion_multiply": "dual_quaternions",
    "dual_quaternion_to_rigid": "dual_quaternions",
    "with_translations": "dual_quaternions",
    "resolve_device": "runtime",
    "available_devices": "runtime",
    "DeviceError": "runtime",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    globals()[name] = value  # later look-ups skip this hook
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
