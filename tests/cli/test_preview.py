"""skinsynth preview: every kind of file renders to .mp4, .gif and .png; bad input is one line."""

import json

import imageio_ffmpeg
import numpy as np
import pytest
import trimesh
from PIL import Image

from cli_helpers import assert_ok, assert_user_error, cli

SMALL = ("--size", "96x64")


@pytest.fixture(scope="module")
def files(stage_files, tmp_path_factory):
    stages = stage_files(frames=24, bones=4, iterations=8, cycles=2, controls=("--count", 6), puppet=(),
                         graph=("--min-segment", 4))
    root = stages.copy_to(tmp_path_factory.mktemp("preview"))  # every other kind of file beside them
    vertices, faces = stages.vertices, stages.faces
    (root / "frames").mkdir()
    for f in range(6):
        trimesh.Trimesh(vertices[f], faces, process=False).export(root / "frames" / f"bar_{f}.obj")
    assert_ok(cli("synthesize", root / "graph.h5", "-o", root / "bones.h5", "-n", 3, "-m", 30, "--crowd",
                  root / "crowd.usda", "--device", "cpu", "-q"))
    assert_ok(cli("play", root / "puppet.h5", "-c", root / "bar.npz", "-o", root / "played.h5", "--instances", 2,
                  "--device", "cpu", "-q"))
    assert_ok(cli("play", root / "puppet.h5", "-c", root / "bar.npz", "-o", root / "played.usda", "-q"))
    assert_ok(cli("export", root / "skin.h5", "-o", root / "points.usdc", "--as", "points", "-q"))
    return root


CASES = [  # (input, extra options, panels, frames)
    ("bar.npz", (), 1, 24),
    ("frames", (), 1, 6),
    ("points.usdc", (), 1, 24),
    ("played.h5", (), 2, 24),
    ("played.usda", (), 1, 24),
    ("crowd.usda", (), 3, 30),
    ("skin.h5", (), 1, 24),
    ("skin.h5", ("--examples",), 1, 24),
    ("skin.h5", ("--compare",), 2, 24),
    ("graph.h5", ("--compare",), 2, 24),
    ("puppet.h5", (), 2, None),
    ("bones.h5", ("--animation", 0, "--animation", 2), 2, 30),
    ("bones.h5", ("--animation", "0:2"), 2, 30),  # a range, as export takes (issue 68)
]


@pytest.mark.parametrize("name, options, panels, frames", CASES)
def test_every_kind_of_file_renders(files, tmp_path, name, options, panels, frames):
    out = tmp_path / "p.mp4"
    summary = json.loads(assert_ok(cli("preview", files / name, "-o", out, *SMALL, *options, "--json")).stdout)
    assert summary["panels"] == panels
    if frames is not None:
        assert summary["frames"] == frames
    written, _ = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert written == summary["frames"]


def test_gif_and_contact_sheet(files, tmp_path):
    assert_ok(cli("preview", files / "bones.h5", "-o", tmp_path / "a.gif", *SMALL, "--frames", "5:15", "-q"))
    with Image.open(tmp_path / "a.gif") as gif:
        assert gif.n_frames == 10 and gif.size == (96, 64)
    assert_ok(cli("preview", files / "skin.h5", "-o", tmp_path / "s.png", *SMALL, "--compare", "--sheet-frames", 6,
                  "--camera", "front", "--flat", "-q"))
    with Image.open(tmp_path / "s.png") as sheet:  # 6 frames of 2 panels, 2 frames per row
        assert sheet.size == (2 * 2 * 96, 3 * 64)


def test_a_synthesis_marks_its_seams(files, tmp_path):
    """The caption of a frame at a seam is red; no other caption is."""
    import h5py

    with h5py.File(files / "bones.h5") as f:
        sources = f["synthesis/sources"][()][:, 0]
    seams = np.flatnonzero(np.any(sources[:, 1:] != sources[:, :-1] + 1, axis=0)) + 1
    assert seams.size
    assert_ok(cli("preview", files / "bones.h5", "-o", tmp_path / "a.gif", "--size", "240x120", "-q"))
    with Image.open(tmp_path / "a.gif") as gif:
        reddish = []
        for m in range(gif.n_frames):
            gif.seek(m)
            corner = np.asarray(gif.convert("RGB"))[:30, :120].astype(int)
            reddish.append(bool(np.any((corner[..., 0] > 150) & (corner[..., 1] < 80) & (corner[..., 2] < 80))))
    assert np.flatnonzero(reddish).tolist() == seams.tolist()


@pytest.mark.parametrize("args, needles", [
    (("missing.npz", "-o", "o.mp4"), ("missing.npz", "no such file")),
    (("bar.npz", "-o", "o.avi"), ("o.avi", ".mp4")),
    (("bones.h5", "-o", "o.mp4", "--animation", 3), ("--animation 3", "0..2")),
    (("bar.npz", "-o", "o.mp4", "--animation", 0), ("--animation", "synthesis")),
    (("bar.npz", "-o", "o.mp4", "--compare"), ("--compare", "skin")),
    (("bar.npz", "-o", "o.mp4", "--frames", "30:40"), ("--frames", "none of the 24")),
    (("bar.npz", "-o", "o.mp4", "--size", "10x10"), ("--size", "WIDTHxHEIGHT")),
    (("bones.h5", "-o", "o.mp4", "--examples"), ("--examples", "skin")),
])
def test_bad_input_is_one_line_and_writes_nothing(files, tmp_path, args, needles):
    args = [files / a if a in ("missing.npz", "bar.npz", "bones.h5") else tmp_path / a if str(a).startswith("o.") else a
            for a in args]
    assert_user_error(cli("preview", *args), *needles, folder=tmp_path)
