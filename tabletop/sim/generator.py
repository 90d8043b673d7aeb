"""Seeded random placement of objects on the table.

Draws kinds (with ``duplicates`` kinds appearing twice in different colours, so that a goal
like "the mug" is ambiguous without another cue), colours, positions and yaws, and places
them without overlap inside the arm's comfortable reach.
"""

from __future__ import annotations

import numpy as np

from tabletop.errors import SceneError
from tabletop.sim.catalog import OBJECT_KINDS, load_mesh_geometry, object_kind

__all__ = ["PLACEMENT_REGION", "footprint_radius", "generate_objects"]

#: Where objects may stand [m]: x range, |y| bound, and the min/max distance from the base.
PLACEMENT_REGION = {"x": (0.28, 0.74), "y_abs": 0.42, "r": (0.30, 0.76)}

_MARGIN = 0.02  # [m] free space kept between object footprints


def footprint_radius(kind: str) -> float:
    """Radius [m] of a circle holding the kind's footprint at any yaw."""
    size = load_mesh_geometry(kind).size
    return 0.5 * float(np.hypot(size[0], size[1]))


def _placeable(x: float, y: float, radius: float) -> bool:
    reg = PLACEMENT_REGION
    r = np.hypot(x, y)
    return (
        reg["x"][0] + radius <= x <= reg["x"][1] - radius
        and abs(y) <= reg["y_abs"] - radius
        and reg["r"][0] <= r - radius
        and r + radius <= reg["r"][1]
    )


def generate_objects(rnd, table, existing=()) -> tuple:
    """Draw ``rnd.count`` objects (a :class:`~tabletop.sim.scene.RandomSpec`) on ``table``.

    ``existing`` objects keep their places; drawn ones avoid them. Deterministic in ``rnd.seed``.
    """
    from tabletop.sim.scene import ObjectSpec

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

    placed = [(np.array(o.position), footprint_radius(o.kind)) for o in existing]
    taken = {o.name for o in existing}
    out = []
    for kind, color in picks:
        radius = footprint_radius(kind)
        for _ in range(2000):
            x = rng.uniform(*PLACEMENT_REGION["x"])
            y = rng.uniform(-PLACEMENT_REGION["y_abs"], PLACEMENT_REGION["y_abs"])
            if not _placeable(x, y, radius):
                continue
            if all(np.hypot(*(p - (x, y))) >= r + radius + _MARGIN for p, r in placed):
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
        placed.append((np.array([x, y]), radius))
        out.append(
            ObjectSpec(
                name=name,
                kind=kind,
                color=color,
                position=(round(x, 4), round(y, 4)),
                yaw_deg=round(float(rng.uniform(-180, 180)), 2),
            )
        )
    return tuple(out)
