"""A motion-capture take drives a puppet: select-controls --markers, play --controls take.c3d."""

import json

import h5py
import numpy as np
import pytest

from c3d_writing import write_c3d
from cli_helpers import assert_ok, assert_user_error, cli
from skinsynth.pipeline.rig.rotations import rotation_exp

#: The known map from the puppet's space (Y up, metres) to the take's (Z up, millimetres).
SCALE, TURN, SHIFT = 1.3, rotation_exp(np.array([0.2, -0.4, 1.1])), np.array([250.0, -1200.0, 30.0])
Y_TO_Z = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # (x, y, z) -> (z, x, y): y becomes up


@pytest.fixture(scope="module")
def puppet(tmp_path_factory):
    """The walker's puppet on 8 markers of a layout (one given by its rest position), its skin,
    and the layout: (folder, labels, control vertices)."""
    folder = tmp_path_factory.mktemp("markers")
    assert_ok(cli("example", "walker", "-o", folder / "walker.npz", "--frames", 48, "--cycles", 2, "--rings", 10, "-q"))
    assert_ok(cli("fit-skin", folder / "walker.npz", "-o", folder / "skin.h5", "--bones", 10, "--iterations", 10, "-q"))
    with h5py.File(folder / "skin.h5", "r") as f:
        rest = f["mesh/rest_vertices"][()]
    height = np.ptp(rest[:, 1])
    picks = [int(np.argmax(rest[:, 1]))]  # farthest-point spread over the body, from the top
    for _ in range(7):
        picks.append(int(np.argmax(np.min(np.linalg.norm(rest[:, None] - rest[picks][None], axis=2), axis=1))))
    labels = [f"M{i}" for i in range(8)]
    layout = {label: vertex for label, vertex in zip(labels, picks)}
    layout["M3"] = rest[picks[3]].tolist()  # given by its position: the nearest vertex
    (folder / "layout.json").write_text(json.dumps(layout))
    assert height > 0
    assert_ok(cli("select-controls", folder / "skin.h5", "-o", folder / "controls.h5", "--markers",
                  folder / "layout.json", "-q"))
    assert_ok(cli("train-kcca", folder / "controls.h5", "-o", folder / "puppet.h5", "-q"))
    return folder, labels, picks


def _take(folder, labels, picks, name, rate_factor=5, holes=(), **write):
    """The walker's own control vertices as a take at rate_factor × its fps, in the known map;
    holes: (label index, first, last) take frames made missing. -> (take path, clean controls
    (F, n, 3) at the walker's frames)."""
    with h5py.File(folder / "skin.h5", "r") as f:
        frames = f["examples/vertices"][()][:, picks]
        fps = float(f["examples"].attrs["fps"])
    times = np.arange((len(frames) - 1) * rate_factor + 1) / rate_factor
    low = np.minimum(np.floor(times).astype(int), len(frames) - 1)
    high = np.minimum(low + 1, len(frames) - 1)
    mix = (times - low)[:, None, None]
    dense = (1 - mix) * frames[low] + mix * frames[high]
    points = (SCALE * (dense @ Y_TO_Z.T) @ TURN.T) * 1000.0 + SHIFT
    for marker, first, last in holes:
        points[first:last + 1, marker] = np.nan
    path = folder / name
    write_c3d(path, [f"Actor:{label}" for label in labels], points, fps * rate_factor, **write)
    return path, frames


def test_layout_is_stored_with_the_controls(puppet):
    folder, labels, picks = puppet
    with h5py.File(folder / "puppet.h5", "r") as f:
        assert [s.decode() for s in f["controls/marker_labels"][()]] == labels
        assert f["controls/vertex_indices"][()].tolist() == picks


def test_a_clean_take_plays_as_its_own_controls_and_recovers_the_transform(puppet, tmp_path):
    folder, labels, picks = puppet
    take, clean = _take(folder, labels, picks, "clean.c3d")
    np.save(tmp_path / "clean.npy", clean)
    report = json.loads(assert_ok(cli("play", folder / "puppet.h5", "-c", take, "-o", tmp_path / "take.h5",
                                      "--json", "--filter", "none")).stdout)  # raw: exactly the controls
    assert_ok(cli("play", folder / "puppet.h5", "-c", tmp_path / "clean.npy", "-o", tmp_path / "clean.h5", "-q"))
    with h5py.File(tmp_path / "take.h5", "r") as a, h5py.File(tmp_path / "clean.h5", "r") as b:
        played, truth = a["vertices"][()], b["vertices"][()]
    assert played.shape == truth.shape
    assert np.abs(played - truth).max() < 1e-5 * np.ptp(truth[..., 1])
    summary = report["takes"][0]
    total = np.array(summary["transform"]["rotation"]) * summary["transform"]["scale"]
    expected = np.linalg.inv(SCALE * 1000.0 * TURN @ Y_TO_Z) * 1000.0  # take metres -> puppet units
    assert np.abs(total - expected).max() < 1e-6 * np.abs(expected).max()
    assert np.abs(np.array(summary["transform"]["translation"]) + expected @ SHIFT / 1000.0).max() < 1e-6
    assert summary["neutral_frame"] == 0 and summary["units"] == "mm" and summary["filled"] == {}
    assert len(report["extrapolation"][0]["per_frame"]) == report["frames"]


def test_gaps_are_filled_and_listed(puppet, tmp_path):
    folder, labels, picks = puppet
    take, _ = _take(folder, labels, picks, "gaps.c3d", holes=[(2, 10, 14), (5, 40, 140)])
    report = json.loads(assert_ok(cli("play", folder / "puppet.h5", "-c", take, "-o", tmp_path / "take.h5",
                                      "--json")).stdout)
    filled = report["takes"][0]["filled"]
    assert filled["M2"] == {"interpolated": "10–14", "from_other_markers": "", "frames": 5}
    assert filled["M5"] == {"interpolated": "", "from_other_markers": "40–140", "frames": 101}
    uncertainty = report["takes"][0]["fill_uncertainty"]["per_frame"]  # at the walker's 24 fps: take frame / 5
    assert len(uncertainty) == report["frames"] and all(u > 0 for u in uncertainty[8:29])
    assert all(u == 0 for u in uncertainty[:2] + uncertainty[29:])
    with h5py.File(tmp_path / "take.h5", "r") as f:
        assert np.isfinite(f["vertices"][()]).all()


@pytest.mark.parametrize("case, needle", [
    ("garbage", "c3d"), ("truncated", "truncated"), ("units", "unit"), ("missing", "lacks markers"),
    ("few", "fewer than 3"), ("vertex", "outside the mesh"), ("differ", "differ from the puppet's controls"),
])
def test_bad_takes_and_layouts_are_refused_in_one_line(puppet, tmp_path, case, needle):
    folder, labels, picks = puppet
    take, _ = _take(folder, labels, picks, "ok.c3d")
    layout = folder / "layout.json"
    if case == "garbage":
        take = tmp_path / "garbage.c3d"
        take.write_bytes(b"not a c3d file at all" * 50)
    elif case == "truncated":
        data = (folder / "ok.c3d").read_bytes()
        take = tmp_path / "cut.c3d"
        take.write_bytes(data[: len(data) * 2 // 3])
    elif case == "units":
        take, _ = _take(folder, labels, picks, "furlong.c3d", units="furlong")
    elif case in ("missing", "few"):
        kept = labels[:-1] if case == "missing" else labels[:2]
        take, _ = _take(folder, kept, [picks[labels.index(k)] for k in kept], f"{case}.c3d")
    elif case == "vertex":
        layout = tmp_path / "far.json"
        layout.write_text(json.dumps({**{l: v for l, v in zip(labels, picks)}, "M7": 10 ** 7}))
    elif case == "differ":
        layout = tmp_path / "other.json"
        layout.write_text(json.dumps({**{l: v for l, v in zip(labels, picks)}, "M7": picks[7] + 1}))
    result = cli("play", folder / "puppet.h5", "-c", take, "--markers", layout, "-o", tmp_path / "out.glb")
    assert_user_error(result, needle, folder=tmp_path, keep=[p.name for p in tmp_path.iterdir()])


def test_a_partial_marker_set_plays_with_allow_missing(puppet, tmp_path):
    """Issue 45: the neutral frame and the alignment need only the markers the take has, and a
    frame is held only when it sees fewer than half of those (not half the layout)."""
    folder, labels, picks = puppet
    kept = [0, 2, 5, 7]
    take, clean = _take(folder, [labels[k] for k in kept], [picks[k] for k in kept], "four.c3d")
    report = json.loads(assert_ok(cli("play", folder / "puppet.h5", "-c", take, "--allow-missing",
                                      "-o", tmp_path / "four.h5", "--json")).stdout)
    summary = report["takes"][0]
    lacking = [label for k, label in enumerate(labels) if k not in kept]
    last = (len(clean) - 1) * 5
    assert summary["missing_markers"] == lacking and summary["min_markers"] == 3 and summary["held_frames"] == ""
    assert {label: summary["filled"][label]["from_other_markers"] for label in lacking} == {
        label: f"0–{last}" for label in lacking}
    with h5py.File(tmp_path / "four.h5", "r") as f:
        assert np.isfinite(f["vertices"][()]).all() and len(f["vertices"]) == len(clean)


def test_the_take_is_low_passed_by_default_and_reported(puppet, tmp_path):
    folder, labels, picks = puppet
    take, _ = _take(folder, labels, picks, "filtered.c3d")
    runs, neutral, frame = {}, {}, {}
    for name, extra in (("default", []), ("raw", ["--filter", "none"]), ("three", ["--filter", "3"]),
                        ("ten", ["--filter", "10"])):
        result = assert_ok(cli("play", folder / "puppet.h5", "-c", take, "-o", tmp_path / f"{name}.h5", "--json",
                               *extra))
        summary = json.loads(result.stdout)["takes"][0]
        runs[name], neutral[name] = summary["filter"], summary["neutral_residual"]
        frame[name] = summary["neutral_frame"]
    # the default chooses the cut-off from the take: a clean take's is high (nothing to stop), and it says so
    assert runs["default"]["chosen"] == "auto" and 15.0 <= runs["default"]["cutoff_hz"] <= 40.0
    said = assert_ok(cli("play", folder / "puppet.h5", "-c", take, "-o", tmp_path / "said.h5"))
    assert f"low-passed at {runs['default']['cutoff_hz']:g} Hz (chosen from the take" in said.stdout + said.stderr
    assert runs["ten"] == {"cutoff_hz": 10.0, "chosen": "given", "order": 2, "passes": 2, "samples_kept_raw": 0}
    assert runs["raw"] == "none"
    # the neutral frame's residual and the noise in it: none known on a raw take, which keeps it whole
    assert set(neutral["default"]) == {"residual", "noise", "kept", "frames"}
    assert 0.0 <= neutral["default"]["kept"] <= 1.0
    assert neutral["default"]["noise"] > 0.0 and neutral["raw"]["noise"] == 0.0 and neutral["raw"]["kept"] == 1.0
    assert neutral["raw"]["frames"] == [frame["raw"]] * 2  # raw: the neutral frame as measured
    assert runs["three"]["cutoff_hz"] == 3.0
    with h5py.File(tmp_path / "raw.h5", "r") as a, h5py.File(tmp_path / "three.h5", "r") as b:
        raw, cut = a["vertices"][()], b["vertices"][()]
        assert np.abs(raw - cut).max() > 0.01 * np.ptp(raw[..., 1])  # the strides cut at 3 Hz (9 % of the height)
    assert_user_error(cli("play", folder / "puppet.h5", "-c", take, "--filter", "low", "-o", tmp_path / "x.h5"),
                      "--filter takes a cut-off in Hz, auto or none", folder=tmp_path,
                      keep=[p.name for p in tmp_path.iterdir()])


def test_take_options_need_a_take(puppet, tmp_path):
    folder, _, _ = puppet
    np.save(tmp_path / "c.npy", np.zeros((3, 8, 3)))
    result = cli("play", folder / "puppet.h5", "-c", tmp_path / "c.npy", "--retarget", "absolute", "-o",
                 tmp_path / "o.h5")
    assert_user_error(result, "--retarget applies to a motion-capture take")


def test_frames_seeing_too_few_markers_are_held_and_the_first_time_is_kept(puppet, tmp_path):
    folder, labels, picks = puppet
    holes = [(m, 60, 64) for m in range(6)]  # 2 of 8 markers seen for 5 take frames: fewer than 4
    take, _ = _take(folder, labels, picks, "held.c3d", holes=holes, first_frame=15)
    report = json.loads(assert_ok(cli("play", folder / "puppet.h5", "-c", take, "--max-gap", 0, "--fps", 12,
                                      "-o", tmp_path / "take.usda", "--as", "points", "--json")).stdout)
    summary = report["takes"][0]
    assert summary["held_frames"] == "60–64" and summary["min_markers"] == 4
    assert summary["fps"] == 12 and report["frames"] == (48 * 5 - 5) * 12 // (24 * 5) + 1
    from pxr import Usd

    stage = Usd.Stage.Open(str(tmp_path / "take.usda"))
    assert stage.GetStartTimeCode() == pytest.approx(15 / (24 * 5) * 12)
    assert stage.GetTimeCodesPerSecond() == pytest.approx(12)


def test_stabilize_removes_the_named_markers_rigid_motion(puppet, tmp_path):
    folder, labels, picks = puppet
    take, _ = _take(folder, labels, picks, "steady.c3d")
    report = json.loads(assert_ok(cli("play", folder / "puppet.h5", "-c", take, "--stabilize", "m0,M1,Actor:M2",
                                      "-o", tmp_path / "take.h5", "--json")).stdout)
    assert report["takes"][0]["neutral_frame"] % 120 == 0  # the rest pose: the walker's cycle is 120 take frames
    result = cli("play", folder / "puppet.h5", "-c", take, "--stabilize", "M0,M1,NOSE", "-o", tmp_path / "x.h5")
    assert_user_error(result, "--stabilize names markers the layout lacks: NOSE")


def test_takes_no_play_can_honour_are_refused_before_the_work_with_advice_that_fits(puppet, tmp_path, monkeypatch):
    """Issue 46: a take whose rate is 1e-9 Hz, or play --fps 1e9, ran until memory failed ("out of
    memory", naming neither the file nor the option); a take with no sample at all was told to
    give --neutral-frame a frame that sees every marker. Now each is refused before the take is
    turned into controls, naming the file, the option and the frames it would make; and a neutral
    frame lacking markers names them by label."""
    from c3d_writing import write_c3d

    folder, labels, picks = puppet
    take, _ = _take(folder, labels, picks, "ok.c3d")

    def never(*args, **kwargs):
        raise AssertionError("the take was turned into controls before the refusal")

    with monkeypatch.context() as patch:
        patch.setattr("skinsynth.pipeline.puppet.drive_from_markers", never)
        slow = tmp_path / "slow.c3d"
        write_c3d(slow, [f"Actor:{label}" for label in labels], np.full((20, 8, 3), 100.0), 1e-9)
        assert_user_error(cli("play", folder / "puppet.h5", "-c", slow, "-o", tmp_path / "o.h5"), str(slow),
                          "1e-09 per second", "frames", "of memory", folder=tmp_path, keep=["slow.c3d"])
        assert_user_error(cli("play", folder / "puppet.h5", "-c", take, "--fps", "1e9", "-o", tmp_path / "o.h5"),
                          str(take), "--fps", "frames", "of memory", folder=tmp_path, keep=["slow.c3d"])
        empty = tmp_path / "empty.c3d"
        write_c3d(empty, [f"Actor:{label}" for label in labels], np.full((20, 8, 3), np.nan), 120.0)
        assert_user_error(cli("play", folder / "puppet.h5", "-c", empty, "-o", tmp_path / "o.h5"), str(empty),
                          "no marker sample", folder=tmp_path, keep=["slow.c3d", "empty.c3d"])
    gaps, _ = _take(folder, labels, picks, "gaps.c3d", holes=[(5, 40, 140)])
    assert_user_error(cli("play", folder / "puppet.h5", "-c", gaps, "--neutral-frame", 50, "-o", tmp_path / "o.h5"),
                      "--neutral-frame 50 lacks markers M5", folder=tmp_path, keep=["slow.c3d", "empty.c3d"])
