"""Time-parametrised joint trajectories within the Panda's limits (ruckig).

A planned path is a list of joint-space waypoints joined by straight segments (that is what
the collision checker certifies). :func:`time_parametrize` turns it into a
:class:`JointTrajectory`: samples every ``period`` seconds of position, velocity and
acceleration that stay within :data:`PANDA_LIMITS` (position, velocity, acceleration, jerk),
scaled down by a :class:`TrajectoryConfig`.

Each segment is a rest-to-rest ruckig profile of one path parameter ``s`` (0 to 1) with
``q(s) = a + s (b - a)``: the joint limits become limits on ``s``'s velocity, acceleration and
jerk (the tightest joint for each), so every joint moves proportionally and the arm stays
exactly on the straight joint-space segment the planner checked (ruckig's own phase
synchronisation of 7 joints left the segment by up to 0.014 rad here, and a blended trajectory
would cut corners the checker never saw). Segment durations are whole multiples of
``period``, so every waypoint is a sample.

Why ruckig and not TOPP-RA: TOPP-RA bounds velocity and acceleration but not jerk (its
acceleration jumps at switching points), and libfranka refuses commands whose jerk exceeds the
Panda's limits; ruckig bounds all three.

:func:`check_trajectory` verifies every sample (limits, continuity between samples); the
drivers that talk to a real arm call it before anything is sent.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from tabletop.errors import ConfigError

__all__ = [
    "PANDA_LIMITS",
    "JointLimits",
    "JointTrajectory",
    "TrajectoryCheck",
    "TrajectoryConfig",
    "check_trajectory",
    "time_parametrize",
]


def _frozen7(v: object, name: str) -> np.ndarray:
    a = np.array(v, dtype=np.float64)
    if a.shape != (7,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"{name} must be a finite (7,) vector, got {np.asarray(v).tolist()}")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class JointLimits:
    """Per-joint limits of the arm, in joint order (panda_joint1..7)."""

    q_lower: np.ndarray  # (7,) [rad]
    q_upper: np.ndarray  # (7,) [rad]
    v_max: np.ndarray  # (7,) [rad/s]
    a_max: np.ndarray  # (7,) [rad/s^2]
    j_max: np.ndarray  # (7,) [rad/s^3]

    def __post_init__(self) -> None:
        for name in ("q_lower", "q_upper", "v_max", "a_max", "j_max"):
            object.__setattr__(self, name, _frozen7(getattr(self, name), f"JointLimits.{name}"))
        if not np.all(self.q_lower < self.q_upper):
            raise ConfigError("JointLimits.q_lower must be below q_upper for every joint")
        for name in ("v_max", "a_max", "j_max"):
            if not np.all(getattr(self, name) > 0):
                raise ConfigError(f"JointLimits.{name} must be positive for every joint")

    def scaled(self, velocity: float, acceleration: float, jerk: float) -> JointLimits:
        """These limits with velocity, acceleration and jerk scaled by factors in (0, 1]."""
        for name, f in (("velocity", velocity), ("acceleration", acceleration), ("jerk", jerk)):
            if not 0 < f <= 1:
                raise ConfigError(f"{name} scale must be in (0, 1], got {f}")
        return JointLimits(
            self.q_lower,
            self.q_upper,
            self.v_max * velocity,
            self.a_max * acceleration,
            self.j_max * jerk,
        )


#: The Panda's joint limits as published by Franka Emika in the Franka Control Interface
#: documentation ("Robot and interface specifications", limits for Panda). These are the
#: limits libfranka enforces; the position limits are tighter than the URDF's.
PANDA_LIMITS = JointLimits(
    q_lower=[-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973],
    q_upper=[2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973],
    v_max=[2.1750, 2.1750, 2.1750, 2.1750, 2.6100, 2.6100, 2.6100],
    a_max=[15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0],
    j_max=[7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0],
)


@dataclass(frozen=True)
class TrajectoryConfig:
    """Parameters of :func:`time_parametrize`."""

    period: float = 0.001
    """Sample period [s] (the Panda's 1 kHz control rate)."""
    velocity_scale: float = 0.3
    """Fraction of the velocity limits used, in (0, 1]."""
    acceleration_scale: float = 0.2
    """Fraction of the acceleration limits used, in (0, 1]."""
    jerk_scale: float = 0.05
    """Fraction of the jerk limits used, in (0, 1]."""

    def __post_init__(self) -> None:
        if not (np.isfinite(self.period) and 0 < self.period <= 0.1):
            raise ConfigError(f"TrajectoryConfig.period must be in (0, 0.1] s, got {self.period}")
        for name in ("velocity_scale", "acceleration_scale", "jerk_scale"):
            v = getattr(self, name)
            if not 0 < v <= 1:
                raise ConfigError(f"TrajectoryConfig.{name} must be in (0, 1], got {v}")


@dataclass(frozen=True, eq=False)
class JointTrajectory:
    """A joint trajectory sampled every ``period`` seconds from t = 0 (at rest at both ends).

    Sample ``k`` is at time ``k * period``; the last one is the final waypoint.
    """

    period: float  # [s]
    q: np.ndarray  # (N, 7) float64 [rad]
    dq: np.ndarray  # (N, 7) float64 [rad/s]
    ddq: np.ndarray  # (N, 7) float64 [rad/s^2]
    waypoints: np.ndarray  # (M, 7) float64 [rad], the path it follows (first and last = ends)

    def __post_init__(self) -> None:
        n = len(self.q)
        for name in ("q", "dq", "ddq"):
            a = np.array(getattr(self, name), dtype=np.float64)
            if a.ndim != 2 or a.shape != (n, 7) or n < 1:
                raise ConfigError(f"JointTrajectory.{name} must be (N, 7) with N >= 1")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        w = np.array(self.waypoints, dtype=np.float64)
        w.setflags(write=False)
        object.__setattr__(self, "waypoints", w)

    def __len__(self) -> int:
        return len(self.q)

    @property
    def times(self) -> np.ndarray:
        """(N,) sample times [s]."""
        return np.arange(len(self.q)) * self.period

    @property
    def duration(self) -> float:
        """[s] time of the last sample."""
        return (len(self.q) - 1) * self.period

    def jerk(self) -> np.ndarray:
        """(N - 1, 7) [rad/s^3] mean jerk between consecutive samples (finite difference)."""
        return np.diff(self.ddq, axis=0) / self.period


@dataclass(frozen=True)
class TrajectoryCheck:
    """Outcome of :func:`check_trajectory`: the worst use of each limit over every sample."""

    ok: bool
    violations: tuple[str, ...]  # one line per broken limit, naming the joint and sample
    position_margin: float  # [rad] smallest distance to a position limit (negative: outside)
    velocity_ratio: float  # max |dq| / v_max over samples and joints
    acceleration_ratio: float  # max |ddq| / a_max
    jerk_ratio: float  # max |d(ddq)/dt| / j_max between consecutive samples
    continuity_ratio: float  # max |dq_k+1 - dq_k| / (a_max period), |q step| / (v_max period)


def check_trajectory(
    traj: JointTrajectory, limits: JointLimits = PANDA_LIMITS, *, tol: float = 1e-6
) -> TrajectoryCheck:
    """Check every sample of ``traj`` against ``limits`` and between consecutive samples.

    On every sample: position inside the limits, |velocity| and |acceleration| within theirs.
    Between consecutive samples: the jerk (difference of accelerations over the period), and
    continuity (a position step no larger than ``v_max * period``, a velocity step no larger
    than ``a_max * period``). At both ends: velocity and acceleration zero. ``tol`` is the
    relative slack allowed on every ratio (rounding).
    """
    lim = limits
    q, dq, ddq, h = traj.q, traj.dq, traj.ddq, traj.period
    out: list[str] = []
    lo = q - lim.q_lower
    hi = lim.q_upper - q
    pos_margin = float(min(lo.min(), hi.min()))
    if pos_margin < -tol:
        k, j = np.unravel_index(np.argmin(np.minimum(lo, hi)), q.shape)
        out.append(f"position of joint {j + 1} at sample {k}: {q[k, j]:.5f} rad outside limits")

    def ratio(values: np.ndarray, limit: np.ndarray, what: str) -> float:
        if not len(values):
            return 0.0
        r = np.abs(values) / limit
        worst = float(r.max())
        if worst > 1 + tol:
            k, j = np.unravel_index(np.argmax(r), r.shape)
            out.append(f"{what} of joint {j + 1} at sample {k}: {worst:.3f} x its limit")
        return worst

    v_r = ratio(dq, lim.v_max, "velocity")
    a_r = ratio(ddq, lim.a_max, "acceleration")
    j_r = ratio(np.diff(ddq, axis=0) / h, lim.j_max, "jerk")
    c_q = ratio(np.diff(q, axis=0), lim.v_max * h, "position step")
    c_v = ratio(np.diff(dq, axis=0), lim.a_max * h, "velocity step")
    ends = np.abs(np.concatenate([dq[[0, -1]], ddq[[0, -1]]])).max()
    if ends > 1e-9:
        out.append(f"the trajectory does not start and end at rest (|dq|, |ddq| up to {ends:.2e})")
    return TrajectoryCheck(
        ok=not out,
        violations=tuple(out),
        position_margin=pos_margin,
        velocity_ratio=v_r,
        acceleration_ratio=a_r,
        jerk_ratio=j_r,
        continuity_ratio=max(c_q, c_v),
    )


def _as_waypoints(path: object) -> np.ndarray:
    w = np.array(path, dtype=np.float64)
    if w.ndim != 2 or w.shape[1] != 7 or len(w) < 1:
        raise ConfigError(
            f"path must be (M, 7) joint waypoints [rad] with M >= 1, got shape {w.shape}"
        )
    if not np.all(np.isfinite(w)):
        raise ConfigError("path contains non-finite joint values")
    return w


def time_parametrize(
    path: object,
    limits: JointLimits = PANDA_LIMITS,
    config: TrajectoryConfig | None = None,
) -> JointTrajectory:
    """Sample a rest-to-rest, jerk-limited trajectory through the (M, 7) waypoints ``path``.

    Straight joint-space segments between consecutive waypoints (one ruckig profile of the
    path parameter per segment, stopping at each waypoint), within ``limits`` scaled by
    ``config``. Raises :class:`ConfigError` for a waypoint outside the position limits
    (naming it and the joint).
    """
    from ruckig import DurationDiscretization, InputParameter, Result, Ruckig, Trajectory

    cfg = config or TrajectoryConfig()
    w = _as_waypoints(path)
    bad = (w < limits.q_lower) | (w > limits.q_upper)
    if bad.any():
        k, j = np.argwhere(bad)[0]
        raise ConfigError(
            f"waypoint {k}: joint {j + 1} = {w[k, j]:.4f} rad outside the position limits "
            f"[{limits.q_lower[j]:.4f}, {limits.q_upper[j]:.4f}]"
        )
    # Drop repeated waypoints (zero-length segments).
    keep = [0] + [i for i in range(1, len(w)) if np.abs(w[i] - w[i - 1]).max() > 1e-9]
    w = w[keep]
    use = limits.scaled(cfg.velocity_scale, cfg.acceleration_scale, cfg.jerk_scale)
    h = cfg.period
    otg = Ruckig(1, h)
    qs, dqs, ddqs = [w[:1]], [np.zeros((1, 7))], [np.zeros((1, 7))]
    for a, b in itertools.pairwise(w):
        # The segment as q(s) = a + s (b - a), s from 0 to 1: the joint limits become limits
        # on s's derivatives (the tightest joint for each), and one jerk-limited profile of s
        # keeps every joint on the straight segment.
        u = np.abs(b - a)
        moving = u > 0
        inp = InputParameter(1)
        inp.current_position = [0.0]
        inp.target_position = [1.0]
        inp.max_velocity = [float(np.min(use.v_max[moving] / u[moving]))]
        inp.max_acceleration = [float(np.min(use.a_max[moving] / u[moving]))]
        inp.max_jerk = [float(np.min(use.j_max[moving] / u[moving]))]
        inp.duration_discretization = DurationDiscretization.Discrete
        seg = Trajectory(1)
        res = otg.calculate(inp, seg)
        if res not in (Result.Working, Result.Finished):
            raise ConfigError(f"ruckig could not parametrise the segment {a} -> {b}: {res}")
        n = max(1, round(seg.duration / h))
        s_k = np.array([seg.at_time(k * h) for k in range(1, n)]).reshape(-1, 3)
        qs += [a + np.outer(s_k[:, 0], b - a), b[None]]
        dqs += [np.outer(s_k[:, 1], b - a), np.zeros((1, 7))]
        ddqs += [np.outer(s_k[:, 2], b - a), np.zeros((1, 7))]
    return JointTrajectory(
        period=h,
        q=np.concatenate(qs),
        dq=np.concatenate(dqs),
        ddq=np.concatenate(ddqs),
        waypoints=w,
    )
