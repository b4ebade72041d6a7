"""run_batches' page policy (pipeline.runtime.execution.small_pages): its batches' large arrays ask no huge
pages, in this process and in the workers it forks, and numpy's setting is restored after."""

import numpy as np
import pytest

from skinsynth.pipeline.runtime import execution

try:
    from numpy._core import multiarray
except ImportError:  # numpy 1.x
    from numpy.core import multiarray

toggle = getattr(multiarray, "_set_madvise_hugepage", None)
pytestmark = pytest.mark.skipif(toggle is None, reason="this numpy has no huge-page setting")


def _pages_asked(batch, count):
    """A batch that reports numpy's huge-page setting where it runs (set it back as it found it)."""
    setting = toggle(True)
    toggle(setting)
    return [np.zeros((count, 1), np.float32), setting]


def test_batches_ask_no_huge_pages_here_or_in_workers_and_the_setting_comes_back(monkeypatch):
    monkeypatch.delenv("NUMPY_MADVISE_HUGEPAGE", raising=False)
    before = toggle(True)
    try:
        for jobs in (1, 2):
            _, rests = execution.run_batches(_pages_asked, (), [(0, 2), (1, 3)], jobs, [(5, 1)])
            assert [rest[0] for rest in rests] == [False, False]
            assert toggle(True) is True  # restored after
    finally:
        toggle(before)


def test_the_environment_decides_when_set(monkeypatch):
    monkeypatch.setenv("NUMPY_MADVISE_HUGEPAGE", "1")
    before = toggle(True)
    try:
        with execution.small_pages():
            assert toggle(True) is True
    finally:
        toggle(before)
