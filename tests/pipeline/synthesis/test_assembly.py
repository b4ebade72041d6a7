"""Multi-component assembly (Zheng Alg. 1, eq. 12–14) against closed-form truths."""

import numpy as np
import pytest
from splice_cases import chain_clip

from skinsynth.pipeline.synthesis.assembly import assemble
from skinsynth.pipeline.synthesis.graph import build_graph
from skinsynth.pipeline.synthesis.splicing import splice_local


@pytest.fixture(scope="module")
def components():
    clip = chain_clip(bones=8, frames=60, period=20.0, drift=1.0)
    graph = build_graph(clip["rest"], clip["faces"], clip["bone_indices"], clip["bone_weights"], clip["rotations"],
                        clip["translations"])
    assert len(graph.components) >= 2
    return clip, graph.components


def test_unspliced_walks_assemble_into_the_input(components):
    clip, parts_of = components
    # Every walk of every component plays the same stretch of the input without a seam: whichever
    # walks eq. 12 pairs, the cut nodes agree exactly, every turn is the identity and the rig is
    # the input's.
    sources = np.stack([np.arange(4, 54)] * 3)
    parts = [splice_local(c, clip["rotations"], clip["translations"], sources) for c in parts_of]
    F, t, choice, rejected = assemble([c.bones for c in parts_of], parts, clip["rotations"].shape[1],
                                      np.random.default_rng(0), dtype=np.float64)
    assert rejected == 0 and choice.shape == (3, len(parts_of))
    assert np.abs(F - clip["rotations"][sources]).max() < 1e-12
    assert np.abs(t - clip["translations"][sources]).max() < 1e-12


def test_merged_components_are_carried_rigidly(components):
    clip, parts_of = components
    # Walks with seams (eq. 7–9 change every component differently): each component's bones
    # must come out as its own spliced motion moved by one rigid transform per frame (eq. 14),
    # i.e. with the relative placement F_k⁻¹ F_l, F_k⁻¹ (t_l − t_k) of any two of its bones kept.
    # Cut nodes are skipped: eq. 13 averages their stretch.
    walks = [np.concatenate([np.arange(5, 30), np.arange(41, 56)]), np.concatenate([np.arange(10, 40), np.arange(22, 32)]),
             np.concatenate([np.arange(2, 22), np.arange(33, 53)])]
    bones = clip["rotations"].shape[1]
    parts = [splice_local(c, clip["rotations"], clip["translations"], np.stack(walks[k % 3:] + walks[:k % 3]))
             for k, c in enumerate(parts_of)]
    F, t, choice, _ = assemble([c.bones for c in parts_of], parts, bones, np.random.default_rng(3), dtype=np.float64)
    shared = np.bincount(np.concatenate([c.bones for c in parts_of]), minlength=bones) > 1
    checked = 0
    for index, (component, part) in enumerate(zip(parts_of, parts)):
        F_own, t_own = part.world()
        inner = [i for i, b in enumerate(component.bones) if not shared[b]]
        cuts = [i for i, b in enumerate(component.bones) if shared[b]]
        for a in range(3):
            mine = choice[a, index]
            for k in inner[:1]:  # the cut node's translation is the anchor side's: eq. 14 put it there
                for c in cuts:
                    bk, bc = component.bones[k], component.bones[c]
                    assert np.allclose(np.linalg.solve(F[a, :, bk], (t[a, :, bc] - t[a, :, bk])[..., None]),
                                       np.linalg.solve(F_own[mine, :, k], (t_own[mine, :, c] - t_own[mine, :, k])[..., None]),
                                       atol=1e-9)
            for k, l in zip(inner[:-1], inner[1:]):
                bk, bl, mine = component.bones[k], component.bones[l], choice[a, index]
                assert np.allclose(np.linalg.solve(F[a, :, bk], F[a, :, bl]),
                                   np.linalg.solve(F_own[mine, :, k], F_own[mine, :, l]), atol=1e-9)
                assert np.allclose(np.linalg.solve(F[a, :, bk], (t[a, :, bl] - t[a, :, bk])[..., None]),
                                   np.linalg.solve(F_own[mine, :, k], (t_own[mine, :, l] - t_own[mine, :, k])[..., None]),
                                   atol=1e-9)
                checked += 1
    assert checked > 0


def test_merge_order_starts_each_piece_at_its_most_central_component():
    from skinsynth.pipeline.synthesis.assembly import merge_order

    # A chain of three components (the middle one is central), a pair, and a lone component.
    order = merge_order([[0, 1, 2], [2, 3], [3, 4, 5], [10, 11], [11, 12, 13, 14], [20]])
    assert order == [(1, None), (0, 2), (2, 3), (4, None), (3, 11), (5, None)]
    # Ties in centrality go to the component with more bones, then the lower index.
    assert merge_order([[0, 1], [1, 2, 3]])[0] == (1, None)
    assert merge_order([[0, 1], [1, 2]])[0] == (0, None)


@pytest.mark.parametrize("patches", [1, 3, 20])
def test_contact_agreement_counts_by_brute_force(patches):
    """The merge's contact agreement (frames × patches where a candidate's states equal the
    anchor walk's), whether the states are packed into a code per frame (≤ 16 patches) or not,
    against counting every comparison in Python."""
    from skinsynth.pipeline.synthesis.assembly import _agreement

    rng = np.random.default_rng(patches)
    frames_in, walks, frames = 30, 7, 13
    sources = rng.integers(0, frames_in, size=(2, walks, frames))
    owned = [rng.random((frames_in, 2)) < 0.5, rng.random((frames_in, patches)) < 0.5]
    candidates = np.stack([rng.permutation(walks)[:4] for _ in range(walks)])
    found = _agreement((sources, owned), 1, 0, candidates)
    states = owned[1]
    for a in range(walks):
        for k in range(4):
            count = sum(int(states[sources[1, candidates[a, k], m], q] == states[sources[0, a, m], q])
                        for m in range(frames) for q in range(patches))
            assert found[a, k] == count
