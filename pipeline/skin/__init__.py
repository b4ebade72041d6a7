"""fit-skin: a rigid-bone linear-blend skin fitted to a mesh sequence (Zheng §3.1, after Le & Deng
2012): clustering initialisation (:mod:`.skin_init`), per-bone weighted Procrustes
(:mod:`.bone_transforms`, :mod:`.transform_sweep`), per-vertex non-negative, affine, sparse
weights (:mod:`.skin_weights`, :mod:`.vertex_weights`, :mod:`.simplex_qp`), alternated to
convergence (:mod:`.skin_fit`).

Public: fit_skin, fit_bones_to_rig (a new take on a given rig), finish_fit, validate_fit_options, fit_memory_bytes, bone_rest_frames, SkinFit;
find_skeleton, Skeleton, MAX_JOINT_DRIFT (joints and a hierarchy found from a free fit: :mod:`.joints`; free_skin_skeleton,
the one ``play`` poses a free skin's puppet with beyond its examples),
fit_jointed (the rig refitted on its joints: :mod:`.jointed_fit`), fit_given_skeleton (under a skeleton the user brings),
fit_pruned_skeleton (grown from more bones, the redundant ones merged: :mod:`.bone_pruning`);
fit_rig (the fit a fit-skin request asks for, one of those), fit_rest_pose (its bones and rest pose, refused
before the fit when no fit can honour them) and skin_summary (its summary: :mod:`.rig_fit`);
compile_loops (the compiled loops built ahead of use: ``skinsynth precompile``); near_ground, keep_contacts and
playback_feet (a fit that keeps the capture's ground contacts, and how its playback keeps the feet: :mod:`.contact_fit`).
"""

from .._lazy import lazy_exports

_EXPORTS = {"fit_skin": "skin_fit", "fit_bones_to_rig": "skin_fit", "finish_fit": "skin_fit", "validate_fit_options": "skin_fit",
            "fit_memory_bytes": "skin_fit", "bone_rest_frames": "skin_fit",
            "SkinFit": "skin_fit", "compile_loops": "precompile",
            "find_skeleton": "joints", "Skeleton": "joints", "MAX_JOINT_DRIFT": "joints", "fit_jointed": "jointed_fit",
            "fit_given_skeleton": "jointed_fit", "fit_pruned_skeleton": "bone_pruning", "given_skeleton": "joints", "free_skin_skeleton": "joints", "fit_rig": "rig_fit",
            "fit_rest_pose": "rig_fit", "skin_summary": "rig_fit", "near_ground": "contact_fit",
            "keep_contacts": "contact_fit", "playback_feet": "contact_fit"}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
