"""A clip of one cycle loops (issue 25): the default bending bar, whose last frame runs into its
first, gets the wrap transition (i, −1), "after i, continue at frame 0", and synthesizes."""

import json
import shutil

import h5py
import numpy as np
import pytest

from skinsynth.formats.meshseq import read_mesh_sequence
from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.mesh.geometry import frame_accelerations
from skinsynth.pipeline.puppet.alignment import control_frames

from cli_helpers import assert_ok, assert_user_error, cli

WINDOW = 4  # synthesize's default --window


@pytest.fixture(scope="module")
def bar(tmp_path_factory):
    """``skinsynth example bending-bar`` (default options: one bend-and-twist cycle, 60 frames),
    fit-skin --bones 6, build-graph and synthesize -n 8 -m 300, all with their defaults but
    synthesize's --no-contact."""
    root = tmp_path_factory.mktemp("one_cycle")
    assert_ok(cli("example", "bending-bar", "-o", root / "bar.npz"))
    assert_ok(cli("fit-skin", root / "bar.npz", "-o", root / "skin.h5", "--bones", 6, "-q"))
    report = json.loads(assert_ok(cli("build-graph", root / "skin.h5", "-o", root / "graph.h5", "--json")).stdout)
    # the bar's base rests on the ground: its plants (issue 35) would move the base toward the input frames,
    # no longer one rigid motion of the fit's frames, which is what the splice checks below hold it to
    assert_ok(cli("synthesize", root / "graph.h5", "-o", root / "bones.h5", "-n", 8, "-m", 300, "-q", "--no-contact"))
    return root, report


def test_the_one_cycle_example_builds_a_loop_and_synthesizes(bar):
    root, report = bar
    assert read_mesh_sequence(str(root / "bar.npz")).vertices.shape[0] == 60
    assert report["transitions"] > 0 and report["components"][0]["share"] == 1.0
    with h5py.File(root / "graph.h5") as f:
        pairs = f["graph/component_000/transitions"][()]
        costs = f["graph/component_000/transition_costs"][()]
        threshold = f["graph/component_000"].attrs["threshold"]
    assert any(j == -1 for _, j in pairs)  # the loop: after frame i, continue at frame 0
    assert [59, -1] in pairs.tolist() and np.all(costs < threshold)  # the end → start wrap, below T_c
    summary = json.loads(assert_ok(cli("inspect", root / "graph.h5", "--json")).stdout)
    assert summary["transitions"] == len(pairs)


def test_every_animation_plays_the_clip_in_order_around_the_wrap(bar):
    root, _ = bar
    with h5py.File(root / "bones.h5") as f:
        F, t = f["synthesis/bone_matrices"][()], f["synthesis/bone_translations"][()]
        sources = f["synthesis/sources"][()]
        rest, idx, w = f["mesh/rest_vertices"][()], f["skin/bone_indices"][()], f["skin/bone_weights"][()]
        examples = f["examples/vertices"][()]
    with h5py.File(root / "graph.h5") as f:
        pairs = {tuple(p) for p in f["graph/component_000/transitions"][()].tolist()}
        fitted = lbs_reference(rest, idx, w, f["skin/rotations"][()], f["skin/translations"][()])
    assert F.shape[:2] == (8, 300) and sources.shape == (1, 8, 300)
    input_worst = frame_accelerations(examples)[1:-1].max()  # the clip's own largest acceleration
    wraps = 0
    for a in range(8):
        src = sources[0, a]
        seam = np.flatnonzero(src[1:] != src[:-1] + 1) + 1
        # Every seam is a transition of the graph (i, j) taken as i → j + 1, here onto frame 0.
        assert all((src[k - 1], src[k] - 1) in pairs for k in seam)
        wraps += int(np.sum(src[seam] == 0))
        out = lbs_reference(rest, idx, w, F[a], t[a])
        # Away from seams the output is the input's frames, each segment moved by one rigid motion.
        blended = np.zeros(300, bool)
        for k in seam:
            blended[max(k - WINDOW, 0):k + WINDOW] = True
        segment = np.searchsorted(seam, np.arange(300), side="right")
        for s in range(seam.size + 1):
            frames = np.flatnonzero((segment == s) & ~blended)
            if frames.size < 3:
                continue
            fits = [control_frames(out[f][None], fitted[src[f]]) for f in frames]  # output → input, per frame
            rot, trans = np.concatenate([r for r, _ in fits]), np.concatenate([c for _, c in fits])
            moved = np.einsum("fab,fvb->fva", rot, out[frames]) + trans[:, None]
            assert np.abs(moved - fitted[src[frames]]).max() < 1e-4 * np.ptp(rest)
            assert np.abs(rot - rot[0]).max() < 1e-4
        # At the seams (and everywhere) the mesh accelerates no more than 1.5 × the clip's own largest.
        acceleration = frame_accelerations(out)[1:-1]
        assert acceleration.max() <= 1.5 * input_worst
        for k in seam:
            near = acceleration[max(k - WINDOW - 2, 0):k + WINDOW]
            assert near.max() <= 1.5 * input_worst
    assert wraps >= 8 * 4  # 300 frames of a 60-frame clip: every animation goes round at least 4 times


def test_a_graph_file_pairs_frames_or_the_virtual_frame_before_the_start(bar, tmp_path):
    root, _ = bar
    good = tmp_path / "graph.h5"
    shutil.copyfile(root / "graph.h5", good)
    assert_ok(cli("inspect", good))  # (59, −1) is a pair like any other
    bad = tmp_path / "bad.h5"
    shutil.copyfile(root / "graph.h5", bad)
    with h5py.File(bad, "r+") as f:
        pairs = f["graph/component_000/transitions"]
        pairs[0] = [59, -2]
    for command in (("inspect", bad), ("synthesize", bad, "-o", tmp_path / "b.h5", "-n", 2, "-m", 30)):
        assert_user_error(cli(*command), str(bad), "/graph/component_000/transitions", "(59, -2)", "−1")
    assert not (tmp_path / "b.h5").exists()
