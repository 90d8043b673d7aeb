"""The reach controller: turn a 3D target into safe motion, and say how it went.

``move_to(target)``:

1. refuses targets outside the workspace box (``outside_workspace``);
2. lifts targets that lie inside an obstacle (or on/just above a surface) to a standoff above
   its top, so the TCP approaches it rather than being driven into it;
3. checks with the damped-least-squares IK (several seeds) that some configuration puts the
   TCP on the goal (``unreachable`` if none) and that one of them keeps the clearance margin;
   when the first solutions all come too close to something, it turns the top-down gripper
   about its axis (a yaw sweep), then searches for clearance around the best solutions
   (perturbed seeds, position only); ``blocked`` if still none;
4. moves through waypoints — a lift to the transit height, a pre-approach point above the goal,
   then a vertical descent — with the mink controller tracking a point that slides along each
   segment at a bounded speed;
5. keeps every commanded step inside the Panda's published joint limits
   (:data:`~tabletop.arm.trajectory.PANDA_LIMITS`, tighter than the URDF's) and checks it
   before it is sent (swept clearance bound, see
   :meth:`CollisionChecker.check_motion`): a step that would go below the margin is halved,
   quartered, then refused; repeated refusals or a stall end the local move as ``blocked``
   (obstacle in the way) or ``no_progress`` (or ``timeout``);
6. then, when the local move ended so (``fallback``), the global planner
   (:class:`~tabletop.arm.planner.JointPlanner`, RRT-Connect in joint space with the same
   collision checker) plans from where the arm stopped to the goal configuration of step 3; the
   path is time-parametrised within the Panda's limits
   (:func:`~tabletop.arm.trajectory.time_parametrize`), executed by the driver
   (``execute_trajectory``), and the local controller finishes the last centimetres. The
   result's ``route`` says which way the arm went (``local`` or ``planned``) and
   ``local_reason`` why the local move handed over.
"""

from __future__ import annotations

import dataclasses
import enum
import logging
import time
from dataclasses import dataclass, field

import numpy as np
from pinocchio import log3 as pin_log3

from tabletop.arm.collision import CollisionChecker
from tabletop.arm.diffik import MinkDiffIK, top_down_rotation
from tabletop.arm.driver import ArmDriver
from tabletop.arm.ik import solve_ik
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.arm.obstacles import Box, Cylinder, obstacle_aabb
from tabletop.arm.planner import JointPlanner, PlannerConfig, PlanResult
from tabletop.arm.success import SUCCESS_RADIUS_M
from tabletop.arm.trajectory import PANDA_LIMITS, TrajectoryConfig, time_parametrize
from tabletop.arm.workspace import Workspace
from tabletop.errors import ConfigError
from tabletop.transforms import make_transform, rotation_about

__all__ = [
    "GoalChoice",
    "ReachConfig",
    "ReachController",
    "ReachReason",
    "ReachResult",
    "ReachRoute",
]

log = logging.getLogger(__name__)


class ReachReason(enum.StrEnum):
    """Why a reach ended."""

    REACHED = "reached"
    OUTSIDE_WORKSPACE = "outside_workspace"  # the target is outside the workspace box
    UNREACHABLE = "unreachable"  # no arm configuration puts the TCP there
    BLOCKED = "blocked"  # obstacles keep the arm from getting there without contact
    NO_PROGRESS = "no_progress"  # the controller stalled away from obstacles (limits)
    TIMEOUT = "timeout"  # the step budget ran out while still moving


class GoalChoice(enum.StrEnum):
    """Which point a reach commanded."""

    TARGET = "target"  # the target itself
    STANDOFF = "standoff"  # the target lifted above the object it was in or on
    ALTERNATIVE = "alternative"  # another point within goal_radius of the target (selection)


class ReachRoute(enum.StrEnum):
    """Which way a reach moved the arm."""

    NONE = "none"  # nothing moved (refused before moving)
    LOCAL = "local"  # the differential-IK controller alone
    PLANNED = "planned"  # the local move stalled; the global planner's trajectory, then local


#: How the local controller's steps reach the arm (:attr:`ReachConfig.execution`).
EXECUTIONS = ("auto", "stream", "batch")


@dataclass(frozen=True)
class ReachConfig:
    """Parameters of :class:`ReachController`."""

    tolerance: float = 0.005
    """Final TCP position tolerance [m]."""
    waypoint_tolerance: float = 0.01
    """Tolerance [m] at the lift and pre-approach waypoints."""
    clearance_margin: float = 0.01
    """No commanded motion may bring the robot closer than this to anything [m]."""
    standoff: float = 0.04
    """Height [m] of the goal above the top of an obstacle that contains the target."""
    approach_height: float = 0.12
    """Height [m] of the pre-approach waypoint above the goal."""
    transit_clearance: float = 0.12
    """The transit height is at least this far [m] above the tallest obstacle top."""
    max_speed: float = 0.3
    """Speed [m/s] of the tracked point along each segment."""
    max_steps: int = 1500
    """Control-step budget of one move_to."""
    stall_steps: int = 60
    """Steps without 1 mm of progress after which a segment is declared stalled."""
    max_refusals: int = 20
    """Consecutive refused steps after which the move is declared blocked."""
    ik_seeds: int = 6
    """Configurations tried by the reachability check (current, home, then seeded random)."""
    yaw_sweep: int = 12
    """Yaw angles (evenly spaced about the TCP z axis, the default first) tried for the
    top-down orientation, from the current and home configurations, when the first solutions
    all break the clearance margin (1 = no sweep)."""
    clearance_search_iters: int = 60
    """IK solves of the clearance search: position-only IK from perturbed copies of the best
    solution so far, kept when the clearance grows (0 = no search)."""
    clearance_search_sigma: float = 0.3
    """Standard deviation [rad] of the clearance search's perturbations."""
    goal_posture: bool = True
    """During the move, the mink posture task pulls towards the goal configuration the check
    found (instead of the controller's own posture), so the arm ends where the check looked."""
    goal_radius: float = 0.08
    """When no configuration with clearance reaches the goal, points within this distance
    [m] of the target are tried instead (0 = never); below the 10 cm success radius."""
    goal_candidates: int = 36
    """Most candidate points tried by the goal selection."""
    goal_candidate_search_iters: int = 10
    """Clearance-search solves per candidate point (``clearance_search_iters`` for the goal)."""
    fallback: bool = True
    """When the local move ends blocked, without progress or out of steps, plan a path to the
    goal configuration with the global planner, execute it as a trajectory, finish locally."""
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    """The global planner's parameters (its margin is replaced by ``clearance_margin``)."""
    trajectory: TrajectoryConfig = field(default_factory=TrajectoryConfig)
    """Limits scaling and sample period of the planned trajectory (and of the local path's,
    when it is executed as one)."""
    execution: str = "auto"
    """How the local controller's steps reach the arm: ``"stream"`` commands each control step
    and reads the arm back; ``"batch"`` steps the model, then executes the local path as one
    time-parametrised trajectory through few waypoints (drivers that run whole motions, such
    as libfranka's through franky, rest between commands); ``"auto"`` picks ``"batch"`` for a
    driver that says ``runs_whole_motions`` and ``"stream"`` otherwise."""
    batch_tolerance: float = 0.05
    """With batch execution: the most [rad] any step of the local path may lie from the
    straight joint-space segments of the waypoints that replace it."""

    def __post_init__(self) -> None:
        if self.execution not in EXECUTIONS:
            raise ConfigError(
                f"ReachConfig.execution {self.execution!r}; valid: {', '.join(EXECUTIONS)}"
            )
        if not self.batch_tolerance > 0:
            raise ConfigError(f"batch_tolerance must be positive [rad], got {self.batch_tolerance}")
        for name in ("tolerance", "waypoint_tolerance", "standoff", "max_speed"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"ReachConfig.{name} must be positive, got {getattr(self, name)}")
        if self.clearance_margin < 0:
            raise ConfigError(f"clearance_margin must be >= 0 [m], got {self.clearance_margin}")
        if self.max_steps < 1 or self.stall_steps < 1 or self.ik_seeds < 1 or self.yaw_sweep < 1:
            raise ConfigError("max_steps, stall_steps, ik_seeds and yaw_sweep must be >= 1")
        if not 0 <= self.goal_radius < SUCCESS_RADIUS_M:
            raise ConfigError(
                f"ReachConfig.goal_radius must be in [0, {SUCCESS_RADIUS_M}) m, got "
                f"{self.goal_radius}"
            )
        if self.goal_candidates < 1:
            raise ConfigError(
                f"ReachConfig.goal_candidates must be >= 1, got {self.goal_candidates}"
            )
        if not isinstance(self.planner, PlannerConfig):
            raise ConfigError(f"ReachConfig.planner must be a PlannerConfig, got {self.planner!r}")
        if not isinstance(self.trajectory, TrajectoryConfig):
            raise ConfigError(
                f"ReachConfig.trajectory must be a TrajectoryConfig, got {self.trajectory!r}"
            )
        if self.clearance_search_iters < 0 or not self.clearance_search_sigma > 0:
            raise ConfigError(
                "clearance_search_iters must be >= 0 and clearance_search_sigma positive, got "
                f"{self.clearance_search_iters}, {self.clearance_search_sigma}"
            )


@dataclass(frozen=True)
class ReachResult:
    """The outcome of :meth:`ReachController.move_to`."""

    reached: bool
    reason: ReachReason
    target: np.ndarray  # (3,) [m] world, as asked
    goal: np.ndarray  # (3,) [m] world, the commanded point (target lifted to a standoff if inside)
    final_tcp: np.ndarray  # (3,) [m] world, TCP position at the end (measured)
    error_m: float  # |final_tcp - goal| [m]
    target_error_m: float  # |final_tcp - target| [m]
    min_clearance_m: float  # smallest clearance of the executed motion [m] (capped)
    steps: int  # control steps executed
    refused_steps: int  # steps refused by the collision check
    time_s: float  # driver time spent [s]
    wall_time_s: float  # wall-clock time of the call [s]
    standoff_applied: bool = False  # the target was inside an obstacle / on a surface
    goal_search_s: float = 0.0  # wall time of the pre-motion goal search [s]
    route: ReachRoute = ReachRoute.NONE  # which way the arm went
    goal_choice: GoalChoice = GoalChoice.TARGET  # which point was commanded
    goal_candidates_tried: int = 0  # candidate points checked by the goal selection
    local_reason: ReachReason | None = None  # why the local move handed over to the planner
    plan: PlanResult | None = None  # the global planner's answer, when it was asked
    trajectory_samples: int = 0  # samples of the planned trajectory sent to the driver


@dataclass
class _Run:
    """Counters of one move, shared by its local and planned parts."""

    min_clear: float  # [m] smallest swept clearance bound so far
    steps: int = 0  # control steps executed
    refused: int = 0  # steps refused by the collision check
    steps_left: int = 0  # step budget of the current local part (set by move_to)


def _yaw_offsets(n: int) -> np.ndarray:
    """(n,) yaw offsets [rad] evenly spaced over a turn, ordered by size (0 first)."""
    a = (np.arange(n) * (2.0 * np.pi / n) + np.pi) % (2.0 * np.pi) - np.pi
    return a[np.argsort(np.abs(a), kind="stable")]


class ReachController:
    """Moves the TCP to 3D targets with mink differential IK and collision checking.

    Args:
        model: the Panda model.
        driver: the arm (simulated or real), see :class:`tabletop.arm.driver.ArmDriver`.
        obstacles: the environment (table, objects, voxel boxes), world frame.
        config: parameters.
        workspace: the allowed TCP box.
        diffik: a prepared :class:`MinkDiffIK` (built from ``obstacles`` when omitted).
        checker: a prepared :class:`CollisionChecker` (built from ``obstacles`` when omitted).
        planner: a prepared :class:`JointPlanner` (built on ``checker`` when omitted).
    """

    def __init__(
        self,
        model: PandaModel,
        driver: ArmDriver,
        obstacles=(),
        config: ReachConfig | None = None,
        workspace: Workspace | None = None,
        diffik: MinkDiffIK | None = None,
        checker: CollisionChecker | None = None,
        planner: JointPlanner | None = None,
    ) -> None:
        self.model = model
        self.driver = driver
        self.config = config or ReachConfig()
        # the driver's own joint limits where it has them (an FR3 is tighter than a Panda)
        self.limits = getattr(driver, "limits", None) or PANDA_LIMITS
        mode = self.config.execution
        if mode == "auto":
            mode = "batch" if getattr(driver, "runs_whole_motions", False) else "stream"
        self.execution = mode
        self.workspace = workspace or Workspace()
        self.obstacles = tuple(obstacles)
        self.diffik = diffik or MinkDiffIK(model, self.obstacles)
        self.checker = checker or CollisionChecker(model, self.obstacles)
        self.planner = planner or JointPlanner(
            model,
            self.checker,
            dataclasses.replace(self.config.planner, margin=self.config.clearance_margin),
        )
        self._rng = np.random.default_rng(0)

    def set_obstacles(self, obstacles) -> None:
        """Replace the environment in both the controller and the collision checker."""
        self.obstacles = tuple(obstacles)
        self.diffik.set_obstacles(self.obstacles)
        self.checker.set_obstacles(self.obstacles)

    # ------------------------------------------------------------------ goal
    def _footprint_contains(self, ob, p: np.ndarray) -> bool:
        if isinstance(ob, Cylinder):
            return bool(np.hypot(*(p[:2] - ob.center[:2])) <= ob.radius)
        if isinstance(ob, Box):
            local = ob.rotation.T @ (np.array([p[0], p[1], ob.center[2]]) - ob.center)
            ext = ob.half_extents
            return bool(abs(local[0]) <= ext[0] and abs(local[1]) <= ext[1])
        lo, hi = obstacle_aabb(ob)
        return bool(np.all(p[:2] >= lo[:2]) and np.all(p[:2] <= hi[:2]))

    def standoff_goal(self, target: np.ndarray) -> tuple[np.ndarray, bool]:
        """The target lifted to ``standoff`` above any obstacle top it is in or just above."""
        goal = np.array(target, dtype=np.float64)
        moved = False
        for _ in range(len(self.obstacles) + 1):
            lifted = False
            for ob in self.obstacles:
                lo, hi = obstacle_aabb(ob)
                if not (lo[2] <= goal[2] < hi[2] + self.config.standoff):
                    continue
                if self._footprint_contains(ob, goal):
                    goal[2] = hi[2] + self.config.standoff
                    lifted = moved = True
            if not lifted:
                break
        return goal, moved

    def goal_candidates(self, target: object, goal: object) -> list[np.ndarray]:
        """Alternative goals [(3,) m] for a blocked ``goal``, nearest to ``target`` (the
        reach's reference) first.

        Points around the goal (8 directions in the horizontal plane and straight up, at 2-8 cm
        steps of 2 cm), each lifted to the standoff above any object it is in or on, kept when
        inside the workspace and within ``goal_radius`` of ``target`` (so a TCP on one of them
        is within the success radius), at most ``goal_candidates`` of them.
        """
        c = self.config
        target = np.asarray(target, dtype=np.float64)
        goal = np.asarray(goal, dtype=np.float64)
        az = np.arange(8) * (np.pi / 4)
        dirs = [np.array([np.cos(a), np.sin(a), 0.0]) for a in az] + [np.array([0.0, 0, 1])]
        out: list[np.ndarray] = []
        for r in np.arange(0.02, c.goal_radius + 1e-9, 0.02):
            for d in dirs:
                p, _ = self.standoff_goal(goal + r * d)
                if not self.workspace.contains(p):
                    continue
                if np.linalg.norm(p - target) > c.goal_radius:
                    continue
                if any(np.linalg.norm(p - o) < 0.01 for o in out) or (
                    np.linalg.norm(p - goal) < 0.01
                ):
                    continue
                out.append(p)
        out.sort(key=lambda p: float(np.linalg.norm(p - target)))
        return out[: c.goal_candidates]

    def _transit_height(self, goal: np.ndarray) -> float:
        tops = [obstacle_aabb(ob)[1][2] for ob in self.obstacles]
        z = max(
            [goal[2] + self.config.approach_height]
            + [t + self.config.transit_clearance for t in tops]
        )
        return float(min(z, self.workspace.upper[2] - 0.05))

    def _goal_configuration(
        self,
        goal: np.ndarray,
        R: np.ndarray,
        q_now: np.ndarray,
        free_yaw: bool = True,
        search_iters: int | None = None,
    ) -> tuple[str, np.ndarray | None]:
        """(status, q) of the reachability check: 'ok', 'unreachable' or 'blocked'.

        1. Full pose ``R`` then position only, from the current, home and seeded random
           configurations (as many as ``ik_seeds``): none converges -> 'unreachable'.
        2. With ``free_yaw`` (the default top-down orientation), ``R`` turned about the TCP
           z axis through ``yaw_sweep`` angles, from the current and home configurations.
        3. The clearance search: position-only IK from perturbed copies of the solution with
           the largest clearance so far (its own posture as the null-space target), keeping
           improvements, for ``clearance_search_iters`` solves.

        The first solution that keeps ``clearance_margin`` is returned ('ok'); 'blocked' with
        the best converged solution if none does.
        """
        c = self.config
        margin = c.clearance_margin
        rng = np.random.default_rng([int(v) for v in np.round((goal + 10.0) * 1e4)])
        seeds = [q_now, np.asarray(HOME_Q)]
        while len(seeds) < c.ik_seeds:
            seeds.append(self.model.random_q(rng, margin=0.3))
        best_q, best_d = None, -np.inf

        def solve(R_: np.ndarray, seed: np.ndarray, position_only: bool, posture=None) -> bool:
            nonlocal best_q, best_d
            res = solve_ik(
                self.model,
                make_transform(R_, goal),
                seed,
                position_only=position_only,
                tol_pos=1e-3,
                tol_rot=0.05,
                max_iters=60,
                q_posture=posture,
            )
            if not res.success:
                return False
            d = self.checker.clearance(res.q).distance
            if d > best_d:
                best_q, best_d = res.q, d
            return d >= margin

        for position_only in (False, True):
            for seed in seeds:
                if solve(R, seed, position_only):
                    return "ok", best_q
        if best_q is None:
            return "unreachable", None
        if free_yaw:
            for dyaw in _yaw_offsets(c.yaw_sweep)[1:]:
                for seed in seeds[:2]:
                    if solve(rotation_about("z", dyaw) @ R, seed, False):
                        return "ok", best_q
        for _ in range(c.clearance_search_iters if search_iters is None else search_iters):
            seed = self.model.clip(best_q + rng.normal(0.0, c.clearance_search_sigma, 7))
            if solve(R, seed, True, posture=seed):
                return "ok", best_q
        return "blocked", best_q

    # ------------------------------------------------------------------ motion
    def move_to(
        self, target: object, orientation: object | None = None, *, reference: object | None = None
    ) -> ReachResult:
        """Move the TCP to ``target`` (3,) [m], world frame; see the module docstring.

        Args:
            target: the point to reach.
            orientation: (3, 3) R_world_tcp; default top-down, yawed towards the target.
            reference: (3,) [m] the point the reach is judged by (the object's top when
                ``target`` is an approach point above it); the goal selection keeps its
                alternative goals within ``goal_radius`` of it. Default: ``target``.

        Returns:
            a :class:`ReachResult`; failures are reasons in it, never exceptions.
        """
        wall0 = time.perf_counter()
        goal_search_s = 0.0
        choice, tried = GoalChoice.TARGET, 0
        target = np.array(target, dtype=np.float64)
        if target.shape != (3,) or not np.all(np.isfinite(target)):
            raise ConfigError(f"target must be a finite (3,) point [m], got {target.tolist()}")
        ref = target if reference is None else np.array(reference, dtype=np.float64)
        if ref.shape != (3,) or not np.all(np.isfinite(ref)):
            raise ConfigError(f"reference must be a finite (3,) point [m], got {ref.tolist()}")
        c = self.config
        state = self.driver.read_state()
        t_start = state.time_s
        q = state.q

        min_clear0 = self.checker.clearance(q).distance

        def result(
            reason: ReachReason,
            goal,
            steps=0,
            refused=0,
            min_clear=min_clear0,
            moved=False,
            route=ReachRoute.NONE,
            local_reason=None,
            plan=None,
            samples=0,
        ):
            tcp = self.model.fk(self.driver.read_state().q)[:3, 3]
            err = float(np.linalg.norm(tcp - goal))
            reached = reason == ReachReason.REACHED
            return ReachResult(
                reached=reached,
                reason=reason,
                target=target,
                goal=np.array(goal, dtype=np.float64),
                final_tcp=tcp,
                error_m=err,
                target_error_m=float(np.linalg.norm(tcp - target)),
                min_clearance_m=float(min_clear),
                steps=steps,
                refused_steps=refused,
                time_s=self.driver.read_state().time_s - t_start,
                wall_time_s=time.perf_counter() - wall0,
                standoff_applied=moved,
                goal_search_s=goal_search_s,
                route=route,
                goal_choice=choice,
                goal_candidates_tried=tried,
                local_reason=local_reason,
                plan=plan,
                trajectory_samples=samples,
            )

        if not self.workspace.contains(target):
            return result(ReachReason.OUTSIDE_WORKSPACE, target)
        goal, moved = self.standoff_goal(target)
        if not self.workspace.contains(goal):
            return result(ReachReason.OUTSIDE_WORKSPACE, goal, moved=moved)
        if orientation is None:
            R = top_down_rotation(float(np.arctan2(goal[1], goal[0])) if goal[0] > 0 else 0.0)
        else:
            R = np.asarray(orientation, dtype=np.float64)
            if R.shape != (3, 3):
                raise ConfigError(f"orientation must be a (3, 3) rotation, got {R.shape}")
        if moved:
            choice = GoalChoice.STANDOFF
        t_search = time.perf_counter()
        status, q_goal = self._goal_configuration(goal, R, q, free_yaw=orientation is None)
        if status == "blocked" and c.goal_radius > 0:
            for cand in self.goal_candidates(ref, goal):
                tried += 1
                st, qc = self._goal_configuration(
                    cand, R, q, orientation is None, c.goal_candidate_search_iters
                )
                if st == "ok":
                    status, q_goal, goal, choice = st, qc, cand, GoalChoice.ALTERNATIVE
                    log.info(
                        "goal selection: %s instead of %s (%.3f m from the reference)",
                        np.round(goal, 3).tolist(),
                        np.round(target, 3).tolist(),
                        float(np.linalg.norm(goal - ref)),
                    )
                    break
        goal_search_s = time.perf_counter() - t_search
        if status == "unreachable":
            return result(ReachReason.UNREACHABLE, goal, moved=moved)
        if status == "blocked":
            return result(ReachReason.BLOCKED, goal, moved=moved)
        R_goal = self.model.fk(q_goal)[:3, :3]
        if orientation is None and np.linalg.norm(pin_log3(R_goal @ R.T)) > 0.05:
            R = R_goal  # top-down is out of reach here: keep the orientation IK found

        posture0 = self.diffik.q_posture
        if c.goal_posture:
            self.diffik.set_posture(q_goal)
        try:
            tcp = self.model.fk(q)[:3, 3]
            z_tr = max(self._transit_height(goal), goal[2])
            waypoints = []
            if tcp[2] < z_tr - 0.02 and np.linalg.norm(tcp[:2] - goal[:2]) > 0.02:
                waypoints.append((np.array([tcp[0], tcp[1], z_tr]), c.waypoint_tolerance))
            if z_tr - goal[2] > 0.02:
                waypoints.append((np.array([goal[0], goal[1], z_tr]), c.waypoint_tolerance))
            waypoints.append((goal, c.tolerance))
            run = _Run(min_clear=self.checker.clearance(q).distance, steps_left=c.max_steps)
            reason = self._follow(waypoints, R, run)
            if reason == ReachReason.REACHED or not c.fallback:
                return result(
                    reason, goal, run.steps, run.refused, run.min_clear, moved, ReachRoute.LOCAL
                )
            # The local move stalled: the global planner, then the local finish.
            local_reason = reason
            plan, samples = self._planned_move(q_goal, run)
            if plan.ok:
                run.steps_left = c.max_steps  # the finish has its own step budget
                tcp = self.model.fk(self.driver.read_state().q)[:3, 3]
                reason = (
                    ReachReason.REACHED
                    if np.linalg.norm(tcp - goal) <= c.tolerance
                    else self._follow([(goal, c.tolerance)], R, run)
                )
            return result(
                reason,
                goal,
                run.steps,
                run.refused,
                run.min_clear,
                moved,
                ReachRoute.PLANNED,
                local_reason,
                plan,
                samples,
            )
        finally:
            self.diffik.set_posture(posture0)

    def _planned_move(self, q_goal: np.ndarray, run: _Run) -> tuple[PlanResult, int]:
        """Plan from the measured configuration to ``q_goal``, execute it; (plan, samples)."""
        q_now = self.driver.read_state().q
        # Plan to the goal configuration inside the published limits (the local finish
        # covers the difference when the IK solution touched the URDF's wider ones).
        lo, hi = self.limits.q_lower + 1e-3, self.limits.q_upper - 1e-3
        q_to = np.clip(q_goal, lo, hi)
        # Likewise the start, when tracking left the arm a hair outside (at most 0.01 rad:
        # the trajectory may start that far from the measured configuration).
        q_from = np.clip(q_now, lo, hi)
        if np.abs(q_from - q_now).max() > 0.01:
            q_from = q_now
        plan = self.planner.plan(q_from, q_to)
        if not plan.ok:
            log.info(
                "global planner: %s after %.3f s (from %s to %s)",
                plan.reason.value,
                plan.planning_time_s,
                np.round(q_now, 4).tolist(),
                np.round(q_to, 4).tolist(),
            )
            return plan, 0
        traj = time_parametrize(plan.path, self.limits, self.config.trajectory)
        self.driver.execute_trajectory(traj)
        run.min_clear = min(run.min_clear, plan.min_clearance_m)
        log.info(
            "global planner: %d waypoints (%d before shortcuts), %.3f s planning, %.2f s motion",
            len(plan.path),
            plan.raw_waypoints,
            plan.planning_time_s,
            traj.duration,
        )
        return plan, len(traj)

    def _follow(self, waypoints, R: np.ndarray, run: _Run) -> ReachReason:
        """The local controller along the TCP waypoints [(point (3,) [m], tolerance [m])].

        Updates ``run`` (steps, refusals, clearance); returns ``REACHED`` or why it stopped.
        """
        path = [self.driver.read_state().q] if self.execution == "batch" else None
        try:
            return self._follow_steps(waypoints, R, run, path)
        finally:
            if path is not None:
                self._execute_path(path)

    def _execute_path(self, path: list[np.ndarray]) -> None:
        """Batch execution: the local path's steps as one trajectory through few waypoints
        (each step within ``batch_tolerance`` of the straight segments, each segment checked
        for clearance as the steps were)."""
        if len(path) < 2:
            return
        q = np.asarray(path)
        tol, margin = self.config.batch_tolerance, self.config.clearance_margin

        def straight(i: int, j: int, c0) -> bool:
            s = np.linspace(0.0, 1.0, j - i + 1)[:, None]
            if np.abs(q[i : j + 1] - (q[i] + s * (q[j] - q[i]))).max() > tol:
                return False
            return self.checker.check_motion(q[i], q[j], margin, c0).ok

        keep, i = [0], 0
        while i < len(q) - 1:
            c0 = self.checker.clearance(q[i])  # never closer than the path already is
            # the farthest step a straight segment reaches (a binary search; one step always
            # does: each was checked when it was taken)
            lo, hi = i + 1, len(q) - 1
            if not straight(i, hi, c0):
                while hi - lo > 1:
                    mid = (lo + hi) // 2
                    if straight(i, mid, c0):
                        lo = mid
                    else:
                        hi = mid
                hi = lo
            keep.append(hi)
            i = hi
        traj = time_parametrize(q[keep], self.limits, self.config.trajectory)
        log.info("local path: %d steps as %d waypoints, %.2f s", len(q), len(keep), traj.duration)
        self.driver.execute_trajectory(traj)

    def _follow_steps(self, waypoints, R: np.ndarray, run: _Run, path: list | None):
        """The local controller's loop; with ``path`` (batch execution) each step goes onto the
        path instead of to the arm."""
        c = self.config
        q = path[-1] if path is not None else self.driver.read_state().q
        dt = self.diffik.config.dt
        step_len = c.max_speed * dt
        steps0 = run.steps
        lo = np.maximum(self.model.q_lower, self.limits.q_lower)
        hi = np.minimum(self.model.q_upper, self.limits.q_upper)

        def stop() -> None:
            if path is None:
                self.driver.stop()

        for wp, tol in waypoints:
            start = self.model.fk(q)[:3, 3]
            seg = wp - start
            seg_len = float(np.linalg.norm(seg))
            s = 0.0
            best, since_best, consecutive_refusals = np.inf, 0, 0
            while True:
                tcp = self.model.fk(q)[:3, 3]
                dist = float(np.linalg.norm(tcp - wp))
                if dist <= tol and s >= seg_len:
                    break
                if run.steps - steps0 >= run.steps_left:
                    stop()
                    return ReachReason.TIMEOUT
                if dist < best - 1e-3:
                    best, since_best = dist, 0
                else:
                    since_best += 1
                if since_best >= c.stall_steps and s >= seg_len:
                    stop()
                    near = self.checker.clearance(q).distance
                    if near < self.diffik.config.collision_min_distance + 0.01:
                        return ReachReason.BLOCKED
                    return ReachReason.NO_PROGRESS
                s = min(seg_len, s + step_len)
                carrot = start + (seg * (s / seg_len) if seg_len > 0 else 0.0)
                ik = self.diffik.step(q, make_transform(R, carrot))
                c0 = self.checker.clearance(q)
                ok = False
                if ik.solved:
                    # Inside the Panda's published limits (tighter than the URDF's that mink
                    # and the IK use), never further outside than the arm already is.
                    q_next = np.clip(ik.q, np.minimum(lo, q), np.maximum(hi, q))
                    for _ in range(3):  # the full step, then half, then a quarter
                        mc = self.checker.check_motion(q, q_next, c.clearance_margin, c0)
                        if mc.ok:
                            ok = True
                            break
                        q_next = q + 0.5 * (q_next - q)
                if not ok:
                    run.refused += 1
                    consecutive_refusals += 1
                    if consecutive_refusals >= c.max_refusals:
                        stop()
                        return ReachReason.BLOCKED
                    if path is None:
                        self.driver.command_positions(q, dt)  # hold position for one period
                        q = self.driver.read_state().q
                    continue
                consecutive_refusals = 0
                run.min_clear = min(run.min_clear, mc.swept_lower_bound)
                run.steps += 1
                if path is None:
                    self.driver.command_positions(q_next, dt)
                    q = self.driver.read_state().q
                else:
                    path.append(q_next)
                    q = q_next
        return ReachReason.REACHED
