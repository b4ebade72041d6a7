"""Varimax rotation (Kaiser 1958) of a loading matrix: the orthogonal rotation that localises bases.

Used by control-point selection (Feng et al. 2008 §3, after Meyer & Anderson 2007): the PCA bases
of the example vertex positions are rotated so that each one moves a small part of the surface.

The criterion is raw varimax, i.e. orthomax with γ = 1:

    maximise  Σ_j [ Σ_i L_ij⁴ − (1/p) (Σ_i L_ij²)² ]   over  L = A R,  R orthogonal,

solved by the usual SVD fixed-point iteration (the one in R's ``stats::varimax``): with
``G = Aᵀ (L³ − L diag(ΣL²)/p)`` and ``G = U S Vᵀ``, set ``R = U Vᵀ``; stop once Σ S grows by less
than a relative ``tol``. It maximises the same criterion as statsmodels'
``rotate_factors(A, "varimax")`` (gradient projection, no row normalisation), which the tests use
as the oracle.
"""

import numpy as np


def varimax(loadings, normalize=False, tol=1e-8, max_iter=500):
    """Rotate ``loadings`` (p, k) to maximise the raw varimax criterion.

    normalize: Kaiser normalisation, i.e. rotate the rows scaled to unit length and scale them
    back afterwards (rows of zero length stay zero). Control selection uses ``False``: with
    vertex coordinates as rows, normalising would blow up vertices that barely move in the
    retained subspace to the weight of those that move most.

    Returns (rotated (p, k) = loadings @ rotation, rotation (k, k) orthogonal).
    """
    a = np.asarray(loadings, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError(f"loadings must be a (p, k) matrix, got shape {a.shape}")
    p, k = a.shape
    if k < 2 or p == 0:  # one column (or no rows): nothing to rotate
        return a.copy(), np.eye(k)
    if normalize:
        norms = np.linalg.norm(a, axis=1, keepdims=True)
        scale = np.where(norms > 0.0, norms, 1.0)
        work = a / scale
    else:
        work = a
    rotation = np.eye(k)
    criterion = 0.0
    for _ in range(max_iter):
        rotated = work @ rotation
        gradient = work.T @ (rotated * (rotated * rotated - np.sum(rotated * rotated, axis=0) / p))
        u, s, vt = np.linalg.svd(gradient)
        rotation = u @ vt
        previous, criterion = criterion, float(np.sum(s))
        if previous > 0.0 and criterion < previous * (1.0 + tol):
            break
    rotated = a @ rotation
    return rotated, rotation
