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
    cached_map_path,
    cached_recording,
    cached_recording_path,
    map_config,
    recording_key,
    scan_recording,
)
from tabletop.eval.results import EncoderRun, GoalResult, TaskRun
from tabletop.eval.tasks import Goal, Landmark, TaskFile, TaskFileError, load_tasks
from tabletop.eval.truth import Region, check_absent, resolve_truth
from tabletop.reader.reading import DEFAULT_READER, get_reader
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
"""``progress(stage, done, total)``: stage is "scan <name>", "map <name>" or "goals <name>";
with workers or Ray (:func:`run_eval`'s ``workers``, ``ray``) "units", one step per unit of
work (an encoder set x a task file) as it finishes, and a line on each through the callback's
``note(text)`` method when it has one (:class:`tabletop.cli.progress.ProgressBars` does)."""


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
    seen: set[Path] = set()
    for tf in out:  # a file given twice (by name and by path, or in a directory) runs twice
        if tf.path is not None:
            key = Path(tf.path).resolve()
            if key in seen:
                raise TaskFileError(
                    f"the task file {str(tf.path)!r} is given twice; give each task file once"
                )
            seen.add(key)
    return out


# ---------------------------------------------------------------------------- instructions
# ---------------------------------------------------------------------------- goals
class _Context:
    """What one task file's goals run against: the robot, the map, the scene and truth."""

    def __init__(
        self, robot, avlmap, spec, rec, radius: float = SUCCESS_RADIUS_M, world=None
    ) -> None:
        self.robot = robot
        self.map = avlmap
        self.spec = spec
        self.rec = rec
        self.gt = GroundTruth.of(rec)
        self.radius = radius
        """Success radius [m]."""
        self.on_floor = world is not None
        """A mobile base in a room: distances are measured on the floor (x, y)."""
        self._world = world  # renders image goals (a room's world is the robot's own)
        self._own_world = world is None
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
        if self._world is not None and self._own_world:
            self._world.close()

    def distance(self, region: Region, p) -> float:
        """[m] from a final position to the goal's region (on the floor for a base)."""
        return region.distance_xy(p) if self.on_floor else region.distance(p)


def _final(res) -> np.ndarray:
    """(3,) [m] where a motion ended: the arm's TCP, a base's centre on the floor."""
    p = getattr(res, "final_tcp", None)
    return np.asarray(res.final_position if p is None else p, np.float64)


def _reason(res) -> str:
    return str(getattr(res.reason, "value", res.reason))


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
    if res is None or not hasattr(res, "route"):  # a base's drive: no route, no audit
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
            error_m=ctx.distance(region, tcp),
            time_s=time.perf_counter() - t0,
        )
    target = np.asarray(target, np.float64)
    tcp = _final(res)
    err = ctx.distance(region, tcp)
    return GoalResult(
        **base,
        status="done",
        reason="" if res.reached else f"reach ended: {_reason(res)}",
        target=tuple(target),
        target_error_m=ctx.distance(region, target),
        tcp=tuple(tcp),
        error_m=err,
        success=err <= ctx.radius,
        reach=_reason(res),
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
        tcp=tuple(_final(res)),
        reach=_reason(res),
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
        kind = getattr(robot, "robot_kind", "arm")
        reader = getattr(robot, "reader", DEFAULT_READER)
        code = str(instruction_to_code(goal.instruction, kind, reader))
        run = run_instruction(goal.instruction, robot, code=code)
    except TabletopError as e:  # a parse error, rejected code, not found, a refused query
        tcp = robot.current_position()
        return GoalResult(
            **base,
            status="not_found" if isinstance(e, GoalNotFound) else "failed",
            reason=f"{type(e).__name__}: {e}",
            tcp=tuple(tcp),
            error_m=ctx.distance(region, tcp),
            contacts=int(sum(robot.contacts[moves_before:])),
            time_s=time.perf_counter() - t0,
            code=code,
        )
    tcp = robot.current_position()
    err = ctx.distance(region, tcp)
    last = run.motions[-1] if run.motions else None
    target = None if last is None else np.asarray(last.target, np.float64)
    res = None if last is None else last.result
    return GoalResult(
        **base,
        status="done",
        reason="" if res is not None and res.reached else "the code's last motion fell short",
        target=None if target is None else tuple(target),
        target_error_m=None if target is None else ctx.distance(region, target),
        tcp=tuple(tcp),
        error_m=err,
        success=err <= ctx.radius,
        reach="" if res is None else _reason(res),
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
    reader: str = DEFAULT_READER,
    driver: str = "sim",
) -> TaskRun:
    """Scan (or reuse), map (or reuse), run every goal of ``tf`` with the encoder set ``encoders``,
    its words read by the reader called ``reader``; write the figures into ``figures_dir`` when
    given. ``map_overrides``: map config fields that replace the task file's ``[map]`` ones (an
    ablation, e.g. ``{"object": {"instances": False}}``); ``scan_overrides``: scan settings that
    replace the task file's ``[scan]`` ones (e.g. ``{"snr_db": 5.0}``: the same scan, sounds 10
    dB quieter); ``noise``: :class:`~tabletop.sim.noise.NoiseConfig` fields that replace the
    task file's ``[noise]`` ones (the clean scan is taken from the cache and the noise applied
    to it, so a noisy run costs a map, not a scan). ``driver``: what moves the arm
    (:data:`DRIVERS`): the PyBullet simulator, or an FR3 on franky-sim through libfranka's
    protocol (:class:`~tabletop.robot.franky_arm.FrankySimArm`; its contacts are counted in a
    PyBullet mirror of the scene, and the run's ``tracking`` holds franky's tracking errors
    and the reflexes)."""
    body = tf.robot.body
    _check_driver(driver, body)
    return body.load("evaluate")(
        tf,
        encoders,
        cache_dir=cache_dir,
        figures_dir=figures_dir,
        progress=progress,
        map_overrides=map_overrides,
        scan_overrides=scan_overrides,
        noise=noise,
        reader=reader,
        driver=driver,
    )


def evaluate_table_task_file(
    tf: TaskFile,
    encoders: str,
    *,
    cache_dir: Path | None = DEFAULT_CACHE_DIR,
    figures_dir: Path | None = None,
    progress: Progress | None = None,
    map_overrides: dict | None = None,
    scan_overrides: dict | None = None,
    noise: dict | None = None,
    reader: str = DEFAULT_READER,
    driver: str = "sim",
) -> TaskRun:
    """:func:`evaluate_task_file` for a robot over a table (the arm's embodiment's
    ``evaluate``): scan the scene with the arm's teleop sweeps (or reuse the scan), map it,
    and run every goal with the embodiment's robot class (``robot_class(map, scene)``), or
    franky-sim's FR3 for ``driver="franky-sim"``."""
    from tabletop.sim.noise import NoiseConfig, apply_noise

    spec = tf.scene.load()
    cache = Path(cache_dir) if cache_dir is not None else None
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
    settings = _map_settings(tf, map_overrides)
    scan = {**dict(tf.scan), **dict(scan_overrides or {})}
    try:
        sensor = NoiseConfig.from_dict({**dict(tf.noise), **dict(noise or {})})
    except ConfigError as e:
        raise TaskFileError(f"{tf.path or tf.name} [noise]: {e}") from None
    # the cache's paths as its keys are now (they hash the source: taken beside each use)
    rec_path = cached_recording_path(spec, scan, cache)
    rec, scan_s, rec_cached = cached_recording(tf.name, scan, spec, cache, progress)
    rec_key = recording_key(spec, scan, sensor.to_dict() if sensor.any else None)
    if sensor.any:
        rec = apply_noise(rec, sensor)
    map_path = cached_map_path(settings, encoders, cache, rec_key)
    m, map_s, map_cached = cached_map(tf.name, settings, rec, encoders, cache, rec_key, progress)
    # Resolve every truth before anything moves: a wrong reference is a task-file error.
    truth = GroundTruth.of(rec)
    regions = _resolve_goals(tf, truth)
    if driver == "franky-sim":
        from tabletop.robot.franky_arm import FrankySimArm

        robot = FrankySimArm(m, spec)
    else:
        robot = tf.robot.body.load("robot_class")(m, spec)
    robot.reader = reader  # every goal's words, instructions and queries alike
    ctx = _Context(robot, m, spec, rec, radius=tf.robot.success_radius)
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
            robot=tf.robot.kind,
            success_radius=tf.robot.success_radius,
            noise=sensor.to_dict() if sensor.any else {},
            map_path=_path_str(map_path),
            recording_path=_path_str(rec_path),
            driver=driver,
            tracking=_tracking(robot) if driver == "franky-sim" else {},
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


#: What can move a robot in an evaluation: the PyBullet simulator, or franky-sim's FR3 (each
#: embodiment says which of them move it: :attr:`~tabletop.embodiments.Embodiment.drivers`).
DRIVERS = ("sim", "franky-sim")


def _check_driver(driver: str, body) -> None:
    if driver not in DRIVERS:
        raise ConfigError(f"driver must be one of {list(DRIVERS)}, got {driver!r}")
    if driver not in body.drivers:
        raise ConfigError(
            f"driver {driver!r} does not move the {body.name} robot; its suites run on "
            f"{' or '.join(repr(d) for d in body.drivers)}"
        )


def _tracking(robot) -> dict:
    """franky's tracking of the run's executed trajectories: the worst and mean of their
    largest joint errors (measured against franky's command), their final errors [rad], and
    the reflexes."""
    reps = robot.tracking_reports
    worst = [r.max_error for r in reps]
    final = [r.final_error for r in reps]
    return {
        "trajectories": len(reps),
        "max_error_rad": float(max(worst, default=0.0)),
        "mean_max_error_rad": float(np.mean(worst)) if worst else 0.0,
        "max_final_error_rad": float(max(final, default=0.0)),
        "reflexes": int(robot.reflexes),
    }


def _path_str(p) -> str:
    """An existing cache file's or directory's path as text ("" for none)."""
    return str(p) if p is not None and Path(p).exists() else ""


def _map_settings(tf: TaskFile, overrides: dict | None, base: dict | None = None) -> dict:
    """The map settings of a task file (``base``, then its ``[map]``, then ``overrides``),
    checked before anything is scanned: a bad value fails before the scan, not after it."""
    settings = {**dict(base or {}), **dict(tf.map), **dict(overrides or {})}
    try:
        map_config(**settings)
    except (TypeError, TabletopError) as e:
        raise TaskFileError(f"{tf.path or tf.name} [map]: {e}") from None
    return settings


def _resolve_goals(tf: TaskFile, truth: GroundTruth) -> dict[str, Region]:
    """Every goal's region, before anything moves: a wrong reference is a task-file error."""
    where = str(tf.path or tf.name)
    regions = {
        g.id: resolve_truth(g.truth, truth, f"{where} goal {g.id!r} truth") for g in tf.goals
    }
    for g in tf.goals:
        if g.type == "absent":
            check_absent(g.query, truth, f"{where} goal {g.id!r}")
    return regions


def evaluate_room_task_file(
    tf: TaskFile,
    encoders: str,
    *,
    cache_dir: Path | None = DEFAULT_CACHE_DIR,
    progress: Progress | None = None,
    map_overrides: dict | None = None,
    scan_overrides: dict | None = None,
    noise: dict | None = None,
    reader: str = DEFAULT_READER,
    figures_dir: Path | None = None,
    driver: str = "sim",
) -> TaskRun:
    """:func:`evaluate_task_file` for a mobile base's task file (its embodiment's ``evaluate``;
    no heatmap figures: ``figures_dir`` draws a table, and is not used here): scan the room with
    the wheeled base (or reuse the scan), map it with the room's settings
    (:func:`~tabletop.eval.room.room_map_settings`), then run every goal, its words read by the
    reader called ``reader``, with a
    :class:`~tabletop.robot.wheeled.MobileRobot` on the room's physics (the ground base) or
    an ideal unicycle (the flyer, which no physics of ours can fly); a goal is reached when
    the base's centre ends within the task file's success radius of the truth, on the floor."""
    from tabletop.base import TABLETOP_BASE, KinematicBaseDriver
    from tabletop.eval.room import cached_room_recording, room_map_settings, room_recording_key
    from tabletop.robot.wheeled import FLYER, GROUND_BASE, MobileRobot
    from tabletop.sim.room_world import RoomWorld, mast_camera_config

    if tf.noise or noise:
        raise TaskFileError(
            f"{tf.path or tf.name}: sensor noise ([noise], --noise) is applied to the arm's "
            "scans only; a mobile base's odometry drift is a [scan] setting of its own"
        )
    spec = tf.scene.load()
    cache = Path(cache_dir) if cache_dir is not None else None
    settings = _map_settings(tf, map_overrides, room_map_settings(spec))
    scan = {**dict(tf.scan), **dict(scan_overrides or {})}
    rec, scan_s, rec_cached = cached_room_recording(tf.name, scan, spec, cache, progress)
    rec_key = room_recording_key(spec, scan)
    map_path = cached_map_path(settings, encoders, cache, rec_key)
    m, map_s, map_cached = cached_map(tf.name, settings, rec, encoders, cache, rec_key, progress)
    truth = GroundTruth.of(rec)
    regions = _resolve_goals(tf, truth)
    h, w = rec.rgb.shape[1:3]
    renderer = (rec.meta or {}).get("renderer", "auto")
    world = RoomWorld(spec, mast_camera_config(width=w, height=h), renderer)
    flyer = tf.robot.embodiment == "flyer"

    def fresh_robot():
        if flyer:
            start = world.driver.read_odometry()
            driver = KinematicBaseDriver(TABLETOP_BASE, start)
        else:
            world.reset_base()
            driver = world.driver
        robot = MobileRobot(m, driver, embodiment=FLYER if flyer else GROUND_BASE)
        robot.reader = reader  # every goal's words, instructions and queries alike
        return robot

    results: list[GoalResult] = []
    try:
        robot = fresh_robot()
        ctx = _Context(robot, m, spec, rec, radius=tf.robot.success_radius, world=world)
        done = 0
        for seq_id, goals in tf.runs():
            ctx.robot = robot = fresh_robot()  # every sequence from the room's start
            for g in goals:
                results.append(_run_goal(ctx, g, seq_id, regions[g.id]))
                done += 1
                if progress:
                    progress(f"goals {tf.name}", done, len(tf.goals))
        return TaskRun(
            task_name=tf.name,
            task_path=str(tf.path or tf.name),
            scene=spec.name,
            goals=results,
            scan_s=scan_s,
            map_s=map_s,
            cached=rec_cached and map_cached,
            encoder_names=dict(m.encoder_names),
            robot=tf.robot.kind,
            success_radius=tf.robot.success_radius,
            map_path=_path_str(map_path),
            recording_path=_path_str(
                cache / f"rec-room-{spec.name}-{rec_key}" if cache is not None else None
            ),
        )
    finally:
        world.close()


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
    reader: str = DEFAULT_READER,
    workers: int | None = None,
    ray: str | None = None,
    driver: str = "sim",
):
    """Evaluate task files (paths, directories, shipped names or :class:`TaskFile`s) with one
    or more encoder sets, their words read by ``reader``; write the report into ``out_dir``
    when given. ``map_overrides``,
    ``scan_overrides``, ``noise``: see :func:`evaluate_task_file`. ``progress`` is called
    as ``progress(stage, done, total)`` (see :data:`Progress`); None reports nothing.

    The units of work are the pairs (encoder set, task file). ``workers=N`` runs them in N
    worker processes, ``ray`` (a cluster's address or "auto") as Ray tasks
    (:mod:`tabletop.parallel`); the results are merged in the serial order and equal a serial
    run's goal for goal (all but the timings). Units that need the same missing recording or
    map wait for the one that makes it (the cache's lock), so it is made once.

    An encoder set that cannot be built here is a row marked unavailable with the reason (no
    scan is wasted on it). Returns an :class:`~tabletop.eval.report.EvalResult`.
    """
    from tabletop.embodiments import embodiment
    from tabletop.eval.report import EvalResult
    from tabletop.parallel import Backend

    backend = Backend(workers=workers, ray=ray)

    files = collect_task_files(tasks)
    kinds = sorted({tf.robot.kind for tf in files})
    if len(kinds) > 1:
        raise ConfigError(
            f"the task files are for different robots ({kinds}): evaluate each robot's suites "
            "apart (their success radii differ)"
        )
    names = [encoders] if isinstance(encoders, str) else list(encoders)
    if not names:
        raise ConfigError("give at least one encoder set")
    get_reader(reader)  # an unknown reader is refused before anything runs
    _check_driver(driver, embodiment(kinds[0] if kinds else "arm"))
    cb: Progress | None = progress or None
    out = Path(out_dir) if out_dir is not None else None
    if not backend.serial:
        runs = _run_units(
            files, names, backend, out, cb,
            dict(
                cache_dir=cache_dir, map_overrides=map_overrides, scan_overrides=scan_overrides,
                noise=noise, reader=reader, driver=driver,
            ),
        )  # fmt: skip
        result = EvalResult([str(f.path or f.name) for f in files], runs, out, reader)
        if out is not None:
            result.write(out)
        return result
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
                reader=reader,
                driver=driver,
            )
            er.tasks.append(tr)
        er.encoder_names = dict(er.tasks[0].encoder_names)
        er.wall_s = time.perf_counter() - t0
        runs.append(er)
    result = EvalResult([str(f.path or f.name) for f in files], runs, out, reader)
    if out is not None:
        result.write(out)
    return result


def _eval_unit(tf: TaskFile, encoders: str, figures_dir: Path | None, options: dict) -> TaskRun:
    """One unit of work in a worker: a task file under an encoder set (no progress bars)."""
    return evaluate_task_file(tf, encoders, figures_dir=figures_dir, progress=None, **options)


def _run_units(files, names, backend, out: Path | None, progress, options: dict) -> list:
    """The rows of :func:`run_eval`, their units (encoder set x task file) run by ``backend``
    and put back in the serial order."""
    from tabletop.eval.results import EncoderRun
    from tabletop.parallel import run_units

    rows: list[EncoderRun] = []
    units, where = [], []
    for name in names:  # in the serial order: rows, then task files
        reason = _check_encoder_set(name)
        rows.append(EncoderRun(name, {}, not reason, reason))
        if reason:
            continue
        for tf in files:
            fig = out / "figures" / name / _slug(tf.name) if out is not None else None
            units.append((tf, name, fig, options))
            where.append(len(rows) - 1)
    labels = [f"{name} x {tf.name}" for tf, name, _, _ in units]
    total, finished = len(units), [0]
    t0 = time.perf_counter()
    row_wall = [0.0] * len(rows)
    note = getattr(progress, "note", None)
    log.info("%d units of work (encoder set x task file) on %s", total, backend.describe())

    def done(i: int, tr: TaskRun, secs: float) -> None:
        finished[0] += 1
        row_wall[where[i]] = time.perf_counter() - t0  # the row's last unit so far
        if note is not None:
            ok = sum(g.success for g in tr.goals)
            note(
                f"[{finished[0]}/{total}] {labels[i]}: {ok}/{len(tr.goals)} goals succeeded, "
                f"{secs:.1f} s (scan {tr.scan_s:.1f} s, map {tr.map_s:.1f} s)"
            )
        if progress:
            progress("units", finished[0], total)

    if progress:
        progress("units", 0, total)
    results = run_units(_eval_unit, units, backend, labels=labels, on_done=done)
    for i, tr in enumerate(results):
        rows[where[i]].tasks.append(tr)
    for k, er in enumerate(rows):
        if er.available:
            er.encoder_names = dict(er.tasks[0].encoder_names)
            er.wall_s = row_wall[k]  # from the start until its last unit finished
    return rows


def _slug(s: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in s).strip("-") or "tasks"
