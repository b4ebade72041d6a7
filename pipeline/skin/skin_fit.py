"""Smooth skinning decomposition with rigid bones (Le & Deng 2012, as used by Zheng §3.1).

Given example frames ``vertices (F, V, 3)`` of one mesh, find B rigid bone transforms per frame
and sparse convex weights so that ``v_i(t) ≈ Σ_j w_ij (R_j(t) ū_i + t_j(t))`` (Zheng eq. 1),
ū being the rest pose (one of the frames). Alternates the per-bone weighted Procrustes update
(:mod:`.bone_transforms`) and the per-vertex constrained weight solve (:mod:`.skin_weights`)
from a clustering initialisation (:mod:`.skin_init`) until the error stops improving.
"""

from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from .bone_transforms import Trajectories, fit_cluster_transforms, refine_bone_transforms
from ..errors import OptionError
from .skin_init import initial_clusters
from .skin_weights import update_weights
from .transform_sweep import sparse_weighted_sums, sweep_bone_transforms


@dataclass
class SkinFit:
    """A fitted LBS model.

    rest_vertices (V, 3); bone_indices (V, K) int32; bone_weights (V, K) (≥ 0, rows sum to 1,
    sorted decreasing); rotations (F, B, 3, 3) proper; translations (F, B, 3); rmse over all
    frames and vertices; error_history: RMSE after each iteration; labels (V,) the initial
    clusters; bones_without_weight: bones that no vertex uses at the end (normally 0).
    """

    rest_vertices: np.ndarray
    bone_indices: np.ndarray
    bone_weights: np.ndarray
    rotations: np.ndarray
    translations: np.ndarray
    rmse: float
    error_history: list = field(default_factory=list)
    iterations: int = 0
    converged: bool = False
    stopped: str = ""
    labels: np.ndarray | None = None
    bones_without_weight: int = 0



def converged_line(patience, gain, tolerance, relation):
    """How a fit says it stopped by its stopping rule: its last ``patience`` iterations changed the
    RMSE by the share ``gain`` (> 0: it fell), below ``tolerance``. Where they raised it (the
    weights' sparsity makes the alternation not quite monotone; a fit of exact data ends at the
    level of rounding, where a rise of 200 % is 1e-6 of the size) that is said as a rise, not as a
    negative improvement."""
    if gain < 0.0:
        return f"converged: the RMSE stopped falling (the last {patience} iterations raised it by {-gain:.2%}; --tolerance)"
    return f"converged: the last {patience} iterations improved the RMSE by {gain:.2%} ({relation} {tolerance:.2%}; --tolerance)"

def validate_fit_options(frame_count, vertex_count, bones, max_influences, iterations, rest_frame):
    """Raise OptionError for option values no fit can honour."""
    if bones < 1:
        raise OptionError(f"--bones must be at least 1 (got {bones})")
    if bones > vertex_count:
        raise OptionError(f"--bones {bones} is more than the mesh's {vertex_count} vertices: "
                          "each bone needs at least one vertex of its own")
    if max_influences < 1:
        raise OptionError(f"--max-influences must be at least 1 (got {max_influences})")
    if iterations < 1:
        raise OptionError(f"--iterations must be at least 1 (got {iterations})")
    if not -frame_count <= rest_frame < frame_count:
        raise OptionError(f"--rest-frame {rest_frame} is outside the {frame_count} frames")


#: Bones up to which ``joint_steps`` refine every frame's bones jointly (its system grows as B²).
JOINT_MAX_BONES = 64
#: What a fit holds besides its arrays: the interpreter, numpy, scipy and numba's compiled loops.
_FIT_BASE_BYTES = 340 << 20


def fit_memory_bytes(frame_count, vertex_count, bones, joint_steps=0):
    """Upper estimate of the bytes a fit holds at its peak, from its shapes, checked before it
    starts: the bone-pair sums Σ_t T_jᵀ T_k (B, B, 4, 4) float64 with the copies their einsum and
    the sweep make (4 in all), per-vertex arrays over every bone (V, B) float64 (3: clustering
    distances, warm starts, current weights), the frames (F, V, 3) float64 (4: input, centred,
    homogeneous, reconstruction), and with ``joint_steps`` (up to :data:`JOINT_MAX_BONES`) the joint
    solve's Hessian (F, B, 6, B, 6) float64 twice. Measured peaks (horse: 8,431 vertices, 48 frames, 2 iterations) were 0.30,
    0.50, 0.89 and 2.29 GB at 100, 400, 1,000 and 2,000 bones; this gives 0.42, 0.56, 1.11, 2.85."""
    pairs = 4 * 128 * bones * bones
    per_vertex = 3 * 8 * vertex_count * bones
    frames = 4 * 24 * frame_count * vertex_count
    joint = 2 * 288 * frame_count * bones * bones if joint_steps and bones <= JOINT_MAX_BONES else 0
    return _FIT_BASE_BYTES + pairs + per_vertex + frames + joint


def _reseed_unused_bones(transforms, weights_total, vertex_error, rest, data):
    """Give bones that lost all weight a fresh transform where the fit is worst.

    Each unused bone takes the rigid fit of the rest-pose neighbourhood (V/B nearest vertices)
    of a badly reconstructed vertex, so the next weight update can use it: the bone count
    asked for stays the bone count delivered.
    """
    unused = np.flatnonzero(weights_total <= 0.0)
    if unused.size == 0:
        return transforms
    frames, bones = transforms.shape[:2]
    size = max(3, data.count // bones)
    taken = np.zeros(data.count, dtype=bool)
    labels = np.full(data.count, unused.size, dtype=np.int64)
    for slot in range(unused.size):
        worst = np.argmax(np.where(taken, -np.inf, vertex_error))
        near = np.argsort(np.linalg.norm(rest - rest[worst], axis=1), kind="stable")[:size]
        near = near[~taken[near]]
        labels[near] = slot
        taken[near] = True
    fitted = fit_cluster_transforms(labels, unused.size + 1, data)
    transforms = transforms.copy()
    transforms[:, unused] = fitted[:, : unused.size]
    return transforms


def _bone_sweep(device):
    """The per-bone Procrustes sweep ``sweep(transforms, p, q)``: compiled on the CPU (device None)
    or the warp kernel on ``device``."""
    if device is None:
        return sweep_bone_transforms
    from skinsynth.gpu import sweep_bone_transforms_warp

    return lambda transforms, p, q: sweep_bone_transforms_warp(transforms, p, q, device)


# One BLAS thread: a threaded product sums in an order that depends on the thread count, and the
# same input must give the same file (issue 11). On two cores threads gained 4 % (horse, 22 bones).
@threadpool_limits.wrap(limits=1, user_api="blas")
def fit_skin(vertices, bones, max_influences=4, iterations=100, rest_frame=0, seed=0,
             tolerance=0.02, patience=5, candidates=None, sweeps=1, joint_steps=0, joint_max_bones=JOINT_MAX_BONES,
             progress=None,
             device=None, start=None):
    """Fit an LBS model with ``bones`` rigid bones to ``vertices (F, V, 3)``.

    Stopping rule: once the last ``patience`` iterations together improved the RMSE by less
    than ``tolerance`` of it (relative), more iterations stop paying and the fit stops
    (``converged``); else after ``iterations``. The defaults (2 % over 5 iterations) were chosen
    on the real captures: the error then falls by a few per cent per further 10 iterations
    (horse: 1.60e-3 of the diagonal at the stop, 1.54e-3 after 60; each iteration costs as much
    as the last). ``fit.stopped`` says which rule ended the fit. ``candidates`` bones are
    considered per vertex in the weight solve (default 2·max_influences). ``progress`` is
    called as ``progress(iteration, rmse)`` after each iteration. ``start``: (bone_indices (V, K),
    bone_weights (V, K), transforms (F, B, 3, 4)), a rig to go on from instead of the clustering
    (``seed`` then unused; :mod:`.helper_bones`). Returns :class:`SkinFit`.

    The weight solve and the bone sweep run compiled on every core (:mod:`.vertex_weights`,
    :mod:`.transform_sweep`), or with ``device`` (a warp device, e.g. "cuda:0") as warp kernels
    there (``gpu.skin_fit``: the same steps, equal to 1e-14 on the CPU); each vertex and
    each frame is solved on its own, so the result does not depend on the thread count.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    frames, count = vertices.shape[:2]
    validate_fit_options(frames, count, bones, max_influences, iterations, rest_frame)
    rest = vertices[rest_frame]
    data = Trajectories(vertices, rest)
    if start is None:
        labels = initial_clusters(data, rest, bones, seed=seed)
        transforms = fit_cluster_transforms(labels, bones, data)
        bone_indices = labels[:, None].astype(np.int32)
        bone_weights = np.ones((count, 1))
    else:  # go on from a rig: (bone_indices (V, K), bone_weights (V, K), transforms (F, B, 3, 4))
        bone_indices, bone_weights, transforms = start
        labels = bone_indices[np.arange(count), np.argmax(bone_weights, axis=1)].astype(np.int64)

    sweep = _bone_sweep(device)

    history, quiet, converged = [], 0, False
    stopped = f"iteration limit ({iterations}; --iterations)"
    for iteration in range(1, iterations + 1):
        p, q = sparse_weighted_sums(bone_indices, bone_weights, data, bones)
        for _ in range(sweeps):
            transforms = sweep(transforms, p, q)
        if joint_steps and bones <= joint_max_bones:
            transforms = refine_bone_transforms(transforms, p, q, steps=joint_steps)
        bone_indices, bone_weights, vertex_error = update_weights(
            transforms, data, bone_indices, bone_weights, max_influences, candidates, device=device)
        rmse = float(np.sqrt(vertex_error.sum() / (frames * count)))
        history.append(rmse)
        if progress is not None:
            progress(iteration, rmse)
        totals = np.bincount(bone_indices.ravel(), weights=bone_weights.ravel(), minlength=bones)
        if iteration < iterations and (totals <= 0.0).any():
            transforms = _reseed_unused_bones(transforms, totals, vertex_error, rest, data)
            quiet = 0
            continue
        quiet += 1  # iterations since the last reseed
        if quiet > patience and history[-1 - patience] - rmse < tolerance * history[-1 - patience]:
            gain = (history[-1 - patience] - rmse) / history[-1 - patience]
            stopped = converged_line(patience, gain, tolerance, "<")
            converged = True
            break
    totals = np.bincount(bone_indices.ravel(), weights=bone_weights.ravel(), minlength=bones)
    return SkinFit(
        rest_vertices=rest.copy(), bone_indices=bone_indices, bone_weights=bone_weights,
        rotations=transforms[..., :3], translations=transforms[..., 3], rmse=history[-1],
        error_history=history, iterations=len(history), converged=converged, stopped=stopped, labels=labels,
        bones_without_weight=int((totals <= 0.0).sum()))


def finish_fit(fit, vertices, rest_frames=None):
    """What the skin file keeps beyond the fit itself, for the fit of vertices (F, V, 3): the
    error measured on a direct reconstruction, not the fit's running sum (sets ``fit.rmse``);
    returns (per-frame RMSE (F,), the bones as dual quaternions (F, B, 8) on one hemisphere per
    bone over the frames (Feng §4.3), the bones' rest frames (B, 4, 4): ``rest_frames`` where
    given (a rig's, so that new clips on it drive exactly the same skeleton), else
    :func:`bone_rest_frames`)."""
    from skinsynth.gpu import lbs_reference

    from ..rig.rotations import align_hemispheres, rigid_to_dual_quaternion

    reconstruction = lbs_reference(fit.rest_vertices, fit.bone_indices, fit.bone_weights, fit.rotations,
                                   fit.translations)
    squared = np.sum((reconstruction - vertices) ** 2, axis=2)
    fit.rmse = float(np.sqrt(squared.mean()))
    dual_quaternions = align_hemispheres(rigid_to_dual_quaternion(fit.rotations, fit.translations), axis=0)
    if rest_frames is None:
        rest_frames = bone_rest_frames(fit.rest_vertices, fit.bone_indices, fit.bone_weights, fit.rotations.shape[1])
    return np.sqrt(squared.mean(axis=1)), dual_quaternions, rest_frames


def bone_rest_frames(rest_vertices, bone_indices, bone_weights, bones):
    """frames (B, 4, 4): world-from-bone rest transforms for a skeleton export.

    Identity rotation, origin at the weighted centroid of the bone's vertices (the rest-pose
    centre of what it moves); a bone without weight sits at the mesh centroid.
    """
    mass = np.bincount(bone_indices.ravel(), weights=bone_weights.ravel(), minlength=bones)
    centre = np.stack([np.bincount(bone_indices.ravel(), weights=(bone_weights * rest_vertices[:, a, None]).ravel(),
                                   minlength=bones) for a in range(3)], axis=1)
    centre = np.where(mass[:, None] > 0.0, centre / np.maximum(mass, 1e-300)[:, None], rest_vertices.mean(axis=0))
    frames = np.tile(np.eye(4), (bones, 1, 1))
    frames[:, :3, 3] = centre
    return frames


@threadpool_limits.wrap(limits=1, user_api="blas")
def fit_bones_to_rig(vertices, rest, bone_indices, bone_weights, bones, iterations=100, tolerance=0.001, patience=3,
                     joint_steps=1, progress=None, device=None):
    """Bone transforms of new frames on a given rig: Dem Bones' "solve bones for given weights".

    vertices (F, V, 3) the new frames; rest (V, 3), bone_indices (V, K), bone_weights (V, K) and
    its B ``bones``: the rig, kept exactly (the new take drives the same skeleton). Minimises Zheng eq. 1's error
    over rotations (F, B, 3, 3) and translations (F, B, 3) alone: a start from each bone's
    Procrustes fit of the vertices it dominates (a bone that dominates none starts at the
    identity), then per-bone weighted Procrustes sweeps (:mod:`.transform_sweep`, each an exact
    block update, so the error never rises) with ``joint_steps`` joint Gauss-Newton steps of every
    bone of a frame per iteration (:func:`.bone_transforms.refine_bone_transforms`, up to
    :data:`JOINT_MAX_BONES` bones: with the weights fixed, coupled bones move together there,
    where the sweep moves them one at a time). Stops once the last ``patience`` iterations
    together improved the RMSE by less than ``tolerance`` (relative; stricter than
    :func:`fit_skin`'s, since an iteration here costs a few milliseconds), else after
    ``iterations``. The error is computed from the sums alone (:func:`.bone_transforms.frame_energies`).
    Returns a :class:`SkinFit` with the rig's rest pose and weights.
    """
    from .bone_transforms import frame_energies

    vertices = np.asarray(vertices, dtype=np.float64)
    frames, count = vertices.shape[:2]
    bone_indices = np.asarray(bone_indices, dtype=np.int32)
    bone_weights = np.asarray(bone_weights, dtype=np.float64)
    if iterations < 1:
        raise OptionError(f"--iterations must be at least 1 (got {iterations})")
    data = Trajectories(vertices, np.asarray(rest, dtype=np.float64))
    p, q = sparse_weighted_sums(bone_indices, bone_weights, data, bones)
    dominant = bone_indices[np.arange(count), np.argmax(bone_weights, axis=1)]
    transforms = fit_cluster_transforms(dominant, bones, data)
    alone = np.bincount(dominant, minlength=bones) == 0
    transforms[:, alone] = np.eye(3, 4)
    sweep = _bone_sweep(device)

    squared = float(data.squared_norm.sum())
    history, converged = [], False
    stopped = f"iteration limit ({iterations}; --iterations)"
    for iteration in range(1, iterations + 1):
        transforms = sweep(transforms, p, q)
        if joint_steps and bones <= JOINT_MAX_BONES:
            transforms = refine_bone_transforms(transforms, p, q, steps=joint_steps)
        energy = squared + float(frame_energies(transforms, p, q).sum())
        rmse = float(np.sqrt(max(energy, 0.0) / (frames * count)))
        history.append(rmse)
        if progress is not None:
            progress(iteration, rmse)
        if iteration > patience and history[-1 - patience] - rmse <= tolerance * history[-1 - patience]:
            gain = (history[-1 - patience] - rmse) / history[-1 - patience] if history[-1 - patience] else 0.0
            stopped = converged_line(patience, gain, tolerance, "≤")
            converged = True
            break
    return SkinFit(
        rest_vertices=np.asarray(rest, dtype=np.float64).copy(), bone_indices=bone_indices,
        bone_weights=bone_weights, rotations=transforms[..., :3], translations=transforms[..., 3], rmse=history[-1],
        error_history=history, iterations=len(history), converged=converged, stopped=stopped, labels=dominant,
        bones_without_weight=int((np.bincount(bone_indices.ravel(), weights=bone_weights.ravel(),
                                              minlength=bones) <= 0.0).sum()))
