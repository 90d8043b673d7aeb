"""A global planner in joint space: RRT-Connect against the collision checker, then shortcuts.

The reach controller is local (differential IK towards a moving point): beside tall objects or
low between them it can stall where a different arm motion would pass. :class:`JointPlanner`
searches joint space for a path from the arm's configuration to a goal configuration (one the
controller's goal check found) that keeps the clearance margin everywhere, with the same
:class:`CollisionChecker` and the same obstacles as the controller.

Every edge is certified, not sampled: :meth:`JointPlanner.segment_clearance` uses the checker's
swept bound (no robot point moves more than ``D`` along the segment, so none comes closer than
``(c_a + c_b - D) / 2``) and bisects the segment until the bound holds on every piece, or a
piece's end breaks the margin. A path is RRT-Connect's (two trees, one from each end, each
extension greedy towards the other tree's newest node), then shortened by random shortcuts
(each checked the same way) and a final greedy pass. The planner samples inside the Panda's
published position limits (:data:`~tabletop.arm.trajectory.PANDA_LIMITS`, tighter than the
URDF's) so its path can be time-parametrised for a real arm.

Why our own planner rather than OMPL's or VAMP's: see ``docs/arm.md`` ("Global planner").
"""

from __future__ import annotations

import enum
import time
from dataclasses import dataclass

import numpy as np

from tabletop.arm.collision import CollisionChecker
from tabletop.arm.model import PandaModel, as_arm_q
from tabletop.arm.trajectory import PANDA_LIMITS, JointLimits
from tabletop.errors import ConfigError

__all__ = ["JointPlanner", "PlanReason", "PlanResult", "PlannerConfig"]


class PlanReason(enum.StrEnum):
    """How a planning query ended."""

    PLANNED = "planned"
    START_IN_COLLISION = "start_in_collision"  # the start breaks the margin
    GOAL_IN_COLLISION = "goal_in_collision"  # the goal breaks the margin
    OUTSIDE_LIMITS = "outside_limits"  # start or goal outside the position limits
    NO_PATH = "no_path"  # the budget ran out before the trees met


@dataclass(frozen=True)
class PlannerConfig:
    """Parameters of :class:`JointPlanner`."""

    margin: float = 0.01
    """Clearance [m] every configuration of the path keeps (swept bound)."""
    step: float = 0.25
    """Largest extension of a tree node [rad] (Euclidean norm over the 7 joints)."""
    max_iterations: int = 4000
    """RRT-Connect iterations (one sample, both trees extended) before giving up."""
    max_time_s: float = 10.0
    """Wall-time budget of the search [s] (shortcutting is extra, bounded by its iterations)."""
    shortcut_iterations: int = 60
    """Random shortcut attempts on the found path."""
    max_bisections: int = 12
    """Depth of the edge check's bisection; a piece still uncertified then is refused."""
    seed: int = 0
    """Seed of the samples and shortcuts (a query is reproducible)."""
    escape_band: float = 0.01
    """An end whose clearance is less than ``margin + escape_band`` [m] and whose tree has not
    grown in ``escape_after`` iterations is moved to a configuration nearby that clears it
    (see :meth:`JointPlanner.plan`); 0 turns this off."""
    escape_after: int = 30
    """Iterations before an end whose tree has not grown is moved off the margin."""

    def __post_init__(self) -> None:
        if self.margin < 0:
            raise ConfigError(f"PlannerConfig.margin must be >= 0 [m], got {self.margin}")
        if not self.step > 0:
            raise ConfigError(f"PlannerConfig.step must be positive [rad], got {self.step}")
        if not self.max_time_s > 0:
            raise ConfigError(f"PlannerConfig.max_time_s must be positive, got {self.max_time_s}")
        for name in ("max_iterations", "max_bisections", "escape_after"):
            if getattr(self, name) < 1:
                raise ConfigError(f"PlannerConfig.{name} must be >= 1, got {getattr(self, name)}")
        if self.escape_band < 0:
            raise ConfigError(f"PlannerConfig.escape_band must be >= 0 [m], got {self.escape_band}")
        if self.shortcut_iterations < 0:
            raise ConfigError(
                f"PlannerConfig.shortcut_iterations must be >= 0, got {self.shortcut_iterations}"
            )


@dataclass(frozen=True)
class PlanResult:
    """The outcome of :meth:`JointPlanner.plan`."""

    ok: bool
    reason: PlanReason
    path: np.ndarray | None  # (M, 7) [rad] waypoints, start first, goal last (None unless ok)
    min_clearance_m: float  # certified lower bound of the path's clearance [m] (-inf: none)
    planning_time_s: float  # wall time of search and shortcuts [s]
    iterations: int  # RRT-Connect iterations run
    raw_waypoints: int  # waypoints of the path before shortcutting (0: none)
    clearance_queries: int  # collision checker calls made


class _Tree:
    def __init__(self, q0: np.ndarray, c0: float) -> None:
        self.q = [q0]
        self.c = [c0]
        self.parent = [-1]

    def nearest(self, q: np.ndarray) -> int:
        d = np.linalg.norm(np.asarray(self.q) - q, axis=1)
        return int(np.argmin(d))

    def add(self, q: np.ndarray, c: float, parent: int) -> int:
        self.q.append(q)
        self.c.append(c)
        self.parent.append(parent)
        return len(self.q) - 1

    def branch(self, i: int) -> list[np.ndarray]:
        """Configurations from node i back to the root."""
        out = []
        while i >= 0:
            out.append(self.q[i])
            i = self.parent[i]
        return out


class JointPlanner:
    """RRT-Connect with certified edges and shortcutting, on a :class:`CollisionChecker`.

    Args:
        model: the Panda model.
        checker: the collision checker of the scene (the reach controller's own).
        config: parameters.
        limits: the position limits sampled within (default: the Panda's published limits).
    """

    def __init__(
        self,
        model: PandaModel,
        checker: CollisionChecker,
        config: PlannerConfig | None = None,
        limits: JointLimits = PANDA_LIMITS,
    ) -> None:
        self.model = model
        self.checker = checker
        self.config = config or PlannerConfig()
        self.limits = limits
        self._queries = 0
        self.timings_s: list[float] = []  # planning time of every query [s]

    # ------------------------------------------------------------------ edges
    def _clearance(self, q: np.ndarray) -> float:
        self._queries += 1
        return self.checker.clearance(q).distance

    def segment_clearance(
        self,
        qa: object,
        qb: object,
        ca: float | None = None,
        cb: float | None = None,
    ) -> float:
        """Certified lower bound [m] of the clearance along the straight segment qa -> qb.

        Returns a value >= ``margin`` when the whole segment keeps the margin, else a value
        below it (the offending piece's bound or end clearance). ``ca`` / ``cb`` are the ends'
        clearances when already known.
        """
        qa, qb = as_arm_q(qa, "qa"), as_arm_q(qb, "qb")
        ca = self._clearance(qa) if ca is None else ca
        cb = self._clearance(qb) if cb is None else cb
        return self._segment(qa, qb, ca, cb, self.config.max_bisections)

    def _segment(self, qa, qb, ca: float, cb: float, depth: int, m: float | None = None) -> float:
        m = self.config.margin if m is None else m
        if min(ca, cb) < m:
            return min(ca, cb)
        D = self.checker.max_displacement(qa, qb)
        bound = (ca + cb - D) / 2
        if bound >= m:
            return min(ca, cb, bound)
        if depth == 0:
            return bound
        qm = (qa + qb) / 2
        cm = self._clearance(qm)
        left = self._segment(qa, qm, ca, cm, depth - 1, m)
        if left < m:
            return left
        return min(left, self._segment(qm, qb, cm, cb, depth - 1, m))

    # ------------------------------------------------------------------ search
    def _inside(self, q: np.ndarray) -> bool:
        return bool(np.all(q >= self.limits.q_lower) and np.all(q <= self.limits.q_upper))

    def _extend(self, tree: _Tree, q_to: np.ndarray, greedy: bool) -> tuple[int, bool]:
        """Grow ``tree`` towards ``q_to`` by steps; (last node added or -1, reached q_to)."""
        i = tree.nearest(q_to)
        last = -1
        while True:
            q_from, c_from = tree.q[i], tree.c[i]
            d = q_to - q_from
            n = float(np.linalg.norm(d))
            reached = n <= self.config.step
            q_new = q_to.copy() if reached else q_from + d * (self.config.step / n)
            c_new = self._clearance(q_new)
            if self._segment(q_from, q_new, c_from, c_new, self.config.max_bisections) < (
                self.config.margin
            ):
                return last, False
            i = last = tree.add(q_new, c_new, i)
            if reached or not greedy:
                return last, reached

    def plan(self, q_start: object, q_goal: object) -> PlanResult:
        """A path from ``q_start`` to ``q_goal`` (both (7,) [rad]) keeping the margin."""
        t0 = time.perf_counter()
        self._queries = 0
        cfg = self.config
        qs, qg = as_arm_q(q_start, "q_start"), as_arm_q(q_goal, "q_goal")

        def done(reason: PlanReason, path=None, raw=0, it=0, clear=-np.inf) -> PlanResult:
            dt = time.perf_counter() - t0
            self.timings_s.append(dt)
            return PlanResult(
                ok=reason == PlanReason.PLANNED,
                reason=reason,
                path=path,
                min_clearance_m=float(clear),
                planning_time_s=dt,
                iterations=it,
                raw_waypoints=raw,
                clearance_queries=self._queries,
            )

        if not (self._inside(qs) and self._inside(qg)):
            return done(PlanReason.OUTSIDE_LIMITS)
        cs, cg = self._clearance(qs), self._clearance(qg)
        if cs < cfg.margin:
            return done(PlanReason.START_IN_COLLISION)
        if cg < cfg.margin:
            return done(PlanReason.GOAL_IN_COLLISION)
        if self._segment(qs, qg, cs, cg, cfg.max_bisections) >= cfg.margin:
            path = np.array([qs, qg])
            return done(PlanReason.PLANNED, path, 2, 0, self._path_clearance(path))
        rng = np.random.default_rng(cfg.seed)
        ts, tg = _Tree(qs, cs), _Tree(qg, cg)
        a, b = ts, tg
        # An end on the margin (where the reach controller stalls) may grow no tree at all:
        # every step's swept bound from it can fall below the margin. Such an end is moved
        # off the margin (a short segment keeping half its clearance) once the first
        # ``escape_after`` iterations have added nothing to its tree.
        head, tail, escape_clear = [], [], np.inf
        it = 0
        while it < cfg.max_iterations and time.perf_counter() - t0 < cfg.max_time_s:
            it += 1
            if it == cfg.escape_after + 1:
                for tree in (ts, tg):
                    moved = self._moved_off(tree, rng)
                    if moved is None:
                        continue
                    new, bound = moved
                    escape_clear = min(escape_clear, bound)
                    a, b = (new, b) if a is tree else (a, new)
                    if tree is ts:
                        head, ts = [tree.q[0]], new
                    else:
                        tail, tg = [tree.q[0]], new
            q_rand = rng.uniform(self.limits.q_lower, self.limits.q_upper)
            i_new, _ = self._extend(a, q_rand, greedy=False)
            if i_new >= 0:
                j_new, met = self._extend(b, a.q[i_new], greedy=True)
                if met:
                    branch_a = a.branch(i_new)[::-1]
                    branch_b = b.branch(j_new)[1:]  # skip the node equal to a's
                    path = branch_a + branch_b
                    if a is not ts:  # the trees were swapped: the path runs goal -> start
                        path = path[::-1]
                    path = np.array(path)
                    raw = len(path) + len(head) + len(tail)
                    path = self._shortcut(path, rng)
                    clear = min(self._path_clearance(path), escape_clear)
                    path = np.array([*head, *path, *tail])
                    return done(PlanReason.PLANNED, path, raw, it, clear)
            a, b = b, a
        return done(PlanReason.NO_PATH, it=it)

    def _moved_off(self, tree: _Tree, rng: np.random.Generator) -> tuple[_Tree, float] | None:
        """A new tree rooted where ``tree``'s root is moved off the margin (:meth:`_escape`),
        and the escape segment's certified bound; None where the tree has grown, its root
        clears ``margin + escape_band``, or no escape was found."""
        q, c = tree.q[0], tree.c[0]
        if len(tree.q) > 1 or c >= self.config.margin + self.config.escape_band:
            return None
        esc = self._escape(q, c, rng)
        return None if esc is None else (_Tree(esc[0], esc[1]), esc[2])

    def _escape(
        self, q: np.ndarray, c: float, rng: np.random.Generator
    ) -> tuple[np.ndarray, float, float] | None:
        """A configuration near ``q`` (clearance ``c``, on or just above the margin) that
        clears ``margin + escape_band``, reached by a straight segment certified to keep half
        of ``c``: (configuration, its clearance, the segment's certified bound), or None.

        Tried along the clearance's numerical gradient first, then the joint axes and random
        directions, each at growing step lengths."""
        cfg = self.config
        want, keep = cfg.margin + cfg.escape_band, 0.5 * c
        h = 1e-3
        grad = np.zeros(7)
        for j in range(7):
            dq = np.zeros(7)
            dq[j] = h
            if self._inside(q + dq):
                grad[j] = (self._clearance(q + dq) - c) / h
            elif self._inside(q - dq):
                grad[j] = (c - self._clearance(q - dq)) / h
        dirs = []
        if np.linalg.norm(grad) > 0:
            dirs.append(grad / np.linalg.norm(grad))
        dirs += [s * e for e in np.eye(7) for s in (1.0, -1.0)]
        rand = rng.normal(size=(16, 7))
        dirs += list(rand / np.linalg.norm(rand, axis=1, keepdims=True))
        for step in (0.05, 0.1, 0.2, 0.3):
            for d in dirs:
                qn = q + step * d
                if not self._inside(qn):
                    continue
                cn = self._clearance(qn)
                if cn < want:
                    continue
                bound = self._segment(q, qn, c, cn, cfg.max_bisections, keep)
                if bound >= keep:
                    return qn, cn, bound
        return None

    # ------------------------------------------------------------------ smoothing
    def _path_clearance(self, path: np.ndarray) -> float:
        cs = [self._clearance(q) for q in path]
        out, depth = min(cs), self.config.max_bisections
        for k in range(len(path) - 1):
            out = min(out, self._segment(path[k], path[k + 1], cs[k], cs[k + 1], depth))
        return out

    def _shortcut(self, path: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Random shortcuts between points on the path, then a greedy pass from the start."""
        m = self.config.margin
        pts = [p for p in path]
        for _ in range(self.config.shortcut_iterations):
            if len(pts) < 3:
                break
            i, j = sorted(rng.choice(len(pts), 2, replace=False))
            if j - i < 2:
                continue
            if self.segment_clearance(pts[i], pts[j]) >= m:
                pts = pts[: i + 1] + pts[j:]
        out, k = [pts[0]], 0
        while k < len(pts) - 1:
            nxt = k + 1
            for j in range(len(pts) - 1, k + 1, -1):
                if self.segment_clearance(pts[k], pts[j]) >= m:
                    nxt = j
                    break
            out.append(pts[nxt])
            k = nxt
        return np.array(out)
