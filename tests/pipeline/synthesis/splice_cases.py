"""Small clips with known bones and the splicing helpers the splicing, assembly and clip tests share."""

import numpy as np

from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.puppet.alignment import control_frames
from skinsynth.pipeline.inputs.examples import synthetic_lbs
from skinsynth.pipeline.synthesis.graph import build_graph
from skinsynth.pipeline.rig.rotations import rotation_exp
from skinsynth.pipeline.synthesis.splicing import splice
from skinsynth.pipeline.synthesis.transitions import bone_centroids


def chain_clip(bones=6, frames=60, period=20.0, second=None, drift=0.0, seed=0, max_influences=4):
    """An exact LBS chain (synthetic_lbs's tube and weights): joints swing sinusoidally with
    ``period`` (plus a ``second`` incommensurate one: no frame repeats), rooted at the most
    weighted bone (the reference bone), which moves rigidly by ``drift`` (0: it stays put)."""
    model = synthetic_lbs(bones=bones, frames=1, rings=24, segments=8, seed=seed, max_influences=max_influences)
    idx, w = model["bone_indices"], model["bone_weights"]
    root = int(np.argmax(np.bincount(idx.ravel(), weights=w.ravel(), minlength=bones)))
    rng = np.random.default_rng(seed)
    amp = rng.uniform(0.15, 0.4, size=(bones, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(bones, 3))
    f = np.arange(frames, dtype=float)
    theta = amp * np.sin(2 * np.pi * f[:, None, None] / period + phase)
    if second is not None:
        theta = theta + 0.3 * amp * np.sin(2 * np.pi * f[:, None, None] / second + 2 * phase)
    joint = rotation_exp(theta)
    centres = (np.arange(bones) + 0.5) * 4.0 / bones
    R = np.empty((frames, bones, 3, 3))
    t = np.empty((frames, bones, 3))
    R[:, root] = rotation_exp(np.stack([0.02 * drift * f, 0.5 * drift * np.sin(f / 13), 0.01 * drift * f], -1))
    t[:, root] = np.stack([0.05 * drift * f, 0.02 * drift * f, np.zeros_like(f)], -1)
    for b in sorted(range(bones), key=lambda b: abs(b - root))[1:]:
        parent = b + 1 if b < root else b - 1
        p = np.array([(centres[b] + centres[parent]) / 2, 0.0, 0.0])
        R[:, b] = R[:, parent] @ joint[:, b]
        t[:, b] = np.einsum("fij,fj->fi", R[:, parent], p - joint[:, b] @ p) + t[:, parent]
    clip = dict(rest=model["rest"], faces=model["faces"], bone_indices=idx, bone_weights=w, rotations=R,
                translations=t)
    graph = build_graph(clip["rest"], clip["faces"], idx, w, R, t, single_component=True)
    clip["component"] = graph.components[0]
    assert clip["component"].transitions.reference == root
    return clip


def skin(clip, F, t):
    return lbs_reference(clip["rest"], clip["bone_indices"], clip["bone_weights"], F, t)


def splice_clip(clip, sources, **kwargs):
    kwargs.setdefault("pivots", bone_centroids(clip["rest"], clip["bone_indices"], clip["bone_weights"],
                                               clip["rotations"].shape[1]))
    return splice(clip["component"], clip["rotations"], clip["translations"], sources, **kwargs)


def walk(*pieces):
    """Concatenate playback pieces (start, stop) into a source walk."""
    return np.concatenate([np.arange(a, b) for a, b in pieces])


def second_differences(vertices):
    """Max vertex second-difference norm per interior frame: (F, V, 3) -> (F − 2,)."""
    return np.linalg.norm(vertices[:-2] - 2 * vertices[1:-1] + vertices[2:], axis=-1).max(axis=-1)


def rigid_fits(meshes, targets):
    """Per frame the rigid transform taking meshes[f] onto targets[f], and the moved meshes."""
    fits = [control_frames(m[None], r) for m, r in zip(meshes, targets)]
    rot = np.concatenate([f[0] for f in fits])
    trans = np.concatenate([f[1] for f in fits])
    return rot, trans, np.einsum("fab,fvb->fva", rot, meshes) + trans[:, None]


def triangle(f, period):
    """A triangle wave of the frame number (period ``period``, a multiple of 4): slope 1 on
    −period/4 … period/4 around every multiple of the period, so at constant velocity there."""
    quarter = period // 4
    g = (np.asarray(f) + quarter) % period
    return np.where(g <= 2 * quarter, g - quarter, 3 * quarter - g).astype(float)


def wrap_clip(frames=32, bones=5, seed=3):
    """A one-cycle LBS clip whose exact continuation is known: ``pose(f)`` for any frame f ≥ 0 of
    the world the clip was cut from, the clip being frames 0 … F−1. The reference bone turns about
    the up axis (y) and drifts on the ground by one constant screw step B per frame and bobs up
    and down (P(f) = h(f) ŷ + B^f); every other bone, in the reference bone's frame, turns about
    its own axis by an angle and moves its pivot (its rest centroid, about which splicing
    blends) along a line; h, the angles and the pivots' offsets are triangle waves of period F:
    at constant velocity across the wrap, where frame −1 extrapolated from frames 0 and 1 is
    exact (and frame F from F−2 and F−1)."""
    model = synthetic_lbs(bones=bones, frames=1, rings=24, segments=8, seed=seed)
    idx, w, rest = model["bone_indices"], model["bone_weights"], model["rest"]
    root = int(np.argmax(np.bincount(idx.ravel(), weights=w.ravel(), minlength=bones)))
    pivots = bone_centroids(rest, idx, w, bones)
    rng = np.random.default_rng(seed)
    axes = rng.normal(size=(bones, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    spin, shift = rng.uniform(0.01, 0.03, bones), rng.normal(scale=0.02, size=(bones, 3))
    base = rotation_exp(rng.uniform(-0.3, 0.3, size=(bones, 3)))
    step_R, step_t = rotation_exp(np.array([0.0, 0.05, 0.0])), np.array([0.03, 0.0, 0.01])

    def pose(f):
        f = np.asarray(f)
        tau = triangle(f, frames)[:, None]  # (n, 1)
        R = rotation_exp(tau[..., None] * spin[None, :, None] * axes[None]) @ base  # (n, B, 3, 3) local
        t = pivots + tau[..., None] * shift - np.einsum("nbij,bj->nbi", R, pivots)
        R[:, root], t[:, root] = np.eye(3), 0.0
        ref_R, ref_t = np.empty((f.size, 3, 3)), np.empty((f.size, 3))
        for n, count in enumerate(f):  # B^count
            ref_R[n], ref_t[n] = np.eye(3), 0.0
            for _ in range(int(count)):
                ref_R[n], ref_t[n] = step_R @ ref_R[n], step_R @ ref_t[n] + step_t
        ref_t[:, 1] += 0.05 * tau[:, 0]  # the bob: a change of posture (height) the costs weigh
        return ref_R[:, None] @ R, np.einsum("nij,nbj->nbi", ref_R, t) + ref_t[:, None]

    R, t = pose(np.arange(frames))
    clip = dict(rest=rest, faces=model["faces"], bone_indices=idx, bone_weights=w, rotations=R, translations=t,
                pose=pose)
    graph = build_graph(rest, model["faces"], idx, w, R, t, single_component=True)
    clip["component"] = graph.components[0]
    assert clip["component"].transitions.reference == root
    return clip
