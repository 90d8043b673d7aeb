"""Instruction -> code -> sandboxed run against a robot, with every motion's target recorded.

:class:`TracingRobot` is the robot the generated code sees, with one method per declared
primitive (:mod:`tabletop.robot.primitives`): the robot API's queries go to the wrapped robot;
every motion is turned into its target point first (through the robot API's own target
primitive), recorded, and then sent to the wrapped robot's ``move_to`` — or, in a dry run, not
sent (the traced position moves to the target, so relative moves still add up).
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tabletop.errors import ConfigError
from tabletop.language.sandbox import SandboxConfig, SandboxRun, check_code, run_code
from tabletop.paths import input_file_problem
from tabletop.reader.reading import DEFAULT_READER
from tabletop.robot.api import check_compass_distance, check_on_map
from tabletop.robot.primitives import PRIMITIVES, Primitive

__all__ = [
    "BACKENDS",
    "InstructionRun",
    "Motion",
    "TracingRobot",
    "generate_code",
    "run_instruction",
]

BACKENDS = ("offline", "llm")


@dataclass(frozen=True)
class Motion:
    """One motion the code asked for: the robot API method, its target (3,) [m] in the base
    frame, and the robot's result (None in a dry run)."""

    method: str
    target: np.ndarray
    result: object = None


class TracingRobot:
    """The robot API seen by generated code, recording each motion's target.

    Its methods are generated from the declaration (:data:`tabletop.robot.primitives.PRIMITIVES`):
    a query or target primitive goes to the wrapped robot; a motion primitive computes its
    target through its target primitive (``move_to_left(x)`` -> ``left_of(x)``, ``move_north(d)``
    -> ``offset(d, 0)``, ``move_to(p)`` -> ``p``), records it, then sends it to the wrapped
    robot's ``move_to`` (or not, in a dry run, which refuses a target off the map instead of
    recording it: :meth:`_check_on_map`). Three primitives are the tracer's own
    (:data:`OWN`): ``current_position`` and ``offset`` answer from the traced position (in a dry
    run the robot never moves), ``load_image`` reads images from ``image_dir`` only (as does
    ``img=`` given a path): code cannot read any other file, nor learn whether one exists.

    Args:
        robot: a :class:`tabletop.robot.RobotAPI` (SimArm, MobileBase, ...).
        execute: send motions to ``robot`` (False: a dry run; nothing moves).
        image_dir: the directory images are read from: a relative path in the code is read
            from here, an absolute one must lie inside it (default: the working directory).
        on_motion: called with each :class:`Motion`: once with ``result=None`` before moving
            (the target), and once more with the result after a real motion (not where the
            robot returns no result: a point robot's jump is reported once).
        start: the traced start point of a dry run (3,) [m] (default: the robot's position).
    """

    OWN = ("current_position", "offset", "load_image")
    """Primitives the tracer answers itself instead of forwarding them to the robot."""

    def __init__(
        self,
        robot,
        *,
        execute: bool = True,
        image_dir=None,
        on_motion: Callable[[Motion], None] | None = None,
        start=None,
    ) -> None:
        self.robot = robot
        self.execute = execute
        self.image_dir = Path(image_dir if image_dir is not None else Path.cwd()).resolve()
        self.on_motion = on_motion
        self.motions: list[Motion] = []
        p = robot.current_position() if start is None else start
        self._pos = np.array(p, dtype=np.float64)

    @property
    def targets(self) -> np.ndarray:
        """(K, 3) [m] the targets of every motion so far, in order."""
        return np.array([m.target for m in self.motions], dtype=np.float64).reshape(-1, 3)

    def _move(self, method: str, target) -> object:
        try:
            p = np.array(target, dtype=np.float64)
        except (TypeError, ValueError):
            p = None
        if p is None or p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ConfigError(f"{method} needs a finite 3-vector [m], got {target!r}")
        target = p
        if not self.execute:  # nothing moves to say it: the tracer refuses what robots refuse
            self._check_on_map(method, target)
        if self.on_motion is not None:
            self.on_motion(Motion(method, target.copy()))
        result = None
        if self.execute:
            result = self.robot.move_to(target)
            self._pos = np.array(self.robot.current_position(), dtype=np.float64)
        else:
            self._pos = target.copy()
        motion = Motion(method, target, result)
        self.motions.append(motion)
        if self.execute and self.on_motion is not None and result is not None:
            self.on_motion(motion)
        return result

    def _check_on_map(self, method: str, target: np.ndarray) -> None:
        """In a dry run, refuse a target every robot on the map refuses without moving: x, y
        outside the map (a base's ``outside_map``; a table map spans the arm's workspace), or
        more than the success radius below the map's floor (under the table or the floor).
        A mapless robot's targets are not checked."""
        grid = getattr(getattr(self.robot, "map", None), "grid", None)
        if grid is None:
            return
        check_on_map(grid, method, target)

    def _robot_kind(self) -> str:
        """The wrapped robot's kind ("arm", "mobile"): its compass moves' longest distance."""
        return getattr(self.robot, "robot_kind", "arm")

    # ---------------------------------------------------------------- the tracer's own
    def current_position(self) -> np.ndarray:
        """(3,) [m]: the traced position (the robot's after a real motion)."""
        return self._pos.copy()

    def offset(self, dx, dy) -> np.ndarray:
        """(3,) [m]: the traced position moved by ``dx``, ``dy`` [m]."""
        return self._pos + np.array([_distance(dx), _distance(dy), 0.0])

    def load_image(self, path):
        """The wrapped robot's ``load_image`` of a file inside ``image_dir`` (a relative path is
        read from there). A path that leads outside, by ``..``, a link or an absolute path, is
        refused whether or not it exists, so the code learns nothing about other files."""
        if not isinstance(path, (str, Path)) or not str(path).strip():
            raise ConfigError(f"an image path must be a non-empty string, got {path!r}")
        p = (self.image_dir / path).resolve()  # an absolute path replaces image_dir
        if not p.is_relative_to(self.image_dir):
            # a path inside by its words that a link leads out of is named as a link (where
            # it leads stays unsaid: the code learns nothing about other files)
            lexical = Path(os.path.normpath(self.image_dir / path))
            how = " through a link" if lexical.is_relative_to(self.image_dir) else ""
            raise ConfigError(
                f"image path {str(path)!r} leads outside the image directory "
                f"{str(self.image_dir)!r}{how}; give a path inside it (relative paths are read "
                "from it)"
            )
        problem = input_file_problem(p)
        if problem:  # the words looked like a path: say what they were not
            raise ConfigError(
                f"{str(path)!r} was read neither as a thing nor as an existing image file (in "
                f"the image directory {str(self.image_dir)!r}, it {problem}); name a thing in "
                "words (e.g. 'the red mug'), or give the path of an image file inside the "
                "image directory"
            )
        return self.robot.load_image(p)


def _distance(v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.number)):
        raise ConfigError(f"a distance must be a number [m], got {v!r}")
    if not np.isfinite(v):
        raise ConfigError(f"a distance must be finite [m], got {v}")
    return float(v)


def _signature(p: Primitive) -> inspect.Signature:
    kind = inspect.Parameter.POSITIONAL_OR_KEYWORD
    params = [inspect.Parameter("self", kind)]
    for name in p.params:
        default = None if p.keywords else inspect.Parameter.empty
        params.append(inspect.Parameter(name, kind, default=default))
    return inspect.Signature(params)


def _has(robot, p: Primitive) -> None:
    """Refuse a primitive the wrapped robot does not have (a mobile base's own motion asked
    of the arm), naming the robots that have it."""
    if getattr(robot, p.name, None) is None:
        raise ConfigError(
            f"{p.name} is a primitive of the {' and '.join(p.robots)} robot; this robot "
            f"({type(robot).__name__}) has no {p.name}"
        )


def _traced(p: Primitive):
    """The tracer's method for primitive ``p`` (see :class:`TracingRobot`)."""
    sig = _signature(p)
    if p.rotates:

        def method(self, *args, **kwargs):
            _has(self.robot, p)
            values = list(sig.bind(self, *args, **kwargs).arguments.values())[1:]
            here = self._pos.copy()
            if self.on_motion is not None:
                self.on_motion(Motion(p.name, here.copy()))
            result = getattr(self.robot, p.name)(*values) if self.execute else None
            motion = Motion(p.name, here, result)
            self.motions.append(motion)
            if self.execute and self.on_motion is not None and result is not None:
                self.on_motion(motion)
            return result

    elif not p.moves:

        def method(self, *args, **kwargs):
            _has(self.robot, p)
            if "img" in p.params:  # an image path is read here, inside image_dir
                bound = sig.bind(self, *args, **kwargs).arguments
                if isinstance(bound.get("img"), (str, Path)):
                    bound["img"] = self.load_image(bound["img"])
                args, kwargs = (), {k: v for k, v in bound.items() if k != "self"}
            return getattr(self.robot, p.name)(*args, **kwargs)

    else:

        def method(self, *args, **kwargs):
            values = list(sig.bind(self, *args, **kwargs).arguments.values())[1:]
            if p.target is None:  # move_to: the argument is the point
                target = values[0]
            elif p.direction is not None:  # a compass move: the offset along its axis
                check_compass_distance(p.name, values[0], self._robot_kind(), limit=False)
                d = _distance(values[0])
                target = getattr(self, p.target)(d * p.direction[0], d * p.direction[1])
            else:
                _has(self.robot, p)
                target = getattr(self, p.target)(*values)
            return self._move(p.name, target)

    method.__name__ = p.name
    method.__qualname__ = f"TracingRobot.{p.name}"
    method.__doc__ = f"{p.kind}: {p.summary}" + (f" (target: {p.target})" if p.target else "")
    method.__signature__ = sig
    return method


for _p in PRIMITIVES:
    if _p.name not in TracingRobot.OWN:
        setattr(TracingRobot, _p.name, _traced(_p))
del _p


@dataclass(frozen=True)
class InstructionRun:
    """An instruction's code and what running it did."""

    instruction: str
    code: str
    motions: tuple[Motion, ...]
    run: SandboxRun
    dry_run: bool

    @property
    def targets(self) -> np.ndarray:
        """(K, 3) [m] every motion's target in order."""
        return np.array([m.target for m in self.motions], dtype=np.float64).reshape(-1, 3)


def generate_code(
    instruction: str,
    backend: str = "offline",
    llm_config=None,
    robot: str = "arm",
    reader: str = DEFAULT_READER,
) -> str:
    """The robot code for ``instruction`` from the ``offline`` reader called ``reader``
    (:data:`tabletop.reader.READERS`) or an ``llm`` endpoint (prompted for ``robot``: "arm"
    or "mobile").

    The code is returned exactly as the sandbox will receive it.
    """
    if backend == "offline":
        from tabletop.language.codegen import instruction_to_code

        return instruction_to_code(instruction, robot, reader)
    if backend == "llm":
        from tabletop.language.llm import LLMConfig, llm_code

        return llm_code(instruction, llm_config or LLMConfig.from_env(), robot)
    raise ConfigError(f"unknown backend {backend!r}; valid: {list(BACKENDS)}")


def run_instruction(
    instruction: str,
    robot,
    *,
    backend: str = "offline",
    llm_config=None,
    code: str | None = None,
    dry_run: bool = False,
    image_dir=None,
    sandbox: SandboxConfig | None = None,
    on_code: Callable[[str], None] | None = None,
    on_motion: Callable[[Motion], None] | None = None,
    reader: str | None = None,
) -> InstructionRun:
    """Turn ``instruction`` into code (or take ``code``), check it, and run it on ``robot``.

    The code is checked before anything runs (:class:`CodeRejected`: the robot does not move).
    ``on_code`` sees the checked code, ``on_motion`` each target and result. ``reader``
    (default: the robot's own) reads the instruction and, during the run, the words of the
    code's queries; the robot's reader is restored after.
    """
    sandbox = sandbox or SandboxConfig()
    own = getattr(robot, "reader", None)
    reader = reader or own or DEFAULT_READER
    if code is None:
        kind = getattr(robot, "robot_kind", "arm")
        code = generate_code(instruction, backend, llm_config, kind, reader)
    checked = check_code(code, sandbox)
    if on_code is not None:
        on_code(code)
    tracer = TracingRobot(robot, execute=not dry_run, image_dir=image_dir, on_motion=on_motion)
    if own is not None:
        robot.reader = reader
    try:
        run = run_code(checked, tracer, sandbox)
    finally:
        if own is not None:
            robot.reader = own
    return InstructionRun(instruction, code, tuple(tracer.motions), run, dry_run)
