"""The memory and disk refusals (pipeline/runtime/resources.py): the estimate against what there is."""

import shutil

import pytest

from skinsynth.pipeline.errors import OptionError
from skinsynth.pipeline.runtime.resources import check_memory, check_space


def test_the_memory_and_disk_checks_compare_the_estimate_with_what_there_is(tmp_path):
    check_memory(2 ** 30, "a request", available=2 ** 31)  # fits: nothing said
    with pytest.raises(OptionError, match=r"a request needs about 2\.0 GiB of memory, and 1\.0 GiB is available"):
        check_memory(2 ** 31, "a request", available=2 ** 30)
    with pytest.raises(OptionError, match="GiB of disk in"):
        check_space("a request", [(None, 2 ** 60, str(tmp_path))])
    with pytest.raises(OptionError, match=r"needs about 5\.0 MiB of memory, and 1\.0 MiB is available"):
        check_memory(5 * 2 ** 20, "a request", available=2 ** 20)  # not "0.0 GiB"


def test_outputs_on_one_disk_add_up_and_the_line_names_each(tmp_path, monkeypatch):
    usage = shutil.disk_usage
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(path)._replace(free=5 << 20))  # every disk: 5 MiB free
    later = tmp_path / "out.h5.shards"  # not there yet: the disk of the folder above it
    check_space("a request", [("the output", 2 << 20, tmp_path), ("its shards", 3 << 20, later)])  # fits exactly
    with pytest.raises(OptionError) as refused:
        check_space("a request", [("the output", 2 << 20, tmp_path), ("its shards", 4 << 20, later)])
    assert str(refused.value) == (f"not enough space: a request needs about 6.0 MiB of disk in {tmp_path} (the output "
                                  f"2.0 MiB in {tmp_path}, its shards 4.0 MiB in {later}), and 5.0 MiB is free; "
                                  "nothing written: ask for fewer, or write elsewhere")
    assert not later.exists()
