"""A sandbox for generated robot code: a static check with ``ast``, then a small interpreter.

The code is never handed to ``exec``. :func:`check_code` parses it and refuses everything but

- calls ``robot.<method>(...)`` of the robot API (:data:`ROBOT_METHODS`, the declared
  primitives of :mod:`tabletop.robot.primitives`),
- arithmetic ``+ - * / // %`` and unary minus on numbers and arrays, and heatmaps (values of
  :data:`HEATMAP_CLASS`) with the operators their class defines (``*``: fusion),
- assignments to plain names (and tuple unpacking), ``+=`` and friends,
- number, string, tuple and list literals, ``name[i]`` with a literal index,
- ``for _ in range(n)`` with literal bounds (at most ``max_loop`` iterations), and ``pass``;

so imports, attribute access other than ``robot.<method>``, dunder names, ``open``, ``eval``,
``exec``, ``while``, ``if``, ``lambda``, comprehensions, function and class definitions,
``**`` and the like are refused, each with its line. Loops have literal bounds, so the number
of steps and robot calls is known before anything runs: code over the limits is refused too.
Refused code raises :class:`CodeRejected` before its first line runs, so the robot never moves.
Before parsing, control and format characters (all but newline and tab) are refused, so the
listing a user reviews is what runs, and a statement's operators and brackets are counted, so
no check recurses deeper than :attr:`SandboxConfig.max_expr_ops`. While running,
:func:`run_code` also counts steps, checks a wall-clock limit between steps, and a memory
budget: a list, tuple or array result is sized before it is built (:class:`SandboxLimit` over
:attr:`SandboxConfig.max_elements`), and lists nested deeper than
:attr:`SandboxConfig.max_depth` are refused as they are built, as are lists of more than
:attr:`SandboxConfig.max_arg_elements` handed to a robot method.
"""

from __future__ import annotations

import ast
import io
import sys
import time
import tokenize
import unicodedata
from collections.abc import Callable
from dataclasses import dataclass
from numbers import Integral, Real

import numpy as np

from tabletop.errors import ConfigError, TabletopError
from tabletop.language.errors import CodeRejected, SandboxError, SandboxLimit
from tabletop.robot.primitives import PRIMITIVES

__all__ = [
    "HEATMAP_CLASS",
    "ROBOT_METHODS",
    "ROBOT_MOVES",
    "CallRecord",
    "CheckedCode",
    "SandboxConfig",
    "SandboxRun",
    "check_code",
    "run_code",
]

#: Robot API methods that move the robot (the declaration's motion primitives).
ROBOT_MOVES = frozenset(p.name for p in PRIMITIVES if p.moves)
#: Every robot API method generated code may call: the declared primitives (queries, targets
#: and motions, :data:`tabletop.robot.primitives.PRIMITIVES`).
ROBOT_METHODS = frozenset(p.name for p in PRIMITIVES)
#: The heatmap class (``module.Name``): its values may be multiplied (``a * b`` fuses two
#: heatmaps). Looked up in ``sys.modules`` only: a value of that class means it is imported.
HEATMAP_CLASS = "tabletop.mapping.heatmaps.Heatmap"
ROBOT_NAME = "robot"

_BINOPS = {
    ast.Add: lambda a, b: a + b,
    ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b,
    ast.FloorDiv: lambda a, b: a // b,
    ast.Mod: lambda a, b: a % b,
}
_UNARY = {ast.USub: lambda a: -a, ast.UAdd: lambda a: +a}
_REFUSED = {
    ast.Import: "import statements",
    ast.ImportFrom: "import statements",
    ast.While: "while loops (loop with 'for _ in range(n)')",
    ast.If: "if statements",
    ast.IfExp: "conditional expressions",
    ast.FunctionDef: "function definitions",
    ast.AsyncFunctionDef: "function definitions",
    ast.ClassDef: "class definitions",
    ast.Lambda: "lambda",
    ast.ListComp: "comprehensions",
    ast.SetComp: "comprehensions",
    ast.DictComp: "comprehensions",
    ast.GeneratorExp: "generator expressions",
    ast.Try: "try statements",
    ast.With: "with statements",
    ast.AsyncWith: "with statements",
    ast.AsyncFor: "async for",
    ast.Raise: "raise",
    ast.Return: "return",
    ast.Assert: "assert",
    ast.Delete: "del",
    ast.Global: "global",
    ast.Nonlocal: "nonlocal",
    ast.Break: "break",
    ast.Continue: "continue",
    ast.Yield: "yield",
    ast.YieldFrom: "yield",
    ast.Await: "await",
    ast.NamedExpr: "assignment expressions (:=)",
    ast.JoinedStr: "f-strings",
    ast.Starred: "starred arguments",
    ast.Dict: "dict literals",
    ast.Set: "set literals",
    ast.Compare: "comparisons",
    ast.BoolOp: "and/or",
    ast.Slice: "slices",
}
if hasattr(ast, "TryStar"):
    _REFUSED[ast.TryStar] = "try statements"
if hasattr(ast, "Match"):
    _REFUSED[ast.Match] = "match statements"


@dataclass(frozen=True)
class SandboxConfig:
    """Limits of the sandbox."""

    max_code_chars: int = 20_000
    """Longest accepted code [characters]."""
    max_loop: int = 100
    """Most iterations of one ``for _ in range(n)`` loop."""
    max_steps: int = 20_000
    """Most evaluation steps (statements and expression nodes, loops unrolled)."""
    max_calls: int = 500
    """Most robot API calls (loops unrolled)."""
    max_moves: int = 50
    """Most robot motions (loops unrolled)."""
    timeout_s: float = 600.0
    """Wall-clock limit [s] of one run, checked between steps (a motion in progress ends)."""
    max_string: int = 500
    """Longest string literal [characters]."""
    max_expr_ops: int = 100
    """Most operators, brackets and dots in one statement (bounds how deep any expression
    nests, checked before the code is parsed)."""
    max_elements: int = 2_000_000
    """Most elements of a list, tuple or array the code builds (nested lists counted through,
    an array by its size); a heatmap product no larger than its factors is always allowed."""
    max_arg_elements: int = 1_000
    """Most elements of a list or tuple handed to a robot method (nested lists counted
    through; arrays and heatmaps are not lists): robot methods take names, numbers, points and
    heatmaps, and their error messages show what they were given (a list of 65536 positions
    took seconds to show, a message of megabytes)."""
    max_depth: int = 32
    """Deepest nesting of the lists and tuples the code builds (an array counts its
    dimensions): a list a loop wraps in another thousands of times is refused while it is
    built, before converting it to an array or showing it in an error message recurses."""

    def __post_init__(self) -> None:
        for name in (
            "max_code_chars",
            "max_loop",
            "max_steps",
            "max_calls",
            "max_moves",
            "max_expr_ops",
            "max_elements",
            "max_depth",
            "max_arg_elements",
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, Integral) or value < 1:
                raise ConfigError(
                    f"SandboxConfig.{name} must be a whole number >= 1, got {value!r}"
                )
        t = self.timeout_s
        if isinstance(t, bool) or not isinstance(t, Real) or not (0 < t < float("inf")):
            raise ConfigError(f"SandboxConfig.timeout_s must be a finite number > 0 [s], got {t!r}")


@dataclass(frozen=True)
class CheckedCode:
    """Code that passed :func:`check_code`, with its bounds known before running."""

    source: str
    tree: ast.Module
    steps: int
    """Evaluation steps with every loop unrolled."""
    calls: int
    """Robot API calls with every loop unrolled."""
    moves: int
    """Robot motions with every loop unrolled."""


@dataclass(frozen=True)
class CallRecord:
    """One robot API call the code made."""

    line: int
    method: str
    args: tuple
    kwargs: dict
    result: object


@dataclass(frozen=True)
class SandboxRun:
    """What a run did: every robot call in order, the steps taken and the time [s]."""

    calls: tuple[CallRecord, ...]
    steps: int
    elapsed_s: float


# ---------------------------------------------------------------------- static check
class _Checker:
    def __init__(self, config: SandboxConfig) -> None:
        self.config = config
        self.problems: list[str] = []
        self.defined: set[str] = set()
        self.steps = self.calls = self.moves = 0

    def refuse(self, node: ast.AST, what: str) -> None:
        self.problems.append(f"line {getattr(node, 'lineno', '?')}: {what}")

    def name_ok(self, node: ast.AST, name: str) -> bool:
        if name.startswith("__"):
            self.refuse(node, f"dunder name {name!r} is not allowed")
            return False
        return True

    # ----------------------------------------------------------- statements
    def body(self, stmts: list[ast.stmt], mult: int) -> None:
        for s in stmts:
            self.stmt(s, mult)

    def stmt(self, s: ast.stmt, mult: int) -> None:
        self.steps += mult
        if isinstance(s, ast.Expr):
            if isinstance(s.value, ast.Constant) and isinstance(s.value.value, str):
                return  # a docstring or a note: nothing runs
            if not isinstance(s.value, ast.Call):
                self.refuse(s, "a bare expression does nothing; call a robot method or assign")
            self.expr(s.value, mult)
        elif isinstance(s, ast.Assign):
            self.expr(s.value, mult)
            for t in s.targets:
                self.target(t)
        elif isinstance(s, ast.AugAssign):
            if type(s.op) not in _BINOPS:
                self.refuse(s, f"operator {type(s.op).__name__} is not allowed")
            if not isinstance(s.target, ast.Name):
                self.refuse(s, "augmented assignment only to a plain name")
            elif s.target.id not in self.defined:
                self.refuse(s, f"name {s.target.id!r} is used before it is assigned")
            self.expr(s.value, mult)
        elif isinstance(s, ast.For):
            n = self.range_len(s)
            if s.orelse:
                self.refuse(s, "for ... else is not allowed")
            self.target(s.target)
            self.body(s.body, mult * max(n, 0))
        elif isinstance(s, ast.Pass):
            pass
        else:
            self.refuse(s, f"{_REFUSED.get(type(s), type(s).__name__)} are not allowed")

    def range_len(self, s: ast.For) -> int:
        it = s.iter
        ok = (
            isinstance(it, ast.Call)
            and isinstance(it.func, ast.Name)
            and it.func.id == "range"
            and not it.keywords
            and 1 <= len(it.args) <= 3
        )
        if not ok:
            self.refuse(s, "a loop must be 'for NAME in range(n)' with literal integer bounds")
            return 0
        bounds = [_literal_int(a) for a in it.args]
        if any(b is None for b in bounds) or (len(bounds) == 3 and bounds[2] == 0):
            self.refuse(s, "range() bounds must be literal integers (a step other than 0)")
            return 0
        if any(abs(b) >= _MAX_INT for b in bounds):
            self.refuse(s, f"range() bounds beyond 2**63; at most {self.config.max_loop} loops")
            return 0
        n = len(range(*bounds))
        if n > self.config.max_loop:
            self.refuse(s, f"range() gives {n} iterations; at most {self.config.max_loop}")
        return n

    def target(self, t: ast.expr) -> None:
        if isinstance(t, ast.Name):
            if not self.name_ok(t, t.id):
                return
            if t.id in (ROBOT_NAME, "range"):
                self.refuse(t, f"{t.id!r} cannot be assigned")
                return
            self.defined.add(t.id)
        elif isinstance(t, (ast.Tuple, ast.List)) and all(isinstance(e, ast.Name) for e in t.elts):
            for e in t.elts:
                self.target(e)
        else:
            self.refuse(t, "assign only to names (or a tuple of names)")

    # ----------------------------------------------------------- expressions
    def expr(self, e: ast.expr, mult: int) -> None:
        self.steps += mult
        if isinstance(e, ast.Constant):
            v = e.value
            if isinstance(v, int) and not isinstance(v, bool) and abs(v) >= _MAX_INT:
                self.refuse(e, "integer literals beyond 2**63 are not allowed")
                return
            if isinstance(v, bool) or v is None or isinstance(v, (int, float)):
                return
            if isinstance(v, str):
                if len(v) > self.config.max_string:
                    self.refuse(e, f"a string longer than {self.config.max_string} characters")
                return
            self.refuse(e, f"{type(v).__name__} literals are not allowed")
        elif isinstance(e, ast.Name):
            if not self.name_ok(e, e.id):
                return
            if e.id == ROBOT_NAME:
                self.refuse(e, "'robot' may only be used to call a method: robot.<method>(...)")
            elif e.id not in self.defined:
                self.refuse(
                    e,
                    f"name {e.id!r} is not defined (there are no builtins: call robot methods, "
                    f"one of {sorted(ROBOT_METHODS)})",
                )
        elif isinstance(e, ast.BinOp):
            if type(e.op) not in _BINOPS:
                sym = {ast.Pow: "**", ast.MatMult: "@", ast.LShift: "<<", ast.RShift: ">>"}
                self.refuse(
                    e, f"operator {sym.get(type(e.op), type(e.op).__name__)!r} is not allowed"
                )
            self.expr(e.left, mult)
            self.expr(e.right, mult)
        elif isinstance(e, ast.UnaryOp):
            if type(e.op) not in _UNARY:
                self.refuse(e, f"unary operator {type(e.op).__name__} is not allowed")
            self.expr(e.operand, mult)
        elif isinstance(e, (ast.Tuple, ast.List)):
            if len(e.elts) > 16:
                self.refuse(e, "tuple/list literals have at most 16 items")
            for x in e.elts:
                self.expr(x, mult)
        elif isinstance(e, ast.Subscript):
            if not isinstance(e.value, ast.Name) or _literal_int(e.slice) is None:
                self.refuse(e, "indexing only as name[integer literal]")
            else:
                self.expr(e.value, mult)
        elif isinstance(e, ast.Call):
            self.call(e, mult)
        elif isinstance(e, ast.Attribute):
            if self.name_ok(e, e.attr):
                self.refuse(
                    e,
                    f"attribute access '.{e.attr}' is not allowed (only robot.<method>(...) calls)",
                )
            if not (isinstance(e.value, ast.Name) and e.value.id == ROBOT_NAME):
                self.expr(e.value, mult)
        else:
            self.refuse(e, f"{_REFUSED.get(type(e), type(e).__name__)} are not allowed")

    def call(self, c: ast.Call, mult: int) -> None:
        f = c.func
        if isinstance(f, ast.Name):
            if not self.name_ok(c, f.id):
                return
            if f.id == "range":
                self.refuse(c, "range() only as the iterable of a for loop")
            else:
                self.refuse(
                    c,
                    f"calling {f.id!r} is not allowed; call robot methods: {sorted(ROBOT_METHODS)}",
                )
            return
        if not isinstance(f, ast.Attribute):
            self.refuse(c, "only robot.<method>(...) can be called")
            return
        if not isinstance(f.value, ast.Name):  # x().attr(...), a.b.c(...)
            self.expr(f, mult)
            return
        if f.value.id != ROBOT_NAME:
            self.refuse(c, f"attribute access '{f.value.id}.{f.attr}' is not allowed")
            return
        if not self.name_ok(c, f.attr):
            return
        if f.attr not in ROBOT_METHODS:
            self.refuse(
                c, f"robot.{f.attr} is not part of the robot API; valid: {sorted(ROBOT_METHODS)}"
            )
            return
        self.calls += mult
        if f.attr in ROBOT_MOVES:
            self.moves += mult
        for a in c.args:
            self.expr(a, mult)
        for k in c.keywords:
            if k.arg is None:
                self.refuse(c, "**keyword unpacking is not allowed")
                continue
            if self.name_ok(c, k.arg):
                self.expr(k.value, mult)


def _literal_int(node: ast.expr) -> int | None:
    if isinstance(node, ast.Constant) and type(node.value) is int:
        return node.value
    if (
        isinstance(node, ast.UnaryOp)
        and isinstance(node.op, ast.USub)
        and isinstance(node.operand, ast.Constant)
        and type(node.operand.value) is int
    ):
        return -node.operand.value
    return None


_CONTROL_NAMES = {0x00: "NUL", 0x08: "BS", 0x0D: "CR", 0x1B: "ESC", 0x7F: "DEL"}


def _hidden_characters(code: str) -> list[str]:
    """One problem per line with a control or format character other than newline and tab:
    such characters (a carriage return, an escape sequence, a bidirectional override) can
    make the listing a user reviews differ from the code that runs."""
    problems = []
    for n, line in enumerate(code.split("\n"), 1):
        for ch in line:
            if ch != "\t" and unicodedata.category(ch) in ("Cc", "Cf", "Zl", "Zp", "Cs"):
                name = _CONTROL_NAMES.get(ord(ch)) or unicodedata.name(ch, "control character")
                problems.append(
                    f"line {n}: character U+{ord(ch):04X} ({name}) is not allowed: only "
                    "printable characters, newlines and tabs, so the listing shows what runs"
                )
                break
    return problems


# Keywords that nest expressions as operators do: 'x = not not ... 1' with a thousand 'not's
# made the checker recurse past Python's limit (RecursionError) when only symbols were counted.
_KEYWORD_OPERATORS = frozenset(
    ("not", "and", "or", "in", "is", "if", "else", "for", "lambda", "await", "yield", "async")
)


def _operator_counts(code: str, limit: int) -> list[str]:
    """One problem per statement with more than ``limit`` operators (keywords such as ``not``
    included), brackets and dots (what makes an expression nest), counted on the tokens so that
    nothing recurses first."""
    problems, count = [], 0
    try:
        for tok in tokenize.generate_tokens(io.StringIO(code).readline):
            if tok.type == tokenize.NEWLINE:
                count = 0
            elif (tok.type == tokenize.OP and tok.string not in ",:;=)]}") or (
                tok.type == tokenize.NAME and tok.string in _KEYWORD_OPERATORS
            ):
                count += 1
                if count == limit + 1:
                    problems.append(
                        f"line {tok.start[0]}: the statement has more than {limit} operators "
                        "and brackets (nested too deeply); split it into several assignments"
                    )
    except (tokenize.TokenError, SyntaxError):
        pass  # ast.parse names the syntax error
    return problems


def check_code(code: str, config: SandboxConfig | None = None) -> CheckedCode:
    """Parse and check ``code``; :class:`CodeRejected` lists every refused construct."""
    config = config or SandboxConfig()
    if not isinstance(code, str):
        raise CodeRejected([f"code must be a string, got {type(code).__name__}"])
    if len(code) > config.max_code_chars:
        raise CodeRejected([f"code is {len(code)} characters; at most {config.max_code_chars}"])
    hidden = _hidden_characters(code)
    if hidden:
        raise CodeRejected(hidden)
    deep = _operator_counts(code, config.max_expr_ops)
    if deep:
        raise CodeRejected(deep)
    try:
        tree = ast.parse(code, mode="exec")
    except SyntaxError as e:
        raise CodeRejected([f"line {e.lineno}: syntax error: {e.msg}"]) from None
    except (RecursionError, MemoryError, ValueError) as e:
        raise CodeRejected([f"the code cannot be parsed: {type(e).__name__}: {e}"]) from None
    checker = _Checker(config)
    checker.body(tree.body, 1)
    c = checker
    if not c.problems:
        for value, limit, what in (
            (c.steps, config.max_steps, "evaluation steps"),
            (c.calls, config.max_calls, "robot calls"),
            (c.moves, config.max_moves, "robot motions"),
        ):
            if value > limit:
                c.problems.append(f"the code makes {value} {what} with its loops; at most {limit}")
    if c.problems:
        raise CodeRejected(c.problems)
    return CheckedCode(code, tree, c.steps, c.calls, c.moves)


# ---------------------------------------------------------------------- interpreter
_NUMERIC = (Real, np.number, np.ndarray)
_MAX_INT = 2**63


def _is_heatmap(value) -> bool:
    """Whether ``value`` is an instance of :data:`HEATMAP_CLASS` (nothing is imported)."""
    module, _, name = HEATMAP_CLASS.rpartition(".")
    cls = getattr(sys.modules.get(module), name, None)
    return isinstance(cls, type) and isinstance(value, cls)


class _Interpreter:
    def __init__(self, robot, config: SandboxConfig, on_call) -> None:
        self.robot = robot
        self.config = config
        self.on_call = on_call
        self.env: dict[str, object] = {}
        self.calls: list[CallRecord] = []
        self.steps = 0
        self.t0 = time.monotonic()
        # id -> (list or tuple, its element count, its depth): the code cannot change a list it
        # built, so both are taken once, from its items' (the object is kept so its id stays)
        self.sizes: dict[int, tuple[object, int, int]] = {}

    def size(self, v) -> int:
        """Elements of ``v`` counted through nested lists and tuples (an array or a heatmap
        by its size); a walk of a sequence the code did not build stops above the budget."""
        known = self.sizes.get(id(v))
        if known is not None and known[0] is v:
            return known[1]
        if isinstance(v, np.ndarray):
            return v.size
        if _is_heatmap(v):
            return int(np.size(v.values))
        if not isinstance(v, (list, tuple)):
            return 1
        total, stack = 0, [v]
        while stack and total <= self.config.max_elements:
            x = stack.pop()
            if isinstance(x, (list, tuple)) and id(x) not in self.sizes:
                stack.extend(x)
            else:
                total += self.size(x)
        return total

    def depth(self, v) -> int:
        """How deep lists and tuples nest in ``v`` (an array: its dimensions; a sequence the
        code did not build: 1)."""
        known = self.sizes.get(id(v))
        if known is not None and known[0] is v:
            return known[2]
        if isinstance(v, np.ndarray):
            return v.ndim
        return 1 if isinstance(v, (list, tuple)) else 0

    def built(self, node: ast.AST, seq: list | tuple):
        """``seq`` (a list or tuple the code just built), within the memory budget and the
        nesting limit (a list wrapped in another thousands of times made the robot API's
        error message, a repr, raise RecursionError)."""
        n = sum(self.size(x) for x in seq)
        if n > self.config.max_elements:
            raise SandboxLimit(
                f"line {node.lineno}: a list of {n} elements (nested lists counted through); "
                f"at most {self.config.max_elements}"
            )
        depth = 1 + max((self.depth(x) for x in seq), default=0)
        if depth > self.config.max_depth:
            raise SandboxLimit(
                f"line {node.lineno}: lists nested {depth} deep; at most {self.config.max_depth}"
            )
        self.sizes[id(seq)] = (seq, n, depth)
        return seq

    def tick(self, node: ast.AST) -> None:
        self.steps += 1
        if self.steps > self.config.max_steps:
            raise SandboxLimit(f"line {node.lineno}: more than {self.config.max_steps} steps")
        if time.monotonic() - self.t0 > self.config.timeout_s:
            raise SandboxLimit(
                f"line {node.lineno}: the run took longer than {self.config.timeout_s} s"
            )

    def body(self, stmts) -> None:
        for s in stmts:
            self.stmt(s)

    def stmt(self, s: ast.stmt) -> None:
        self.tick(s)
        if isinstance(s, ast.Expr):
            if not isinstance(s.value, ast.Constant):
                self.expr(s.value)
        elif isinstance(s, ast.Assign):
            value = self.expr(s.value)
            for t in s.targets:
                self.assign(t, value)
        elif isinstance(s, ast.AugAssign):
            value = self.binop(s, s.op, self.lookup(s, s.target.id), self.expr(s.value))
            self.env[s.target.id] = value
        elif isinstance(s, ast.For):
            for i in range(*[_literal_int(a) for a in s.iter.args]):
                self.assign(s.target, i)
                self.body(s.body)

    def lookup(self, node: ast.AST, name: str):
        if name not in self.env:  # assigned only inside a loop that ran no iteration
            raise SandboxError(f"line {node.lineno}: name {name!r} has no value")
        return self.env[name]

    def assign(self, t: ast.expr, value) -> None:
        if isinstance(t, ast.Name):
            self.env[t.id] = value
            return
        try:
            values = list(value)
        except TypeError:
            raise SandboxError(f"line {t.lineno}: cannot unpack {type(value).__name__}") from None
        if len(values) != len(t.elts):
            raise SandboxError(
                f"line {t.lineno}: unpacking {len(values)} values into {len(t.elts)} names"
            )
        for e, v in zip(t.elts, values, strict=True):
            self.env[e.id] = v

    def expr(self, e: ast.expr):
        self.tick(e)
        if isinstance(e, ast.Constant):
            return e.value
        if isinstance(e, ast.Name):
            return self.lookup(e, e.id)
        if isinstance(e, ast.BinOp):
            return self.binop(e, e.op, self.expr(e.left), self.expr(e.right))
        if isinstance(e, ast.UnaryOp):
            v = self.expr(e.operand)
            if not isinstance(v, _NUMERIC) or isinstance(v, bool):
                raise SandboxError(f"line {e.lineno}: unary minus on {type(v).__name__}")
            return _UNARY[type(e.op)](v)
        if isinstance(e, ast.Tuple):
            return self.built(e, tuple(self.expr(x) for x in e.elts))
        if isinstance(e, ast.List):
            return self.built(e, [self.expr(x) for x in e.elts])
        if isinstance(e, ast.Subscript):
            v = self.lookup(e, e.value.id)
            if not isinstance(v, (tuple, list, np.ndarray)):
                raise SandboxError(f"line {e.lineno}: {type(v).__name__} cannot be indexed")
            try:
                return v[_literal_int(e.slice)]
            except (IndexError, OverflowError) as err:  # an index beyond any C integer
                raise SandboxError(f"line {e.lineno}: index out of range ({err})") from None
        return self.call(e)

    def binop(self, node: ast.AST, op: ast.operator, a, b):
        arrays = isinstance(a, np.ndarray) or isinstance(b, np.ndarray)
        for v in (a, b):
            seq_ok = arrays and isinstance(v, (tuple, list))
            ok = isinstance(v, _NUMERIC) or seq_ok or _is_heatmap(v)
            if not ok or isinstance(v, bool):
                raise SandboxError(
                    f"line {node.lineno}: arithmetic on {type(v).__name__} is not allowed "
                    "(numbers, arrays and heatmaps only)"
                )
        if arrays:
            self.check_broadcast(node, a, b)
        try:
            with np.errstate(all="raise", under="ignore"):  # heat products may underflow to 0
                out = _BINOPS[type(op)](a, b)
        except (ArithmeticError, ValueError, TypeError, FloatingPointError) as err:
            raise SandboxError(f"line {node.lineno}: {type(err).__name__}: {err}") from None
        if isinstance(out, int) and abs(out) >= _MAX_INT:
            raise SandboxError(f"line {node.lineno}: integer result beyond 2**63")
        return out

    def check_broadcast(self, node: ast.AST, a, b) -> None:
        """Refuse an array operation whose result would outgrow both operands and the budget
        (a nested list times an array broadcasts to the product of their shapes)."""
        try:
            shape = np.broadcast_shapes(np.shape(a), np.shape(b))
        except ValueError as err:  # ragged lists, shapes that do not broadcast
            raise SandboxError(f"line {node.lineno}: ValueError: {err}") from None
        n = int(np.prod(shape, dtype=object))
        if n > max(self.config.max_elements, self.size(a), self.size(b)):
            raise SandboxLimit(
                f"line {node.lineno}: the result would have {n} elements (shape {shape}); at "
                f"most {self.config.max_elements}"
            )

    def call(self, c: ast.Call):
        method = c.func.attr
        args = tuple(self.expr(a) for a in c.args)
        kwargs = {k.arg: self.expr(k.value) for k in c.keywords}
        fn = getattr(self.robot, method, None)
        if fn is None or not callable(fn):
            raise SandboxError(f"line {c.lineno}: this robot has no method {method!r}")
        for v in (*args, *kwargs.values()):
            n = self.size(v) if isinstance(v, (list, tuple)) else 0
            if n > self.config.max_arg_elements:
                raise SandboxLimit(
                    f"line {c.lineno}: robot.{method} given a list of {n} elements; at most "
                    f"{self.config.max_arg_elements} (robot methods take names, numbers, "
                    "points and heatmaps)"
                )
        try:
            result = fn(*args, **kwargs)
        except TabletopError:
            raise
        except (TypeError, ValueError, ArithmeticError, LookupError) as err:
            # arguments the code chose that the robot API could not take (a path with a NUL
            # in it raised ValueError from the file system): the code's error, on its line
            raise SandboxError(
                f"line {c.lineno}: robot.{method}: {type(err).__name__}: {err}"
            ) from None
        rec = CallRecord(c.lineno, method, args, kwargs, result)
        self.calls.append(rec)
        if self.on_call is not None:
            self.on_call(rec)
        # a call may outlast the limit on its own (a motion): the run stops after it
        if time.monotonic() - self.t0 > self.config.timeout_s:
            raise SandboxLimit(
                f"line {c.lineno}: the run took longer than {self.config.timeout_s} s "
                f"(robot.{method} ended after the limit; nothing after it ran)"
            )
        return result


def run_code(
    code: str | CheckedCode,
    robot,
    config: SandboxConfig | None = None,
    on_call: Callable[[CallRecord], None] | None = None,
) -> SandboxRun:
    """Check ``code`` (unless already checked) and run it against ``robot``.

    ``robot`` is bound to the name ``robot``; nothing else is in scope. Errors: CodeRejected
    (nothing ran), SandboxLimit (stopped), SandboxError (a runtime error with its line), and the
    robot API's own errors (e.g. GoalNotFound) unchanged.
    """
    config = config or SandboxConfig()
    checked = code if isinstance(code, CheckedCode) else check_code(code, config)
    interp = _Interpreter(robot, config, on_call)
    interp.body(checked.tree.body)
    return SandboxRun(tuple(interp.calls), interp.steps, time.monotonic() - interp.t0)
