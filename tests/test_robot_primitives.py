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
    from tabletop.robot.wheeled import MobileRobot

    # a primitive of every robot is the shared API's; a base's own is the base's
    cls = RobotAPI if p.shared else MobileRobot
    assert p.robots in ((), ("mobile",)), p.robots
    assert callable(getattr(cls, p.name, None)), p.name
    assert _params(cls, p.name) == p.params
    assert p.kind in KINDS and p.summary and "\n" not in p.summary
    if cls is MobileRobot:
        assert not hasattr(RobotAPI, p.name)  # the arm has no base motions


def test_the_mobile_base_has_every_primitive_of_its_own_and_no_undeclared_one():
    from tabletop.robot.wheeled import MobileRobot

    assert signature_mismatches(MobileRobot, "mobile") == ()
    assert undeclared_methods(MobileRobot) == ()
    assert MobileRobot.robot_kind == "mobile" and RobotAPI.robot_kind == "arm"
    mobile_only = [p.name for p in PRIMITIVES if p.robots == ("mobile",)]
    assert set(mobile_only) == {"ahead", "move_forward", "turn", "face"}
    assert signature_mismatches(RobotAPI, "mobile") == tuple(
        f"RobotAPI has no method {n!r}" for n in mobile_only
    )


def test_every_public_robot_api_method_is_declared_or_excluded():
    public = {
        n
        for n, v in inspect.getmembers(RobotAPI)
        if not n.startswith("_") and (inspect.isfunction(v) or inspect.ismethod(v))
    }
    from tabletop.robot.wheeled import MobileRobot

    shared = {p.name for p in PRIMITIVES if p.shared}
    assert public == shared | (set(EXCLUDED) & public)
    assert undeclared_methods(RobotAPI) == ()
    assert signature_mismatches(RobotAPI) == ()
    for name, why in EXCLUDED.items():  # a stale exclusion is an error too
        assert (hasattr(RobotAPI, name) or hasattr(MobileRobot, name)) and why, name


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
        "move_forward",
        "turn",
        "face",
    }
    assert motion_to("ahead").name == "move_forward"
    assert {p.name for p in motions if p.rotates} == {"turn", "face"}
    assert all(p.target is None for p in motions if p.rotates)
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


@pytest.mark.parametrize("robot", ["arm", "mobile"])
def test_the_prompt_lists_exactly_the_declared_primitives(robot):
    from tabletop.language.prompts import SYSTEM_PROMPT, api_list, system_prompt

    prompt = system_prompt(robot)
    listed = re.findall(r"^robot\.(\w+)\(", api_list(robot), flags=re.MULTILINE)
    assert listed == [p.name for p in PRIMITIVES if p.available_to(robot)]
    assert api_list(robot) in prompt
    for p in PRIMITIVES:
        shown = f"{p.call}" in prompt and p.summary in prompt
        assert shown == p.available_to(robot), p.name  # the arm's prompt has no base motions
    assert "robot.get_major_map(obj=, sound=, img=, area=, primary=)" in prompt
    assert "robot.move_north(distance_m)" in prompt
    assert SYSTEM_PROMPT == system_prompt("arm")
    assert ("wheeled robot base" in prompt) == (robot == "mobile")
