"""Control-point selection (Feng §3): varimax against statsmodels, in-place alignment, PCA,
representative vertices, the automatic choice, the controls file and the ``select-controls`` CLI.

Our varimax is raw (no Kaiser normalisation), like statsmodels' ``rotate_factors(A, "varimax")``
(orthomax γ = 1, gradient projection, no row normalisation); the Kaiser-normalised variant is
compared with statsmodels run on the row-normalised matrix.
"""

import json
import os

import h5py
import numpy as np
import pytest

from skinsynth.formats.controls_file import controls_groups, read_controls
from skinsynth.formats.errors import FormatError
from skinsynth.formats.model import read_model, write_model
from skinsynth.pipeline.puppet.controls import (align_in_place, choose_controls, pca_bases, representative_vertices,
                                         select_controls)
from skinsynth.pipeline.errors import OptionError
from skinsynth.pipeline.rig.rotations import rotation_exp

from cli_helpers import assert_ok, cli
from skinsynth.pipeline.puppet.varimax import varimax

statsmodels_rotation = pytest.importorskip("statsmodels.multivariate.factor_rotation")


def random_rotations(rng, count, angle=np.pi):
    return rotation_exp(rng.uniform(-angle, angle, size=(count, 3)))


def varimax_criterion(loadings):
    squared = loadings ** 2
    return float(np.sum(squared ** 2) - np.sum(squared.sum(axis=0) ** 2) / loadings.shape[0])


# ---------------------------------------------------------------- varimax


# statsmodels' gradient projection stalls near 1e-6 of the optimum (tighter tolerances only run
# it to max_tries, for seconds), so the comparison is at 1e-5 plus the criterion value.
@pytest.mark.parametrize("shape,seed", [((30, 3), 0), ((100, 5), 1), ((12, 2), 2)])
def test_varimax_matches_statsmodels(shape, seed):
    a = np.random.default_rng(seed).normal(size=shape)
    expected, expected_rotation = statsmodels_rotation.rotate_factors(a, "varimax")
    rotated, rotation = varimax(a, tol=1e-12, max_iter=5000)
    np.testing.assert_allclose(rotated, expected, atol=1e-5)
    np.testing.assert_allclose(rotation, expected_rotation, atol=1e-5)
    assert varimax_criterion(rotated) >= varimax_criterion(expected) * (1.0 - 1e-10)
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(shape[1]), atol=1e-12)
    np.testing.assert_allclose(rotated, a @ rotation, atol=1e-12)
    assert varimax_criterion(rotated) >= varimax_criterion(a)


def test_varimax_kaiser_normalisation_matches_statsmodels_on_normalised_rows():
    rng = np.random.default_rng(4)
    a = rng.normal(size=(50, 4)) * rng.uniform(0.1, 3.0, size=(50, 1))
    norms = np.linalg.norm(a, axis=1, keepdims=True)
    expected, _ = statsmodels_rotation.rotate_factors(a / norms, "varimax")
    rotated, rotation = varimax(a, normalize=True, tol=1e-12, max_iter=5000)
    np.testing.assert_allclose(rotated, expected * norms, atol=1e-4)
    np.testing.assert_allclose(rotated, a @ rotation, atol=1e-12)
    assert varimax_criterion(rotated / norms) >= varimax_criterion(expected) * (1.0 - 1e-10)


def test_varimax_recovers_planted_simple_structure():
    rng = np.random.default_rng(5)
    p, k = 80, 4
    planted = np.zeros((p, k))
    owner = np.arange(p) % k
    planted[np.arange(p), owner] = rng.uniform(0.5, 1.5, size=p) * rng.choice([-1.0, 1.0], size=p)
    mixing, _ = np.linalg.qr(rng.normal(size=(k, k)))
    rotated, _ = varimax(planted @ mixing, tol=1e-12, max_iter=5000)
    # Up to column order and sign: match each rotated column to the planted column it correlates with.
    match = np.abs(rotated.T @ planted)
    order = np.argmax(match, axis=1)
    assert sorted(order.tolist()) == list(range(k))
    signs = np.sign(np.sum(rotated * planted[:, order], axis=0))
    np.testing.assert_allclose(rotated * signs, planted[:, order], atol=1e-6)


def test_varimax_single_column_is_untouched():
    a = np.random.default_rng(6).normal(size=(10, 1))
    rotated, rotation = varimax(a)
    np.testing.assert_array_equal(rotated, a)
    np.testing.assert_array_equal(rotation, np.eye(1))


# ---------------------------------------------------------------- a sequence with two independent "mouths"


def two_mouths(frames=30, seed=7, global_motion=True):
    """A curved 21 x 21 sheet with two patches; each opens like a mouth (upper lobe +y, lower lobe -y)
    with its own random amplitude per frame. Returns (vertices (F, V, 3), rest, lobe peak ids)."""
    rng = np.random.default_rng(seed)
    xs = np.linspace(0.0, 1.0, 21)
    x, y = np.meshgrid(xs, xs, indexing="ij")
    rest = np.stack([x.ravel(), y.ravel(), 0.3 * (x.ravel() - 0.5) ** 2], axis=1)
    peaks, displacement = [], []
    for cx in (0.25, 0.75):
        field = np.zeros_like(rest)
        for cy, direction in ((0.6, 1.0), (0.4, -1.0)):  # no net translation or rotation
            weight = np.exp(-((rest[:, 0] - cx) ** 2 + (rest[:, 1] - cy) ** 2) / (2 * 0.06 ** 2))
            field[:, 1] += direction * 0.05 * weight
            peaks.append(int(np.argmin((rest[:, 0] - cx) ** 2 + (rest[:, 1] - cy) ** 2)))
        displacement.append(field)
    amplitude = rng.normal(size=(frames, 2))
    vertices = rest + np.einsum("fp,pva->fva", amplitude, np.stack(displacement))
    if global_motion:
        rotations = random_rotations(rng, frames)
        vertices = np.einsum("fab,fvb->fva", rotations, vertices) + rng.normal(scale=2.0, size=(frames, 1, 3))
    return vertices, rest, peaks


def test_align_in_place_undoes_a_known_rigid_motion():
    rng = np.random.default_rng(8)
    rest = rng.normal(size=(40, 3))
    rotations = random_rotations(rng, 5)
    translations = rng.normal(scale=3.0, size=(5, 3))
    moved = np.einsum("fab,vb->fva", rotations, rest) + translations[:, None]
    in_place, found_r, found_t = align_in_place(moved, rest)
    np.testing.assert_allclose(in_place, np.broadcast_to(rest, in_place.shape), atol=1e-10)
    np.testing.assert_allclose(found_r, np.swapaxes(rotations, 1, 2), atol=1e-10)
    # A deformed sequence: moving it rigidly does not change its in-place frames.
    deformed = rest + rng.normal(scale=0.1, size=(5, 40, 3))
    moved = np.einsum("fab,fvb->fva", rotations, deformed) + translations[:, None]
    np.testing.assert_allclose(align_in_place(moved, rest)[0], align_in_place(deformed, rest)[0], atol=1e-10)


def test_pca_matches_numpy_svd():
    rng = np.random.default_rng(9)
    frames = rng.normal(size=(12, 20, 3))
    bases, share, explained = pca_bases(frames, components=5)
    data = frames.reshape(12, -1)
    _, s, vt = np.linalg.svd(data - data.mean(axis=0), full_matrices=False)
    np.testing.assert_allclose(share, (s ** 2 / np.sum(s ** 2))[:5], rtol=1e-12)
    assert explained == pytest.approx(share.sum()) and explained <= 1.0
    flat = bases.reshape(5, -1)
    np.testing.assert_allclose(np.abs(np.sum(flat * vt[:5], axis=1)), 1.0, atol=1e-10)
    np.testing.assert_allclose(flat @ flat.T, np.eye(5), atol=1e-10)
    # Default: the smallest K reaching 99 %, and K <= min(F - 1, 3V).
    _, share_all, explained_all = pca_bases(frames)
    cumulative = np.cumsum(s ** 2) / np.sum(s ** 2)
    assert len(share_all) == np.searchsorted(cumulative, 0.99) + 1 and explained_all >= 0.99
    for bad in (0, 12):
        with pytest.raises(OptionError, match="--components"):
            pca_bases(frames, components=bad)


def test_representative_vertices_lie_on_the_mouth_lobes():
    vertices, rest, peaks = two_mouths()
    in_place, _, _ = align_in_place(vertices, rest)
    bases, share, explained = pca_bases(in_place)
    assert len(share) == 2 and explained > 0.999
    rotated, _ = varimax(bases.reshape(2, -1).T)
    rotated = rotated.T.reshape(2, -1, 3)
    candidates, basis_of, loading = representative_vertices(rotated)
    assert basis_of.tolist() == [0, 0, 1, 1]
    # Each rotated basis is one mouth: the pair of candidates is that mouth's two lobe peaks.
    pairs = sorted(sorted(candidates[2 * k:2 * k + 2].tolist()) for k in range(2))
    assert pairs == sorted([sorted(peaks[:2]), sorted(peaks[2:])])
    energy = np.sum(rotated ** 2, axis=2)
    left = rest[:, 0] < 0.5
    assert sorted([energy[0, left].sum(), energy[1, left].sum()]) == pytest.approx([0.0, 1.0], abs=1e-6)
    np.testing.assert_allclose(loading, np.linalg.norm(rotated, axis=2)[basis_of, candidates])


def test_select_controls_ignores_global_motion_and_finds_the_lobes():
    moving, rest, peaks = two_mouths(global_motion=True)
    still, _, _ = two_mouths(global_motion=False)
    a = select_controls(moving, rest, count=4)
    b = select_controls(still, rest, count=4)
    assert sorted(a.indices.tolist()) == sorted(peaks)
    assert sorted(b.indices.tolist()) == sorted(peaks)
    # The two lobes of a mouth move equally much, so which one is a basis's "first" representative
    # is a tie that round-off decides; either way round 1 takes one lobe of each mouth.
    mouth = {peaks[0]: 0, peaks[1]: 0, peaks[2]: 1, peaks[3]: 1}
    for selection in (a, b):
        assert sorted(mouth[v] for v in selection.indices[:2].tolist()) == [0, 1]
        assert sorted(mouth[v] for v in selection.indices[2:].tolist()) == [0, 1]
    np.testing.assert_allclose(a.basis_variance, b.basis_variance, atol=1e-8)
    assert a.method == "auto" and a.components == 2 and len(a.reasons) == 4
    assert a.basis_variance.sum() == pytest.approx(a.explained) and a.explained <= 1.0 + 1e-12
    assert np.all(np.diff(a.basis_variance) <= 0.0)
    # Round 1 takes each basis's first representative, round 2 the second ones.
    assert [r.split(" ")[1] for r in a.reasons] == ["1", "1", "2", "2"]
    assert a.control_basis.tolist() == [0, 1, 0, 1]
    # Only 4 distinct candidates exist in a rank-2 sequence.
    with pytest.raises(OptionError, match="--count 5 but only 4 candidate vertices"):
        select_controls(moving, rest, count=5)


def test_choose_controls_spacing_count_and_determinism():
    rng = np.random.default_rng(10)
    rest = rng.uniform(size=(200, 3))
    candidates = rng.choice(200, size=16, replace=False)
    basis_of = np.repeat(np.arange(8), 2)
    share = rng.dirichlet(np.ones(8))
    first, reasons = choose_controls(candidates, basis_of, share, rest, 6, 0.2)
    again, reasons_again = choose_controls(candidates, basis_of, share, rest, 6, 0.2)
    np.testing.assert_array_equal(first, again)
    assert reasons == reasons_again and len(reasons) == 6 and len(set(first.tolist())) == 6
    assert set(first.tolist()) <= set(candidates.tolist())
    gaps = np.linalg.norm(rest[first][:, None] - rest[first][None], axis=2) + np.eye(6) * 9
    round_robin = [not r.startswith("farthest-point") for r in reasons]
    for i in range(6):  # each round-robin pick respects the spacing to the controls chosen before it
        if round_robin[i]:
            assert np.all(gaps[i, :i] >= 0.2)
    # The first pick is the top vertex of the basis with the largest variance share.
    assert first[0] == candidates[2 * np.argmax(share)]
    # A spacing nothing can satisfy: one round-robin pick, then farthest-point fill.
    spread, why = choose_controls(candidates, basis_of, share, rest, 16, 10.0)
    assert sorted(spread.tolist()) == sorted(candidates.tolist())
    assert sum(r.startswith("farthest-point") for r in why) == 15
    with pytest.raises(OptionError, match="--count 17 but only 16"):
        choose_controls(candidates, basis_of, share, rest, 17, 0.0)
    with pytest.raises(OptionError, match="--count must be at least 1"):
        choose_controls(candidates, basis_of, share, rest, 0, 0.0)


def test_near_candidates_are_skipped_only_when_they_move_with_a_control():
    # Candidates 0 (first, top basis) and 1 lie close; 2 is far. Over the frames, 1 either keeps
    # its distance to 0 (one rigid piece: skipped) or moves away from it (a lip: kept).
    rest = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [5.0, 0.0, 0.0]])
    t = np.linspace(0.0, 1.0, 6)[:, None]
    turn = np.stack([np.cos(t), np.sin(t), np.zeros_like(t)], axis=-1)[:, 0]  # (F, 3) unit directions
    rigid = np.stack([np.zeros((6, 3)), 0.1 * turn, np.tile(rest[2], (6, 1))], axis=1)
    apart = np.stack([np.zeros((6, 3)), rest[1] + 0.3 * t * [1.0, 0.0, 0.0], np.tile(rest[2], (6, 1))], axis=1)
    candidates, basis_of, share = np.array([0, 1, 2]), np.array([0, 1, 1]), np.array([0.7, 0.3])
    chosen, _ = choose_controls(candidates, basis_of, share, rest, 2, 0.5, in_place=rigid)
    assert chosen.tolist() == [0, 2]
    chosen, reasons = choose_controls(candidates, basis_of, share, rest, 2, 0.5, in_place=apart)
    assert chosen.tolist() == [0, 1] and "moves on its own" in reasons[1]
    chosen, _ = choose_controls(candidates, basis_of, share, rest, 2, 0.5)  # no frames: plain spacing
    assert chosen.tolist() == [0, 2]


def test_select_controls_user_vertices_and_option_errors():
    vertices, rest, peaks = two_mouths()
    user = select_controls(vertices, rest, user_vertices=[peaks[0], 3, 17])
    assert user.method == "user" and user.indices.tolist() == [peaks[0], 3, 17]
    assert "also a representative" in user.reasons[0] and "not one of" in user.reasons[1]
    assert user.warnings == []
    two = select_controls(vertices, rest, user_vertices=[1, 2])
    assert two.warnings and "3 non-collinear" in two.warnings[0]
    line = select_controls(vertices, rest, user_vertices=[0, 1, 2])  # three points on one grid line
    assert line.warnings and "collinear" in line.warnings[0]
    cases = [
        (dict(user_vertices=[1, 1000]), "vertex id 1000 is out of range"),
        (dict(user_vertices=[-1, 3]), "vertex id -1 is out of range"),
        (dict(user_vertices=[4, 4]), "vertex id 4 is given more than once"),
        (dict(user_vertices=[1, 2, 3], count=4), "--count 4 disagrees"),
        (dict(count=0), "--count must be at least 1"),
        (dict(components=0), "--components 0 is out of range"),
        (dict(components=30), "--components 30 is out of range"),
        (dict(components=3, count=4), "--components 3 is more than the 2 independent directions"),
    ]
    for kwargs, message in cases:
        with pytest.raises(OptionError, match=message.replace("(", r"\(")):
            select_controls(vertices, rest, **kwargs)
    with pytest.raises(OptionError, match="at least 3 example frames"):
        select_controls(vertices[:2], rest)
    rigid = np.einsum("fab,vb->fva", random_rotations(np.random.default_rng(1), 6), rest)
    with pytest.raises(OptionError, match="do not deform"):
        select_controls(rigid, rest)


# ---------------------------------------------------------------- the controls file


def test_controls_file_round_trip_with_utf8_reasons(tmp_path):
    vertices, rest, _ = two_mouths()
    selection = select_controls(vertices, rest, count=3)
    selection.reasons[0] += " — ≥ ünïcode"
    path = tmp_path / "c.h5"
    model = {"mesh": {"rest_vertices": rest, "faces": np.zeros((1, 3), np.int64)}}
    write_model(path, "controls", controls_groups(selection, None) | model, [], "test")
    with h5py.File(path, "r") as f:
        assert h5py.check_string_dtype(f["controls/reasons"].dtype).encoding == "utf-8"
        assert f["controls/vertex_indices"].dtype == np.int64 and f["controls/candidate_basis"].dtype == np.int32
    data = read_controls(path)
    assert data.reasons == selection.reasons
    np.testing.assert_array_equal(data.vertex_indices, selection.indices)
    np.testing.assert_array_equal(data.candidate_vertices, selection.candidates)
    np.testing.assert_array_equal(data.basis_variance, selection.basis_variance)
    assert (data.components, data.count, data.method) == (selection.components, 3, "auto")
    # Missing group or dataset: FormatError naming the problem.
    with pytest.raises(FormatError, match="without control points"):
        read_controls(path, {"stage": "skin", "provenance": []})
    broken = read_model(path)
    del broken["controls"]["reasons"]
    with pytest.raises(FormatError, match="/controls lacks reasons"):
        read_controls(path, broken)
    broken = read_model(path)
    broken["controls"]["vertex_indices"] = np.array([0, 5000, 2])
    with pytest.raises(FormatError, match="outside the mesh"):
        read_controls(path, broken)


# ---------------------------------------------------------------- the command line


@pytest.fixture(scope="module")
def skin(stage_files):
    """A skin file fitted to a small bending bar (tests must not modify it)."""
    return stage_files(frames=16, bones=3, iterations=3) / "skin.h5"


def test_cli_select_controls_happy_path(skin, tmp_path):
    out = tmp_path / "controls.h5"
    result = assert_ok(cli("select-controls", skin, "-o", out))
    lines = result.stdout.splitlines()
    assert len(lines) == 9 and all(line.startswith(f"control {i}: vertex ") for i, line in enumerate(lines[:8]))
    assert "% of variance): round 1" in lines[0]
    assert lines[-1].startswith(f"wrote {out}: 8 control points (auto)")
    assert result.stderr == ""
    summary = json.loads(assert_ok(cli("inspect", out, "--json")).stdout)
    assert summary["stage"] == "controls"
    assert [r["stage"] for r in summary["provenance"]] == ["skin", "controls"]
    data = read_controls(out)
    assert data.method == "auto" and data.count == 8 and len(set(data.vertex_indices.tolist())) == 8
    assert set(data.vertex_indices.tolist()) <= set(data.candidate_vertices.tolist())
    assert data.basis_variance.sum() <= 1.0 + 1e-12
    # /mesh, /examples and /skin are carried forward unchanged.
    before, after = read_model(skin), read_model(out)
    for group in ("mesh", "examples", "skin"):
        assert before[group].keys() == after[group].keys()
        for name, value in before[group].items():
            np.testing.assert_array_equal(after[group][name], value)
    # Deterministic: a second run chooses the same vertices in the same order.
    again = tmp_path / "again.h5"
    assert_ok(cli("select-controls", skin, "-o", again, "-q"))
    np.testing.assert_array_equal(read_controls(again).vertex_indices, data.vertex_indices)
    assert read_controls(again).reasons == data.reasons


def test_cli_select_controls_user_vertices(skin, tmp_path):
    out = tmp_path / "controls.h5"
    result = assert_ok(cli("select-controls", skin, "-o", out, "--vertices", "3, 40,77", "--count", 3))
    assert result.stdout.splitlines()[0].startswith("control 0: vertex 3, basis ")
    data = read_controls(out)
    assert data.method == "user" and data.vertex_indices.tolist() == [3, 40, 77]
    assert all(r.startswith("given by --vertices") for r in data.reasons)
    # Fewer than 3 controls: allowed, with a warning on stderr.
    few = tmp_path / "few.h5"
    result = assert_ok(cli("select-controls", skin, "-o", few, "--vertices", "3,40"))
    assert result.stderr.startswith("warning: only 2 control point(s)") and len(result.stderr.splitlines()) == 1
    assert few.exists()


def _short_skin(skin, path, frames):
    model = read_model(skin)
    for name in ("rotations", "translations", "dual_quaternions", "frame_rmse"):
        model["skin"][name] = model["skin"][name][:frames]
    model["examples"]["vertices"] = model["examples"]["vertices"][:frames]
    if "clip_frames" in model["examples"]:  # the clip table (issue 26) sums to the frames kept
        model["examples"]["clip_frames"] = np.array([frames], dtype=np.int64)
    write_model(path, "skin", {g: model[g] for g in ("mesh", "examples", "skin")}, model["provenance"], "test")


@pytest.mark.parametrize("args,needle", [
    (["--count", 40], "--count 40 but only"),
    (["--count", 0], "--count must be at least 1"),
    (["--vertices", "1,1000"], "vertex id 1000 is out of range"),
    (["--vertices", "5,5"], "vertex id 5 is given more than once"),
    (["--vertices", "1,2,3", "--count", 4], "--count 4 disagrees"),
    (["--vertices", "1,x"], "--vertices takes comma-separated integer"),
    (["--components", 0], "--components 0 is out of range"),
    (["--components", 99], "--components 99 is out of range"),
    (["--min-spacing", -1], "--min-spacing must not be negative"),
    (["WRONG_STAGE"], "this command needs a 'skin' file (from fit-skin)"),
    (["NOT_A_MODEL"], "not an HDF5 file"),
    (["TWO_FRAMES"], "at least 3 example frames"),
    (["BAD_SUFFIX"], "output must end in .h5"),
])
def test_cli_select_controls_errors(skin, tmp_path, args, needle):
    folder = tmp_path / "work"
    folder.mkdir()
    source, output = skin, folder / "controls.h5"
    keep = []
    if args == ["WRONG_STAGE"]:
        source = tmp_path / "first.h5"
        assert_ok(cli("select-controls", skin, "-o", source, "-q"))
        args = []
    elif args == ["NOT_A_MODEL"]:
        source = os.path.join(os.path.dirname(skin), "bar.npz")
        args = []
    elif args == ["TWO_FRAMES"]:
        source = folder / "short.h5"
        _short_skin(skin, source, 2)
        keep, args = ["short.h5"], []
    elif args == ["BAD_SUFFIX"]:
        output, args = folder / "controls.txt", []
    result = cli("select-controls", source, "-o", output, *args)
    detail = f"exit {result.exit_code}\nstdout: {result.stdout!r}\nstderr: {result.stderr!r}"
    assert isinstance(result.exception, SystemExit), detail + f"\n{result.exception!r}"
    assert result.exit_code == 2, detail
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("skinsynth: error: ") and needle in lines[0], detail
    assert result.stdout == "", detail
    assert sorted(os.listdir(folder)) == keep  # no output, no temporary file


def test_cli_select_controls_help_has_examples():
    text = assert_ok(cli("select-controls", "--help")).stdout
    assert "skinsynth select-controls face.skin.h5 -o face.controls.h5 --vertices" in text
    assert "no randomness" in " ".join(text.split())
