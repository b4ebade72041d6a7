import numpy as np
import pytest

from skinsynth.formats.errors import FormatError
from skinsynth.formats.meshseq import write_array_sequence
from skinsynth.formats.trajectories import read_control_trajectories

CONTROLS = np.array([1, 3])


def write_csv(path, rows, header="frame,point,x,y,z"):
    path.write_text(header + "\n" + "".join(",".join(str(v) for v in row) + "\n" for row in rows))
    return path


def test_csv_any_order(tmp_path):
    rows = [(1, 1, 7, 8, 9), (0, 0, 1, 2, 3), (1, 0, 4, 5, 6), (0, 1, 0, 0, 1)]
    out = read_control_trajectories(write_csv(tmp_path / "c.csv", rows), 2, CONTROLS, 5)
    assert out.shape == (2, 2, 3)
    assert np.array_equal(out[1, 1], [7, 8, 9]) and np.array_equal(out[0, 0], [1, 2, 3])


def test_npy_and_mesh_sequence(tmp_path):
    data = np.random.default_rng(0).normal(size=(4, 2, 3))
    np.save(tmp_path / "c.npy", data)
    assert np.array_equal(read_control_trajectories(tmp_path / "c.npy", 2, CONTROLS, 5), data)
    vertices = np.random.default_rng(1).normal(size=(3, 5, 3))
    write_array_sequence(tmp_path / "m.npz", vertices, np.array([[0, 1, 2], [2, 3, 4]]), 24.0)
    assert np.array_equal(read_control_trajectories(str(tmp_path / "m.npz"), 2, CONTROLS, 5), vertices[:, CONTROLS])


@pytest.mark.parametrize("rows,needle", [
    ([(0, 0, 1, 2, 3)], "frame 0, point 1 is missing"),
    ([(0, 0, 1, 2, 3), (0, 0, 1, 2, 3), (0, 1, 1, 1, 1)], "given twice"),
    ([(0, 0, 1, 2, 3), (0, 2, 1, 2, 3)], "point 2 does not exist"),
    ([(0, 0, 1, 2, 3), (0, 1, "nan", 1, 1)], "non-finite"),
    ([(0.5, 0, 1, 2, 3)], "integers"),
    ([(0, 0, 1, 2)], "5 columns"),
])
def test_bad_csv(tmp_path, rows, needle):
    with pytest.raises(FormatError, match=needle):
        read_control_trajectories(write_csv(tmp_path / "c.csv", rows), 2, CONTROLS, 5)


def test_bad_inputs(tmp_path):
    with pytest.raises(FormatError, match="header"):
        read_control_trajectories(write_csv(tmp_path / "h.csv", [], header="a,b"), 2, CONTROLS, 5)
    np.save(tmp_path / "three.npy", np.zeros((4, 3, 3)))
    with pytest.raises(FormatError, match="3 control points per frame, but the puppet has 2"):
        read_control_trajectories(tmp_path / "three.npy", 2, CONTROLS, 5)
    with pytest.raises(FormatError, match="no such file"):
        read_control_trajectories(tmp_path / "none.npy", 2, CONTROLS, 5)
    write_array_sequence(tmp_path / "other.npz", np.zeros((3, 7, 3)), np.array([[0, 1, 2]]), 24.0)
    with pytest.raises(FormatError, match="7 vertices per frame"):
        read_control_trajectories(str(tmp_path / "other.npz"), 2, CONTROLS, 5)


@pytest.mark.parametrize("name", ["session.csv", "session.npy"])
def test_a_written_trajectory_reads_back_exactly(tmp_path, name):
    from skinsynth.formats.trajectories import read_control_trajectories, write_control_trajectories

    controls = np.random.default_rng(5).normal(size=(7, 3, 3)) * 1e3
    write_control_trajectories(tmp_path / name, controls)
    assert np.array_equal(read_control_trajectories(tmp_path / name, 3, [0, 1, 2], 10), controls)
    with pytest.raises(ValueError):
        write_control_trajectories(tmp_path / "session.txt", controls)
    with pytest.raises(ValueError):
        write_control_trajectories(tmp_path / "missing" / name, controls)
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]
