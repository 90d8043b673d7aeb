"""Teleop-style camera paths: smooth sweeps over the table, like a person with a VR controller.

A path is a list of keyframes — where the wrist camera is, which table point it looks at, and
its roll about the viewing ray — joined by a C1 Catmull-Rom spline in time, with a slow,
seeded hand tremor on top. :func:`sample_path` turns it into camera poses at the frame rate;
:mod:`tabletop.sim.scan` turns those into joint motions with IK.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tabletop.errors import ConfigError
from tabletop.transforms import make_transform

__all__ = [
    "Keyframe",
    "dwell_keyframes",
    "look_at",
    "mapping_keyframes",
    "sample_path",
    "transit_keyframes",
]


@dataclass(frozen=True)
class Keyframe:
    """Where the camera is [m], what it looks at [m] (world frame), and its roll [rad]."""

    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    roll: float = 0.0

    def as_array(self) -> np.ndarray:
        return np.array([*self.eye, *self.target, self.roll], dtype=np.float64)


def look_at(eye: np.ndarray, target: np.ndarray, roll: float = 0.0) -> np.ndarray:
    """(4, 4) OpenCV camera pose at ``eye`` whose optical axis points at ``target``.

    With roll 0 the image's "up" (-y) points away from the robot base (+x) as far as the
    viewing ray allows, so a top-down view shows the table the way the robot faces it.
    """
    eye = np.asarray(eye, dtype=np.float64)
    z = np.asarray(target, dtype=np.float64) - eye
    norm = np.linalg.norm(z)
    if norm < 1e-6:
        raise ConfigError("look_at: eye and target coincide")
    z /= norm
    up = np.array([1.0, 0.0, 0.0])
    if abs(z @ up) > 0.95:  # looking along x: use z up instead
        up = np.array([0.0, 0.0, 1.0])
    y = -(up - (up @ z) * z)
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    R = np.stack([x, y, z], axis=1)
    c, s = np.cos(roll), np.sin(roll)
    R = R @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return make_transform(R, eye)


def _durations(keys: np.ndarray, speed: float, min_time: float) -> np.ndarray:
    d_eye = np.linalg.norm(np.diff(keys[:, :3], axis=0), axis=1)
    d_tgt = np.linalg.norm(np.diff(keys[:, 3:6], axis=0), axis=1)
    d_roll = np.abs(np.diff(keys[:, 6])) * 0.15  # 1 rad of roll ~ 15 cm of motion
    return np.maximum(np.maximum(d_eye, 0.6 * d_tgt + d_roll) / speed, min_time)


def sample_path(
    keyframes: list[Keyframe],
    rate_hz: float,
    speed: float,
    rng: np.random.Generator | None = None,
    tremor_m: float = 0.004,
    min_segment_s: float = 0.6,
) -> np.ndarray:
    """Camera poses (N, 4, 4) along the keyframes at ``rate_hz``, ``speed`` [m/s] nominal.

    The path starts and ends at rest and passes through every keyframe. ``tremor_m`` is the
    amplitude [m] of a slow (0.3-1.2 Hz) seeded wobble of eye and target, as a human hand
    would add; 0 disables it.
    """
    if len(keyframes) < 2:
        raise ConfigError("a path needs at least two keyframes")
    if rate_hz <= 0 or speed <= 0:
        raise ConfigError(f"rate_hz and speed must be positive, got {rate_hz}, {speed}")
    keys = np.stack([k.as_array() for k in keyframes])
    dur = _durations(keys, speed, min_segment_s)
    knots = np.concatenate([[0.0], np.cumsum(dur)])
    total = knots[-1]
    t = np.arange(0.0, total + 1e-9, 1.0 / rate_hz)

    # Tangents (Catmull-Rom on non-uniform knots), zero at both ends: start and stop at rest.
    m = np.zeros_like(keys)
    for i in range(1, len(keys) - 1):
        m[i] = (keys[i + 1] - keys[i - 1]) / (knots[i + 1] - knots[i - 1])
    seg = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(keys) - 2)
    h = dur[seg]
    s = (t - knots[seg]) / h
    # Ease in and out within each segment's time: smooth but never stopping mid-path.
    h00 = 2 * s**3 - 3 * s**2 + 1
    h10 = s**3 - 2 * s**2 + s
    h01 = -2 * s**3 + 3 * s**2
    h11 = s**3 - s**2
    p = (
        h00[:, None] * keys[seg]
        + (h10 * h)[:, None] * m[seg]
        + h01[:, None] * keys[seg + 1]
        + (h11 * h)[:, None] * m[seg + 1]
    )
    if rng is not None and tremor_m > 0:
        freqs = rng.uniform(0.3, 1.2, size=(3, 6))
        phases = rng.uniform(0, 2 * np.pi, size=(3, 6))
        wobble = np.sin(2 * np.pi * freqs[None] * t[:, None, None] + phases[None]).sum(axis=1)
        p[:, :6] += tremor_m / np.sqrt(3) * wobble
    return np.stack([look_at(row[:3], row[3:6], row[6]) for row in p])


def mapping_keyframes(rng: np.random.Generator, table_x=(0.25, 0.78), table_y=(-0.48, 0.48)):
    """Keyframes of the mapping sweep: high and low passes over the whole table.

    Three lateral passes at different heights and tilts, then a look along each side, so every
    part of the table is seen from above and at an angle. Small seeded variations of heights
    and aim points make every scan a little different, as two teleoperated sweeps would be.
    """
    j = lambda a: rng.uniform(-a, a)  # noqa: E731 - a jitter of at most a
    x0, x1 = table_x
    y0, y1 = table_y
    xm = (x0 + x1) / 2
    k = [
        # high pass, looking forward and down, left to right
        Keyframe((0.22 + j(0.02), 0.30, 0.58 + j(0.03)), (xm + 0.05, 0.32, 0.0), j(0.2)),
        Keyframe((0.24 + j(0.02), 0.0, 0.60 + j(0.03)), (xm + 0.05, 0.0, 0.0), j(0.2)),
        Keyframe((0.22 + j(0.02), -0.30, 0.58 + j(0.03)), (xm + 0.05, -0.32, 0.0), j(0.2)),
        # lower pass over the near half, right to left, steeper view
        Keyframe((0.33, -0.30, 0.42 + j(0.03)), (0.36, y0 + 0.12, 0.0), 0.3 + j(0.2)),
        Keyframe((0.35, 0.0, 0.40 + j(0.03)), (0.40, 0.0, 0.0), j(0.2)),
        Keyframe((0.33, 0.30, 0.42 + j(0.03)), (0.36, y1 - 0.12, 0.0), -0.3 + j(0.2)),
        # far pass, reaching forward, left to right
        Keyframe((0.45, 0.26, 0.45 + j(0.03)), (x1 - 0.06, 0.30, 0.0), j(0.2)),
        Keyframe((0.48, 0.0, 0.44 + j(0.03)), (x1 - 0.04, 0.0, 0.0), j(0.2)),
        Keyframe((0.45, -0.26, 0.45 + j(0.03)), (x1 - 0.06, -0.30, 0.0), j(0.2)),
        # side looks: the right edge, then across to the left edge
        Keyframe((0.40, -0.12, 0.50 + j(0.03)), (xm, y0 + 0.04, 0.0), 0.5),
        Keyframe((0.40, 0.12, 0.50 + j(0.03)), (xm, y1 - 0.04, 0.0), -0.5),
        # back to an overview
        Keyframe((0.28, 0.0, 0.55), (xm, 0.0, 0.0), 0.0),
    ]
    return k


def dwell_keyframes(
    center_xy, rng: np.random.Generator, height: float = 0.42, radius: float = 0.03, n: int = 4
) -> list[Keyframe]:
    """A short hover above a table point, circling slowly while looking at it."""
    cx, cy = center_xy
    phase = rng.uniform(0, 2 * np.pi)
    keys = []
    for i in range(n):
        a = phase + 2 * np.pi * i / n
        keys.append(
            Keyframe(
                (cx - 0.08 + radius * np.cos(a), cy + radius * np.sin(a), height),
                (cx, cy, 0.0),
                0.0,
            )
        )
    return keys


def transit_keyframes(start: Keyframe, end: Keyframe, lift: float = 0.08) -> list[Keyframe]:
    """From one keyframe to another, lifting the camera on the way like an operator would."""
    mid_eye = (np.add(start.eye, end.eye) / 2 + [0, 0, lift]).tolist()
    mid_tgt = (np.add(start.target, end.target) / 2).tolist()
    return [start, Keyframe(tuple(mid_eye), tuple(mid_tgt), (start.roll + end.roll) / 2), end]
