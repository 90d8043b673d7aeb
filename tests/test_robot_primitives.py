"""The robot API's primitives, declared once: the declaration matches RobotAPI, and the
sandbox, the tracing robot and the LLM prompt are derived from it."""

import inspect
import re

import pytest

from tabletop.errors import ConfigError
from tabletop.robot import EXCLUDED, PRIMITIVES, Primitive, RobotAPI
from tabletop.robot.primitives import (
    KINDS,
    motion_to,
    primitive,
    signature_mismatches,
    undeclared_methods,
)

DECLARED = {p.name for p in PRIMITIVES}


def _params(cls, name):
    attr = inspect.getattr_static(cls, name)
    fn = attr.__func__ if isinstance(attr, staticmethod) else attr
    names = list(inspect.signature(fn).parameters)
    return tuple(names if isinstance(attr, staticmethod) else names[1:])


@pytest.mark.parametrize("p", PRIMITIVES, ids=[p.name for p in PRIMITIVES])
def test_every_primitive_is_a_robot_api_method_with_the_declared_parameters(p):
    assert callable(getattr(RobotAPI, p.name, None)), p.name
    assert _params(RobotAPI, p.name) == p.params
    assert p.kind in KINDS and p.summary and "\n" not in p.summary


def test_every_public_robot_api_method_is_declared_or_excluded():
    public = {
        n
        for n, v in inspect.getmembers(RobotAPI)
        if not n.startswith("_") and (inspect.isfunction(v) or inspect.ismethod(v))
    }
    assert public == DECLARED | set(EXCLUDED)
    assert undeclared_methods(RobotAPI) == ()
    assert signature_mismatches(RobotAPI) == ()
    for name, why in EXCLUDED.items():
        assert hasattr(RobotAPI, name) and why, name  # a stale exclusion is an error too


def test_a_method_added_without_a_declaration_is_caught():
    class Extended(RobotAPI):
        def wave(self, times):
            pass

        @staticmethod
        def beep():
            pass

        @property
        def speed(self):  # an attribute, not a method
            return 1.0

        def _helper(self):  # private
            pass

    assert undeclared_methods(Extended) == ("beep", "wave")

    class Renamed(RobotAPI):
        def move_to_left(self, landmark):
            pass

    assert signature_mismatches(Renamed) == (
        "Renamed.move_to_left('landmark',) != declared ('name',)",
    )


def test_motions_name_their_target_primitive():
    motions = [p for p in PRIMITIVES if p.moves]
    assert {p.name for p in motions} == {
        "move_to",
        "move_to_object",
        "move_to_left",
        "move_to_right",
        "move_in_front_of",
        "move_behind",
        "move_in_between",
        "move_north",
        "move_south",
        "move_east",
        "move_west",
    }
    assert motion_to("above").name == "move_to_object"
    assert motion_to("left_of").name == "move_to_left"
    assert motion_to("between").name == "move_in_between"
    assert primitive("move_to").target is None
    assert primitive("move_north").target == "offset"
    assert primitive("move_north").direction == (1.0, 0.0)
    assert primitive("move_west").direction == (0.0, 1.0)
    for p in motions:
        if p.target is not None:
            assert primitive(p.target).kind == "target"


def test_lookups_and_malformed_declarations_name_the_valid_options():
    with pytest.raises(ConfigError, match=r"'fly' is not a robot API primitive; valid: \["):
        primitive("fly")
    with pytest.raises(ConfigError, match="no single motion moves to 'get_pos'"):
        motion_to("get_pos")
    with pytest.raises(ConfigError, match="unknown kind 'jump'"):
        Primitive("hop", (), "x", "jump")
    with pytest.raises(ConfigError, match="only a motion"):
        Primitive("left_of", ("name",), "x", "target", target="above")
    with pytest.raises(ConfigError, match="public identifier"):
        Primitive("_secret", (), "x", "query")


def test_the_sandbox_allows_exactly_the_declared_primitives():
    from tabletop.language.sandbox import ROBOT_METHODS, ROBOT_MOVES

    assert ROBOT_METHODS == DECLARED
    assert ROBOT_MOVES == {p.name for p in PRIMITIVES if p.kind == "motion"}


def test_the_tracing_robot_has_exactly_the_declared_primitives():
    from tabletop.language.run import TracingRobot

    methods = {
        n
        for n in dir(TracingRobot)
        if not n.startswith("_") and callable(inspect.getattr_static(TracingRobot, n))
    }
    assert methods == DECLARED
    assert set(TracingRobot.OWN) <= DECLARED
    for p in PRIMITIVES:  # generated methods carry the declared signature
        if p.name not in TracingRobot.OWN:
            assert _params(TracingRobot, p.name) == p.params


def test_the_prompt_lists_exactly_the_declared_primitives():
    from tabletop.language.prompts import SYSTEM_PROMPT, api_list

    listed = re.findall(r"^robot\.(\w+)\(", api_list(), flags=re.MULTILINE)
    assert listed == [p.name for p in PRIMITIVES]
    assert api_list() in SYSTEM_PROMPT
    for p in PRIMITIVES:
        assert f"{p.call}" in SYSTEM_PROMPT and p.summary in SYSTEM_PROMPT
    assert "robot.get_major_map(obj=, sound=, img=, area=, primary=)" in SYSTEM_PROMPT
    assert "robot.move_north(distance_m)" in SYSTEM_PROMPT
