"""Imports run downward only: a module may import its own subpackage and the layers below it.

core (errors, transforms, grid, recording, paths) -> arm -> sim; mapping beside arm and sim
(importing neither) -> robot -> language -> eval, train -> cli. The test walks every module's
imports (top-level and inside functions) with ``ast``.
"""

import ast
from pathlib import Path

import tabletop

ROOT = Path(tabletop.__file__).parent
#: layer -> the layers it may import (besides itself).
ALLOWED = {
    "core": set(),
    "arm": {"core"},
    "sim": {"core", "arm"},
    "mapping": {"core"},
    "robot": {"core", "arm", "sim", "mapping"},
    "language": {"core", "arm", "sim", "mapping", "robot"},
    "eval": {"core", "arm", "sim", "mapping", "robot", "language"},
    "train": {"core", "arm", "sim", "mapping", "robot", "language"},
    "cli": {"core", "arm", "sim", "mapping", "robot", "language", "eval", "train"},
}


def _layer(module: str) -> str:
    parts = module.split(".")
    if len(parts) < 2 or parts[1] not in ALLOWED:
        return "core"  # tabletop, tabletop.errors, tabletop.transforms, ...
    return parts[1]


def _imports(path: Path, module: str) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")[: -node.level + (path.name == "__init__.py") or None]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = node.module or ""
            if name.startswith("tabletop"):
                out.add(name)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("tabletop")}
    return out


def upward_imports(root: Path = ROOT) -> list[str]:
    bad = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root.parent).with_suffix("")
        module = ".".join(rel.parts).removesuffix(".__init__")
        layer = _layer(module)
        for name in _imports(path, module):
            other = _layer(name)
            if other != layer and other not in ALLOWED[layer]:
                bad.append(f"{module} ({layer}) imports {name} ({other})")
    return bad


def test_imports_run_downward_only():
    assert upward_imports() == []


def test_the_walk_catches_an_upward_import(tmp_path):
    pkg = tmp_path / "tabletop"
    (pkg / "mapping").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "mapping" / "__init__.py").write_text("")
    (pkg / "mapping" / "m.py").write_text("def f():\n    from tabletop.sim.scan import run_scan\n")
    assert upward_imports(pkg) == ["tabletop.mapping.m (mapping) imports tabletop.sim.scan (sim)"]


def test_requires_python_covers_the_standard_library_the_code_uses():
    import re
    import tomllib

    meta = tomllib.loads((ROOT.parent / "pyproject.toml").read_text())
    floor = re.fullmatch(r">=\s*3\.(\d+)", meta["project"]["requires-python"])
    assert floor, meta["project"]["requires-python"]
    uses_tomllib = any("tomllib" in p.read_text() for p in ROOT.rglob("*.py"))
    assert not uses_tomllib or int(floor.group(1)) >= 11  # tomllib is new in 3.11
