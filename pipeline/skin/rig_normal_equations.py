"""The Gauss–Newton system of a jointed rig's frames, compiled (:func:`.jointed_fit._gauss_newton`).

For each frame, the normal equations of a step ω_k on every bone's rotation (R_k ← exp(ω_k) R_k)
and δ_a on every anchor's translation, from the rig's sums alone (:class:`.jointed_fit._Sums`):
with M_km = R_k G_km R_mᵀ and y_ik = R_k a_ik,

    H_ωω[k, m] = tr(M_km) I − M_mk,   H_ωδ[k, a] = [R_k H_ak]×,   H_δδ[a, b] = S_ab I,
    g_ω[k] = axial(C_k R_kᵀ − Σ_m M_mk) − Σ_a (R_k H_ak) × t_a,
    g_δ[a] = Σ_i s_ia v_i − Σ_b S_ab t_b − Σ_k R_k H_ak.

numpy formed these as (F, B, B, 3, 3) arrays and copied them into place (most of a step's time on
the 30-bone sheet: 22 of 55 ms); here each frame's blocks are written where they go, one frame at
a time (no numba threads: the caller runs runs of frames on threads of its own, and numba's
default threading layer does not take parallel regions from two threads at once). Tested
against the system formed vertex by vertex from the chain coefficients (``test_jointed_fit.py``).
"""

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def normal_equations(R, gram, anchor_cross, anchor_gram, cross, anchor_vertices, T, H, g):
    """H (F, n, n) and g (F, n), n = 3(B + A), of rotations R (F, B, 3, 3) and anchor
    translations T (F, A, 3): gram (B·3, B·3) [(k, y), (m, z)] = G_km[y, z]; anchor_cross (A, B, 3)
    = H_ak; anchor_gram (A, A) = S; cross (F, B, 3, 3) = C_k; anchor_vertices (F, A, 3) (module notes)."""
    frames, bones = R.shape[0], R.shape[1]
    anchors = T.shape[1]
    rows = 3 * bones
    turned = np.empty((rows, rows))  # R_k G_km, [(k, x), (m, z)]
    model = np.empty((bones, 3, 3))  # Σ_m M_mk
    turned_cross = np.empty((bones, anchors, 3))  # R_k H_ak
    d = np.empty((3, 3))  # C_k R_kᵀ − Σ_m M_mk
    for f in range(frames):
        for k in range(bones):
            for x in range(3):
                for c in range(rows):
                    turned[3 * k + x, c] = (R[f, k, x, 0] * gram[3 * k, c] + R[f, k, x, 1] * gram[3 * k + 1, c]
                                            + R[f, k, x, 2] * gram[3 * k + 2, c])
        model[:] = 0.0
        for k in range(bones):
            for m in range(bones):
                # M_km[x, w] = Σ_z (R_k G_km)[x, z] R_m[w, z]; M_mk = M_kmᵀ (G symmetric)
                trace = 0.0
                for x in range(3):
                    trace += (turned[3 * k + x, 3 * m] * R[f, m, x, 0] + turned[3 * k + x, 3 * m + 1] * R[f, m, x, 1]
                              + turned[3 * k + x, 3 * m + 2] * R[f, m, x, 2])
                for x in range(3):
                    for w in range(3):
                        value = (turned[3 * k + w, 3 * m] * R[f, m, x, 0] + turned[3 * k + w, 3 * m + 1] * R[f, m, x, 1]
                                 + turned[3 * k + w, 3 * m + 2] * R[f, m, x, 2])  # M_km[w, x] = M_mk[x, w]
                        H[f, 3 * k + x, 3 * m + w] = (trace if x == w else 0.0) - value
                        model[k, x, w] += value
        for k in range(bones):
            for a in range(anchors):
                for x in range(3):
                    turned_cross[k, a, x] = (R[f, k, x, 0] * anchor_cross[a, k, 0]
                                             + R[f, k, x, 1] * anchor_cross[a, k, 1]
                                             + R[f, k, x, 2] * anchor_cross[a, k, 2])
                v0, v1, v2 = turned_cross[k, a, 0], turned_cross[k, a, 1], turned_cross[k, a, 2]
                r, c = 3 * k, rows + 3 * a
                H[f, r, c], H[f, r, c + 1], H[f, r, c + 2] = 0.0, -v2, v1
                H[f, r + 1, c], H[f, r + 1, c + 1], H[f, r + 1, c + 2] = v2, 0.0, -v0
                H[f, r + 2, c], H[f, r + 2, c + 1], H[f, r + 2, c + 2] = -v1, v0, 0.0
                for x in range(3):
                    for w in range(3):
                        H[f, c + w, r + x] = H[f, r + x, c + w]
        for a in range(anchors):
            for b in range(anchors):
                for x in range(3):
                    for w in range(3):
                        H[f, rows + 3 * a + x, rows + 3 * b + w] = anchor_gram[a, b] if x == w else 0.0
        for k in range(bones):
            # X_k = C_k R_kᵀ less Σ_m M_mk; its axial vector, less Σ_a (R_k H_ak) × t_a
            for x in range(3):
                for z in range(3):
                    d[x, z] = (cross[f, k, x, 0] * R[f, k, z, 0] + cross[f, k, x, 1] * R[f, k, z, 1]
                               + cross[f, k, x, 2] * R[f, k, z, 2]) - model[k, x, z]
            g0, g1, g2 = d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]
            for a in range(anchors):
                u0, u1, u2 = turned_cross[k, a, 0], turned_cross[k, a, 1], turned_cross[k, a, 2]
                t0, t1, t2 = T[f, a, 0], T[f, a, 1], T[f, a, 2]
                g0 -= u1 * t2 - u2 * t1
                g1 -= u2 * t0 - u0 * t2
                g2 -= u0 * t1 - u1 * t0
            g[f, 3 * k], g[f, 3 * k + 1], g[f, 3 * k + 2] = g0, g1, g2
        for a in range(anchors):
            for x in range(3):
                total = anchor_vertices[f, a, x]
                for b in range(anchors):
                    total -= anchor_gram[a, b] * T[f, b, x]
                for k in range(bones):
                    total -= turned_cross[k, a, x]
                g[f, rows + 3 * a + x] = total
