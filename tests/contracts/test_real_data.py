"""Slow tests on the real sequences in ../shared/data (skipped, with the reason, when absent)."""

import numpy as np
import pytest

from skinsynth.formats.errors import FormatError
from skinsynth.formats.meshseq import read_mesh_sequence
from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.mesh.geometry import bounding_box_diagonal
from skinsynth.pipeline.skin.skin_fit import fit_skin

pytestmark = pytest.mark.slow


def _sequences(root):
    for folder in sorted(p for p in root.iterdir() if p.is_dir()):
        for spec in [folder] + sorted(folder.rglob("*")):
            if spec.is_dir() or spec.suffix.lower() in (".usd", ".usda", ".usdc", ".npz", ".h5"):
                try:
                    yield folder.name, read_mesh_sequence(str(spec))
                    break
                except FormatError:
                    continue


def test_real_sequences_fit_with_valid_weights(shared_data):
    """Every shared capture's first 24 frames, 12 bones, 4 iterations: weights valid, RMSE under
    5 % of the diagonal (measured at most 0.45 %, the horse gallop)."""
    fitted = 0
    for name, seq in _sequences(shared_data):
        frames = seq.vertices[: min(len(seq.vertices), 24)]
        fit = fit_skin(frames, bones=12, iterations=4)
        recon = lbs_reference(fit.rest_vertices, fit.bone_indices, fit.bone_weights, fit.rotations, fit.translations)
        rmse = np.sqrt(np.mean(np.sum((recon - frames) ** 2, axis=2))) / bounding_box_diagonal(frames[0])
        assert np.all(fit.bone_weights >= 0) and np.allclose(fit.bone_weights.sum(axis=1), 1.0), name
        assert fit.rotations.shape[1] == 12, name
        assert rmse < 0.05, f"{name}: RMSE/diag {rmse:.4f}"
        fitted += 1
    assert fitted > 0, f"no readable sequence under {shared_data}"


def _read(shared_data, name):
    path = shared_data / name / f"{name}.npz"
    if not path.exists():
        pytest.skip(f"{path} is absent")
    return read_mesh_sequence(str(path))


@pytest.fixture(scope="module")
def samba_fit(shared_data, tmp_path_factory):
    """The samba fitted with 22 bones in 10 iterations, once per run (both modes of the seams
    test read it): a dict of the fit's arrays."""
    from shared_builds import built_once, run_folder

    seq = _read(shared_data, "vlasic_samba")

    def fit(folder):
        found = fit_skin(seq.vertices, bones=22, iterations=10, seed=0)
        np.savez(folder / "fit.npz", **{k: getattr(found, k) for k in FIT_ARRAYS})

    built_once(tmp_path_factory, "samba_fit_10", fit)
    with np.load(run_folder(tmp_path_factory) / "samba_fit_10" / "fit.npz") as arrays:
        return seq, {k: arrays[k] for k in FIT_ARRAYS}


FIT_ARRAYS = ("rest_vertices", "bone_indices", "bone_weights", "rotations", "translations")


@pytest.mark.parametrize("single", [False, True])
def test_samba_synthesis_has_no_visible_seams_and_plays_the_whole_clip(samba_fit, single):
    """The capture where the issue measured 16.9× the input's acceleration at seams (multi-component):
    200 walks of 600 frames play at least 90 % of the clip, and the first 10, skinned (about 500
    seams), accelerate at most 1.5× the input's largest (measured 0.69× in both modes, on the
    first 50 as on the first 10 and 20)."""
    from skinsynth.gpu import lbs
    from skinsynth.pipeline.mesh.geometry import frame_accelerations
    from skinsynth.pipeline.synthesis.graph import build_graph
    from skinsynth.pipeline.synthesis.synthesis import Request, synthesize

    seq, fit = samba_fit
    rest, idx, w, R, t = (fit[k] for k in FIT_ARRAYS)
    graph = build_graph(rest, seq.faces, idx, w, R, t, single_component=single)
    assert all(len(c.transitions.pairs) <= 60 for c in graph.components)  # tens, not hundreds
    result = synthesize(graph.components, R, t, rest, idx, w, Request(count=200, frames=600, seed=3), jobs=2)
    assert min(result.statistics["coverage"]) >= 0.9
    assert min(result.statistics["shortest_segment"]) >= 6  # half of 12: a walk leaving a loop (motion_graph)
    largest = np.nanmax(frame_accelerations(seq.vertices))
    worst = max(np.nanmax(frame_accelerations(lbs(rest, idx, w, result.F[a], result.t[a]))) for a in range(10))
    assert worst <= 1.5 * largest, f"worst acceleration {worst / largest:.2f}× the input's"


def test_horse_stays_on_the_ground_over_long_animations(shared_data):
    from skinsynth.gpu import lbs
    from skinsynth.pipeline.synthesis.graph import build_graph
    from skinsynth.pipeline.synthesis.synthesis import Request, synthesize

    seq = _read(shared_data, "horse_gallop")
    fit = fit_skin(seq.vertices, bones=22, iterations=10, seed=0)
    graph = build_graph(fit.rest_vertices, seq.faces, fit.bone_indices, fit.bone_weights, fit.rotations,
                        fit.translations)
    result = synthesize(graph.components, fit.rotations, fit.translations, fit.rest_vertices, fit.bone_indices,
                        fit.bone_weights, Request(count=3, frames=3000, seed=0), jobs=1)
    lowest_in = seq.vertices[..., 1].min(axis=1)
    height = np.ptp(fit.rest_vertices[:, 1])
    for a in range(3):
        lowest = lbs(fit.rest_vertices, fit.bone_indices, fit.bone_weights, result.F[a], result.t[a])[..., 1].min(axis=1)
        assert lowest.min() >= lowest_in.min() - 0.05 * height and lowest.max() <= lowest_in.max() + 0.05 * height


def test_horse_puppet_beats_its_baselines_and_plays_as_evaluated(shared_data):
    """The horse gallop is one cycle twice: with repeat-aware cross-validation the puppet is the
    lowest of evaluate's rows at every:4 and every:10 and within 0.8× the PCA baseline (before: 1.39×
    and 0.81×), and play's float32 device path matches the float64 reference (before: 1.7e-3)."""
    from skinsynth.gpu import DevicePuppet, run_puppet
    from skinsynth.pipeline.puppet.controls import select_controls
    from skinsynth.pipeline.puppet.evaluation import evaluate_puppet
    from skinsynth.pipeline.puppet.playback import host_inputs
    from skinsynth.pipeline.puppet.puppet import parse_frame_spec, predict_vertices, train_puppet

    seq = _read(shared_data, "horse_gallop")
    fit = fit_skin(seq.vertices, bones=22, iterations=30, seed=0)
    controls = select_controls(seq.vertices, fit.rest_vertices, count=8).indices
    frames = seq.vertices.shape[0]
    for spec in ("every:4", "every:10"):
        train = parse_frame_spec(spec, frames)
        puppet = train_puppet(seq.vertices, fit.rest_vertices, seq.faces, fit.bone_indices, fit.bone_weights,
                              fit.rotations, fit.translations, controls, train)
        errors = evaluate_puppet(puppet, seq.vertices, np.setdiff1d(np.arange(frames), train)).overall
        assert min(errors, key=errors.get) == "kcca", (spec, errors)
        assert errors["kcca"] <= 0.8 * errors["pca_blendshape"], (spec, errors)
    played = np.empty(seq.vertices.shape, dtype=np.float32)
    run_puppet(DevicePuppet(puppet, "cpu"), *host_inputs(puppet, seq.vertices[:, controls]), out=played,
               skinning=puppet.skinning)
    reference = predict_vertices(puppet, seq.vertices[:, controls])
    assert np.abs(played - reference).max() < 1e-5 * bounding_box_diagonal(fit.rest_vertices)


def test_samba_feet_stay_planted_as_the_dancer_plants_them(samba_skin, tmp_path):
    """Issue 35 on the real dancer, as a user runs it (fit-skin, build-graph, synthesize --json,
    its "contact" figures against the input): single-component walks slide about as the input
    does (measured on these 16 animations, the limbs reaching by their joints: 0.55× median,
    1.00× p95, 1.11× share, since walks no longer take a drawn transition back into a loop they
    replay, issue 63; 0.53×, 0.94×, 1.01× before; 0.73× away from the 4.7 % of contact steps where a limb could not
    hold its foot, 18 % of which slide), no animation accelerates beyond 1.25× the input's largest (0.94× with
    components, 0.83× single), the feet stay on the floor (penetration p95 0.12 % of the height
    with components, whose first 8 animations are measured: the feet's measure costs four times the
    synthesis), and no frame is broken (issue 62: ``--json``'s "shape")."""
    import json

    from cli_helpers import assert_ok, cli

    figures = {}
    for mode, measured in (("components", 8), ("single", 16)):  # the slide figures on 16; the bounds on 8
        extra = ["--single-component"] if mode == "single" else []
        assert_ok(cli("build-graph", samba_skin, "-o", tmp_path / f"{mode}.graph.h5", "-q", *extra))
        result = cli("synthesize", tmp_path / f"{mode}.graph.h5", "-o", tmp_path / f"{mode}.h5", "-n", 16, "-m", 600,
                     "--seed", 0, "--measure-feet", measured, "--json")
        assert_ok(result)
        summary = json.loads(result.stdout)
        figures[mode] = summary["contact"]
        assert summary["shape"]["broken_frames"] == 0 and summary["shape"]["worst_frame"] < 0.02, summary["shape"]
    single = figures["single"]["ratios"]
    assert single["slide_median"] <= 0.8 and single["slide_p95"] <= 1.15 and single["sliding_share"] <= 1.25, single
    # the steps sliding beyond the input's share are where a limb could not hold its foot (its joints
    # at their range, or a turn cut to keep the skin: issue 62); away from them, fewer slide than in the input
    limits, output = figures["single"]["limits"], figures["single"]["output"]
    away = ((output["sliding_share"] - limits["contact_steps"] * limits.get("sliding_share", 0.0))
            / (1.0 - limits["contact_steps"]))
    assert away <= 0.9 * figures["single"]["input"]["sliding_share"], (away, limits)
    for mode, found in figures.items():
        assert found["ratios"]["largest_accel"] <= 1.25, (mode, found["ratios"])
        assert found["output"]["penetration_p95"] <= 0.002, (mode, found["output"])


def test_the_dancers_body_stays_whole_under_its_plants_and_its_contact_sheet_renders(dancer_graph, tmp_path):
    """Issue 62 as a user meets it: Zheng's dancer (four components) synthesized at the defaults,
    its plants on, and a contact sheet of it rendered (``preview``). Before the limbs turned at their
    joints, the plants broke the dancer's body in 69 % of its frames (a torso torn across the chest,
    a head twisted on its neck) and 21 % of one frame's edges were strained past anything the capture
    shows; now no frame is broken (``synthesize --json``'s "shape", docs/contact.md), and the feet
    stay planted better than with the plants off."""
    import json

    from PIL import Image

    from cli_helpers import assert_ok, cli

    out = tmp_path / "dance.h5"
    result = cli("synthesize", dancer_graph, "-o", out, "-n", 4, "-m", 300, "--seed", 3, "--measure-feet", 4, "--json")
    assert_ok(result)
    summary = json.loads(result.stdout)
    shape = summary["shape"]
    assert shape["frames"] == 1200 and shape["broken_frames"] == 0 and shape["worst_frame"] < 0.02, shape
    off = cli("synthesize", dancer_graph, "-o", tmp_path / "off.h5", "-n", 4, "-m", 300, "--seed", 3, "--measure-feet",
              4, "--json", "--no-contact")
    assert_ok(off)
    off_contact = json.loads(off.stdout)["contact"]
    assert summary["contact"]["output"]["slide_median"] < 0.5 * off_contact["output"]["slide_median"]
    # where a limb could not hold its foot, the report says how often and how much it slid there
    # (these four: limbs at their range in 44 % of the frames, turns cut in 2.6 %); without plants, nothing
    limits = summary["contact"]["limits"]
    assert 0.1 < limits["held_frames"] < 0.9 and 0.0 < limits["cut_frames"] < 0.2, limits
    assert 0.0 < limits["contact_steps"] < 1.0 and limits["slide_median"] > 0.0, limits
    assert "limits" not in off_contact
    sheet = tmp_path / "sheet.png"
    assert_ok(cli("preview", out, "-o", sheet, "--animation", 0, "--sheet-frames", 8, "--size", "160x200"))
    with Image.open(sheet) as image:
        assert image.size == (4 * 160, 2 * 200)
        pixels = np.asarray(image.convert("L"), dtype=np.float64)
    assert pixels.std() > 10.0  # a picture, not a blank sheet


def test_horse_gallop_skeleton_is_one_tree_of_joints_inside_the_horse_that_hold(horse_skeleton):
    """fit-skin --skeleton on the 22-bone gallop (issue: joints and a hierarchy, Le & Deng 2014): one
    root; every joint inside the mesh (winding number), drifting at most 2 % of the diagonal on the
    free fit; the jointed rig within 1.5x the free fit's error (measured 1.37x); the hind hooves
    at least 3 joints from the root (a horse's shoulder is no joint, docs/skeleton.md); every joint
    held by the refitted bones. The bones with no fixed joint (the
    forelegs' tops) slide on a neighbour, within the travel reported: none hangs free from the root.
    The four legs, the neck and the tail are named by what they are (issues 44, 65)."""
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.mesh.geometry import points_inside
    from skinsynth.pipeline.rig.influence import bone_centroids
    from skinsynth.pipeline.rig.skeleton import slide_offsets

    path, summary = horse_skeleton
    summary = summary["skeleton"]
    skin = read_skin(path)
    parents, jointed, joints = (skin.skeleton[k] for k in ("parents", "jointed", "joints"))
    assert (parents < 0).sum() == 1 and summary["rmse_over_free"] <= 1.5
    sliding = skin.skeleton["sliding"]
    assert points_inside(joints[jointed | sliding], skin.rest_vertices, skin.faces).all()
    assert skin.skeleton["drift"][jointed].max() <= 0.02 and skin.skeleton["drift"][sliding].min() > 0.02
    assert summary["free_bones"] == 0 and [s["bone"] for s in summary["sliding"]] == np.flatnonzero(sliding).tolist()
    slides = slide_offsets(skin.rotations, skin.translations, parents, joints, np.flatnonzero(sliding))
    assert (slides >= skin.skeleton["slide_low"][sliding] - 1e-12).all()
    assert (slides <= skin.skeleton["slide_high"][sliding] + 1e-12).all()
    diagonal = bounding_box_diagonal(skin.rest_vertices)
    for bone in np.flatnonzero(jointed):
        p = parents[bone]
        gap = (np.einsum("fxy,y->fx", skin.rotations[:, bone] - skin.rotations[:, p], joints[bone])
               + skin.translations[:, bone] - skin.translations[:, p])
        assert np.abs(gap).max() < 1e-9 * diagonal
    centres = bone_centroids(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.bones)
    # the horse faces +z: its ears are its highest point (z +0.6; its raised tail reaches further, to
    # z −1.34, and tops out 0.2 lower): docs/skeleton.md, preview --camera side shows the head at +z
    assert skin.rest_vertices[np.argmax(skin.rest_vertices[:, 1]), 2] > 0.3
    hind = [b for b in range(skin.bones) if b not in parents and centres[b, 1] < 0.15 * np.ptp(skin.rest_vertices[:, 1])
            + skin.rest_vertices[:, 1].min() and centres[b, 2] < 0.0]
    assert hind
    for bone in hind:
        count = 0
        while parents[bone] >= 0:
            count, bone = count + int(jointed[bone]), parents[bone]
        assert count >= 3
    # its four legs named from the geometry alone: the front ones at its head's end (+z, ahead of both
    # hind legs), the left ones at +x (left = up × forward: y × z), the neck at the head's end and the
    # tail at the other, the root in the trunk between the legs (issue 65: before, the hind legs were
    # named its forelegs, its tail its neck, and its root was its head)
    names = skin.skeleton["names"]
    ahead = {}
    for leg in ("leg_front_l", "leg_front_r", "leg_back_l", "leg_back_r", "neck", "tail"):
        bones = [b for b, name in enumerate(names) if name.startswith(leg + "_")]
        assert bones, (leg, names)
        ahead[leg] = centres[bones, 2].mean()
        assert leg in ("neck", "tail") or (centres[bones, 0].mean() > 0) == leg.endswith("_l")
    assert min(ahead["leg_front_l"], ahead["leg_front_r"]) > max(ahead["leg_back_l"], ahead["leg_back_r"])
    assert ahead["neck"] > 0.3 > -0.3 > ahead["tail"]
    assert max(ahead["leg_back_l"], ahead["leg_back_r"]) < centres[skin.skeleton["root"], 2] < ahead["neck"]
    # the horse mirrored in x: the same bones named with the other side
    from skinsynth.pipeline.rig.chain_labels import chain_labels

    mirror = np.array([-1.0, 1.0, 1.0])
    mirrored = chain_labels(parents, joints * mirror, skin.rest_vertices * mirror, skin.bone_indices, skin.bone_weights,
                            1, skin.examples * mirror, jointed=jointed)
    assert mirrored == [n.replace("_l_", "_x_").replace("_r_", "_l_").replace("_x_", "_r_") for n in names]


def test_horse_gallop_fitted_under_its_own_skeleton_as_usdskel_keeps_tree_names_and_error(shared_data, horse_skeleton,
                                                                                          tmp_path):
    """--skeleton FROM.usd on the horse (issue: a skeleton given): its found skeleton exported as
    UsdSkel, then the gallop fitted under it: the same tree, free bones and joint names, the error
    within 1.1x the found rig's (measured 1.04x)."""
    from cli_helpers import assert_ok, cli
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.rig.skeleton import bone_names

    gallop = shared_data / "horse_gallop" / "horse_gallop.npz"
    found_path, _ = horse_skeleton
    assert_ok(cli("export", found_path, "-o", tmp_path / "rig.usda", "-q"))
    assert_ok(cli("fit-skin", gallop, "-o", tmp_path / "given.h5", "--skeleton", tmp_path / "rig.usda", "-q"))
    found, given = read_skin(found_path), read_skin(tmp_path / "given.h5")

    def tree(skin):
        names = bone_names(skin.skeleton)
        return {(names[b], names[p] if p >= 0 else None, bool(j))
                for b, (p, j) in enumerate(zip(skin.skeleton["parents"], skin.skeleton["jointed"]))}

    assert tree(given) == tree(found)
    assert given.rmse <= 1.1 * found.rmse


@pytest.mark.parametrize("capture", ["samba", "crane", "dancer", "horse"])
def test_a_captures_skeleton_mirrored_or_turned_keeps_its_tree_and_root_and_swaps_its_sides(capture, request):
    """Issue 65: rules that hold on every character hold on its mirror image and however it faces.
    The skeleton found on a capture's free fit (joints, tree, the root hung from the hips, the chains
    named), then on the same fit mirrored in x and turned 40° about the up axis: the same tree and
    root; mirrored, every left name a right one and back; turned, the same names. The horse is its
    gallop and its collapse fitted together: its four legs found in the frames it stands in (lying,
    it touches the floor with its side)."""
    from skinsynth.formats.graph_file import read_graph
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.rig.chain_labels import chain_labels
    from skinsynth.pipeline.rig.rotations import rotation_exp
    from skinsynth.pipeline.skin.joints import find_skeleton, hung_from_centre

    if capture == "dancer":
        skin = read_graph(str(request.getfixturevalue("dancer_graph"))).skin
    else:
        skin = read_skin(request.getfixturevalue(f"{capture}_skin") if capture in ("samba", "crane")
                         else request.getfixturevalue("horse_clips")[1])

    def found(transform, faces):
        rest, frames = skin.rest_vertices @ transform.T, skin.examples @ transform.T
        R = transform @ skin.rotations.astype(np.float64) @ transform.T
        t = skin.translations.astype(np.float64) @ transform.T
        tree = find_skeleton(rest, faces, skin.bone_indices, skin.bone_weights, R, t)
        tree, _ = hung_from_centre(tree, tree.drift, rest, skin.bone_indices, skin.bone_weights, frames)
        return tree, chain_labels(tree.parents, tree.joints, rest, skin.bone_indices, skin.bone_weights, 1, frames,
                                  jointed=tree.jointed)

    tree, names = found(np.eye(3), skin.faces)
    limbs = ("leg_front_l", "leg_front_r", "leg_back_l", "leg_back_r") if capture == "horse" else \
        ("leg_l", "leg_r", "arm_l", "arm_r")
    assert names is not None and {f"{limb}_01" for limb in limbs} <= set(names)
    mirrored, mirrored_names = found(np.diag([-1.0, 1.0, 1.0]), skin.faces[:, ::-1])
    turned, turned_names = found(rotation_exp(np.array([0.0, 0.7, 0.0])), skin.faces)
    for other in (mirrored, turned):
        assert other.parents.tolist() == tree.parents.tolist() and other.root == tree.root
    assert mirrored_names == [n.replace("_l_", "_x_").replace("_r_", "_l_").replace("_x_", "_r_") for n in names]
    assert turned_names == names
