"""docs/architecture.md matches the code: every module it names exists, every module of the four
packages is named in it, and every package (each folder with an ``__init__.py``) is drawn in its
floors. A module moved, renamed or added without the map fails here, as a wrong-way import fails
test_layering.py."""

import pathlib
import re
import shutil

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGES = ("cli", "formats", "pipeline", "gpu")


def named_paths(text):
    """Every ``.py`` path the page names in backticks (a whole path or its tail, as the stage map's
    columns name them relative to their package), templates (``<name>``, ``*``) aside."""
    found = set(re.findall(r"`([\w./]+\.py)`", text)) | set(re.findall(r"`([\w./]+\.py)[ (]", text))
    return {path for path in found if "<" not in path and "*" not in path}


def modules(root):
    """Every module of the four packages, as paths relative to ``root`` (``__init__`` aside)."""
    return sorted(str(path.relative_to(root)) for package in PACKAGES for path in (root / package).rglob("*.py")
                  if path.name != "__init__.py" and "__pycache__" not in path.parts)


def map_problems(root):
    """One line per disagreement between ``root``/docs/architecture.md and the tree at ``root``."""
    text = (root / "docs" / "architecture.md").read_text()
    names = named_paths(text)
    files = sorted(str(p.relative_to(root)) for top in (*PACKAGES, "tests", "benchmarks")
                   for p in (root / top).rglob("*.py"))
    problems = [f"docs/architecture.md names {name}, which is not in the tree" for name in sorted(names)
                if not any(f == name or f.endswith("/" + name) for f in files)]
    problems += [f"{module} is not named in docs/architecture.md" for module in modules(root)
                 if not any(module == name or module.endswith("/" + name) for name in names)]
    drawing = text.split("```")[1]  # the floors, the page's first code block
    for package in sorted({init.parent for top in PACKAGES for init in (root / top).rglob("__init__.py")}):
        name = package.name + "/"
        if name not in drawing:
            problems.append(f"the package {package.relative_to(root)}/ is not drawn in docs/architecture.md's floors")
    return problems


def test_the_architecture_page_maps_every_module_and_package():
    problems = map_problems(ROOT)
    assert problems == [], "\n".join(problems)


def test_a_module_moved_or_added_without_the_map_is_named(tmp_path):
    for package in PACKAGES:
        shutil.copytree(ROOT / package, tmp_path / package, ignore=shutil.ignore_patterns("__pycache__"))
    (tmp_path / "docs").mkdir()
    shutil.copyfile(ROOT / "docs" / "architecture.md", tmp_path / "docs" / "architecture.md")
    for folder in ("tests", "benchmarks"):
        shutil.copytree(ROOT / folder, tmp_path / folder, ignore=shutil.ignore_patterns("__pycache__", "node_modules"))
    (tmp_path / "pipeline" / "synthesis" / "splicing.py").rename(tmp_path / "pipeline" / "synthesis" / "seams.py")
    (tmp_path / "formats" / "newformat").mkdir()
    (tmp_path / "formats" / "newformat" / "__init__.py").write_text("")
    problems = map_problems(tmp_path)
    assert problems == ["docs/architecture.md names pipeline/synthesis/splicing.py, which is not in the tree",
                        "docs/architecture.md names synthesis/splicing.py, which is not in the tree",
                        "pipeline/synthesis/seams.py is not named in docs/architecture.md",
                        "the package formats/newformat/ is not drawn in docs/architecture.md's floors"]
