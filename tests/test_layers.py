"""Imports run downward only: a module may import its own subpackage and the layers below it.

core (errors, transforms, grid, recording, paths) -> arm, base -> sim; the lexicon
(``tabletop.reader.lexicon``, the one place English word lists live) on the core alone; mapping
beside arm, base and sim (importing none of them, only the core and the lexicon) -> reader ->
robot -> language -> eval, train -> viewer -> cli. The lexicon is its own layer inside the
reader's package: the map and every layer above it may ask it for words, while the map still
imports nothing else of the reader. The test walks every module's imports (top-level and inside
functions) with ``ast``.
"""

import ast
from pathlib import Path

from helpers import package_modules, plant_package

import tabletop

ROOT = Path(tabletop.__file__).parent
#: layer -> the layers it may import (besides itself).
ALLOWED = {
    "core": set(),
    "lexicon": {"core"},
    "arm": {"core"},
    "base": {"core"},
    "sim": {"core", "arm", "base"},
    "mapping": {"core", "lexicon"},
    "reader": {"core", "lexicon", "mapping"},
    "robot": {"core", "lexicon", "arm", "base", "sim", "mapping", "reader"},
    "language": {"core", "lexicon", "arm", "base", "sim", "mapping", "reader", "robot"},
    "eval": {"core", "lexicon", "arm", "base", "sim", "mapping", "reader", "robot", "language"},
    "train": {"core", "lexicon", "arm", "base", "sim", "mapping", "reader", "robot", "language"},
    "viewer": {
        "core",
        "lexicon",
        "arm",
        "base",
        "sim",
        "mapping",
        "reader",
        "robot",
        "language",
        "eval",
    },
    "cli": {
        "core",
        "lexicon",
        "arm",
        "base",
        "sim",
        "mapping",
        "reader",
        "robot",
        "language",
        "eval",
        "train",
        "viewer",
    },
}


def _layer(module: str) -> str:
    parts = module.split(".")
    if parts[1:3] == ["reader", "lexicon"]:
        return "lexicon"  # tabletop.reader.lexicon: its own layer inside the reader's package
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
    for module, path in package_modules(root):
        layer = _layer(module)
        for name in _imports(path, module):
            other = _layer(name)
            if other != layer and other not in ALLOWED[layer]:
                bad.append(f"{module} ({layer}) imports {name} ({other})")
    return bad


def test_imports_run_downward_only():
    assert upward_imports() == []


def test_the_walk_catches_an_upward_import(tmp_path):
    pkg = plant_package(
        tmp_path, {"mapping/m.py": "def f():\n    from tabletop.sim.scan import run_scan\n"}
    )
    assert upward_imports(pkg) == ["tabletop.mapping.m (mapping) imports tabletop.sim.scan (sim)"]


def test_the_lexicon_is_a_layer_of_its_own(tmp_path):
    pkg = plant_package(
        tmp_path,
        {
            "mapping/m.py": "from tabletop.reader.lexicon.words import negations\n"
            "from tabletop.reader.rules import x\n",
            "reader/lexicon/w.py": "from tabletop.errors import E\n"
            "from tabletop.mapping.colors import delta_e\nfrom tabletop.reader.plan import Plan\n",
        },
    )
    assert sorted(upward_imports(pkg)) == [
        "tabletop.mapping.m (mapping) imports tabletop.reader.rules (reader)",
        "tabletop.reader.lexicon.w (lexicon) imports tabletop.mapping.colors (mapping)",
        "tabletop.reader.lexicon.w (lexicon) imports tabletop.reader.plan (reader)",
    ]


def test_requires_python_covers_the_standard_library_the_code_uses():
    import re
    import tomllib

    meta = tomllib.loads((ROOT.parent / "pyproject.toml").read_text())
    floor = re.fullmatch(r">=\s*3\.(\d+)", meta["project"]["requires-python"])
    assert floor, meta["project"]["requires-python"]
    uses_tomllib = any("tomllib" in p.read_text() for p in ROOT.rglob("*.py"))
    assert not uses_tomllib or int(floor.group(1)) >= 11  # tomllib is new in 3.11


def own_imports_behind_import_error(root: Path = ROOT) -> list[str]:
    """``try: from tabletop... except ImportError`` hides a real bug in the package's own code
    behind a fallback: list every such place."""
    bad = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.Try):
                continue
            own = any(
                isinstance(n, ast.ImportFrom)
                and (n.level or (n.module or "").startswith("tabletop"))
                for stmt in node.body
                for n in ast.walk(stmt)
            )
            caught = {getattr(h.type, "id", None) for h in node.handlers if h.type is not None} | {
                getattr(e, "id", None)
                for h in node.handlers
                if isinstance(h.type, ast.Tuple)
                for e in h.type.elts
            }
            if own and caught & {"ImportError", "ModuleNotFoundError"}:
                bad.append(f"{path.relative_to(root.parent)}:{node.lineno}")
    return bad


def test_the_package_never_hides_its_own_import_errors(tmp_path):
    assert own_imports_behind_import_error() == []
    pkg = tmp_path / "tabletop"
    pkg.mkdir()
    (pkg / "m.py").write_text(
        "try:\n    from tabletop.train.vision import x\nexcept ImportError:\n    x = None\n"
    )
    assert own_imports_behind_import_error(pkg) == ["tabletop/m.py:1"]


def module_cycles(root: Path = ROOT) -> list[list[str]]:
    """Groups of modules (package ``__init__`` files aside) that import each other, directly
    or through others: each group is a strongly connected component of the import graph."""
    modules = dict(package_modules(root))
    inits = {m for m, p in modules.items() if p.name == "__init__.py"}
    graph = {}
    for m, path in modules.items():
        if m in inits:
            continue
        graph[m] = set()
        for name in _imports(path, m):
            if name in modules and name not in inits and name != m:
                graph[m].add(name)
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(sorted(group))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_no_two_modules_import_each_other(tmp_path):
    assert module_cycles() == []
    pkg = plant_package(
        tmp_path,
        {
            "sim/a.py": "from tabletop.sim.b import x\n",
            "sim/b.py": "def f():\n    from tabletop.sim.a import y\n",
        },
    )
    assert module_cycles(pkg) == [["tabletop.sim.a", "tabletop.sim.b"]]
