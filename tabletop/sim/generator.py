"""Seeded random placement of objects on the table.

Draws kinds (with ``duplicates`` kinds appearing twice in different colours, so that a goal
like "the mug" is ambiguous without another cue), colours, positions and yaws, and places
them without overlap inside the arm's comfortable reach.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from tabletop.errors import SceneError
from tabletop.sim.catalog import OBJECT_KINDS, load_mesh_geometry, object_kind

__all__ = ["PLACEMENT_REGION", "DrawnObject", "footprint_radius", "generate_objects"]


class DrawnObject(NamedTuple):
    """One object the generator placed (the scene module turns it into an ``ObjectSpec``)."""

    name: str
    kind: str
    color: str
    position: tuple[float, float]  # (x, y) [m], world frame
    yaw_deg: float  # [deg] about +z


#: Where objects may stand [m]: x range, |y| bound, and min/max distance of the footprint's
#: corners from the robot base (the arm reaches everything inside).
PLACEMENT_REGION = {"x": (0.22, 0.78), "y_abs": 0.46, "r": (0.25, 0.78)}

_MARGIN = 0.02  # [m] free space kept between object footprints


def footprint_radius(kind: str) -> float:
    """Radius [m] of a circle holding the kind's footprint at any yaw."""
    size = load_mesh_geometry(kind).size
    return 0.5 * float(np.hypot(size[0], size[1]))


def _footprint(kind: str, x: float, y: float, yaw_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """World-frame (min, max) xy box of the kind's mesh at a pose."""
    a = np.deg2rad(yaw_deg)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    v = load_mesh_geometry(kind).vertices[:, :2] @ R.T + (x, y)
    return v.min(axis=0), v.max(axis=0)


def _placeable(lo: np.ndarray, hi: np.ndarray) -> bool:
    reg = PLACEMENT_REGION
    if lo[0] < reg["x"][0] or hi[0] > reg["x"][1] or max(-lo[1], hi[1]) > reg["y_abs"]:
        return False
    corners = np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], lo[1]], [hi[0], hi[1]]])
    r = np.hypot(corners[:, 0], corners[:, 1])
    return r.min() >= reg["r"][0] and r.max() <= reg["r"][1]


def _apart(box, others) -> bool:
    lo, hi = box
    return all(
        np.any(lo[:2] - _MARGIN >= ohi[:2]) or np.any(olo[:2] >= hi[:2] + _MARGIN)
        for olo, ohi in others
    )


def generate_objects(rnd, table, existing=()) -> tuple[DrawnObject, ...]:
    """Draw ``rnd.count`` objects (a :class:`~tabletop.sim.scene.RandomSpec`) on ``table``.

    ``existing`` objects keep their places; drawn ones avoid them. Deterministic in ``rnd.seed``.
    """
    rng = np.random.default_rng(rnd.seed)
    pool = list(rnd.kinds) if rnd.kinds else sorted(OBJECT_KINDS)
    # Duplicated kinds need two colours; trays are never duplicated (they define an area).
    dup_pool = [k for k in pool if len(object_kind(k).colors) >= 2 and k != "tray"]
    if rnd.duplicates > len(dup_pool):
        raise SceneError(
            f"random: {rnd.duplicates} duplicated kinds asked, only {len(dup_pool)} kinds "
            f"have two colours: {dup_pool}"
        )
    dups = list(rng.choice(dup_pool, size=rnd.duplicates, replace=False))
    singles_needed = rnd.count - 2 * rnd.duplicates
    rest = [k for k in pool if k not in dups]
    replace = singles_needed > len(rest)
    singles = list(rng.choice(rest, size=singles_needed, replace=replace)) if singles_needed else []

    picks: list[tuple[str, str]] = []
    for k in dups:
        c1, c2 = rng.choice(object_kind(k).colors, size=2, replace=False)
        picks += [(k, str(c1)), (k, str(c2))]
    for k in singles:
        picks.append((k, str(rng.choice(object_kind(k).colors))))
    # Place big objects first: they are the hardest to fit.
    picks.sort(key=lambda kc: -footprint_radius(kc[0]))

    placed = [_footprint(o.kind, *o.position, o.yaw_deg) for o in existing]
    taken = {o.name for o in existing}
    out = []
    for kind, color in picks:
        for _ in range(2000):
            x = round(float(rng.uniform(*PLACEMENT_REGION["x"])), 4)
            y = round(float(rng.uniform(-PLACEMENT_REGION["y_abs"], PLACEMENT_REGION["y_abs"])), 4)
            yaw = round(float(rng.uniform(-180, 180)), 2)
            box = _footprint(kind, x, y, yaw)
            if _placeable(*box) and _apart(box, placed):
                break
        else:
            raise SceneError(
                f"random (seed {rnd.seed}): no free place for a {kind} after 2000 tries; "
                f"ask for fewer objects (count={rnd.count})"
            )
        name = f"{color}_{kind}"
        i = 2
        while name in taken:
            name, i = f"{color}_{kind}_{i}", i + 1
        taken.add(name)
        placed.append(box)
        out.append(DrawnObject(name, kind, color, (x, y), yaw))
    return tuple(out)
