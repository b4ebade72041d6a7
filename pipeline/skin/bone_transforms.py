"""Rigid bone transforms of a linear-blend-skinning model, fitted by weighted Procrustes.

Transforms are stored as ``transforms (F, B, 3, 4)``: ``[R | t]`` acting on homogeneous rest
positions ``(x, y, z, 1)``. The per-bone update of smooth skinning decomposition (Le & Deng 2012,
used by Zheng §3.1) fixes every other bone and solves a weighted Procrustes problem per frame.
Following Dem Bones, the vertex sums it needs are gathered once per weight update into
``P (B, F, 3, 4)`` and ``Q (B, B, 4, 4)``, so each sweep over bones costs O(B² · F), never
O(V · F · B).
"""

import numpy as np
import scipy.sparse as sp

from ..rig.rotations import polar_rotation


class Trajectories:
    """The example frames arranged once for every product the fit needs.

    vertices (F, V, 3), rest (V, 3). Attributes: ``homogeneous (V, 4)``, ``flat (V, F*3)``
    (vertex-major trajectories, for matrix products), ``squared_norm (V,)`` (Σ_t |v_i(t)|²),
    ``frames`` F, ``count`` V.
    """

    def __init__(self, vertices, rest):
        vertices = np.asarray(vertices, dtype=np.float64)
        self.frames, self.count = vertices.shape[:2]
        self.homogeneous = np.concatenate([rest, np.ones((self.count, 1))], axis=1)
        self.flat = np.ascontiguousarray(vertices.transpose(1, 0, 2).reshape(self.count, -1))
        self.squared_norm = np.einsum("ij,ij->i", self.flat, self.flat)


def weighted_sums(weights, data):
    """Vertex sums for the transform update.

    weights (V, B) sparse or dense -> (P (B, F, 3, 4), Q (B, B, 4, 4)) with
    ``P[j, t] = Σ_i w_ij v_i(t) ũ_iᵀ`` and ``Q[j, k] = Σ_i w_ij w_ik ũ_i ũ_iᵀ`` (ũ homogeneous rest).
    """
    weights = sp.coo_matrix(weights)
    n_vertices, n_bones = weights.shape
    # Row i of wu holds w_ij * ũ_i in columns 4j..4j+3: (V, B*4), as sparse as the weights.
    slot = np.arange(4)
    wu = sp.csr_matrix(
        ((weights.data[:, None] * data.homogeneous[weights.row]).ravel(),
         (np.repeat(weights.row, 4), (weights.col[:, None] * 4 + slot).ravel())),
        shape=(n_vertices, n_bones * 4))
    p = np.asarray(wu.T @ data.flat).reshape(n_bones, 4, data.frames, 3).transpose(0, 2, 3, 1)
    q = (wu.T @ wu).toarray().reshape(n_bones, 4, n_bones, 4).transpose(0, 2, 1, 3)
    return np.ascontiguousarray(p), np.ascontiguousarray(q)


def procrustes_from_sums(moment, second):
    """Best rigid transform from weighted sums.

    moment (..., 3, 4) = ``Σ_i ω_i y_i ũ_iᵀ``, second (..., 4, 4) = ``Σ_i ω_i² ũ_i ũ_iᵀ`` where the
    per-vertex targets are ``y_i/ω_i`` with weight ``ω_i²``. Returns transforms (..., 3, 4)
    minimising ``Σ_i ω_i² |R u_i + t − y_i/ω_i|²`` with R a proper rotation.
    """
    mass = second[..., 3, 3]
    safe = np.where(mass > 0.0, mass, 1.0)
    rest_mean = second[..., :3, 3] / safe[..., None]
    target_sum = moment[..., :, 3]
    cross = moment[..., :, :3] - target_sum[..., :, None] * rest_mean[..., None, :]
    rotation = polar_rotation(cross)
    translation = target_sum / safe[..., None] - np.einsum("...ab,...b->...a", rotation, rest_mean)
    return np.concatenate([rotation, translation[..., None]], axis=-1)


def update_bone_transforms(transforms, p, q):
    """One Gauss-Seidel sweep of per-bone weighted Procrustes over all frames at once.

    transforms (F, B, 3, 4) current; p (B, F, 3, 4), q (B, B, 4, 4) from :func:`weighted_sums`.
    For bone j the residual target of vertex i is ``v_i − Σ_{k≠j} w_ik T_k ũ_i`` with weight
    ``w_ij``; its sums are ``P_j − Σ_{k≠j} T_k Q_kj``. Bones without weight keep their
    transform. Returns the updated transforms (F, B, 3, 4).
    """
    transforms = transforms.copy()
    coupled = q[:, :, 3, 3] > 0.0
    for j in np.flatnonzero(np.diag(coupled)):
        others = np.flatnonzero(coupled[j])
        others = others[others != j]
        moment = p[j] - np.einsum("tkac,kcd->tad", transforms[:, others], q[others, j])
        transforms[:, j] = procrustes_from_sums(moment, q[j, j])
    return transforms


def fit_cluster_transforms(labels, n_clusters, data):
    """One rigid transform per cluster and frame: transforms (F, n_clusters, 3, 4).

    labels (V,) in [0, n_clusters). Each cluster's transform is the Procrustes fit of its rest
    vertices onto their positions in every frame.
    """
    hard = sp.csr_matrix((np.ones(data.count), (np.arange(data.count), labels)),
                         shape=(data.count, n_clusters))
    p, q = weighted_sums(hard, data)
    diag = np.arange(n_clusters)
    return procrustes_from_sums(p, q[diag, diag][:, None]).transpose(1, 0, 2, 3)


def transform_products(transforms):
    """H (B, B, 4, 4) = Σ_t T_j(t)ᵀ T_k(t), the frame-summed Gram blocks of bone transforms."""
    return np.einsum("tjac,tkad->jkcd", transforms, transforms, optimize=True)


def bone_projections(transforms, data):
    """b (V, B) = Σ_t (T_j(t) ũ_i) · v_i(t): how well each bone alone points at each vertex."""
    frames, bones = transforms.shape[:2]
    stacked = transforms.transpose(0, 2, 1, 3).reshape(frames * 3, bones * 4)
    z = (data.flat @ stacked).reshape(data.count, bones, 4)
    return np.einsum("ijc,ic->ij", z, data.homogeneous)


def single_bone_errors(transforms, data, products=None, projections=None):
    """e (V, B) = Σ_t |T_j(t) ũ_i − v_i(t)|²: squared error of vertex i if bone j moved it alone."""
    products = transform_products(transforms) if products is None else products
    projections = bone_projections(transforms, data) if projections is None else projections
    diag = np.arange(products.shape[0])
    outer = (data.homogeneous[:, :, None] * data.homogeneous[:, None, :]).reshape(data.count, 16)
    own = outer @ products[diag, diag].reshape(-1, 16).T
    return np.maximum(own - 2.0 * projections + data.squared_norm[:, None], 0.0)


# Generators of so(3): _SKEW[a] = [e_a]×.
_SKEW = np.zeros((3, 3, 3))
_SKEW[0, 2, 1], _SKEW[0, 1, 2] = 1.0, -1.0
_SKEW[1, 0, 2], _SKEW[1, 2, 0] = 1.0, -1.0
_SKEW[2, 1, 0], _SKEW[2, 0, 1] = 1.0, -1.0


def frame_energies(transforms, p, q):
    """E (F,) = Σ_i |Σ_j w_ij T_j ũ_i − v_i|² − Σ_i |v_i|² per frame, from the sums alone."""
    quad = np.einsum("tjac,jkcd,tkad->t", transforms, q, transforms, optimize=True)
    return quad - 2.0 * np.einsum("jtac,tjac->t", p, transforms)


def _gauss_newton_system(transforms, p, q):
    """Gauss-Newton normal matrix (F, 6B, 6B) and gradient (F, 6B) of the per-frame energy.

    Parameters per bone: a rotation increment ω (R ← exp([ω]×) R) then a translation increment.
    Every entry comes from Q and P: no vertex is touched.
    """
    frames, bones = transforms.shape[:2]
    rot = transforms[..., :3]
    s, m = q[:, :, :3, :3], q[:, :, :3, 3]
    x = np.einsum("tjab,jkbc,tkdc->tjkad", rot, s, rot, optimize=True)
    h_ww = np.einsum("axy,tjkyz,bxz->tjakb", _SKEW, x, _SKEW, optimize=True)
    y = np.einsum("tjxy,jky->tjkx", rot, m)
    h_wt = np.einsum("abx,tjkx->tjakb", _SKEW, y)
    h_tt = np.einsum("jk,ab->jakb", q[:, :, 3, 3], np.eye(3))
    h = np.zeros((frames, bones, 6, bones, 6))
    h[:, :, :3, :, :3] = h_ww
    h[:, :, :3, :, 3:] = h_wt
    h[:, :, 3:, :, :3] = h_wt.transpose(0, 3, 4, 1, 2)
    h[:, :, 3:, :, 3:] = h_tt
    grad_blocks = np.einsum("tkac,kjcd->tjad", transforms, q, optimize=True) - p.transpose(1, 0, 2, 3)
    g = np.empty((frames, bones, 6))
    g[..., :3] = np.einsum("tjxy,axz,tjzy->tja", grad_blocks[..., :3], _SKEW, rot, optimize=True)
    g[..., 3:] = grad_blocks[..., 3]
    return h.reshape(frames, 6 * bones, 6 * bones), g.reshape(frames, 6 * bones)


def _apply_increment(transforms, step):
    from ..rig.rotations import rotation_exp

    frames, bones = transforms.shape[:2]
    step = step.reshape(frames, bones, 6)
    out = transforms.copy()
    out[..., :3] = rotation_exp(step[..., :3]) @ transforms[..., :3]
    out[..., 3] = transforms[..., 3] + step[..., 3:]
    return out


def refine_bone_transforms(transforms, p, q, steps=4, damping=1e-6):
    """Joint Levenberg-Marquardt refinement of all bones of each frame at once.

    transforms (F, B, 3, 4); p, q from :func:`weighted_sums`. Gauss-Seidel sweeps converge
    slowly where neighbouring bones share many vertices; solving the 6B-parameter problem of
    each frame together removes that. Each frame keeps its own damping and accepts a step only
    if its energy falls, so the result is never worse than the input. Cost per step:
    O(B² · F) to build the systems plus F solves of size 6B.
    """
    frames, bones = transforms.shape[:2]
    energy = frame_energies(transforms, p, q)
    lam = np.full(frames, damping)
    for _ in range(steps):
        h, g = _gauss_newton_system(transforms, p, q)
        diag = np.einsum("tii->ti", h)
        floor = 1e-9 * np.maximum(diag.mean(axis=1, keepdims=True), np.finfo(float).tiny)
        for _attempt in range(4):
            damped = h.copy()
            idx = np.arange(6 * bones)
            damped[:, idx, idx] += lam[:, None] * diag + floor
            step = np.linalg.solve(damped, -g[..., None])[..., 0]
            trial = _apply_increment(transforms, step)
            trial_energy = frame_energies(trial, p, q)
            better = trial_energy < energy
            transforms = np.where(better[:, None, None, None], trial, transforms)
            energy = np.where(better, trial_energy, energy)
            lam = np.where(better, lam / 3.0, lam * 8.0)
            if better.all():
                break
    return transforms
