"""skinsynth.gpu: warp kernels with numpy references, and the device choice.

Public API (resolved lazily, so importing this package neither imports nor initialises warp):
lbs, dq_skin, linear_skin (skinning), lbs_reference, dqs_reference, vertex_dual_quaternions
(references.skinning), resolve_device, available_devices, DeviceError (runtime); the puppet's
run-time path: kernel_vectors, predict_dual_quaternions, normalise_dual_quaternions,
solve_translations, rigid_transforms, corrective_offsets (puppet_stages, one launch each),
run_puppet (puppet_run), DevicePuppet (device_puppet), PuppetArrays (puppet_arrays), and their
numpy references (references.puppet): the stage references *_reference and reference_run_puppet;
fit-skin's two warp solves (skin_fit): solve_vertex_weights_warp, sweep_bone_transforms_warp. The
quaternion and dual-quaternion arithmetic is pipeline.rotations' (the floor of the algorithms); the
references here write the few closed forms they need themselves, as independent oracles.

Three kinds of module: references/ (numpy only), kernels/ (the warp kernels at module level;
each imports and initialises warp, through runtime, when imported), and the launchers here
(host code: validation, uploads, chunks, BLAS threads, launches), which import kernels/ only
inside their functions. runtime.py is the one place that imports and initialises warp.
compile_cpu_kernels (precompile) builds every module the CPU path loads ahead of use.
"""

import importlib

_EXPORTS = {
    "lbs": "skinning",
    "lbs_reference": "references.skinning",
    "dqs_reference": "references.skinning",
    "vertex_dual_quaternions": "references.skinning",
    "kernel_vectors": "puppet_stages",
    "predict_dual_quaternions": "puppet_stages",
    "normalise_dual_quaternions": "puppet_stages",
    "solve_translations": "puppet_stages",
    "dq_skin": "skinning",
    "linear_skin": "skinning",
    "rigid_transforms": "puppet_stages",
    "rigid_transforms_reference": "references.puppet",
    "corrective_offsets": "puppet_stages",
    "corrective_offsets_reference": "references.puppet",
    "corrective_weights_reference": "references.puppet",
    "run_puppet": "puppet_run",
    "reference_run_puppet": "references.puppet",
    "PuppetArrays": "puppet_arrays",
    "DevicePuppet": "device_puppet",
    "kernel_vectors_reference": "references.puppet",
    "predict_dual_quaternions_reference": "references.puppet",
    "normalise_dual_quaternions_reference": "references.puppet",
    "solve_translations_reference": "references.puppet",
    "solve_vertex_weights_warp": "skin_fit",
    "sweep_bone_transforms_warp": "skin_fit",
    "compile_cpu_kernels": "precompile",
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
