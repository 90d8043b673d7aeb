"""Hardening of the sandbox at run time: memory bombs are sized before they are built and
stopped with a typed error naming the line."""

from __future__ import annotations

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.language import (
    CodeRejected,
    SandboxConfig,
    SandboxError,
    SandboxLimit,
    check_code,
    run_code,
)
from tabletop.robot.api import RobotAPI


class PointRobot(RobotAPI):
    """A robot without a body or a map: it records motions and loaded images."""

    def __init__(self):
        super().__init__(avlmap=None)
        self.moves, self.images = [], []
        self.pos = np.array([0.3, 0.0, 0.3])

    def move_to(self, pos):
        self.moves.append(np.array(pos, float))
        return "moved"

    def current_position(self):
        return self.pos.copy()

    def load_image(self, path):
        self.images.append(path)
        return RobotAPI.load_image(path)

    def get_major_map(self, obj=None, sound=None, img=None, area=None, *, primary=None):
        return img


def _nest(levels: int, leaf: str = "[0]") -> str:
    """Code building a nested list 16 wide per level from ``leaf``: l{levels} at the end."""
    lines = [f"l0 = {leaf}"]
    lines += [f"l{i} = [{', '.join([f'l{i - 1}'] * 16)}]" for i in range(1, levels + 1)]
    return "\n".join(lines) + "\n"


# (code, the error's type, a phrase its message must contain); none may allocate its bomb
BOMBS = [
    (_nest(6), SandboxLimit, "line 7: a list of 16777216 elements"),
    (
        _nest(5) + "p = robot.current_position()\nx = l5 * p\n",
        SandboxLimit,
        "line 8: the result would have 3145728 elements",
    ),
    (
        _nest(5) + "p = robot.current_position()\nx = p + l5\nrobot.move_to(x)\n",
        SandboxLimit,
        "line 8: the result would have 3145728 elements",
    ),
    ("a = [0]\nfor _ in range(40):\n    a = [a, a]\nrobot.move_to(a)\n", SandboxLimit, "line 3"),
    (
        "p = robot.current_position()\nq = [p, p]\nfor _ in range(40):\n    q = [q, q]\n",
        SandboxLimit,
        "line 4: a list of",
    ),
    (_nest(2) + "x = l2 * 1000000000\n", SandboxError, "line 4: arithmetic on list"),
    ("x = 'ab' * 100000000\n", SandboxError, "line 1: arithmetic on str"),
    ("x = [0] * 1000000000\n", SandboxError, "line 1: arithmetic on list"),
    (
        "x = 9000000000000000000\nfor _ in range(100):\n    x = x * x\n",
        SandboxError,
        "line 3: integer result beyond 2**63",
    ),
    (
        "p = robot.current_position()\nx = p * 1e300\nx = x * 1e300\n",
        SandboxError,
        "line 3: FloatingPointError",
    ),
    (
        "p = robot.current_position()\nx = p + [[0, 0], [0, 0, 0]]\n",
        SandboxError,
        "line 2",
    ),
]


@pytest.mark.parametrize(("code", "kind", "phrase"), BOMBS, ids=[f"b{i}" for i in range(11)])
def test_memory_bombs_stop_with_a_typed_error_naming_the_line(code, kind, phrase):
    robot = PointRobot()
    with pytest.raises(kind) as e:
        run_code(code, robot)
    assert phrase in str(e.value), str(e.value)
    assert robot.moves == []


def test_the_budget_is_configurable_and_heatmap_sized_results_pass():
    code = _nest(3) + "p = robot.current_position()\nx = l3 * p\n"
    code += "a = x[0]\nb = a[0]\nrobot.move_to(b[0])\n"
    with pytest.raises(SandboxLimit, match="at most 1000"):
        run_code(code, PointRobot(), SandboxConfig(max_elements=1000))
    robot = PointRobot()
    run_code(code, robot)  # 12288 elements: within the default budget
    np.testing.assert_allclose(robot.moves, [[0.0, 0.0, 0.0]])
    with pytest.raises(ConfigError, match="max_elements"):
        SandboxConfig(max_elements=0)


def test_lists_nested_deeper_than_the_limit_stop_as_they_are_built():
    # a list wrapped in another 6000 times: the robot API's error message (its repr) raised
    # RecursionError, an untyped crash, from robot.move_to(a)
    deep = "a = [0]\nfor _ in range(100):\n    for _ in range(60):\n        a = [a]\n"
    for use in ("robot.move_to(a)", "robot.get_pos(a)", "p = robot.current_position()\nx = p * a"):
        robot = PointRobot()
        with pytest.raises(SandboxLimit, match="line 4: lists nested 33 deep; at most 32"):
            run_code(deep + use, robot)
        assert robot.moves == []
    shallow = SandboxConfig(max_depth=3)  # an array counts its dimensions
    run_code("a = [[[0]]]\np = robot.current_position()\nb = [[p]]\n", PointRobot(), shallow)
    for code in ("a = [[[[0]]]]", "p = robot.current_position()\nb = [[[p]]]"):
        with pytest.raises(SandboxLimit, match="nested 4 deep; at most 3"):
            run_code(code, PointRobot(), shallow)
    with pytest.raises(ConfigError, match="max_depth"):
        SandboxConfig(max_depth=0)


@pytest.mark.parametrize("word", ["not", "lambda:", "await", "-"])
def test_keywords_count_as_operators_before_the_checker_recurses(word):
    # 'x = not not ... 1' with a thousand 'not's: the checker raised RecursionError
    with pytest.raises(CodeRejected, match="line 2: the statement has more than 100 operators"):
        check_code("x = 1\nx = " + f"{word} " * 1000 + "1\n")
    with pytest.raises(CodeRejected, match="unary operator Not is not allowed"):
        check_code("x = " + "not " * 90 + "1")  # below the limit: refused for what it is


@pytest.mark.parametrize(
    "call",
    [
        "robot.load_image('goal\\x00.png')",
        "robot.get_major_map(img='a\\x00b')",
        "robot.get_pos('\\ud800')",
    ],
)
def test_arguments_the_robot_api_cannot_take_are_a_sandbox_error_naming_the_line(call, tmp_path):
    # a NUL in an image path raised ValueError ('embedded null byte') out of run_code
    from tabletop.language.run import TracingRobot
    from tabletop.language.suite import PointRobot as MapRobot
    from tabletop.language.suite import load_suite, reference_map

    suite = load_suite()
    robot = MapRobot(reference_map(suite), suite.start)
    with pytest.raises(SandboxError, match=r"line 2: robot\.\w+: \w+Error: "):
        run_code("x = 1\n" + call, TracingRobot(robot, image_dir=tmp_path))


def test_lists_handed_to_the_robot_are_bounded():
    # 65536 positions in nested lists handed to move_to: its error message showed them all,
    # seconds of work for a message of megabytes, in one step the time limit cannot stop
    code = _nest(4, leaf="robot.current_position()") + "robot.move_to(l4)\n"
    robot = PointRobot()
    with pytest.raises(SandboxLimit, match=r"line 6: robot.move_to given a list of 196608 el"):
        run_code(code, robot)
    assert robot.moves == []
    with pytest.raises(SandboxLimit, match="line 5: robot.get_pos given a list of 4096 elements"):
        run_code(_nest(3, leaf="0") + "robot.get_pos(l3)\n", robot)
    p = "p = robot.current_position()\n"
    run_code(p + "robot.move_to(p * [1.0, 1.0, 2.0])\n", robot)  # an array: not a list
    run_code(p + "robot.move_to([p[0], p[1], 0.1])\n", robot)
    assert len(robot.moves) == 2
    with pytest.raises(ConfigError, match="max_arg_elements"):
        SandboxConfig(max_arg_elements=0)


def test_an_index_beyond_any_c_integer_is_a_typed_error():
    robot = PointRobot()
    code = "p = robot.current_position()\nx = p[9223372036854775808]"
    with pytest.raises(SandboxError, match="line 2: index out of range"):
        run_code(code, robot)
    assert robot.moves == []
