"""Instruction -> code -> sandboxed run against a robot, with every motion's target recorded.

:class:`TracingRobot` is the robot the generated code sees: the robot API's queries go to the
wrapped robot; every motion is turned into its target point first (the same targets the robot
API computes), recorded, and then sent to the wrapped robot's ``move_to`` — or, in a dry run,
not sent (the traced position moves to the target, so relative moves still add up).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tabletop.errors import ConfigError
from tabletop.language.sandbox import SandboxConfig, SandboxRun, check_code, run_code

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

    Args:
        robot: a :class:`tabletop.robot.RobotAPI` (SimArm, MobileBase, ...).
        execute: send motions to ``robot`` (False: a dry run; nothing moves).
        image_dir: relative image paths in the code are read from here (default: the working
            directory).
        on_motion: called with each :class:`Motion`: once with ``result=None`` before moving
            (the target), and once more with the result after a real motion.
        start: the traced start point of a dry run (3,) [m] (default: the robot's position).
    """

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
        self.image_dir = Path(image_dir) if image_dir is not None else None
        self.on_motion = on_motion
        self.motions: list[Motion] = []
        p = robot.current_position() if start is None else start
        self._pos = np.array(p, dtype=np.float64)

    @property
    def targets(self) -> np.ndarray:
        """(K, 3) [m] the targets of every motion so far, in order."""
        return np.array([m.target for m in self.motions], dtype=np.float64).reshape(-1, 3)

    # ---------------------------------------------------------------- motions
    def move_to(self, pos):
        p = np.array(pos, dtype=np.float64)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ConfigError(
                f"move_to needs a finite 3-vector [m], got {np.asarray(pos).tolist()}"
            )
        return self._move("move_to", p)

    def _move(self, method: str, target: np.ndarray):
        target = np.array(target, dtype=np.float64)
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
        if self.execute and self.on_motion is not None:
            self.on_motion(motion)
        return result

    def move_to_object(self, name):
        return self._move("move_to_object", self.robot.above(name))

    def move_to_left(self, name):
        return self._move("move_to_left", self.robot.left_of(name))

    def move_to_right(self, name):
        return self._move("move_to_right", self.robot.right_of(name))

    def move_in_front_of(self, name):
        return self._move("move_in_front_of", self.robot.in_front_of(name))

    def move_behind(self, name):
        return self._move("move_behind", self.robot.behind(name))

    def move_in_between(self, a, b):
        return self._move("move_in_between", self.robot.between(a, b))

    def _offset(self, dx, dy) -> np.ndarray:
        for v in (dx, dy):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.number)):
                raise ConfigError(f"a distance must be a number [m], got {v!r}")
            if not np.isfinite(v):
                raise ConfigError(f"a distance must be finite [m], got {v}")
        return self._pos + np.array([dx, dy, 0.0])

    def move_north(self, distance_m):
        return self._move("move_north", self._offset(distance_m, 0.0))

    def move_south(self, distance_m):
        return self._move("move_south", self._offset(-distance_m, 0.0))

    def move_west(self, distance_m):
        return self._move("move_west", self._offset(0.0, distance_m))

    def move_east(self, distance_m):
        return self._move("move_east", self._offset(0.0, -distance_m))

    # ---------------------------------------------------------------- queries
    def current_position(self) -> np.ndarray:
        return self._pos.copy()

    def load_image(self, path):
        p = Path(path).expanduser()
        if self.image_dir is not None and not p.is_absolute():
            p = self.image_dir / p
        return self.robot.load_image(p)

    def get_major_map(self, obj=None, sound=None, img=None, area=None, *, primary=None):
        return self.robot.get_major_map(obj=obj, sound=sound, img=img, area=area, primary=primary)

    def get_map(self, obj=None, sound=None, img=None, area=None):
        return self.robot.get_map(obj=obj, sound=sound, img=img, area=area)

    def get_max_pos_3d(self, heatmap):
        return self.robot.get_max_pos_3d(heatmap)

    def get_pos(self, name):
        return self.robot.get_pos(name)

    def above(self, name):
        return self.robot.above(name)

    def left_of(self, name):
        return self.robot.left_of(name)

    def right_of(self, name):
        return self.robot.right_of(name)

    def in_front_of(self, name):
        return self.robot.in_front_of(name)

    def behind(self, name):
        return self.robot.behind(name)

    def between(self, a, b):
        return self.robot.between(a, b)


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


def generate_code(instruction: str, backend: str = "offline", llm_config=None) -> str:
    """The robot code for ``instruction`` from the ``offline`` parser or an ``llm`` endpoint.

    The code is returned exactly as the sandbox will receive it.
    """
    if backend == "offline":
        from tabletop.language.parser import instruction_to_code

        return instruction_to_code(instruction)
    if backend == "llm":
        from tabletop.language.llm import LLMConfig, llm_code

        return llm_code(instruction, llm_config or LLMConfig.from_env())
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
) -> InstructionRun:
    """Turn ``instruction`` into code (or take ``code``), check it, and run it on ``robot``.

    The code is checked before anything runs (:class:`CodeRejected`: the robot does not move).
    ``on_code`` sees the checked code, ``on_motion`` each target and result.
    """
    sandbox = sandbox or SandboxConfig()
    if code is None:
        code = generate_code(instruction, backend, llm_config)
    checked = check_code(code, sandbox)
    if on_code is not None:
        on_code(code)
    tracer = TracingRobot(robot, execute=not dry_run, image_dir=image_dir, on_motion=on_motion)
    run = run_code(checked, tracer, sandbox)
    return InstructionRun(instruction, code, tuple(tracer.motions), run, dry_run)
