"""Run task files: scan (or reuse a cached scan), build (or reuse) the map, query through the
robot API, reach in simulation with :class:`~tabletop.robot.SimArm`, score against the truth.

```python
from tabletop.eval import run_eval

result = run_eval("demo", encoders="oracle", out_dir="out/eval")
print(result.to_markdown())       # the table; result.report_path is the written report
```

The cache (``cache_dir``, default ``out/eval-cache``) holds one recording per scene + scan
settings and one map per recording + encoder set + map settings; the keys include a
fingerprint of the simulator and mapping source, so editing either invalidates old entries.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from tabletop.arm.success import SUCCESS_RADIUS_M
from tabletop.errors import ConfigError, GoalNotFound, TabletopError
from tabletop.eval.harness import (
    DEFAULT_CACHE_DIR,
    cached_map,
    cached_recording,
    map_config,
    recording_key,
    scan_recording,
)
from tabletop.eval.results import EncoderRun, GoalResult, TaskRun
from tabletop.eval.tasks import Goal, Landmark, TaskFile, TaskFileError, load_tasks
from tabletop.eval.truth import Region, check_absent, resolve_truth
from tabletop.sim.ground_truth import GroundTruth

__all__ = [
    "DEFAULT_CACHE_DIR",
    "collect_task_files",
    "evaluate_task_file",
    "run_eval",
    "scan_recording",
]

log = logging.getLogger(__name__)

Progress = Callable[[str, int, int], None]
"""``progress(stage, done, total)``: stage is "scan <name>", "map <name>" or "goals <name>"."""


# ---------------------------------------------------------------------------- task files
def collect_task_files(items: str | Path | TaskFile | Iterable) -> list[TaskFile]:
    """Task files from paths, directories (every .toml/.json inside, sorted), shipped names
    ("demo", or "default" for the directory of default suites), or parsed :class:`TaskFile`s."""
    from tabletop.eval.tasks import _tasks_dir, list_shipped_tasks

    if isinstance(items, (str, Path, TaskFile)):
        items = [items]
    out: list[TaskFile] = []
    for it in items:
        if isinstance(it, TaskFile):
            out.append(it)
            continue
        p = Path(it)
        if not p.exists() and p.suffix == "" and (_tasks_dir() / p.name).is_dir():
            p = _tasks_dir() / p.name
        if p.is_dir():
            files = sorted([*p.glob("*.toml"), *p.glob("*.json")])
            if not files:
                raise TaskFileError(f"directory {p} holds no task files (.toml, .json)")
            out += [load_tasks(f) for f in files]
        elif p.exists() or p.suffix:
            out.append(load_tasks(p))
        else:
            d = _tasks_dir()
            dirs = sorted(x.name for x in d.iterdir() if x.is_dir()) if d.is_dir() else []
            shipped = list_shipped_tasks()
            if p.name not in shipped:
                raise TaskFileError(
                    f"no task file {str(p)!r}; shipped suites: {shipped}, shipped directories: "
                    f"{dirs}, or give a path to a .toml/.json task file"
                )
            out.append(load_tasks(p))
    if not out:
        raise TaskFileError("no task files given")
    return out


# ---------------------------------------------------------------------------- instructions
# ---------------------------------------------------------------------------- goals
class _Context:
    """What one task file's goals run against: the robot, the map, the scene and truth."""

    def __init__(self, robot, avlmap, spec, rec) -> None:
        self.robot = robot
        self.map = avlmap
        self.spec = spec
        self.rec = rec
        self.gt = GroundTruth.of(rec)
        self._world = None
        self.images: dict[str, np.ndarray] = {}  # goal id -> rendered query image
        self.heatmaps: dict[str, list] = {}  # goal id -> [(label, values)], for the report
        self.keep_heatmaps: set[str] = set()

    def image(self, goal_id: str, view) -> np.ndarray:
        from tabletop.eval.images import render_view

        if self._world is None:
            from tabletop.sim.camera import WristCameraConfig
            from tabletop.sim.world import SimWorld

            renderer = (self.rec.meta or {}).get("renderer", "auto")
            h, w = self.rec.rgb.shape[1:3]
            self._world = SimWorld(self.spec, WristCameraConfig(width=w, height=h), renderer)
        rgb = render_view(self._world, view)
        self.images.setdefault(goal_id, rgb)
        return rgb

    def close(self) -> None:
        if self._world is not None:
            self._world.close()


def _parts(ctx: _Context, goal_id: str, lm: Landmark) -> dict:
    return {k: ctx.image(goal_id, v) if k == "img" else v for k, v in lm.parts}


def _landmark(ctx: _Context, goal: Goal, lm: Landmark, tag: str):
    """A spatial relation's landmark for the robot API: an object name, or the (fused) major
    map of a query landmark."""
    if len(lm.parts) == 1 and lm.primary == "obj":
        return lm.as_dict["obj"]
    return _query_heatmap(ctx, goal, lm, tag)


def _query_heatmap(ctx: _Context, goal: Goal, lm: Landmark, tag: str = ""):
    """The landmark's (fused) major map, through the robot API (kept for the report)."""
    robot = ctx.robot
    heat = robot.get_major_map(**_parts(ctx, goal.id, lm), primary=lm.primary)
    if goal.id in ctx.keep_heatmaps:
        names = [k for k, _ in lm.parts]
        for k, h in zip(names, robot.last_heatmaps, strict=False):
            role = "primary" if k == lm.primary else "auxiliary"
            ctx.heatmaps.setdefault(goal.id, []).append((f"{tag}{role} {k}", h.values))
        if len(lm.parts) > 1:
            ctx.heatmaps[goal.id].append((f"{tag}fused", heat.values))
    return heat


def _move(ctx: _Context, goal: Goal):
    """(target, reach result) of a query or spatial goal, through the public robot API only:
    ``move_to(get_max_pos_3d(get_major_map(...)))``, or ``move_to(<relation>(*landmarks))``
    with object names or query heatmaps as landmarks. Every relation of a task file
    (:data:`~tabletop.eval.tasks.RELATIONS`) is the robot API's target primitive of that name,
    and ``move_to`` of its target is what the matching motion primitive (``move_to_left``,
    ``move_in_between``, ...) does: the target is computed once."""
    robot = ctx.robot
    if not goal.landmarks:
        target = robot.get_max_pos_3d(_query_heatmap(ctx, goal, goal.query))
        return target, robot.move_to(target)
    marks = [_landmark(ctx, goal, m, f"landmark {i + 1} ") for i, m in enumerate(goal.landmarks)]
    target = getattr(robot, goal.relation)(*marks)
    return target, robot.move_to(target)


def _reach_fields(robot, res) -> dict:
    """The reach's route, planning time and, when it ended short of its goal (blocked,
    unreachable, no progress, timeout), whether the audit finds a configuration that puts the
    TCP on that goal with the controller's clearance margin
    (:func:`tabletop.arm.bench.audit_goal`, from where the arm stands)."""
    if res is None:
        return {}
    out = {
        "route": res.route.value,
        "planning_s": None if res.plan is None else float(res.plan.planning_time_s),
    }
    if not res.reached and res.reason.value != "outside_workspace":
        from tabletop.arm.bench import audit_goal

        ctrl = robot.controller
        audit = audit_goal(
            ctrl.model,
            ctrl.checker,
            res.goal,
            margin=ctrl.config.clearance_margin,
            q_start=robot.driver.read_state().q,
        )
        out["audit"] = "feasible" if audit.feasible else "infeasible"
    return out


def _run_goal(ctx: _Context, goal: Goal, sequence: str, region: Region) -> GoalResult:
    from tabletop.robot.api import ImageGoalUnavailable

    robot = ctx.robot
    base = dict(
        goal_id=goal.id,
        type=goal.type,
        text=goal.text,
        sequence=sequence,
        truth=region.to_json(),
    )
    t0 = time.perf_counter()
    if goal.type == "instruction":
        return _run_code(ctx, goal, base, region, t0)
    if goal.type == "absent":
        return _run_absent(ctx, goal, base, t0)
    try:
        target, res = _move(ctx, goal)
    except ImageGoalUnavailable as e:
        return GoalResult(**base, status="unavailable", reason=f"image goals unavailable: {e}")
    except TabletopError as e:  # not found, or a query the map or the API refuses
        tcp = robot.current_position()
        return GoalResult(
            **base,
            status="not_found" if isinstance(e, GoalNotFound) else "failed",
            reason=str(e) if isinstance(e, GoalNotFound) else f"{type(e).__name__}: {e}",
            tcp=tuple(tcp),
            error_m=region.distance(tcp),
            time_s=time.perf_counter() - t0,
        )
    target = np.asarray(target, np.float64)
    tcp = np.asarray(res.final_tcp, np.float64)
    err = region.distance(tcp)
    return GoalResult(
        **base,
        status="done",
        reason="" if res.reached else f"reach ended: {res.reason.value}",
        target=tuple(target),
        target_error_m=region.distance(target),
        tcp=tuple(tcp),
        error_m=err,
        success=err <= SUCCESS_RADIUS_M,
        reach=res.reason.value,
        contacts=int(robot.contacts[-1]),
        time_s=time.perf_counter() - t0,
        **_reach_fields(robot, res),
    )


def _run_absent(ctx: _Context, goal: Goal, base: dict, t0: float) -> GoalResult:
    """An absent goal succeeds when the robot API finds nothing (:class:`GoalNotFound`): then
    nothing moves. A target the map returns is a false positive: the robot goes there, as
    ``move_to(get_max_pos_3d(get_major_map(...)))`` would, and the goal fails with the target
    and the final TCP in the result. A query the map or the API refuses otherwise is a failure."""
    robot = ctx.robot
    try:
        target = np.asarray(robot.get_max_pos_3d(_query_heatmap(ctx, goal, goal.query)))
    except GoalNotFound as e:
        return GoalResult(
            **base,
            status="not_found",
            reason=str(e),
            success=True,
            tcp=tuple(robot.current_position()),
            time_s=time.perf_counter() - t0,
        )
    except TabletopError as e:
        return GoalResult(
            **base,
            status="failed",
            reason=f"{type(e).__name__}: {e}",
            tcp=tuple(robot.current_position()),
            time_s=time.perf_counter() - t0,
        )
    found = f"found at {np.round(target, 3).tolist()} (a false positive)"
    try:
        res = robot.move_to(target)
    except TabletopError as e:
        return GoalResult(
            **base,
            status="failed",
            reason=f"{found}; the reach failed: {type(e).__name__}: {e}",
            target=tuple(target),
            tcp=tuple(robot.current_position()),
            time_s=time.perf_counter() - t0,
        )
    return GoalResult(
        **base,
        status="done",
        reason=found,
        target=tuple(target),
        tcp=tuple(np.asarray(res.final_tcp, np.float64)),
        reach=res.reason.value,
        contacts=int(robot.contacts[-1]),
        time_s=time.perf_counter() - t0,
    )


def _run_code(ctx: _Context, goal: Goal, base: dict, region: Region, t0: float):
    """Parse an instruction, run its code in the sandbox against the robot, score the TCP
    after the last motion. A parse error or rejected code is a failure (nothing moves)."""

    from tabletop.language import instruction_to_code, run_instruction

    robot = ctx.robot
    moves_before = len(robot.history)
    code = ""
    try:
        code = str(instruction_to_code(goal.instruction))
        run = run_instruction(goal.instruction, robot, code=code)
    except TabletopError as e:  # a parse error, rejected code, not found, a refused query
        tcp = robot.current_position()
        return GoalResult(
            **base,
            status="not_found" if isinstance(e, GoalNotFound) else "failed",
            reason=f"{type(e).__name__}: {e}",
            tcp=tuple(tcp),
            error_m=region.distance(tcp),
            contacts=int(sum(robot.contacts[moves_before:])),
            time_s=time.perf_counter() - t0,
            code=code,
        )
    tcp = robot.current_position()
    err = region.distance(tcp)
    last = run.motions[-1] if run.motions else None
    target = None if last is None else np.asarray(last.target, np.float64)
    res = None if last is None else last.result
    return GoalResult(
        **base,
        status="done",
        reason="" if res is not None and res.reached else "the code's last motion fell short",
        target=None if target is None else tuple(target),
        target_error_m=None if target is None else region.distance(target),
        tcp=tuple(tcp),
        error_m=err,
        success=err <= SUCCESS_RADIUS_M,
        reach="" if res is None else res.reason.value,
        contacts=int(sum(robot.contacts[moves_before:])),
        time_s=time.perf_counter() - t0,
        code=code,
        **_reach_fields(robot, res),
    )


def _heatmap_goals(tf: TaskFile, per_type: int = 1) -> set[str]:
    """Goals whose heatmaps the report shows: the first of each query type (ambiguous first)."""
    out: list[str] = []
    for t in ("ambiguous", "multimodal_spatial", "object", "sound", "image", "area"):
        out += [g.id for g in tf.goals if g.type == t][:per_type]
    return set(out)


def evaluate_task_file(
    tf: TaskFile,
    encoders: str,
    *,
    cache_dir: Path | None = DEFAULT_CACHE_DIR,
    figures_dir: Path | None = None,
    progress: Progress | None = None,
    map_overrides: dict | None = None,
    scan_overrides: dict | None = None,
    noise: dict | None = None,
) -> TaskRun:
    """Scan (or reuse), map (or reuse), run every goal of ``tf`` with the encoder set
    ``encoders``; write the figures into ``figures_dir`` when given. ``map_overrides``: map
    config fields that replace the task file's ``[map]`` ones (an ablation, e.g.
    ``{"object": {"instances": False}}``); ``scan_overrides``: scan settings that replace the
    task file's ``[scan]`` ones (e.g. ``{"snr_db": 5.0}``: the same scan, sounds 10 dB
    quieter); ``noise``: :class:`~tabletop.sim.noise.NoiseConfig` fields that replace the task
    file's ``[noise]`` ones (the clean scan is taken from the cache and the noise applied to
    it, so a noisy run costs a map, not a scan)."""
    from tabletop.robot import SimArm
    from tabletop.sim.noise import NoiseConfig, apply_noise

    spec = tf.scene.load()
    cache = Path(cache_dir) if cache_dir is not None else None
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
    settings = {**dict(tf.map), **dict(map_overrides or {})}
    try:  # a bad [map] value fails before the scan, not after it
        map_config(**settings)
    except (TypeError, TabletopError) as e:
        raise TaskFileError(f"{tf.path or tf.name} [map]: {e}") from None
    scan = {**dict(tf.scan), **dict(scan_overrides or {})}
    try:
        sensor = NoiseConfig.from_dict({**dict(tf.noise), **dict(noise or {})})
    except ConfigError as e:
        raise TaskFileError(f"{tf.path or tf.name} [noise]: {e}") from None
    rec, scan_s, rec_cached = cached_recording(tf.name, scan, spec, cache, progress)
    rec_key = recording_key(spec, scan, sensor.to_dict() if sensor.any else None)
    if sensor.any:
        rec = apply_noise(rec, sensor)
    m, map_s, map_cached = cached_map(tf.name, settings, rec, encoders, cache, rec_key, progress)
    # Resolve every truth before anything moves: a wrong reference is a task-file error.
    where = str(tf.path or tf.name)
    truth = GroundTruth.of(rec)
    regions = {
        g.id: resolve_truth(g.truth, truth, f"{where} goal {g.id!r} truth") for g in tf.goals
    }
    for g in tf.goals:
        if g.type == "absent":
            check_absent(g.query, truth, f"{where} goal {g.id!r}")
    robot = SimArm(m, spec)
    ctx = _Context(robot, m, spec, rec)
    if figures_dir is not None:
        ctx.keep_heatmaps = _heatmap_goals(tf)
    results: list[GoalResult] = []
    try:
        runs = tf.runs()
        done = 0
        for seq_id, goals in runs:
            robot.reset()
            for g in goals:
                results.append(_run_goal(ctx, g, seq_id, regions[g.id]))
                done += 1
                if progress:
                    progress(f"goals {tf.name}", done, len(tf.goals))
        run = TaskRun(
            task_name=tf.name,
            task_path=str(tf.path or tf.name),
            scene=spec.name,
            goals=results,
            scan_s=scan_s,
            map_s=map_s,
            cached=rec_cached and map_cached,
            encoder_names=dict(m.encoder_names),
            noise=sensor.to_dict() if sensor.any else {},
        )
        if figures_dir is not None:
            from tabletop.eval.report import write_task_figures

            run.figures = write_task_figures(
                figures_dir, tf, encoders, m, truth, results, regions, ctx
            )
    finally:
        ctx.close()
        robot.close()
    return run


def _check_encoder_set(name: str) -> str:
    """'' when the encoder set can be built here, else the reason it cannot."""
    from tabletop.mapping.encoders.registry import ENCODER_SETS, make_encoders

    if name not in ENCODER_SETS:
        raise ConfigError(f"unknown encoder set {name!r}; valid: {list(ENCODER_SETS)}")
    if name == "oracle":
        return ""
    try:
        make_encoders(name)
    except TabletopError as e:  # not wired yet, weights missing, an optional extra absent
        return f"{type(e).__name__}: {e}"
    return ""


def run_eval(
    tasks,
    encoders: str | Sequence[str] = "oracle",
    out_dir: str | Path | None = None,
    progress: Progress | None = None,
    cache_dir: str | Path | None = DEFAULT_CACHE_DIR,
    map_overrides: dict | None = None,
    scan_overrides: dict | None = None,
    noise: dict | None = None,
):
    """Evaluate task files (paths, directories, shipped names or :class:`TaskFile`s) with one
    or more encoder sets; write the report into ``out_dir`` when given. ``map_overrides``,
    ``scan_overrides``, ``noise``: see :func:`evaluate_task_file`. ``progress`` is called
    as ``progress(stage, done, total)`` (see :data:`Progress`); None reports nothing.

    An encoder set that cannot be built here is a row marked unavailable with the reason (no
    scan is wasted on it). Returns an :class:`~tabletop.eval.report.EvalResult`.
    """
    from tabletop.eval.report import EvalResult

    files = collect_task_files(tasks)
    names = [encoders] if isinstance(encoders, str) else list(encoders)
    if not names:
        raise ConfigError("give at least one encoder set")
    cb: Progress | None = progress or None
    out = Path(out_dir) if out_dir is not None else None
    runs = []
    for name in names:
        t0 = time.perf_counter()
        reason = _check_encoder_set(name)
        if reason:
            runs.append(EncoderRun(name, {}, False, reason))
            continue
        er = EncoderRun(name, {}, True)
        for tf in files:
            fig = out / "figures" / name / _slug(tf.name) if out is not None else None
            tr = evaluate_task_file(
                tf,
                name,
                cache_dir=cache_dir,
                figures_dir=fig,
                progress=cb,
                map_overrides=map_overrides,
                scan_overrides=scan_overrides,
                noise=noise,
            )
            er.tasks.append(tr)
        er.encoder_names = dict(er.tasks[0].encoder_names)
        er.wall_s = time.perf_counter() - t0
        runs.append(er)
    result = EvalResult([str(f.path or f.name) for f in files], runs, out)
    if out is not None:
        result.write(out)
    return result


def _slug(s: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in s).strip("-") or "tasks"
