"""synthesize keeps the input's support (issue 25, part 2): the lowest point of every output frame
stays within the input's own range of lowest points (1 % of the height), in every mode, while
``--no-contact`` gives the merged bones as they were; the correction is vertical, moves the
whole character, and touches only the frames that need it."""

import h5py
import numpy as np
import pytest

from skinsynth.gpu import lbs_reference

from cli_helpers import assert_ok, assert_user_error, cli


def read_synthesis(path):
    with h5py.File(path) as f:
        return {"F": f["synthesis/bone_matrices"][()], "t": f["synthesis/bone_translations"][()],
                "rest": f["mesh/rest_vertices"][()], "idx": f["skin/bone_indices"][()],
                "w": f["skin/bone_weights"][()], "examples": f["examples/vertices"][()],
                "input_F": f["skin/rotations"][()], "input_t": f["skin/translations"][()]}


def ground_excess(data, up=1, against="fit"):
    """(below, above): how far any animation's lowest point goes below the input's lowest and above
    the input's highest lowest point, as shares of the rest pose's height. The input is the skin's
    own playback of the input frames (``against="fit"``: what splicing plays, so a coarse test
    fit's error does not count) or the input frames themselves (``"examples"``)."""
    from skinsynth.pipeline.synthesis.contact.ground import ground_excess as excess, lowest_heights

    def skinned(F, t):
        return lbs_reference(data["rest"], data["idx"], data["w"], F, t)

    height = float(np.ptp(data["rest"][:, up]))
    lowest = [lowest_heights(skinned(F, t), up) for F, t in zip(data["F"], data["t"])]
    given = skinned(data["input_F"], data["input_t"]) if against == "fit" else data["examples"]
    return excess(np.concatenate(lowest), lowest_heights(given, up), height)


@pytest.fixture(scope="module")
def bar(stage_files, tmp_path_factory):
    stages = stage_files(frames=40, bones=4, iterations=10, cycles=2, graph=("--min-segment", 4))
    return stages.copy_to(tmp_path_factory.mktemp("contact"))


@pytest.mark.parametrize("mode", [(), ("--single-component",), ("--alignment", "full")])
def test_contact_moves_the_whole_character_vertically_and_only_where_it_leaves_the_band(bar, tmp_path, mode):
    """The rule for a graph without ground contacts (--no-contacts; the bar's base rests on the
    ground, whose plants issue 35 keeps instead)."""
    assert_ok(cli("build-graph", bar / "skin.h5", "-o", tmp_path / "banded.h5", "--no-contacts", "--min-segment", 4,
                  "-q"))
    common = ("synthesize", tmp_path / "banded.h5", "-n", 6, "-m", 300, "--seed", 2, "-q", *mode)
    assert_ok(cli(*common, "-o", tmp_path / "kept.h5"))
    assert_ok(cli(*common, "-o", tmp_path / "free.h5", "--no-contact"))
    kept, free = read_synthesis(tmp_path / "kept.h5"), read_synthesis(tmp_path / "free.h5")
    assert np.array_equal(kept["F"], free["F"])  # rotations untouched
    assert np.array_equal(kept["t"][..., [0, 2]], free["t"][..., [0, 2]])  # no sideways motion
    shift = kept["t"][..., 1] - free["t"][..., 1]  # (A, M, B): one vertical shift per frame, every bone
    assert np.allclose(shift, shift[..., :1], atol=1e-5)
    below, above = ground_excess(kept, against="examples")
    assert below <= 0.01 and above <= 0.01
    if "full" in mode:  # Zheng's eq. 7 placement sinks the bar 44 % of its height: lifted back
        assert ground_excess(free, against="examples")[0] > 0.3


@pytest.fixture(scope="module")
def walker(tmp_path_factory):
    """``skinsynth example walker`` fitted with 12 bones: build-graph gives each leg a component of
    its own (tests/pipeline/inputs/test_walker_example.py), 5 components in all."""
    root = tmp_path_factory.mktemp("walker")
    assert_ok(cli("example", "walker", "-o", root / "walker.npz", "-q"))
    assert_ok(cli("fit-skin", root / "walker.npz", "-o", root / "skin.h5", "--bones", 12, "--seed", 0, "-q"))
    assert_ok(cli("build-graph", root / "skin.h5", "-o", root / "graph.h5", "-q"))
    assert_ok(cli("build-graph", root / "skin.h5", "-o", root / "single.h5", "--single-component", "-q"))
    with h5py.File(root / "graph.h5") as f:
        assert int(f["graph"].attrs["components"]) >= 3
    return root


@pytest.mark.parametrize("graph", ["graph.h5", "single.h5"])
def test_a_walker_whose_legs_are_components_keeps_its_feet_on_the_ground_over_3_x_3000_frames(walker, tmp_path, graph):
    """The must-show of issue 25: within 1 % of the height of the input's own range of lowest
    points (the input frames themselves), in both modes; without the correction the merged legs
    float and sink (measured 8 % below and 5 % above)."""
    common = ("synthesize", walker / graph, "-n", 3, "-m", 3000, "--seed", 0, "-q", "--measure-feet", 0)
    assert_ok(cli(*common, "-o", tmp_path / "kept.h5"))
    below, above = ground_excess(read_synthesis(tmp_path / "kept.h5"), against="examples")
    assert below <= 0.01 and above <= 0.01
    if graph == "graph.h5":
        assert_ok(cli(*common, "-o", tmp_path / "free.h5", "--no-contact"))
        assert max(ground_excess(read_synthesis(tmp_path / "free.h5"), against="examples")) > 0.03


def test_json_reports_the_feet_of_the_input_and_of_the_first_animations_and_writes_the_same(bar, tmp_path):
    """Issue 35 part 4: --json's "contact" (docs/contact.md) for the input and the first N
    animations; --measure-feet changes nothing written, and 0 measures nothing."""
    import json

    from skinsynth.pipeline.mesh.contact_measures import (character_height, clip_ground, contact_steps, measure_input,
                                                          summary)

    common = ("synthesize", bar / "graph.h5", "-n", 5, "-m", 60, "--seed", 1, "--device", "cpu")
    report = json.loads(assert_ok(cli(*common, "-o", tmp_path / "a.h5", "--json", "--measure-feet", 3)).stdout)
    contact = report["contact"]
    assert contact["animations"] == 3 and contact["definitions"] == "docs/contact.md"
    assert contact["output"]["steps"] == 3 * 59
    data = read_synthesis(tmp_path / "a.h5")
    height = character_height(data["rest"])
    expected = summary(measure_input(data["examples"], [0, data["examples"].shape[0]], height)[0])
    assert contact["height"] == pytest.approx(height, rel=1e-5)
    for key, value in expected.items():
        assert contact["input"][key] == pytest.approx(value, rel=1e-4, abs=1e-9), key
    assert set(contact["ratios"]) == {"slide_median", "slide_p95", "sliding_share", "largest_accel"}
    assert contact["ratios"]["largest_accel"] > 0.0
    # issue 64: against the fit's playback too (its bones over the input's frames, the input's ground)
    played = lbs_reference(data["rest"], data["idx"], data["w"], data["input_F"], data["input_t"])
    fit = summary(contact_steps(played, clip_ground(data["examples"]), height))
    assert set(contact["fit"]) == set(fit) and set(contact["ratios_fit"]) == set(contact["ratios"])
    for key, value in fit.items():
        assert contact["fit"][key] == pytest.approx(value, rel=1e-4, abs=1e-9), key
    quiet = json.loads(assert_ok(cli(*common, "-o", tmp_path / "b.h5", "--json", "--measure-feet", 0)).stdout)
    assert "contact" not in quiet
    again = read_synthesis(tmp_path / "b.h5")
    assert np.array_equal(again["F"], data["F"]) and np.array_equal(again["t"], data["t"])
    text = assert_ok(cli(*common, "-o", tmp_path / "c.h5")).stdout
    assert "feet (first 4 animations" in text  # the default


def test_fit_skin_weighs_the_ground_contacts_by_default_and_says_how_the_playback_keeps_the_feet(tmp_path):
    """Issue 64: the planted walker fitted with 6 bones (its feet share bones with its shins). At
    the defaults the fit is weighed toward the vertices near the ground and its playback slides
    0.59× the plain fit's at the 95th percentile (test_contact_fit.py has the figures); the
    summary says so, in --json and in a line, and the same command writes the same file."""
    import json

    assert_ok(cli("example", "walker", "--planted", "-o", tmp_path / "w.npz", "-q"))
    summaries = {}
    for mode, extra in (("contacts", ()), ("plain", ("--no-contacts",))):
        done = assert_ok(cli("fit-skin", tmp_path / "w.npz", "-o", tmp_path / f"{mode}.h5", "--bones", 6, "--seed", 0,
                             "--json", *extra))
        summaries[mode] = json.loads(done.output.strip().splitlines()[-1])
    ours, plain = summaries["contacts"]["contacts"], summaries["plain"]["contacts"]
    assert plain["weighed"] is None and ours["weighed"]["vertices"] > 0 and 0.0 < ours["weighed"]["weight"] <= 20.0
    assert ours["capture"] == plain["capture"]
    assert ours["playback"]["slide_p95"] < 0.8 * plain["playback"]["slide_p95"]
    assert summaries["contacts"]["rmse"] < 1.05 * summaries["plain"]["rmse"]
    line = assert_ok(cli("fit-skin", tmp_path / "w.npz", "-o", tmp_path / "text.h5", "--bones", 6, "--seed", 0)).output
    assert "ground contacts:" in line and "vertices near the ground weighed" in line
    with h5py.File(tmp_path / "contacts.h5") as f, h5py.File(tmp_path / "text.h5") as g:  # deterministic
        assert np.array_equal(f["skin"]["bone_weights"][()], g["skin"]["bone_weights"][()])
        assert np.array_equal(f["skin"]["rotations"][()], g["skin"]["rotations"][()])


def test_a_contact_weight_without_the_contact_fit_is_refused_in_one_line(tmp_path):
    """--contact-weight weighs the contact fit: with --no-contacts, --rig or --skeleton there is none
    (it was silently unused), so the command refuses it before reading anything, nothing written."""
    assert_ok(cli("example", "walker", "--planted", "-o", tmp_path / "w.npz", "-q", "--frames", 12, "--rings", 6,
                  "--segments", 5))
    for extra in (("--no-contacts",), ("--skeleton",)):
        assert_user_error(cli("fit-skin", tmp_path / "w.npz", "-o", tmp_path / "s.h5", "--bones", 4,
                              "--contact-weight", 5, *extra), "--contact-weight", folder=tmp_path,
                          keep=["w.npz"])
    assert_ok(cli("fit-skin", tmp_path / "w.npz", "-o", tmp_path / "s.h5", "--bones", 4, "--contact-weight", 5, "-q"))
