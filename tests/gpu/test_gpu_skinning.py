"""skinsynth.gpu: warp LBS on every warp device against its numpy reference, the reference against a
plain loop, devices, and warp imported only where kernels are."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from skinsynth.gpu import DeviceError, available_devices, lbs, lbs_reference, resolve_device
from skinsynth.gpu import runtime, skinning
from skinsynth.gpu.references import skinning as skinning_reference

from rigs import random_skin


@pytest.fixture(scope="session", autouse=True)
def warp_cache(tmp_path_factory):
    """Keep test kernels out of the user's cache; must be set before warp is first initialised."""
    folder = str(tmp_path_factory.mktemp("warp-cache"))
    old = os.environ.get("SKINSYNTH_CACHE_DIR")
    os.environ["SKINSYNTH_CACHE_DIR"] = folder
    yield folder
    if old is None:
        os.environ.pop("SKINSYNTH_CACHE_DIR", None)
    else:
        os.environ["SKINSYNTH_CACHE_DIR"] = old


def random_rig(rng, verts, bones, frames, influences, rigid=True):
    rest, idx, w = random_skin(rng, verts, bones, influences, offset=3.0)
    mats = rng.normal(size=(frames, bones, 3, 3))
    if rigid:
        q, r = np.linalg.qr(mats)
        mats = q * np.sign(np.diagonal(r, axis1=-2, axis2=-1))[..., None, :]
        mats *= np.sign(np.linalg.det(mats))[..., None, None]
    trans = rng.normal(size=(frames, bones, 3)) * 2.0
    return rest, idx, w, mats, trans


def relative_error(a, b):
    scale = np.linalg.norm(b.reshape(-1, 3).max(axis=0) - b.reshape(-1, 3).min(axis=0))
    return np.abs(a - b).max() / scale


@pytest.mark.parametrize("influences", [1, 2, 3, 4])
def test_warp_matches_reference(influences, device):
    rig = random_rig(np.random.default_rng(influences), 700, 13, 6, influences)
    expected = lbs_reference(*rig)
    got = lbs(*rig, device=device)
    assert got.shape == (6, 700, 3) and got.dtype == np.float64
    assert relative_error(got, expected) < 1e-5


def test_affine_bones_and_frame_chunks(monkeypatch, device):
    rig = random_rig(np.random.default_rng(7), 50, 5, 7, 4, rigid=False)
    expected = lbs_reference(*rig)
    monkeypatch.setattr(skinning, "_DEVICE_CHUNK", 3 * 50 + 1)  # chunks of 3, 3, 1 frames
    monkeypatch.setattr(skinning_reference, "_REFERENCE_CHUNK", 2 * 9 * 50)  # chunks of 2 frames
    assert relative_error(lbs(*rig, device=device), expected) < 1e-5
    np.testing.assert_allclose(lbs_reference(*rig), expected, rtol=0, atol=1e-12)


def test_reference_matches_brute_force_loop():
    rest, idx, w, mats, trans = random_rig(np.random.default_rng(3), 6, 4, 3, 3, rigid=False)
    expected = np.zeros((3, 6, 3))
    for f in range(3):
        for i in range(6):
            for k in range(3):
                if w[i, k] != 0.0:
                    b = idx[i, k]
                    expected[f, i] += w[i, k] * (mats[f, b] @ rest[i] + trans[f, b])
    np.testing.assert_allclose(lbs_reference(rest, idx, w, mats, trans), expected, rtol=1e-12, atol=1e-12)


def test_identity_pose_returns_rest(device):
    rest, idx, w, _, _ = random_rig(np.random.default_rng(4), 20, 3, 2, 2)
    mats = np.broadcast_to(np.eye(3), (2, 3, 3, 3))
    got = lbs(rest, idx, w, mats, np.zeros((2, 3, 3)), device=device)
    np.testing.assert_allclose(got, np.broadcast_to(rest, (2, 20, 3)), atol=1e-5)


def test_bad_inputs():
    rest, idx, w, mats, trans = random_rig(np.random.default_rng(5), 10, 3, 2, 2)
    idx[0, 0], w[0, 0] = 3, 0.5
    for fn in (lbs, lbs_reference):
        with pytest.raises(ValueError, match=r"\[0, 3\)"):
            fn(rest, idx, w, mats, trans)
        with pytest.raises(ValueError, match="translations"):
            fn(rest, idx, w, mats, trans[:, :2])
    assert lbs(rest, idx % 3, w, mats[:0], trans[:0]).shape == (0, 10, 3)


def test_devices():
    assert resolve_device("cpu") == "cpu"
    assert "cpu" in available_devices()
    has_cuda = any(d.startswith("cuda") for d in available_devices())
    assert resolve_device("auto") == ("cuda:0" if has_cuda else "cpu")
    assert resolve_device() == resolve_device("auto")
    with pytest.raises(DeviceError, match="unknown device"):
        resolve_device("bogus")
    with pytest.raises(DeviceError, match=r"cuda:99"):
        resolve_device("cuda:99")
    if not has_cuda:
        with pytest.raises(DeviceError, match=r"^--device cuda: no CUDA device is available \(warp found only cpu\)$"):
            resolve_device("cuda")
        with pytest.raises(DeviceError):
            lbs(*random_rig(np.random.default_rng(6), 4, 2, 1, 1), device="cuda")


def test_stderr_restored_when_init_fails(capfd):
    with pytest.raises(RuntimeError):
        with runtime._stderr_to_devnull():
            os.write(2, b"hidden")
            raise RuntimeError("init failed")
    os.write(2, b"shown")
    assert capfd.readouterr().err == "shown"


def run_python(code, **env):
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        env={**os.environ, **env},
        check=True,
    )


def test_import_does_not_import_warp():
    """Only gpu/kernels/ imports warp (through runtime.warp()): the package, every public name and
    every launcher and reference module import without it."""
    done = run_python(
        """
        import importlib, pathlib, sys
        import skinsynth.gpu
        from skinsynth.gpu import lbs, lbs_reference, resolve_device, DeviceError, available_devices
        assert "warp" not in sys.modules, "importing skinsynth.gpu imported warp"
        for name in skinsynth.gpu.__all__:
            getattr(skinsynth.gpu, name)
        root = pathlib.Path(skinsynth.gpu.__file__).parent
        for path in sorted(root.rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            if parts[0] != "kernels" or parts == ("kernels", "__init__"):
                importlib.import_module(".".join(("skinsynth.gpu",) + parts).removesuffix(".__init__"))
                assert "warp" not in sys.modules, f"importing {path.name} imported warp"
        print(sorted(name for name in sys.modules if name.split(".")[0] == "warp"))
        """
    )
    assert done.stdout == b"[]\n"  # no warp module loaded, not merely no top-level "warp"


def test_first_use_is_quiet_and_uses_cache_dir(warp_cache):
    done = run_python(
        """
        import os
        import numpy as np
        from skinsynth.gpu import lbs
        lbs(np.zeros((2, 3)), np.zeros((2, 1), int), np.ones((2, 1)), np.zeros((1, 1, 3, 3)), np.zeros((1, 1, 3)))
        os.write(2, b"fd 2 restored")
        """,
        SKINSYNTH_CACHE_DIR=warp_cache,
    )
    assert done.stdout == b""
    assert done.stderr == b"fd 2 restored"
    assert any("lbs_kernel" in name for _, dirs, _ in os.walk(warp_cache) for name in dirs)
