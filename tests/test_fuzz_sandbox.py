"""Fuzzing the sandbox with generated programs: each ends in a result or a typed error.

Programs come from five generators: token soups, arbitrary text (control characters, format
characters and lone surrogates included), a grammar of Python expressions and statements
(hostile: imports, dunders, builtins, comprehensions, lambdas, huge literals, escapes), a
grammar of the subset the sandbox allows (so that most programs run and reach the robot API),
and memory bombs. Each goes through :func:`check_code` and :func:`run_code` against the robot
API on a real map (the instruction suite's reference map) through the tracer generated code
sees, and must end in a :class:`SandboxRun` or a :class:`TabletopError` naming the problem:
never another exception, never a hang (a hard alarm and a Hypothesis deadline), never a memory
blow-up (the bombs run under ``tracemalloc``); refused code never moves the robot, and accepted
code never does more steps, calls or motions than the checker counted.

The runs are derandomized (the same inputs on every run); :data:`EXAMPLES` holds the number of
generated inputs of each test and :data:`TOTAL_EXAMPLES` their sum.
"""

from __future__ import annotations

import contextlib
import re
import signal
import tracemalloc
import unicodedata

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from tabletop.errors import TabletopError
from tabletop.language import CodeRejected, SandboxConfig, SandboxError, check_code, run_code
from tabletop.language.run import TracingRobot
from tabletop.language.sandbox import ROBOT_METHODS
from tabletop.language.suite import PointRobot, load_suite, reference_map, write_suite_images

# the parser warns of invalid escapes ('\\q') in generated strings: expected, not a failure
pytestmark = pytest.mark.filterwarnings("ignore:invalid .*escape sequence:DeprecationWarning")

#: Generated inputs per test (Hypothesis ``max_examples``; derandomized, so the same each run).
EXAMPLES = {
    "token_soup": 1000,
    "text": 1000,
    "hostile_grammar": 1000,
    "allowed_grammar": 800,
    "memory_bombs": 400,
}
#: Generated inputs of this file in all.
TOTAL_EXAMPLES = sum(EXAMPLES.values())

#: The limits the programs run under: the defaults, with a short wall-clock limit.
CONFIG = SandboxConfig(timeout_s=2.0)
#: Seconds after which one example counts as a hang (the sandbox's own limit is 2 s).
HANG_S = 20
#: Most memory [bytes] one memory-bomb example may allocate at its peak.
PEAK_BYTES = 256 * 2**20


def _settings(name: str):
    return settings(
        max_examples=EXAMPLES[name],
        deadline=10_000,  # [ms]; the sandbox stops a run at 2 s, the alarm at HANG_S
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )


# ---------------------------------------------------------------------- the robot
class MovingRobot(PointRobot):
    """A point robot on the reference map that records every motion it is sent."""

    def __init__(self, avlmap, start) -> None:
        super().__init__(avlmap, start)
        self.moves: list[np.ndarray] = []

    def move_to(self, pos):
        self.moves.append(np.array(pos, dtype=np.float64))
        return super().move_to(pos)


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """The reference map (real object, sound and area queries), the start, an image dir."""
    suite = load_suite()
    images = write_suite_images(suite, tmp_path_factory.mktemp("images"))
    return reference_map(suite), suite.start, images


class Hang(Exception):
    """Raised by the alarm: one example ran longer than :data:`HANG_S`."""


@contextlib.contextmanager
def _alarm(seconds: float):
    def ring(signum, frame):
        raise Hang(f"the example ran longer than {seconds} s")

    old = signal.signal(signal.SIGALRM, ring)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


# ---------------------------------------------------------------------- the property
_LINE = re.compile(r"line (\d+)")
_WHOLE_CODE = ("code is ", "code must be a string", "the code makes ", "the code cannot be parsed")
_HIDDEN = ("Cc", "Cf", "Zl", "Zp", "Cs")


def _assert_names_a_line(problem: str, code) -> None:
    if problem.startswith(_WHOLE_CODE):
        return
    m = _LINE.match(problem)
    assert m, f"a refusal that names no line: {problem!r}"
    n_lines = code.count("\n") + 1
    assert 1 <= int(m.group(1)) <= n_lines + 1, (problem, n_lines)


def _assert_listing_is_what_runs(code: str) -> None:
    """Accepted code holds no character that could make its listing differ from what runs:
    no control or format character but newline and tab, no line break but newline."""
    for line in code.split("\n"):
        assert len(line.splitlines()) <= 1, repr(line)
        hidden = [c for c in line if c != "\t" and unicodedata.category(c) in _HIDDEN]
        assert not hidden, (hidden, line)


def outcome(code, world, *, config: SandboxConfig = CONFIG) -> str:
    """Check and run ``code``; assert the sandbox's promises; return what happened:
    ``"rejected"``, ``"ran"``, ``"stopped"`` (SandboxError) or ``"robot error"``."""
    avlmap, start, images = world
    robot = MovingRobot(avlmap, start)
    tracer = TracingRobot(robot, image_dir=images)
    with _alarm(HANG_S):
        try:
            checked = check_code(code, config)
        except CodeRejected as e:
            assert e.problems, "a refusal without a problem"
            for p in e.problems:
                _assert_names_a_line(p, code)
            with pytest.raises(CodeRejected):  # the runner refuses it too, before anything runs
                run_code(code, tracer, config)
            assert robot.moves == [], "refused code moved the robot"
            return "rejected"
        _assert_listing_is_what_runs(code)
        try:
            run = run_code(checked, tracer, config)
        except SandboxError as e:
            assert _LINE.search(str(e)), f"a runtime error that names no line: {e}"
            what = "stopped"
        except TabletopError as e:  # the robot API's own (GoalNotFound, ConfigError, ...)
            assert str(e).strip(), f"{type(e).__name__} without a message"
            what = "robot error"
        else:
            assert run.steps <= checked.steps
            assert len(run.calls) <= checked.calls
            what = "ran"
    assert len(robot.moves) <= checked.moves, "more motions than the checker counted"
    return what


# ---------------------------------------------------------------------- vocabularies
NAMES = ("v0", "v1", "v2", "v3")
METHODS = tuple(sorted(ROBOT_METHODS))
NOT_METHODS = ("close", "reset", "map", "controller", "_heatmap", "__init__", "spatial", "robot")
BUILTINS = (
    "open", "eval", "exec", "compile", "getattr", "setattr", "delattr", "vars", "globals",
    "locals", "__import__", "print", "len", "type", "object", "range", "iter", "next", "input",
    "breakpoint", "help", "dir", "id", "super", "memoryview", "bytes", "bytearray", "chr", "ord",
    "sum", "max", "list", "dict", "set", "tuple", "str", "int", "float", "format", "repr",
    "isinstance", "exit", "quit", "__builtins__", "__loader__", "__spec__", "np", "os", "sys",
)  # fmt: skip
ATTRS = (
    "__class__", "__bases__", "__base__", "__mro__", "__subclasses__", "__globals__",
    "__builtins__", "__dict__", "__code__", "__closure__", "__getattribute__", "__reduce_ex__",
    "__init__", "__self__", "__func__", "__module__", "__name__", "gi_frame", "gi_code",
    "f_back", "f_globals", "f_locals", "tb_frame", "cr_frame", "mro", "format", "values",
    "grid", "map", "controller", "shape", "real", "T", "tolist", "copy", "close", "robot",
)  # fmt: skip
OBJECT_WORDS = (
    "mug", "red mug", "duck", "teddy bear", "soccer ball", "jenga block", "tray area",
    "dog barking", "cat meowing", "piano playing", "the moon", "giraffe", "", " ", "\t",
    "goal_mug.png", "goals/ball.png", "../goal_mug.png", "/etc/passwd", "nope.png",
)  # fmt: skip
KEYWORDS = (
    "obj", "sound", "img", "area", "primary", "name", "pos", "distance_m", "heatmap", "a", "b",
    "dx", "dy", "path", "x", "__class__",
)  # fmt: skip
BINOPS = ("+", "-", "*", "/", "//", "%", "**", "<<", ">>", "@", "&", "|", "^", "<", "==", "!=",
          ">=", "and", "or", "in", "is", "not in", "is not")  # fmt: skip
ALLOWED_BINOPS = ("+", "-", "*", "/", "//", "%")
UNARY = ("-", "+", "~", "not ")
BIG_INTS = (
    2**31, 2**62, 2**63 - 1, 2**63, -(2**63), 2**64, 10**18, 10**19, 10**30, 10**100, 10**4299,
)  # fmt: skip
ESCAPES = (
    r"\x00", r"\x1b[2K", r"\r", r"\b", r"\x7f", r"\u202e", r"\u2066", r"\u200b", r"\ufeff",
    r"\ud800", r"\U0001F600", r"\N{BELL}", r"\N{RIGHT-TO-LEFT OVERRIDE}", r"\0", r"\777",
    r"\q", "\\", r"\x", r"\N{nonexistent}",
)  # fmt: skip
# raw characters, placed unescaped in the source
HIDDEN_CHARS = ("\x00", "\x1b", "\r", "\x08", "\x0b", "\x0c", "\x7f", "\x85", "\u202e", "\u2066",
                "\u200b", "\u2028", "\u2029", "\ufeff", "\ud800", "\U000e0041")  # fmt: skip

# drawn by index: a strategy's repr holding a 4300-digit number would be printed in full
big_ints = st.integers(0, len(BIG_INTS) - 1).map(BIG_INTS.__getitem__)
ints = st.one_of(st.integers(-3, 120), big_ints, st.integers(-(2**70), 2**70)).map(str)
int_spellings = st.one_of(
    ints,
    st.sampled_from(
        ("0x7fffffffffffffff", "0x8000000000000000", "1_000_000", "0b1", "0o777", "00", "1e3",
         "1j", "9" * 50, "9" * 4301, "-0", "True", "False")
    ),
)  # fmt: skip
floats = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.sampled_from(("1e308", "1e309", "-1e309", "1e-320", "0.0", "-0.0", "1e999", ".5", "5.")),
)
texts = st.text(max_size=12)
strings = st.one_of(
    st.sampled_from(OBJECT_WORDS).map(repr),
    texts.map(repr),
    st.lists(st.sampled_from(ESCAPES) | st.sampled_from(OBJECT_WORDS), max_size=4).map(
        lambda parts: "'" + "".join(parts) + "'"
    ),
    st.tuples(st.sampled_from(HIDDEN_CHARS), st.sampled_from(OBJECT_WORDS)).map(
        lambda t: f"'{t[1]}{t[0]}'"
    ),
    st.integers(490, 520).map(lambda n: "'" + "x" * n + "'"),
    st.sampled_from(("b'x'", "r'\\x00'", "u'mug'", "'''a\nb'''", "f'{1}'", "'a' 'b'", "'")),
)
other_leaves = st.sampled_from(("None", "...", "True", "robot", "range", "__builtins__", "nan"))


def _names(allowed: bool):
    return st.sampled_from(NAMES) if allowed else st.sampled_from(NAMES + BUILTINS)


def _robot_call(sub, allowed: bool):
    methods = st.sampled_from(METHODS)
    if not allowed:
        methods = methods | st.sampled_from(NOT_METHODS + ATTRS)
    args = st.lists(sub | st.sampled_from(OBJECT_WORDS).map(repr), max_size=3)
    kwargs = st.lists(st.tuples(st.sampled_from(KEYWORDS), sub), max_size=2)
    return st.tuples(methods, args, kwargs).map(
        lambda t: f"robot.{t[0]}(" + ", ".join(list(t[1]) + [f"{k}={v}" for k, v in t[2]]) + ")"
    )


def _join(xs, opening: str, closing: str, trailing: str = "") -> str:
    return opening + ", ".join(xs) + (trailing if len(xs) == 1 else "") + closing


def _expressions(allowed: bool):
    """Expression source text. ``allowed``: only constructs the sandbox accepts (so programs
    get to run); otherwise any Python expression, hostile ones favoured."""
    leaf = st.one_of(ints, floats, strings, _names(allowed))
    if not allowed:
        leaf = leaf | int_spellings | other_leaves
    ops = ALLOWED_BINOPS if allowed else BINOPS
    index = st.integers(-5, 5).map(str) | (big_ints.map(str))

    def extend(sub):
        parts = [
            st.tuples(sub, st.sampled_from(ops), sub).map(lambda t: f"({t[0]} {t[1]} {t[2]})"),
            st.tuples(sub, st.sampled_from(ops), sub).map(lambda t: f"{t[0]} {t[1]} {t[2]}"),
            st.tuples(st.sampled_from(UNARY[:2] if allowed else UNARY), sub).map("".join),
            st.lists(sub, max_size=18).map(lambda xs: _join(xs, "[", "]")),
            st.lists(sub, max_size=18).map(lambda xs: _join(xs, "(", ")", ",")),
            st.tuples(_names(allowed), index).map(lambda t: f"{t[0]}[{t[1]}]"),
            _robot_call(sub, allowed),
            st.tuples(sub, big_ints).map(lambda t: f"[{t[0]}] * {t[1]}"),
        ]
        if not allowed:
            parts += [
                st.tuples(sub, st.sampled_from(ATTRS)).map(lambda t: f"{t[0]}.{t[1]}"),
                st.tuples(st.sampled_from(BUILTINS), st.lists(sub, max_size=3)).map(
                    lambda t: f"{t[0]}({', '.join(t[1])})"
                ),
                st.tuples(sub, sub).map(lambda t: f"[{t[0]} for v0 in {t[1]}]"),
                st.tuples(sub, sub).map(lambda t: f"{{v0: {t[0]} for v0 in {t[1]}}}"),
                st.tuples(sub, sub).map(lambda t: f"{{{t[0]} for v0 in range({t[1]})}}"),
                st.tuples(sub, sub).map(lambda t: f"({t[0]} for v0 in {t[1]})"),
                sub.map(lambda a: f"(lambda v0: {a})"),
                sub.map(lambda a: f"(lambda: {a})()"),
                st.tuples(sub, sub, sub).map(lambda t: f"({t[0]} if {t[1]} else {t[2]})"),
                sub.map(lambda a: f"f'{{{a}}}'"),
                sub.map(lambda a: f'f"{{{a}!r:>10}}"'),
                st.sampled_from(ATTRS).map(lambda a: f"'{{0.{a}}}'.format(v0)"),
                st.sampled_from(ATTRS).map(lambda a: f"'%s' % v0.{a}"),
                st.tuples(sub, sub).map(lambda t: f"{{{t[0]}: {t[1]}}}"),
                st.lists(sub, min_size=1, max_size=3).map(lambda xs: _join(xs, "{", "}")),
                sub.map(lambda a: f"(v0 := {a})"),
                sub.map(lambda a: f"robot.move_to(*{a})"),
                sub.map(lambda a: f"robot.get_major_map(**{a})"),
                st.tuples(sub, index, index).map(lambda t: f"{t[0]}[{t[1]}:{t[2]}]"),
                sub.map(lambda a: f"(yield {a})"),
                sub.map(lambda a: f"(await {a})"),
                sub.map(lambda a: f"{a}()"),
                sub.map(lambda a: f"{a}[0]"),
                st.tuples(sub, st.integers(1, 60)).map(lambda t: "(" * t[1] + t[0] + ")" * t[1]),
            ]
        return st.one_of(*parts)

    return st.recursive(leaf, extend, max_leaves=12 if allowed else 8)


HOSTILE_STATEMENTS = (
    "import os",
    "import os.path as p",
    "from os import system",
    "from . import x",
    "from tabletop import robot",
    "import importlib",
    "__import__('os')",
    "global v0",
    "nonlocal v0",
    "del v0",
    "return 1",
    "raise SystemExit",
    "assert False",
    "break",
    "continue",
    "yield 1",
    "exec('1')",
    "eval('1')",
    "open('/etc/passwd')",
    "v0 = vars()",
    "v0 = globals()['__builtins__']",
    "robot.map = None",
    "robot.x += 1",
    "v0[0] = 1",
    "v0.attr = 1",
    "*v0, v1 = (1, 2)",
    "v0 = v1 = 2",
    "v0: int = 1",
    "async def f(): pass",
    "@robot.move_to\ndef f(): pass",
    "v0 = (yield)",
    "print(robot)",
    "type(robot).__subclasses__()",
    "robot.__class__.__bases__[0].__subclasses__()",
    "v0 = (i for i in ()).gi_frame.f_back.f_globals",
    "v0 = '{0.__class__.__init__.__globals__}'.format(robot)",
)


def _statements(allowed: bool):
    """Statement source text (a block of lines, unindented)."""
    expr = _expressions(allowed)
    name = st.sampled_from(NAMES) if allowed else st.sampled_from(NAMES + BUILTINS + ("robot",))
    range_args = st.one_of(
        st.integers(-5, 120).map(str),
        st.tuples(st.integers(-5, 20), st.integers(-5, 120)).map(lambda t: f"{t[0]}, {t[1]}"),
        st.tuples(st.integers(-5, 5), st.integers(-50, 50), st.integers(-3, 3)).map(
            lambda t: f"{t[0]}, {t[1]}, {t[2]}"
        ),
        big_ints.map(str),
    )
    if not allowed:
        range_args = range_args | expr
    simple = [
        st.tuples(name, expr).map(lambda t: f"{t[0]} = {t[1]}"),
        st.tuples(name, name, expr).map(lambda t: f"{t[0]}, {t[1]} = {t[2]}"),
        st.tuples(name, st.sampled_from(ALLOWED_BINOPS), expr).map(
            lambda t: f"{t[0]} {t[1]}= {t[2]}"
        ),
        _robot_call(expr, allowed),
        st.just("pass"),
        texts.map(lambda s: "# " + s.replace("\n", " ")),
        st.text(alphabet=st.sampled_from((*HIDDEN_CHARS, "a", " ", "#")), max_size=6).map(
            lambda s: "# " + s
        ),
        strings.map(lambda s: s),  # a docstring
    ]
    if not allowed:
        simple += [
            expr,
            st.sampled_from(HOSTILE_STATEMENTS),
        ]
    simple_stmt = st.one_of(*simple)

    def extend(body):
        indented = body.map(lambda b: "\n".join("    " + line for line in b.split("\n")))
        parts = [
            st.tuples(name, range_args, indented).map(
                lambda t: f"for {t[0]} in range({t[1]}):\n{t[2]}"
            ),
            st.lists(body, min_size=1, max_size=3).map("\n".join),
        ]
        if not allowed:
            parts += [
                st.tuples(expr, indented).map(lambda t: f"while {t[0]}:\n{t[1]}"),
                st.tuples(expr, indented).map(lambda t: f"if {t[0]}:\n{t[1]}"),
                indented.map(lambda b: f"try:\n{b}\nexcept Exception:\n    pass"),
                indented.map(lambda b: f"with open('x') as f:\n{b}"),
                indented.map(lambda b: f"def f(v0=robot):\n{b}"),
                indented.map(lambda b: f"class A(object):\n{b}"),
                st.tuples(name, expr, indented).map(lambda t: f"for {t[0]} in {t[1]}:\n{t[2]}"),
                indented.map(lambda b: f"for v0 in range(3):\n{b}\nelse:\n    pass"),
            ]
        return st.one_of(*parts)

    return st.recursive(simple_stmt, extend, max_leaves=6 if allowed else 4)


# the allowed programs start by giving each name a value of another kind (an array, a heatmap,
# a number, a list), so that their statements get past "not defined" to the interpreter
PRELUDE = (
    "v0 = robot.current_position()\nv1 = robot.get_major_map(obj='mug')\nv2 = 0.1\n"
    "v3 = [0.3, 0.0, 0.2]\n"
)


def _programs(allowed: bool):
    program = st.lists(_statements(allowed), min_size=1, max_size=4).map("\n".join)
    return program.map(lambda code: PRELUDE + code) if allowed else program


# ---------------------------------------------------------------------- memory bombs
def _nest(levels: int, width: int, leaf: str) -> str:
    lines = [f"l0 = {leaf}"]
    lines += [f"l{i} = [{', '.join([f'l{i - 1}'] * width)}]" for i in range(1, levels + 1)]
    return "\n".join(lines) + f"\na = l{levels}"


BOMB_LEAVES = (
    "[0]", "0", "0.5", "'x'", "robot.current_position()", "robot.get_major_map(obj='mug')",
    "(0, 0, 0)", "[[0, 0, 0]]",
)  # fmt: skip
BOMB_USES = (
    "robot.move_to(a)", "p = robot.current_position()\nx = p * a",
    "p = robot.current_position()\nx = a + p", "p = robot.current_position()\nx = a - p * 2",
    "robot.get_pos(a)", "robot.get_major_map(obj=a)", "robot.move_north(a)",
    "h = robot.get_major_map(obj='mug')\nx = h * a",
    "h = robot.get_major_map(obj='mug')\nx = a * h",
    "b, c = a", "x = a[0]", "x = -a", "x = a * 1000000000", "x = a + a", "x = a * a",
    "x = [a, a, a, a, a, a, a, a, a, a, a, a, a, a, a, a]", "x = (a, a)", "robot.offset(a, a)",
    "robot.move_in_between(a, a)", "pass",
)  # fmt: skip
BOMB_ONE_LINERS = (
    "x = [0] * 10**9", "x = [0] * 1000000000", "x = 'x' * 10**10", "x = 'x' * 10000000000",
    "x = bytes(10**10)", "x = bytearray(10000000000)", "x = 2**10**10", "x = 1 << 10**9",
    "x = 1 << 1000000000", "x = [0 for _ in range(10**9)]", "x = {i: i for i in range(10**9)}",
    "x = {i for i in range(10**9)}", "x = sum(range(10**18))", "x = list(range(10**9))",
    "x = '%0999999999d' % 1", "x = '{:>9999999999}'.format(1)", "x = f'{1:>9999999999}'",
    "x = 9**9**9", "x = (1,) * 10**9", "x = [[0] * 10**5] * 10**5", "x = 'ab' * 100000000",
    "x = 10000000000 * [0]", "x = 99999999999999999999 * 99999999999999999999",
)  # fmt: skip


@st.composite
def memory_bombs(draw) -> str:
    kind = draw(st.sampled_from(("nest", "double", "deepen", "grow", "one_liner")))
    if kind == "one_liner":
        return draw(st.sampled_from(BOMB_ONE_LINERS))
    leaf = draw(st.sampled_from(BOMB_LEAVES))
    if kind == "nest":
        setup = _nest(draw(st.integers(1, 8)), draw(st.integers(1, 16)), leaf)
    elif kind == "double":
        n, k = draw(st.integers(1, 100)), draw(st.integers(2, 16))
        setup = f"a = {leaf}\nfor _ in range({n}):\n    a = [{', '.join(['a'] * k)}]"
    elif kind == "deepen":  # one list inside another, up to 6000 deep
        n, m = draw(st.integers(1, 100)), draw(st.integers(1, 60))
        setup = f"a = {leaf}\nfor _ in range({n}):\n    for _ in range({m}):\n        a = [a]"
    else:  # a value multiplied by itself or grown by a factor, again and again
        n = draw(st.integers(1, 100))
        op = draw(st.sampled_from(("a * a", "a * 1e300", "a + a", "a * 3", "[a, a] * a")))
        setup = f"a = {leaf}\nfor _ in range({n}):\n    a = {op}"
    return setup + "\n" + draw(st.sampled_from(BOMB_USES)) + "\n"


# ---------------------------------------------------------------------- the tests
TOKENS = (
    *METHODS,
    *HIDDEN_CHARS,
    "robot", ".", "(", ")", "[", "]", "{", "}", ",", ":", "=", "+", "-", "*", "**", "/", "//",
    "%", "@", "<<", ">>", "~", "not", "and", "or", "if", "else", "for", "in", "range", "while",
    "lambda", "import", "from", "def", "class", "return", "yield", "await", "async", "with",
    "as", "try", "except", "raise", "del", "global", "pass", ":=", "...", "\\", "#", "'", '"',
    "'''", "f'", "b'", "\n", "\n    ", "\n        ", "\t", ";", "0", "1", "-1", "1e309",
    "9223372036854775808", "'mug'", "'\\x1b'", "v0", "v1", "_", "__class__", "__import__",
    "__builtins__", "open", "eval", "exec", "getattr", "print", "gi_frame", "f_back",
)  # fmt: skip


@_settings("token_soup")
@given(
    tokens=st.lists(st.sampled_from(TOKENS), max_size=40),
    gaps=st.lists(st.sampled_from(("", " ", "  ", "\n")), min_size=40, max_size=40),
)
def test_token_soups_end_in_a_result_or_a_typed_error(world, tokens, gaps):
    code = "".join(t + g for t, g in zip(tokens, gaps, strict=False))
    event(outcome(code, world))


@_settings("text")
@given(
    code=st.one_of(
        st.text(max_size=200),
        st.text(alphabet=st.characters(codec=None, categories=["Cc", "Cf", "Cs", "Zl", "Zp"])),
        st.tuples(st.text(max_size=40), st.sampled_from(HIDDEN_CHARS), st.text(max_size=40)).map(
            "".join
        ),
        st.binary(max_size=40),
        st.none(),
        st.integers(),
    )
)
def test_any_text_ends_in_a_result_or_a_typed_error(world, code):
    what = outcome(code, world)
    event(what)
    if not isinstance(code, str):
        assert what == "rejected"


@_settings("hostile_grammar")
@given(code=_programs(allowed=False))
def test_generated_python_ends_in_a_result_or_a_typed_error(world, code):
    event(outcome(code, world))


@_settings("allowed_grammar")
@given(code=_programs(allowed=True))
def test_generated_sandbox_code_runs_or_stops_with_a_typed_error(world, code):
    event(outcome(code, world))


@_settings("memory_bombs")
@given(code=memory_bombs())
def test_memory_bombs_end_in_a_typed_error_within_the_budget(world, code):
    tracemalloc.start()
    try:
        event(outcome(code, world))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < PEAK_BYTES, f"{peak / 2**20:.0f} MiB at the peak"


# ---------------------------------------------------------------------- the generators
def test_the_generators_reach_every_outcome(world):
    """The property is not vacuous: the allowed grammar's programs do run, reach the robot
    and move it, and hostile ones are refused (a fixed sample, drawn once)."""
    seen = {"rejected": 0, "ran": 0, "stopped": 0, "robot error": 0}
    for code in [
        "v0 = robot.get_pos('mug')\nrobot.move_to(v0)",
        "v0 = 1\nfor v1 in range(3):\n    v0 += v1\nrobot.move_north(v0 / 100)",
        "v0 = robot.get_pos('')",
        "v0 = [1, 2]\nv1 = v0[5]",
        "import os",
    ]:
        seen[outcome(code, world)] += 1
    assert all(seen.values()), seen
    assert sum(EXAMPLES.values()) == TOTAL_EXAMPLES >= 1000
