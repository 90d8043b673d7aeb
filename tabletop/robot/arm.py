"""The Panda in simulation behind the robot API: the map's obstacles, the reach controller.

:class:`SimArm` builds a PyBullet :class:`~tabletop.sim.world.SimWorld` of the scene, drives its
Panda with the :class:`~tabletop.arm.reach.ReachController` over a
:class:`~tabletop.arm.driver.PyBulletDriver`, and gives the controller the obstacles the MAP
says are there (:func:`tabletop.robot.obstacles.arm_obstacles`), not the simulator's ground
truth. The simulator only checks the outcome: PyBullet contact points between the robot and the
table or objects are counted after every control step.
"""

from __future__ import annotations

import numpy as np

from tabletop.arm.driver import PyBulletDriver
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.arm.reach import ReachConfig, ReachController, ReachResult
from tabletop.robot.api import RobotAPI, SpatialConfig, _point
from tabletop.robot.obstacles import ARM, Embodiment, arm_obstacles

__all__ = ["SimArm"]


class _ContactCountingDriver(PyBulletDriver):
    """A PyBulletDriver that counts robot contacts with given bodies after every command."""

    def __init__(self, client_id: int, body_id: int, others: list[int], **kw) -> None:
        super().__init__(client_id, body_id, **kw)
        self.others = list(others)
        self.contacts = 0

    def _count(self) -> None:
        pb = self._pb
        for b in self.others:
            self.contacts += len(
                pb.getContactPoints(self.body_id, b, physicsClientId=self.client_id)
            )

    def command_positions(self, q: np.ndarray, duration: float) -> None:
        super().command_positions(q, duration)
        self._count()

    def command_velocities(self, dq: np.ndarray, duration: float) -> None:
        super().command_velocities(dq, duration)
        self._count()


class SimArm(RobotAPI):
    """The simulated Panda, moving on the map's obstacles.

    Args:
        avlmap: the map (queries and obstacles).
        spec: the scene to simulate (a :class:`~tabletop.sim.scene.SceneSpec` or a scene name);
            it should be the scene the map was built from.
        embodiment: the arm's obstacle concepts.
        keep_out: heatmaps whose heat >= ``keep_out_threshold`` the arm must stay out of.
        keep_out_threshold: heat in (0, 1].
        reach_config: the reach controller's parameters.
        spatial: offsets of the spatial primitives.
        max_boxes: at most this many obstacle boxes (the voxels are coarsened to fit).
    """

    def __init__(
        self,
        avlmap,
        spec="default",
        *,
        embodiment: Embodiment = ARM,
        keep_out=(),
        keep_out_threshold: float = 0.5,
        reach_config: ReachConfig | None = None,
        spatial: SpatialConfig | None = None,
        max_boxes: int = 2000,
    ) -> None:
        from tabletop.sim.scene import SceneSpec, load_scene_spec
        from tabletop.sim.world import SimWorld

        super().__init__(avlmap, spatial)
        if not isinstance(spec, SceneSpec):
            spec = load_scene_spec(spec)
        self.obstacles = tuple(
            arm_obstacles(avlmap, embodiment, keep_out, keep_out_threshold, max_boxes)
        )
        self.world = SimWorld(spec, renderer="tiny")
        self.model = PandaModel()
        self.driver = _ContactCountingDriver(
            self.world._client,
            self.world.robot_id,
            [self.world.table_id, *self.world.object_ids.values()],
            finger_opening=self.model.finger_opening,
        )
        self.controller = ReachController(self.model, self.driver, self.obstacles, reach_config)
        self.history: list[ReachResult] = []
        """Every move's result, in order."""
        self.contacts: list[int] = []
        """PyBullet contact points (robot vs table/objects) counted during each move."""

    def move_to(self, pos) -> ReachResult:
        """Reach ``pos`` (3,) [m] base frame with the TCP; failures are reasons in the result."""
        p = _point(pos)
        before = self.driver.contacts
        result = self.controller.move_to(p)
        self.history.append(result)
        self.contacts.append(self.driver.contacts - before)
        return result

    def current_position(self) -> np.ndarray:
        """(3,) [m] base frame: the TCP (``panda_grasptarget``), from the measured joints."""
        return self.model.fk(self.driver.read_state().q)[:3, 3].copy()

    def reset(self, q=HOME_Q) -> None:
        """Put the arm at ``q`` (7,) [rad] kinematically (home by default)."""
        self.world.set_arm(np.asarray(q, np.float64), self.model.finger_opening)

    def close(self) -> None:
        self.world.close()

    def __enter__(self) -> SimArm:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
