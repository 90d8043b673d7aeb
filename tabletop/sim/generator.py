"""Seeded random placement of objects on the table.

Draws kinds (with ``duplicates`` kinds appearing twice in different colours, so that a goal
like "the mug" is ambiguous without another cue), colours, positions and yaws, and places
them without overlap inside the arm's comfortable reach.

A draw follows a placement profile (:data:`PROFILES`, ``RandomSpec.profile``):

- ``table`` (the default): objects anywhere in :data:`PLACEMENT_REGION`, 2 cm apart;
- ``clutter``: a dense table. Objects stand in a smaller region (:data:`CLUTTER_REGION`), 1 cm
  apart, each placed against one already on the table (a low object against a tall one when
  there is one); at least a quarter of them are tall kinds (:data:`TALL_KINDS`) and a quarter
  low ones (:data:`LOW_KINDS`); trays are left out unless ``kinds`` names them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from tabletop.errors import SceneError
from tabletop.sim.catalog import OBJECT_KINDS, load_mesh_geometry, object_kind

__all__ = [
    "CLUTTER_REGION",
    "LOW_KINDS",
    "PLACEMENT_REGION",
    "PROFILES",
    "TALL_KINDS",
    "DrawnObject",
    "PlacementProfile",
    "footprint_radius",
    "generate_objects",
]


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

#: The dense region of the ``clutter`` profile [m] (same keys), inside the part of the table
#: the scans cover and the arm reaches from above.
CLUTTER_REGION = {"x": (0.30, 0.68), "y_abs": 0.30, "r": (0.30, 0.74)}

#: Kinds at least 9 cm tall (mug 10 cm, teddy bear 12 cm, duck, soccer ball) and kinds at most
#: 5 cm tall (lego brick, jenga block, toy prism): a clutter draw has both.
TALL_KINDS = ("duck", "mug", "soccer_ball", "teddy_bear")
LOW_KINDS = ("jenga_block", "lego_brick", "toy_prism")


@dataclass(frozen=True)
class PlacementProfile:
    """How a draw places its objects (see the module docstring)."""

    name: str
    region: dict  # keys as PLACEMENT_REGION: x range, |y| bound, corner distance range [m]
    gap: float  # [m] free space kept between object footprints
    packed: bool  # each object against one already placed (else uniform in the region)
    tall_share: float  # at least this share of the objects are TALL_KINDS (and LOW_KINDS)
    exclude: tuple[str, ...]  # kinds left out when the draw names no kinds


#: The placement profiles, by ``RandomSpec.profile``.
PROFILES = {
    "table": PlacementProfile("table", PLACEMENT_REGION, 0.02, False, 0.0, ()),
    "clutter": PlacementProfile("clutter", CLUTTER_REGION, 0.01, True, 0.25, ("tray",)),
}


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


def _placeable(lo: np.ndarray, hi: np.ndarray, reg: dict = PLACEMENT_REGION) -> bool:
    if lo[0] < reg["x"][0] or hi[0] > reg["x"][1] or max(-lo[1], hi[1]) > reg["y_abs"]:
        return False
    corners = np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], lo[1]], [hi[0], hi[1]]])
    r = np.hypot(corners[:, 0], corners[:, 1])
    return r.min() >= reg["r"][0] and r.max() <= reg["r"][1]


def _apart(box, others, gap: float = 0.02) -> bool:
    lo, hi = box
    return all(
        np.any(lo[:2] - gap >= ohi[:2]) or np.any(olo[:2] >= hi[:2] + gap) for olo, ohi in others
    )


def _profile(name: str) -> PlacementProfile:
    try:
        return PROFILES[name]
    except KeyError:
        raise SceneError(
            f"random: unknown profile {name!r}; valid profiles: {sorted(PROFILES)}"
        ) from None


def _draw_singles(rng, rest: list[str], n: int, prof: PlacementProfile, dups: list[str]):
    """``n`` single kinds from ``rest``: the table profile draws them uniformly; a profile with
    a ``tall_share`` first tops up the tall and low kinds it needs (duplicates count twice)."""
    if not prof.tall_share:
        replace = n > len(rest)
        return list(rng.choice(rest, size=n, replace=replace)) if n else []
    total = n + 2 * len(dups)
    need = int(np.ceil(prof.tall_share * total))
    out: list[str] = []
    for group in (TALL_KINDS, LOW_KINDS):
        have = 2 * sum(k in group for k in dups)
        cand = [k for k in rest if k in group]
        k = min(max(need - have, 0), len(cand), n - len(out))
        if k:
            out += list(rng.choice(cand, size=k, replace=False))
    others = [k for k in rest if k not in out]
    m = n - len(out)
    if m:
        out += list(rng.choice(others, size=m, replace=m > len(others)))
    return out


def _place(rng, kind: str, placed: list, tall: list, prof: PlacementProfile):
    """(x, y, yaw, footprint) of a free place for ``kind``, or None after 2000 tries. A packed
    profile puts it against a placed object (a tall one for a low kind, when there is one), a
    gap to 4 cm beyond both footprints, and falls back to the whole region."""
    reg = prof.region
    r = footprint_radius(kind)
    anchors = placed
    if prof.packed and kind in LOW_KINDS and tall:
        anchors = tall
    for i in range(2000):
        if prof.packed and anchors and i < 1500:
            (ax, ay), ar = anchors[int(rng.integers(len(anchors)))][2:]
            a = rng.uniform(-np.pi, np.pi)
            d = ar + r + prof.gap + rng.uniform(0.0, 0.04)
            x, y = ax + d * np.cos(a), ay + d * np.sin(a)
        else:
            x = rng.uniform(*reg["x"])
            y = rng.uniform(-reg["y_abs"], reg["y_abs"])
        x, y = round(float(x), 4), round(float(y), 4)
        yaw = round(float(rng.uniform(-180, 180)), 2)
        box = _footprint(kind, x, y, yaw)
        if _placeable(*box, reg) and _apart(box, [p[:2] for p in placed], prof.gap):
            return x, y, yaw, box
    return None


def generate_objects(rnd, table, existing=()) -> tuple[DrawnObject, ...]:
    """Draw ``rnd.count`` objects (a :class:`~tabletop.sim.scene.RandomSpec`) on ``table``,
    placed by the profile ``rnd.profile`` (:data:`PROFILES`).

    ``existing`` objects keep their places; drawn ones avoid them. Deterministic in ``rnd.seed``.
    """
    prof = _profile(getattr(rnd, "profile", "table"))
    rng = np.random.default_rng(rnd.seed)
    pool = (
        list(rnd.kinds) if rnd.kinds else [k for k in sorted(OBJECT_KINDS) if k not in prof.exclude]
    )
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
    singles = _draw_singles(rng, rest, singles_needed, prof, dups)

    picks: list[tuple[str, str]] = []
    for k in dups:
        c1, c2 = rng.choice(object_kind(k).colors, size=2, replace=False)
        picks += [(k, str(c1)), (k, str(c2))]
    for k in singles:
        picks.append((k, str(rng.choice(object_kind(k).colors))))
    # Place big objects first: they are the hardest to fit.
    picks.sort(key=lambda kc: -footprint_radius(kc[0]))

    # (footprint lo, hi, centre xy, footprint radius) of every object on the table
    placed = [
        (*_footprint(o.kind, *o.position, o.yaw_deg), o.position, footprint_radius(o.kind))
        for o in existing
    ]
    tall = [p for p, o in zip(placed, existing, strict=True) if o.kind in TALL_KINDS]
    taken = {o.name for o in existing}
    out = []
    for kind, color in picks:
        spot = _place(rng, kind, placed, tall, prof)
        if spot is None:
            raise SceneError(
                f"random (seed {rnd.seed}): no free place for a {kind} after 2000 tries; "
                f"ask for fewer objects (count={rnd.count})"
            )
        x, y, yaw, box = spot
        name = f"{color}_{kind}"
        i = 2
        while name in taken:
            name, i = f"{color}_{kind}_{i}", i + 1
        taken.add(name)
        placed.append((*box, (x, y), footprint_radius(kind)))
        if kind in TALL_KINDS:
            tall.append(placed[-1])
        out.append(DrawnObject(name, kind, color, (x, y), yaw))
    return tuple(out)
