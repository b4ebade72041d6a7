"""build-graph from the command line: outputs, inspect summary, plots, determinism, bad input."""

import json

import h5py
import numpy as np
import pytest

from skinsynth.formats.graph_file import read_graph
from skinsynth.formats.meshseq import write_array_sequence
from skinsynth.pipeline.inputs.examples import bending_bar

from cli_helpers import assert_folder_holds, assert_ok, assert_user_error, cli


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("graph")
    cycle, faces = bending_bar(frames=20, rings=10, segments=8)
    write_array_sequence(root / "loop.npz", np.concatenate([cycle, cycle, cycle[:6]]), faces, 24.0)
    assert_ok(cli("fit-skin", root / "loop.npz", "-o", root / "skin.h5", "--bones", 5, "--iterations", 8, "-q"))
    write_array_sequence(root / "two.npz", cycle[:2], faces, 24.0)
    assert_ok(cli("fit-skin", root / "two.npz", "-o", root / "two.h5", "--bones", 2, "--iterations", 2, "-q"))
    return root


def test_build_graph_finds_the_loop_and_summarises(files, tmp_path):
    out = assert_ok(cli("build-graph", files / "skin.h5", "-o", tmp_path / "g.h5", "--plot", tmp_path / "plots")).stdout
    assert "component" in out and "transitions" in out
    summary = json.loads(assert_ok(cli("inspect", tmp_path / "g.h5", "--json")).stdout)
    assert summary["stage"] == "graph" and summary["components"] >= 1 and summary["transitions"] > 0
    graph = read_graph(tmp_path / "g.h5")
    for component in graph.components:
        pairs = component.transitions
        # Two exact cycles of 20 frames: frames 20 apart are the same state.
        assert np.all(np.abs(pairs[:, 0] - pairs[:, 1]) % 20 == 0)
    pngs = sorted(p.name for p in (tmp_path / "plots").iterdir() if p.name != ".skinsynth-folder.json")
    assert (tmp_path / "plots" / ".skinsynth-folder.json").is_file()  # the folder is skinsynth's to replace
    assert "bone_graph.png" in pngs and any(p.startswith("costs_component_") for p in pngs)
    assert all((tmp_path / "plots" / p).read_bytes()[:4] == b"\x89PNG" for p in pngs)


def test_build_graph_is_deterministic(files, tmp_path):
    for name in ("a.h5", "b.h5"):
        assert_ok(cli("build-graph", files / "skin.h5", "-o", tmp_path / name, "-q"))
    with h5py.File(tmp_path / "a.h5") as a, h5py.File(tmp_path / "b.h5") as b:
        def datasets(group, prefix=""):
            for name, item in group.items():
                if isinstance(item, h5py.Dataset):
                    yield prefix + name
                else:
                    yield from datasets(item, prefix + name + "/")
        names = list(datasets(a["graph"]))
        assert names and names == list(datasets(b["graph"]))
        for name in names:
            assert a["graph"][name][()].tobytes() == b["graph"][name][()].tobytes(), name


def test_single_component(files, tmp_path):
    assert_ok(cli("build-graph", files / "skin.h5", "-o", tmp_path / "g.h5", "--single-component", "-q"))
    summary = json.loads(assert_ok(cli("inspect", tmp_path / "g.h5", "--json")).stdout)
    assert summary["components"] == 1 and summary["cut_nodes"] == []


@pytest.mark.parametrize("args,needles", [
    (["--threshold-scale", "0"], ["--threshold-scale"]),
    (["--edge-threshold", "-1"], ["--edge-threshold"]),
    (["--svd-threshold", "0"], ["--svd-threshold"]),
    (["--min-gap", "0"], ["--min-gap"]),
])
def test_bad_options(files, tmp_path, args, needles):
    assert_user_error(cli("build-graph", files / "skin.h5", "-o", tmp_path / "g.h5", *args), *needles, folder=tmp_path)


def test_bad_inputs(files, tmp_path):
    assert_user_error(cli("build-graph", files / "two.h5", "-o", tmp_path / "g.h5"),
                      f"{files / 'two.h5'}: the clip has 2 frames", "at least 3", folder=tmp_path)  # names the file
    assert_user_error(cli("build-graph", files / "loop.npz", "-o", tmp_path / "g.h5"), "loop.npz", folder=tmp_path)
    (tmp_path / "not.h5").write_bytes(b"nothing")
    assert_user_error(cli("build-graph", tmp_path / "not.h5", "-o", tmp_path / "g.h5"), "not.h5")
    assert_folder_holds(tmp_path, ["not.h5"])


@pytest.fixture(scope="module")
def bar_clips(tmp_path_factory):
    """A skin of two clips: the bar bends in one cycle of 20 frames; clip "bend" plays it twice,
    clip "part" holds its frames 5..14 again: part's frame m is bend's 5 + m (and 25 + m), so
    walks can cross both ways."""
    folder = tmp_path_factory.mktemp("bar_clips")
    cycle, faces = bending_bar(frames=20, rings=10, segments=8)
    write_array_sequence(folder / "bend.npz", np.concatenate([cycle, cycle]), faces, 24.0)
    write_array_sequence(folder / "part.npz", cycle[5:15], faces, 24.0)
    assert_ok(cli("fit-skin", folder / "bend.npz", folder / "part.npz", "-o", folder / "skin.h5", "--bones", 5,
                  "--iterations", 8, "-q"))
    return folder / "skin.h5"


def test_two_clips_get_transitions_between_them_counted_per_direction(bar_clips, tmp_path):
    result = assert_ok(cli("build-graph", bar_clips, "-o", tmp_path / "g.h5", "--plot", tmp_path / "plots"))
    assert "clips bend (40 frames), part (10 frames)" in result.stdout and "bend→part" in result.stdout
    summary = json.loads(assert_ok(cli("build-graph", bar_clips, "-o", tmp_path / "g.h5", "--json")).stdout)
    assert summary["clips"] == ["bend", "part"]
    with h5py.File(tmp_path / "g.h5") as f:
        found = [(f["graph"][k]["transitions"][()], f["graph"][k]["transition_costs"][()], f["graph"][k].attrs["threshold"])
                 for k in sorted(f["graph"]) if k.startswith("component_")]

    def phase(frame):  # the frame's place in the bar's cycle
        return np.where(frame < 40, frame % 20, (frame - 40 + 5) % 20)

    names = ("bend", "part")
    for component, (pairs, costs, threshold) in zip(summary["components"], found):
        assert np.all((pairs[:, 1] >= -2) & (pairs[:, 1] != 39) & (pairs[:, 1] != 49))  # j never a clip's last frame
        entered_frame = np.where(pairs[:, 1] >= 0, pairs[:, 1] + 1, np.where(pairs[:, 1] == -1, 0, 40))
        left, entered = (pairs[:, 0] >= 40).astype(int), (entered_frame >= 40).astype(int)
        expected = {f"{names[a]}->{names[b]}": int(((left == a) & (entered == b)).sum()) for a in (0, 1) for b in (0, 1)}
        assert component["transitions_between"] == expected
        crossing = (left != entered) & (costs < threshold)
        assert ((left == 0) & crossing).any() and ((left == 1) & crossing).any()
        # each cheap crossing plays next the frame of the cycle that follows the one it leaves
        assert np.all((phase(pairs[crossing, 0]) + 1) % 20 == phase(entered_frame[crossing]))
    assert summary["transitions_between"] == {key: sum(c["transitions_between"][key] for c in summary["components"])
                                              for key in summary["components"][0]["transitions_between"]}


def test_clips_left_out_of_the_walks_get_no_transition_and_are_never_played(bar_clips, tmp_path):
    summary = json.loads(assert_ok(cli("build-graph", bar_clips, "-o", tmp_path / "g.h5", "--clips", "bend",
                                       "--json")).stdout)
    assert summary["walk_clips"] == ["bend"]
    with h5py.File(tmp_path / "g.h5") as f:
        assert list(f["graph"].attrs["clips"]) == ["bend"]
        pairs = np.concatenate([f["graph"][k]["transitions"][()] for k in f["graph"] if k.startswith("component_")])
    entered = np.where(pairs[:, 1] >= 0, pairs[:, 1] + 1, np.where(pairs[:, 1] == -1, 0, 40))
    assert len(pairs) and np.all((pairs[:, 0] < 40) & (entered < 40))  # bend's frames only
    assert_ok(cli("synthesize", tmp_path / "g.h5", "-o", tmp_path / "s.h5", "-n", 8, "-m", 120, "-q"))
    with h5py.File(tmp_path / "s.h5") as f:
        assert f["synthesis/sources"][()].max() < 40
    # a walk cannot start in a clip left out; the message names the frame as CLIP:FRAME
    assert_user_error(cli("synthesize", tmp_path / "g.h5", "-o", tmp_path / "t.h5", "-n", 2, "-m", 60, "--start",
                          "part:2"), "input frame part:2", "dead end")
    assert_user_error(cli("build-graph", bar_clips, "-o", tmp_path / "x.h5", "--clips", "bend,trot"),
                      "--clips", "no clip named 'trot'", "bend, part")


# --- ground contacts (issue 35, part 1) ----------------------------------------------------------


@pytest.fixture(scope="module")
def contact_files(tmp_path_factory):
    """A block that rests, lifts and rests again (contacts), and the bending bar floating around
    a circle, never at rest (none); each fitted."""
    import trimesh

    root = tmp_path_factory.mktemp("contacts")
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    rest, faces = trimesh.remesh.subdivide(box.vertices, box.faces)
    rest = rest - [0.0, rest[:, 1].min(), 0.0]
    lift = np.zeros(30)
    lift[10:18] = [0.1, 0.3, 0.4, 0.5, 0.4, 0.3, 0.2, 0.1]
    write_array_sequence(root / "block.npz", rest[None] + lift[:, None, None] * [0.0, 1.0, 0.0], faces, 10.0)
    cycle, bar_faces = bending_bar(frames=20, rings=10, segments=8)
    bar = np.concatenate([cycle, cycle, cycle[:6]])
    turn = 4.0 * np.pi * np.arange(len(bar)) / len(bar)  # two whole turns of a circle: no belt to stand on
    bar = bar + (6.0 * np.stack([np.cos(turn), np.zeros_like(turn), np.sin(turn)], axis=1))[:, None]
    write_array_sequence(root / "bar.npz", bar, bar_faces, 24.0)
    for name, bones in (("block", 2), ("bar", 5)):
        assert_ok(cli("fit-skin", root / f"{name}.npz", "-o", root / f"{name}.skin.h5", "--bones", bones,
                      "--iterations", 8, "-q"))
    return root


def test_contacts_are_stored_read_back_and_drawn(contact_files, tmp_path):
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.inputs.clips import Clips
    from skinsynth.pipeline.synthesis.contact.patches import find_contacts

    out = assert_ok(cli("build-graph", contact_files / "block.skin.h5", "-o", tmp_path / "g.h5", "--json",
                        "--plot", tmp_path / "plots")).stdout
    summary = json.loads(out)
    assert summary["contacts"]["patches"] == 1 and summary["contacts"]["plants"] == 2
    graph = read_graph(tmp_path / "g.h5")
    skin = read_skin(contact_files / "block.skin.h5")
    found = find_contacts(skin.examples, skin.faces, skin.fps, 1, Clips(skin.clip_names, skin.clip_frames))
    record = graph.contacts
    assert record.count == 1 and np.array_equal(record.vertices, found.vertices)
    assert np.array_equal(record.offsets, found.offsets) and np.array_equal(record.planted, found.planted)
    assert np.array_equal(record.ground, found.ground) and record.height == found.height
    assert record.options == {"height": 0.02, "speed": 1.0, "release": 1.5, "min_duration": 0.1, "min_support": 0.12}
    assert record.planted[:10, 0].all() and not record.planted[10:18, 0].any() and record.planted[18:, 0].all()
    assert (tmp_path / "plots" / "contacts.png").read_bytes()[:4] == b"\x89PNG"
    assert_ok(cli("build-graph", contact_files / "block.skin.h5", "-o", tmp_path / "none.h5", "--no-contacts", "-q"))
    assert read_graph(tmp_path / "none.h5").contacts is None


def test_view_shows_a_graph_files_contacts_on_its_input_frames(contact_files, tmp_path):
    # `view GRAPH.h5` opens the skin page (the input frames and the fit); it carries the contacts
    # its page colours: the planted patch's vertices at a planted frame, none while lifted.
    from skinsynth.cli.view import _read
    from skinsynth.pipeline.view import scenes

    assert_ok(cli("build-graph", contact_files / "block.skin.h5", "-o", tmp_path / "g.h5", "-q"))
    kind, view, details, _ = _read(tmp_path / "g.h5", 0, 0.01, 0.1, None, "cpu")
    record = read_graph(tmp_path / "g.h5").contacts
    assert kind == "skin" and details["contact_patches"] == 1
    assert [np.array_equal(a, b) for a, b in zip(view.contacts, (record.vertices, record.offsets, record.planted))] \
        == [True] * 3
    assert np.array_equal(scenes.planted_vertices(*view.contacts, 0), record.vertices)  # its one patch
    assert scenes.planted_vertices(*view.contacts, 13).size == 0
    assert _read(contact_files / "block.skin.h5", 0, 0.01, 0.1, None, "cpu")[1].contacts is None  # a skin file


def test_a_capture_that_never_rests_keeps_its_graph_file(contact_files, tmp_path):
    from skinsynth.formats.model import content_digests

    out = assert_ok(cli("build-graph", contact_files / "bar.skin.h5", "-o", tmp_path / "a.h5", "--plot",
                        tmp_path / "plots")).stdout
    assert "ground contacts: none" in out
    assert_ok(cli("build-graph", contact_files / "bar.skin.h5", "-o", tmp_path / "b.h5", "--no-contacts", "-q"))
    assert content_digests(tmp_path / "a.h5") == content_digests(tmp_path / "b.h5")
    with h5py.File(tmp_path / "a.h5") as f:
        assert "contacts" not in f["graph"]
    assert not (tmp_path / "plots" / "contacts.png").exists()


@pytest.mark.parametrize("args,needles", [
    (["--contact-height", "0"], ["--contact-height"]),
    (["--contact-speed", "-1"], ["--contact-speed"]),
    (["--contact-release", "0.5"], ["--contact-release", "at least 1"]),
    (["--contact-min-duration", "-1"], ["--contact-min-duration"]),
    (["--contact-min-support", "1.5"], ["--contact-min-support"]),
])
def test_bad_contact_options(contact_files, tmp_path, args, needles):
    assert_user_error(cli("build-graph", contact_files / "block.skin.h5", "-o", tmp_path / "g.h5", *args), *needles,
                      folder=tmp_path)
