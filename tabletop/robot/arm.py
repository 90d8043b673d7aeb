"""An arm behind the robot API: the map's obstacles, the reach controller, any arm driver.

:class:`ArmRobot` drives any :class:`~tabletop.arm.driver.ArmDriver` (the simulator's, or a
real Panda's: :class:`~tabletop.arm.panda_py_driver.PandaPyDriver`) with the
:class:`~tabletop.arm.reach.ReachController`, on the obstacles the map says are there. Its
``move_to`` approaches a target from above: the TCP goes to the target raised to ``above_gap``
over the highest map surface within the gripper's radius
(:func:`tabletop.mapping.targets.approach_point`), so ``move_to(get_max_pos_3d(...))`` reaches
a goal on or in an object without driving into it. In clutter a taller neighbour within that
radius would lift the TCP out of the success radius; then the TCP goes ``above_gap`` over the
approached object alone (the map instance at the target, or the surface beneath it), and the
reach controller, whose obstacles are every object the map holds, checks what the gripper
clears there and selects another goal within its ``goal_radius`` of that object's top when it
does not (:meth:`ArmRobot.approach`).

:class:`SimArm` is an :class:`ArmRobot` on a PyBullet world of the scene; the obstacles still come
from the MAP (:func:`tabletop.robot.obstacles.arm_obstacles`), not the simulator's ground truth.
The simulator only checks the outcome: PyBullet contact points between the robot and the table
or objects are counted after every physics step (the planner's trajectories included).
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np

from tabletop.arm.driver import ArmDriver, PyBulletDriver, touching_points
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.arm.reach import GoalChoice, ReachConfig, ReachController, ReachResult
from tabletop.arm.success import SUCCESS_RADIUS_M
from tabletop.errors import ConfigError, check_bool
from tabletop.mapping.targets import APPROACH_RADIUS_M, approach_point, surface_z
from tabletop.robot.api import (
    PrimitiveArgumentError,
    RobotAPI,
    RobotClosed,
    SpatialConfig,
    _point,
    _shown,
)
from tabletop.robot.obstacles import ARM, Embodiment, arm_obstacles

__all__ = ["ArmReachResult", "ArmRobot", "SimArm"]


@dataclass(frozen=True)
class ArmReachResult(ReachResult):
    """The outcome of :meth:`ArmRobot.move_to`: the reach controller's result (``target`` is
    the point the controller was asked for, the approach point; ``goal`` the point it
    commanded) with the point ``move_to`` itself was given, and why they differ."""

    requested: np.ndarray | None = None
    """(3,) [m] world: the point ``move_to`` was given (what the caller asked for)."""
    requested_error_m: float = float("nan")
    """|final_tcp - requested| [m]."""
    note: str = ""
    """Why the commanded goal differs from ``requested`` (empty when it does not): the
    approach from above raised it, the goal selection moved it, or it lies outside the
    workspace and nothing moved."""


#: The robot's own base, which no target may lie in: a cylinder about the base's axis (x = y = 0)
#: [m] from the table top up to the shoulder joint (the Panda's link0 and link1).
BASE_RADIUS_M = 0.12
BASE_TOP_M = 0.333


def check_outside_base(p: np.ndarray) -> None:
    """:class:`PrimitiveArgumentError` when ``p`` (3,) [m] lies inside the robot's own base
    (within :data:`BASE_RADIUS_M` of its axis, below :data:`BASE_TOP_M`): the arm cannot
    reach into itself, and a TCP there would not be "reached" but a collision."""
    r = float(np.hypot(p[0], p[1]))
    if r < BASE_RADIUS_M and p[2] < BASE_TOP_M:
        raise PrimitiveArgumentError(
            f"move_to(pos=...): the point {_xyz(p)} lies inside the robot's own base (within "
            f"{BASE_RADIUS_M:g} m of its axis at x = y = 0, below z = {BASE_TOP_M:g} m, its "
            f"shoulder; this point is {r:.3f} m from the axis): the arm cannot reach into "
            f"itself; give a point at least {BASE_RADIUS_M:g} m from the axis or above "
            f"{BASE_TOP_M:g} m"
        )


def _xyz(p) -> str:
    return "(" + ", ".join(f"{v:+.3f}" for v in p) + ") m"


class _ContactCountingDriver(PyBulletDriver):
    """A PyBulletDriver that counts robot contacts with given bodies after every physics step
    (control steps and planned trajectories alike): points that touch or overlap
    (:func:`~tabletop.arm.driver.touching_points`)."""

    def __init__(self, client_id: int, body_id: int, others: list[int], **kw) -> None:
        super().__init__(client_id, body_id, on_step=self._count, **kw)
        self.others = list(others)
        self.contacts = 0

    def _count(self) -> None:
        pb = self._pb
        for b in self.others:
            self.contacts += touching_points(pb, self.body_id, b, self.client_id)


class ArmRobot(RobotAPI):
    """A Panda on any arm driver, moving on the map's obstacles.

    Args:
        avlmap: the map (queries and obstacles).
        driver: the arm's driver (simulated or real).
        model: the arm's kinematic model (the Panda's by default).
        embodiment: the arm's obstacle concepts.
        keep_out: heatmaps whose heat >= ``keep_out_threshold`` the arm must stay out of.
        keep_out_threshold: heat in (0, 1].
        reach_config: the reach controller's parameters.
        spatial: offsets of the spatial primitives (``above_gap`` is also the approach
            clearance of ``move_to``).
        max_boxes: at most this many obstacle boxes (the voxels are coarsened to fit).
        approach_radius: horizontal radius [m] of the surface ``move_to`` clears.
    """

    refuses_off_map = False  # a point off the workspace: outside_workspace, nothing moves

    needs_map = True

    def __init__(
        self,
        avlmap,
        driver: ArmDriver,
        model: PandaModel | None = None,
        *,
        embodiment: Embodiment = ARM,
        keep_out=(),
        keep_out_threshold: float = 0.5,
        reach_config: ReachConfig | None = None,
        spatial: SpatialConfig | None = None,
        max_boxes: int = 2000,
        approach_radius: float = APPROACH_RADIUS_M,
    ) -> None:
        super().__init__(avlmap, spatial)
        self.model = model or PandaModel()
        self.driver = driver
        self.approach_radius = float(approach_radius)
        self.obstacles = tuple(
            arm_obstacles(avlmap, embodiment, keep_out, keep_out_threshold, max_boxes)
        )
        self.controller = ReachController(self.model, self.driver, self.obstacles, reach_config)
        self.history: list[ReachResult] = []
        """Every move's result, in order."""

    def _own_top(self, p: np.ndarray, occupancy: np.ndarray) -> float:
        """Height [m] of the top of what stands at ``p``: the map instance whose box holds
        ``p`` horizontally (the one with a voxel nearest to it, when several do), else the
        highest surface in the voxel column beneath (the table, 0, where there is none)."""
        objects = getattr(self.map, "objects", None)
        inst = list(objects.instances.items) if getattr(objects, "uses_instances", False) else []
        holding = [i for i in inst if np.all(p[:2] >= i.lo[:2]) and np.all(p[:2] <= i.hi[:2])]
        if holding:
            centers = self.map.voxels.centers
            near = min(holding, key=lambda i: np.min(np.linalg.norm(centers[i.rows] - p, axis=1)))
            return float(near.hi[2])
        return surface_z(self.map.grid, occupancy, p[:2])

    def approach_goal(self, pos) -> tuple[np.ndarray, np.ndarray]:
        """(goal, reference), (3,) [m] each: where ``move_to(pos)`` sends the TCP, and the point
        the reach is judged by (the goal selection keeps alternative goals within the
        controller's ``goal_radius`` of it).

        The reference is ``pos`` raised to the top of what stands there (:meth:`_own_top`).
        The goal is ``pos`` raised to ``above_gap`` over the highest map surface within
        ``approach_radius`` (the gripper's disc), when that is within ``goal_radius`` of the
        reference; else (a taller neighbour in the disc) ``above_gap`` over the reference."""
        p = _point(pos)
        occ = self.map.voxels.occupancy()
        ref = p.copy()
        ref[2] = max(p[2], self._own_top(p, occ))
        gap = self.spatial.above_gap
        wide = approach_point(self.map.grid, occ, p, gap, self.approach_radius)
        if np.linalg.norm(wide - ref) <= self.controller.config.goal_radius:
            return wide, ref
        return np.array([p[0], p[1], max(p[2], ref[2] + gap)]), ref

    def approach(self, pos) -> np.ndarray:
        """(3,) [m]: where ``move_to(pos)`` sends the TCP (:meth:`approach_goal`)."""
        return self.approach_goal(pos)[0]

    def move_to(self, pos) -> ArmReachResult:
        """Reach ``pos`` (3,) [m] base frame with the TCP, approached from above
        (:meth:`approach_goal`); failures are reasons in the result, which states the point
        asked (``requested``), the point commanded (``goal``), the final TCP, and in
        ``note`` why the first two differ.

        A point outside the workspace (below the table's top) whose approach point lies
        beyond the success radius from it is refused: nothing moves, the reason is
        ``outside_workspace`` (raising it onto the table would reach another place)."""
        p = _point(pos)
        check_outside_base(p)
        goal, ref = self.approach_goal(p)
        ws = self.controller.workspace
        far = float(np.linalg.norm(goal - p))
        if not ws.contains(p) and far > SUCCESS_RADIUS_M:
            result = self.controller.move_to(p, reference=p)  # refused: nothing moves
            below = ws.lower[2] - p[2]
            where = (
                f"{below:.2f} m below the table's top (z = {ws.lower[2]:g})"
                if below > 0
                else f"outside the workspace {list(ws.lower)} .. {list(ws.upper)} m"
            )
            note = (
                f"the target {_xyz(p)} lies {where}: the arm cannot reach it; approached from "
                f"above it would stop at {_xyz(goal)}, {far:.2f} m from it (beyond the "
                f"{SUCCESS_RADIUS_M * 100:.0f} cm success radius), so nothing moved"
            )
        else:
            result = self.controller.move_to(goal, reference=ref)
            note = self._difference(p, result)
        honest = ArmReachResult(
            **{f.name: getattr(result, f.name) for f in dataclasses.fields(ReachResult)},
            requested=p,
            requested_error_m=float(np.linalg.norm(result.final_tcp - p)),
            note=note,
        )
        self.history.append(honest)
        return honest

    def _difference(self, p: np.ndarray, result: ReachResult) -> str:
        """Why ``result``'s commanded goal differs from the requested point ``p`` (empty when
        it is within the controller's tolerance of it)."""
        goal = result.goal
        shift = float(np.linalg.norm(goal - p))
        if shift <= self.controller.config.tolerance:
            return ""
        why = []
        if result.target[2] > p[2] + 1e-9:
            what = "the table" if p[2] < 0 else "the surface or object at it"
            why.append(
                f"raised {result.target[2] - p[2]:.3f} m to approach from above: the gripper "
                f"stops {self.spatial.above_gap:g} m over {what}"
            )
        if result.goal_choice == GoalChoice.STANDOFF:
            why.append("lifted to a standoff: the point was inside an obstacle")
        elif result.goal_choice == GoalChoice.ALTERNATIVE:
            why.append(
                "the goal selection chose another point within "
                f"{self.controller.config.goal_radius:g} m: the arm could not clear the first"
            )
        return f"asked {_xyz(p)}, commanded {_xyz(goal)} ({shift:.3f} m apart): " + "; ".join(
            why or ["the approach moved it"]
        )

    def current_position(self) -> np.ndarray:
        """(3,) [m] base frame: the TCP (``panda_grasptarget``), from the measured joints."""
        return self.model.fk(self.driver.read_state().q)[:3, 3].copy()


def _scene_mismatch(avlmap, spec) -> str:
    """Why ``avlmap`` was not built from scene ``spec`` (its header's scene fingerprint
    differs), or empty (the same scene, or a map that does not record its scene)."""
    from tabletop.mapping.persistence import scene_fingerprint

    source = getattr(avlmap, "source", None) or {}
    built = source.get("scene_fingerprint") if isinstance(source, dict) else None
    if built is None:
        return ""
    here = scene_fingerprint(spec.to_dict())
    if built == here:
        return ""
    return (
        f"the map was built from scene {source.get('scene')!r} (fingerprint {built}), not from "
        f"scene {spec.name!r} (fingerprint {here}): the arm would reach the map's places in "
        "another world; give the scene the map was built from"
    )


class SimArm(ArmRobot):
    """The simulated Panda (an :class:`ArmRobot` on a PyBullet driver that counts contacts).

    Args:
        avlmap: the map (queries and obstacles).
        spec: the scene to simulate (a :class:`~tabletop.sim.scene.SceneSpec` or a scene name);
            it must be the scene the map was built from (when the map records it):
            :class:`~tabletop.errors.ConfigError` naming both scenes, as ``tabletop run``.
        other_scene: run in another scene anyway (``--other-scene``): a warning now, and in
            the ``note`` of every result (``scene_mismatch`` holds it).
        **kwargs: the :class:`ArmRobot` options (embodiment, keep_out, reach_config, ...).
    """

    def __init__(self, avlmap, spec="default", *, other_scene: bool = False, **kwargs) -> None:
        from tabletop.sim.scene import SceneSpec, load_scene_spec
        from tabletop.sim.world import SimWorld

        check_bool("SimArm", "other_scene", other_scene)
        if not isinstance(spec, SceneSpec):
            spec = load_scene_spec(spec)
        self.scene_mismatch = _scene_mismatch(avlmap, spec)
        """Why the map was built in another scene (``other_scene=True``), else empty."""
        if self.scene_mismatch and not other_scene:
            raise ConfigError(f"{self.scene_mismatch} (or pass other_scene=True to run it anyway)")
        if self.scene_mismatch:
            warnings.warn(f"SimArm(other_scene=True): {self.scene_mismatch}", stacklevel=2)
        self.world = SimWorld(spec, renderer="tiny")
        model = PandaModel()
        driver = _ContactCountingDriver(
            self.world._client,
            self.world.robot_id,
            [self.world.table_id, *self.world.object_ids.values()],
            finger_opening=model.finger_opening,
        )
        try:
            super().__init__(avlmap, driver, model, **kwargs)
        except BaseException:
            self.world.close()
            raise
        self.contacts: list[int] = []
        """PyBullet contact points (robot vs table/objects) counted during each move."""

    def move_to(self, pos) -> ArmReachResult:
        before = self.driver.contacts
        result = super().move_to(pos)
        self.contacts.append(self.driver.contacts - before)
        if self.scene_mismatch:  # said in every result, as the CLI's summary does
            warn = f"WARNING (other_scene): {self.scene_mismatch}"
            result = dataclasses.replace(
                result, note=f"{warn}; {result.note}" if result.note else warn
            )
            self.history[-1] = result
        return result

    def reset(self, q=HOME_Q) -> None:
        """Put the arm at ``q`` (7,) [rad] kinematically (home by default).

        Raises:
            RobotClosed: the arm was closed.
            PrimitiveArgumentError: ``q`` is not 7 finite joint angles within the joint limits.
        """
        if self.closed:
            raise RobotClosed("reset: this SimArm was closed; make a new one")
        try:
            arr = np.array(q, dtype=np.float64)
        except (TypeError, ValueError):
            arr = None
        if (
            arr is None
            or np.asarray(q).dtype.kind == "b"
            or arr.shape != (7,)
            or not np.all(np.isfinite(arr))
            or not self.model.within_limits(arr)
        ):
            lo, hi = (
                np.round(self.model.q_lower, 2).tolist(),
                np.round(self.model.q_upper, 2).tolist(),
            )
            raise PrimitiveArgumentError(
                f"reset(q=...): q must be 7 finite joint angles [rad] within the joint limits "
                f"{lo} .. {hi} (default: home, {np.round(HOME_Q, 2).tolist()}); got {_shown(q)}"
            )
        self.world.set_arm(arr, self.model.finger_opening)

    def close(self) -> None:
        """Close the simulator; primitives called after it raise
        :class:`~tabletop.robot.api.RobotClosed` (a second close does nothing)."""
        if not self.closed:
            self.world.close()
        super().close()

    def __enter__(self) -> SimArm:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
