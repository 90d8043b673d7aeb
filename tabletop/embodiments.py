"""The robots, declared once: one :class:`Embodiment` per kind of robot.

Everything that differs between the arm over a table and the wheeled base in a room is a field
of its embodiment: the robot-API class, the obstacle embodiments it may take, its prompt, its
success radius and longest move, whether it drives and turns, the task file's section naming
where it works, its scan's settings, the evaluation (scan driver, world and robot), the suite
generator, the demo and the drivers that may move it. Its primitives are those declared for
it (:func:`tabletop.robot.primitives.primitives_of`). The reader, code
generation, evaluation, report and CLI look the embodiment up by name (:func:`embodiment`)
instead of testing for one robot; a new robot is a new :class:`Embodiment` handed to
:func:`register`, and no other file changes.

The heavy parts (classes and functions that import the simulator, the map or the evaluation)
are named as ``"module:attribute"`` and imported only when asked for (:meth:`Embodiment.load`),
so declaring a robot costs nothing and this module imports nothing heavy.

Typical use::

    from tabletop.embodiments import embodiment

    e = embodiment("mobile")
    e.success_radius_m                      # 1.0
    e.load("scan_config")(seed=3)           # a RoomScanConfig
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

from tabletop.errors import ConfigError

__all__ = ["EMBODIMENTS", "Embodiment", "embodiment", "register", "unregister"]

#: The fields of :class:`Embodiment` that name a ``"module:attribute"`` to import lazily.
LAZY_FIELDS = (
    "robot_class",
    "prompt",
    "scan_config",
    "evaluate",
    "suites",
    "demo",
)


@dataclass(frozen=True)
class Embodiment:
    """One kind of robot: what it is and where its parts live."""

    name: str
    """The robot's kind as task files (``[robot] kind``), the CLI (``--robot``) and the
    primitives (:attr:`~tabletop.robot.primitives.Primitive.robots`) spell it."""
    summary: str
    """One line: what the robot is and where it works."""
    robot_class: str
    """``"module:Class"``: its robot API (:class:`~tabletop.robot.api.RobotAPI` or a
    subclass), which takes the map as its first argument."""
    success_radius_m: float
    """A goal is reached within this distance [m] (the default of a task file's
    ``[robot] success_radius``)."""
    max_move_m: float
    """The longest compass move or drive [m] one call or one instruction step may ask."""
    workspace: str
    """The task file's section that names where it works: ``"scene"`` (a table) or
    ``"room"``."""
    drives: bool = False
    """It drives ahead and turns on the spot and never moves sideways (a wheeled base): the
    reader reads "drive 2 m", "turn left" and "face X" as its own motions and refuses a
    sideways move."""
    obstacles: tuple[str, ...] = ()
    """The obstacle embodiments a task file may give it (``[robot] embodiment``), the first
    the default; empty: none to choose."""
    prompt: str = "tabletop.language.prompts:ARM_PROMPT"
    """``"module:attr"``: its :class:`~tabletop.language.prompts.PromptParts` (preamble,
    conventions, examples); the API list is made from its primitives
    (:func:`~tabletop.robot.primitives.primitives_of`)."""
    scan_config: str = "tabletop.sim.scan:ScanConfig"
    """``"module:Class"``: its scan's settings (a task file's ``[scan]``)."""
    scan_fields: tuple[str, ...] | None = None
    """The ``[scan]`` keys a task file may set (None: every field of :attr:`scan_config`)."""
    evaluate: str = "tabletop.eval.runner:evaluate_table_task_file"
    """``"module:function"``: scan, map and run a task file's goals
    (``(task_file, encoders, *, cache_dir, figures_dir, progress, map_overrides,
    scan_overrides, noise, reader, driver)`` -> :class:`~tabletop.eval.results.TaskRun`)."""
    suites: str | None = None
    """``"module:function"``: writes its generated goal suites (None: none)."""
    demo: str | None = None
    """``"module:function"``: its end-to-end demo ``(out_dir, encoders, driver) -> exit
    code``."""
    drivers: tuple[str, ...] = ("sim",)
    """What may move it in an evaluation (``--driver``), the first the default."""

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise ConfigError(f"embodiment name {self.name!r} must be an identifier")
        if self.workspace not in WORKSPACES:
            raise ConfigError(
                f"{self.name}: workspace must be one of {list(WORKSPACES)}, got {self.workspace!r}"
            )
        for f in ("success_radius_m", "max_move_m"):
            v = getattr(self, f)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0:
                raise ConfigError(f"{self.name}: {f} must be a number > 0 [m], got {v!r}")
        for f in LAZY_FIELDS:
            v = getattr(self, f)
            if v is not None and (not isinstance(v, str) or v.count(":") != 1):
                raise ConfigError(f"{self.name}: {f} must be 'module:attribute', got {v!r}")
        if not self.drivers:
            raise ConfigError(f"{self.name}: drivers must name at least one driver")

    @property
    def default_obstacles(self) -> str | None:
        """The obstacle embodiment a task file gets without one (None: none to choose)."""
        return self.obstacles[0] if self.obstacles else None

    def load(self, part: str):
        """The object a lazy field (:data:`LAZY_FIELDS`) names, imported now;
        :class:`ConfigError` when the field is unset or names nothing importable."""
        if part not in LAZY_FIELDS:
            raise ConfigError(f"{part!r} is not a part to load; valid: {list(LAZY_FIELDS)}")
        ref = getattr(self, part)
        if ref is None:
            raise ConfigError(f"the {self.name} robot has no {part}")
        module, attr = ref.split(":")
        try:
            return getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError) as e:
            raise ConfigError(
                f"the {self.name} robot's {part} {ref!r} cannot be loaded: {e}"
            ) from None


#: Where a robot may work, as a task file's section names it.
WORKSPACES = ("scene", "room")

ARM = Embodiment(
    name="arm",
    summary="a Franka Panda over a table, its wrist camera scanning in teleop sweeps",
    robot_class="tabletop.robot.arm:SimArm",
    success_radius_m=0.10,
    max_move_m=1.0,
    workspace="scene",
    prompt="tabletop.language.prompts:ARM_PROMPT",
    scan_config="tabletop.sim.scan:ScanConfig",
    scan_fields=(
        "seed",
        "speed",
        "episodes",
        "episode_s",
        "repeat_sounds",
        "clip_split",
        "snr_db",
    ),
    evaluate="tabletop.eval.runner:evaluate_table_task_file",
    suites="tabletop.eval.suites:write_default_suites",
    demo="tabletop.cli.evaluate:_arm_demo",
    drivers=("sim", "franky-sim"),
)

MOBILE = Embodiment(
    name="mobile",
    summary="a wheeled base in a room, its mast camera scanning every table",
    robot_class="tabletop.robot.wheeled:MobileRobot",
    success_radius_m=1.0,
    max_move_m=20.0,
    workspace="room",
    drives=True,
    obstacles=("ground", "flyer"),
    prompt="tabletop.language.prompts:MOBILE_PROMPT",
    scan_config="tabletop.sim.room_scan:RoomScanConfig",
    scan_fields=(
        "seed",
        "rate_hz",
        "max_linear",
        "max_angular",
        "views_per_table",
        "standoff",
        "look_s",
        "pan_rad",
        "look_around",
        "episodes",
        "episode_s",
        "repeat_sounds",
        "clip_split",
        "snr_db",
    ),
    evaluate="tabletop.eval.runner:evaluate_room_task_file",
    suites="tabletop.eval.room_suites:write_room_suites",
    demo="tabletop.cli.evaluate:_mobile_demo",
)

#: Every registered embodiment by name, the arm first.
EMBODIMENTS: dict[str, Embodiment] = {e.name: e for e in (ARM, MOBILE)}


def embodiment(name: str) -> Embodiment:
    """The embodiment called ``name``; :class:`ConfigError` naming the valid ones if none."""
    try:
        return EMBODIMENTS[name]
    except (KeyError, TypeError):
        raise ConfigError(f"unknown robot {name!r}; valid: {list(EMBODIMENTS)}") from None


def register(spec: Embodiment) -> Embodiment:
    """Add ``spec`` to :data:`EMBODIMENTS` (a new robot); :class:`ConfigError` if its name is
    taken or a lazy part cannot be imported."""
    if not isinstance(spec, Embodiment):
        raise ConfigError(f"register takes an Embodiment, got {type(spec).__name__}")
    if spec.name in EMBODIMENTS:
        raise ConfigError(f"a robot called {spec.name!r} is registered already")
    for part in LAZY_FIELDS:
        if getattr(spec, part) is not None:
            spec.load(part)  # fails now, naming the part, rather than mid-run
    EMBODIMENTS[spec.name] = spec
    return spec


def unregister(name: str) -> None:
    """Remove the robot ``name`` (registered by :func:`register`; the shipped ones stay)."""
    if name in (ARM.name, MOBILE.name):
        raise ConfigError(f"the shipped robot {name!r} cannot be removed")
    embodiment(name)
    del EMBODIMENTS[name]
