"""Only the reader's package holds English word lists: the map's modules (and every layer that
reads words) ask :mod:`tabletop.reader.lexicon` for them.

The test walks every module of the layers that *read* English text with ``ast`` and names the
module and line of each English word list it finds:

- a ``set``/``list``/``tuple`` literal (``frozenset(...)`` and ``dict.fromkeys(...)`` wrap one)
  or the keys of a ``dict`` literal, holding at least :data:`MIN_WORDS` lower-case words;
- ``"...".split()`` of a string literal into at least :data:`MIN_WORDS` such words;
- a regular expression (a pattern given to ``re``) whose pattern holds ``|`` alternations and
  at least :data:`MIN_WORDS` different words.

A list is no word list but a list of identifiers when every one of its strings (each word of
a two-word string) is also an identifier of the package: a name (variable, function, class,
argument), an attribute, a keyword argument, a string subscript or ``.get``/``.pop``/``getattr``
key, a ``choices=`` value of the command line, a Python keyword, a key of the map's data files
(``tabletop/data/*.toml`` and ``tabletop/data/sounds/*.toml``: object kinds, sound categories),
or a name the simulator gives a thing it builds (a one- or two-word string constant of
``tabletop.sim``: "shelf", "sofa"). Field names ("obj", "sound", "img", "area"), modality
names, measure names, sound categories and the map's background and furniture categories all
are; "the", "an", "please" never are. The rule needs no allowlist: a list stops counting as
identifiers as soon as one of its strings is read in text only.

A list that holds a phrase of three words or more ("an animal making a sound") holds texts (the
prompts a module embeds, a benchmark's queries), not words, and is no word list either.

Out of scope, and why: ``tabletop.sim`` (its catalogue and scenes *write* scene data: object
names and colours it renders, never text it reads), ``tabletop.eval`` and ``tabletop.train``
(suite and training-text generators *write* the words people might say, to test and teach the
reader with; a few of their lists of determiners and prepositions shape the texts they write),
``tabletop.cli`` and ``tabletop.viewer`` (help text and labels for people), and
``tabletop.ingest`` (file formats). The reader's own package (``tabletop/reader/``, the
lexicon with it) is where the lists live.
"""

from __future__ import annotations

import ast
import keyword
import re
import tomllib
from pathlib import Path

from helpers import package_modules, plant_package

import tabletop

ROOT = Path(tabletop.__file__).parent
#: The layers (``tabletop.X``, see tests/test_layers.py) whose modules read English text.
READING_LAYERS = ("core", "arm", "base", "mapping", "robot", "language")
#: Fewer words than this make no list (``w in ("with", "having", "has")`` is a test of words,
#: not a lexicon).
MIN_WORDS = 4
_WORD = re.compile(r"[a-z]+(?:['\- ][a-z]+)*")
_RE_FUNCS = {"compile", "search", "match", "fullmatch", "findall", "finditer", "sub", "subn"}
_RE_FUNCS |= {"split"}


def _layer(module: str) -> str:
    parts = module.split(".")
    layers = {"arm", "base", "sim", "mapping", "reader", "robot", "language", "eval", "train"}
    layers |= {"viewer", "cli", "ingest"}
    return parts[1] if len(parts) > 1 and parts[1] in layers else "core"


def _data_keys(node, out: set[str]) -> None:
    if isinstance(node, dict):
        for k, v in node.items():
            out.add(str(k))
            _data_keys(v, out)
    elif isinstance(node, list):
        for v in node:
            _data_keys(v, out)


def identifiers(root: Path = ROOT) -> set[str]:
    """Every identifier of the package under ``root`` (see the module docstring)."""
    out: set[str] = set()
    for module, path in package_modules(root):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Name):
                out.add(node.id)
            elif isinstance(node, ast.Attribute):
                out.add(node.attr)
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                out.add(node.name)
            elif isinstance(node, ast.arg):
                out.add(node.arg)
            elif isinstance(node, ast.keyword) and node.arg:
                out.add(node.arg)
                if node.arg == "choices":
                    out |= {s for s in _strings(node.value) or ()}
            elif isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant):
                if isinstance(node.slice.value, str):
                    out.add(node.slice.value)
            elif isinstance(node, ast.Call) and node.args:
                f = node.func
                name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
                key = node.args[1] if name in ("getattr", "hasattr") else node.args[0]
                if name in ("get", "pop", "setdefault", "getattr", "hasattr") and (
                    isinstance(key, ast.Constant) and isinstance(key.value, str)
                ):
                    if name not in ("getattr", "hasattr") or len(node.args) > 1:
                        out.add(key.value)
        if _layer(module) == "sim":  # the names the simulator gives the things it builds
            out |= {
                n.value
                for n in ast.walk(tree)
                if isinstance(n, ast.Constant)
                and isinstance(n.value, str)
                and _WORD.fullmatch(n.value)
            }
    data = root / "data"
    for path in sorted([*data.glob("*.toml"), *data.glob("sounds/*.toml")]):
        try:
            _data_keys(tomllib.loads(path.read_text()), out)
        except (UnicodeDecodeError, tomllib.TOMLDecodeError):
            continue
    return out | set(keyword.kwlist) | set(keyword.softkwlist)


def _strings(node) -> list[str] | None:
    """The strings of a literal list, set or tuple, or None when it holds anything else."""
    if not isinstance(node, (ast.List, ast.Set, ast.Tuple)):
        return None
    out = []
    for e in node.elts:
        if not (isinstance(e, ast.Constant) and isinstance(e.value, str)):
            return None
        out.append(e.value)
    return out


def _pattern(node) -> str | None:
    """The constant text of a pattern: a string, or strings joined by ``+``."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        parts = [_pattern(node.left), _pattern(node.right)]
        return "".join(p for p in parts if p is not None) or None
    return None


def _regex_words(pattern: str) -> list[str]:
    """The words of a regular expression's pattern: its letters outside escapes, character
    classes, group names and flags."""
    p = re.sub(r"\\.", " ", pattern)
    p = re.sub(r"\[[^\]]*\]", " ", p)
    p = re.sub(r"\(\?(?:P<[^>]*>|P=[^)]*\)|[:!=]|<[=!]|[aiLmsux-]+[:)])", " ", p)
    return list(dict.fromkeys(re.findall(r"[a-z]{2,}", p)))


def _lists(tree: ast.AST):
    """(line, words, kind) of every literal of words in ``tree``."""
    for node in ast.walk(tree):
        words = _strings(node)
        kind = "list"
        if isinstance(node, ast.Dict) and all(
            isinstance(k, ast.Constant) and isinstance(k.value, str) for k in node.keys
        ):
            words, kind = [k.value for k in node.keys], "dict keys"
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "split"
            and not node.args
            and isinstance(node.func.value, ast.Constant)
            and isinstance(node.func.value.value, str)
        ):
            words, kind = node.func.value.value.split(), "split string"
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and getattr(node.func.value, "id", None) == "re"
            and node.func.attr in _RE_FUNCS
            and node.args
        ):
            pattern = _pattern(node.args[0])
            if pattern is None or "|" not in pattern:
                continue
            words, kind = _regex_words(pattern), "regex"
        if words is None:
            continue
        plain = [w for w in words if _WORD.fullmatch(w)]
        if kind != "regex" and len(plain) < len(words):
            continue  # a string that is no lower-case word: no word list
        if any(len(w.split()) > 2 for w in plain):
            continue  # a phrase of three words or more: texts (prompts, queries), not words
        if len(set(plain)) >= MIN_WORDS:
            yield node.lineno, plain, kind


def word_lists(root: Path = ROOT, layers=READING_LAYERS) -> list[str]:
    """``module:line (kind) words...`` of every English word list in ``layers`` under ``root``."""
    known = identifiers(root)
    bad = []
    for module, path in package_modules(root):
        if _layer(module) not in layers:
            continue
        for line, words, kind in _lists(ast.parse(path.read_text())):
            if all(set(w.split()) <= known for w in words):
                continue  # identifiers, not words
            shown = ", ".join(w for w in words if not set(w.split()) <= known)
            bad.append(f"{module}:{line} ({kind}) {shown}")
    return sorted(set(bad), key=lambda s: (s.split(":")[0], int(s.split(":")[1].split()[0])))


def test_only_the_reader_holds_word_lists():
    assert word_lists() == []


def test_the_walk_catches_a_planted_word_list(tmp_path):
    pkg = plant_package(
        tmp_path,
        {
            "mapping/m.py": "import re\n"
            "FIELDS = ('obj', 'sound')\n"
            "KEYS = ('obj', 'sound', 'img', 'area')\n"
            "\n"
            "def f(d, obj, sound, img, area):\n"
            "    return d['obj']\n"
            "\n"
            "STOP = frozenset('the a an of'.split())\n"
            "PRONOUNS = {'it', 'this', 'that', 'them'}\n"
            "HERE = re.compile(r'\\b(?:over|right|just)\\s+(?:there|here)\\b')\n",
            "reader/__init__.py": "WORDS = ('the', 'a', 'an', 'of')\n",
        },
    )
    assert word_lists(pkg) == [
        "tabletop.mapping.m:8 (split string) the, a, an, of",
        "tabletop.mapping.m:9 (list) it, this, that, them",
        "tabletop.mapping.m:10 (regex) over, right, just, there, here",
    ]
