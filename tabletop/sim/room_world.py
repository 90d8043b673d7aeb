"""The simulated room: a PyBullet world with the room's walls, furniture and objects, and the
wheeled base driven by its wheel motors with physics on.

:class:`RoomWorld` builds the room from a :class:`~tabletop.sim.room.RoomSpec` and loads
``urdf/base/tabletop_base.urdf`` at the spec's start; :meth:`RoomWorld.render` renders the
mast camera (RGB, metric depth, segmentation; OpenCV optical frame), :meth:`RoomWorld.ground_truth`
tells where everything is. :class:`PyBulletBaseDriver` is the base's
:class:`~tabletop.base.driver.BaseDriver`: velocity motors on the two wheel joints, physics
stepped in simulated time, odometry integrated from the wheel joint angles (what a real base's
encoders give, with an optional seeded drift), the true pose from the simulator, and a count
of the robot's collisions with anything but the floor.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from tabletop.base import (
    TABLETOP_BASE,
    BaseDriver,
    BasePose,
    DiffDriveParams,
    OdometryDrift,
    WheelOdometry,
    base_urdf_path,
    check_command,
    load_base_description,
)
from tabletop.base.description import BASE_FRAME, MIC_FRAME, WHEEL_JOINTS
from tabletop.errors import ConfigError, SimulationError
from tabletop.sim.camera import WristCameraConfig
from tabletop.sim.catalog import pybullet_data_dir
from tabletop.sim.ground_truth import AreaTruth, FurnitureTruth
from tabletop.sim.room import FURNITURE_MODELS, FurnitureSpec, RoomSpec
from tabletop.sim.world import PlacedObject, PyBulletWorld
from tabletop.transforms import make_transform, quat_from_matrix, rotation_about

__all__ = [
    "INSTANCE_FLOOR",
    "INSTANCE_NONE",
    "INSTANCE_ROBOT",
    "Collision",
    "PyBulletBaseDriver",
    "RoomWorld",
    "mast_camera_config",
]

log = logging.getLogger(__name__)

INSTANCE_NONE, INSTANCE_FLOOR, INSTANCE_ROBOT = 0, 1, 2
_FIRST_ITEM_INSTANCE = 3
#: Legs of the pybullet_data tables, which collide only with their tops: (x, y) of each leg's
#: centre from the table's, its half sizes (x, y, z) [m] and centre height [m].
_TABLE_LEGS = {
    "table": ([(-0.65, -0.4), (-0.65, 0.4), (0.65, -0.4), (0.65, 0.4)], (0.05, 0.05, 0.29), 0.29),
    "table_square": (
        [(-0.25, -0.25), (-0.25, 0.25), (0.25, -0.25), (0.25, 0.25)],
        (0.025, 0.025, 0.28),
        0.28,
    ),
}
#: Contact spring of the casters [N/m] and its damping [N s/m] (see PyBulletBaseDriver).
_CASTER_STIFFNESS, _CASTER_DAMPING = 3.0e4, 300.0
#: The sofa's seat height [m] and back-rest depth [m].
_SOFA_SEAT, _SOFA_BACK = 0.45, 0.2


def mast_camera_config(**overrides) -> WristCameraConfig:
    """The mast camera: 320x240, 58 deg vertical field of view, depth valid 0.1-5 m, its
    extrinsic (``T_hand_cam``, the hand being ``base_footprint``) from the base's URDF."""
    kw = dict(near=0.1, far=5.0, T_hand_cam=load_base_description().T_base_cam)
    kw.update(overrides)
    return WristCameraConfig(**kw)


@dataclass(frozen=True)
class Collision:
    """The start of a contact between the robot and something other than the floor."""

    t: float
    """Simulated time [s]."""
    other: str
    """What it touched (a furniture, wall or object name)."""
    position: tuple[float, float, float]
    """Contact point [m], world frame."""


class RoomWorld(PyBulletWorld):
    """A PyBullet room built from a :class:`RoomSpec`, with the wheeled base at its start.

    Args:
        spec: the room.
        camera: the mast camera (default :func:`mast_camera_config`).
        renderer: "auto" (EGL when it works), "egl" or "tiny".
        physics_hz: physics steps per simulated second.
        drift: odometry drift of the :attr:`driver` (None: exact wheel odometry).
    """

    camera_link = BASE_FRAME
    truth_frame = "world = room frame; z up, floor at z = 0; metres"

    def __init__(
        self,
        spec: RoomSpec,
        camera: WristCameraConfig | None = None,
        renderer: str = "auto",
        *,
        physics_hz: float = 240.0,
        drift: OdometryDrift | None = None,
    ) -> None:
        self._physics_hz, self._drift = physics_hz, drift
        super().__init__(spec, camera, renderer)

    def _configure(self) -> None:
        physics_hz = self._physics_hz
        if not (isinstance(physics_hz, (int, float)) and 60 <= physics_hz <= 2000):
            raise ConfigError(f"physics_hz must be in [60, 2000], got {physics_hz!r}")
        self.description = load_base_description()
        self.physics_dt = 1.0 / physics_hz

    def _default_camera(self) -> WristCameraConfig:
        return mast_camera_config()

    def _built(self) -> None:
        self.driver = PyBulletBaseDriver(self, drift=self._drift)
        """The base's driver (one per world)."""

    # ------------------------------------------------------------------ building
    def _box(self, half, center, yaw: float, rgba, visual: bool = True, collision: bool = True):
        pb, cid = self._pb, self._client
        vis = (
            pb.createVisualShape(
                pb.GEOM_BOX, halfExtents=list(half), rgbaColor=rgba, physicsClientId=cid
            )
            if visual
            else -1
        )
        col = (
            pb.createCollisionShape(pb.GEOM_BOX, halfExtents=list(half), physicsClientId=cid)
            if collision
            else -1
        )
        q = quat_from_matrix(rotation_about("z", yaw)).tolist()
        return pb.createMultiBody(0, col, vis, list(center), q, physicsClientId=cid)

    def _local(self, f: FurnitureSpec, xy, z: float) -> list[float]:
        """A point of ``f``'s frame (x, y from its centre, z above the floor) in the room."""
        c, s = math.cos(f.yaw), math.sin(f.yaw)
        return [f.position[0] + c * xy[0] - s * xy[1], f.position[1] + s * xy[0] + c * xy[1], z]

    def _build_item(self, f: FurnitureSpec) -> list[int]:
        pb, cid = self._pb, self._client
        data = pybullet_data_dir()
        q = quat_from_matrix(rotation_about("z", f.yaw)).tolist()
        model = FURNITURE_MODELS[f.model]
        if f.model in ("table", "table_square"):
            body = pb.loadURDF(
                str(data / model.source),
                [*f.position, 0.0],
                q,
                useFixedBase=True,
                physicsClientId=cid,
            )
            legs, half, z = _TABLE_LEGS[f.model]
            return [body] + [
                self._box(half, self._local(f, xy, z), f.yaw, None, visual=False) for xy in legs
            ]
        if f.model == "kiva_shelf":
            bodies = list(pb.loadSDF(str(data / model.source), physicsClientId=cid))
            for b in bodies:
                pb.resetBasePositionAndOrientation(
                    b, [*f.position, model.base_z], q, physicsClientId=cid
                )
            return bodies
        L, D, H = f.dims
        rgba = [*f.color, 1.0]
        if f.model == "box":
            return [self._box((L / 2, D / 2, H / 2), [*f.position, H / 2], f.yaw, rgba)]
        if f.model == "sofa":
            seat = self._box(
                (L / 2, D / 2, _SOFA_SEAT / 2), [*f.position, _SOFA_SEAT / 2], f.yaw, rgba
            )
            back = self._box(
                (L / 2, _SOFA_BACK / 2, H / 2),
                self._local(f, (0.0, -D / 2 + _SOFA_BACK / 2), H / 2),
                f.yaw,
                [0.8 * c for c in f.color] + [1.0],
            )
            return [seat, back]
        raise SimulationError(f"no builder for furniture model {f.model!r}")  # pragma: no cover

    def _build(self) -> None:
        pb, cid = self._pb, self._client
        pb.setGravity(0, 0, -9.81, physicsClientId=cid)
        pb.setTimeStep(self.physics_dt, physicsClientId=cid)
        self._start_bodies(
            {
                INSTANCE_NONE: "none",
                INSTANCE_FLOOR: "floor",
                INSTANCE_ROBOT: "robot",
            }
        )
        self.floor_id = pb.loadURDF(str(pybullet_data_dir() / "plane.urdf"), physicsClientId=cid)
        self._add_body(self.floor_id, INSTANCE_FLOOR, "floor")
        inst = _FIRST_ITEM_INSTANCE
        self.item_instance: dict[str, int] = {}
        for f in self.spec.furniture:
            for body in self._build_item(f):
                self._add_body(body, inst, f.name)
            self.item_instance[f.name] = inst
            self.instance_names[inst] = f.name
            inst += 1
        for w in self.spec.walls():
            body = self._box(w.half_extents, w.center, 0.0, [*self.spec.wall_color, 1.0])
            self._add_body(body, inst, w.name)
            self.item_instance[w.name] = inst
            self.instance_names[inst] = w.name
            inst += 1
        self._add_objects(inst)

        sx, sy = self.spec.start.position
        q = quat_from_matrix(rotation_about("z", math.radians(self.spec.start.yaw_deg)))
        self._load_robot(
            str(base_urdf_path()), BASE_FRAME, INSTANCE_ROBOT, [sx, sy, 0.0], q.tolist()
        )
        self._finish_bodies()

    def _placed_objects(self) -> list[PlacedObject]:
        placed = []
        for f, obj in self.spec.objects:
            T = f.T_world_obj(obj)
            yaw_deg = float(np.degrees(math.atan2(T[1, 0], T[0, 0])))
            placed.append(PlacedObject(obj, T, T[:2, 3], yaw_deg, f.object_aabb(obj), f.name))
        return placed

    # ------------------------------------------------------------------ state
    def T_world_base(self) -> np.ndarray:
        """(4, 4) the true pose of ``base_footprint`` (with any tilt physics gives it)."""
        return self.link_pose(BASE_FRAME)

    def T_world_mic(self) -> np.ndarray:
        """(4, 4) the true pose of the microphone."""
        return self.link_pose(MIC_FRAME)

    # ------------------------------------------------------------------ ground truth
    def _scene_truth(self) -> dict:
        """Furniture and walls (category, box) and one area per table (its top); no table of
        the arm's (the room's tables are among the furniture)."""
        furniture = []
        for f in self.spec.furniture:
            lo, hi = f.aabb()
            furniture.append(
                FurnitureTruth(
                    name=f.name,
                    category=f.category,
                    model=f.model,
                    instance_id=self.item_instance[f.name],
                    T_world_item=make_transform(rotation_about("z", f.yaw), (*f.position, 0.0)),
                    aabb_min=lo,
                    aabb_max=hi,
                    top_z=f.top_z,
                )
            )
        for w in self.spec.walls():
            lo, hi = w.aabb()
            furniture.append(
                FurnitureTruth(
                    name=w.name,
                    category="wall",
                    model="wall",
                    instance_id=self.item_instance[w.name],
                    T_world_item=make_transform(None, (w.center[0], w.center[1], 0.0)),
                    aabb_min=lo,
                    aabb_max=hi,
                )
            )
        areas = []
        for f in self.spec.furniture:
            if f.objects or f.category == "table":
                lo, hi = f.aabb()
                areas.append(
                    AreaTruth(
                        name=f.name.replace("_", " "),
                        aliases=(f.name,),
                        x=(lo[0], hi[0]),
                        y=(lo[1], hi[1]),
                        center=[*f.position, f.top_z or 0.0],
                    )
                )
        return dict(table=None, areas=tuple(areas), furniture=tuple(furniture))

    def reset_base(self, pose: BasePose | None = None) -> None:
        """Put the base back at ``pose`` (default: the room's start) at rest, with its
        odometry there, and clear its collision count (a new run in the same room)."""
        if pose is None:
            sx, sy = self.spec.start.position
            pose = BasePose(sx, sy, math.radians(self.spec.start.yaw_deg))
        pb, cid = self._pb, self._client
        q = quat_from_matrix(rotation_about("z", pose.yaw))
        pb.resetBasePositionAndOrientation(
            self.robot_id, [pose.x, pose.y, 0.0], q.tolist(), physicsClientId=cid
        )
        pb.resetBaseVelocity(self.robot_id, [0, 0, 0], [0, 0, 0], physicsClientId=cid)
        for j in self.driver._wheels:
            pb.resetJointState(self.robot_id, j, 0.0, 0.0, physicsClientId=cid)
        self.driver._target = [0.0, 0.0]
        self.driver._set_motors()
        self.driver.hold(0.25)  # settle on the floor
        self.driver.reset_odometry()
        self.driver.collisions = 0
        self.driver.collision_log.clear()
        self.driver._touching.clear()


class PyBulletBaseDriver(BaseDriver):
    """The base in a :class:`RoomWorld`, driven through its wheel motors with physics on.

    Each command sets velocity motors on the two wheel joints (their targets ramped at
    ``max_wheel_accel``, as a motor controller does) and steps the physics for the command's
    duration. After every physics step the odometry reads the wheel joint angles, contacts
    with anything but the floor are counted, and ``on_physics_step`` (if set) is called with
    the simulated time.

    Args:
        world: the room (the driver steps its physics).
        drift: odometry errors (wheel radius error, slip), seeded; None: exact encoders.
        max_wheel_accel: largest change of a wheel's target speed [rad/s^2].
        max_wheel_torque: motor torque limit [N m] (the URDF's wheel effort).
    """

    def __init__(
        self,
        world: RoomWorld,
        *,
        drift: OdometryDrift | None = None,
        max_wheel_accel: float = 16.0,
        max_wheel_torque: float = 8.0,
    ) -> None:
        if not (max_wheel_accel > 0 and max_wheel_torque > 0):
            raise ConfigError(
                f"max_wheel_accel and max_wheel_torque must be > 0, got {max_wheel_accel}, "
                f"{max_wheel_torque}"
            )
        self.world = world
        self.params: DiffDriveParams = world.description.params
        if self.params != TABLETOP_BASE:  # pragma: no cover - a changed URDF
            log.warning("the base URDF's wheels differ from TABLETOP_BASE: %s", self.params)
        self.max_wheel_accel = float(max_wheel_accel)
        self.max_wheel_torque = float(max_wheel_torque)
        pb, cid, body = world._pb, world._client, world.robot_id
        self._pb, self._cid, self._body = pb, cid, body
        self._wheels = [world._joint_index[n] for n in WHEEL_JOINTS]
        # Four rigid contacts (two wheels, two casters) share the load as the solver pleases:
        # in some start poses the casters took it all and the wheels spun without traction.
        # Compliant casters (a spring of _CASTER_STIFFNESS) leave the load on the wheels; the
        # rear caster carries the few newtons of the mast's offset, tilting the base < 0.1 deg.
        for link in ("front_caster", "rear_caster"):
            pb.changeDynamics(
                body,
                world._link_index[link],
                lateralFriction=0.0,
                rollingFriction=0.0,
                spinningFriction=0.0,
                contactStiffness=_CASTER_STIFFNESS,
                contactDamping=_CASTER_DAMPING,
                physicsClientId=cid,
            )
        for j in self._wheels:
            pb.changeDynamics(body, j, lateralFriction=1.0, physicsClientId=cid)
        self.time = 0.0
        """Simulated time [s] since the world was built."""
        self._target = [0.0, 0.0]
        self._set_motors()
        self.collisions = 0
        """Contacts begun between the robot and anything but the floor."""
        self.collision_log: list[Collision] = []
        self._touching: set[int] = set()
        self.on_physics_step: Callable[[float], None] | None = None
        """Called after every physics step with the simulated time [s] (e.g. to record)."""
        # settle on the floor, then start the odometry where the base stands
        for _ in range(int(0.25 / world.physics_dt)):
            self._step()
        self._odometry = WheelOdometry(self.params, self.true_pose(), self.wheel_angles(), drift)

    # ------------------------------------------------------------------ sensing
    def wheel_angles(self) -> tuple[float, float]:
        """(left, right) wheel joint angles [rad], accumulated (not wrapped)."""
        st = self._pb.getJointStates(self._body, self._wheels, physicsClientId=self._cid)
        return float(st[0][0]), float(st[1][0])

    def wheel_speeds(self) -> tuple[float, float]:
        """(left, right) measured wheel angular velocities [rad/s]."""
        st = self._pb.getJointStates(self._body, self._wheels, physicsClientId=self._cid)
        return float(st[0][1]), float(st[1][1])

    def true_pose(self) -> BasePose:
        """Where the simulator has the base (planar part), on the driver clock."""
        return BasePose.from_matrix(self.world.T_world_base(), self.time)

    def read_odometry(self) -> BasePose:
        return self._odometry.pose

    # ------------------------------------------------------------------ acting
    def _set_motors(self) -> None:
        self._pb.setJointMotorControlArray(
            self._body,
            self._wheels,
            self._pb.VELOCITY_CONTROL,
            targetVelocities=list(self._target),
            forces=[self.max_wheel_torque] * 2,
            physicsClientId=self._cid,
        )

    def _step(self) -> None:
        self._pb.stepSimulation(physicsClientId=self._cid)
        self.time += self.world.physics_dt
        touching = {}
        for c in self._pb.getContactPoints(bodyA=self._body, physicsClientId=self._cid):
            other = c[2]
            if other not in (self.world.floor_id, self._body):
                touching.setdefault(other, c[5])
        for other in touching.keys() - self._touching:
            self.collisions += 1
            self.collision_log.append(
                Collision(
                    self.time,
                    self.world.body_name.get(other, str(other)),
                    tuple(float(v) for v in touching[other]),
                )
            )
        self._touching = set(touching)

    def _run(self, goal: tuple[float, float], duration: float) -> None:
        n = max(1, round(duration / self.world.physics_dt))
        step = self.max_wheel_accel * self.world.physics_dt
        for _ in range(n):
            if self._target != list(goal):
                self._target = [
                    t + float(np.clip(g - t, -step, step))
                    for t, g in zip(self._target, goal, strict=True)
                ]
                self._set_motors()
            self._step()
            if hasattr(self, "_odometry"):
                self._odometry.update(*self.wheel_angles(), self.time)
            if self.on_physics_step is not None:
                self.on_physics_step(self.time)

    def command_wheels(self, left: float, right: float, duration: float) -> None:
        left, right, duration = check_command(self.params, left, right, duration)
        self._run((left, right), duration)

    def hold(self, duration: float) -> None:
        """Stand still (wheels commanded to 0) for ``duration`` [s] of simulated time."""
        self.command_wheels(0.0, 0.0, duration)

    def stop(self) -> None:
        """Ramp the wheel targets to 0 and step until the wheels are at rest (at most 1 s)."""
        t0 = self.time
        while self.time - t0 < 1.0:
            self._run((0.0, 0.0), self.world.physics_dt)
            if self._target == [0.0, 0.0] and max(map(abs, self.wheel_speeds())) < 0.05:
                break

    def reset_odometry(self, pose: BasePose | None = None) -> None:
        """Set the odometry to ``pose`` (default: the true pose), e.g. after a relocalisation."""
        pose = pose or self.true_pose()
        self._odometry.reset(replace(pose, t=self.time), self.wheel_angles())
