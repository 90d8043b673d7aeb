"""Measure the reach controller's global planner against OMPL's RRT-Connect on the same problems.

The problems are the ones the arm benchmark's fallback meets: the benchmark runs as usual
(``run_arm_benchmark``) and every call of :meth:`JointPlanner.plan` is recorded (start and goal
configuration, and the planner itself, which carries the scene's :class:`CollisionChecker`, the
margin and the limits). Each problem is then planned ``--runs`` times by:

- ``ours``: :class:`JointPlanner` as the controller configures it (seed = run index);
- ``ompl-rrtc-certified``: OMPL's ``RRTConnect`` (range = our step), state validity = the
  checker's clearance keeps the margin, motion validity = our certified
  :meth:`JointPlanner.segment_clearance` (the same edge check as ours), then OMPL's own
  ``simplifySolution``;
- ``ompl-rrtc-discrete``: the same, but OMPL's default motion validator (states sampled along
  the edge at OMPL's default resolution, 1 % of the space's extent); its paths are then checked
  with our certified edge check, and ``certified`` says how many would pass the controller.

``RRTConnect`` is also what OMPL's ``SimpleSetup`` picks by default for this kind of problem
(a geometric space, a single goal state). Both planners sample inside ``PANDA_LIMITS``.

OMPL is not a dependency of the project: install it somewhere apart and put it on the path for
this measurement only, e.g.::

    pip install --target /tmp/ompl-site ompl
    OMP_NUM_THREADS=1 PYTHONPATH=.:/tmp/ompl-site python tools/measure_planners.py

Reports per planner: success rate, planning time (search and simplification, wall) median /
p95, joint-space path length [rad] median, and per problem the same figures.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import os
import sys
import time

import numpy as np

from tabletop.arm import planner as planner_mod
from tabletop.arm.bench import run_arm_benchmark
from tabletop.arm.planner import JointPlanner


def capture_problems(seeds: list[int], n_targets: int) -> list[tuple[str, JointPlanner, tuple]]:
    """Run the benchmark for each seed; (label, planner, (q_start, q_goal)) of every fallback."""
    problems: list[tuple[str, JointPlanner, tuple]] = []
    orig = JointPlanner.plan
    current = {"seed": 0}

    def recording_plan(self, q_start, q_goal):
        n = sum(p[0].startswith(f"s{current['seed']}/") for p in problems)
        problems.append(
            (
                f"s{current['seed']}/{n}",
                self,
                (np.array(q_start, dtype=float), np.array(q_goal, dtype=float)),
            )
        )
        return orig(self, q_start, q_goal)

    planner_mod.JointPlanner.plan = recording_plan
    try:
        for s in seeds:
            current["seed"] = s
            t0 = time.perf_counter()
            r = run_arm_benchmark(n_targets=n_targets, seed=s)
            print(
                f"benchmark seed {s}: routes {r['routes']}, planning median/p95 "
                f"{r['planning_ms_median']:.1f}/{r['planning_ms_p95']:.1f} ms "
                f"({time.perf_counter() - t0:.0f} s)",
                flush=True,
            )
    finally:
        planner_mod.JointPlanner.plan = orig
    return problems


def path_length(path: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def certified(jp: JointPlanner, path: np.ndarray) -> bool:
    m = jp.config.margin
    return all(jp.segment_clearance(a, b) >= m for a, b in itertools.pairwise(path))


def run_ours(jp: JointPlanner, qs, qg, run: int) -> dict:
    p = JointPlanner(jp.model, jp.checker, dataclasses.replace(jp.config, seed=run), jp.limits)
    spent = {"simplify": 0.0}

    def timed(method):
        def wrapper(*a):
            t0 = time.perf_counter()
            try:
                return method(*a)
            finally:
                spent["simplify"] += time.perf_counter() - t0

        return wrapper

    # The search is the time outside the shortcuts and the final clearance of the path.
    p._shortcut = timed(p._shortcut)
    p._path_clearance = timed(p._path_clearance)
    r = p.plan(qs, qg)
    return {
        "ok": r.ok,
        "time_s": r.planning_time_s,
        "length": path_length(r.path) if r.ok else np.nan,
        "waypoints": len(r.path) if r.ok else 0,
        "certified": r.ok,  # every edge certified by construction
        "search_s": r.planning_time_s - spent["simplify"],
        "simplify_s": spent["simplify"],
    }


def make_ompl_runner(certified_edges: bool):
    from ompl import base as ob
    from ompl import geometric as og

    class CertifiedMotion(ob.MotionValidator):
        """OMPL motion validity = our certified edge check."""

        def __init__(self, si, jp: JointPlanner) -> None:
            super().__init__(si)
            self.jp = jp

        def checkMotion(self, a, b) -> bool:
            qa = np.array([a[i] for i in range(7)])
            qb = np.array([b[i] for i in range(7)])
            return self.jp.segment_clearance(qa, qb) >= self.jp.config.margin

    def run_ompl(jp: JointPlanner, qs, qg, run: int) -> dict:
        cfg = jp.config
        t0 = time.perf_counter()
        space = ob.RealVectorStateSpace(7)
        bounds = ob.RealVectorBounds(7)
        for i in range(7):
            bounds.setLow(i, float(jp.limits.q_lower[i]))
            bounds.setHigh(i, float(jp.limits.q_upper[i]))
        space.setBounds(bounds)
        ss = og.SimpleSetup(space)

        def valid(state) -> bool:
            q = np.array([state[i] for i in range(7)])
            return jp.checker.clearance(q).distance >= cfg.margin

        ss.setStateValidityChecker(valid)
        si = ss.getSpaceInformation()
        mv = None
        if certified_edges:
            mv = CertifiedMotion(si, jp)
            si.setMotionValidator(mv)
        start, goal = space.allocState(), space.allocState()
        for i in range(7):
            start[i], goal[i] = float(qs[i]), float(qg[i])
        ss.setStartAndGoalStates(start, goal)
        planner = og.RRTConnect(si)
        planner.setRange(cfg.step)
        ss.setPlanner(planner)
        status = ss.solve(cfg.max_time_s)
        ok = bool(ss.haveExactSolutionPath())
        length, n, cert = np.nan, 0, False
        if ok:
            ss.simplifySolution()
            p = ss.getSolutionPath()
            n = p.getStateCount()
            path = np.array([[p.getState(k)[i] for i in range(7)] for k in range(n)])
        dt = time.perf_counter() - t0
        if ok:
            length = path_length(path)
            cert = certified(jp, path)
        del mv, status
        return {
            "ok": ok,
            "time_s": dt,
            "length": length,
            "waypoints": n,
            "certified": cert,
            "search_s": ss.getLastPlanComputationTime(),
            "simplify_s": ss.getLastSimplificationTime() if ok else 0.0,
        }

    return run_ompl


def summary(rows: list[dict]) -> dict:
    t = np.array([r["time_s"] for r in rows]) * 1e3
    lengths = np.array([r["length"] for r in rows if r["ok"]])
    return {
        "runs": len(rows),
        "success": sum(r["ok"] for r in rows) / len(rows),
        "certified": sum(r["certified"] for r in rows) / len(rows),
        "time_ms_median": float(np.median(t)),
        "time_ms_p95": float(np.percentile(t, 95)),
        "length_rad_median": float(np.median(lengths)) if len(lengths) else np.nan,
        "search_ms_median": float(np.median([r["search_s"] for r in rows]) * 1e3),
        "simplify_ms_median": float(np.median([r["simplify_s"] for r in rows]) * 1e3),
        "length_rad_mean": float(np.mean(lengths)) if len(lengths) else np.nan,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0], help="benchmark seeds")
    ap.add_argument("--targets", type=int, default=200, help="benchmark targets per seed")
    ap.add_argument("--runs", type=int, default=5, help="runs per problem and planner")
    ap.add_argument("--json", help="write all rows and summaries here")
    args = ap.parse_args(argv)

    problems = capture_problems(args.seeds, args.targets)
    print(f"{len(problems)} fallback problems", flush=True)
    planners = {"ours": run_ours}
    try:
        from ompl import util as ou

        ou.setLogLevel(ou.LOG_WARN)
        ou.RNG.setSeed(1)  # OMPL seeds once per process: the whole measurement is reproducible
        planners["ompl-rrtc-certified"] = make_ompl_runner(True)
        planners["ompl-rrtc-discrete"] = make_ompl_runner(False)
    except ImportError:
        print("ompl is not importable: measuring ours only", file=sys.stderr)

    rows: dict[str, list[dict]] = {name: [] for name in planners}
    for label, jp, (qs, qg) in problems:
        straight = jp.segment_clearance(qs, qg) >= jp.config.margin
        line = [f"{label:6s} straight {'yes' if straight else 'no '}"]
        for name, fn in planners.items():
            rs = [
                fn(jp, qs, qg, k) | {"problem": label, "straight": straight}
                for k in range(args.runs)
            ]
            rows[name] += rs
            s = summary(rs)
            line.append(
                f"{name} {s['success']:.0%} {s['time_ms_median']:.1f}/{s['time_ms_p95']:.1f} ms "
                f"L {s['length_rad_median']:.2f} cert {s['certified']:.0%}"
            )
        print(" | ".join(line), flush=True)

    out: dict[str, dict] = {}
    subsets = {
        "all problems": lambda r: True,
        "problems needing a search (straight segment blocked)": lambda r: not r["straight"],
    }
    for title, keep in subsets.items():
        print(
            f"\n{title}\nplanner | success | certified | planning median / p95 [ms] "
            "| search / simplify median [ms] | path length median / mean [rad]"
        )
        for name, rs in rows.items():
            rs = [r for r in rs if keep(r)]
            if not rs:
                continue
            s = out.setdefault(title, {})[name] = summary(rs)
            print(
                f"{name} | {s['success']:.0%} | {s['certified']:.0%} | "
                f"{s['time_ms_median']:.1f} / {s['time_ms_p95']:.1f} | "
                f"{s['search_ms_median']:.1f} / {s['simplify_ms_median']:.1f} | "
                f"{s['length_rad_median']:.2f} / {s['length_rad_mean']:.2f}"
            )
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"summary": out, "rows": rows}, f, indent=1, default=float)
    sys.stdout.flush()
    if len(planners) > 1:
        os._exit(0)  # skip OMPL's binding teardown (nanobind reports its leaks at exit)
    return 0


if __name__ == "__main__":
    sys.exit(main())
