"""The sandbox: hostile and malformed code is refused before anything runs, and the robot does
not move; allowed code runs with its limits."""

import time

import numpy as np
import pytest

from tabletop.language import (
    CodeRejected,
    SandboxConfig,
    SandboxError,
    SandboxLimit,
    check_code,
    run_code,
)
from tabletop.language.sandbox import ROBOT_METHODS
from tabletop.robot.api import RobotAPI
from tabletop.robot.primitives import PRIMITIVES


class CountingRobot(RobotAPI):
    """An embodiment without a body: counts every motion and every API call it gets.

    The map queries of RobotAPI need a map; the hostile snippets must never get that far."""

    def __init__(self, delay_s=0.0):
        super().__init__(avlmap=None)
        self.moves = []
        self.delay_s = delay_s
        self.pos = np.array([0.3, 0.0, 0.3])

    def move_to(self, pos):
        time.sleep(self.delay_s)
        self.moves.append(np.array(pos, float))
        self.pos = np.array(pos, float)
        return "moved"

    def current_position(self):
        return self.pos.copy()


# Every entry must be refused by the static check (CodeRejected) with the robot untouched.
# (snippet, a word the refusal must contain)
HOSTILE = [
    ("import os\nos.system('rm -rf /')", "import"),
    ("from subprocess import run\nrun(['ls'])", "import"),
    ("__import__('os').system('id')", "dunder"),
    ("open('/etc/passwd').read()", "attribute"),
    ("x = open('/tmp/pwned', 'w')", "calling 'open'"),
    ("eval('1+1')", "calling 'eval'"),
    ("exec('import os')", "calling 'exec'"),
    ("compile('1', 'f', 'exec')", "calling 'compile'"),
    ("getattr(robot, 'map')", "calling 'getattr'"),
    ("robot.map.grid", "attribute access"),
    ("robot.__class__.__bases__", "dunder"),
    ("m = robot.__dict__", "dunder"),
    ("robot.move_to.__globals__", "attribute access"),
    ("r = robot\nr.move_to((0, 0, 0))", "'robot' may only"),
    ("robot.close()", "not part of the robot API"),
    ("robot.reset()", "not part of the robot API"),
    ("robot.controller.move_to((0.4, 0, 0.1))", "attribute access"),
    ("while True:\n    robot.move_north(0.01)", "while"),
    ("for i in range(10**9):\n    robot.move_north(0.01)", "literal"),
    ("for i in range(1000):\n    robot.move_north(0.001)", "at most 100"),
    ("for i in [1, 2]:\n    robot.move_north(0.01)", "range"),
    ("n = 5\nfor i in range(n):\n    robot.move_north(0.01)", "literal"),
    (
        "for a in range(100):\n    for b in range(100):\n        for c in range(100):\n"
        "            robot.get_pos('mug')",
        "at most",
    ),
    ("for i in range(60):\n    robot.move_north(0.001)", "robot motions"),
    ("f = lambda: 0", "lambda"),
    ("def f():\n    pass", "function definitions"),
    ("class A:\n    pass", "class definitions"),
    ("x = [p for p in range(3)]", "comprehensions"),
    ("x = (p for p in range(3))", "generator"),
    ("x = {1: 2}", "dict"),
    ("if True:\n    robot.move_north(0.1)", "if statements"),
    ("try:\n    pass\nexcept Exception:\n    pass", "try"),
    ("with open('x') as f:\n    pass", "with"),
    ("x = 2 ** 1000000", "'**'"),
    ("x = 'a' + f'{robot}'", "f-strings"),
    ("global x", "global"),
    ("del x", "del"),
    ("raise SystemExit", "raise"),
    ("assert False", "assert"),
    ("x = y + 1", "not defined"),
    ("print('hi')", "calling 'print'"),
    ("robot.move_to(*[(0, 0, 0)])", "starred"),
    ("robot.get_major_map(**{'obj': 'mug'})", "keyword unpacking"),
    ("robot.move_to((0.4, 0, 0.1)) if True else None", "conditional"),
    ("(x := 3)", "assignment expressions"),
    ("x = 1 < 2", "comparisons"),
    ("pos = robot.get_pos('mug')\nx = pos[0:2]", "indexing only"),
    ("robot.move_to((0.4, 0.0, 0.1))\nrobot.move_to(", "syntax error"),
    ("robot.move_to((0.4, 0.0, 0.1))\nimport os", "import"),
    ("async def f():\n    await robot.move_to((0, 0, 0))", "function definitions"),
    ("x = 'a' * 10\nrange = 3", "cannot be assigned"),
    ("robot = 3", "cannot be assigned"),
    ("__builtins__", "dunder"),
    ("x = b'bytes'", "bytes literals"),
    ("x" * 30_000, "characters"),
    ("robot.move_to((0.4, 0, 0.1))\x00", "NUL"),
    # expressions nested deeper than any check may recurse: refused before parsing
    ("x = " + "+".join(["1"] * 9000), "more than 100 operators"),
    ("x = " + "1+" * 99_999 + "1", "characters"),
    ("x = " + "-" * 5000 + "1", "more than 100 operators"),
    ("x = " + "(" * 300 + "1" + ")" * 300, "more than 100 operators"),
    ("x = " + "[" * 300 + "]" * 300, "more than 100 operators"),
    ("x = robot" + ".a" * 500, "more than 100 operators"),
    ("x = robot.current_position" + "()" * 500, "more than 100 operators"),
    ("p = robot.current_position()\nx = p" + " * p" * 200, "line 2: the statement has more"),
    # control and format characters: the listing a user reviews must be what runs
    ("# go north\x1b[2K\rrobot.move_south(0.5)\nrobot.move_north(0.01)", "U+001B (ESC)"),
    ("robot.move_north(0.01)\rrobot.move_south(0.5)", "U+000D (CR)"),
    ("robot.move_north(0.01)  # \u202e)5.0(htuos_evom.tobor", "U+202E"),
    ("robot.move_north(0.01)\u2028robot.move_south(0.5)", "U+2028"),
    ("x = 'mug\u200b'", "U+200B"),
    ("x = 1\x0bx = 2", "U+000B"),
    ("robot.move_north(0.01)\x08\x08\x08", "U+0008 (BS)"),
    ("\ufeffrobot.move_north(0.01)", "U+FEFF"),
    ("x = 1\n\nrobot.move_north(0.01) \x7f", "line 3: character U+007F (DEL)"),
    # numbers and loops too large to be sized
    ("for i in range(100000000000000000000000000000):\n    pass", "2**63"),
    ("for i in range(0, 9223372036854775808, 2):\n    pass", "2**63"),
    ("x = 100000000000000000000000000000000", "beyond 2**63"),
    ("x = -9223372036854775808", "beyond 2**63"),
    ("x = '" + "a" * 600 + "'", "longer than 500"),
    ("x = [" + "0, " * 17 + "]", "at most 16 items"),
    ("x = (" + "0, " * 17 + ")", "at most 16 items"),
    ("x = 2 ** 64", "'**'"),
    ("x = 1 << 64", "'<<'"),
    ("p = robot.current_position()\nx = p @ p", "'@'"),
    # memory bombs that the static check refuses (those it cannot see are stopped at run time:
    # tests/test_hardening_sandbox.py)
    ("x = [0] * 10**9", "'**'"),
    ("x = 'x' * 10**10", "'**'"),
    ("x = bytes(10**10)", "calling 'bytes'"),
    ("x = bytearray(10000000000)", "calling 'bytearray'"),
    ("x = 2**10**10", "'**'"),
    ("x = 9**9**9", "'**'"),
    ("x = 1 << 10**9", "'<<'"),
    ("x = 1 << 1000000000", "'<<'"),
    ("x = [0 for _ in range(10**9)]", "comprehensions"),
    ("x = {i: i for i in range(10**9)}", "comprehensions"),
    ("x = {i for i in range(10**9)}", "comprehensions"),
    ("x = [*range(1000000000)]", "starred"),
    ("x = list(range(1000000000))", "calling 'list'"),
    ("x = sum(range(10**18))", "calling 'sum'"),
    ("x = [0] * 9223372036854775808", "beyond 2**63"),
    ("x = 'ab' * 10000000000000000000000", "beyond 2**63"),
    ("x = '{:>9999999999}'.format(1)", "attribute access '.format'"),
    ("x = f'{1:>9999999999}'", "f-strings"),
    ("x = {0: [0] * 1000000}", "dict literals"),
    ("x = {0} * 1000000", "set literals"),
    ("x = 'x'\nfor _ in range(100):\n    for _ in range(100):\n        x = x + x", "steps"),
    ("h = robot.get_map(obj='mug')\nx = [[h] * 16] * 16 ** 6", "'**'"),
    ("x = 0x8000000000000000", "beyond 2**63"),
    ("x = 1_000_000_000_000_000_000_000", "beyond 2**63"),
    ("x = '" + "\\x41" * 501 + "'", "longer than 500"),
    ("x = [" + "[0] * 10, " * 17 + "]", "at most 16 items"),
    # expressions nested deeper than any check may recurse
    ("+".join(["1"] * 10_000), "more than 100 operators"),
    ("x = " + "(" * 1000 + "1" + ")" * 1000, "more than 100 operators"),
    ("x = " + "[" * 1000 + "]" * 1000, "more than 100 operators"),
    ("x = " + "lambda: " * 1000 + "0", "more than 100 operators"),
    ("x = " + "not " * 1000 + "1", "more than 100 operators"),
    ("x = " + "-(" * 600 + "1" + ")" * 600, "more than 100 operators"),
    ("x = " + "{0: " * 500 + "0" + "}" * 500, "more than 100 operators"),
    ("x = " + "robot.get_pos(" * 400 + "'mug'" + ")" * 400, "more than 100 operators"),
    ("x = robot.current_position()\ny = x" + "[0]" * 1000, "more than 100 operators"),
    ("x = " + " if 1 else ".join(["1"] * 1000), "more than 100 operators"),
    ("x = " + " and ".join(["1"] * 2000), "more than 100 operators"),
    ("".join(" " * i + "for _ in range(1):\n" for i in range(101)) + " " * 101 + "pass", "syntax"),
    # control and format characters in comments and strings: the listing must be what runs
    ("x = 'mug'  # \u2066 robot.move_south(0.5) \u2069", "U+2066"),
    ("# \u202e )5.0(htuos_evom.tobor\nrobot.move_north(0.01)", "line 1: character U+202E"),
    ("x = 'mug\u200f'", "U+200F"),
    ("robot.move_north(0.01)\x0crobot.move_south(0.5)", "U+000C"),
    ("robot.move_north(0.01)\x85robot.move_south(0.5)", "U+0085"),
    ("robot.move_north(0.01)\u2029robot.move_south(0.5)", "U+2029"),
    ("x = 1  # \x1b]8;;http://example.invalid\x1b\\link", "U+001B (ESC)"),
    ("x = 'a\ud800'", "U+D800"),
    ("x = 'mug\U000e0041'", "U+E0041"),
    ("robot.move_north(0.01)\r\nrobot.move_south(0.5)", "U+000D (CR)"),
    ("x = 1\x1a", "U+001A"),
    ('x = 1\n# fine\n\n\n"""\u202a"""', "line 5: character U+202A"),
    # escapes through attributes, format strings and frames
    ("x = robot.move_to.__self__", "dunder"),
    ("x = robot.get_pos.__func__.__globals__['os']", "indexing only"),
    ("x = ().__class__.__base__.__subclasses__()", "dunder"),
    ("x = robot.get_pos('mug').__class__", "dunder"),
    ("x = (i for i in []).gi_frame.f_back", "attribute access '.gi_frame'"),
    ("x = (i for i in []).gi_frame.f_back", "attribute access '.f_back'"),
    ("x = '{0.__class__}'.format(robot)", "attribute access '.format'"),
    ("x = '{0.__init__.__globals__}'.format(robot.move_to)", "attribute access"),
    ("x = '%s' % robot", "'robot' may only"),
    ("x = robot.current_position().tofile('/tmp/x')", "attribute access '.tofile'"),
    ("x = robot.get_major_map(obj='mug').values", "attribute access '.values'"),
    ("x = robot.move_to", "attribute access '.move_to'"),
    ("x = robot.spatial", "attribute access '.spatial'"),
    ("robot.map.voxels = None", "assign only to names"),
    ("robot.move_to = print", "assign only to names"),
    ("x = robot.current_position()\nx[0] = 5", "assign only to names"),
    ("x = getattr(robot, '__cl' + 'ass__')", "calling 'getattr'"),
    ("x = vars(robot)", "calling 'vars'"),
    ("x = globals()", "calling 'globals'"),
    ("x = locals()", "calling 'locals'"),
    ("x = type(robot)", "calling 'type'"),
    ("x = __builtins__.__dict__['eval']", "indexing only"),
    ("x = robot._heatmap({}, {})", "not part of the robot API"),
    ("robot.__init__(None)", "dunder"),
    ("robot.get_major_map(obj='mug', **{'sound': 'dog'})", "keyword unpacking"),
    ("robot.get_pos(__class__='mug')", "dunder"),
    # imports in all spellings
    ("import os as o", "import"),
    ("import os.path", "import"),
    ("from os import *", "import"),
    ("from . import sandbox", "import"),
    ("import importlib\nimportlib.import_module('os')", "import"),
    ("x = __import__('subprocess')", "dunder"),
    ("x = __loader__.load_module('os')", "attribute access"),
    ("import\tos", "import"),
    ("from os import (path,\n    sep)", "import"),
    ("x = 1; import os", "import"),
    ("if True: import os", "if statements"),
    # exec, eval, compile, open and friends
    ("exec(compile('import os', 's', 'exec'))", "calling 'exec'"),
    ("x = eval(input())", "calling 'eval'"),
    ("x = open", "name 'open' is not defined"),
    ("f = exec\nf('import os')", "name 'exec' is not defined"),
    ("x = breakpoint()", "calling 'breakpoint'"),
    ("x = memoryview(b'x')", "calling 'memoryview'"),
    # loops that do not end, recursion
    ("while 1:\n    pass", "while"),
    (
        "for i in range(100):\n    for j in range(100):\n        for k in range(100):\n"
        "            pass",
        "evaluation steps",
    ),
    ("def f():\n    return f()\nf()", "function definitions"),
    ("f = lambda f: f(f)\nf(f)", "lambda"),
    ("for _ in iter(int, 1):\n    pass", "range"),
    ("for _ in range(-1, -10**9, -1):\n    pass", "literal"),
    ("for _ in range(0, 1000, 1):\n    pass", "at most 100"),
    ("for _ in range(0, 10, 0):\n    pass", "other than 0"),
    ("for _ in range(3):\n    pass\nelse:\n    robot.move_north(0.1)", "for ... else"),
    # generator tricks
    ("def g():\n    yield 1\nx = g()", "function definitions"),
    ("x = (yield)", "yield"),
    ("x = (i for i in range(3)).gi_frame", "generator"),
    ("async def f():\n    async for x in y:\n        pass", "function definitions"),
    # exceptions that leak frames or run code on the way out
    ("try:\n    x = 1 / 0\nexcept Exception as e:\n    x = e.__traceback__.tb_frame", "try"),
    ("raise Exception(robot)", "raise"),
    ("assert robot.get_pos('mug'), robot", "assert"),
    ("with robot as r:\n    pass", "with"),
    ("try:\n    pass\nfinally:\n    robot.move_north(0.1)", "try"),
    # other statements and literals
    ("match robot:\n    case _:\n        pass", "match"),
    ("x: int = 1", "AnnAssign"),
    ("x = 1j", "complex literals"),
    ("x = ...", "ellipsis literals"),
    ("del robot", "del"),
    ("nonlocal x", "nonlocal"),
    ("robot = robot", "cannot be assigned"),
    ("for robot in range(3):\n    pass", "cannot be assigned"),
    ("x, robot = 1, 2", "cannot be assigned"),
]


@pytest.mark.parametrize("snippet, word", HOSTILE, ids=[f"h{i:03d}" for i in range(len(HOSTILE))])
def test_hostile_code_is_refused_and_the_robot_does_not_move(snippet, word):
    robot = CountingRobot()
    with pytest.raises(CodeRejected) as e:
        run_code(snippet, robot)
    assert word in str(e.value), str(e.value)
    assert e.value.problems
    assert robot.moves == []


def test_there_are_at_least_a_hundred_hostile_snippets():
    assert len(HOSTILE) >= 100


def test_a_refusal_after_valid_lines_still_runs_nothing():
    robot = CountingRobot()
    code = "robot.move_north(0.05)\nrobot.move_north(0.05)\nimport os\n"
    with pytest.raises(CodeRejected, match="line 3: import"):
        run_code(code, robot)
    assert robot.moves == []


def test_every_problem_is_listed_with_its_line():
    with pytest.raises(CodeRejected) as e:
        check_code("import os\nx = 1\nwhile x:\n    pass\nopen('f')\n")
    lines = [p.split(":")[0] for p in e.value.problems]
    assert lines == ["line 1", "line 3", "line 5"]


def test_allowed_code_runs_in_order_and_counts_its_bounds():
    code = (
        "# a note\n"
        '"""a docstring"""\n'
        "p = robot.current_position()\n"
        "q = (p + [0.1, 0.0, 0.0]) * 1\n"
        "d = -0.02\n"
        "d += 0.04\n"
        "a, b = 1, 2\n"
        "for _ in range(2):\n"
        "    robot.move_to(q)\n"
        "    robot.move_west(d * a / b)\n"
        "robot.move_to([q[0], q[1], 0.25])\n"
        "pass\n"
    )
    checked = check_code(code)
    assert (checked.calls, checked.moves) == (6, 5)
    robot = CountingRobot()
    run = run_code(checked, robot)
    assert len(robot.moves) == 5
    np.testing.assert_allclose(robot.moves[0], [0.4, 0.0, 0.3])
    np.testing.assert_allclose(robot.moves[1], [0.4, 0.01, 0.3])
    np.testing.assert_allclose(robot.moves[-1], [0.4, 0.0, 0.25])
    assert [c.method for c in run.calls] == ["current_position"] + ["move_to", "move_west"] * 2 + [
        "move_to"
    ]
    assert run.calls[1].line == 9 and run.calls[1].result == "moved"


def test_the_allowed_api_is_the_robot_api():
    from tabletop.robot.wheeled import MobileRobot

    shared = {p.name for p in PRIMITIVES if p.available_to("arm")}
    assert all(callable(getattr(RobotAPI, m, None)) for m in shared)
    assert all(callable(getattr(MobileRobot, m, None)) for m in ROBOT_METHODS)
    assert not {"close", "reset", "map", "controller", "history"} & ROBOT_METHODS
    assert ROBOT_METHODS == {p.name for p in PRIMITIVES}  # the declaration, nothing else


class FakeHeatmap:
    """Stands for the heatmap class: ``*`` multiplies the values, nothing else is defined."""

    def __init__(self, values):
        self.values = np.asarray(values, np.float32)

    def __mul__(self, other):
        if not isinstance(other, FakeHeatmap):
            return NotImplemented
        return FakeHeatmap(self.values * other.values)


class MapRobot(CountingRobot):
    """get_major_map / get_map answer heatmaps of the class under test."""

    def __init__(self, make):
        super().__init__()
        self.make = make

    def get_major_map(self, obj=None, sound=None, img=None, area=None, *, primary=None):
        return self.make([0.2, 1.0, 0.5])

    def get_map(self, obj=None, sound=None, img=None, area=None):
        return self.make([1.0, 0.5, 0.0])


def test_heatmaps_multiply_in_the_sandbox_and_nothing_else(monkeypatch):
    from tabletop.language import sandbox

    monkeypatch.setattr(sandbox, "HEATMAP_CLASS", f"{__name__}.FakeHeatmap")
    robot = MapRobot(FakeHeatmap)
    code = 'a = robot.get_major_map(obj="mug")\nb = robot.get_map(sound="dog")\nf = a * b\n'
    run = run_code(code + "robot.move_north(0.01)\n", robot)
    assert len(run.calls) == 3 and len(robot.moves) == 1
    for bad, word in [
        ("g = a + b", "unsupported operand"),  # the class defines no +
        ("g = a * 'mug'", "arithmetic on str"),
        ("g = -a", "unary minus on FakeHeatmap"),
        ("g = a[0]", "cannot be indexed"),
    ]:
        with pytest.raises(SandboxError, match=word):
            run_code(code + bad, robot)
    monkeypatch.setattr(sandbox, "HEATMAP_CLASS", "tabletop.mapping.heatmaps.Nothing")
    with pytest.raises(SandboxError, match="arithmetic on FakeHeatmap is not allowed"):
        run_code(code, robot)


def test_the_map_heatmap_class_multiplies_in_the_sandbox():
    from tabletop.mapping import heatmaps

    if not hasattr(heatmaps, "Heatmap"):  # the class moves there with the query layer
        pytest.skip("tabletop.mapping.heatmaps.Heatmap does not exist yet")
    from tabletop.grid import VoxelGrid

    grid = VoxelGrid(voxel_size=0.1)

    def make(row):
        values = np.zeros(grid.shape, np.float32)
        values[0, 0, :3] = row
        return heatmaps.Heatmap(grid, values, "q", "object", 10.0, 1.0, True)

    class Robot(MapRobot):
        def get_max_pos_3d(self, heatmap):
            return heatmap  # hands the fused value back for the check below

    code = 'a = robot.get_major_map(obj="mug")\nb = robot.get_map(sound="dog")\n'
    run = run_code(code + "f = robot.get_max_pos_3d(a * b)\n", Robot(make))
    fused = run.calls[-1].result
    assert isinstance(fused, heatmaps.Heatmap)
    np.testing.assert_allclose(fused.values[0, 0, :3], [0.2, 0.5, 0.0])


@pytest.mark.parametrize(
    "code, word",
    [
        ("x = 'mug' * 3", "arithmetic on str"),
        ("x = [0] * 3", "arithmetic on list"),
        ("x = 1 / 0", "ZeroDivisionError"),
        ("x = 3\ny = x[0]", "cannot be indexed"),
        ("a, b = 1", "cannot unpack"),
        ("a, b = (1, 2, 3)", "unpacking 3 values"),
        ("for _ in range(0):\n    y = 1\nz = y", "has no value"),
        ("x = 2\nfor _ in range(70):\n    x = x * x", "beyond 2**63"),
        ("robot.move_north()", "robot.move_north"),
    ],
)
def test_runtime_errors_name_the_line(code, word):
    with pytest.raises(SandboxError) as e:
        run_code(code, CountingRobot())
    assert word in str(e.value) and "line" in str(e.value)


def test_step_and_time_limits_stop_a_run():
    with pytest.raises(CodeRejected, match="evaluation steps"):
        check_code("for _ in range(100):\n    x = 1 + 2 + 3\n", SandboxConfig(max_steps=50))
    slow = CountingRobot(delay_s=0.05)
    code = "for _ in range(10):\n    robot.move_north(0.001)\n"
    with pytest.raises(SandboxLimit, match="longer than"):
        run_code(code, slow, SandboxConfig(timeout_s=0.01))
    assert 1 <= len(slow.moves) < 10  # stopped between motions
    # one motion that outlasts the limit on its own: the run is stopped after it, not reported
    # as done
    one = CountingRobot(delay_s=0.05)
    with pytest.raises(SandboxLimit, match="ended after the limit"):
        run_code("robot.move_north(0.001)\n", one, SandboxConfig(timeout_s=0.01))
    assert len(one.moves) == 1


def test_config_is_checked():
    with pytest.raises(Exception, match="max_loop"):
        SandboxConfig(max_loop=0)
    with pytest.raises(Exception, match="timeout_s"):
        SandboxConfig(timeout_s=0)
