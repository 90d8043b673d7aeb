"""Spatial relations, declared once.

A goal may name a place by its relation to landmarks: between two of them, on one side of one,
above one. Each :class:`Relation` here says everything the project needs of one relation, and
every layer derives its own table from :data:`RELATIONS` instead of keeping a copy:

- the **reader** (:mod:`tabletop.reader`): the plan's side names (``Side.side``);
- the **robot API** (:class:`tabletop.robot.api.RobotAPI`): a target primitive named as the
  relation (``left_of``), whose point :func:`side_point` computes, and the motion primitive
  declared to move there (:func:`tabletop.robot.primitives.motion_to`);
- **code generation** (:mod:`tabletop.language.codegen`): the motion a plan's step calls;
- **task files and their truth** (:mod:`tabletop.eval.tasks`, :mod:`tabletop.eval.truth`):
  how many landmarks a relation takes, and the point it names (:func:`side_point`);
- **suite wording** (:mod:`tabletop.eval.suites`): the words generated goals use.

``tests/test_relations.py`` checks, relation by relation, that these agree. Conventions: the
robot's base frame, +x away from the robot ("in front of" a thing is beyond it), +y to the
robot's left.

Typical use::

    from tabletop.relations import relation, side_point

    relation("left_of").axis                 # (0.0, 1.0, 0.0)
    relation_by_side("front").name           # "in_front_of"
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tabletop.errors import ConfigError

__all__ = [
    "RELATIONS",
    "SIDES",
    "Relation",
    "relation",
    "relation_by_side",
    "side_point",
]


@dataclass(frozen=True)
class Relation:
    """One spatial relation."""

    name: str
    """As task files, the robot API's target primitive and the evaluation name it."""
    landmarks: int
    """How many landmarks it takes."""
    wording: str
    """How generated goals word it before its landmarks ("to the left of")."""
    side: str | None = None
    """Side relations: the side as the reader's plan names it (``left``, ``right``, ``front``,
    ``behind``); None otherwise."""
    axis: tuple[float, float, float] | None = None
    """Side relations: the horizontal unit direction from the landmark [base frame]."""


#: Every spatial relation, in the order suites and prompts list them.
RELATIONS: tuple[Relation, ...] = (
    Relation("between", 2, "between"),
    Relation("left_of", 1, "to the left of", "left", (0.0, 1.0, 0.0)),
    Relation("right_of", 1, "to the right of", "right", (0.0, -1.0, 0.0)),
    Relation("in_front_of", 1, "in front of", "front", (1.0, 0.0, 0.0)),
    Relation("behind", 1, "behind", "behind", (-1.0, 0.0, 0.0)),
    Relation("above", 1, "above"),
)
_BY_NAME = {r.name: r for r in RELATIONS}
_BY_SIDE = {r.side: r for r in RELATIONS if r.side is not None}
#: The plan's side names, in declaration order.
SIDES: tuple[str, ...] = tuple(_BY_SIDE)


def relation(name: str) -> Relation:
    """The relation called ``name`` (:class:`ConfigError` naming the valid ones otherwise)."""
    try:
        return _BY_NAME[name]
    except (KeyError, TypeError):
        raise ConfigError(f"unknown relation {name!r}; valid: {list(_BY_NAME)}") from None


def relation_by_side(side: str) -> Relation:
    """The side relation whose plan side is ``side`` (``left`` -> ``left_of``)."""
    try:
        return _BY_SIDE[side]
    except (KeyError, TypeError):
        raise ConfigError(f"unknown side {side!r}; valid: {list(SIDES)}") from None


def side_point(axis, centre, half, top: float, offset: float, gap: float) -> np.ndarray:
    """(3,) [m]: the point beside a landmark along the horizontal unit ``axis``: ``offset``
    from its ``centre`` (3,), and at least ``gap`` beyond its ``half`` extents (3,) along the
    axis; level with its ``top`` (a gripper beside it clears its neighbours). The robot API
    moves here and the evaluation's truth is here: one function for both."""
    d = np.asarray(axis, np.float64)
    half = np.asarray(half, np.float64)
    dist = max(float(offset), float(np.abs(d[:2]) @ half[:2]) + float(gap))
    p = np.asarray(centre, np.float64) + dist * d
    p[2] = top
    return p
