"""Room scans: drive the wheeled base through a room like a teleoperator would, looking at every
table and around, recording the mast camera at 30 Hz of simulated time, with sounds inserted
into the audio track while the base stands at some of the tables.

The plan: from the start, visit the tables in nearest-first order; at each, drive (A* on the
room's occupancy grid, inflated by the base's radius and a margin, then the pure-pursuit
follower on the wheel motors) to viewpoints on its free sides, face the table, pan the
camera left and right; at the first ``episodes`` tables, stand still for an audio episode;
at the end, turn once around on the spot in the middle of the room. The recording is the
arm's format (:mod:`tabletop.recording`): ``T_world_hand`` is the base's pose from its wheel
odometry (``ee_frame = "base_footprint"``), ``T_world_hand_true`` the simulator's,
``T_hand_cam`` / ``T_hand_mic`` the mast's extrinsics from the URDF, ``joint_positions`` the
two wheel angles. A scan in which the base touches anything but the floor fails.

Like an operator who watches the robot, the scan steers by the base's true pose; what the
base itself believes (its odometry, which drifts with every turn) is what the recording holds,
beside the truth.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, fields

import numpy as np

from tabletop.base import (
    BasePose,
    FollowConfig,
    OdometryDrift,
    follow_path,
    grid_path,
    turn_to,
)
from tabletop.base.description import BASE_FRAME, WHEEL_JOINTS
from tabletop.errors import ConfigError, SimulationError
from tabletop.recording import Recording
from tabletop.sim.camera import WristCameraConfig
from tabletop.sim.noise import NoiseConfig
from tabletop.sim.room import FurnitureSpec, RoomSpec
from tabletop.sim.room_world import RoomWorld, mast_camera_config
from tabletop.sim.scan import check_field_types
from tabletop.sim.scan_frames import FrameRecorder, FrameState, assemble_recording

__all__ = ["RoomScanConfig", "RoomScanStats", "base_pose_of", "run_room_scan", "scan_room"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RoomScanConfig:
    """How a room scan is driven and recorded."""

    seed: int = 0
    """Seed of the viewpoint choice and the sound placement."""
    rate_hz: float = 30.0
    """Frame rate [Hz] of simulated time."""
    max_linear: float = 0.45
    """Top driving speed [m/s]."""
    max_angular: float = 0.8
    """Top turning rate [rad/s] (the camera pans at this rate)."""
    views_per_table: int = 2
    """Viewpoints per table (on different sides where the room allows); a table less than
    1 m across gets one."""
    standoff: float = 0.55
    """Distance [m] from a table's edge to the base's centre at a viewpoint."""
    look_s: float = 1.0
    """Time [s] the base stands still facing a table at each viewpoint."""
    pan_rad: float = 0.4
    """How far [rad] the base turns left and right of the table at a viewpoint (0: no pan)."""
    look_around: bool = True
    """End with a full turn on the spot in the middle of the room."""
    tables: tuple[str, ...] = ()
    """Which tables (furniture names) to visit; empty: every table and every item with
    objects."""
    clearance: float = 0.2
    """Margin [m] beyond the base's radius that planned paths keep from furniture and walls
    (pure pursuit cuts corners, and the odometry drifts a little)."""
    lookahead: float = 0.25
    """The follower's lookahead [m]."""
    episodes: int = 3
    """Audio episodes (0 = no audio): the base stands at the first ``episodes`` visited tables
    while a sound-bank clip plays. At most one per visited table."""
    episode_s: float = 4.0
    """Length [s] of each audio episode."""
    repeat_sounds: int = 0
    """How many sound categories are inserted at two tables (ambiguous sound goals)."""
    clip_split: str = "heldout"
    """Which sound-bank clips to insert: "heldout", "train" or "any"."""
    snr_db: float = 15.0
    """Clip-to-background ratio [dB] of the inserted sounds."""
    min_recordings: int = 6
    """Only categories with at least this many clips in the bank are inserted (see
    :class:`tabletop.sim.scan.ScanConfig`)."""
    drift: OdometryDrift = field(default_factory=OdometryDrift)
    """Odometry drift of the base (default: exact wheel odometry)."""
    camera: WristCameraConfig = field(default_factory=mast_camera_config)
    """The mast camera (its ``T_hand_cam`` is the mast extrinsic in ``base_footprint``)."""
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    """Sensor noise added to the recording (default: none)."""
    renderer: str = "auto"
    """"auto" (EGL if it works), "egl" or "tiny"."""
    timeout_s: float = 60.0
    """Longest drive [s] to one viewpoint before the scan fails."""

    def __post_init__(self) -> None:
        check_field_types(self, "room scan")
        object.__setattr__(self, "tables", tuple(self.tables))
        positive = ("rate_hz", "max_linear", "max_angular", "standoff", "timeout_s", "lookahead")
        for name in positive:
            if getattr(self, name) <= 0:
                raise ConfigError(f"room scan {name} must be > 0, got {getattr(self, name)}")
        for name in ("look_s", "pan_rad", "clearance", "seed", "episodes", "repeat_sounds"):
            if getattr(self, name) < 0:
                raise ConfigError(f"room scan {name} must be >= 0, got {getattr(self, name)}")
        if self.views_per_table < 1:
            raise ConfigError(f"room scan views_per_table must be >= 1, got {self.views_per_table}")
        if self.pan_rad > 1.5:
            raise ConfigError(f"room scan pan_rad must be at most 1.5 rad, got {self.pan_rad}")
        if self.episode_s < 1.0:
            raise ConfigError(f"room scan episode_s must be >= 1 s, got {self.episode_s}")
        if not 0 <= self.repeat_sounds <= self.episodes // 2:
            raise ConfigError(
                f"room scan repeat_sounds must be in [0, episodes // 2 = {self.episodes // 2}], "
                f"got {self.repeat_sounds}"
            )
        if self.clip_split not in ("heldout", "train", "any"):
            raise ConfigError(
                f"room scan clip_split must be 'heldout', 'train' or 'any', not {self.clip_split!r}"
            )
        if self.renderer not in ("auto", "egl", "tiny"):
            raise ConfigError(
                f"room scan renderer must be 'auto', 'egl' or 'tiny', not {self.renderer!r}"
            )
        for name, cls in (
            ("drift", OdometryDrift),
            ("camera", WristCameraConfig),
            ("noise", NoiseConfig),
        ):
            if not isinstance(getattr(self, name), cls):
                raise ConfigError(f"room scan {name} must be a {cls.__name__}")

    def follow_config(self) -> FollowConfig:
        """The follower's settings for this scan."""
        return FollowConfig(
            max_linear=self.max_linear,
            max_angular=self.max_angular,
            timeout_s=self.timeout_s,
            lookahead=self.lookahead,
            control_dt=min(0.05, 1.0 / self.rate_hz),
        )


@dataclass(frozen=True)
class RoomScanStats:
    """What a room scan took."""

    frames: int
    simulated_s: float
    wall_s: float
    render_s: float
    distance_m: float
    """Path length [m] the base drove (true poses)."""
    collisions: int
    """Contacts of the base with anything but the floor (a scan fails on any)."""


@dataclass(frozen=True)
class _Visit:
    table: FurnitureSpec
    viewpoints: tuple[tuple[float, float], ...]


_CELL = 0.05
#: The base stops within the follower's goal tolerance of a free viewpoint, which may put it
#: in a blocked cell of the inflated grid; it then leaves from the nearest free cell.
_SNAP = 0.15


def _viewpoints(
    table: FurnitureSpec, free: np.ndarray, config: RoomScanConfig
) -> list[tuple[int, tuple[float, float]]]:
    """(side, point): free, reachable points ``standoff`` from the table's edge, at most one
    per side (its middle, else shifted along it); sides 0-3 are +x, +y, -x, -y of the table's
    frame."""
    L, D = table.dims[0] / 2, table.dims[1] / 2
    c, s = math.cos(table.yaw), math.sin(table.yaw)
    sides = [
        (L + config.standoff, 0.0),
        (0.0, D + config.standoff),
        (-L - config.standoff, 0.0),
        (0.0, -D - config.standoff),
    ]
    out = []
    for k in range(4):
        for shift in (0.0, 0.25, -0.25, 0.45, -0.45):  # along the side if its middle is blocked
            lx, ly = sides[k]
            if lx == 0.0:
                lx = shift * L
            else:
                ly = shift * D
            p = (table.position[0] + c * lx - s * ly, table.position[1] + s * lx + c * ly)
            i, j = int(p[0] / _CELL), int(p[1] / _CELL)
            if 0 <= i < free.shape[0] and 0 <= j < free.shape[1] and free[i, j]:
                out.append((k, p))
                break
    return out


def _plan(spec: RoomSpec, config: RoomScanConfig, blocked: np.ndarray) -> list[_Visit]:
    from scipy import ndimage

    labels, _ = ndimage.label(~blocked)
    sx, sy = spec.start.position
    start_label = labels[int(sx / _CELL), int(sy / _CELL)]
    if start_label == 0:
        raise SimulationError(
            f"the base's start {list(spec.start.position)} is within {config.clearance} m of "
            "furniture or a wall: no room to plan from"
        )
    free = labels == start_label
    if config.tables:
        names = [f.name for f in spec.furniture]
        unknown = [t for t in config.tables if t not in names]
        if unknown:
            raise ConfigError(f"room scan tables: no furniture {unknown}; furniture: {names}")
        tables = [spec.item(t) for t in config.tables]
    else:
        tables = [f for f in spec.furniture if f.category == "table" or f.objects]
    candidates = {}
    for t in tables:
        vps = _viewpoints(t, free, config)
        if not vps:
            raise SimulationError(
                f"table {t.name!r} has no free viewpoint {config.standoff} m from its edge that "
                "the base can reach; move the furniture apart or lower standoff"
            )
        candidates[t.name] = vps
    # a nearest-first tour from the start: at each table, the nearest side first, then the
    # opposite one (else the farthest), so that both views together see the whole top
    order, here = [], np.array(spec.start.position)
    left = list(tables)
    while left:
        dist = [min(math.dist(p, here) for _, p in candidates[t.name]) for t in left]
        t = left.pop(int(np.argmin(dist)))
        vps = sorted(candidates[t.name], key=lambda kp: math.dist(kp[1], here))
        views = [vps[0]]
        n = config.views_per_table if max(t.dims[:2]) >= 1.0 else 1
        rest = sorted(
            vps[1:], key=lambda kp: (kp[0] != (vps[0][0] + 2) % 4, -math.dist(kp[1], vps[0][1]))
        )
        views += rest[: n - 1]
        order.append(_Visit(t, tuple(p for _, p in views)))
        here = np.array(views[-1][1])
    return order


class _OperatorView:
    """The base as a teleoperator drives it: by where it really is (the simulator's pose),
    not by its odometry."""

    def __init__(self, driver) -> None:
        self._driver = driver
        self.params = driver.params

    def read_odometry(self) -> BasePose:
        return self._driver.true_pose()

    def command_wheels(self, left: float, right: float, duration: float) -> None:
        self._driver.command_wheels(left, right, duration)

    def stop(self) -> None:
        self._driver.stop()


def _check(result, what: str) -> None:
    if not result.reached:
        raise SimulationError(f"room scan: {what} failed ({result.reason})")


def run_room_scan(
    spec: RoomSpec,
    config: RoomScanConfig | None = None,
    progress: Callable[[int], None] | None = None,
) -> Recording:
    """Scan a room with the wheeled base; return the recording (with ground truth).

    ``meta`` records the contacts (``collisions``, 0) and the distance driven
    (``distance_m``); :func:`scan_room` also returns the timing figures.

    Raises:
        SimulationError: the base touched furniture, a wall or an object, or could not reach
            a viewpoint.
    """
    return scan_room(spec, config, progress)[0]


def scan_room(
    spec: RoomSpec,
    config: RoomScanConfig | None = None,
    progress: Callable[[int], None] | None = None,
) -> tuple[Recording, RoomScanStats]:
    """Scan a room with the wheeled base; return the recording (with ground truth) and figures.

    ``progress(frames)`` is called after each recorded frame (the total is not known ahead:
    the drive takes what the physics takes).

    Raises:
        SimulationError: the base touched furniture, a wall or an object, or could not reach
            a viewpoint.
    """
    config = config or RoomScanConfig()
    t_start = time.perf_counter()
    follow = config.follow_config()
    with RoomWorld(spec, config.camera, config.renderer, drift=config.drift) as world:
        base = world.driver
        d = _OperatorView(base)
        inflate = d.params.radius + config.clearance
        blocked = spec.occupancy(_CELL, inflate=inflate)
        visits = _plan(spec, config, blocked)
        if len(visits) < config.episodes:  # before any driving
            raise ConfigError(
                f"room scan: {config.episodes} audio episodes need as many tables to stand "
                f"at; the scan visits {len(visits)}: {[v.table.name for v in visits]}"
            )

        def state() -> FrameState:
            return FrameState(
                base.read_odometry().as_matrix(),
                world.T_world_base(),
                base.wheel_angles(),
                world.T_world_mic()[:3, 3],
            )

        rec = FrameRecorder(world, config.rate_hz, state, progress, t0=base.time)
        base.on_physics_step = rec
        rec(base.time)  # frame 0 where the base stands
        episode_places: list[FurnitureSpec] = []
        for i, visit in enumerate(visits):
            t = visit.table
            for j, vp in enumerate(visit.viewpoints):
                here = d.read_odometry()
                path = grid_path(blocked, _CELL, here.xy, vp, snap_start=_SNAP)
                if path is None:
                    raise SimulationError(f"room scan: no path to {t.name!r} viewpoint {vp}")
                facing = math.atan2(t.position[1] - vp[1], t.position[0] - vp[0])
                rec.segment = (f"transit_{i}_{j}", "transit")
                first = (
                    math.atan2(path[1][1] - here.y, path[1][0] - here.x)
                    if len(path) > 1
                    else facing
                )
                _check(turn_to(d, first, follow), f"turning toward {t.name!r}")
                _check(follow_path(d, path, follow, final_yaw=facing), f"driving to {t.name!r}")
                rec.segment = (f"look_{i}_{j}", "mapping")
                base.hold(config.look_s)
                if config.pan_rad > 0:
                    for yaw in (facing + config.pan_rad, facing - config.pan_rad, facing):
                        _check(turn_to(d, yaw, follow), f"panning at {t.name!r}")
                if j == 0 and len(episode_places) < config.episodes:
                    rec.segment = (f"episode_{len(episode_places)}", "episode")
                    base.hold(config.episode_s)
                    episode_places.append(t)
        if config.look_around:
            free = np.argwhere(~blocked)
            centre = np.array(spec.size) / 2
            pts = (free + 0.5) * _CELL
            goal = pts[int(np.argmin(np.linalg.norm(pts - centre, axis=1)))]
            path = grid_path(blocked, _CELL, d.read_odometry().xy, goal, snap_start=_SNAP)
            if path is not None:
                rec.segment = ("transit_centre", "transit")
                here = d.read_odometry()
                if len(path) > 1:
                    _check(
                        turn_to(d, math.atan2(path[1][1] - here.y, path[1][0] - here.x), follow),
                        "turning toward the room's centre",
                    )
                _check(follow_path(d, path, follow), "driving to the room's centre")
                rec.segment = ("look_around", "mapping")
                yaw = d.read_odometry().yaw
                for k in range(1, 5):
                    _check(turn_to(d, yaw + k * math.pi / 2, follow), "looking around")
        base.hold(1.0 / config.rate_hz)
        rec.segment = ("end", "mapping")
        base.stop()
        base.on_physics_step = None
        if base.collisions:
            c = base.collision_log[0]
            k = min(int((c.t - rec.t0) * config.rate_hz), len(rec.labels) - 1)
            raise SimulationError(
                f"room scan: the base touched {c.other!r} at t = {c.t:.2f} s during "
                f"{rec.labels[k][0]!r}, at {np.round(c.position, 3).tolist()} "
                f"({base.collisions} contacts in all)"
            )
        ground_truth = world.ground_truth()
        renderer = world.renderer
        K = world.intrinsics.K
        T_hand_mic = world.description.T_base_mic
        collisions = base.collisions

    n = len(rec.labels)
    f = rec.arrays()
    true = f["true"]

    def annotate(events: list[dict]) -> None:
        for e, place in zip(events, episode_places, strict=True):
            e["region_center"][2] = float(place.top_z or 0.0)
            e["place"] = place.name

    distance = float(np.linalg.norm(np.diff(true[:, :2, 3], axis=0), axis=1).sum()) if n else 0.0
    recording = assemble_recording(
        f,
        config=config,
        segments=rec.segments(),
        episode_centers=[p.position for p in episode_places],
        ground_truth=ground_truth,
        K=K,
        T_hand_cam=config.camera.T_hand_cam,
        T_hand_mic=T_hand_mic,
        meta={
            "source": "tabletop.sim.room_scan",
            "robot": "mobile_base",
            "room": spec.name,
            "seed": config.seed,
            "renderer": renderer,
            "rate_hz": config.rate_hz,
            "collisions": collisions,
            "distance_m": round(distance, 4),
            "odometry_drift": {k.name: getattr(config.drift, k.name) for k in fields(config.drift)},
        },
        annotate_events=annotate,
        T_world_hand_true=true,
        ee_frame=BASE_FRAME,
        joint_names=WHEEL_JOINTS,
    )
    stats = RoomScanStats(
        frames=len(recording),
        simulated_s=n / config.rate_hz,
        wall_s=time.perf_counter() - t_start,
        render_s=rec.render_s,
        distance_m=distance,
        collisions=collisions,
    )
    log.info(
        "room scan: %d frames, %.1f s simulated, %.1f s wall", n, stats.simulated_s, stats.wall_s
    )
    return recording, stats


def base_pose_of(recording: Recording, i: int) -> BasePose:
    """The recorded (odometry) base pose of frame ``i`` as a :class:`BasePose`."""
    return BasePose.from_matrix(recording.T_world_hand[i], float(recording.timestamps[i]))
