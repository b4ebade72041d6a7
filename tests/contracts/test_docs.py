"""The documentation holds what the commands do: every command has a page in docs/commands/ whose
``--help`` block is the live ``--help`` (docs/commands/help_pages.py writes them), the README's links
and picture are there, and the strict docs build (``make docs``, run by ``make test``) fails on a
broken link."""

import importlib.util
import os
import pathlib
import re
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _help_pages():
    spec = importlib.util.spec_from_file_location("help_pages", ROOT / "docs" / "commands" / "help_pages.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_command_page_holds_its_live_help():
    problems = _help_pages().problems()
    assert not problems, "\n".join(problems) + "\nrun: python docs/commands/help_pages.py"


def test_the_pages_help_is_what_the_installed_command_prints():
    """The blocks are rendered in-process; the console script in a 100-column terminal prints the same."""
    exe = shutil.which("skinsynth", path=os.path.dirname(sys.executable))
    if exe is None:
        pytest.skip("no skinsynth console script beside this Python")
    pages = _help_pages()
    live = subprocess.run([exe, "example", "--help"], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, COLUMNS=str(pages.COLUMNS)))
    assert live.returncode == 0, live.stderr
    assert live.stdout == pages.help_text("example")


def test_every_command_page_is_in_the_nav():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    for command in _help_pages().commands():
        assert f"commands/{command}.md" in nav, f"mkdocs.yml's nav lacks commands/{command}.md"


def test_readme_is_a_front_door_whose_links_resolve():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 220, "the README is the short tour: the manual goes under docs/"
    assert readme.splitlines()[readme.splitlines().index("```sh", 0) + 1].startswith("make demo")
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", readme)
    local = [t for t in targets if not re.match(r"[a-z]+:", t)]
    assert any(t.endswith(".png") for t in local)
    for target in local:
        assert (ROOT / target).exists(), f"README.md links to {target}, which is not there"
    for command in _help_pages().commands():
        assert f"docs/commands/{command}.md" in local, f"README.md does not link the page of {command}"
    for picture in (ROOT / "docs").glob("*.png"):
        assert picture.stat().st_size < 500_000, f"{picture.name}: keep the docs' pictures small"


def test_strict_docs_build_fails_on_a_broken_link(tmp_path):
    """mkdocs.yml's validation turns a link to a missing page into a failure of ``mkdocs build
    --strict`` (a change to it that let one through would make ``make docs`` pass anything)."""
    if importlib.util.find_spec("mkdocs") is None:
        pytest.skip("mkdocs is not installed (pip install -e '.[test]')")
    shutil.copy(ROOT / "mkdocs.yml", tmp_path / "mkdocs.yml")
    (tmp_path / "docs").mkdir()
    for page in (ROOT / "docs").rglob("*.md"):
        target = tmp_path / "docs" / page.relative_to(ROOT / "docs")
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(page, target)
    for picture in (ROOT / "docs").rglob("*.png"):
        target = tmp_path / "docs" / picture.relative_to(ROOT / "docs")
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(picture, target)
    build = [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")]
    clean = subprocess.run(build, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert clean.returncode == 0, clean.stderr[-2000:]
    with open(tmp_path / "docs" / "make.md", "a", encoding="utf-8") as page:
        page.write("\nSee [the missing page](no_such_page.md).\n")
    broken = subprocess.run(build, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert broken.returncode != 0
    assert "no_such_page.md" in broken.stderr
