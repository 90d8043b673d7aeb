"""The arm on franky-sim: the robot API driving an FR3 through libfranka's network protocol.

:class:`FrankySimArm` is an :class:`~tabletop.robot.arm.ArmRobot` whose driver is a
:class:`~tabletop.arm.franky_driver.FrankyDriver` connected to a franky-sim server on a
loopback address (:class:`~tabletop.arm.franky_sim.FrankySimServer`, started by the arm unless
one is given): every reach is planned on the map as in the simulator and sent through the real
franky client, which franky-sim executes in MuJoCo. franky-sim simulates the arm alone, so the
scene's table and objects are mirrored in PyBullet: after each motion the joints the server
*measured* are replayed there, and the arm's contacts with the table and objects are counted
(:attr:`contacts`, as :class:`~tabletop.robot.arm.SimArm` counts them while it moves).
Reflexes are counted (:attr:`reflexes`) and raised (:class:`~tabletop.arm.errors.ReflexError`).

Used by ``tabletop demo --driver franky-sim`` and ``tabletop eval --driver franky-sim``.
"""

from __future__ import annotations

import numpy as np

from tabletop.arm.driver import touching_points
from tabletop.arm.errors import ReflexError
from tabletop.arm.franky_driver import FrankyDriver
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.errors import ConfigError
from tabletop.robot.arm import ArmReachResult, ArmRobot, _scene_mismatch

__all__ = ["FrankySimArm", "ReplayedFrankyDriver"]

#: Motion settings of the arm on franky-sim (fractions of the FR3's limits): those of the
#: driver's tests, which franky-sim tracks within 0.25 rad at half speed.
DYNAMICS = {"velocity_scale": 0.5, "acceleration_scale": 0.5, "jerk_scale": 0.2}


class ReplayedFrankyDriver(FrankyDriver):
    """A :class:`FrankyDriver` that keeps the joints measured during every executed
    trajectory (:attr:`measured`, each (K, 7) [rad]) for a mirror to replay, and every
    trajectory's tracking (:attr:`reports`)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.measured: list[np.ndarray] = []
        self.reports: list = []

    def execute_trajectory(self, trajectory) -> None:
        self.last_tracking = None
        try:
            super().execute_trajectory(trajectory)
        finally:
            rep = self.last_tracking
            if rep is not None:
                self.measured.append(np.asarray(rep.q, np.float64))
                self.reports.append(rep)

    def command_positions(self, q: np.ndarray, duration: float) -> None:
        start = self.read_state().q
        super().command_positions(q, duration)
        # a single rest-to-rest motion: its path is the straight joint line
        self.measured.append(np.linspace(start, self.read_state().q, 50))


class FrankySimArm(ArmRobot):
    """The Panda's reach on franky-sim's FR3, with the scene mirrored for contacts.

    Args:
        avlmap: the map (queries and obstacles).
        spec: the scene mirrored for contacts (a :class:`~tabletop.sim.scene.SceneSpec` or a
            scene name); it must be the scene the map was built from, when the map records
            it (:class:`~tabletop.errors.ConfigError` naming both).
        server: a running :class:`~tabletop.arm.franky_sim.FrankySimServer` (default: one
            is started here and killed on :meth:`close`).
        replay_step: replay every this many measured samples (the server samples at about
            1 kHz of robot time).
        **kwargs: the :class:`ArmRobot` options (embodiment, keep_out, reach_config, ...).

    Raises:
        DriverError: franky-sim is not installed or did not start; the connection failed.
    """

    def __init__(
        self, avlmap, spec="default", *, server=None, replay_step: int = 5, **kwargs
    ) -> None:
        from tabletop.arm.franky_sim import FrankySimServer
        from tabletop.sim.scene import SceneSpec, load_scene_spec
        from tabletop.sim.world import SimWorld

        if not isinstance(spec, SceneSpec):
            spec = load_scene_spec(spec)
        mismatch = _scene_mismatch(avlmap, spec)
        if mismatch:
            raise ConfigError(mismatch)
        if int(replay_step) < 1:
            raise ConfigError(f"replay_step must be a positive integer, got {replay_step!r}")
        self.replay_step = int(replay_step)
        self._own_server = server is None
        self.server = FrankySimServer() if server is None else server
        self.world = None
        self._driver: ReplayedFrankyDriver | None = None
        try:
            model = PandaModel()
            driver = self._driver = ReplayedFrankyDriver(
                self.server.host, robot_model="fr3", model=model, realtime=False, **DYNAMICS
            )
            self.world = SimWorld(spec, renderer="tiny")
            super().__init__(avlmap, driver, model, **kwargs)
            self._bodies = [self.world.table_id, *self.world.object_ids.values()]
            self.reset()
        except BaseException:
            self._shutdown()
            raise
        self.contacts: list[int] = []
        """Mirrored contact points (arm vs table and objects) counted during each move."""
        self.reflexes = 0
        """Motions the robot aborted with a reflex."""

    @property
    def tracking_reports(self) -> list:
        """franky's :class:`~tabletop.arm.franky_driver.TrackingReport` of every trajectory
        the reaches executed, in order."""
        return list(self.driver.reports)

    def _count_contacts(self, samples: list[np.ndarray]) -> int:
        """Contacts of the arm with the scene's table and objects, the measured joints
        replayed kinematically in the mirror."""
        pb, client, body = self.world._pb, self.world._client, self.world.robot_id
        opening = self.model.finger_opening
        n = 0
        for q in samples:
            rows = q[:: self.replay_step]
            if len(q) and (len(q) - 1) % self.replay_step:
                rows = np.vstack([rows, q[-1:]])
            for row in rows:
                self.world.set_arm(row, opening)
                pb.performCollisionDetection(physicsClientId=client)
                n += sum(touching_points(pb, body, b, client) for b in self._bodies)
        return n

    def move_to(self, pos) -> ArmReachResult:
        before = len(self.driver.measured)
        try:
            result = super().move_to(pos)
        except ReflexError:
            self.reflexes += 1
            raise
        finally:
            self.contacts.append(self._count_contacts(self.driver.measured[before:]))
        return result

    def reset(self, q=HOME_Q) -> None:
        """Move the arm to ``q`` (7,) [rad] (home by default) through franky: a real motion
        on the server, not a kinematic reset."""
        q = np.asarray(q, np.float64)
        now = self.driver.read_state().q
        if np.abs(now - q).max() > self.driver.goal_tolerance:
            v = self.driver.v_limit * 0.5
            duration = max(1.0, float(np.max(np.abs(q - now) / v)))
            self.driver.command_positions(q, duration)
        self.world.set_arm(q, self.model.finger_opening)

    def _shutdown(self) -> None:
        drv = self._driver
        if drv is not None and not drv.closed:
            drv.close()
        if self.world is not None:
            self.world.close()
            self.world = None
        if self._own_server:
            self.server.close()

    def close(self) -> None:
        """Close the driver, the mirror and (when the arm started it) the server."""
        if not self.closed:
            self._shutdown()
        super().close()

    def __enter__(self) -> FrankySimArm:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
