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

import hashlib
import json
import logging
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from tabletop.errors import ConfigError, TabletopError
from tabletop.eval.results import EncoderRun, GoalResult, TaskRun
from tabletop.eval.tasks import Goal, Landmark, TaskFile, TaskFileError, load_tasks
from tabletop.eval.truth import Region, relation_point, resolve_truth

__all__ = [
    "DEFAULT_CACHE_DIR",
    "collect_task_files",
    "evaluate_task_file",
    "hover_point",
    "run_eval",
    "scan_recording",
]

log = logging.getLogger(__name__)

DEFAULT_CACHE_DIR = Path("out/eval-cache")
#: A query goal's target is approached from above: ``above_gap`` over the highest map surface
#: within this radius [m] (about a gripper's half span).
HOVER_RADIUS_M = 0.05

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


# ---------------------------------------------------------------------------- cache
def _fingerprint(*packages: str) -> str:
    """Hash of the Python source (and shipped weights/manifests) a cached artefact depends on."""
    from tabletop.paths import DATA_DIR, PACKAGE_DIR

    h = hashlib.sha1()
    for pkg in packages:
        for f in sorted((PACKAGE_DIR / pkg).rglob("*.py")):
            h.update(f.name.encode())
            h.update(f.read_bytes())
    if "mapping" in packages:
        for f in sorted((DATA_DIR / "weights").rglob("*")):
            if f.is_file():
                h.update(f"{f.name}:{f.stat().st_size}".encode())
    return h.hexdigest()[:10]


def _key(obj) -> str:
    return hashlib.sha1(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:12]


def _rec_key(spec, scan: dict) -> str:
    return _key({"scene": spec.to_dict(), "scan": scan, "sim": _fingerprint("sim")})


def _recording(name: str, scan: dict, spec, cache: Path | None, progress: Progress | None):
    """(recording, scan seconds, cached?) for a scene and scan settings (``ScanConfig``
    fields), through the cache."""
    from tabletop.sim.recording import load_recording, save_recording
    from tabletop.sim.scan import ScanConfig, run_scan

    path = cache / f"rec-{spec.name}-{_rec_key(spec, scan)}" if cache else None
    if path is not None and path.is_dir():
        try:
            return load_recording(path), 0.0, True
        except TabletopError as e:
            log.warning("cached recording %s is unusable (%s); scanning again", path, e)
    t0 = time.perf_counter()
    cb = (lambda d, n: progress(f"scan {name}", d, n)) if progress else None
    rec, _ = run_scan(spec, ScanConfig(**scan), progress=cb)
    scan_s = time.perf_counter() - t0
    if path is not None:
        cache.mkdir(parents=True, exist_ok=True)
        save_recording(rec, path, overwrite=True)
    return rec, scan_s, False


def scan_recording(scene: dict, scan: dict, cache_dir: str | Path | None = DEFAULT_CACHE_DIR):
    """(recording, cached?) of a task file's ``[scene]`` and ``[scan]`` sections, scanned or
    taken from the cache (what the suite generator reads the ground truth from)."""
    from tabletop.eval.tasks import _check_scan, scene_ref

    _check_scan(scan)
    spec = scene_ref(scene).load()
    cache = Path(cache_dir) if cache_dir is not None else None
    rec, _, cached = _recording(spec.name, dict(scan), spec, cache, None)
    return rec, cached


def _map_config(tf: TaskFile):
    from tabletop.mapping.avlmap import MapConfig
    from tabletop.mapping.grid import VoxelGrid

    kw = dict(tf.map)
    grid = VoxelGrid(voxel_size=float(kw.pop("voxel_size", 0.01)))
    try:
        return MapConfig(grid=grid, **kw)
    except TypeError as e:
        raise TaskFileError(f"{tf.path or tf.name} [map]: {e}") from None


def _map(tf: TaskFile, rec, encoders: str, cache: Path | None, rec_key: str, progress):
    """(AVLMap, map seconds, cached?)."""
    from tabletop.mapping.avlmap import AVLMap

    key = _key({"rec": rec_key, "map": tf.map, "mapping": _fingerprint("mapping")})
    path = cache / f"map-{encoders}-{key}.npz" if cache else None
    if path is not None and path.is_file():
        try:
            return AVLMap.load(path), 0.0, True
        except TabletopError as e:
            log.warning("cached map %s is unusable (%s); building again", path, e)
    t0 = time.perf_counter()
    cb = (lambda d, n: progress(f"map {tf.name}", d, n)) if progress else None
    m = AVLMap.build(rec, _map_config(tf), encoders=encoders, progress=cb)
    map_s = time.perf_counter() - t0
    if path is not None:
        m.save(path)
    return m, map_s, False


# ---------------------------------------------------------------------------- instructions
def instruction_parser() -> tuple[tuple | None, str]:
    """((to_code, run), "") from :mod:`tabletop.language` (the offline instruction parser and
    the sandboxed runner), or (None, reason) when this version has no instruction parser."""
    try:
        from tabletop.language import instruction_to_code, run_instruction
    except ImportError as e:
        return None, f"instruction parser not available ({e})"
    return (instruction_to_code, run_instruction), ""


# ---------------------------------------------------------------------------- goals
class _Context:
    """What one task file's goals run against: the robot, the map, the scene and truth."""

    def __init__(self, robot, avlmap, spec, rec) -> None:
        self.robot = robot
        self.map = avlmap
        self.spec = spec
        self.rec = rec
        self.gt = rec.ground_truth
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


def _query_target(ctx: _Context, goal: Goal, lm: Landmark, tag: str = "") -> np.ndarray:
    """The argmax of the landmark's (fused) major map, through the robot API."""
    robot = ctx.robot
    heat = robot.get_major_map(**_parts(ctx, goal.id, lm), primary=lm.primary)
    if goal.id in ctx.keep_heatmaps:
        names = [k for k, _ in lm.parts]
        for k, h in zip(names, robot.last_heatmaps, strict=False):
            role = "primary" if k == lm.primary else "auxiliary"
            ctx.heatmaps.setdefault(goal.id, []).append((f"{tag}{role} {k}", h.values))
        if len(lm.parts) > 1:
            ctx.heatmaps[goal.id].append((f"{tag}fused", heat))
    return robot.get_max_pos_3d(heat)


def hover_point(avlmap, target, gap: float, radius: float = HOVER_RADIUS_M) -> np.ndarray:
    """(3,) [m]: ``target`` raised to ``gap`` above the highest surface the map has within
    ``radius`` of it (horizontally), so a top-down gripper approaches a goal on or in an
    object (a mug's cavity, the table beside a tall object) from above instead of being driven
    into it."""
    p = np.array(target, np.float64)
    g = avlmap.grid
    xs, ys, zs = g.axes()
    near = (xs[:, None] - p[0]) ** 2 + (ys[None, :] - p[1]) ** 2 <= radius**2
    cols = avlmap.voxels.occupancy()[near]  # (K, nz)
    top = 0.0
    if cols.size and cols.any():
        top = float(zs[np.nonzero(cols.any(axis=0))[0].max()] + g.voxel_size / 2)
    p[2] = max(p[2], top + gap)
    return p


def _spatial_target(ctx: _Context, goal: Goal) -> np.ndarray:
    robot = ctx.robot
    marks = goal.landmarks
    plain = [len(m.parts) == 1 and m.primary == "obj" for m in marks]
    if all(plain):  # the robot API's own primitives
        names = [m.as_dict["obj"] for m in marks]
        fn = {
            "between": robot.between,
            "left_of": robot.left_of,
            "right_of": robot.right_of,
            "in_front_of": robot.in_front_of,
            "behind": robot.behind,
            "above": robot.above,
        }[goal.relation]
        return fn(*names)
    anchors = []
    for i, (m, is_obj) in enumerate(zip(marks, plain, strict=True)):
        if is_obj:
            p = robot.get_pos(m.as_dict["obj"])
        else:  # a found place: level with the highest surface there (an object's top)
            p = _query_target(ctx, goal, m, tag=f"landmark {i + 1} ")
            p = hover_point(ctx.map, p, 0.0)
        anchors.append((np.asarray(p, np.float64), np.zeros(3)))
    return relation_point(goal.relation, anchors, robot.spatial)


def _run_goal(ctx: _Context, goal: Goal, sequence: str, region: Region, parser) -> GoalResult:
    from tabletop.robot.api import GoalNotFound, ImageGoalUnavailable

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
        if parser[0] is None:
            return GoalResult(**base, status="unavailable", reason=parser[1])
        return _run_code(ctx, goal, base, parser[0], region, t0)
    try:
        target = (
            _spatial_target(ctx, goal) if goal.landmarks else _query_target(ctx, goal, goal.query)
        )
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
    if goal.query is not None:
        res = robot.move_to(hover_point(ctx.map, target, robot.spatial.above_gap))
    else:
        res = robot.move_to(target)
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
        success=err <= 0.10,
        reach=res.reason.value,
        contacts=int(robot.contacts[-1]),
        time_s=time.perf_counter() - t0,
    )


def _run_code(ctx: _Context, goal: Goal, base: dict, parser, region: Region, t0: float):
    """Parse an instruction, run its code in the sandbox against the robot, score the TCP
    after the last motion. A parse error or rejected code is a failure (nothing moves)."""
    from tabletop.robot.api import GoalNotFound

    to_code, run_instruction = parser
    robot = ctx.robot
    moves_before = len(robot.history)
    code = ""
    try:
        code = str(to_code(goal.instruction))
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
        success=err <= 0.10,
        reach="" if res is None else res.reason.value,
        contacts=int(sum(robot.contacts[moves_before:])),
        time_s=time.perf_counter() - t0,
        code=code,
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
) -> TaskRun:
    """Scan (or reuse), map (or reuse), run every goal of ``tf`` with the encoder set
    ``encoders``; write the figures into ``figures_dir`` when given."""
    from tabletop.robot import SimArm

    spec = tf.scene.load()
    cache = Path(cache_dir) if cache_dir is not None else None
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
    rec, scan_s, rec_cached = _recording(tf.name, tf.scan, spec, cache, progress)
    rec_key = _rec_key(spec, tf.scan)
    m, map_s, map_cached = _map(tf, rec, encoders, cache, rec_key, progress)
    # Resolve every truth before anything moves: a wrong reference is a task-file error.
    where = str(tf.path or tf.name)
    regions = {
        g.id: resolve_truth(g.truth, rec.ground_truth, f"{where} goal {g.id!r} truth")
        for g in tf.goals
    }
    parser = instruction_parser()
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
                results.append(_run_goal(ctx, g, seq_id, regions[g.id], parser))
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
        )
        if figures_dir is not None:
            from tabletop.eval.report import write_task_figures

            run.figures = write_task_figures(
                figures_dir, tf, encoders, m, rec.ground_truth, results, regions, ctx
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
    progress: bool | Progress = True,
    cache_dir: str | Path | None = DEFAULT_CACHE_DIR,
):
    """Evaluate task files (paths, directories, shipped names or :class:`TaskFile`s) with one
    or more encoder sets; write the report into ``out_dir`` when given.

    An encoder set that cannot be built here is a row marked unavailable with the reason (no
    scan is wasted on it). Returns an :class:`~tabletop.eval.report.EvalResult`.
    """
    from tabletop.eval.report import EvalResult

    files = collect_task_files(tasks)
    names = [encoders] if isinstance(encoders, str) else list(encoders)
    if not names:
        raise ConfigError("give at least one encoder set")
    cb: Progress | None
    bar = None
    if progress is True:
        from tabletop.eval.cli import ProgressBars

        bar = ProgressBars()
        cb = bar
    else:
        cb = progress or None
    out = Path(out_dir) if out_dir is not None else None
    runs = []
    try:
        for name in names:
            t0 = time.perf_counter()
            reason = _check_encoder_set(name)
            if reason:
                runs.append(EncoderRun(name, {}, False, reason))
                continue
            er = EncoderRun(name, {}, True)
            for tf in files:
                fig = out / "figures" / name / _slug(tf.name) if out is not None else None
                tr = evaluate_task_file(tf, name, cache_dir=cache_dir, figures_dir=fig, progress=cb)
                er.tasks.append(tr)
            er.encoder_names = dict(er.tasks[0].encoder_names)
            er.wall_s = time.perf_counter() - t0
            runs.append(er)
    finally:
        if bar is not None:
            bar.close()
    result = EvalResult([str(f.path or f.name) for f in files], runs, out)
    if out is not None:
        result.write(out)
    return result


def _slug(s: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in s).strip("-") or "tasks"
