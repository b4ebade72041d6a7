"""Folder outputs never cost the user a file (issue 27, group 1): a folder output replaces only a
folder skinsynth wrote, never one that holds anything else, never the working folder, never one
that holds an input or another output of the same command; the swap leaves no moment with
neither folder; a killed writer's temporary folder is swept by the next write."""

import hashlib
import os
import signal

import pytest

from cli_helpers import assert_ok, assert_user_error, cli
from skinsynth.formats.output_folder import MANIFEST, atomic_folder, unowned_entries

VAT_FILES = [MANIFEST, "animation.exr", "animation_normals.exr", "rest.glb", "rest.obj", "vat.json"]


@pytest.fixture(scope="module")
def chain(stage_files):
    """bar.npz → skin.h5 → graph.h5, controls.h5 → puppet.h5."""
    return stage_files(frames=48, bones=4, iterations=4, cycles=2, graph=("--min-segment", 4), controls=("--count", 4),
                       puppet=()).folder


def tree(folder):
    """{relative path: sha256} of every file below ``folder``."""
    found = {}
    for top, _, names in os.walk(folder):
        for name in names:
            path = os.path.join(top, name)
            with open(path, "rb") as handle:
                found[os.path.relpath(path, folder)] = hashlib.sha256(handle.read()).hexdigest()
    return found


def copy(source, target):
    target.write_bytes(source.read_bytes())
    return target


# -- the cases the fault campaign found ------------------------------------------------------------

def test_export_into_the_folder_of_its_own_input_is_refused(chain, tmp_path):
    shot = tmp_path / "shot"
    shot.mkdir()
    copy(chain / "skin.h5", shot / "skin.h5")
    before = tree(shot)
    assert_user_error(cli("export", shot / "skin.h5", "-o", f"{shot}/"), "skin.h5", "an input of this command")
    assert tree(shot) == before


def test_export_to_the_working_folder_is_refused(chain, tmp_path, monkeypatch):
    copy(chain / "skin.h5", tmp_path / "skin.h5")
    (tmp_path / "project.blend").write_bytes(b"a user's scene")
    before = tree(tmp_path)
    monkeypatch.chdir(tmp_path)
    for target in ("./", ".", f"{tmp_path}/", f"{tmp_path.parent}/"):
        assert_user_error(cli("export", "skin.h5", "-o", target if target.endswith("/") else target + "/"),
                          "working folder")
    assert tree(tmp_path) == before


def test_a_folder_holding_a_users_file_is_refused(chain, tmp_path):
    (tmp_path / "vat").mkdir()
    (tmp_path / "vat" / "notes.txt").write_text("keep me")
    assert_user_error(cli("export", chain / "skin.h5", "-o", f"{tmp_path / 'vat'}/"), "notes.txt",
                      "skinsynth did not write", "nothing was touched")
    assert (tmp_path / "vat" / "notes.txt").read_text() == "keep me"
    assert sorted(os.listdir(tmp_path)) == ["vat"]  # no temporary left beside it


def test_a_folder_skinsynth_wrote_is_replaced_and_a_changed_one_is_not(chain, tmp_path):
    vat = tmp_path / "vat"
    assert_ok(cli("export", chain / "skin.h5", "-o", f"{vat}/"))
    assert sorted(os.listdir(vat)) == VAT_FILES
    assert unowned_entries(vat) == []
    assert_ok(cli("export", chain / "skin.h5", "-o", f"{vat}/", "--half"))  # its own: replaced
    assert sorted(os.listdir(tmp_path)) == ["vat"]
    (vat / "rest.obj").write_text("# edited by hand\n")
    assert_user_error(cli("export", chain / "skin.h5", "-o", f"{vat}/"), "rest.obj", "changed since")
    assert (vat / "rest.obj").read_text() == "# edited by hand\n"
    (vat / MANIFEST).write_text("not json")
    assert_user_error(cli("export", chain / "skin.h5", "-o", f"{vat}/"), MANIFEST)


def test_a_vat_folder_from_before_manifests_is_replaced_only_as_its_vat_json_lists(chain, tmp_path):
    vat = tmp_path / "vat"
    assert_ok(cli("export", chain / "skin.h5", "-o", f"{vat}/"))
    (vat / MANIFEST).unlink()  # as the previous version wrote it
    assert_ok(cli("export", chain / "skin.h5", "-o", f"{vat}/"))
    (vat / MANIFEST).unlink()
    (vat / "extra.exr").write_bytes(b"a user's texture")
    assert_user_error(cli("export", chain / "skin.h5", "-o", f"{vat}/"), "extra.exr")
    assert (vat / "extra.exr").read_bytes() == b"a user's texture"


def test_play_into_a_folder_holding_its_puppet_or_controls_is_refused(chain, tmp_path):
    crowd = tmp_path / "crowd"
    crowd.mkdir()
    puppet, controls = copy(chain / "puppet.h5", crowd / "puppet.h5"), copy(chain / "bar.npz", crowd / "bar.npz")
    before = tree(crowd)
    assert_user_error(cli("play", puppet, "-c", chain / "bar.npz", "-o", f"{crowd}/"), "puppet.h5", "input")
    assert_user_error(cli("play", chain / "puppet.h5", "-c", controls, "-o", f"{crowd}/"), "bar.npz", "input")
    assert tree(crowd) == before


@pytest.mark.parametrize("case", ["output inside", "graph inside", "usd inside", "usd is exr", "exr inside usd",
                                  "plot inside"])
def test_synthesize_folders_never_hold_the_commands_other_files(chain, tmp_path, case):
    shot = tmp_path / "shot"
    shot.mkdir()
    graph, out = chain / "graph.h5", tmp_path / "bones.h5"
    extra = []
    if case == "output inside":
        out = shot / "bones.h5"
    elif case == "graph inside":
        graph = copy(chain / "graph.h5", shot / "graph.h5")
    elif case == "usd inside":
        extra = ["--usd", shot / "usd"]
    elif case == "usd is exr":
        extra = ["--usd", f"{shot}/"]
    elif case == "exr inside usd":
        extra, shot = ["--usd", shot], shot / "vat"
    else:
        extra = ["--plot", shot / "plots"]
    before = tree(tmp_path)
    line = assert_user_error(cli("synthesize", graph, "-o", out, "-n", 2, "-m", 20, "--exr", f"{shot}/", *extra))
    assert "output of this command" in line or "an input of this command" in line
    assert tree(tmp_path) == before and not out.exists()


def test_side_folders_with_a_users_file_are_refused_before_any_work(chain, tmp_path):
    for option, folder in (("--usd", "usd"), ("--plot", "plots")):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "animation_0000.usdc").write_bytes(b"a user's own cache")
        assert_user_error(cli("synthesize", chain / "graph.h5", "-o", tmp_path / "b.h5", "-n", 2, "-m", 20, option,
                              tmp_path / folder), "animation_0000.usdc", "skinsynth did not write")
        assert (tmp_path / folder / "animation_0000.usdc").read_bytes() == b"a user's own cache"
    (tmp_path / "graph_plots").mkdir()
    (tmp_path / "graph_plots" / "bone_graph.png").write_bytes(b"mine")
    assert_user_error(cli("build-graph", chain / "skin.h5", "-o", tmp_path / "g.h5", "--plot", tmp_path / "graph_plots"),
                      "bone_graph.png")
    assert not (tmp_path / "b.h5").exists() and not (tmp_path / "g.h5").exists()


def test_side_folders_are_written_whole_and_rewritten(chain, tmp_path):
    args = ["synthesize", chain / "graph.h5", "-o", tmp_path / "b.h5", "-n", 2, "-m", 20, "--usd", tmp_path / "usd",
            "--plot", tmp_path / "plots", "--plot-count", 2, "-q"]
    assert_ok(cli(*args))
    assert sorted(os.listdir(tmp_path / "usd")) == [MANIFEST, "animation_0000.usdc", "animation_0001.usdc"]
    assert sorted(os.listdir(tmp_path / "plots")) == [MANIFEST, "animation_0000.png", "animation_0001.png"]
    assert_ok(cli(*args[:5], 1, *args[6:]))  # one animation now: the old folders are replaced, not added to
    assert sorted(os.listdir(tmp_path / "usd")) == [MANIFEST, "animation_0000.usdc"]
    assert sorted(os.listdir(tmp_path)) == ["b.h5", "plots", "usd"]


def test_a_symbolic_link_to_a_folder_writes_that_folder_and_keeps_the_link(chain, tmp_path):
    (tmp_path / "real").mkdir()
    os.symlink(tmp_path / "real", tmp_path / "link")
    assert_ok(cli("export", chain / "skin.h5", "-o", f"{tmp_path / 'link'}/"))
    assert os.path.islink(tmp_path / "link") and sorted(os.listdir(tmp_path / "real")) == VAT_FILES
    os.symlink(tmp_path / "nowhere", tmp_path / "dangling")
    assert_user_error(cli("export", chain / "skin.h5", "-o", f"{tmp_path / 'dangling'}/"), "symbolic link")
    (tmp_path / "file").write_text("x")
    assert_user_error(cli("export", chain / "skin.h5", "-o", f"{tmp_path / 'file'}/"), "is a file")


# -- the swap and the temporaries ------------------------------------------------------------------

def _write(folder, name, text):
    with open(os.path.join(folder, name), "w") as handle:
        handle.write(text)


def test_the_swap_without_renameat2_puts_the_old_folder_back_when_the_new_cannot_go_in(tmp_path, monkeypatch):
    import skinsynth.formats.output_folder as output_folder

    target = tmp_path / "out"
    with atomic_folder(target) as tmp:
        _write(tmp, "a.txt", "old")
    monkeypatch.setattr(output_folder, "_exchange", lambda a, b: False)
    real_rename, renames = os.rename, []

    def failing_second_rename(a, b):  # the new folder cannot go in once the old one is aside
        renames.append((a, b))
        if len(renames) == 2:
            raise OSError(5, "Input/output error", b)
        real_rename(a, b)

    monkeypatch.setattr(output_folder.os, "rename", failing_second_rename)
    with pytest.raises(OSError):
        with atomic_folder(target) as tmp:
            _write(tmp, "b.txt", "new")
    monkeypatch.setattr(output_folder.os, "rename", real_rename)
    assert sorted(os.listdir(tmp_path)) == ["out"] and sorted(os.listdir(target)) == [MANIFEST, "a.txt"]
    with atomic_folder(target) as tmp:  # and without the failure, two renames replace it
        _write(tmp, "b.txt", "new")
    assert sorted(os.listdir(tmp_path)) == ["out"] and sorted(os.listdir(target)) == [MANIFEST, "b.txt"]


def test_the_swap_is_one_step_where_renameat2_exists(tmp_path, monkeypatch):
    import skinsynth.formats.output_folder as output_folder

    target = tmp_path / "out"
    with atomic_folder(target) as tmp:
        _write(tmp, "a.txt", "old")
    first, second = tmp_path / "first", tmp_path / "second"
    first.mkdir(), second.mkdir()
    _write(first, "1", "")
    if not output_folder._exchange(str(first), str(second)):
        pytest.skip("this file system cannot exchange two folders in one step")
    assert os.listdir(second) == ["1"] and os.listdir(first) == []

    def no_plain_rename(a, b):
        raise AssertionError("a folder that exists is replaced by the exchange, not by rename")

    monkeypatch.setattr(output_folder.os, "rename", no_plain_rename)
    with atomic_folder(target) as tmp:
        _write(tmp, "b.txt", "new")
    assert sorted(os.listdir(target)) == [MANIFEST, "b.txt"]


def test_a_signal_during_the_swap_ends_the_command_with_the_new_folder_in_place(tmp_path, monkeypatch):
    import skinsynth.formats.output_folder as output_folder
    from skinsynth.formats.atomic import Interrupted

    target = tmp_path / "out"
    with atomic_folder(target) as tmp:
        _write(tmp, "a.txt", "old")
    swap = output_folder._swap_in

    def signalled_swap(tmp, target):
        os.kill(os.getpid(), signal.SIGTERM)  # held back until the old folder is gone
        return swap(tmp, target)

    monkeypatch.setattr(output_folder, "_swap_in", signalled_swap)
    with pytest.raises(Interrupted) as stop:
        with atomic_folder(target) as tmp:
            _write(tmp, "b.txt", "new")
    assert stop.value.signum == signal.SIGTERM
    assert sorted(os.listdir(tmp_path)) == ["out"]
    assert sorted(os.listdir(target)) == [MANIFEST, "b.txt"]


def test_a_killed_writers_temporary_folder_is_swept_by_the_next_write(chain, tmp_path):
    dead = 2 ** 22 + 12345  # a pid no process has
    for name in (f".vat.{dead}.abcdefgh.tmp", f".vat.{dead}.abcdefgh.old.tmp"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "animation.exr").write_bytes(b"partial")
    alive = tmp_path / f".vat.{os.getppid()}.ijklmnop.tmp"  # a writer still running: left alone
    alive.mkdir()
    assert_ok(cli("export", chain / "skin.h5", "-o", f"{tmp_path / 'vat'}/"))
    assert sorted(os.listdir(tmp_path)) == [alive.name, "vat"]


def test_a_failed_write_leaves_no_folder_and_no_parent_made_for_it(tmp_path):
    with pytest.raises(RuntimeError):
        with atomic_folder(tmp_path / "a" / "b" / "out") as tmp:
            _write(tmp, "x.txt", "partial")
            raise RuntimeError("the writer failed")
    assert os.listdir(tmp_path) == []


def test_plots_of_animations_too_short_for_an_acceleration(chain, tmp_path):
    assert_ok(cli("synthesize", chain / "graph.h5", "-o", tmp_path / "b.h5", "-n", 1, "-m", 2, "--plot",
                  tmp_path / "plots", "-q"))
    assert sorted(os.listdir(tmp_path / "plots")) == [MANIFEST, "animation_0000.png"]
