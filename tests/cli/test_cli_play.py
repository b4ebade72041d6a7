"""play from the command line: outputs read back with pxr / h5py, JSON report, bad input."""

import json
import os
import re
import subprocess
import sys

import h5py
import numpy as np
import pytest

from skinsynth.formats.exr import read_vat
from skinsynth.formats.puppet_file import read_puppet
from skinsynth.pipeline.puppet import puppet_from_record
from skinsynth.formats.usd import read_points_cache, read_skel_characters
from skinsynth.gpu import available_devices
from skinsynth.pipeline.puppet.puppet import predict_vertices

from cli_helpers import assert_folder_holds, assert_ok, assert_user_error, cli


@pytest.fixture(scope="module")
def files(stage_files, tmp_path_factory):
    stages = stage_files(frames=24, bones=4, iterations=8, cycles=2, controls=("--count", 6), puppet=())
    root = stages.copy_to(tmp_path_factory.mktemp("play"))  # plain.h5 beside them
    assert_ok(cli("train-kcca", root / "controls.h5", "-o", root / "plain.h5", "--no-translation-solver", "-q"))
    return root


def test_play_h5_matches_the_numpy_reference(files, tmp_path, device):
    report = json.loads(assert_ok(cli("play", files / "puppet.h5", "-c", files / "bar.npz", "-o",
                                      tmp_path / "v.h5", "--json", "--device", device)).stdout)
    assert report["frames"] == 24 and report["characters"] == 1
    assert report["seconds"] > 0 and report["frames_per_second"] > 0
    played = h5py.File(tmp_path / "v.h5")["vertices"][()]
    record, _, skin = read_puppet(files / "puppet.h5")
    puppet = puppet_from_record(record)
    expected = predict_vertices(puppet, skin.examples[:, puppet.control_indices])
    scale = np.ptp(skin.rest_vertices, axis=0).max()
    assert np.abs(played - expected).max() < 1e-5 * scale * 10  # float32 device arithmetic


def test_usd_skel_plays_back_the_same_vertices(files, tmp_path):
    assert_ok(cli("play", files / "puppet.h5", "-c", files / "bar.npz", "-o", tmp_path / "v.h5", "--device", "cpu"))
    assert_ok(cli("play", files / "puppet.h5", "-c", files / "bar.npz", "-o", tmp_path / "p.usdc"))
    played = h5py.File(tmp_path / "v.h5")["vertices"][()]
    (_, skinned), = read_skel_characters(tmp_path / "p.usdc")  # UsdSkel's own DQ skinning
    scale = np.ptp(played[0], axis=0).max()
    assert np.abs(skinned - played).max() < 1e-4 * scale


def test_instances_points_cache_and_exr(files, tmp_path):
    assert_ok(cli("play", files / "puppet.h5", "-c", files / "bar.npz", "-o", tmp_path / "c.h5", "--instances", 4))
    crowd = h5py.File(tmp_path / "c.h5")["vertices"][()]
    assert crowd.shape[:2] == (4, 24)
    # Copy i starts 24·i/4 frames later and stands on its own grid cell.
    spacing = 1.5 * np.ptp(crowd[0, 0], axis=0).max()
    assert np.allclose(crowd[1, 0] - crowd[0, 6], [spacing, 0, 0], atol=1e-3 * spacing)
    assert_ok(cli("play", files / "puppet.h5", "-c", files / "bar.npz", "-o", tmp_path / "c.usda", "--instances", 4,
                  "--as", "points"))
    vertices, _, _ = read_points_cache(tmp_path / "c.usda", prim="/characters/character_003")
    assert np.allclose(vertices, crowd[3], atol=1e-4)
    # Several textures: a folder, written whole (a Make rule's target is exactly the path given).
    assert_user_error(cli("play", files / "puppet.h5", "-c", files / "bar.npz", "-o", tmp_path / "t.exr",
                          "--instances", 2), "give a folder", f"-o {tmp_path / 't'}/")
    assert_ok(cli("play", files / "puppet.h5", "-c", files / "bar.npz", "-o", f"{tmp_path / 'vat'}/", "--instances", 2))
    assert sorted(os.listdir(tmp_path / "vat")) == [".skinsynth-folder.json", "character_000.exr", "character_000_normals.exr",
                                                    "character_001.exr", "character_001_normals.exr", "rest.glb",
                                                    "rest.obj", "vat.json"]
    offsets, meta = read_vat(tmp_path / "vat" / "character_001.exr")
    assert offsets.shape == (24, crowd.shape[2], 3) and meta["vat_frame_count"] == 24
    assert_ok(cli("play", files / "puppet.h5", "-c", files / "bar.npz", "-o", f"{tmp_path / 'vat'}/"))  # replaced
    assert "character_001.exr" not in os.listdir(tmp_path / "vat")
    assert not [n for n in os.listdir(tmp_path) if n.startswith(".")]


def test_several_control_files_and_csv(files, tmp_path):
    skin_vertices = np.load(files / "bar.npz")["vertices"]
    record, _, _ = read_puppet(files / "puppet.h5")
    puppet = puppet_from_record(record)
    controls = skin_vertices[:, puppet.control_indices]
    np.save(tmp_path / "a.npy", controls)
    rows = [(f, p, *controls[f, p]) for f in range(controls.shape[0]) for p in range(controls.shape[1])]
    (tmp_path / "b.csv").write_text("frame,point,x,y,z\n" + "".join(",".join(map(str, r)) + "\n" for r in rows))
    assert_ok(cli("play", files / "puppet.h5", "-c", tmp_path / "a.npy", "-c", tmp_path / "b.csv", "-o", tmp_path / "o.h5",
                  "--spacing", "0"))
    both = h5py.File(tmp_path / "o.h5")["vertices"][()]
    assert np.allclose(both[0], both[1], atol=1e-5)


def test_bad_inputs(files, tmp_path):
    np.save(tmp_path / "few.npy", np.zeros((5, 2, 3)))
    assert_user_error(cli("play", files / "puppet.h5", "-c", tmp_path / "few.npy", "-o", tmp_path / "o.h5"),
                      "few.npy", "2 control points per frame", "6", folder=tmp_path, keep=["few.npy"])
    bad = np.ones((5, 6, 3))
    bad[2, 3, 1] = np.nan
    np.save(tmp_path / "nan.npy", bad)
    assert_user_error(cli("play", files / "puppet.h5", "-c", tmp_path / "nan.npy", "-o", tmp_path / "o.h5"),
                      "nan.npy", "frame 2, point 3", folder=tmp_path, keep=["few.npy", "nan.npy"])
    assert_user_error(cli("play", files / "controls.h5", "-c", files / "bar.npz", "-o", tmp_path / "o.h5"),
                      "controls.h5", "train-kcca")
    assert_user_error(cli("play", files / "plain.h5", "-c", files / "bar.npz", "-o", tmp_path / "o.h5"),
                      "--no-translation-solver")
    assert_user_error(cli("play", files / "puppet.h5", "-c", files / "bar.npz", "-o", tmp_path / "o.obj"), ".usd")
    assert_user_error(cli("play", files / "puppet.h5", "-c", files / "bar.npz", "-o", tmp_path / "o.h5",
                          "--instances", 0), "--instances")
    assert_user_error(cli("play", files / "puppet.h5", "-c", files / "bar.npz", "-o", tmp_path / "o.h5",
                          "--device", "bogus"), "--device bogus")
    assert_folder_holds(tmp_path, ["few.npy", "nan.npy"])


@pytest.mark.skipif(any(d.startswith("cuda") for d in available_devices()), reason="a GPU is present")
def test_device_cuda_without_gpu_is_one_line(files, tmp_path):
    script = os.path.join(os.path.dirname(sys.executable), "skinsynth")
    run = subprocess.run([script, "play", str(files / "puppet.h5"), "-c", str(files / "bar.npz"), "-o",
                          str(tmp_path / "o.h5"), "--device", "cuda"], capture_output=True, text=True)
    assert run.returncode == 2
    assert run.stderr.strip().count("\n") == 0 and "no CUDA device" in run.stderr
    assert not os.listdir(tmp_path)


def test_help_names_both_skinnings_and_linear_by_default():
    # play once called every puppet dual-quaternion; linear is train-kcca's default, --skinning chooses
    text = re.sub(r"-\s+", "-", " ".join(assert_ok(cli("play", "--help")).stdout.split()))  # unwrapped
    assert "dual-quaternion skinning —" not in text and "UsdSkel with dual-quaternion skinning" not in text
    assert "linear blend unless it was trained with train-kcca --skinning dual-quaternion" in text
    assert "--skinning chooses" in text
    assert "linear unless asked otherwise" in text
