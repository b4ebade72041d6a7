"""The house rule, enforced (docs/architecture.md): imports point one way.

    cli ──▶ formats, pipeline, gpu        nothing imports cli
    pipeline ──▶ gpu (its public API)     never formats or cli
    formats, gpu ──▶ nothing else of skinsynth
    pipeline's stages (skin, puppet, synthesis, view) never import each other;
    the floor (pipeline's top-level modules) imports no stage.

Every import statement counts, the ones inside functions too; relative imports are resolved."""

import ast
import pathlib
import shutil

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGES = ("cli", "formats", "pipeline", "gpu")
STAGES = ("skin", "puppet", "synthesis", "view")
RULES = {"pipeline": "pipeline imports only gpu, never formats or cli", "formats": "formats imports nothing else of "
         "skinsynth (it returns plain records)", "gpu": "gpu imports nothing else of skinsynth"}


def module_name(path, root):
    """``skinsynth.pipeline.skin.skin_fit`` for ``root/pipeline/skin/skin_fit.py``."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(["skinsynth", *parts])


def imported_modules(path, name):
    """Yield (line, absolute module name) of every import in the file ``path`` (module ``name``)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            if node.module is None:  # "from . import x": each x is a module
                for alias in node.names:
                    yield node.lineno, f"{target}.{alias.name}"
            else:
                yield node.lineno, target


def _place(module):
    """(package, stage or None) of a skinsynth module; stage '' for pipeline's floor."""
    parts = module.split(".")
    package = parts[1] if len(parts) > 1 else ""
    stage = None
    if package == "pipeline":
        stage = parts[2] if len(parts) > 3 or (len(parts) == 3 and parts[2] in STAGES) else ""
        stage = stage if stage in STAGES else ""
    return package, stage


def violations(root):
    """Every import that points the wrong way in the tree at ``root``, one message each."""
    found = []
    allowed = {"cli": {"cli", "formats", "pipeline", "gpu"}, "pipeline": {"pipeline", "gpu"}, "formats": {"formats"},
               "gpu": {"gpu"}}
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            name = module_name(path, root)
            source, source_stage = _place(name)
            for line, target in imported_modules(path, name):
                if not (target == "skinsynth" or target.startswith("skinsynth.")):
                    continue
                where = f"{path.relative_to(root)}:{line}"
                package_to, stage_to = _place(target)
                if package_to not in allowed[source]:
                    found.append(f"{where}: {source} imports {target}; {RULES[source]}")
                elif source == "pipeline" and package_to == "gpu" and target != "skinsynth.gpu":
                    found.append(f"{where}: pipeline imports {target}; pipeline uses gpu through its public API "
                                 "(from skinsynth.gpu import …)")
                elif source == "pipeline" and stage_to and stage_to != source_stage:
                    what = f"the stage {source_stage}" if source_stage else "the floor"
                    found.append(f"{where}: {what} imports {target}, of the stage {stage_to}; stages never import "
                                 "each other, and the floor imports no stage: move what both need to the floor")
    return found


def test_every_import_points_down():
    assert violations(ROOT) == []


def test_a_planted_wrong_way_import_is_named(tmp_path):
    for package in PACKAGES:
        shutil.copytree(ROOT / package, tmp_path / package, ignore=shutil.ignore_patterns("__pycache__"))
    plants = {
        "formats/errors.py": ("from skinsynth.pipeline.mesh.geometry import largest_side\n",
                              "formats/errors.py:1: formats imports skinsynth.pipeline.mesh.geometry; formats imports "
                              "nothing else of skinsynth"),
        "gpu/runtime.py": ("from skinsynth.formats import errors\n",
                           "gpu/runtime.py:1: gpu imports skinsynth.formats; gpu imports nothing else of skinsynth"),
        "pipeline/skin/skin_init.py": ("from ..puppet.kcca import KERNELS\n",
                                       "pipeline/skin/skin_init.py:1: the stage skin imports "
                                       "skinsynth.pipeline.puppet.kcca, of the stage puppet"),
        "pipeline/mesh/geometry.py": ("def f():\n    from ..synthesis import graph\n",
                                      "pipeline/mesh/geometry.py:2: the floor imports skinsynth.pipeline.synthesis, of the "
                                      "stage synthesis"),
        "pipeline/puppet/kcca.py": ("from skinsynth.gpu.skinning import dq_skin\n",
                                    "pipeline/puppet/kcca.py:1: pipeline imports skinsynth.gpu.skinning; "
                                    "pipeline uses gpu through its public API"),
        "formats/model.py": ("import skinsynth.cli.common\n",
                             "formats/model.py:1: formats imports skinsynth.cli.common"),
    }
    for relative, (line, _) in plants.items():
        path = tmp_path / relative
        path.write_text(line + path.read_text())
    found = violations(tmp_path)
    assert len(found) == len(plants), "\n".join(found)
    for _, message in plants.values():
        assert any(f.startswith(message) for f in found), (message, found)
