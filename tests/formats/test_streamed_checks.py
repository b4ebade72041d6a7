"""Checks and digests streamed block by block (issue 25): ``inspect`` on a 10⁴-animation cluster
output held 7.5 GB (every dataset read whole). Datasets larger than a block are now read a block
at a time (:mod:`skinsynth.formats.hdf5_storage`), with the verdicts, messages and digests of a
whole read, for every file."""

import h5py
import numpy as np
import pytest

from skinsynth.formats.errors import FormatError
from skinsynth.formats.hdf5_storage import DatasetSummary, block_selections, read_blocks
from skinsynth.formats.inspection import describe_model
from skinsynth.formats.model import content_digests, read_model

from cli_helpers import assert_ok, assert_user_error, cli


@pytest.mark.parametrize("shape", [(7, 3, 2), (3, 5, 4), (2, 0, 3), (5,), (4, 1000), (1, 1, 9)])
@pytest.mark.parametrize("block_bytes", [1, 8, 40, 10 ** 6])
def test_blocks_are_runs_of_the_array_in_c_order_within_the_block_size(shape, block_bytes):
    array = np.arange(int(np.prod(shape)), dtype=np.int64).reshape(shape)
    blocks = [array[selection] for selection in block_selections(shape, 8, block_bytes)]
    flat = np.concatenate([b.ravel() for b in blocks]) if blocks else np.zeros(0, np.int64)
    assert np.array_equal(flat, array.ravel())
    assert all(b.nbytes <= max(block_bytes, 8) for b in blocks)


def test_read_blocks_give_a_datasets_values_compressed_big_endian_or_strings(tmp_path):
    rng = np.random.default_rng(0)
    values = rng.normal(size=(5, 7, 3)).astype(">f4")
    with h5py.File(tmp_path / "d.h5", "w") as f:
        f.create_dataset("packed", data=values, chunks=(2, 3, 3), compression="gzip", shuffle=True)
        f.create_dataset("names", data=np.array([b"ab", b"cd", b"ef"]))
    with h5py.File(tmp_path / "d.h5") as f:
        for block_bytes in (4, 20, 100, 1 << 20):
            blocks = [b.copy() for b in read_blocks(f["packed"], block_bytes)]
            assert all(b.dtype == values.dtype for b in blocks)  # as stored: the bytes digests hash
            assert b"".join(b.tobytes() for b in blocks) == values.tobytes()
            assert b"".join(b.tobytes() for b in read_blocks(f["names"], block_bytes)) == b"abcdef"


def test_a_summary_has_what_the_checks_ask_of_an_array(tmp_path):
    values = np.arange(60, dtype=np.float32).reshape(5, 4, 3) - 7.0
    values[3, 2, 1] = np.inf
    with h5py.File(tmp_path / "d.h5", "w") as f:
        f["a"] = values
    with h5py.File(tmp_path / "d.h5") as f:
        summary = DatasetSummary(f["a"], 40)
    assert (summary.shape, summary.dtype, summary.ndim, summary.size, len(summary)) == ((5, 4, 3), np.float32, 3, 60, 5)
    assert summary.min() == values.min() and summary.max() == values.max() and not summary.all_finite()
    assert np.array_equal(np.asarray(summary), values)


@pytest.fixture(scope="module")
def synthesis(stage_files):
    """A synthesis file: motions (N, M, B, 3, 3) and (N, M, B, 3), sources (C, N, M)."""
    return stage_files(frames=40, bones=4, iterations=6, cycles=2, graph=(), synthesis=("-n", 6, "-m", 30))


def _damage(path, how):
    with h5py.File(path, "r+") as f:
        g = f["synthesis"]
        if how == "nan":
            g["bone_matrices"][4, 17, 2, 1, 0] = np.nan
        elif how == "inf":
            g["bone_translations"][5, 29, 3, 2] = -np.inf
        elif how == "sources below 0":
            sources = g["sources"][()]
            sources[-1, 3, 11] = -2
            g["sources"][...] = sources
        elif how == "sources past the clip":
            sources = g["sources"][()]
            sources[0, 5, 2] = 999
            g["sources"][...] = sources
        elif how == "nan and a bad source":  # the first check in order wins, as in a whole read
            g["bone_translations"][0, 0, 0, 0] = np.nan
            sources = g["sources"][()]
            sources[0, 0, 0] = -1
            g["sources"][...] = sources
        elif how == "a shape that disagrees":
            short = g["bone_translations"][:, :, :3]
            del g["bone_translations"]
            g.create_dataset("bone_translations", data=short)
        elif how == "seams below 0":
            g["seams"][2] = -5


def _verdict(path, **read):
    try:
        return describe_model(path, read_model(path, **read))
    except FormatError as error:
        return str(error)


@pytest.mark.parametrize("how", ["none", "nan", "inf", "sources below 0", "sources past the clip",
                                 "nan and a bad source", "a shape that disagrees", "seams below 0"])
def test_streamed_checks_give_the_verdict_of_a_whole_read(synthesis, tmp_path, how):
    path = tmp_path / "bones.h5"
    path.write_bytes((synthesis / "bones.h5").read_bytes())
    _damage(path, how)
    whole = _verdict(path)
    model = read_model(path, summarise_above=16)  # blocks of 16 bytes: every dataset in many
    if how != "a shape that disagrees":
        assert isinstance(model["synthesis"]["bone_matrices"], DatasetSummary)
        assert isinstance(model["synthesis"]["sources"], DatasetSummary)
    assert _verdict(path, summarise_above=16) == whole
    assert (how == "none") == isinstance(whole, dict), whole
    if how == "none":
        assert_ok(cli("inspect", path, "-q"))
    else:  # the command (blocks of 64 MiB) says the same
        assert_user_error(cli("inspect", path, "-q"), whole)


def test_digests_in_blocks_are_the_digests_of_whole_rows(synthesis):
    path = synthesis / "bones.h5"
    assert content_digests(path, block_bytes=7) == content_digests(path, block_bytes=1 << 30) == content_digests(path)
