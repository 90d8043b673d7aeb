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

import numpy as np

from tabletop.arm.driver import ArmDriver, PyBulletDriver, touching_points
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.arm.reach import ReachConfig, ReachController, ReachResult
from tabletop.mapping.targets import APPROACH_RADIUS_M, approach_point, surface_z
from tabletop.robot.api import RobotAPI, SpatialConfig, _point
from tabletop.robot.obstacles import ARM, Embodiment, arm_obstacles

__all__ = ["ArmRobot", "SimArm"]


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

    def move_to(self, pos) -> ReachResult:
        """Reach ``pos`` (3,) [m] base frame with the TCP, approached from above
        (:meth:`approach_goal`); failures are reasons in the result."""
        goal, ref = self.approach_goal(pos)
        result = self.controller.move_to(goal, reference=ref)
        self.history.append(result)
        return result

    def current_position(self) -> np.ndarray:
        """(3,) [m] base frame: the TCP (``panda_grasptarget``), from the measured joints."""
        return self.model.fk(self.driver.read_state().q)[:3, 3].copy()


class SimArm(ArmRobot):
    """The simulated Panda (an :class:`ArmRobot` on a PyBullet driver that counts contacts).

    Args:
        avlmap: the map (queries and obstacles).
        spec: the scene to simulate (a :class:`~tabletop.sim.scene.SceneSpec` or a scene name);
            it should be the scene the map was built from.
        **kwargs: the :class:`ArmRobot` options (embodiment, keep_out, reach_config, ...).
    """

    def __init__(self, avlmap, spec="default", **kwargs) -> None:
        from tabletop.sim.scene import SceneSpec, load_scene_spec
        from tabletop.sim.world import SimWorld

        if not isinstance(spec, SceneSpec):
            spec = load_scene_spec(spec)
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

    def move_to(self, pos) -> ReachResult:
        before = self.driver.contacts
        result = super().move_to(pos)
        self.contacts.append(self.driver.contacts - before)
        return result

    def reset(self, q=HOME_Q) -> None:
        """Put the arm at ``q`` (7,) [rad] kinematically (home by default)."""
        self.world.set_arm(np.asarray(q, np.float64), self.model.finger_opening)

    def close(self) -> None:
        self.world.close()

    def __enter__(self) -> SimArm:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
