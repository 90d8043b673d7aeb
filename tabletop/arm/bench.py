"""The arm benchmark: seeded reach targets in a cluttered PyBullet scene.

``run_arm_benchmark`` builds its own PyBullet DIRECT world (a table slab, a handful of boxes and
cylinders, the Panda under gravity), drives it with :class:`PyBulletDriver` (physics stepping,
position control) and the :class:`ReachController`, and reports:

- ``reach_within_1cm``: share of reachable targets (the controller's reachability check passed)
  whose final TCP ends within 1 cm of the commanded point (the target, or its standoff);
- ``object_within_10cm``: share of object targets whose final TCP is within 10 cm of the
  object's ground-truth box;
- ``contacts``: PyBullet contact points between the robot and the table/objects, counted over
  every control step of every reach;
- median / 95th percentile of the mink IK step and of the collision check [ms], their sum per
  executed step, and the damped-least-squares reference per iteration (``dls_iter_ms_median``);
- ``reasons``: how many reaches ended with each reason; unreachable and out-of-workspace probes
  must come back with the right reason, never an exception.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from tabletop.arm.collision import CollisionChecker
from tabletop.arm.diffik import MinkDiffIK, top_down_rotation
from tabletop.arm.driver import PyBulletDriver
from tabletop.arm.ik import solve_ik
from tabletop.arm.model import ARM_JOINT_NAMES, HOME_Q, PandaModel
from tabletop.arm.obstacles import Box, Cylinder, table_box
from tabletop.arm.reach import ReachController, ReachReason
from tabletop.arm.success import reach_success
from tabletop.paths import panda_urdf_path
from tabletop.transforms import make_transform, quat_from_matrix

__all__ = ["cluttered_scene", "run_arm_benchmark"]

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


def run_arm_benchmark(n_targets: int = 200, seed: int = 0, n_objects: int = 6) -> dict:
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
        ctrl = ReachController(model, driver, obstacles, diffik=diffik, checker=checker)
        joint_idx = {
            pb.getJointInfo(robot, j, physicsClientId=cid)[1].decode(): j
            for j in range(pb.getNumJoints(robot, physicsClientId=cid))
        }
        arm = [joint_idx[n] for n in ARM_JOINT_NAMES]

        contacts = 0
        orig_command = driver.command_positions

        def counted(q, duration):  # count contacts after every executed control step
            nonlocal contacts
            orig_command(q, duration)
            for b in bodies:
                contacts += len(pb.getContactPoints(robot, b, physicsClientId=cid))

        driver.command_positions = counted

        reasons: dict[str, int] = {}
        reachable = within_1cm = 0
        obj_total = obj_ok = 0
        errors = []
        for i in range(n_targets):
            for j, v in zip(arm, HOME_Q, strict=True):
                pb.resetJointState(robot, j, float(v), physicsClientId=cid)
            is_object = i % 4 == 3 and objects
            if is_object:
                ob = objects[int(rng.integers(len(objects)))]
                target = ob.center.copy()
            else:
                target = rng.uniform([0.25, -0.45, 0.0], [0.75, 0.45, 0.35])
            res = ctrl.move_to(target)
            reasons[res.reason.value] = reasons.get(res.reason.value, 0) + 1
            if res.reason not in (ReachReason.UNREACHABLE, ReachReason.OUTSIDE_WORKSPACE) and not (
                res.reason == ReachReason.BLOCKED and res.steps == 0
            ):
                reachable += 1
                errors.append(res.error_m)
                within_1cm += res.error_m <= 0.01
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
        return {
            "n_targets": n_targets,
            "seed": seed,
            "n_objects": len(objects),
            "reachable": reachable,
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
            "physics_steps": driver.steps,
        }
    finally:
        pb.disconnect(cid)
