"""Shared test set-up: warp's kernel cache in a per-run folder, and where the real data lives."""

import os
import pathlib

import pytest

SHARED_DATA = pathlib.Path(__file__).resolve().parents[1].parent / "shared" / "data"


def pytest_configure(config):
    # Before any test imports warp: keep compiled kernels out of the user's cache folder.
    os.environ.setdefault("SKINSYNTH_CACHE_DIR", str(pathlib.Path(config.rootpath) / "build" / "test-warp-cache"))
    # Commands keep Python's warning filters, so the suite's "every warning is an error" reaches
    # them in-process, and a command run as a process prints any warning it meets (tests then see
    # more than one stderr line).
    os.environ["SKINSYNTH_WARNINGS"] = "1"


@pytest.fixture(scope="session")
def shared_data():
    """The real sequences in ../shared/data; skips the test when they are not there."""
    if not SHARED_DATA.is_dir() or not any(SHARED_DATA.iterdir()):
        pytest.skip(f"real data not found at {SHARED_DATA} (read-only folder beside the checkout)")
    return SHARED_DATA


# The warp devices of the kernel tests: a test taking ``device`` runs once per device here.
import functools  # noqa: E402 (this block stands alone)


@functools.cache
def _warp_devices():
    """["cpu"], plus "cuda:0" where warp sees a GPU (warp is imported on the first call only)."""
    from skinsynth.gpu import available_devices

    return ["cpu"] + (["cuda:0"] if "cuda:0" in available_devices() else [])


def pytest_generate_tests(metafunc):
    if "device" in metafunc.fixturenames:
        metafunc.parametrize("device", _warp_devices(), indirect=True)


@pytest.fixture
def device(request):
    """A warp device name, "cpu" or "cuda:0": each kernel test runs on every one present."""
    return request.param
