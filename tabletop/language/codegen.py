"""Code generation: a plan (:mod:`tabletop.reader.plan`) becomes Python against the robot API.

The code is what a prompted LLM writes in the paper's style (``obj_map = robot.get_major_map(...)``,
``robot.get_max_pos_3d(...)``, ``robot.move_to(...)``), one commented block per step, and it
goes through the sandbox like any other code. Every call is a primitive of the declaration
(:data:`tabletop.robot.primitives.PRIMITIVES`), looked up by name or by its target when this
module is imported, so a renamed or undeclared primitive fails here, not in generated code.

- a plain object goal: ``robot.move_to_object(name)`` (above it);
- any other goal: its heatmap (sharp primary, broad ``near`` parts, multiplied), the argmax,
  ``robot.move_to``;
- between: ``robot.move_in_between(a, b)``, each goal a landmark: a plain object by name,
  any other goal as its heatmap (the robot API takes both);
- sides: ``robot.move_to_left(name)``, ...; compass: ``robot.move_north(d)``, ...;
- back and forth: the two points once, then a loop of two ``robot.move_to``.

Typical use::

    from tabletop.language import instruction_to_code

    print(instruction_to_code("go between the tray and where you heard the dog barking"))
"""

from __future__ import annotations

import re

from tabletop.reader.plan import (
    Above,
    BackAndForth,
    Between,
    Compass,
    Face,
    Forward,
    Goal,
    GoTo,
    Part,
    Side,
    Step,
    Turn,
)
from tabletop.reader.reading import DEFAULT_READER, understand
from tabletop.relations import RELATIONS
from tabletop.robot.primitives import PRIMITIVES, Primitive, motion_to, primitive

__all__ = ["instruction_to_code", "plan_to_code"]

# The primitives the code calls, resolved once against the declaration.
_LOAD_IMAGE = primitive("load_image")
_MAJOR_MAP = primitive("get_major_map")
_BROAD_MAP = primitive("get_map")
_ARGMAX = primitive("get_max_pos_3d")
_ABOVE = primitive("above")
_MOVE_TO = primitive("move_to")
_MOVE_ABOVE = motion_to(_ABOVE.name)  # move_to_object
_MOVE_BETWEEN = motion_to("between")  # move_in_between
_MOVE_SIDE = {r.side: motion_to(r.name) for r in RELATIONS if r.side is not None}
#: Compass direction -> its motion: the robot API's compass moves ("move_north", ...).
_MOVE_COMPASS = {
    p.name.removeprefix("move_"): p for p in PRIMITIVES if p.kind == "motion" and p.direction
}
_MOVE_FORWARD = primitive("move_forward")
_TURN = primitive("turn")
_FACE = primitive("face")


def _call(p: Primitive, *args: str) -> str:
    """``robot.<p>(args)``; ``args`` are code (literals, variables, ``kind=value``)."""
    return f"robot.{p.name}({', '.join(args)})"


class _Names:
    """Variable names in the paper's style (obj_map, sound_map, pos1, ...), numbered on reuse."""

    def __init__(self) -> None:
        self.used: dict[str, int] = {}

    def __call__(self, base: str) -> str:
        n = self.used.get(base, 0) + 1
        self.used[base] = n
        return base if n == 1 else f"{base}_{n}"


def _q(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _arg(part: Part, lines: list[str], names: _Names) -> str:
    if part.kind != "img":
        return f"{part.kind}={_q(part.text)}"
    var = names("img")
    lines.append(f"{var} = {_call(_LOAD_IMAGE, _q(part.text))}")
    return f"img={var}"


def _goal_map(goal: Goal, lines: list[str], names: _Names) -> str:
    """Append the lines that build the goal's heatmap; return its variable."""
    arg = _arg(goal.primary, lines, names)
    main = names(f"{goal.primary.kind}_map")
    lines.append(f"{main} = {_call(_MAJOR_MAP, arg)}")
    if not goal.near:
        return main
    factors = [main]
    for part in goal.near:
        arg = _arg(part, lines, names)
        var = names(f"{part.kind}_map")
        lines.append(f"{var} = {_call(_BROAD_MAP, arg)}")
        factors.append(var)
    fused = names("fuse_map")
    lines.append(f"{fused} = {' * '.join(factors)}")
    return fused


def _is_plain_object(goal: Goal) -> bool:
    return goal.primary.kind == "obj" and not goal.near


def _landmark(goal: Goal, lines: list[str], names: _Names) -> str:
    """The goal as a spatial primitive's landmark: an object's name, else its heatmap."""
    if _is_plain_object(goal):
        return _q(goal.primary.text)
    return _goal_map(goal, lines, names)


def _point(goal: Goal, lines: list[str], names: _Names, var: str) -> None:
    """Lines that put the goal's target point into ``var``."""
    if _is_plain_object(goal):
        lines.append(f"{var} = {_call(_ABOVE, _q(goal.primary.text))}")
        return
    heat = _goal_map(goal, lines, names)
    lines.append(f"{var} = {_call(_ARGMAX, heat)}")


def _named(landmark: str | Goal, lines: list[str], names: _Names) -> str:
    """A relation's landmark as an argument: an object's name, or a narrowed goal's heatmap."""
    return _q(landmark) if isinstance(landmark, str) else _landmark(landmark, lines, names)


def _step_code(step: Step, names: _Names) -> list[str]:
    a = step.action
    setup: list[str] = []
    moves: list[str]
    if isinstance(a, GoTo):
        if _is_plain_object(a.goal):
            moves = [_call(_MOVE_ABOVE, _q(a.goal.primary.text))]
        else:
            heat = _goal_map(a.goal, setup, names)
            pos = names("pos")
            setup.append(f"{pos} = {_call(_ARGMAX, heat)}")
            moves = [_call(_MOVE_TO, pos)]
    elif isinstance(a, Between):
        la = _landmark(a.a, setup, names)
        lb = _landmark(a.b, setup, names)
        moves = [_call(_MOVE_BETWEEN, la, lb)]
    elif isinstance(a, Side):
        moves = [_call(_MOVE_SIDE[a.side], _named(a.landmark, setup, names))]
    elif isinstance(a, Above):
        moves = [_call(_MOVE_ABOVE, _named(a.landmark, setup, names))]
    elif isinstance(a, Compass):
        moves = [_call(_MOVE_COMPASS[a.direction], repr(a.distance_m))]
    elif isinstance(a, Forward):
        moves = [_call(_MOVE_FORWARD, repr(a.distance_m))]
    elif isinstance(a, Turn):
        moves = [_call(_TURN, repr(a.angle_deg))]
    elif isinstance(a, Face):
        moves = [_call(_FACE, _named(a.landmark, setup, names))]
    elif isinstance(a, BackAndForth):
        # the two points once, outside the loop: each pass goes to the same places
        p1, p2 = names("pos1"), names("pos2")
        _point(a.a, setup, names, p1)
        _point(a.b, setup, names, p2)
        moves = [_call(_MOVE_TO, p1), _call(_MOVE_TO, p2)]
    else:
        raise TypeError(f"unknown plan action {type(a).__name__}")
    if step.times == 1:
        return setup + moves
    return [*setup, f"for _ in range({step.times}):", *("    " + m for m in moves)]


def plan_to_code(steps: tuple[Step, ...]) -> str:
    """Python against the robot API, one commented block per step (the sandbox's input)."""
    names = _Names()
    out: list[str] = []
    for step in steps:
        out.append("# " + re.sub(r"\s+", " ", step.text).strip())
        out += _step_code(step, names)
    return "\n".join(out) + "\n"


def instruction_to_code(instruction: str, robot: str = "arm", reader: str = DEFAULT_READER) -> str:
    """Read ``instruction`` for ``robot`` ("arm" or "mobile") with the reader called
    ``reader`` (:data:`tabletop.reader.READERS`) and write its robot code (:class:`ParseError`
    if not understood)."""
    reading = understand(instruction, robot, reader)
    code = plan_to_code(reading.steps)
    if reading.unhonoured:
        said = ", ".join(repr(w) for w in reading.unhonoured)
        code = f"# not honoured: {said} (the robot moves at its controller's speed)\n" + code
    return code
