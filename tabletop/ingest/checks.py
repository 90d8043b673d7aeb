"""Frame checks on an imported recording, judged from what the data itself says.

The classic mistakes in a user's own recordings (an inverted pose, a camera body frame for the
optical frame, depth in the wrong unit, timestamps out of order or on another clock, an
extrinsic that puts the camera inside the arm) each leave a trace in the data:

- **views agree**: a point seen in one frame, carried through both frames' poses into a
  neighbouring frame, must land where that frame measured a surface at the same depth;
- **the table is level**: the largest horizontal surface in the world frame is a thin slab;
- **depth is plausible**: a wrist camera sees surfaces tens of centimetres away, not hundreds
  of metres or a few millimetres;
- **the camera is outside the arm**: the extrinsic puts the camera origin outside every link.

When the views disagree, each known mistake is undone in turn; the one that makes them agree
is named (a typed error from :mod:`tabletop.ingest.errors`) with the numbers and the fix.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from tabletop.ingest.errors import (
    CameraFrameError,
    CameraInsideArmError,
    DepthScaleError,
    FrameCheckError,
    InvertedPoseError,
    TimestampError,
)

__all__ = [
    "MIN_AGREEMENT",
    "MIN_LEVEL",
    "R_BODY_OPTICAL",
    "ArmGeometry",
    "CheckReport",
    "check_clock",
    "check_order",
    "check_recording",
    "level_fraction",
    "view_agreement",
]

#: The optical frame (z forward, x right, y down) in a camera body frame (x forward, y left,
#: z up): ``T_world_optical = T_world_body @ R_BODY_OPTICAL``.
R_BODY_OPTICAL = np.array(
    [[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)
#: The views pass when at least this fraction of a frame's sampled points agree with a
#: neighbouring view (median over the pairs). The test scans agree at 0.81 to 0.86, their
#: injected mistakes at 0.2 to 0.46, and their corrections at 0.81 to 0.86
#: (tests/test_import.py). A mistake is named when undoing it passes both checks.
MIN_AGREEMENT = 0.6
#: ... and at least this fraction of the world points lie in the 3 cm slab of the dominant
#: horizontal surface.
MIN_LEVEL = 0.3
#: Plausible median depth of a wrist camera [m].
DEPTH_RANGE_M = (0.05, 5.0)
#: Depth factors tried when the views disagree (those that keep the median depth plausible):
#: millimetres read as metres (1e-3) and back, TUM's 5000 units per metre read as 1000 and
#: back, a factor of ten.
DEPTH_FACTORS = (1e-3, 1e3, 0.2, 5.0, 0.1, 10.0)


class ArmGeometry(Protocol):
    """What the checks need to know of the arm (``tabletop.arm.recording_kinematics`` has the
    Panda's): which link, if any, contains a point at given joints."""

    def link_containing(
        self, point_world: np.ndarray, q: np.ndarray, T_world_hand: np.ndarray
    ) -> str | None: ...


@dataclass(frozen=True)
class CheckReport:
    """What the checks measured on a recording that passed them."""

    agreement: float
    """Median over neighbouring frame pairs of the fraction of points that agree [0, 1]."""
    level: float
    """Fraction of world points in the dominant horizontal slab [0, 1]."""
    table_z: float
    """Height of that slab in the world frame [m]."""
    median_depth: float
    pairs: int

    def to_dict(self) -> dict:
        return {
            "agreement": round(self.agreement, 4),
            "level": round(self.level, 4),
            "table_z": round(self.table_z, 4),
            "median_depth_m": round(self.median_depth, 4),
            "pairs": self.pairs,
        }


# ---------------------------------------------------------------------- timestamps
def check_order(name: str, stamps: np.ndarray) -> None:
    """Stamps of one stream, in the order they were recorded, must increase."""
    stamps = np.asarray(stamps, np.float64)
    back = np.flatnonzero(np.diff(stamps) <= 0)
    if len(back):
        i = int(back[0])
        raise TimestampError(
            f"timestamps out of order: {name} message {i + 1} is stamped {stamps[i + 1]:.6f} s, "
            f"not after message {i} ({stamps[i]:.6f} s); {len(back)} step(s) go backwards. "
            "Likely fix: stamp every message from one monotonic clock at capture (the driver's "
            "header stamp, not a re-stamp on arrival), or re-record"
        )


def check_clock(
    name: str, stamps: np.ndarray, pose_name: str, pose_stamps: np.ndarray, slack_s: float = 0.1
) -> None:
    """Every frame stamp must fall within the pose stream's span (``slack_s`` either side):
    frames outside it are either on another clock or recorded before or after the poses."""
    stamps = np.asarray(stamps, np.float64)
    pose_stamps = np.asarray(pose_stamps, np.float64)
    lo, hi = pose_stamps.min() - slack_s, pose_stamps.max() + slack_s
    out = (stamps < lo) | (stamps > hi)
    if not out.any():
        return
    offset = float(np.median(stamps) - np.median(pose_stamps))
    if stamps.max() < lo or stamps.min() > hi:
        raise TimestampError(
            f"timestamps on another clock: {name} spans {stamps.min():.3f}..{stamps.max():.3f} s, "
            f"{pose_name} {pose_stamps.min():.3f}..{pose_stamps.max():.3f} s: no overlap, an "
            f"offset of {offset:+.3f} s. Likely fix: stamp both from the same clock (ROS time "
            f"for both, or the sensor's clock for both), or pass --pose-time-offset {offset:.3f} "
            "if the offset is constant"
        )
    raise TimestampError(
        f"{int(out.sum())} of {len(stamps)} {name} frames fall outside the {pose_name} span "
        f"{pose_stamps.min():.3f}..{pose_stamps.max():.3f} s (first at {stamps[out][0]:.3f} s): "
        "frames recorded without poses, or the streams are on different clocks. Likely fix: "
        "record the poses for the whole scan, or trim the frames with --start/--stop"
    )


# ---------------------------------------------------------------------- geometry
def _rays(K: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    pix = np.stack([u + 0.0, v + 0.0, np.ones_like(u, dtype=np.float64)], axis=1)
    return pix @ np.linalg.inv(K).T  # (P, 3) with z = 1


def _sample(depth: np.ndarray, rng: np.random.Generator, n: int):
    v, u = np.nonzero(depth > 0)
    if len(u) > n:
        k = rng.choice(len(u), n, replace=False)
        u, v = u[k], v[k]
    return u, v, depth[v, u].astype(np.float64)


def _pairs(
    T_world_cam: np.ndarray, n_pairs: int, min_move_m: float = 0.02
) -> list[tuple[int, int]]:
    """Up to ``n_pairs`` (i, j): i evenly spread, j the first later frame whose camera moved
    at least ``min_move_m`` or turned 3 degrees (and at most 10 frames on)."""
    n = len(T_world_cam)
    out = []
    for i in np.unique(np.linspace(0, n - 2, min(n_pairs, max(n - 1, 0))).astype(int)):
        for j in range(i + 1, min(n, i + 11)):
            dt = np.linalg.norm(T_world_cam[j, :3, 3] - T_world_cam[i, :3, 3])
            R = T_world_cam[i, :3, :3].T @ T_world_cam[j, :3, :3]
            ang = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
            if dt >= min_move_m or ang >= np.radians(3):
                out.append((int(i), j))
                break
    return out


def view_agreement(
    depth: np.ndarray,
    K: np.ndarray,
    T_world_cam: np.ndarray,
    pairs: list[tuple[int, int]],
    *,
    samples: int = 800,
    seed: int = 0,
) -> float:
    """Median over ``pairs`` of the fraction of frame i's sampled points that, carried into
    frame j, land on a measured surface within 1 cm + 2 % of its depth."""
    rng = np.random.default_rng(seed)
    h, w = depth.shape[1:]
    fracs = []
    for i, j in pairs:
        u, v, d = _sample(depth[i], rng, samples)
        if not len(d):
            continue
        p = _rays(K, u, v) * d[:, None]
        T = np.linalg.inv(T_world_cam[j]) @ T_world_cam[i]
        q = p @ T[:3, :3].T + T[:3, 3]
        z = q[:, 2]
        front = z > 1e-3
        pix = q[front] @ K.T
        uj = np.round(pix[:, 0] / pix[:, 2]).astype(np.int64)
        vj = np.round(pix[:, 1] / pix[:, 2]).astype(np.int64)
        inside = (uj >= 0) & (uj < w) & (vj >= 0) & (vj < h)
        dj = depth[j][vj[inside], uj[inside]].astype(np.float64)
        zj = z[front][inside]
        ok = (dj > 0) & (np.abs(zj - dj) <= 0.01 + 0.02 * dj)
        fracs.append(ok.sum() / len(d))
    return float(np.median(fracs)) if fracs else 0.0


def level_fraction(
    depth: np.ndarray, K: np.ndarray, T_world_cam: np.ndarray, *, frames: int = 20, seed: int = 0
) -> tuple[float, float]:
    """(fraction, z): the share of world points within the densest 3 cm horizontal slab, and
    the slab's height [m]. A level table seen from above fills most of the views."""
    rng = np.random.default_rng(seed)
    zs = []
    for i in np.unique(np.linspace(0, len(depth) - 1, min(frames, len(depth))).astype(int)):
        u, v, d = _sample(depth[i], rng, 1500)
        p = _rays(K, u, v) * d[:, None]
        zs.append(p @ T_world_cam[i, 2, :3] + T_world_cam[i, 2, 3])
    z = np.concatenate(zs) if zs else np.zeros(0)
    z = z[np.isfinite(z)]
    if not len(z):
        return 0.0, float("nan")
    z = np.sort(z)
    # densest window of 3 cm: for each point, how many lie within [z, z + 0.03]
    hi = np.searchsorted(z, z + 0.03, side="right")
    k = int(np.argmax(hi - np.arange(len(z))))
    slab = z[k : hi[k]]
    return float(len(slab) / len(z)), float(np.median(slab))


# ---------------------------------------------------------------------- the checks
def _fmt(T: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:+.3f}" for x in T[:3, 3]) + ") m"


def check_recording(
    rec,
    *,
    pose_of: str = "hand",
    arm: ArmGeometry | None = None,
    min_agreement: float = MIN_AGREEMENT,
    min_level: float = MIN_LEVEL,
    n_pairs: int = 24,
) -> CheckReport:
    """Run the frame checks on a :class:`tabletop.recording.Recording`; return what they
    measured, or raise the typed error of the mistake they found.

    ``pose_of``: where the poses came from: ``"hand"`` (a hand pose stream such as TF),
    ``"camera"`` (camera poses such as TUM's groundtruth) or ``"joints"`` (forward kinematics
    of joint states: they cannot be inverted, so that mistake is not tried). ``arm``: the arm's
    geometry for the camera-inside-the-arm check (skipped when None).
    """
    if pose_of not in ("hand", "camera", "joints"):
        raise ValueError(f"pose_of must be 'hand', 'camera' or 'joints', got {pose_of!r}")
    if len(rec) < 2:
        raise FrameCheckError(
            f"the recording has {len(rec)} frame(s): the checks (and a map) need at least 2 views"
        )
    depth, K = rec.depth, rec.K
    valid = depth[depth > 0]
    if not len(valid):
        raise DepthScaleError(
            "every depth pixel is 0 (invalid): is the depth topic or folder right?"
        )
    med = float(np.median(valid))
    lo, hi = DEPTH_RANGE_M
    if not lo <= med <= hi:
        factor = 1e-3 if med > hi else 1e3
        guess = (
            "depth in millimetres read as metres"
            if med > hi
            else "depth in metres read as millimetres"
        )
        raise DepthScaleError(
            f"median depth is {med:.4g} m, outside the {lo}..{hi} m a wrist camera sees: {guess} "
            f"(or a wrong depth scale). Likely fix: scale depth by {factor:g} (for 16-bit depth "
            "pass the units per metre, e.g. --depth-scale 1000 for millimetres, 5000 for TUM)"
        )

    T_hand = rec.T_world_hand
    T_cam = rec.T_world_cam
    if arm is not None:
        for i in np.unique(np.linspace(0, len(rec) - 1, min(8, len(rec))).astype(int)):
            link = arm.link_containing(T_cam[i, :3, 3], rec.joint_positions[i], T_hand[i])
            if link is None:
                continue
            inv = np.linalg.inv(rec.T_hand_cam)
            fix = ""
            if (
                arm.link_containing((T_hand[i] @ inv)[:3, 3], rec.joint_positions[i], T_hand[i])
                is None
            ):
                fix = (
                    f"; its inverse puts the camera at {_fmt(inv)} in the hand frame, outside "
                    "the arm: T_cam_hand was probably given for T_hand_cam, pass the inverse"
                )
            raise CameraInsideArmError(
                f"the extrinsic T_hand_cam puts the camera at {_fmt(rec.T_hand_cam)} in the "
                f"{rec.ee_frame} frame, inside the arm's link {link} (frame {i})"
                + (
                    fix
                    or ". Likely fix: check the hand-eye calibration's direction and units (metres)"
                )
            )

    pairs = _pairs(T_cam, n_pairs)
    if not pairs:
        raise FrameCheckError(
            "the camera never moves 2 cm or turns 3 degrees between frames 10 apart: the views "
            "cannot be checked against one another (a still camera, or every pose the same?)"
        )
    agreement = view_agreement(depth, K, T_cam, pairs)
    level, table_z = level_fraction(depth, K, T_cam)
    if agreement >= min_agreement and level >= min_level:
        cam_z = float(np.median(T_cam[:, 2, 3]))
        if cam_z < table_z + 0.05:
            raise FrameCheckError(
                f"the views agree ({agreement:.0%}) and the largest level surface lies at "
                f"z = {table_z:+.3f} m, but the camera is at z = {cam_z:+.3f} m, not above it: "
                "the world frame is not the robot base with z up (the first camera frame taken "
                "as the world, as a SLAM trajectory starts?). Likely fix: express the poses in "
                "the robot base frame (panda_link0)"
            )
        return CheckReport(agreement, level, table_z, med, len(pairs))
    # the views disagree: undo each known mistake in turn
    hyps: dict[str, tuple[Callable[[], tuple[np.ndarray, np.ndarray]], type, str, str]] = {}
    if pose_of == "hand":
        hyps["inverted"] = (
            lambda: (depth, np.linalg.inv(T_hand) @ rec.T_hand_cam),
            InvertedPoseError,
            "the hand poses inverted",
            "inverted hand poses: T_hand_world was given for T_world_hand (a TF with parent and "
            "child swapped, or a pose inverted once too often). Likely fix: invert the poses, or "
            "swap the TF's parent and child frames",
        )
    elif pose_of == "camera":
        hyps["inverted"] = (
            lambda: (depth, np.linalg.inv(T_cam)),
            InvertedPoseError,
            "the camera poses inverted",
            "inverted camera poses: T_cam_world was given for T_world_cam (TUM's groundtruth is "
            "the camera's pose in the world). Likely fix: invert each pose before writing it",
        )
    hyps["camera_frame"] = (
        lambda: (depth, T_cam @ R_BODY_OPTICAL),
        CameraFrameError,
        "the camera frame turned from body to optical axes",
        "a camera body frame (x forward, z up) was given where the optical frame (z forward, "
        "x right, y down) is meant. Likely fix: use the optical frame (in ROS the "
        "*_optical_frame child, e.g. camera_color_optical_frame), or right-multiply the pose "
        "by the body-to-optical rotation [[0,0,1],[-1,0,0],[0,-1,0]]",
    )
    for f in DEPTH_FACTORS:
        if not lo <= med * f <= hi:
            continue
        hyps[f"depth x{f:g}"] = (
            lambda f=f: (depth * np.float32(f), T_cam),
            DepthScaleError,
            f"depth scaled by {f:g}",
            f"depth must be multiplied by {f:g} to agree (millimetres read as metres: by "
            "0.001; TUM's 5000 units per metre read as 1000: by 0.2; 1000 read as 5000: by 5). "
            f"Likely fix: the right depth scale (for 16-bit depth --depth-scale, the units per "
            f"metre, divided by {f:g})",
        )
    tried = {}
    for name, (make, *_) in hyps.items():
        d, T = make()
        lv, z = level_fraction(d, K, T)
        above = float(np.median(T[:, 2, 3])) >= z + 0.05
        tried[name] = (view_agreement(d, K, T, pairs), lv if above else 0.0)
    # a correction fixes the data when the views then agree, the table is level and the
    # cameras are above it
    fixes = {n: a for n, (a, lv) in tried.items() if a >= min_agreement and lv >= min_level}
    measured = (
        f"{agreement:.0%} of the points of one view agree with a neighbouring view (need "
        f"{min_agreement:.0%}), {level:.0%} of the points lie on one level surface (need "
        f"{min_level:.0%})"
    )
    if fixes:
        best = max(fixes, key=fixes.get)
        _, cls, short, what = hyps[best]
        raise cls(
            f"{measured}; with {short}, {tried[best][0]:.0%} agree and {tried[best][1]:.0%} "
            f"lie on the level table: {what}"
        )
    if agreement >= min_agreement:
        raise FrameCheckError(
            f"the views agree ({agreement:.0%}) but only {level:.0%} of the points lie on one "
            f"level surface (need {min_level:.0%}): the world frame's z axis is not up (the "
            "first camera frame taken as the world, as a SLAM trajectory starts?). Likely fix: "
            "express the poses in the robot base frame (panda_link0), z up"
        )
    shown = ", ".join(f"{k} {a:.0%}" for k, (a, _) in tried.items())
    raise FrameCheckError(
        f"{measured}, and none of the known mistakes explains it (agreement with each undone: "
        f"{shown}). Check the poses' frames, the extrinsic, the intrinsics K and the depth "
        "alignment to the colour image"
    )
