"""The arm benchmark: seeded reach targets in a cluttered PyBullet scene.

``run_arm_benchmark`` builds its own PyBullet DIRECT world (a table slab, a handful of boxes and
cylinders, the Panda under gravity), drives it with :class:`PyBulletDriver` (physics stepping,
position control) and the :class:`ReachController`, and reports:

- ``reach_within_1cm``: share of reachable targets whose final TCP ends within 1 cm of the
  commanded point (the target, or its standoff). A target is reachable when some arm
  configuration puts the TCP on its goal while keeping the controller's clearance margin: the
  controller's own goal check found one (``reachable_by_controller``), or, for a goal the
  controller refused before moving, :func:`audit_goal` found one (``missed_reachable``: the
  controller wrongly gave up; ``infeasible_by_audit``: the audit found none either).
  ``reachable`` (= ``reachable_by_audit``) is this ground-truth denominator, not the
  controller's verdict;
- ``object_within_10cm``: share of object targets whose final TCP is within 10 cm of the
  object's ground-truth box;
- ``contacts``: PyBullet contact points between the robot and the table/objects, counted after
  every physics step of every reach (local control steps and planned trajectories alike);
- ``routes``: how many reaches moved the arm with the local controller alone (``local``), with
  the global planner's fallback (``planned``), or not at all (``none``); ``fallback_share`` is
  the planned share of the reaches that moved, ``fallback_reached`` how many of those reached;
  ``planning_ms_median`` / ``_p95``: wall time of the global planner per fallback;
  ``alternative_goals``: reaches whose goal selection commanded another point than the goal
  (never counted within 1 cm);
- median / 95th percentile of the mink IK step and of the collision check [ms], their sum per
  executed step, and the damped-least-squares reference per iteration (``dls_iter_ms_median``);
- ``goal_search_ms_median`` / ``_p95``: wall time of the controller's pre-motion goal search
  per reach;
- ``reach_s_median`` / ``_p95``: wall time of one whole reach [s] (goal search, motion with
  physics stepping, checks);
- ``reasons``: how many reaches ended with each reason; unreachable and out-of-workspace probes
  must come back with the right reason, never an exception.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from tabletop.arm.collision import CollisionChecker
from tabletop.arm.diffik import MinkDiffIK, top_down_rotation
from tabletop.arm.driver import PyBulletDriver, touching_points
from tabletop.arm.ik import solve_ik
from tabletop.arm.model import ARM_JOINT_NAMES, HOME_Q, PandaModel
from tabletop.arm.obstacles import Box, Cylinder, table_box
from tabletop.arm.reach import GoalChoice, ReachConfig, ReachController, ReachReason
from tabletop.arm.success import reach_success
from tabletop.errors import ConfigError
from tabletop.paths import panda_urdf_path
from tabletop.transforms import make_transform, quat_from_matrix

__all__ = [
    "GoalAudit",
    "audit_goal",
    "audit_reachability",
    "benchmark_targets",
    "cluttered_scene",
    "run_arm_benchmark",
]

log = logging.getLogger(__name__)


def cluttered_scene(rng: np.random.Generator, n_objects: int = 6) -> list[Box | Cylinder]:
    """The table and ``n_objects`` boxes/cylinders on it (x in [0.3, 0.7], |y| <= 0.4)."""
    obs: list[Box | Cylinder] = [table_box()]
    placed: list[tuple[np.ndarray, float]] = []
    tries = 0
    while len(placed) < n_objects and tries < 1000:
        tries += 1
        xy = rng.uniform([0.3, -0.4], [0.7, 0.4])
        h = rng.uniform(0.05, 0.20)
        if rng.random() < 0.5:
            he = np.array([*rng.uniform(0.02, 0.05, 2), h / 2])
            yaw = rng.uniform(-np.pi, np.pi)
            r = float(np.hypot(he[0], he[1]))
            shape = Box(
                [xy[0], xy[1], h / 2],
                he,
                _rz(yaw),
                name=f"box{len(placed)}",
            )
        else:
            r = float(rng.uniform(0.02, 0.045))
            shape = Cylinder([xy[0], xy[1], h / 2], r, h, name=f"cylinder{len(placed)}")
        if any(np.linalg.norm(xy - c) < r + rc + 0.10 for c, rc in placed):
            continue
        placed.append((xy, r))
        obs.append(shape)
    return obs


def benchmark_targets(
    rng: np.random.Generator, objects, n_targets: int
) -> list[tuple[np.ndarray, Box | Cylinder | None]]:
    """The benchmark's targets: (target (3,) [m] world, the object it is the centre of or None).

    Every fourth target is the centre of a random object (inside it: the standoff applies); the
    others are uniform in x in [0.25, 0.75], |y| <= 0.45, z in [0, 0.35] m. Draws from ``rng``
    in the same order as the benchmark always did, so seeded figures are unchanged.
    """
    out: list[tuple[np.ndarray, Box | Cylinder | None]] = []
    for i in range(n_targets):
        if i % 4 == 3 and objects:
            ob = objects[int(rng.integers(len(objects)))]
            out.append((ob.center.copy(), ob))
        else:
            out.append((rng.uniform([0.25, -0.45, 0.0], [0.75, 0.45, 0.35]), None))
    return out


@dataclass(frozen=True)
class GoalAudit:
    """Outcome of :func:`audit_goal`: does a collision-free arm configuration reach a goal?"""

    goal: np.ndarray  # (3,) [m] world, the TCP position asked for
    feasible: bool  # a configuration with the TCP within 1 mm of goal keeps the margin
    q: np.ndarray | None  # (7,) [rad] such a configuration when feasible, else the best found
    best_clearance_m: float  # largest clearance [m] over the converged IK solutions (-inf: none)
    converged: int  # IK solves that put the TCP on the goal
    solves: int  # IK solves run


def audit_goal(
    model: PandaModel,
    checker: CollisionChecker,
    goal: object,
    *,
    margin: float = 0.01,
    q_start: object = HOME_Q,
    n_random: int = 300,
    n_yaw: int = 12,
    climb_starts: int = 3,
    climb_iters: int = 200,
    seed: int = 0,
) -> GoalAudit:
    """Search hard for an arm configuration that puts the TCP on ``goal`` and keeps ``margin``.

    The ground truth behind the benchmark's ``reachable``, independent of the controller's own
    (deliberately cheap) goal check. Seeds: ``q_start``, ``HOME_Q`` and ``n_random`` uniform
    configurations inside the joint limits. From each, position-only damped-least-squares IK
    (the seed as the null-space posture, so solutions stay diverse), then the top-down
    orientation at ``n_yaw`` yaw angles over a full turn. If no solution keeps the margin, a
    clearance climb from the ``climb_starts`` solutions with the largest clearance:
    ``climb_iters`` position-only solves each from perturbed copies (0.3 rad), keeping
    improvements. Stops at the first solution that keeps the margin.

    A negative answer is the outcome of this search, not a proof that none exists.

    Args:
        model: the Panda model.
        checker: the collision checker of the scene (the same obstacles as the controller).
        goal: (3,) [m] world, the TCP position (after any standoff).
        margin: clearance [m] a solution must keep (the controller's ``clearance_margin``).
        q_start: (7,) [rad] the arm's configuration when the reach started.
        n_random, n_yaw, climb_starts, climb_iters: the search budget (see above).
        seed: seed of the random configurations and perturbations.
    """
    goal = np.asarray(goal, dtype=np.float64)
    if goal.shape != (3,) or not np.all(np.isfinite(goal)):
        raise ConfigError(f"goal must be a finite (3,) point [m], got {goal.tolist()}")
    rng = np.random.default_rng(seed)
    seeds = [np.asarray(q_start, dtype=np.float64), np.asarray(HOME_Q)]
    seeds += [model.random_q(rng) for _ in range(n_random)]
    yaws = np.linspace(-np.pi, np.pi, n_yaw, endpoint=False)
    found: list[tuple[float, np.ndarray]] = []  # (clearance, q) of converged solutions
    solves = 0

    def solve(T: np.ndarray, q0: np.ndarray, position_only: bool) -> float:
        """Clearance [m] of the solution from q0 (-inf when IK does not converge)."""
        nonlocal solves
        solves += 1
        res = solve_ik(
            model,
            T,
            q0,
            position_only=position_only,
            tol_pos=1e-3,
            tol_rot=0.05,
            max_iters=60,
            q_posture=q0,
        )
        if not res.success:
            return -np.inf
        found.append((checker.clearance(res.q).distance, res.q))
        return found[-1][0]

    def result() -> GoalAudit:
        if not found:
            return GoalAudit(goal, False, None, -np.inf, 0, solves)
        d, q = max(found, key=lambda f: f[0])
        return GoalAudit(goal, d >= margin, q, float(d), len(found), solves)

    T_pos = make_transform(np.eye(3), goal)
    for q0 in seeds:
        if solve(T_pos, q0, True) >= margin:
            return result()
        for yaw in yaws:
            if solve(make_transform(top_down_rotation(float(yaw)), goal), q0, False) >= margin:
                return result()
    starts = sorted(found, key=lambda f: -f[0])[:climb_starts]
    for d_best, q_best in starts:
        for _ in range(climb_iters):
            d = solve(T_pos, model.clip(q_best + rng.normal(0.0, 0.3, 7)), True)
            if d >= margin:
                return result()
            if d > d_best:
                d_best, q_best = found[-1]
    return result()


def audit_reachability(
    model: PandaModel, checker: CollisionChecker, goals, **kwargs
) -> list[GoalAudit]:
    """:func:`audit_goal` for each (3,) goal [m] of ``goals``; keyword arguments pass through."""
    return [audit_goal(model, checker, g, **kwargs) for g in goals]


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _build_world(obstacles) -> tuple[int, int, list[int]]:
    import pybullet as pb

    cid = pb.connect(pb.DIRECT)
    pb.setGravity(0, 0, -9.81, physicsClientId=cid)
    bodies = []
    for ob in obstacles:
        if isinstance(ob, Box):
            col = pb.createCollisionShape(
                pb.GEOM_BOX, halfExtents=ob.half_extents.tolist(), physicsClientId=cid
            )
            quat = quat_from_matrix(ob.rotation).tolist()
        else:
            col = pb.createCollisionShape(
                pb.GEOM_CYLINDER, radius=ob.radius, height=ob.height, physicsClientId=cid
            )
            quat = [0, 0, 0, 1]
        bodies.append(pb.createMultiBody(0, col, -1, ob.center.tolist(), quat, physicsClientId=cid))
    robot = pb.loadURDF(str(panda_urdf_path()), [0, 0, 0], useFixedBase=True, physicsClientId=cid)
    return cid, robot, bodies


def _percentiles(ts: list[float]) -> tuple[float, float]:
    a = np.asarray(ts) * 1e3
    return (float(np.median(a)), float(np.percentile(a, 95))) if len(a) else (np.nan, np.nan)


def run_arm_benchmark(
    n_targets: int = 200,
    seed: int = 0,
    n_objects: int = 6,
    reach_config: ReachConfig | None = None,
) -> dict:
    """Run the reach benchmark; see the module docstring for the keys of the returned dict."""
    import pybullet as pb

    rng = np.random.default_rng(seed)
    obstacles = cluttered_scene(rng, n_objects)
    objects = obstacles[1:]
    cid, robot, bodies = _build_world(obstacles)
    try:
        model = PandaModel()
        driver = PyBulletDriver(cid, robot, finger_opening=model.finger_opening)
        diffik = MinkDiffIK(model, obstacles)
        checker = CollisionChecker(model, obstacles)
        ctrl = ReachController(
            model, driver, obstacles, reach_config, diffik=diffik, checker=checker
        )
        joint_idx = {
            pb.getJointInfo(robot, j, physicsClientId=cid)[1].decode(): j
            for j in range(pb.getNumJoints(robot, physicsClientId=cid))
        }
        arm = [joint_idx[n] for n in ARM_JOINT_NAMES]

        contacts = 0

        def count_contacts():  # after every physics step, local steps and trajectories alike
            nonlocal contacts
            for b in bodies:
                contacts += touching_points(pb, robot, b, cid)

        driver.on_step = count_contacts

        reasons: dict[str, int] = {}
        reachable = within_1cm = by_controller = missed = infeasible = 0
        audit_checker = None  # built on first use: its timings stay out of the step figures
        audit_s = 0.0
        goal_search, reach_times, planning = [], [], []
        routes: dict[str, int] = {}
        fallback_reached = alternatives = 0
        obj_total = obj_ok = 0
        errors = []
        for i, (target, ob) in enumerate(benchmark_targets(rng, objects, n_targets)):
            for j, v in zip(arm, HOME_Q, strict=True):
                pb.resetJointState(robot, j, float(v), physicsClientId=cid)
            is_object = ob is not None
            t_reach = time.perf_counter()
            res = ctrl.move_to(target)
            reach_times.append(time.perf_counter() - t_reach)
            reasons[res.reason.value] = reasons.get(res.reason.value, 0) + 1
            goal_search.append(res.goal_search_s)
            routes[res.route.value] = routes.get(res.route.value, 0) + 1
            alternatives += res.goal_choice == GoalChoice.ALTERNATIVE
            if res.plan is not None:
                planning.append(res.plan.planning_time_s)
                fallback_reached += res.reached
            refused = res.reason in (ReachReason.UNREACHABLE, ReachReason.BLOCKED) and (
                res.steps == 0 and res.refused_steps == 0
            )
            if res.reason == ReachReason.OUTSIDE_WORKSPACE:
                feasible = False
            elif not refused:  # the controller's goal check found a configuration
                by_controller += 1
                feasible = True
            else:  # refused before moving: does a collision-free configuration exist?
                if audit_checker is None:
                    audit_checker = CollisionChecker(model, obstacles)
                t0 = time.perf_counter()
                audit = audit_goal(
                    model,
                    audit_checker,
                    res.goal,
                    margin=ctrl.config.clearance_margin,
                    q_start=HOME_Q,
                    seed=i,
                )
                audit_s += time.perf_counter() - t0
                feasible = audit.feasible
                missed += feasible
                infeasible += not feasible
                log.info(
                    "target %d: %s before moving, audit %s (best clearance %.4f m)",
                    i,
                    res.reason.value,
                    "feasible" if feasible else "infeasible",
                    audit.best_clearance_m,
                )
            if feasible:
                reachable += 1
                errors.append(res.error_m)
                # A reach to an alternative goal is not within 1 cm of the goal asked for.
                within_1cm += res.error_m <= 0.01 and res.goal_choice != GoalChoice.ALTERNATIVE
            if is_object:
                obj_total += 1
                gt = (
                    ob
                    if isinstance(ob, Box)
                    else Box(ob.center, [ob.radius, ob.radius, ob.height / 2])
                )
                obj_ok += reach_success(res.final_tcp, box=gt).success

        # Probes that must fail with the right reason (never an exception).
        probes_ok = 0
        probes = [
            ([1.5, 0.0, 0.3], ReachReason.OUTSIDE_WORKSPACE),
            ([0.5, 0.0, -0.3], ReachReason.OUTSIDE_WORKSPACE),
            ([0.5, 0.0, 1.2], ReachReason.OUTSIDE_WORKSPACE),
            ([0.8, -0.6, 0.6], ReachReason.UNREACHABLE),
            ([0.8, 0.5, 0.8], ReachReason.UNREACHABLE),
            ([0.8, 0.6, 0.7], ReachReason.UNREACHABLE),
        ]
        for p, want in probes:
            probes_ok += ctrl.move_to(p).reason == want

        # The damped-least-squares reference, per iteration, on the same kind of goals.
        dls_times = []
        for _ in range(100):
            p = rng.uniform([0.3, -0.4, 0.05], [0.7, 0.4, 0.35])
            T = make_transform(top_down_rotation(float(np.arctan2(p[1], p[0]))), p)
            t0 = time.perf_counter()
            r = solve_ik(model, T, HOME_Q)
            if r.iterations:
                dls_times.append((time.perf_counter() - t0) / r.iterations)

        ik_med, ik_p95 = _percentiles(diffik.timings_s)
        cc_med, cc_p95 = _percentiles(checker.timings_s)
        dls_med, _ = _percentiles(dls_times)
        gs_med, gs_p95 = _percentiles(goal_search)
        pl_med, pl_p95 = _percentiles(planning)
        moved = routes.get("local", 0) + routes.get("planned", 0)
        return {
            "n_targets": n_targets,
            "seed": seed,
            "n_objects": len(objects),
            "reachable": reachable,
            "reachable_by_audit": reachable,
            "reachable_by_controller": by_controller,
            "missed_reachable": missed,
            "infeasible_by_audit": infeasible,
            "audit_s": audit_s,
            "reach_within_1cm": within_1cm / reachable if reachable else float("nan"),
            "reach_error_m_median": float(np.median(errors)) if errors else float("nan"),
            "object_targets": obj_total,
            "object_within_10cm": obj_ok / obj_total if obj_total else float("nan"),
            "contacts": contacts,
            "reasons": reasons,
            "probes_right_reason": f"{probes_ok}/{len(probes)}",
            "ik_step_ms_median": ik_med,
            "ik_step_ms_p95": ik_p95,
            "collision_check_ms_median": cc_med,
            "collision_check_ms_p95": cc_p95,
            "ik_plus_collision_ms_median": ik_med + cc_med,
            "dls_iter_ms_median": dls_med,
            "mink_over_dls_ratio": ik_med / dls_med if dls_med else float("nan"),
            "goal_search_ms_median": gs_med,
            "goal_search_ms_p95": gs_p95,
            "routes": routes,
            "fallback_share": len(planning) / moved if moved else float("nan"),
            "fallback_reached": fallback_reached,
            "alternative_goals": alternatives,
            "planning_ms_median": pl_med,
            "planning_ms_p95": pl_p95,
            "physics_steps": driver.steps,
            "reach_s_median": float(np.median(reach_times)) if reach_times else float("nan"),
            "reach_s_p95": float(np.percentile(reach_times, 95)) if reach_times else float("nan"),
        }
    finally:
        pb.disconnect(cid)
