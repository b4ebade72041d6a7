"""play of a puppet of a jointed skin beyond its examples (pipeline/puppet/jointed_play.py): the
frames inside the examples play the kernel CCA's prediction bit for bit, the frames beyond follow
the controls with the skeleton and are reported, and the shared tennis serve on the samba
skeleton puppet keeps the tail of the skin's strain within 1.2× of the puppet playing its own samba."""

import json
import pathlib

import h5py
import numpy as np
import pytest
from cli_helpers import assert_ok, cli

from skinsynth.formats.skin_file import read_skin
from skinsynth.pipeline.mesh.shape import edge_strain, shape_envelope
from skinsynth.pipeline.puppet.jointed_play import skeleton_blend


def _played(path):
    with h5py.File(path, "r") as f:
        return f["vertices"][()].astype(np.float64).reshape(-1, *f["vertices"].shape[-2:])


def _strain(skin, vertices):
    """(p99, p99.99, largest) of |edge length / rest length − 1| over every edge and frame (the rest:
    the capture's first frame)."""
    envelope = shape_envelope(skin.examples[:1], skin.faces)
    strain = edge_strain(vertices, envelope.edges, envelope.rest_lengths)
    return float(np.percentile(strain, 99)), float(np.percentile(strain, 99.99)), float(strain.max())


def _broken(skin, vertices):
    """Issue 66's broken frames (an edge stretched past its largest strain in the capture by a
    quarter of its rest length, on more than 0.5 % of the edges) and the largest share of a
    frame's edges so stretched."""
    envelope = shape_envelope(skin.examples, skin.faces)
    return np.flatnonzero(envelope.broken(vertices)), float(envelope.beyond_share(vertices).max())


def test_the_blend_is_zero_inside_the_examples_spread_and_one_from_one_and_a_half_of_it():
    alpha = skeleton_blend(np.array([0.0, 0.5, 1.0, 1.125, 1.25, 1.375, 1.5, 5.0]), 1.0)
    assert np.array_equal(alpha[:3], [0.0, 0.0, 0.0]) and np.array_equal(alpha[-2:], [1.0, 1.0])
    assert np.all(np.diff(alpha) >= 0.0) and alpha[4] == pytest.approx(0.5)


@pytest.fixture(scope="module")
def walker_puppet(jointed_skins, tmp_path_factory):
    folder = tmp_path_factory.mktemp("jointed_play")
    assert_ok(cli("select-controls", jointed_skins / "skin.h5", "-o", folder / "controls.h5", "--count", 8, "-q"))
    assert_ok(cli("train-kcca", folder / "controls.h5", "-o", folder / "puppet.h5", "-q"))
    return folder


def test_inside_the_examples_play_is_the_prediction_and_beyond_them_the_skeleton_follows(walker_puppet, jointed_skins):
    skin = read_skin(jointed_skins / "skin.h5")
    from skinsynth.formats.puppet_file import read_puppet

    indices = read_puppet(walker_puppet / "puppet.h5")[0].control_indices
    own = skin.examples[:, indices].astype(np.float64)
    # beyond: every control pushed away from the body's centre (the limbs spread far past any example)
    centre = own.mean(axis=1, keepdims=True)
    spread = centre + 2.5 * (own - centre)
    np.save(walker_puppet / "own.npy", own)
    np.save(walker_puppet / "spread.npy", spread)
    summaries = {}
    for name in ("own", "spread"):
        for flag in ("--ik", "--no-ik"):  # --ik is the default: played without the flag
            out = walker_puppet / f"{name}{flag}.h5"
            summary = json.loads(assert_ok(cli("play", walker_puppet / "puppet.h5", "-c", walker_puppet / f"{name}.npy",
                                               "-o", out, "--json", *([flag] if flag == "--no-ik" else []))).stdout)
            assert ("skeleton" in summary) == (flag == "--ik")
            summaries[name, flag] = summary
    assert summaries["own", "--ik"]["skeleton"]["frames_beyond"] == 0
    assert np.array_equal(_played(walker_puppet / "own--ik.h5"), _played(walker_puppet / "own--no-ik.h5"))
    # far beyond: every frame wholly the skeleton's
    assert summaries["spread", "--ik"]["skeleton"]["frames_skeleton"] == len(spread)
    ik, extrapolated = _played(walker_puppet / "spread--ik.h5"), _played(walker_puppet / "spread--no-ik.h5")
    assert _strain(skin, ik)[0] < 0.2 * _strain(skin, extrapolated)[0]  # 0.08 against 6.7


@pytest.mark.slow
def test_the_tennis_serve_on_the_samba_skeleton_puppet_keeps_the_strain_of_its_own_samba(shared_data, tmp_path):
    """Issue 45: the real serve (not a samba, not the dancer) on the samba puppet trained on its
    --skeleton fit: edge strain p99 and p99.99 (one edge-frame in ten thousand) within 1.2× the same
    puppet's on its own samba controls, the largest within 1.5× (the kernel CCA's extrapolation,
    --no-ik: 2.6× and 4.8×). Measured 1.00×, 1.09× and 1.38× (issue 65); since issue 66 (the serve
    aligned in its still start, the skeleton whole from 1.5× the examples' gap, the frames the blend
    tore played by the skeleton) 0.83× and 0.74× (p99, largest: benchmarks/markers.py --only
    skeleton), and no broken frame (25 of 524 before the guard; the worst frame 0.31 % of its edges
    past the capture's, a frame breaks at 0.5 %)."""
    take = shared_data / "mocap_c3d" / "kinematics_tennis_serve_nan.c3d"
    if not take.exists():
        pytest.skip(f"the tennis serve take is needed at {take}")
    layout = pathlib.Path(__file__).resolve().parents[2] / "docs" / "markers" / "vlasic_samba.layout.json"
    assert_ok(cli("fit-skin", shared_data / "vlasic_samba" / "vlasic_samba.npz", "-o", tmp_path / "skin.h5", "--bones",
                  22, "--skeleton", "-q"))
    assert_ok(cli("select-controls", tmp_path / "skin.h5", "-o", tmp_path / "controls.h5", "--markers", layout, "-q"))
    # the defaults but the mode auto chooses here, given to skip its cross-validation (the same puppet)
    assert_ok(cli("train-kcca", tmp_path / "controls.h5", "-o", tmp_path / "puppet.h5", "--global-motion",
                  "control-frame", "-q"))
    skin = read_skin(tmp_path / "skin.h5")
    np.save(tmp_path / "own.npy", skin.examples[:, list(json.loads(layout.read_text()).values())])
    assert_ok(cli("play", tmp_path / "puppet.h5", "-c", tmp_path / "own.npy", "-o", tmp_path / "own.h5", "-q"))
    summary = json.loads(assert_ok(cli("play", tmp_path / "puppet.h5", "-c", take, "-o", tmp_path / "serve.h5",
                                       "--json")).stdout)
    assert summary["skeleton"]["frames_beyond"] > len(_played(tmp_path / "serve.h5")) // 2
    own, serve = _strain(skin, _played(tmp_path / "own.h5")), _strain(skin, _played(tmp_path / "serve.h5"))
    assert serve[0] <= 1.2 * own[0] and serve[1] <= 1.2 * own[1] and serve[2] <= 1.5 * own[2], (own, serve)
    broken, worst = _broken(skin, _played(tmp_path / "serve.h5"))
    assert len(broken) == 0, (broken, worst)
    assert summary["skeleton"]["frames_torn"] > 0 and summary["skeleton"]["frames_broken"] == []


def test_a_free_skins_puppet_beyond_its_examples_follows_a_skeleton_found_for_it(jointed_skins, tmp_path):
    """Issue 66: a puppet of a free skin (no --skeleton) has no skeleton of its own; beyond its
    examples play poses it on the one its bones keep best, found as fit-skin --skeleton finds it,
    and says so; inside them it is the prediction, bit for bit."""
    assert_ok(cli("fit-skin", jointed_skins / "walker.npz", "-o", tmp_path / "skin.h5", "--bones", 10, "-q"))
    assert read_skin(tmp_path / "skin.h5").skeleton is None
    assert_ok(cli("select-controls", tmp_path / "skin.h5", "-o", tmp_path / "controls.h5", "--count", 8, "-q"))
    assert_ok(cli("train-kcca", tmp_path / "controls.h5", "-o", tmp_path / "puppet.h5", "-q"))
    from skinsynth.formats.puppet_file import read_puppet

    skin = read_skin(tmp_path / "skin.h5")
    own = skin.examples[:, read_puppet(tmp_path / "puppet.h5")[0].control_indices].astype(np.float64)
    centre = own.mean(axis=1, keepdims=True)
    np.save(tmp_path / "own.npy", own)
    np.save(tmp_path / "spread.npy", centre + 2.5 * (own - centre))
    summaries = {}
    for name in ("own", "spread"):
        for flag in ("--ik", "--no-ik"):
            result = assert_ok(cli("play", tmp_path / "puppet.h5", "-c", tmp_path / f"{name}.npy", "-o",
                                   tmp_path / f"{name}{flag}.h5", "--json", flag))
            if flag == "--ik":
                summaries[name] = json.loads(result.stdout)["skeleton"]
                assert summaries[name]["skeleton"] == "found for the free skin"
    assert summaries["spread"]["frames_skeleton"] == len(own)
    said = assert_ok(cli("play", tmp_path / "puppet.h5", "-c", tmp_path / "spread.npy", "-o", tmp_path / "s.h5"))
    assert "a skeleton found for the free skin" in said.stdout + said.stderr
    assert summaries["own"]["frames_beyond"] == 0
    assert np.array_equal(_played(tmp_path / "own--ik.h5"), _played(tmp_path / "own--no-ik.h5"))
    ik, extrapolated = _played(tmp_path / "spread--ik.h5"), _played(tmp_path / "spread--no-ik.h5")
    assert _strain(skin, ik)[0] < 0.2 * _strain(skin, extrapolated)[0]


@pytest.mark.slow
def test_the_serve_on_the_documented_free_samba_puppet_keeps_the_body_whole(samba_skin, shared_data, tmp_path):
    """Issue 66: docs/mocap.md's own path (the samba's free skin, its 20-marker layout, train-kcca's
    defaults) under the real serve: aligned in the pose the take begins in (held for its first
    1.5 s; frame 52 at 50 Hz, where the whole take's closest pose was frame 810); edge strain p99
    and largest within 1.2× the same puppet's on its own samba (measured 0.80× and 0.73×; the kernel
    CCA's extrapolation, --no-ik, over 2×); no broken frame (an edge stretched past its largest
    strain in the capture by a quarter of its rest length on more than 0.5 % of the edges: 454 of
    524 before issue 66; the worst frame now 0.36 %), the frames the blend tore played by the
    skeleton; the samba's own frames untouched."""
    take = shared_data / "mocap_c3d" / "kinematics_tennis_serve_nan.c3d"
    if not take.exists():
        pytest.skip(f"the tennis serve take is needed at {take}")
    layout = pathlib.Path(__file__).resolve().parents[2] / "docs" / "markers" / "vlasic_samba.layout.json"
    assert_ok(cli("select-controls", samba_skin, "-o", tmp_path / "controls.h5", "--markers", layout, "-q"))
    # the defaults but the mode auto chooses here, given to skip its cross-validation (the same puppet)
    assert_ok(cli("train-kcca", tmp_path / "controls.h5", "-o", tmp_path / "puppet.h5", "--global-motion",
                  "control-frame", "-q"))
    skin = read_skin(samba_skin)
    np.save(tmp_path / "own.npy", skin.examples[:, list(json.loads(layout.read_text()).values())])
    own_summary = json.loads(assert_ok(cli("play", tmp_path / "puppet.h5", "-c", tmp_path / "own.npy", "-o",
                                           tmp_path / "own.h5", "--json")).stdout)
    summary = json.loads(assert_ok(cli("play", tmp_path / "puppet.h5", "-c", take, "-o", tmp_path / "serve.h5",
                                       "--json")).stdout)
    assert summary["takes"][0]["neutral_frame"] < 1.2 * summary["takes"][0]["take_rate"]  # in its still start
    assert summary["skeleton"]["skeleton"] == "found for the free skin"
    assert own_summary["skeleton"]["frames_beyond"] == 0 and own_summary["skeleton"]["frames_torn"] == 0
    own, serve = _played(tmp_path / "own.h5"), _played(tmp_path / "serve.h5")
    assert _strain(skin, serve)[0] <= 1.2 * _strain(skin, own)[0]
    assert _strain(skin, serve)[2] <= 1.2 * _strain(skin, own)[2]
    broken, worst = _broken(skin, serve)
    assert len(broken) == 0, (broken, worst)
    assert summary["skeleton"]["frames_torn"] > 0 and summary["skeleton"]["frames_broken"] == []
