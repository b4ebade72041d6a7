"""write_synthesis_plot: a valid PNG of the right shape, seams and over-limit frames drawn, bad input refused."""

import os

import matplotlib.colors
import matplotlib.image
import numpy as np
import pytest
from matplotlib.collections import LineCollection, PathCollection
from matplotlib.figure import Figure

from skinsynth.formats import plots
from skinsynth.formats.errors import FormatError
from skinsynth.formats.plots import write_synthesis_plot

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _animation(count):
    """sources (count, length): runs of consecutive input frames with a jump every 17 + 5c frames."""
    length = 60
    sources = np.empty((count, length), dtype=np.int64)
    for c in range(count):
        period = 17 + 5 * c
        k = np.arange(length)
        sources[c] = 3 * c + k % period + 40 * (k // period)
    accel = 0.8 + 0.5 * np.sin(np.arange(length) / 4.0) ** 2
    accel[[10, 25]] = [2.0, 3.5]
    accel[[0, -1]] = np.nan
    accel[30] = np.nan
    return sources, accel


def _expected_seams(sources):
    return [set(np.flatnonzero(row[1:] != row[:-1] + 1) + 1) for row in sources]


@pytest.fixture
def saved_figures(monkeypatch):
    """The Figure objects passed to plots._save, which still writes them."""
    figures = []
    real_save = plots._save

    def spy(figure, path):
        figures.append(figure)
        real_save(figure, path)

    monkeypatch.setattr(plots, "_save", spy)
    return figures


@pytest.mark.parametrize("count", [1, 3])
def test_writes_a_valid_png_of_the_right_aspect(tmp_path, count):
    sources, accel = _animation(count)
    assert all(seams for seams in _expected_seams(sources))
    path = tmp_path / "synthesis.png"
    write_synthesis_plot(path, sources, accel, f"{count} components")
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    assert len(data) > 10_000
    image = matplotlib.image.imread(path)
    height, width = image.shape[:2]
    assert image.ndim == 3 and width > 600
    assert width / height == pytest.approx(10.0 / 6.0, rel=0.02)
    assert os.listdir(tmp_path) == ["synthesis.png"]


@pytest.mark.parametrize("count", [1, 3])
def test_draws_components_seams_limit_and_frames_above_it(tmp_path, saved_figures, count):
    sources, accel = _animation(count)
    write_synthesis_plot(tmp_path / "s.png", sources, accel, "the title", limit=1.5)
    (figure,) = saved_figures
    top, bottom = figure.axes
    assert top.get_shared_x_axes().joined(top, bottom)
    assert top.get_title() == "the title"
    assert top.get_ylabel() == "input frame"
    assert bottom.get_xlabel() == "output frame"
    assert bottom.get_ylabel() == "max acceleration / input's"

    steps = top.get_lines()
    assert [line.get_label() for line in steps] == [f"component {c}" for c in range(count)]
    for c, line in enumerate(steps):
        np.testing.assert_array_equal(line.get_ydata(), sources[c])
    dots = [collection for collection in top.collections if isinstance(collection, PathCollection)]
    assert len(dots) == count
    for c, (line, collection, seams) in enumerate(zip(steps, dots, _expected_seams(sources))):
        offsets = collection.get_offsets()
        assert set(offsets[:, 0].astype(int)) == seams
        np.testing.assert_array_equal(offsets[:, 1], sources[c, offsets[:, 0].astype(int)])
        np.testing.assert_allclose(collection.get_facecolor()[0], matplotlib.colors.to_rgba(line.get_color()))
    assert (top.get_legend() is not None) == (count > 1)

    legend = bottom.get_legend()
    assert legend is not None
    texts = [text.get_text() for text in legend.get_texts()]
    assert "input's largest" in texts
    assert "limit 1.5×" in texts
    references = {line.get_ydata()[0]: line for line in bottom.get_lines()
                  if line.get_label() in ("input's largest", "limit 1.5×")}
    assert set(references) == {1.0, 1.5}
    assert references[1.5].get_linestyle() == "--"
    (red,) = [line for line in bottom.get_lines() if line.get_marker() == "o"]
    np.testing.assert_array_equal(red.get_xdata(), [10, 25])
    assert matplotlib.colors.same_color(red.get_color(), "red")
    (vertical,) = [collection for collection in bottom.collections if isinstance(collection, LineCollection)]
    seam_frames = sorted(set().union(*_expected_seams(sources)))
    assert sorted(int(segment[0, 0]) for segment in vertical.get_segments()) == seam_frames


def test_no_seams_and_nothing_over_the_limit_still_plots(tmp_path, saved_figures):
    sources = np.arange(5, 25)[None, :]
    accel = np.full(20, 0.5)
    accel[[0, -1]] = np.nan
    write_synthesis_plot(tmp_path / "calm.png", sources, accel, "calm", limit=2)
    (figure,) = saved_figures
    top, bottom = figure.axes
    assert all(len(collection.get_offsets()) == 0 for collection in top.collections)
    assert not [line for line in bottom.get_lines() if line.get_marker() == "o"]
    assert "limit 2×" in [text.get_text() for text in bottom.get_legend().get_texts()]
    assert (tmp_path / "calm.png").read_bytes()[:8] == PNG_SIGNATURE


def test_refuses_bad_requests(tmp_path):
    sources, accel = _animation(2)
    with pytest.raises(ValueError, match="png"):
        write_synthesis_plot(tmp_path / "s.pdf", sources, accel, "t")
    with pytest.raises(ValueError, match="png"):
        write_synthesis_plot(tmp_path / "s", sources, accel, "t")
    with pytest.raises(ValueError, match="2-D|\\(C, M\\)"):
        write_synthesis_plot(tmp_path / "s.png", sources[0], accel, "t")
    with pytest.raises(ValueError, match="2-D|\\(C, M\\)"):
        write_synthesis_plot(tmp_path / "s.png", np.zeros((0, 60), dtype=int), accel, "t")
    with pytest.raises(ValueError, match="accel_ratio"):
        write_synthesis_plot(tmp_path / "s.png", sources, accel[:-1], "t")
    with pytest.raises(ValueError, match="accel_ratio"):
        write_synthesis_plot(tmp_path / "s.png", sources, accel[None, :], "t")
    with pytest.raises(ValueError, match="integer"):
        write_synthesis_plot(tmp_path / "s.png", sources + 0.5, accel, "t")
    assert os.listdir(tmp_path) == []


def test_a_missing_folder_raises_and_creates_nothing(tmp_path):
    sources, accel = _animation(1)
    target = tmp_path / "absent" / "s.png"
    with pytest.raises(FormatError, match="does not exist"):
        write_synthesis_plot(target, sources, accel, "t")
    assert not target.parent.exists()
    assert os.listdir(tmp_path) == []


def test_a_write_that_fails_midway_leaves_no_file(tmp_path, monkeypatch):
    sources, accel = _animation(3)
    path = tmp_path / "s.png"
    path.write_bytes(b"old")

    def broken_savefig(self, target, **kwargs):
        with open(target, "wb") as handle:
            handle.write(PNG_SIGNATURE + b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(Figure, "savefig", broken_savefig)
    with pytest.raises(OSError, match="disk full"):
        write_synthesis_plot(path, sources, accel, "t")
    assert os.listdir(tmp_path) == ["s.png"]
    assert path.read_bytes() == b"old"
