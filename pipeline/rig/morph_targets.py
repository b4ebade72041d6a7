"""A puppet's pose-space correctives as a few morph targets, for formats whose engines play few.

The correctives (``pipeline.puppet.correctives``) are n_p rest-pose shapes, offsets (n_p, V, 3),
blended per frame with weights w (F, n_p): the skin plays ``skin(rest + w @ offsets)``. glTF's
morph targets are added to the rest pose before skinning, so they carry exactly this — but the
shapes themselves cannot be written as they are. Under a Gaussian kernel every weight of w is
non-zero at every frame (w = A ξ^p + tail, ξ a Gaussian of the distance to each example), so all
n_p shapes are active at once, and n_p is the number of training frames (tens to hundreds).
Engines play few simultaneously active morph targets: three.js's WebGL renderer had a limit of 8
(4 with normals) before it moved morphs into a texture (r133), and in Unity (blend shapes) and
Unreal (morph targets) every active target costs a pass over the mesh's vertices each frame, so
their budgets keep a character to a handful. Eight is what every engine plays as written.

So the shapes are compressed by PCA: the singular value decomposition of the offsets reshaped
(n_p, 3V) = U S Vᵀ gives targets, the leading k rows of S Vᵀ (k, V, 3), and per-frame target
weights w @ U[:, :k] (F, k), whose blend ``(w @ U_k) (S_k V_kᵀ)`` is the best rank-k
approximation of every blend the puppet can play. k is the smallest count whose reconstruction
of the blends actually played (every frame of every clip, every vertex) stays within a tolerance
of the rest bounding-box diagonal, at most :data:`MAX_MORPH_TARGETS`; more is refused. Each
target's sign is fixed by making its largest-magnitude component positive (the decomposition's
own signs are arbitrary), so the same correctives give the same targets.

The weights of a blend are signed, and some importers clamp a shape's weight to [0, 1] (Blender's
shape keys; its glTF importer sets the slider range from the first key only): :func:`unit_range_pairs`
writes each shape as a ± pair weighted in [0, 1], of which at most one is non-zero at a time, so
k components are 2k targets with at most k active.
"""

import numpy as np

from ..runtime.rows import unique_rows

#: Morph targets written at most: the few engines play simultaneously active (module docstring).
MAX_MORPH_TARGETS = 8
#: Largest vertex error of the compressed correctives, relative to the rest bounding-box diagonal.
MORPH_TOLERANCE = 1e-6
#: Values per chunk of played frames when measuring the reconstruction (bounds the (f, 3V) blend).
_CHUNK_VALUES = 1 << 22


def corrective_morph_targets(offsets, weights, diagonal, tolerance=MORPH_TOLERANCE, maximum=MAX_MORPH_TARGETS):
    """The correctives offsets (n_p, V, 3), played with blend weights (F, n_p) (every frame of
    every clip), as few morph targets: (targets (k, V, 3), target weights (F, k), the largest
    vertex error of the played blends (F, V) relative to ``diagonal``, the rest bounding-box
    diagonal). k is the smallest count within ``tolerance`` (relative to ``diagonal``); k = 0
    when no played blend moves a vertex by more. ValueError, naming the count needed and the
    error at ``maximum``, when more than ``maximum`` targets are needed."""
    offsets = np.asarray(offsets, dtype=np.float64)
    weights = np.asarray(weights, dtype=np.float64)
    shapes, verts = offsets.shape[:2]
    if weights.ndim != 2 or weights.shape[1] != shapes:
        raise ValueError(f"blend weights must have shape (F, {shapes}), got {weights.shape}")
    basis, singular, shape_rows = np.linalg.svd(offsets.reshape(shapes, -1), full_matrices=False)
    largest = np.argmax(np.abs(shape_rows), axis=1)
    signs = np.where(shape_rows[np.arange(len(singular)), largest] < 0.0, -1.0, 1.0)
    basis, shape_rows = basis * signs, shape_rows * signs[:, None]
    components = singular[:, None] * shape_rows  # (r, 3V): every target, largest first
    played = unique_rows(weights) @ basis  # (F', r): each distinct frame's blend, once
    bound = tolerance * diagonal
    errors = _truncation_errors(played, components, verts, min(maximum, len(singular)))
    within = np.flatnonzero(errors <= bound)
    if within.size == 0:
        everything = _truncation_errors(played, components, verts, len(singular))
        needed = np.flatnonzero(everything <= bound)
        count = int(needed[0]) if needed.size else len(singular)
        raise ValueError(f"the {shapes} corrective shapes need {count} morph targets to stay within {tolerance:g} "
                         f"of the rest diagonal ({maximum} leave {errors[-1] / diagonal:.2g} of it), and engines "
                         f"play at most {maximum} at once: train the puppet with train-kcca --correctives off for "
                         "glTF, or write UsdSkel (-o X.usdc), which carries every shape as a blend shape")
    count = int(within[0])
    targets = components[:count].reshape(count, verts, 3)
    return targets, weights @ basis[:, :count], float(errors[count] / diagonal) if diagonal > 0 else 0.0


def played_morph_targets(offsets, shape_weights, diagonal, characters, label):
    """A puppet's correctives ``offsets`` (n_p, V, 3), played by ``characters`` characters with
    blend weights shape_weights (C·F, n_p) or None, as morph targets
    (:func:`corrective_morph_targets`): (targets (k, V, 3), [weights (F, k) per character], the
    largest vertex error relative to ``diagonal``, the rest bounding-box diagonal; k = 0 when no
    played blend needs one), or None without correctives (``shape_weights`` None); an OptionError
    naming ``label`` (one line) when more than :data:`MAX_MORPH_TARGETS` would be needed."""
    from ..errors import OptionError

    if shape_weights is None:
        return None
    try:
        targets, weights, error = corrective_morph_targets(offsets, shape_weights, diagonal)
    except ValueError as problem:
        raise OptionError(f"{label}: {problem}") from None
    return targets, list(weights.reshape(characters, -1, len(targets))), error


def unit_range_pairs(shapes, weights):
    """The same blend with every weight in [0, 1]: shape j becomes ``+k_j O_j`` and ``−k_j O_j``
    weighted ``max(±w_j, 0) / k_j``, with k_j the largest |w_j| over every leading axis.
    shapes (S, V, 3), weights (..., S) -> (2S, V, 3) (pairs interleaved: j+, j−), (..., 2S)."""
    weights = np.asarray(weights, dtype=np.float64)
    shapes = np.asarray(shapes, dtype=np.float64)
    scale = np.maximum(np.abs(weights).max(axis=tuple(range(weights.ndim - 1))), np.finfo(np.float32).tiny)  # (S,)
    both = np.stack([shapes * scale[:, None, None], -shapes * scale[:, None, None]], axis=1)
    split = np.stack([np.maximum(weights, 0.0), np.maximum(-weights, 0.0)], axis=-1) / scale[:, None]
    return both.reshape(-1, *shapes.shape[1:]), split.reshape(*weights.shape[:-1], -1)


def _truncation_errors(played, components, verts, limit):
    """(limit + 1,): for k = 0 … limit targets, the largest vertex distance between the played
    blends played (F', r) @ components (r, 3V) and their first k terms, chunked over frames."""
    errors = np.zeros(limit + 1)
    step = max(1, _CHUNK_VALUES // max(1, components.shape[1]))
    for f0 in range(0, len(played), step):
        chunk = played[f0:f0 + step]
        residual = chunk @ components  # k = 0: the whole blend is the error
        for k in range(limit + 1):
            distance = np.linalg.norm(residual.reshape(len(chunk), verts, 3), axis=2).max()
            errors[k] = max(errors[k], distance)
            if k < limit:
                residual -= np.outer(chunk[:, k], components[k])
    return errors
