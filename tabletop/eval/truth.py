"""Ground truth of goals, resolved against a recording's ground truth.

A :class:`Region` is a union of axis-aligned boxes (a point is a box of zero size, the column
beneath a microphone a box of zero width); the distance of a point to it is the distance to the
nearest box (0 inside); an ``absent`` goal's region has no box (every point is infinitely far).
Every reference (object name, sound category, area name) is checked against the recording and a
wrong one is named together with the valid ones; an absent goal's query is checked not to name,
word for word, something the recording has (:func:`check_absent`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from tabletop.eval.calibration import AREA_HEIGHT_M
from tabletop.eval.map_goals import heard_column
from tabletop.eval.tasks import Landmark, TaskFileError, Truth
from tabletop.relations import relation as _relation
from tabletop.relations import side_point
from tabletop.robot.api import SpatialConfig
from tabletop.sim.ground_truth import (
    AreaTruth,
    GroundTruth,
    NotInGroundTruth,
    ObjectTruth,
    SoundEventTruth,
)

__all__ = ["AREA_HEIGHT_M", "Region", "check_absent", "resolve_truth", "sound_occurrences"]


@dataclass(frozen=True)
class Region:
    """Acceptable places of a goal: boxes (K, 2, 3) [m] world frame (lower, upper corners);
    K = 0 for an absent goal (no place is right)."""

    boxes: np.ndarray  # (K, 2, 3) float64 [m]
    description: str

    def distance(self, p) -> float:
        """Distance [m] from a point (3,) to the nearest box (0 inside; inf without boxes)."""
        if not len(self.boxes):
            return math.inf
        p = np.asarray(p, np.float64)
        lo, hi = self.boxes[:, 0], self.boxes[:, 1]
        d = np.maximum(lo - p, 0) + np.maximum(p - hi, 0)
        return float(np.linalg.norm(d, axis=1).min())

    def distance_xy(self, p) -> float:
        """Distance [m] in x and y only from a point (2,) or (3,) to the nearest box's
        footprint (a mobile base is on the floor; inf without boxes)."""
        if not len(self.boxes):
            return math.inf
        p = np.asarray(p, np.float64)[:2]
        lo, hi = self.boxes[:, 0, :2], self.boxes[:, 1, :2]
        d = np.maximum(lo - p, 0) + np.maximum(p - hi, 0)
        return float(np.linalg.norm(d, axis=1).min())

    @property
    def center(self) -> np.ndarray:
        """(3,) centre of the first box [m]."""
        return self.boxes[0].mean(axis=0)

    def to_json(self) -> list:
        return np.round(self.boxes, 4).tolist()


def _region(boxes, description: str) -> Region:
    b = np.asarray(boxes, np.float64).reshape(-1, 2, 3)
    b.setflags(write=False)
    return Region(b, description)


def sound_occurrences(ground_truth: GroundTruth, category: str) -> list[SoundEventTruth]:
    """The sound events of ``category``, in time order (empty when it was not inserted)."""
    return [e for e in ground_truth.sound_events_by_onset if e.category == category]


def _object(gt: GroundTruth, name: str, where: str) -> ObjectTruth:
    try:
        return gt.object(name)
    except NotInGroundTruth as e:
        raise TaskFileError(f"{where}: {e}") from None


def _sound_events(gt: GroundTruth, t: Truth, where: str) -> list[SoundEventTruth]:
    try:
        occ = list(gt.sound_events_of(t.sound))
    except NotInGroundTruth as e:
        raise TaskFileError(f"{where}: {e}") from None
    if t.occurrence is not None:
        if t.occurrence >= len(occ):
            raise TaskFileError(
                f"{where}: sound {t.sound!r} occurrence {t.occurrence} does not exist; it was "
                f"inserted {len(occ)} time(s) (occurrences 0..{len(occ) - 1})"
            )
        occ = [occ[t.occurrence]]
    return occ


def _area(gt: GroundTruth, name: str, where: str) -> AreaTruth:
    try:
        return gt.area(name)
    except NotInGroundTruth as e:
        raise TaskFileError(f"{where}: {e}") from None


def _anchor(gt: GroundTruth, t: Truth, where: str) -> tuple[np.ndarray, np.ndarray]:
    """(centre (3,), half extents (3,)) [m] of a truth used as a relation's landmark."""
    if t.kind == "object":
        o = _object(gt, t.object, where)
        lo, hi = np.array(o.aabb_min), np.array(o.aabb_max)
        return (lo + hi) / 2, (hi - lo) / 2
    if t.kind == "sound":
        occ = _sound_events(gt, t, where)
        if len(occ) > 1:
            raise TaskFileError(
                f"{where}: sound {t.sound!r} was heard in {len(occ)} places; a relation needs "
                f"one: give occurrence = 0..{len(occ) - 1}"
            )
        return np.array(occ[0].table_point, np.float64), np.zeros(3)
    if t.kind == "area":
        a = _area(gt, t.area, where)
        c = np.array([np.mean(a.x), np.mean(a.y), 0.0])
        return c, np.array([np.ptp(a.x) / 2, np.ptp(a.y) / 2, 0.0])
    if t.kind in ("point", "camera"):
        p = np.array(t.point, np.float64)
        if t.kind == "camera":
            p[2] = 0.0
        return p, np.zeros(3)
    if t.kind == "box":
        lo, hi = np.array(t.box[0]), np.array(t.box[1])
        return (lo + hi) / 2, (hi - lo) / 2
    r = resolve_truth(t, gt, where)
    if len(r.boxes) != 1:
        raise TaskFileError(f"{where}: a nested relation must resolve to one place")
    lo, hi = r.boxes[0]
    return (lo + hi) / 2, (hi - lo) / 2


def relation_point(
    relation: str,
    anchors: list[tuple[np.ndarray, np.ndarray]],
    spatial: SpatialConfig | None = None,
) -> np.ndarray:
    """(3,) [m] the point a relation names, from its landmarks' (centre, half extents), with the
    robot API's offsets (:class:`tabletop.robot.SpatialConfig`)."""
    s = spatial or SpatialConfig()
    if relation == "between":
        return (anchors[0][0] + anchors[1][0]) / 2
    c, half = anchors[0]
    top = c[2] + half[2]
    if relation == "above":
        return np.array([c[0], c[1], top + s.above_gap])
    return side_point(_relation(relation).axis, c, half, top, s.side_offset, s.side_gap)


def resolve_truth(t: Truth, ground_truth: GroundTruth, where: str = "truth") -> Region:
    """The :class:`Region` a :class:`~tabletop.eval.tasks.Truth` names in a recording's ground
    truth (:meth:`GroundTruth.of(recording) <tabletop.sim.GroundTruth.of>`).

    Raises:
        TaskFileError: a reference the recording does not have (naming the valid ones).
    """
    gt = ground_truth
    if t.kind == "object":
        o = _object(gt, t.object, where)
        return _region([[o.aabb_min, o.aabb_max]], f"box of {t.object}")
    if t.kind == "sound":
        boxes = [heard_column(e) for e in _sound_events(gt, t, where)]
        return _region(boxes, f"where {t.sound!r} was heard ({len(boxes)} place(s))")
    if t.kind == "area":
        a = _area(gt, t.area, where)
        lo = [a.x[0], a.y[0], 0.0]
        hi = [a.x[1], a.y[1], AREA_HEIGHT_M]
        return _region([[lo, hi]], f"area {a.name!r}")
    if t.kind == "point":
        return _region([[t.point, t.point]], f"point {list(t.point)}")
    if t.kind == "camera":
        p = np.array(t.point)
        return _region([[[p[0], p[1], 0.0], p]], "beneath the camera that took the image")
    if t.kind == "box":
        return _region([t.box], "box")
    if t.kind == "absent":
        return _region(np.zeros((0, 2, 3)), "nowhere: absent from the scene")
    anchors = [_anchor(gt, x, f"{where}.of[{i}]") for i, x in enumerate(t.of)]
    p = relation_point(t.relation, anchors)
    return _region([[p, p]], t.describe())


def _words(text: str) -> str:
    """Lower case, no leading articles, single spaces: how two names are compared."""
    text = re.sub(r"\s+", " ", text.lower()).strip()
    return re.sub(r"^(?:(?:the|a|an)\s+)+", "", text)


def check_absent(query: Landmark, ground_truth: GroundTruth, where: str = "goal") -> None:
    """An ``absent`` goal's query must not be, word for word (case and leading articles aside),
    what the recording calls something it has: an object's label, name or kind, an inserted
    sound's caption or category, a named table area. (Synonyms are the suite writer's
    responsibility.)

    Raises:
        TaskFileError: naming the query and what the scene has under that name.
    """
    gt = ground_truth
    for kind, text in query.parts:
        if kind == "obj":
            names = {
                n: f"object {o.name}"
                for o in gt.objects
                for n in (o.label, o.name.replace("_", " "), o.category)
            }
        elif kind == "sound":
            names = {
                n: f"sound {e.category}"
                for e in gt.sound_events
                for n in (e.caption, e.category.replace("_", " "))
            }
        elif kind == "area":
            names = {a.name: f"area {a.name}" for a in gt.areas}
        else:
            continue
        hit = {_words(n): what for n, what in names.items()}.get(_words(str(text)))
        if hit is not None:
            raise TaskFileError(
                f"{where}: an 'absent' goal asks {kind}={text!r}, which this recording has "
                f"({hit}); an absent goal names something the scene does not have"
            )
