"""Path following on the wheels: pure pursuit, turning in place when the heading is far off.

:func:`follow_path` drives a :class:`~tabletop.base.driver.BaseDriver` along a polyline of
waypoints. Each control step it reads the odometry, finds the path point one lookahead
distance ahead of the base's projection on the path, and steers toward it on the circular
arc through both (pure pursuit); when that point lies more than ``turn_in_place`` off the
heading, the base turns on the spot first. Speed drops near the goal; the run ends within
``goal_tolerance`` of the last waypoint (then turns to ``final_yaw`` if one is given), at
the timeout, or when ``on_step`` returns False. The follower never raises for a path it
cannot finish: the result says why it stopped.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields

import numpy as np

from tabletop.base.driver import BaseDriver
from tabletop.base.errors import PathError
from tabletop.base.kinematics import limit_wheels, wheels_from_twist
from tabletop.base.pose import BasePose, wrap_angle
from tabletop.errors import ConfigError

__all__ = ["FollowConfig", "FollowResult", "follow_path", "turn_to"]

#: Called after every control step with the odometry; returning False stops the base.
StepCallback = Callable[[BasePose], "bool | None"]


@dataclass(frozen=True)
class FollowConfig:
    """How the follower drives."""

    lookahead: float = 0.30
    """Pure-pursuit lookahead distance along the path [m]."""
    goal_tolerance: float = 0.05
    """The run has reached the goal when the base is this close to the last waypoint [m]."""
    max_linear: float = 0.40
    """Top forward speed [m/s] (also capped by the wheels' limit)."""
    min_linear: float = 0.04
    """Forward speed [m/s] the slow-down near the goal never goes below."""
    max_angular: float = 1.2
    """Top turn rate [rad/s]."""
    slowdown_distance: float = 0.40
    """Within this distance of the goal [m], speed falls linearly with the distance."""
    turn_in_place: float = 0.8
    """Heading error [rad] above which the base stops and turns on the spot."""
    heading_gain: float = 2.5
    """Turn rate per radian of heading error [1/s] when turning in place."""
    control_dt: float = 0.05
    """Control period [s] (driver time): one wheel command per step."""
    timeout_s: float = 120.0
    """Give up after this much driver time [s]."""
    yaw_tolerance: float = 0.05
    """A turn (``turn_to``, ``final_yaw``) is done within this heading error [rad]."""

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(f"FollowConfig.{f.name} must be a finite number, got {v!r}")
            if v <= 0:
                raise ConfigError(f"FollowConfig.{f.name} must be > 0, got {v}")
            object.__setattr__(self, f.name, float(v))
        if self.min_linear > self.max_linear:
            raise ConfigError(
                f"FollowConfig.min_linear ({self.min_linear}) must not exceed max_linear "
                f"({self.max_linear}) [m/s]"
            )
        if self.turn_in_place >= math.pi:
            raise ConfigError(f"FollowConfig.turn_in_place must be < pi, got {self.turn_in_place}")


@dataclass(frozen=True)
class FollowResult:
    """The outcome of :func:`follow_path` or :func:`turn_to` (a value)."""

    reached: bool
    """Whether the base ended within the tolerances."""
    reason: str
    """``"reached"`` | ``"timeout"`` | ``"stopped"`` (``on_step`` returned False)."""
    final: BasePose
    """The odometry at the end."""
    driven: np.ndarray
    """(K, 3) float64: the odometry's x [m], y [m], yaw [rad] at the start and after every
    control step."""
    duration_s: float
    """Driver time [s] the run took."""


def _as_path(path_xy: object) -> np.ndarray:
    try:
        p = np.array(path_xy, dtype=np.float64)
    except (TypeError, ValueError):
        raise PathError(f"path_xy must be (K, 2) numbers [m], got {path_xy!r}") from None
    if p.ndim == 1 and p.shape == (2,):
        p = p[None]
    if p.ndim != 2 or p.shape[1] != 2 or len(p) == 0:
        raise PathError(f"path_xy must have shape (K, 2) with K >= 1 [m], got {p.shape}")
    bad = np.flatnonzero(~np.isfinite(p).all(axis=1))
    if len(bad):
        raise PathError(f"path_xy[{bad[0]}] is not finite: {p[bad[0]].tolist()}")
    keep = np.concatenate([[True], np.linalg.norm(np.diff(p, axis=0), axis=1) > 1e-9])
    return p[keep]


def _check_yaw(yaw: object, name: str) -> float:
    if isinstance(yaw, bool) or not isinstance(yaw, (int, float)) or not math.isfinite(yaw):
        raise ConfigError(f"{name} must be a finite angle [rad], got {yaw!r}")
    return float(yaw)


class _Run:
    """Bookkeeping shared by both controllers: the odometry trace, time, the callback."""

    def __init__(self, driver: BaseDriver, config: FollowConfig, on_step) -> None:
        self.driver, self.config, self.on_step = driver, config, on_step
        self.start = driver.read_odometry()
        self.trace = [self.start.as_array()]

    def step(self, v: float, w: float) -> BasePose | None:
        """Command a twist for one control period; the new odometry, or None if stopped."""
        p = self.driver.params
        left, right = limit_wheels(p, *wheels_from_twist(p, v, w))
        self.driver.command_wheels(left, right, self.config.control_dt)
        pose = self.driver.read_odometry()
        self.trace.append(pose.as_array())
        if self.on_step is not None and self.on_step(pose) is False:
            return None
        return pose

    def timed_out(self, pose: BasePose) -> bool:
        return pose.t - self.start.t >= self.config.timeout_s

    def result(self, reached: bool, reason: str) -> FollowResult:
        self.driver.stop()
        final = self.driver.read_odometry()
        return FollowResult(
            reached=reached,
            reason=reason,
            final=final,
            driven=np.array(self.trace),
            duration_s=final.t - self.start.t,
        )


def _turn(run: _Run, yaw: float) -> str:
    """Turn in place to ``yaw`` [rad]: "reached", "timeout" or "stopped"."""
    c = run.config
    pose = run.driver.read_odometry()
    while True:
        err = wrap_angle(yaw - pose.yaw)
        if abs(err) <= c.yaw_tolerance:
            return "reached"
        if run.timed_out(pose):
            return "timeout"
        # never overshoot within one step, never stall below a tenth of the top rate
        rate = min(c.max_angular, c.heading_gain * abs(err), abs(err) / c.control_dt)
        rate = max(rate, min(0.1 * c.max_angular, abs(err) / c.control_dt))
        pose = run.step(0.0, math.copysign(rate, err))
        if pose is None:
            return "stopped"


def turn_to(
    driver: BaseDriver,
    yaw: float,
    config: FollowConfig | None = None,
    *,
    on_step: StepCallback | None = None,
) -> FollowResult:
    """Turn on the spot until the odometry's heading is within ``yaw_tolerance`` of ``yaw``
    [rad] (world frame)."""
    yaw = _check_yaw(yaw, "yaw")
    run = _Run(driver, config or FollowConfig(), on_step)
    reason = _turn(run, yaw)
    return run.result(reason == "reached", reason)


def _project(path: np.ndarray, cum: np.ndarray, xy: np.ndarray, lo: float) -> float:
    """Arc length [m] of the point of ``path`` nearest to ``xy`` at or beyond ``lo``."""
    a, b = path[:-1], path[1:]
    ab = b - a
    seg_len = np.linalg.norm(ab, axis=1)
    s = np.clip(np.einsum("ij,ij->i", xy - a, ab) / np.maximum(seg_len**2, 1e-18), 0.0, 1.0)
    arc = cum[:-1] + s * seg_len
    arc = np.maximum(arc, lo)
    pts = np.array([_at(path, cum, x) for x in arc])
    d = np.linalg.norm(pts - xy, axis=1)
    return float(arc[int(np.argmin(d))])


def _at(path: np.ndarray, cum: np.ndarray, s: float) -> np.ndarray:
    """The path point at arc length ``s`` [m] (clamped to the ends)."""
    s = min(max(s, 0.0), cum[-1])
    i = min(int(np.searchsorted(cum, s, side="right")) - 1, len(path) - 2)
    seg = cum[i + 1] - cum[i]
    f = 0.0 if seg <= 0 else (s - cum[i]) / seg
    return path[i] + f * (path[i + 1] - path[i])


def follow_path(
    driver: BaseDriver,
    path_xy: object,
    config: FollowConfig | None = None,
    *,
    final_yaw: float | None = None,
    on_step: StepCallback | None = None,
) -> FollowResult:
    """Drive along ``path_xy`` (K, 2) [m], world frame, to its last point.

    The base starts wherever its odometry says; the first waypoint is usually where it
    stands. With ``final_yaw`` [rad], the base turns to that heading at the goal.

    Raises:
        PathError: ``path_xy`` is not (K, 2) finite numbers.
        ConfigError: ``final_yaw`` is not a finite angle.
    """
    c = config or FollowConfig()
    path = _as_path(path_xy)
    if final_yaw is not None:
        final_yaw = _check_yaw(final_yaw, "final_yaw")
    run = _Run(driver, c, on_step)
    pose = run.start
    path = np.vstack([pose.xy, path]) if np.linalg.norm(path[0] - pose.xy) > 1e-9 else path
    goal = path[-1]
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    progress = 0.0
    v_top = min(c.max_linear, driver.params.max_linear_speed)
    while True:
        to_goal = float(np.linalg.norm(goal - pose.xy))
        if to_goal <= c.goal_tolerance:
            break
        if run.timed_out(pose):
            return run.result(False, "timeout")
        if len(path) > 1:
            progress = _project(path, cum, pose.xy, progress)
        remaining = cum[-1] - progress
        target = _at(path, cum, progress + c.lookahead) if len(path) > 1 else goal
        if remaining < c.lookahead or np.linalg.norm(target - pose.xy) < 1e-6:
            target = goal
        d = target - pose.xy
        alpha = wrap_angle(math.atan2(d[1], d[0]) - pose.yaw)
        if abs(alpha) > c.turn_in_place:
            rate = min(c.max_angular, c.heading_gain * abs(alpha))
            pose = run.step(0.0, math.copysign(rate, alpha))
        else:
            dist = max(float(np.linalg.norm(d)), 1e-6)
            v = v_top * min(1.0, max(to_goal, remaining) / c.slowdown_distance)
            # never overshoot the goal within one control step
            v = min(max(v, c.min_linear), to_goal / c.control_dt)
            kappa = 2.0 * math.sin(alpha) / dist
            w = v * kappa
            if abs(w) > c.max_angular:  # keep the curvature, drop the speed
                v *= c.max_angular / abs(w)
                w = math.copysign(c.max_angular, w)
            pose = run.step(v, w)
        if pose is None:
            return run.result(False, "stopped")
    if final_yaw is not None:
        reason = _turn(run, final_yaw)
        if reason != "reached":
            return run.result(False, reason)
    return run.result(True, "reached")
