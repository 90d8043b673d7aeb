"""What the viewer shows and does, without the browser: one map (its picture first, the map
itself loaded behind it), its queries, reaches, sounds, evaluation goals and a room's
obstacle grids.

Every query goes through the robot API and the reader the robot uses
(:class:`~tabletop.robot.api.RobotAPI`, :func:`tabletop.language.run.run_instruction` for a
request in words: the reader reads it, code generation writes the robot code, the sandbox runs
it dry), so the viewer's heatmap is the one ``tabletop run --dry-run`` and the benchmark
compute. "go" sends the query's targets to the arm's reach controller in simulation (the
simulated Panda in the map's scene when the map says which scene it is, else an ideal
kinematic arm), or to a wheeled base's planner and follower on a room map.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tabletop.errors import ConfigError, GoalNotFound, TabletopError

__all__ = [
    "KINDS",
    "EvalGoal",
    "InstanceInfo",
    "QueryOutcome",
    "ReachOutcome",
    "SoundInfo",
    "ViewerSession",
    "is_room_grid",
]

log = logging.getLogger(__name__)

#: How a query's words are read: a request through the reader (the default: objects, sounds,
#: areas, "near" combinations and instructions alike), or one modality of the robot API.
KINDS = {
    "request": None,
    "object": "obj",
    "sound": "sound",
    "area": "area",
    "image file": "img",
}
#: A grid taller than this [m] is a room's (the table's workspace is 0.36 m tall).
ROOM_HEIGHT_M = 1.0
#: The embodiments whose obstacles are shown on a table and in a room, by name
#: (:data:`tabletop.robot.obstacles.ARM`, ``MOBILE_BASE``; :data:`tabletop.robot.wheeled.
#: GROUND_BASE`, ``FLYER``).
TABLE_EMBODIMENTS = ("panda arm", "table-top mobile base")
ROOM_EMBODIMENTS = ("ground base", "flyer")


def is_room_grid(grid) -> bool:
    """Whether a map's grid is a room's (the wheeled base's) rather than a table's."""
    return grid.upper[2] - grid.lower[2] > ROOM_HEIGHT_M


@dataclass(frozen=True)
class PartInfo:
    """One query part's verdict: what the module said."""

    modality: str
    query: str
    confidence: float
    found: bool
    reason: str


@dataclass(frozen=True)
class QueryOutcome:
    """What a query gave: the heatmap drawn, the targets, the verdict and why."""

    text: str
    kind: str
    found: bool
    reason: str = ""
    heat: np.ndarray | None = None
    """The heatmap drawn (the grid's shape), None when there is none."""
    targets: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """(K, 3) [m]: where the query sends the robot, in order."""
    confidence: float | None = None
    parts: tuple[PartInfo, ...] = ()
    code: str = ""
    """The robot code of a request (as the sandbox ran it, dry)."""
    seconds: float = 0.0


@dataclass(frozen=True)
class ReachOutcome:
    """What "go" did: the motion to animate and each target's result."""

    robot: str
    """"arm" or "base"."""
    frames: np.ndarray
    """The arm's joint configurations (T, 7) [rad], or the base's poses (T, 3) x, y [m], yaw
    [rad], in time order."""
    results: tuple[dict, ...]
    """Per target: reached, reason, error_m, clearance_m (arm), route (arm), final (3,)."""
    planned: tuple[np.ndarray, ...] = ()
    """A base's planned waypoints (K, 2) [m] per target."""
    simulator: str = ""
    """What ran the motion, in words."""


@dataclass(frozen=True)
class InstanceInfo:
    id: int
    label: str
    probability: float
    colour: tuple[int, int, int]
    rows: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


@dataclass(frozen=True)
class SoundInfo:
    index: int
    start_s: float
    end_s: float
    position: np.ndarray
    label: str
    score: float
    samples: np.ndarray | None
    rate: int


@dataclass(frozen=True)
class EvalGoal:
    """One goal of an evaluation's ``results.json``."""

    encoders: str
    task: str
    scene: str
    result: dict
    same_map: bool
    """Whether the goal ran on this map (its task's map file, or its scene, is this map's)."""

    @property
    def label(self) -> str:
        r = self.result
        return f"{r['goal_id']}: {r.get('text', '')}"[:80]


class _QueryLog:
    """Records every heatmap a robot's queries return (mixed into the robots the viewer asks)."""

    def _log_reset(self) -> None:
        self.queried: list = []  # (Heatmap, its parts)
        self.targeted: list = []  # heatmaps given to get_max_pos_3d

    def get_major_map(self, *args, **kwargs):
        h = super().get_major_map(*args, **kwargs)
        self.queried.append((h, tuple(self.last_heatmaps)))
        return h

    def get_map(self, *args, **kwargs):
        h = super().get_map(*args, **kwargs)
        self.queried.append((h, tuple(self.last_heatmaps)))
        return h

    def get_max_pos_3d(self, heatmap):
        self.targeted.append(heatmap)
        return super().get_max_pos_3d(heatmap)


def _part(h) -> PartInfo:
    return PartInfo(h.modality, str(h.query), float(h.confidence), bool(h.found), h.reason or "")


class ViewerSession:
    """One map in the viewer.

    Args:
        map_path: the map file (``tabletop build-map --out``).
        recording: its recording directory (camera path, the arm's joints, the audio), or None.
        eval_dir: an evaluation's output directory (``results.json``), or None.
        scene: the scene the arm runs in for "go" (default: the one the map says it was built
            from; a map that says none gets an ideal kinematic arm).
        reader: the reader of requests (:data:`tabletop.reader.READERS`).
    """

    def __init__(
        self, map_path, recording=None, eval_dir=None, scene: str | None = None, reader=None
    ) -> None:
        from tabletop.mapping.persistence import read_map_preview

        self.map_path = Path(map_path)
        self.preview = read_map_preview(self.map_path)
        self.grid = self.preview.grid
        self.linear = self.preview.linear
        self.room = is_room_grid(self.grid)
        self.recording_path = Path(recording) if recording else None
        self.eval_dir = Path(eval_dir) if eval_dir else None
        self.scene = scene
        self.reader = reader
        """The reader's name (None: the default reader, resolved when the map loads)."""
        self.map = None
        self.recording = None
        self.error = ""
        """Why the map (or the recording) could not be loaded; empty when it loaded."""
        self.ready = threading.Event()
        self._lock = threading.RLock()
        self._arm = None
        self._arm_kind = ""
        self._base = None
        self.arm_q = None
        """The arm's joint configuration now (7,) [rad] (None before the first reach)."""

    # ------------------------------------------------------------------ loading
    def load(self) -> None:
        """Load the map with its encoders, then the recording (call it in a thread: the
        viewer draws the map's picture meanwhile). Errors end up in :attr:`error`."""
        from tabletop.mapping.avlmap import AVLMap
        from tabletop.reader.reading import DEFAULT_READER, get_reader

        try:
            self.reader = self.reader or DEFAULT_READER
            get_reader(self.reader)  # an unknown reader is said here, not at the first query
            self.map = AVLMap.load(self.map_path)
            if self.recording_path is not None:
                from tabletop.recording import load_recording

                try:
                    self.recording = load_recording(self.recording_path)
                except TabletopError as e:  # the map stays usable without it
                    self.error = f"the recording could not be loaded: {e}"
        except TabletopError as e:
            self.error = str(e)
        finally:
            self.ready.set()

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until :meth:`load` has finished; True when the map is usable."""
        self.ready.wait(timeout)
        return self.map is not None

    def _need_map(self):
        if not self.ready.is_set():
            raise ConfigError("the map is still loading (its encoders); try again in a moment")
        if self.map is None:
            raise ConfigError(f"the map could not be loaded: {self.error}")
        return self.map

    # ------------------------------------------------------------------ what there is
    @property
    def title(self) -> str:
        h = self.preview.header
        src = (h.get("source") or {}).get("scene")
        where = f"scene {src!r}" if src else ("a room" if self.room else "a table")
        return (
            f"{self.map_path.name}: {len(self.preview.centers)} voxels at "
            f"{self.grid.voxel_size * 100:g} cm, {h.get('encoder_set', '?')} encoders, {where}"
        )

    def instances(self) -> list[InstanceInfo]:
        """The map's object instances, each named by the object module's most probable kind
        and its measured colour's nearest basic colour name."""
        from tabletop.reader.lexicon.colour_names import BASIC_COLOURS

        m = self._need_map()
        objs = m.objects
        if not getattr(objs, "uses_instances", False):
            return []
        inst = list(objs.instances.items)
        if not inst:
            return []
        names = list(objs.vocabulary) + list(m.config.object.background)
        probs = objs.kind_probabilities(inst)
        weights = [objs.colour_weights(c) for c in BASIC_COLOURS]
        fits = np.stack([objs.colour_match(w, inst) for w in weights], axis=1)
        out = []
        for k, i in enumerate(inst):
            c = int(np.argmax(probs[k]))
            colour = BASIC_COLOURS[int(np.argmax(fits[k]))]
            rgb = tuple(int(v) for v in np.clip(np.round(i.rgb), 0, 255))
            out.append(
                InstanceInfo(
                    int(i.id), f"{colour} {names[c]}", float(probs[k, c]), rgb,
                    np.asarray(i.rows), np.asarray(i.lo), np.asarray(i.hi),
                )
            )  # fmt: skip
        return out

    def embodiment_names(self) -> tuple[str, ...]:
        """The names of :meth:`embodiments`, known before anything is imported (the page's
        panel is built before the robot's packages load)."""
        return ROOM_EMBODIMENTS if self.room else TABLE_EMBODIMENTS

    def embodiments(self) -> list:
        """The embodiments whose obstacles the viewer shows: the arm and the table-top base on
        a table; the ground base and the flyer in a room."""
        if self.room:
            from tabletop.robot.wheeled import FLYER, GROUND_BASE

            return [GROUND_BASE, FLYER]
        from tabletop.robot.obstacles import ARM, MOBILE_BASE

        return [ARM, MOBILE_BASE]

    def obstacles(self, embodiment) -> tuple[np.ndarray, float]:
        """(centres (N, 3) [m], cell size [m]) of an embodiment's obstacles on this map: its
        obstacle voxels on a table (columns filled down to the table, as the arm's boxes
        are); on a room map its top-down grid (the base plans on it), drawn at the floor."""
        from tabletop.robot.obstacles import obstacle_voxels, occupancy_grid

        m = self._need_map()
        if self.room:
            g = occupancy_grid(m, embodiment)
            cells = np.argwhere(g.occupied)
            xy = g.to_world(cells) if len(cells) else np.zeros((0, 2))
            z = np.full((len(xy), 1), 0.01 if embodiment.block_above is None else 1.2)
            return np.hstack([xy, z]), g.cell_size
        ov = obstacle_voxels(m, embodiment)
        idx = np.argwhere(ov.mask)
        return (m.grid.centers(idx) if len(idx) else np.zeros((0, 3))), m.grid.voxel_size

    def sounds(self) -> list[SoundInfo]:
        """The map's sound segments: where each was heard, the nearest sound of the audio
        encoder's vocabulary with its posterior, and the samples when the recording is
        loaded."""
        m = self._need_map()
        s = m.sounds
        if not len(s):
            return []
        labels = [("", float("nan"))] * len(s)
        if s.vocabulary is not None:
            post = s.matcher(m.audio_text).posteriors(np.stack(s.embeddings))
            cats = s.vocabulary.categories
            labels = [
                (s.vocabulary.caption(cats[int(np.argmax(p))]), float(np.max(p))) for p in post
            ]
        rec = self.recording
        out = []
        for i, (seg, pos) in enumerate(zip(s.segments, s.positions, strict=True)):
            samples = None
            rate = 16000
            if rec is not None and rec.audio is not None:
                rate = int(rec.audio_rate)
                a, b = int(seg.start_s * rate), int(np.ceil(seg.end_s * rate))
                samples = np.asarray(rec.audio[max(a, 0) : max(b, a + 1)], np.float32)
            label, score = labels[i]
            out.append(
                SoundInfo(i, seg.start_s, seg.end_s, np.asarray(pos), label or f"segment {i}",
                          score, samples, rate)
            )  # fmt: skip
        return out

    def camera_poses(self) -> tuple[np.ndarray, np.ndarray | None, tuple[int, int] | None]:
        """(T_world_cam (N, 4, 4), K or None, image size or None): the recording's camera
        along its path when loaded, else the map's fused frames' poses."""
        rec = self.recording
        if rec is not None:
            return np.asarray(rec.T_world_cam), np.asarray(rec.K), tuple(rec.image_size)
        return self.preview.frame_poses, None, None

    def joint_path(self) -> np.ndarray | None:
        """(N, 7) the arm's joints along the recording (None: no arm recording)."""
        rec = self.recording
        if rec is None or self.room or rec.joint_positions.shape[1] != 7:
            return None
        return np.asarray(rec.joint_positions)

    def base_start(self):
        """The wheeled base's start (a :class:`~tabletop.base.BasePose`): the recording's first
        odometry pose, else the base beneath the map's first camera pose."""
        import math

        from tabletop.base import BasePose, load_base_description

        rec = self.recording
        if rec is not None and rec.ee_frame == "base_footprint":
            T = np.asarray(rec.T_world_hand[0])
        elif len(self.preview.frame_poses):
            T = self.preview.frame_poses[0] @ np.linalg.inv(load_base_description().T_base_cam)
        else:
            T = np.eye(4)
        return BasePose(float(T[0, 3]), float(T[1, 3]), math.atan2(T[1, 0], T[0, 0]))

    # ------------------------------------------------------------------ queries
    def _query_robot(self):
        """The robot a query runs on (dry): the map and a point for the arm, the wheeled
        base's planner for a room; both log the heatmaps they return."""
        m = self._need_map()
        if self.room:
            from tabletop.base import TABLETOP_BASE, KinematicBaseDriver
            from tabletop.robot.wheeled import MobileRobot

            class _Base(_QueryLog, MobileRobot):
                pass

            pose = self.base_start() if self._base is None else None
            if pose is None:
                p = self._base.driver.read_odometry()
                from tabletop.base import BasePose

                pose = BasePose(p.x, p.y, p.yaw)
            robot = _Base(m, KinematicBaseDriver(TABLETOP_BASE, pose))
        else:
            from tabletop.language.suite import PointRobot

            class _Point(_QueryLog, PointRobot):
                pass

            robot = _Point(m, self.tcp())
        robot.reader = self.reader
        robot._log_reset()
        return robot

    def tcp(self) -> np.ndarray:
        """(3,) [m] the arm's TCP now (home before the first reach)."""
        from tabletop.arm.model import HOME_Q, PandaModel

        q = HOME_Q if self.arm_q is None else self.arm_q
        return PandaModel().fk(q)[:3, 3].copy()

    def query(
        self, text: str, kind: str = "request", near: str = "", near_kind: str = "object"
    ) -> QueryOutcome:
        """Ask the map: ``text`` read as ``kind`` (:data:`KINDS`), narrowed by ``near`` read as
        ``near_kind`` (a broad map multiplied in). A request in words goes through the reader,
        code generation and a dry run in the sandbox, as ``tabletop run --dry-run`` does."""
        t0 = time.perf_counter()
        text = (text or "").strip()
        near = (near or "").strip()
        if kind not in KINDS or near_kind not in KINDS:
            raise ConfigError(f"read as one of {list(KINDS)}")
        if not text:
            return QueryOutcome(text, kind, False, "type something to ask the map")
        with self._lock:
            robot = self._query_robot()
            try:
                if KINDS[kind] is None:
                    text = _with_near(text, near, near_kind)
                    out = self._request(robot, text)
                else:
                    out = self._typed(robot, text, kind, near, near_kind)
            except GoalNotFound as e:
                out = self._outcome(robot, text, kind, False, str(e))
            except TabletopError as e:  # the reader refused, a bad image path, ...
                out = QueryOutcome(text, kind, False, f"{type(e).__name__}: {e}")
        return _timed(out, t0)

    def _outcome(self, robot, text, kind, found, reason, targets=None, code="") -> QueryOutcome:
        """The outcome from what ``robot`` logged: the heatmap given to a target selector
        last (else the hottest of every landmark's), its parts' verdicts."""
        parts = tuple(_part(p) for _, ps in robot.queried for p in ps)
        heat = None
        conf = None
        if robot.targeted:
            h = robot.targeted[-1]
            heat, conf = np.asarray(h.values), float(h.confidence)
        elif robot.queried:
            hs = [h for h, _ in robot.queried]
            heat = np.max(np.stack([np.asarray(h.values) for h in hs]), axis=0)
            conf = float(min(h.confidence for h in hs))
        if parts and conf is None:
            conf = min(p.confidence for p in parts)
        if not found and parts and not reason:
            reason = next((p.reason for p in parts if not p.found), "")
        t = np.zeros((0, 3)) if targets is None else np.asarray(targets, np.float64).reshape(-1, 3)
        return QueryOutcome(text, kind, found, reason, heat, t, conf, parts, code)

    def _request(self, robot, text: str) -> QueryOutcome:
        from tabletop.language.run import run_instruction

        run = run_instruction(text, robot, dry_run=True, reader=self.reader)
        return self._outcome(robot, text, "request", True, "", run.targets, run.code)

    def _typed(self, robot, text, kind, near, near_kind) -> QueryOutcome:
        k = KINDS[kind]
        heat = robot.get_major_map(**{k: text})
        if near:
            nk = KINDS[near_kind]
            if nk is None:
                raise ConfigError("read 'near' as an object, a sound, an area or an image file")
            heat = heat * robot.get_map(**{nk: near})
        target = robot.get_max_pos_3d(heat)
        label = text if not near else f"{text} near {near}"
        return self._outcome(robot, label, kind, True, "", [target])

    def goal_query(self, goal: EvalGoal) -> QueryOutcome:
        """An evaluation goal asked again through the same robot API: its query or its
        landmarks (relation targets), an instruction through the reader; an image goal's
        picture was rendered by the evaluation's simulator and is not asked again here."""
        t0 = time.perf_counter()
        from tabletop.eval.tasks import load_tasks

        r = goal.result
        try:
            g = load_tasks(goal.task).goal(r["goal_id"])
        except (TabletopError, KeyError, OSError) as e:
            return QueryOutcome(r.get("text", ""), "goal", False, f"its task file: {e}")
        if g.type == "instruction":
            return _timed(self.query(g.instruction or g.text, "request"), t0)
        if g.needs_image:
            return QueryOutcome(
                g.text, "goal", False,
                "an image goal: its picture was rendered by the evaluation's simulator; the "
                "evaluation's own figures show its heatmap",
            )  # fmt: skip
        with self._lock:
            robot = self._query_robot()
            try:
                if g.query is not None:
                    h = robot.get_major_map(**g.query.as_dict, primary=g.query.primary)
                    out = self._outcome(robot, g.text, "goal", True, "", [robot.get_max_pos_3d(h)])
                else:
                    marks = []
                    for lm in g.landmarks:
                        if len(lm.parts) == 1 and lm.primary == "obj":
                            marks.append(lm.as_dict["obj"])
                        else:
                            marks.append(robot.get_major_map(**lm.as_dict, primary=lm.primary))
                    target = getattr(robot, g.relation)(*marks)
                    out = self._outcome(robot, g.text, "goal", True, "", [target])
            except GoalNotFound as e:
                out = self._outcome(robot, g.text, "goal", False, str(e))
            except TabletopError as e:
                out = QueryOutcome(g.text, "goal", False, f"{type(e).__name__}: {e}")
        return _timed(out, t0)

    # ------------------------------------------------------------------ reaching
    def _arm_robot(self):
        """The arm "go" runs: the simulated Panda in the map's scene (physics, contacts
        counted) when the map says which scene it was built from, else an ideal kinematic arm
        on the map's obstacles. Its joints are logged at 30 Hz for the animation."""
        if self._arm is not None:
            return self._arm
        from tabletop.arm.driver import KinematicDriver
        from tabletop.robot.arm import ArmRobot, SimArm

        m = self._need_map()
        spec, why = self._scene_spec(m)
        log_q: list = []
        if spec is not None:
            arm = SimArm(m, spec)
            drv = arm.driver
            inner = drv.on_step
            count = [0]

            def on_step() -> None:
                if inner is not None:
                    inner()
                count[0] += 1
                if count[0] % 8 == 0:  # 240 Hz physics -> 30 Hz frames
                    log_q.append(drv.read_state().q)

            drv.on_step = on_step
            self._arm_kind = f"the simulated Panda in scene {spec.name!r} (PyBullet physics)"
        else:

            class _Logged(KinematicDriver):
                def command_positions(self, q, duration):
                    super().command_positions(q, duration)
                    log_q.append(self.read_state().q)

                def command_velocities(self, dq, duration):
                    super().command_velocities(dq, duration)
                    log_q.append(self.read_state().q)

                def execute_trajectory(self, trajectory):
                    super().execute_trajectory(trajectory)
                    step = max(1, round(1 / 30 / trajectory.period))
                    log_q.extend(np.asarray(trajectory.q)[::step])

            arm = ArmRobot(m, _Logged())
            self._arm_kind = f"an ideal kinematic arm on the map's obstacles ({why})"
        arm.reader = self.reader
        self._arm = arm
        self._log_q = log_q
        return arm

    def _scene_spec(self, m):
        """(the scene spec the arm runs in, or None and why not)."""
        from tabletop.mapping.persistence import scene_fingerprint
        from tabletop.sim.scene import load_scene_spec

        name = self.scene or (m.source or {}).get("scene")
        if not name:
            return None, "the map does not say which scene it was built from; give --scene"
        try:
            spec = load_scene_spec(name)
        except TabletopError as e:
            return None, f"its scene {name!r} cannot be loaded: {e}"
        built = (m.source or {}).get("scene_fingerprint")
        if self.scene is None and built is not None and built != scene_fingerprint(spec.to_dict()):
            return None, f"the shipped scene {name!r} is not the one the map was built from"
        return spec, ""

    def reach(self, targets) -> ReachOutcome:
        """Send the robot to each of ``targets`` (K, 3) [m] in order: the arm's reach
        controller (approached from above, as ``move_to`` does), or a room's wheeled base
        (planned on its obstacle grid, driven by its follower)."""
        pts = np.asarray(targets, np.float64).reshape(-1, 3)
        if not len(pts):
            raise ConfigError("no target to go to: ask the map first")
        with self._lock:
            if self.room:
                return self._drive(pts)
            arm = self._arm_robot()
            self._log_q.clear()
            start = arm.driver.read_state().q
            self._log_q.append(start)
            results = []
            for p in pts:
                r = arm.move_to(p)
                contacts = getattr(arm, "contacts", None)
                results.append(
                    {
                        "reached": bool(r.reached),
                        "reason": r.reason.value,
                        "requested": p,
                        "final": np.asarray(r.final_tcp),
                        "error_m": float(r.requested_error_m),
                        "clearance_m": float(r.min_clearance_m),
                        "route": r.route.value,
                        "note": r.note,
                        "contacts": None if not contacts else int(contacts[-1]),
                    }
                )
            q = arm.driver.read_state().q
            self._log_q.append(q)
            self.arm_q = np.asarray(q)
            frames = np.stack(self._log_q)
        return ReachOutcome("arm", frames, tuple(results), simulator=self._arm_kind)

    def _drive(self, pts: np.ndarray) -> ReachOutcome:
        from tabletop.base import TABLETOP_BASE, KinematicBaseDriver
        from tabletop.robot.wheeled import MobileRobot

        if self._base is None:
            drv = KinematicBaseDriver(TABLETOP_BASE, self.base_start())
            self._base = MobileRobot(self._need_map(), drv)
        base = self._base
        p = base.driver.read_odometry()
        frames = [np.array([p.x, p.y, p.yaw])]
        results, planned = [], []
        for target in pts:
            r = base.move_to(target)
            if len(r.driven):
                frames.extend(np.asarray(r.driven)[:: max(1, len(r.driven) // 300)])
            results.append(
                {
                    "reached": bool(r.reached),
                    "reason": r.reason,
                    "requested": target,
                    "final": np.asarray(r.final_position),
                    "error_m": float(r.error_m),
                    "route": f"planned, {r.length_m:.2f} m" + (
                        ", goal moved out of an obstacle" if r.goal_shifted else ""
                    ),
                }
            )  # fmt: skip
            planned.append(np.asarray(r.planned))
        p = base.driver.read_odometry()
        frames.append(np.array([p.x, p.y, p.yaw]))
        kind = "an ideal kinematic base (no physics) on the ground base's obstacle grid"
        return ReachOutcome("base", np.stack(frames), tuple(results), tuple(planned), kind)

    # ------------------------------------------------------------------ evaluation
    def eval_goals(self) -> list[EvalGoal]:
        """The goals of the evaluation in :attr:`eval_dir` that ran on this map (its task's map
        file or scene), of the encoder set the map was built with when several ran; every
        goal when none ran on it (each marked)."""
        if self.eval_dir is None:
            return []
        p = self.eval_dir / "results.json"
        try:
            d = json.loads(p.read_text())
            rows = d["rows"]
        except (OSError, ValueError, KeyError, TypeError) as e:
            raise ConfigError(
                f"--eval {str(self.eval_dir)!r}: no readable results.json ({e})"
            ) from None
        enc = self.preview.header.get("encoder_set")
        rows = [r for r in rows if r.get("encoders") == enc] or rows
        scene = (self.preview.header.get("source") or {}).get("scene")
        goals = []
        for row in rows[:1]:
            for t in row.get("tasks", []):
                mp = t.get("map_file") or ""
                same = bool(mp) and Path(mp).resolve() == self.map_path.resolve()
                same = same or (not mp and scene is not None and t.get("scene") == scene)
                for g in t.get("goals", []):
                    goals.append(
                        EvalGoal(row.get("encoders", ""), t.get("task", ""), t.get("scene", ""),
                                 g, same)
                    )  # fmt: skip
        mine = [g for g in goals if g.same_map]
        return mine or goals


def _with_near(text: str, near: str, near_kind: str) -> str:
    """A request with a "near" part in words, as a person would add it (the reader reads the
    whole): "<request> near <object>", "... near the sound of <sound>", "... in <area>"."""
    if not near:
        return text
    k = KINDS[near_kind]
    if k == "sound" and "sound" not in near.lower():
        return f"{text} near the sound of {near}"
    if k == "area":
        return f"{text} in {near}"
    if k == "img":
        raise ConfigError(
            "a request cannot be narrowed by an image file: read the first box as an object, "
            "a sound or an area, then 'near' as an image file"
        )
    return f"{text} near {near}"


def _timed(out: QueryOutcome, t0: float) -> QueryOutcome:
    from dataclasses import replace

    return replace(out, seconds=time.perf_counter() - t0)
