"""A wheeled base behind the robot API: it plans on the map's obstacle grid of its embodiment
and drives its wheels along the path.

:class:`MobileRobot` implements :meth:`~tabletop.robot.api.RobotAPI.move_to` for any
:class:`~tabletop.base.driver.BaseDriver` (the simulator's wheels, an ideal unicycle, a real
base's adapter):

1. the embodiment's obstacles (:func:`~tabletop.robot.obstacles.occupancy_grid`: the map's
   voxels labelled with its obstacle concepts, in its height band, seen from above) are
   pooled onto cells of ``cell_m`` and inflated by the base's radius plus ``clearance_m``;
2. a goal inside an obstacle (an object on a table, a table) moves to the nearest free cell the
   base can reach, at most ``max_goal_shift`` away (a mobile goal is reached within a radius,
   1 m in the paper's evaluation);
3. A* (8-connected, no corner cutting) finds the cells, which are shortened to the waypoints
   that see each other on the inflated grid (:func:`tabletop.base.planner.grid_path`);
4. the path follower (:func:`~tabletop.base.follower.follow_path`) drives the wheels.

The same map gives different robots different obstacles (the paper's open-vocabulary
obstacle maps): :data:`GROUND_BASE` is blocked by everything that stands on the floor, a
:data:`FLYER` passes over tables, what stands on them and low furniture, but not walls and
shelves.

Spatial primitives resolve in the base's frame (x along its heading, y to its left), as the
arm's resolve in its fixed base frame: "left of" an object is to the base's left of it, "in
front of" further along its heading; compass moves (``move_north``...) stay in the room
frame. :meth:`MobileRobot.move_forward`, :meth:`MobileRobot.turn` and :meth:`MobileRobot.face`
are the base's own motions.

World frame = the room frame: metres, z up, floor at z = 0; yaw counter-clockwise from +x.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from tabletop.base.driver import BaseDriver
from tabletop.base.follower import FollowConfig, FollowResult, follow_path, turn_to
from tabletop.base.planner import grid_path
from tabletop.errors import ConfigError
from tabletop.robot.api import RobotAPI, SpatialConfig, _point, check_axis
from tabletop.robot.obstacles import Embodiment, OccupancyGrid, occupancy_grid

__all__ = [
    "FLYER",
    "GROUND_BASE",
    "DriveResult",
    "MobileRobot",
    "RoomMoveConfig",
    "plan_path",
]

#: A wheeled base in a room: everything from just above the floor to its mast's height blocks
#: it (tables, shelves, walls, what stands on them).
GROUND_BASE = Embodiment(
    name="ground base",
    obstacles=("other", "table", "wall", "shelf", "cabinet", "robot arm"),
    free=("floor",),
    z_range=(0.04, 1.4),
    fill_down_to=None,
)

#: A flyer cruising at 1.2 m: walls, shelves and anything it cannot name block it, and so
#: does whatever reaches above its cruising height, named or not; it passes over the floor,
#: tables, what stands on them and low furniture (the map's object names are free for it).
FLYER = Embodiment(
    name="flyer",
    obstacles=("wall", "shelf", "other"),
    free=("floor", "table", "cabinet", "sofa"),
    z_range=(0.04, 2.2),
    fill_down_to=None,
    map_objects=False,
    objects_free=True,
    block_above=1.2,
)


@dataclass(frozen=True)
class RoomMoveConfig:
    """How :class:`MobileRobot` plans."""

    radius: float = 0.20
    """The base's footprint radius [m]."""
    clearance_m: float = 0.08
    """Extra distance [m] kept from obstacles beyond the radius."""
    cell_m: float = 0.05
    """Planning cell [m]: the obstacle grid pooled to it (any obstacle voxel blocks a cell)."""
    max_goal_shift: float = 1.0
    """A goal inside an (inflated) obstacle moves to the nearest reachable free cell if that
    is at most this far [m]; else the move ends ``no_path``."""
    follow: FollowConfig = field(default_factory=FollowConfig)
    """The path follower's settings."""

    def __post_init__(self) -> None:
        for name in ("radius", "clearance_m", "max_goal_shift"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0:
                raise ConfigError(f"RoomMoveConfig.{name} must be a number >= 0 [m], got {v!r}")
        v = self.cell_m
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.005 <= v <= 0.5:
            raise ConfigError(f"RoomMoveConfig.cell_m must be in [0.005, 0.5] m, got {v!r}")


@dataclass(frozen=True)
class DriveResult:
    """The outcome of a :class:`MobileRobot` motion (a value)."""

    reached: bool
    reason: str
    """"reached" | "outside_map" | "start_blocked" | "no_path" | the follower's reason
    ("timeout", "stopped")."""
    target: np.ndarray
    """(3,) [m] the point asked for."""
    goal: np.ndarray
    """(3,) [m] where the base was sent (z = 0; the target moved out of an obstacle)."""
    goal_shifted: bool
    final_position: np.ndarray
    """(3,) [m] the base's odometry at the end (z = 0)."""
    final_yaw: float
    """[rad] its heading at the end."""
    planned: np.ndarray
    """(K, 2) [m] the planned waypoints; (0, 2) without a plan."""
    driven: np.ndarray
    """(M, 3) x [m], y [m], yaw [rad] of the odometry along the way."""
    length_m: float
    """Length [m] of the planned path."""
    duration_s: float
    """Driver time [s] of the motion."""
    collisions: int = 0
    """Collisions the driver counted during the motion (a simulated base; 0 otherwise)."""

    @property
    def error_m(self) -> float:
        """|final - target| in x, y [m]."""
        return float(np.hypot(*(self.final_position[:2] - self.target[:2])))


def _pooled(grid: OccupancyGrid, cell_m: float) -> OccupancyGrid:
    """``grid`` on cells of about ``cell_m`` (a whole number of its cells; any occupied cell
    occupies the pooled one)."""
    f = max(round(cell_m / grid.cell_size), 1)
    if f == 1:
        return grid
    occ = grid.occupied
    nx, ny = -(-occ.shape[0] // f), -(-occ.shape[1] // f)
    pad = np.zeros((nx * f, ny * f), bool)
    pad[: occ.shape[0], : occ.shape[1]] = occ
    pooled = pad.reshape(nx, f, ny, f).any(axis=(1, 3))
    return OccupancyGrid(pooled, grid.lower, grid.cell_size * f)


def plan_path(
    blocked: OccupancyGrid, start_xy, goal_xy, max_goal_shift: float
) -> tuple[str, np.ndarray, np.ndarray, bool]:
    """(reason, waypoints (K, 2) [m], goal (2,) [m], goal shifted?) on an inflated grid:
    reason is "reached" (a path exists), "outside_map", "start_blocked" or "no_path"."""
    start_xy = np.asarray(start_xy, float)[:2]
    goal_xy = np.asarray(goal_xy, float)[:2]
    none = np.zeros((0, 2))
    sc, s_in = blocked.to_cell(start_xy)
    gc, g_in = blocked.to_cell(goal_xy)
    if not g_in:
        return "outside_map", none, goal_xy, False
    if not s_in or blocked.occupied[tuple(sc)]:
        return "start_blocked", none, goal_xy, False
    free = ~blocked.occupied
    lab, _ = ndimage.label(free, structure=np.ones((3, 3)))
    region = lab == lab[tuple(sc)]
    shifted = not region[tuple(gc)]
    if shifted:
        cells = np.argwhere(region)
        d = np.linalg.norm(blocked.to_world(cells) - goal_xy, axis=1)
        k = int(np.argmin(d))
        if d[k] > max_goal_shift:
            return "no_path", none, goal_xy, True
        gc = cells[k]
    # the goal's cell is free and reachable: finish on the exact point (or that cell's centre)
    end = goal_xy if not shifted else blocked.to_world(np.array([gc]))[0]
    xy = grid_path(blocked.occupied, blocked.cell_size, start_xy, end, blocked.lower)
    if xy is None:  # pragma: no cover - the goal is in the start's free region
        return "no_path", none, goal_xy, shifted
    return "reached", xy, xy[-1].copy(), shifted


class MobileRobot(RobotAPI):
    """A wheeled base on any base driver, planning on the map's obstacles for its embodiment.

    Its primitives are the shared robot API's and a base's own (``ahead``, ``move_forward``,
    ``turn``, ``face``: :data:`tabletop.robot.primitives.PRIMITIVES`).

    Args:
        avlmap: the map (queries and obstacles).
        driver: the base's driver (:class:`~tabletop.base.driver.BaseDriver`).
        embodiment: its obstacle concepts (:data:`GROUND_BASE`, :data:`FLYER`, your own).
        config: footprint, planning cell, goal handling, the follower.
        keep_out: heatmaps whose heat >= ``keep_out_threshold`` the base must stay out of.
        spatial: offsets of the spatial primitives (a base keeps further from objects than a
            gripper: 0.6 m beside by default).
    """

    refuses_off_map = False  # its own honest results

    robot_kind = "mobile"

    needs_map = True

    def __init__(
        self,
        avlmap,
        driver: BaseDriver,
        *,
        embodiment: Embodiment = GROUND_BASE,
        config: RoomMoveConfig | None = None,
        keep_out=(),
        keep_out_threshold: float = 0.5,
        spatial: SpatialConfig | None = None,
    ) -> None:
        super().__init__(avlmap, spatial or SpatialConfig(side_offset=0.6, side_gap=0.3))
        self.driver = driver
        self.embodiment = embodiment
        self.config = config or RoomMoveConfig()
        self.obstacles: OccupancyGrid = _pooled(
            occupancy_grid(avlmap, embodiment, keep_out, keep_out_threshold), self.config.cell_m
        )
        """The embodiment's obstacles seen from above, on planning cells (not inflated)."""
        self.blocked: OccupancyGrid = self.obstacles.inflated(
            self.config.radius + self.config.clearance_m
        )
        """The configuration space: obstacles inflated by the radius and the clearance."""
        self.history: list[DriveResult] = []
        self._seen = self._collisions()

    def _collisions(self) -> int:
        return int(getattr(self.driver, "collisions", 0))

    @property
    def contacts(self) -> list[int]:
        """Collisions per motion, in the order of :attr:`history`."""
        return [r.collisions for r in self.history]

    # --------------------------------------------------------------------- state
    def current_position(self) -> np.ndarray:
        """(3,) [m]: the base's centre on the floor (z = 0), from its odometry."""
        p = self.driver.read_odometry()
        return np.array([p.x, p.y, 0.0])

    def heading(self) -> float:
        """[rad] the base's yaw, from its odometry."""
        return float(self.driver.read_odometry().yaw)

    # --------------------------------------------------------------------- motion
    def _result(self, reason, target, goal_xy, shifted, planned, run: FollowResult | None):
        pose = self.driver.read_odometry()
        r = DriveResult(
            reached=run is not None and run.reached,
            reason=reason if run is None else run.reason,
            target=target,
            goal=np.array([goal_xy[0], goal_xy[1], 0.0]),
            goal_shifted=shifted,
            final_position=np.array([pose.x, pose.y, 0.0]),
            final_yaw=float(pose.yaw),
            planned=planned,
            driven=np.zeros((0, 3)) if run is None else run.driven,
            length_m=float(np.linalg.norm(np.diff(planned, axis=0), axis=1).sum()),
            duration_s=0.0 if run is None else run.duration_s,
            collisions=self._collisions() - self._seen,
        )
        self._seen = self._collisions()
        self.history.append(r)
        return r

    def plan(self, pos) -> tuple[str, np.ndarray, np.ndarray, bool]:
        """Plan without moving: (reason, waypoints (K, 2) [m], goal (2,) [m], shifted?)."""
        return plan_path(
            self.blocked, self.current_position(), _point(pos), self.config.max_goal_shift
        )

    def move_to(self, pos) -> DriveResult:
        """Plan a collision-free path to ``pos`` (x, y used) and drive it; at the end the
        base faces the target."""
        target = _point(pos)
        reason, xy, goal, shifted = self.plan(target)
        if reason != "reached":
            return self._result(reason, target, goal, shifted, xy, None)
        d = target[:2] - goal
        yaw = math.atan2(d[1], d[0]) if np.hypot(*d) > 1e-3 else None
        run = follow_path(self.driver, xy, self.config.follow, final_yaw=yaw)
        return self._result("reached", target, goal, shifted, xy, run)

    def ahead(self, distance_m: float) -> np.ndarray:
        """(3,) [m] the point ``distance_m`` [m] ahead of the base along its heading (negative:
        behind it), on the floor."""
        d = _finite(distance_m, "distance_m")
        p = self.driver.read_odometry()
        return np.array([p.x + d * math.cos(p.yaw), p.y + d * math.sin(p.yaw), 0.0])

    def move_forward(self, distance_m: float) -> DriveResult:
        """Drive ``distance_m`` [m] straight ahead (negative: back), around what is in the way."""
        return self.move_to(self.ahead(distance_m))

    def turn(self, angle_deg: float) -> DriveResult:
        """Turn on the spot by ``angle_deg`` [deg], counter-clockwise positive."""
        a = math.radians(_finite(angle_deg, "angle_deg"))
        p = self.driver.read_odometry()
        run = turn_to(self.driver, p.yaw + a, self.config.follow)
        here = np.array([p.x, p.y, 0.0])
        return self._result("reached", here, here[:2], False, np.zeros((0, 2)), run)

    def face(self, name) -> DriveResult:
        """Turn on the spot towards an object (or any landmark heatmap)."""
        c, _, _ = self._landmark(name)
        p = self.driver.read_odometry()
        run = turn_to(self.driver, math.atan2(c[1] - p.y, c[0] - p.x), self.config.follow)
        here = np.array([p.x, p.y, 0.0])
        return self._result("reached", here, here[:2], False, np.zeros((0, 2)), run)

    # --------------------------------------------------------------------- spatial
    def side_target(self, name, direction) -> np.ndarray:
        """(3,) [m] on the floor: the point beside landmark ``name`` along ``direction``, a unit
        axis of the BASE's frame (x forward along its heading, y to its left), as the arm's
        axes are of its base frame: "left of" is to the base's left, "in front of" further
        along its heading (``side_offset`` from the centre, at least ``side_gap`` beyond the
        landmark's extent)."""
        d = check_axis("side_target", direction)
        yaw = self.heading()
        c, s = math.cos(yaw), math.sin(yaw)
        u = np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]])
        ctr, lo, hi = self._landmark(name)
        half = float(np.abs(u) @ ((hi - lo)[:2] / 2))
        dist = max(self.spatial.side_offset, half + self.spatial.side_gap)
        return np.array([ctr[0] + dist * u[0], ctr[1] + dist * u[1], 0.0])

    def offset(self, dx: float, dy: float) -> np.ndarray:
        """The current position moved by (``dx``, ``dy``) [m] in the room frame (the compass
        moves: north = +x, west = +y)."""
        return super().offset(dx, dy)


def _finite(v, name: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ConfigError(f"{name} must be a finite number, got {v!r}")
    return float(v)
