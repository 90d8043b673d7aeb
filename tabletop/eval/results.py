"""Results of an evaluation: per goal, per task file, per encoder set, and their summaries.

Metrics per goal type (the paper's tabletop criterion and its cross-modal indexing tables):

- ``success_rate``: the TCP ends within 10 cm of the goal's ground truth;
- ``recall_at``: recall@1 of the predicted target (the point the robot was sent to, before the
  controller's standoff) within 2, 5 and 10 cm of the ground truth;
- ``mean_error_m`` (final TCP to truth) and ``mean_target_error_m`` (predicted target to truth);
- ``contacts``: PyBullet contact points between the robot and the table or objects during the
  motions; ``time_per_goal_s``: wall time of query and reach;
- ``in_a_row``: for sequences, the share of sequences whose first n goals all succeeded.

Goals that could not be attempted because a component is missing (an image goal without the
visual localization module, an instruction without the parser) are counted as ``unavailable``
and left out of the rates; a goal the map does not find, or a reach that fails, is a failure.

An ``absent`` goal (something the scene does not have) succeeds when the map finds nothing: its
success rate is the share reported not found. It has no place, so recall and the mean errors
leave it out (they are over the goals with a place; ``None`` for a row of absent goals alone).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

from tabletop.arm.success import SUCCESS_RADIUS_M
from tabletop.eval.tasks import GOAL_TYPES

__all__ = [
    "RECALL_RADII_M",
    "SUCCESS_RADIUS_M",
    "EncoderRun",
    "GoalResult",
    "TaskRun",
    "reach_summary",
    "summarize",
]

RECALL_RADII_M = (0.02, 0.05, 0.10)
ORACLE_NOTE = "simulator upper bound"


@dataclass(frozen=True)
class GoalResult:
    """What happened to one goal."""

    goal_id: str
    type: str
    text: str
    sequence: str
    # "done" | "not_found" | "failed" | "unavailable"; an absent goal's success is "not_found"
    status: str
    reason: str = ""
    target: tuple | None = None  # (3,) [m] predicted target, world frame
    target_error_m: float | None = None  # predicted target to the truth [m]
    tcp: tuple | None = None  # (3,) [m] final TCP
    error_m: float | None = None  # final TCP to the truth [m]
    success: bool = False
    reach: str = ""  # the reach controller's reason ("reached", "blocked", ...)
    contacts: int = 0
    time_s: float = 0.0
    truth: list = field(default_factory=list)  # boxes [[lo, hi], ...] [m]
    code: str = ""  # an instruction's generated code
    route: str = ""  # how the (last) reach moved the arm: "none", "local", "planned"
    planning_s: float | None = None  # wall time of its global planner [s], when it was asked
    # for a reach that ended short (blocked, unreachable, ...): "feasible" when the audit
    # (tabletop.arm.bench.audit_goal) finds a configuration on its goal keeping the margin,
    # "infeasible" when it finds none
    audit: str = ""

    @property
    def attempted(self) -> bool:
        return self.status != "unavailable"

    @property
    def has_place(self) -> bool:
        """Whether the goal's truth is a place (every type but ``absent``)."""
        return self.type != "absent"

    def to_json(self) -> dict:
        d = dict(self.__dict__)
        for k in ("target", "tcp"):
            if d[k] is not None:
                d[k] = [round(float(v), 4) for v in d[k]]
        for k in ("target_error_m", "error_m", "time_s", "planning_s"):
            if d[k] is not None:
                d[k] = round(float(d[k]), 4)
        return d


@dataclass
class TaskRun:
    """One task file's goals under one encoder set."""

    task_name: str
    task_path: str
    scene: str
    goals: list[GoalResult]
    figures: dict = field(default_factory=dict)  # name -> path (relative to the report)
    scan_s: float = 0.0
    map_s: float = 0.0
    cached: bool = False
    encoder_names: dict = field(default_factory=dict)
    noise: dict = field(default_factory=dict)  # the sensor noise applied (empty: clean)
    robot: str = "arm"  # "arm" or "mobile" (the task file's [robot] kind)
    success_radius: float = SUCCESS_RADIUS_M  # [m]
    map_path: str = ""  # the map file the goals ran on (in the cache; "" without one)
    recording_path: str = ""  # its (clean) recording's directory in the cache ("" without one)
    driver: str = "sim"  # what moved the arm: "sim" (PyBullet) or "franky-sim" (see DRIVERS)
    tracking: dict = field(default_factory=dict)  # franky-sim: tracking errors and reflexes


@dataclass
class EncoderRun:
    """Every task file under one encoder set; ``available`` is False when the set could not
    be built (the reason says why)."""

    encoders: str
    encoder_names: dict
    available: bool
    reason: str = ""
    tasks: list[TaskRun] = field(default_factory=list)
    wall_s: float = 0.0

    @property
    def label(self) -> str:
        return f"{self.encoders} ({ORACLE_NOTE})" if self.encoders == "oracle" else self.encoders

    @property
    def goals(self) -> list[GoalResult]:
        return [g for t in self.tasks for g in t.goals]

    def summary(self) -> dict:
        s = summarize(self.goals, _sequences(self.tasks))
        return {
            "encoders": self.encoders,
            "encoders_label": self.label,
            "encoder_names": self.encoder_names,
            "available": self.available,
            "reason": self.reason,
            "wall_s": round(self.wall_s, 1),
            **s,
        }


def _sequences(tasks: list[TaskRun]) -> list[list[GoalResult]]:
    out: dict[tuple, list] = {}
    for t in tasks:
        for g in t.goals:
            out.setdefault((t.task_path, g.sequence), []).append(g)
    return list(out.values())


def _rate(goals: list[GoalResult]) -> dict:
    att = [g for g in goals if g.attempted]
    n = len(att)
    out = {
        "goals": len(goals),
        "attempted": n,
        "unavailable": len(goals) - n,
        "successes": sum(g.success for g in att),
        "success_rate": None,
        "recall_at": {f"{int(r * 100)}cm": None for r in RECALL_RADII_M},
        "mean_error_m": None,
        "mean_target_error_m": None,
        "not_found": sum(g.status == "not_found" for g in att),
        "contacts": sum(g.contacts for g in att),
        "time_per_goal_s": None,
    }
    if not n:
        reasons = sorted({g.reason for g in goals})
        out["unavailable_reason"] = "; ".join(reasons)
        return out
    out["success_rate"] = out["successes"] / n
    # A goal without a prediction (not found) counts as a miss at every radius; an absent goal
    # has no place to recall.
    terr = [g.target_error_m for g in att if g.has_place]
    for r in RECALL_RADII_M:
        out["recall_at"][f"{int(r * 100)}cm"] = (
            sum(e is not None and e <= r for e in terr) / len(terr) if terr else None
        )
    errs = [g.error_m for g in att if g.error_m is not None]
    terrs = [e for e in terr if e is not None]
    out["mean_error_m"] = float(np.mean(errs)) if errs else None
    out["mean_target_error_m"] = float(np.mean(terrs)) if terrs else None
    out["time_per_goal_s"] = float(np.mean([g.time_s for g in att]))
    return out


def in_a_row(sequences: list[list[GoalResult]]) -> dict:
    """{n: share of sequences of >= n attempted goals whose first n all succeeded}."""
    seqs = [[g for g in s if g.attempted] for s in sequences]
    seqs = [s for s in seqs if len(s) > 1]
    out = {}
    for n in range(1, max((len(s) for s in seqs), default=0) + 1):
        long = [s for s in seqs if len(s) >= n]
        out[str(n)] = {
            "sequences": len(long),
            "success_rate": sum(all(g.success for g in s[:n]) for s in long) / len(long),
        }
    return out


def reach_summary(goals: list[GoalResult]) -> dict:
    """How the arm did, apart from the map: ``right_target`` (goals whose predicted target is
    within the success radius of the truth) and the share of them that succeeded
    (``right_target_success_rate``), the reaches' ``routes``, ``fallback_share`` (planned
    among the reaches that moved), the global planner's wall time (``planning_ms_median`` /
    ``_p95``), and the reaches that ended ``blocked``, ``blocked_audit_feasible`` of them
    although the audit found a collision-free configuration on the goal."""
    moved = [g for g in goals if g.attempted and g.route]
    right = [
        g
        for g in goals
        if g.attempted
        and g.has_place
        and g.target_error_m is not None
        and g.target_error_m <= SUCCESS_RADIUS_M
    ]
    routes = {r: sum(g.route == r for g in moved) for r in ("none", "local", "planned")}
    went = routes["local"] + routes["planned"]
    plan_ms = [1e3 * g.planning_s for g in moved if g.planning_s is not None]
    return {
        "right_target": len(right),
        "right_target_successes": sum(g.success for g in right),
        "right_target_success_rate": (sum(g.success for g in right) / len(right))
        if right
        else None,
        "routes": routes,
        "fallback_share": routes["planned"] / went if went else None,
        "planning_ms_median": float(np.median(plan_ms)) if plan_ms else None,
        "planning_ms_p95": float(np.percentile(plan_ms, 95)) if plan_ms else None,
        "blocked": sum(g.reach == "blocked" for g in goals),
        "blocked_audit_feasible": sum(
            g.reach == "blocked" and g.audit == "feasible" for g in goals
        ),
    }


def summarize(goals: list[GoalResult], sequences: list[list[GoalResult]]) -> dict:
    """``by_type`` (in :data:`GOAL_TYPES` order, types present only), ``all``, ``contacts``,
    ``in_a_row`` (sequences of two or more goals), ``reach`` (:func:`reach_summary`)."""
    by_type = {}
    for t in GOAL_TYPES:
        gs = [g for g in goals if g.type == t]
        if gs:
            by_type[t] = _rate(gs)
    total = _rate(goals)
    return {
        "by_type": by_type,
        "all": total,
        "goals": len(goals),
        "contacts": total["contacts"] if total["attempted"] else None,  # None: nothing moved
        "in_a_row": in_a_row(sequences),
        "reach": reach_summary(goals),
    }


def json_safe(obj):
    """``obj`` with every NaN or infinite float as None and numpy scalars as Python numbers:
    what strict JSON readers accept (bare ``NaN`` is not JSON)."""
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def dumps(obj) -> str:
    """Strict JSON (no NaN or Infinity) of a result."""
    return json.dumps(json_safe(obj), indent=1, default=float, allow_nan=False)
