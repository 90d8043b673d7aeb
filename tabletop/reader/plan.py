"""The plan of an instruction: the values the parser (:mod:`tabletop.reader.rules`) makes and
code generation (:mod:`tabletop.language.codegen`) reads.

An instruction is a tuple of :class:`Step`; each step does one action (:data:`Action`) ``times``
times. A :class:`Goal` is a ``primary`` :class:`Part` (the place to reach, a sharp map) narrowed
by ``near`` parts (broad maps), each in one modality (:data:`PART_KINDS`).
"""

from __future__ import annotations

from dataclasses import dataclass

from tabletop.errors import ConfigError

__all__ = [
    "MOTIONS",
    "PART_KINDS",
    "Above",
    "Action",
    "BackAndForth",
    "Between",
    "Compass",
    "Face",
    "Forward",
    "GoTo",
    "Goal",
    "Part",
    "Reading",
    "Side",
    "Step",
    "Turn",
]

#: The modalities of a goal part, named as the robot API's query keywords (obj=, sound=, ...).
PART_KINDS = ("obj", "sound", "img", "area")


@dataclass(frozen=True)
class Part:
    """One goal in one modality: ``kind`` in obj, sound, img, area; ``text`` is the object,
    sound or area description, or the image path."""

    kind: str
    text: str

    def __post_init__(self) -> None:
        if self.kind not in PART_KINDS:
            raise ConfigError(f"unknown goal kind {self.kind!r}; valid: {list(PART_KINDS)}")


@dataclass(frozen=True)
class Goal:
    """A target: the ``primary`` part (sharp map) constrained by ``near`` parts (broad maps)."""

    primary: Part
    near: tuple[Part, ...] = ()


@dataclass(frozen=True)
class GoTo:
    """Go to the goal's target (above it, for a plain object)."""

    goal: Goal


@dataclass(frozen=True)
class Between:
    """Go to the midpoint of two goals."""

    a: Goal
    b: Goal


@dataclass(frozen=True)
class Side:
    """``side`` in left, right, front, behind of ``landmark``: an object's name, or an object
    goal narrowed by others ("the mug near the sound of X": the fused heatmap's region)."""

    side: str
    landmark: str | Goal


@dataclass(frozen=True)
class Above:
    """Go above ``landmark`` (an object's name or a narrowed object goal, as for :class:`Side`)."""

    landmark: str | Goal


@dataclass(frozen=True)
class Compass:
    """``direction`` in north, south, east, west; ``distance_m`` [m] from the current point."""

    direction: str
    distance_m: float


@dataclass(frozen=True)
class BackAndForth:
    """Go to goal ``a``, then to ``b`` (the step's ``times`` repeats the pair)."""

    a: Goal
    b: Goal


@dataclass(frozen=True)
class Forward:
    """A mobile base drives ``distance_m`` [m] along its heading (negative: back)."""

    distance_m: float


@dataclass(frozen=True)
class Turn:
    """A mobile base turns on the spot by ``angle_deg`` [deg], counter-clockwise positive."""

    angle_deg: float


@dataclass(frozen=True)
class Face:
    """A mobile base turns on the spot towards ``landmark`` (as for :class:`Side`)."""

    landmark: str | Goal


Action = GoTo | Between | Side | Above | Compass | BackAndForth | Forward | Turn | Face
"""What one step does."""


@dataclass(frozen=True)
class Step:
    """One clause of the instruction, done ``times`` times."""

    action: Action
    times: int
    text: str


@dataclass(frozen=True)
class Reading:
    """What a reader made of ``text``: the ``steps`` it read from ``read`` (the words after
    ``corrections``), the ``wrapper`` words it left out, and the reader's name."""

    text: str
    read: str
    steps: tuple[Step, ...]
    corrections: tuple = ()
    """The typing slips corrected (:class:`~tabletop.reader.spelling.Correction`)."""
    wrapper: tuple[str, ...] = ()
    reader: str = ""
    unhonoured: tuple[str, ...] = ()
    """Words read that do not change where the robot goes and that it does not honour (how
    fast or how carefully to move: it moves at its controller's speed); said to the user."""


#: The steps that move by a distance or turn (a base's own), not to a place: the grammar
#: reads them, and a side word in them ("move 5 cm left") names no side of a thing.
MOTIONS = (Compass, Forward, Turn, Face)
