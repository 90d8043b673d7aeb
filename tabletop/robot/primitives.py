"""The robot API's primitives, declared once.

Every call generated code may make on a robot is declared here, as a :class:`Primitive`: its
name, its parameters (as :class:`tabletop.robot.api.RobotAPI` spells them), a one-line summary
for the LLM prompt, and its kind:

- ``query``: reads the map or the robot (``get_major_map``, ``get_pos``, ``current_position``);
- ``target``: computes a point without moving (``above``, ``left_of``, ``between``, ``offset``);
- ``motion``: moves the robot, to the point its ``target`` primitive computes from the same
  arguments (``move_to_left`` -> ``left_of``), to ``offset`` along a compass ``direction``
  scaled by the distance (``move_north`` -> ``offset(d, 0)``), or, for ``move_to``, to the
  point it is given.

What is derived from :data:`PRIMITIVES`: the sandbox's allowed and moving methods
(:mod:`tabletop.language.sandbox`), the tracing robot's methods (:mod:`tabletop.language.run`),
the prompt's API list (:mod:`tabletop.language.prompts`) and the calls the offline parser
writes (:mod:`tabletop.language.codegen`). :func:`undeclared_methods` finds public methods of
a robot class that are neither declared nor in :data:`EXCLUDED`; the tests run it on
``RobotAPI``, so a method added there without a declaration fails them.

Typical use::

    from tabletop.robot import PRIMITIVES, motion_to

    [p.name for p in PRIMITIVES if p.kind == "motion"]
    motion_to("left_of").name                            # "move_to_left"
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass

from tabletop.errors import ConfigError

__all__ = [
    "EXCLUDED",
    "KINDS",
    "PRIMITIVES",
    "Primitive",
    "motion_to",
    "primitive",
    "primitives_of",
    "signature_mismatches",
    "undeclared_methods",
]

#: The kinds of primitive: a map or robot query, a target point (no motion), a motion.
KINDS = ("query", "target", "motion")


@dataclass(frozen=True)
class Primitive:
    """One call of the robot API that generated code may make."""

    name: str
    """The method's name on :class:`~tabletop.robot.api.RobotAPI`."""
    params: tuple[str, ...]
    """Parameter names in order, as in the method's signature (without ``self``)."""
    summary: str
    """One line for the LLM prompt: what the call returns or does."""
    kind: str
    """One of :data:`KINDS`."""
    target: str | None = None
    """Motion only: the target primitive whose point it moves to (called with the motion's
    arguments, or with the compass offset when ``direction`` is set); None for ``move_to``,
    whose argument is the point."""
    direction: tuple[float, float] | None = None
    """Compass motion only: the horizontal unit axis (dx, dy) [base frame]; the motion's one
    argument, a distance [m], scales it into the ``offset`` target's (dx, dy)."""
    keywords: bool = False
    """The parameters are optional keywords (``obj=``, ``sound=``, ...), given by name."""
    robots: tuple[str, ...] = ()
    """The robots that have it (:mod:`tabletop.embodiments` names): empty, the
    default, for every robot (the shared API); a mobile base's own motions (``move_forward``,
    ``turn``, ``face``) only ``("mobile",)``."""
    rotates: bool = False
    """Motion only: it turns the robot on the spot (no target point: the robot stays where it
    is)."""

    def __post_init__(self) -> None:
        if not all(isinstance(r, str) and r.isidentifier() for r in self.robots):
            raise ConfigError(f"{self.name}: robots must be robot names, got {self.robots!r}")
        if self.rotates and (self.kind != "motion" or self.target is not None):
            raise ConfigError(f"{self.name}: a rotation is a motion without a target")
        if not self.name.isidentifier() or self.name.startswith("_"):
            raise ConfigError(f"primitive name {self.name!r} must be a public identifier")
        if self.kind not in KINDS:
            raise ConfigError(f"{self.name}: unknown kind {self.kind!r}; valid: {list(KINDS)}")
        if self.kind != "motion" and (self.target is not None or self.direction is not None):
            raise ConfigError(f"{self.name}: only a motion has a target or a direction")
        if self.direction is not None and (self.target != "offset" or len(self.params) != 1):
            raise ConfigError(f"{self.name}: a compass motion takes one distance to 'offset'")

    @property
    def shared(self) -> bool:
        """Whether every robot has it (the shared API)."""
        return not self.robots

    def available_to(self, robot: str) -> bool:
        """Whether the robot called ``robot`` has it."""
        return self.shared or robot in self.robots

    @property
    def moves(self) -> bool:
        """Whether calling it moves the robot."""
        return self.kind == "motion"

    @property
    def call(self) -> str:
        """The call as the prompt shows it: ``robot.left_of(name)``, ``robot.get_map(obj=, …)``."""
        args = ", ".join(f"{p}=" if self.keywords else p for p in self.params)
        return f"robot.{self.name}({args})"


def _compass(direction: str, axis: str, unit: tuple[float, float]) -> Primitive:
    return Primitive(
        f"move_{direction}",
        ("distance_m",),
        f"move distance_m metres {direction} ({axis})",
        "motion",
        "offset",
        unit,
    )


PRIMITIVES: tuple[Primitive, ...] = (
    # ------------------------------------------------------------------ queries
    Primitive("load_image", ("path",), "an image array read from a file", "query"),
    Primitive(
        "get_major_map",
        ("obj", "sound", "img", "area", "primary"),
        "a sharp heatmap: where exactly the goal is",
        "query",
        keywords=True,
    ),
    Primitive(
        "get_map",
        ("obj", "sound", "img", "area"),
        "a broad heatmap: the region near the goal",
        "query",
        keywords=True,
    ),
    Primitive("get_max_pos_3d", ("heatmap",), "the 3D point of highest heat", "query"),
    Primitive("get_pos", ("name",), "the centre of a landmark", "query"),
    Primitive("current_position", (), "where the gripper is now", "query"),
    # ------------------------------------------------------------------ targets (no motion)
    Primitive("above", ("name",), "the point just above a landmark", "target"),
    Primitive("left_of", ("name",), "the point beside a landmark on its left (+y)", "target"),
    Primitive("right_of", ("name",), "the point beside a landmark on its right (-y)", "target"),
    Primitive("in_front_of", ("name",), "the point beyond a landmark (+x)", "target"),
    Primitive("behind", ("name",), "the point on the near side of a landmark (-x)", "target"),
    Primitive("between", ("a", "b"), "the midpoint of two landmarks", "target"),
    Primitive("offset", ("dx", "dy"), "the current position moved by dx, dy metres", "target"),
    # ------------------------------------------------------------------ motions
    Primitive("move_to", ("pos",), "move the gripper to a 3D point", "motion"),
    Primitive("move_to_object", ("name",), "move just above a landmark", "motion", "above"),
    Primitive("move_to_left", ("name",), "move beside a landmark (+y)", "motion", "left_of"),
    Primitive("move_to_right", ("name",), "move beside a landmark (-y)", "motion", "right_of"),
    Primitive(
        "move_in_front_of", ("name",), "move beside a landmark (+x)", "motion", "in_front_of"
    ),
    Primitive("move_behind", ("name",), "move beside a landmark (-x)", "motion", "behind"),
    Primitive(
        "move_in_between", ("a", "b"), "move to the midpoint of two landmarks", "motion", "between"
    ),
    _compass("north", "+x", (1.0, 0.0)),
    _compass("south", "-x", (-1.0, 0.0)),
    _compass("east", "-y", (0.0, -1.0)),
    _compass("west", "+y", (0.0, 1.0)),
    # ------------------------------------------------------------------ a mobile base's own
    Primitive(
        "ahead",
        ("distance_m",),
        "the point distance_m metres ahead of the base (mobile base)",
        "target",
        robots=("mobile",),
    ),
    Primitive(
        "move_forward",
        ("distance_m",),
        "drive distance_m metres ahead, negative: back (mobile base)",
        "motion",
        "ahead",
        robots=("mobile",),
    ),
    Primitive(
        "turn",
        ("angle_deg",),
        "turn on the spot by angle_deg degrees, counter-clockwise (mobile base)",
        "motion",
        robots=("mobile",),
        rotates=True,
    ),
    Primitive(
        "face",
        ("name",),
        "turn on the spot towards a landmark (mobile base)",
        "motion",
        robots=("mobile",),
        rotates=True,
    ),
)
"""Every primitive, in the order the prompt lists them (queries, targets, motions)."""

#: Public methods of :class:`~tabletop.robot.api.RobotAPI` that are deliberately not
#: primitives (generated code cannot call them), each with the reason.
EXCLUDED: dict[str, str] = {
    "side_target": "the general form of left_of/right_of/in_front_of/behind, taking a direction "
    "vector; generated code names the side instead",
    "heading": "a mobile base's yaw; generated code turns with turn and face instead",
    "plan": "a mobile base's path without moving, for tools and reports",
    "close": "releases the simulator or driver; the code's caller ends the robot, not the code",
}

_BY_NAME = {p.name: p for p in PRIMITIVES}


def _check_declaration() -> None:
    if len(_BY_NAME) != len(PRIMITIVES):
        raise ConfigError("PRIMITIVES declares a name twice")
    for p in PRIMITIVES:
        if p.target is None:
            continue
        t = _BY_NAME.get(p.target)
        if t is None or t.kind != "target":
            raise ConfigError(f"{p.name}: its target {p.target!r} is not a declared target")
        if p.direction is None and t.params != p.params:
            raise ConfigError(f"{p.name}{p.params} must take the parameters of {t.name}{t.params}")
    overlap = set(EXCLUDED) & set(_BY_NAME)
    if overlap:
        raise ConfigError(f"{sorted(overlap)} are both declared and excluded")


_check_declaration()


def primitive(name: str) -> Primitive:
    """The declared primitive ``name`` (:class:`ConfigError` naming the valid ones if none)."""
    try:
        return _BY_NAME[name]
    except KeyError:
        raise ConfigError(
            f"{name!r} is not a robot API primitive; valid: {sorted(_BY_NAME)}"
        ) from None


def primitives_of(robot: str) -> tuple[Primitive, ...]:
    """The declared primitives the robot called ``robot`` has (an
    :mod:`~tabletop.embodiments` name), in the prompt's order."""
    from tabletop.embodiments import embodiment

    embodiment(robot)  # names the valid robots
    return tuple(p for p in PRIMITIVES if p.available_to(robot))


def motion_to(target: str) -> Primitive:
    """The motion primitive that moves to target primitive ``target`` (``"left_of"`` ->
    ``move_to_left``); :class:`ConfigError` if there is none."""
    found = [p for p in PRIMITIVES if p.target == target and p.direction is None]
    if len(found) != 1:
        targets = sorted(p.target for p in PRIMITIVES if p.target and p.direction is None)
        raise ConfigError(f"no single motion moves to {target!r}; targets with one: {targets}")
    return found[0]


def _public_methods(cls: type) -> list[str]:
    out = []
    for name in dir(cls):
        if name.startswith("_"):
            continue
        attr = inspect.getattr_static(cls, name)
        if isinstance(attr, (staticmethod, classmethod)) or inspect.isfunction(attr):
            out.append(name)
    return out


def undeclared_methods(cls: type) -> tuple[str, ...]:
    """Public methods of ``cls`` (a robot API class) that are neither in :data:`PRIMITIVES`
    nor in :data:`EXCLUDED`, sorted: what a new method must be added to."""
    return tuple(n for n in _public_methods(cls) if n not in _BY_NAME and n not in EXCLUDED)


def signature_mismatches(cls: type, robot: str | None = None) -> tuple[str, ...]:
    """One line per declared primitive that ``cls`` lacks or whose parameter names (without
    ``self``) differ from the declaration: the primitives every robot has (``robot`` None:
    the shared API), or those of ``robot`` (a :mod:`~tabletop.embodiments` name)."""
    if robot is not None:
        from tabletop.embodiments import embodiment

        embodiment(robot)  # names the valid robots
    problems = []
    for p in PRIMITIVES:
        if (robot is None and not p.shared) or (robot is not None and not p.available_to(robot)):
            continue
        attr = inspect.getattr_static(cls, p.name, None)
        if attr is None:
            problems.append(f"{cls.__name__} has no method {p.name!r}")
            continue
        fn = attr.__func__ if isinstance(attr, (staticmethod, classmethod)) else attr
        names = list(inspect.signature(fn).parameters)
        if not isinstance(attr, staticmethod) and names[:1] in (["self"], ["cls"]):
            names = names[1:]
        if tuple(names) != p.params:
            problems.append(f"{cls.__name__}.{p.name}{tuple(names)} != declared {p.params}")
    return tuple(problems)
