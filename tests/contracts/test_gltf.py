"""glTF 2.0 export (issue 23): Khronos glTF-Validator finds no error in any .glb skinsynth writes,
and three.js (GLTFLoader, AnimationMixer, CPU skinning) plays every clip to skinsynth's own LBS.

The JavaScript clients are installed by ``make setup`` into tests/contracts/js/node_modules."""

import json

import h5py
import numpy as np
import pytest

from skinsynth.gpu import lbs

from cli_helpers import assert_ok, assert_user_error, cli
from glb_reading import glb_accessor, glb_document
from gltf_clients import in_gltf_axes, skin_of, skip_without_clients, three_positions, validate

skip_without_clients()


@pytest.fixture(scope="module")
def files(stage_files, tmp_path_factory):
    stages = stage_files(frames=40, bones=4, iterations=6, cycles=2, graph=())
    root = stages.copy_to(tmp_path_factory.mktemp("gltf"))
    assert_ok(cli("synthesize", root / "graph.h5", "-o", root / "bones.h5", "-n", 4, "-m", 30, "--seed", 3, "-q"))
    # the same clip recorded Z up in centimetres: glTF's axes and metres come from the conversion
    assert_ok(cli("fit-skin", root / "bar.npz", "-o", root / "zup.h5", "--bones", 4, "--iterations", 4,
                  "--up-axis", "Z", "--meters-per-unit", 0.01, "-q"))
    return root


CASES = {  # name: (export arguments after the input, the input)
    "skin fit": ([], "skin.h5"),
    "synthesis, three clips": (["--animation", "0:3"], "bones.h5"),
    "weights 8 bits": (["--quantize", 8], "skin.h5"),
    "weights 16 bits": (["--quantize", 16, "--animation", 1, "--animation", 3], "bones.h5"),
    "Z up, centimetres": ([], "zup.h5"),
    "root motion": (["--animation", "0:2", "--root-motion"], "bones.h5"),
    "root motion, Z up": (["--root-motion"], "zup.h5"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_every_glb_is_valid_and_three_js_plays_it_as_skinsynth_skins_it(files, tmp_path, case):
    extra, source = CASES[case]
    out = tmp_path / "out.glb"
    summary = json.loads(assert_ok(cli("export", files / source, "-o", out, "--json", *extra)).stdout)
    report = validate(out)
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]
    skin = skin_of(files / source)
    if source == "bones.h5":
        with h5py.File(files / source) as f:
            motions = [(f["synthesis/bone_matrices"][a], f["synthesis/bone_translations"][a])
                       for a in summary["animations"]]
    else:
        motions = [(skin.rotations, skin.translations)]
    count = motions[0][0].shape[0]
    frames = [0, count // 2, count - 1]
    played, names = three_positions(out, skin.fps, frames, tmp_path)
    assert names == summary["names"] and played.shape[:2] == (len(motions), 3)
    truth_rest = in_gltf_axes(skin.rest_vertices, skin.scene)
    diagonal = np.linalg.norm(np.ptp(truth_rest, axis=0))
    for clip, (rotations, translations) in enumerate(motions):
        truth = in_gltf_axes(lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights,
                                 np.asarray(rotations, np.float64), np.asarray(translations, np.float64),
                                 device="cpu")[frames], skin.scene)
        tolerance = 1e-5 if "bits" not in case else 3e-3  # quantised weights move vertices by their rounding
        assert np.abs(played[clip] - truth).max() <= tolerance * diagonal, (case, clip)


JOINTED_CASES = {"jointed": ("skin.h5", []), "free bones": ("free.h5", []),
                 "Z up cm, root motion": ("zup.h5", ["--root-motion"])}


@pytest.mark.parametrize("case", list(JOINTED_CASES))
def test_the_glb_of_a_jointed_skin_is_valid_and_three_js_plays_its_tree_as_skinsynth_skins_it(jointed_skins,
                                                                                               tmp_path, case):
    """fit-skin --skeleton: the joints nested as the skeleton's tree (tests/cli/test_cli_skeleton_exports.py
    checks the nesting), no validator error or warning, and three.js's skinning of the nested
    joints is skinsynth's LBS."""
    source, extra = JOINTED_CASES[case]
    out = tmp_path / "out.glb"
    assert_ok(cli("export", jointed_skins / source, "-o", out, "-q", *extra))
    report = validate(out)
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]
    skin = skin_of(jointed_skins / source)
    document, _ = glb_document(out)
    assert any("children" in document["nodes"][n] for n in document["skins"][0]["joints"][1:])  # nested
    frames = [0, len(skin.rotations) // 2, len(skin.rotations) - 1]
    played, _ = three_positions(out, skin.fps, frames, tmp_path)
    truth = in_gltf_axes(lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations,
                             skin.translations, device="cpu")[frames], skin.scene)
    diagonal = np.linalg.norm(np.ptp(in_gltf_axes(skin.rest_vertices, skin.scene), axis=0))
    error = np.abs(played[0] - truth).max() / diagonal
    assert error <= 1e-5, (case, error)


def test_with_root_motion_the_root_travels_on_the_ground_and_without_it_stays(files, tmp_path):
    for flag in ([], ["--root-motion"]):
        out = tmp_path / f"root{len(flag)}.glb"
        assert_ok(cli("export", files / "bones.h5", "--animation", 0, "-o", out, "-q", *flag))
        document, binary = glb_document(out)
        root = document["skins"][0]["skeleton"]
        assert document["nodes"][root]["name"] == "root" and len(document["scenes"][0]["nodes"]) == 2
        channels = [c for c in document["animations"][0]["channels"] if c["target"]["node"] == root]
        assert len(channels) == (2 if flag else 0)
        for c in channels:
            if c["target"]["path"] == "translation":
                sampler = document["animations"][0]["samplers"][c["sampler"]]
                accessor = document["accessors"][sampler["output"]]
                view = document["bufferViews"][accessor["bufferView"]]
                travel = np.frombuffer(binary, np.float32, 3 * accessor["count"],
                                       view["byteOffset"] + accessor.get("byteOffset", 0)).reshape(-1, 3)
                assert np.abs(travel[:, 1]).max() < 1e-6 and np.abs(travel[:, [0, 2]]).max() > 0  # on the ground


def test_quantised_weights_sum_exactly_to_one_and_name_no_joint_at_zero(files, tmp_path):
    for bits, dtype in ((8, np.uint8), (16, np.uint16)):
        out = tmp_path / f"q{bits}.glb"
        assert_ok(cli("export", files / "skin.h5", "-o", out, "--quantize", bits, "-q"))
        document, binary = glb_document(out)
        attributes = document["meshes"][0]["primitives"][0]["attributes"]

        def read(index, width, kind):
            accessor = document["accessors"][index]
            view = document["bufferViews"][accessor["bufferView"]]
            start = view["byteOffset"] + accessor.get("byteOffset", 0)
            return np.frombuffer(binary, kind, accessor["count"] * width, start).reshape(-1, width)

        weights = read(attributes["WEIGHTS_0"], 4, dtype)
        joints = read(attributes["JOINTS_0"], 4, np.uint8)
        assert (weights.astype(np.int64).sum(axis=1) == (1 << bits) - 1).all()
        assert (joints[weights == 0] == 0).all()
        assert (np.diff(weights.astype(np.int64), axis=1) <= 0).all()  # heaviest first


@pytest.mark.parametrize("args, needles", [
    (["--quantize", 7], ["--quantize"]),
    (["--quantize", 8, "-o", "{out}/a.usdc"], ["--quantize is for .glb"]),
    (["--animation", 9], ["--animation 9", "animations 0..3"]),
    (["--animation", 1, "--root-motion", "-o", "{out}/a.usdc", "--as", "points"], ["--root-motion", "--as points"]),
], ids=["quantize 7", "quantize to usd", "animation out of range", "root motion of points"])
def test_bad_gltf_requests_are_one_line(files, tmp_path, args, needles):
    if "-o" not in args:
        args = args + ["-o", "{out}/a.glb"]
    args = [a.replace("{out}", str(tmp_path)) if isinstance(a, str) else a for a in args]
    assert_user_error(cli("export", files / "bones.h5", *args), *needles, folder=tmp_path)


def test_more_influences_than_gltf_carries_are_refused(files, tmp_path):
    assert_ok(cli("fit-skin", files / "bar.npz", "-o", tmp_path / "wide.h5", "--bones", 8, "--max-influences", 8,
                  "--iterations", 6, "-q"))
    with h5py.File(tmp_path / "wide.h5") as f:
        widest = int((f["skin/bone_weights"][()] > 0).sum(axis=1).max())
    out = tmp_path / "out"
    out.mkdir()
    if widest <= 4:
        pytest.skip("this fit happened to keep at most 4 influences per vertex")
    assert_user_error(cli("export", tmp_path / "wide.h5", "-o", out / "a.glb"), "glTF carries 4",
                      "--max-influences 4", folder=out)


@pytest.mark.parametrize("flag", [[], ["--root-motion"]], ids=["fixed root", "root motion"])
def test_synthesize_writes_the_glb_export_writes_of_its_file(files, tmp_path, flag):
    """synthesize --gltf at run time and export afterwards give the same bytes (one writer)."""
    assert_ok(cli("synthesize", files / "graph.h5", "-o", tmp_path / "b.h5", "-n", 3, "-m", 20, "--seed", 5,
                  "--gltf", tmp_path / "run.glb", "-q", *flag))
    assert_ok(cli("export", tmp_path / "b.h5", "-o", tmp_path / "later.glb", "-q", *flag))
    assert (tmp_path / "run.glb").read_bytes() == (tmp_path / "later.glb").read_bytes()
    assert validate(tmp_path / "run.glb")["errors"] == 0


def test_synthesize_root_motion_needs_a_gltf_output(files, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    assert_user_error(cli("synthesize", files / "graph.h5", "-o", out / "b.h5", "-n", 3, "-m", 20, "--root-motion"),
                      "--root-motion", "--gltf", folder=out)
    assert_user_error(cli("synthesize", files / "graph.h5", "-o", out / "b.h5", "-n", 3, "-m", 20, "--gltf",
                          out / "b.usdc"), "must end in .glb", folder=out)


#: The test bar's stage recipe up to its controls, for the puppets below.
BAR_PUPPET = dict(frames=40, bones=4, iterations=6, cycles=2, controls=("--count", 4))


@pytest.fixture(scope="module")
def puppets(stage_files, tmp_path_factory):
    """A puppet of the test bar without correctives (a glTF rig)."""
    stages = stage_files(**BAR_PUPPET, puppet=("--correctives", "off"))
    return stages.copy_to(tmp_path_factory.mktemp("puppets"))


def test_a_played_linear_puppet_as_gltf_is_what_play_computes(puppets, tmp_path):
    args = ["play", puppets / "puppet.h5", "-c", puppets / "bar.npz", "--instances", 2, "--spacing", 0,
            "--skinning", "linear", "-q"]
    assert_ok(cli(*args, "-o", tmp_path / "played.glb"))
    assert_ok(cli(*args, "-o", tmp_path / "played.h5"))
    report = validate(tmp_path / "played.glb")
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]
    with h5py.File(tmp_path / "played.h5") as f:
        vertices, fps = f["vertices"][()], float(f.attrs["fps"])
    frames = [0, vertices.shape[1] // 2, vertices.shape[1] - 1]
    played, names = three_positions(tmp_path / "played.glb", fps, frames, tmp_path)
    assert names == ["character_000", "character_001"]
    skin = skin_of(puppets / "puppet.h5")
    truth = in_gltf_axes(vertices[:, frames], skin.scene)
    diagonal = np.linalg.norm(np.ptp(in_gltf_axes(skin.rest_vertices, skin.scene), axis=0))
    assert np.abs(played - truth).max() <= 1e-5 * diagonal


def test_a_played_puppets_correctives_are_morph_targets_three_js_plays_as_play_computes(stage_files, tmp_path):
    """A linear puppet with pose-space correctives: at most 8 principal components as ± pairs of
    morph targets weighted in [0, 1] (at most one of a pair active), a weights channel per clip,
    and three.js (morph influences before CPU skinning) at play's own vertices."""
    from skinsynth.formats.meshseq import read_played_characters

    stages = stage_files(**BAR_PUPPET, puppet=("--skinning", "linear", "--correctives", "1e-3"))
    args = ["play", stages / "puppet.h5", "-c", stages / "bar.npz", "--instances", 2, "--spacing", 0]
    summary = json.loads(assert_ok(cli(*args, "-o", tmp_path / "played.glb", "--json")).stdout)
    assert_ok(cli(*args, "-o", tmp_path / "played.h5", "-q"))
    report = validate(tmp_path / "played.glb")
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]
    document, binary = glb_document(tmp_path / "played.glb")
    mesh, components = document["meshes"][0], summary["morph_targets"]
    count = 2 * components
    assert 1 <= components <= 8 and summary["morph_target_error"] <= 1e-6
    assert len(mesh["primitives"][0]["targets"]) == count and mesh["weights"] == [0.0] * count
    assert mesh["extras"]["targetNames"] == [f"corrective_{i}{s}" for i in range(components) for s in "pn"]
    targets = np.stack([glb_accessor(document, binary, t["POSITION"]) for t in mesh["primitives"][0]["targets"]])
    blends = []
    for animation in document["animations"]:
        sampler, = [animation["samplers"][c["sampler"]] for c in animation["channels"]
                    if c["target"] == {"node": 0, "path": "weights"}]  # the mesh node's
        assert document["accessors"][sampler["output"]]["count"] == \
            document["accessors"][sampler["input"]]["count"] * count  # glTF 2.0 §3.11
        blends.append(glb_accessor(document, binary, sampler["output"]).reshape(-1, count))
        assert blends[-1].min() >= 0.0 and blends[-1].max() <= 1.0  # Blender clamps to [0, 1]
        assert np.all(np.minimum(blends[-1][:, 0::2], blends[-1][:, 1::2]) == 0.0)  # one of each pair
    names, vertices, _, fps = read_played_characters(tmp_path / "played.h5")
    frames = [0, vertices.shape[1] // 2, vertices.shape[1] - 1]
    played, clips = three_positions(tmp_path / "played.glb", fps, frames, tmp_path)
    assert clips == list(names) == ["character_000", "character_001"]
    skin = skin_of(stages / "puppet.h5")
    truth = in_gltf_axes(vertices[:, frames], skin.scene)
    diagonal = np.linalg.norm(np.ptp(in_gltf_axes(skin.rest_vertices, skin.scene), axis=0))
    assert np.abs(played - truth).max() <= 1e-5 * diagonal
    moved = np.abs(np.einsum("fk,kc->fc", np.concatenate(blends), targets.reshape(count, -1))).max()
    assert moved > 1e-3 * diagonal  # the correctives matter: without their targets three.js would be far off


def test_a_played_puppet_to_gltf_must_skin_linearly_and_have_few_correctives(puppets, tmp_path):
    """A dual-quaternion puppet, and correctives that need more than 8 morph targets (a noisy bar:
    every training frame's residual its own shape), are one line each, naming what to use."""
    from skinsynth.formats.meshseq import write_array_sequence
    from skinsynth.pipeline.inputs.examples import bending_bar

    out = tmp_path / "out"
    out.mkdir()
    assert_ok(cli("train-kcca", puppets / "controls.h5", "-o", tmp_path / "dual.h5", "--skinning", "dual-quaternion",
                  "--correctives", "off", "-q"))
    assert_user_error(cli("play", tmp_path / "dual.h5", "-c", puppets / "bar.npz", "-o", out / "p.glb"),
                      "glTF skins linearly", "train-kcca --skinning linear", folder=out)
    vertices, faces = bending_bar(frames=40, rings=10, segments=8, cycles=2)
    noisy = vertices + 0.02 * np.random.default_rng(1).standard_normal(vertices.shape)
    write_array_sequence(tmp_path / "noisy.npz", noisy, faces, 24.0)
    assert_ok(cli("fit-skin", tmp_path / "noisy.npz", "-o", tmp_path / "skin.h5", "--bones", 4, "--iterations", 6,
                  "-q"))
    assert_ok(cli("select-controls", tmp_path / "skin.h5", "-o", tmp_path / "controls.h5", "--count", 4, "-q"))
    assert_ok(cli("train-kcca", tmp_path / "controls.h5", "-o", tmp_path / "noisy.h5", "--skinning", "linear",
                  "--correctives", "1e-3", "-q"))
    assert_user_error(cli("play", tmp_path / "noisy.h5", "-c", tmp_path / "noisy.npz", "-o", out / "p.glb"),
                      "corrective shapes need", "morph targets", "8 leave", "--correctives off", "-o X.usdc",
                      folder=out)


@pytest.mark.slow
def test_a_real_take_played_on_the_samba_as_gltf_is_valid_and_three_js_plays_it(samba_marker_puppet, shared_data,
                                                                                 tmp_path):
    """Issue 37: the samba puppet driven by the real take with its 145-frame gap, as .glb."""
    folder, _ = samba_marker_puppet
    take = shared_data / "mocap_c3d" / "kinematics_tennis_serve_nan.c3d"
    for out in ("take.glb", "take.h5"):  # --no-ik: a glTF skin carries bones, not the deformation the skeleton
        # path adds to the points beyond the examples (docs/mocap.md)
        assert_ok(cli("play", folder / "puppet.h5", "-c", take, "-o", tmp_path / out, "-q", "--no-ik"))
    report = validate(tmp_path / "take.glb")
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]
    with h5py.File(tmp_path / "take.h5") as f:
        vertices, fps = f["vertices"][()][None], float(f.attrs["fps"])  # one character: (1, F, V, 3)
    frames = [0, vertices.shape[1] // 2, vertices.shape[1] - 1]
    played, _ = three_positions(tmp_path / "take.glb", fps, frames, tmp_path)
    skin = skin_of(folder / "puppet.h5")
    truth = in_gltf_axes(vertices[:, frames], skin.scene)
    diagonal = np.linalg.norm(np.ptp(in_gltf_axes(skin.rest_vertices, skin.scene), axis=0))
    assert np.abs(played - truth).max() <= 1e-5 * diagonal
