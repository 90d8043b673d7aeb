"""Teleop-style scans: drive the Panda's joints along smooth camera sweeps, record the wrist
camera at 30 Hz of simulated time, then visit table regions in short audio episodes into whose
audio track a sound-bank clip is inserted.

The camera path comes from :mod:`tabletop.sim.teleop`; each pose is reached by inverse
kinematics warm-started from the previous frame, so the recorded motion is a continuous joint
trajectory. Every frame's joints are set in the simulator, its clearance to the table and
objects is checked, and the recorded end-effector pose is the simulator's forward kinematics
of those joints, never the commanded pose.
"""

from __future__ import annotations

import functools
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, fields

import numpy as np

from tabletop.arm.model import TCP_FRAME
from tabletop.errors import ConfigError, SimulationError
from tabletop.recording import Recording, Segment
from tabletop.sim.camera import WristCameraConfig
from tabletop.sim.noise import NoiseConfig
from tabletop.sim.scan_frames import FrameRecorder, FrameState, assemble_recording
from tabletop.sim.scene import SceneSpec
from tabletop.sim.teleop import (
    Keyframe,
    dwell_keyframes,
    look_at,
    mapping_keyframes,
    sample_path,
    transit_keyframes,
)
from tabletop.sim.world import HOME_Q, SimWorld
from tabletop.transforms import invert

__all__ = ["ScanConfig", "ScanStats", "T_hand_tcp", "plan_scan", "run_scan"]

log = logging.getLogger(__name__)


def check_field_types(config, what: str, strings: bool = False) -> None:
    """Refuse a scan config (a dataclass) whose ``int`` or ``float`` field is not a finite
    number of that type (a bool is none), or, with ``strings``, whose ``str`` field is not a
    string; fields in their order, the first wrong one named after ``what`` ("scan", "room
    scan"). The table's and the rooms' scan configs check their fields through this."""
    for f in fields(config):
        v = getattr(config, f.name)
        if f.type in ("int", "float") and (
            isinstance(v, bool)
            or not isinstance(v, (int, float) if f.type == "float" else int)
            or not math.isfinite(v)
        ):
            raise ConfigError(f"{what} {f.name} must be a finite {f.type}, got {v!r}")
        if strings and f.type == "str" and not isinstance(v, str):
            raise ConfigError(f"{what} {f.name} must be a string, got {v!r}")


@dataclass(frozen=True)
class ScanConfig:
    """How a scan is recorded."""

    seed: int = 0
    """Seed of the path variations, the hand tremor and the sound placement."""
    rate_hz: float = 30.0
    """Frame rate [Hz] of simulated time."""
    speed: float = 0.15
    """Nominal camera speed [m/s] along the sweeps."""
    tremor_m: float = 0.004
    """Amplitude [m] of the operator's hand tremor (0 = none)."""
    episodes: int = 6
    """Audio episodes after the mapping sweep (0 = no audio)."""
    episode_s: float = 4.0
    """Length [s] of each audio episode."""
    repeat_sounds: int = 1
    """How many sound categories are inserted in two regions (ambiguous sound goals)."""
    clip_split: str = "heldout"
    """Which sound-bank clips to insert: "heldout" (never seen in training), "train", "any"."""
    snr_db: float = 15.0
    """Clip-to-background ratio [dB] of the inserted sounds."""
    min_recordings: int = 6
    """Only categories with at least this many clips in the bank (all splits) are inserted:
    the categories an encoder could learn from several recordings. A bank with fewer such
    categories than the scan needs lowers it to what it has (see ``sound_insertion``)."""
    min_clearance: float = 0.02
    """Smallest allowed distance [m] between the arm and the table or objects."""
    camera: WristCameraConfig = field(default_factory=WristCameraConfig)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    renderer: str = "auto"
    """"auto" (EGL if it works), "egl" or "tiny"."""

    def __post_init__(self) -> None:
        if isinstance(self.noise, dict):  # from a task file or JSON
            object.__setattr__(self, "noise", NoiseConfig.from_dict(self.noise, "scan noise"))
        if isinstance(self.camera, dict):
            try:
                object.__setattr__(self, "camera", WristCameraConfig(**self.camera))
            except TypeError as e:
                raise ConfigError(f"scan camera: {e}") from None
        check_field_types(self, "scan", strings=True)
        if not isinstance(self.noise, NoiseConfig):
            raise ConfigError(f"scan noise must be a table of noise settings, got {self.noise!r}")
        if not isinstance(self.camera, WristCameraConfig):
            raise ConfigError(
                f"scan camera must be a table of camera settings, got {self.camera!r}"
            )
        if self.seed < 0:
            raise ConfigError(f"scan seed must be >= 0, got {self.seed}")
        if self.tremor_m < 0 or self.min_clearance < 0:
            raise ConfigError("tremor_m and min_clearance must be >= 0 [m]")
        if self.renderer not in ("auto", "egl", "tiny"):
            raise ConfigError(f"renderer must be 'auto', 'egl' or 'tiny', not {self.renderer!r}")
        if self.rate_hz <= 0 or self.speed <= 0:
            raise ConfigError("rate_hz and speed must be positive")
        if self.episodes < 0 or self.episode_s < 1.0:
            raise ConfigError("episodes must be >= 0 and episode_s >= 1 s")
        if not 0 <= self.repeat_sounds <= self.episodes // 2:
            raise ConfigError(
                f"repeat_sounds must be in [0, episodes // 2 = {self.episodes // 2}], "
                f"got {self.repeat_sounds}"
            )
        if self.min_recordings < 1:
            raise ConfigError(f"min_recordings must be >= 1, got {self.min_recordings}")
        if self.clip_split not in ("heldout", "train", "any"):
            raise ConfigError(
                f"clip_split must be 'heldout', 'train' or 'any', not {self.clip_split!r}"
            )


@dataclass(frozen=True)
class ScanStats:
    """What a scan took: frames and simulated/wall-clock time."""

    frames: int
    simulated_s: float
    wall_s: float
    render_s: float
    ik_s: float

    @property
    def fps(self) -> float:
        """Frames recorded per wall-clock second (planning, IK, checks and rendering)."""
        return self.frames / self.wall_s if self.wall_s > 0 else float("inf")


@dataclass(frozen=True)
class _Plan:
    T_world_cam: np.ndarray  # (N, 4, 4) commanded camera poses
    segments: tuple[Segment, ...]
    episode_centers: tuple[tuple[float, float], ...]


def _episode_centers(rng: np.random.Generator, n: int) -> list[tuple[float, float]]:
    """Distinct table regions for the audio episodes, spread over a 3 x 3 grid."""
    xs, ys = (0.40, 0.54, 0.68), (-0.30, 0.0, 0.30)
    cells = [(x, y) for x in xs for y in ys]
    if n > len(cells):
        raise ConfigError(f"at most {len(cells)} audio episodes (one per table region), got {n}")
    order = rng.permutation(len(cells))[:n]
    return [
        (cells[i][0] + rng.uniform(-0.03, 0.03), cells[i][1] + rng.uniform(-0.04, 0.04))
        for i in order
    ]


#: The planner samples camera poses this many times per frame; retiming then picks frames.
_OVERSAMPLE = 4
#: How closely the arm must follow the planned camera path.
_PATH_TOL_M, _PATH_TOL_RAD = 0.002, np.deg2rad(0.5)
#: Retiming keeps every joint below this fraction of its velocity limit.
_VELOCITY_FRACTION = 0.6


@functools.cache
def T_hand_tcp() -> np.ndarray:
    """(4, 4) pose of the tool centre point in the hand frame (fixed by the URDF)."""
    from tabletop.arm import HOME_Q, TCP_FRAME, PandaModel

    model = PandaModel()
    return invert(model.fk(HOME_Q, frame="panda_hand")) @ model.fk(HOME_Q, frame=TCP_FRAME)


def plan_scan(config: ScanConfig) -> _Plan:
    """Commanded camera poses of a whole scan, sampled ``_OVERSAMPLE`` times per frame:
    the mapping sweep, then a transit and an episode per audio region."""
    rng = np.random.default_rng(config.seed)
    rate, speed, tremor = config.rate_hz * _OVERSAMPLE, config.speed, config.tremor_m
    poses = [sample_path(mapping_keyframes(rng), rate, speed, rng, tremor)]
    segments = [Segment("mapping", "mapping", 0, len(poses[0]))]
    last = mapping_keyframes(np.random.default_rng(config.seed))[-1]
    centers = _episode_centers(rng, config.episodes)
    n = len(poses[0])
    T_cam_tcp = invert(config.camera.T_hand_cam) @ T_hand_tcp()
    for i, c in enumerate(centers):
        dwell = dwell_keyframes(c, rng)
        # Shift the hover so that the tool centre point, not the camera, is above the region.
        tcp = look_at(np.array(dwell[0].eye), np.array(dwell[0].target), dwell[0].roll) @ T_cam_tcp
        delta = np.array([c[0] - tcp[0, 3], c[1] - tcp[1, 3], 0.0])
        dwell = [
            Keyframe(tuple(np.add(k.eye, delta)), tuple(np.add(k.target, delta)), k.roll)
            for k in dwell
        ]
        transit = sample_path(transit_keyframes(last, dwell[0]), rate, speed, rng, tremor)[1:]
        poses.append(transit)
        segments.append(Segment(f"transit_{i}", "transit", n, n + len(transit)))
        n += len(transit)
        # Loop the hover until the episode is long enough.
        loop = [*dwell, dwell[0]]
        ep = sample_path(loop, rate, 0.03, rng, tremor)[1:]
        while len(ep) < config.episode_s * rate:
            ep = np.concatenate([ep, ep])
        ep = ep[: round(config.episode_s * rate)]
        poses.append(ep)
        segments.append(Segment(f"episode_{i}", "episode", n, n + len(ep)))
        n += len(ep)
        last = dwell[0]
    return _Plan(np.concatenate(poses), tuple(segments), tuple(centers))


def _solve_path(T_world_hand: np.ndarray, q0: np.ndarray):
    """Joint positions (N, 7) tracking hand poses, each IK warm-started from the last."""
    from tabletop.arm import PandaModel, solve_ik

    model = PandaModel()
    qs = np.empty((len(T_world_hand), 7))
    q = np.asarray(q0, dtype=np.float64)
    for i, T in enumerate(T_world_hand):
        res = solve_ik(model, T, q, frame="panda_hand")
        # The recorded pose is the forward kinematics of the joints, so a scan only needs
        # to follow its path closely, not to the IK's default 0.1 mm.
        if res.pos_error_m > _PATH_TOL_M or res.rot_error_rad > _PATH_TOL_RAD:
            raise SimulationError(
                f"scan pose {i} is not reachable (IK error {res.pos_error_m * 1000:.1f} mm, "
                f"{np.rad2deg(res.rot_error_rad):.1f} deg); shorten or lower the sweep"
            )
        q = res.q
        qs[i] = q
    return qs, model.v_max


def _retime(
    q_dense: np.ndarray, dense_rate: float, rate: float, v_max: np.ndarray, fraction: float
) -> np.ndarray:
    """Resample a dense joint path at ``rate``, slowing where a joint would exceed
    ``fraction * v_max``: each dense step takes at least as long as its fastest joint needs.
    """
    step = np.abs(np.diff(q_dense, axis=0))
    dt = np.maximum(1.0 / dense_rate, (step / (fraction * v_max)).max(axis=1))
    t_dense = np.concatenate([[0.0], np.cumsum(dt)])
    t = np.arange(0.0, t_dense[-1] + 1e-9, 1.0 / rate)
    q = np.stack([np.interp(t, t_dense, q_dense[:, j]) for j in range(7)], axis=1)

    def frame_of(dense_index: int) -> int:
        """First frame at or after a dense sample's time."""
        if dense_index >= len(t_dense):
            return len(t)
        return int(np.searchsorted(t, t_dense[dense_index] - 1e-9))

    return q, frame_of


def _approach(start_q: np.ndarray, q: np.ndarray, rate_hz: float, max_vel: float = 0.6):
    """A rest-to-rest joint move (smoothstep) from ``start_q`` to ``q`` at ``rate_hz``."""
    n = max(2, int(np.ceil(np.abs(q - start_q).max() / max_vel * rate_hz * 1.5)))
    s = np.linspace(0.0, 1.0, n)
    s = s * s * (3 - 2 * s)
    return start_q + s[:, None] * (q - start_q)


def run_scan(
    spec: SceneSpec,
    config: ScanConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[Recording, ScanStats]:
    """Scan a scene and return the recording (with ground truth) and timing figures.

    ``progress(done, total)`` is called after each rendered frame.
    """
    if not isinstance(spec, SceneSpec):
        raise ConfigError(
            f"run_scan scans a SceneSpec (tabletop.sim.scene.load_scene_spec('default')), got "
            f"{type(spec).__name__} {spec!r:.60}"
        )
    if config is not None and not isinstance(config, ScanConfig):
        raise ConfigError(f"config must be a ScanConfig or None, got {type(config).__name__}")
    config = config or ScanConfig()
    t_start = time.perf_counter()
    plan = plan_scan(config)
    with SimWorld(spec, config.camera, renderer=config.renderer) as world:
        T_hand_cam = world.camera.T_hand_cam
        t0 = time.perf_counter()
        q_dense, v_max = _solve_path(plan.T_world_cam @ invert(T_hand_cam), HOME_Q)
        ik_s = time.perf_counter() - t0
        # Start from the home pose: the operator first moves the arm into the sweep.
        lead = _approach(HOME_Q, q_dense[0], config.rate_hz * _OVERSAMPLE)[:-1]
        q_dense = np.concatenate([lead, q_dense])
        q_all, frame_of = _retime(
            q_dense, config.rate_hz * _OVERSAMPLE, config.rate_hz, v_max, _VELOCITY_FRACTION
        )
        bounds = [0] + [s.start + len(lead) for s in plan.segments] + [len(q_dense)]
        frames = [int(frame_of(b)) for b in bounds]
        kinds = [("approach", "transit")] + [(s.name, s.kind) for s in plan.segments]
        segments = [
            Segment(name, kind, a, b)
            for (name, kind), a, b in zip(kinds, frames[:-1], frames[1:], strict=True)
        ]
        n = len(q_all)

        def state() -> FrameState:  # the joints the loop below has just set, q
            T = world.T_world_hand()
            return FrameState(T, T, q, world.link_pose(TCP_FRAME)[:3, 3])

        recorder = FrameRecorder(
            world, config.rate_hz, state, None if progress is None else lambda k: progress(k, n)
        )
        for i, q in enumerate(q_all):
            world.set_arm(q)
            clearance = world.min_clearance(max_distance=config.min_clearance + 0.01)
            if clearance < config.min_clearance:
                raise SimulationError(
                    f"scan frame {i}: the arm comes {clearance * 1000:.1f} mm from the scene "
                    f"(minimum {config.min_clearance * 1000:.0f} mm)"
                )
            recorder.capture()
        ground_truth = world.ground_truth()
        renderer = world.renderer
        K = world.intrinsics.K

    rec = assemble_recording(
        recorder.arrays(),
        config=config,
        segments=segments,
        episode_centers=plan.episode_centers,
        ground_truth=ground_truth,
        K=K,
        T_hand_cam=T_hand_cam,
        T_hand_mic=T_hand_tcp(),  # the microphone rides at the tool centre point
        meta={
            "source": "tabletop.sim",
            "scene": spec.name,
            "seed": config.seed,
            "renderer": renderer,
            "rate_hz": config.rate_hz,
        },
    )
    stats = ScanStats(
        frames=len(rec),
        simulated_s=float(n / config.rate_hz),
        wall_s=time.perf_counter() - t_start,
        render_s=recorder.render_s,
        ik_s=ik_s,
    )
    log.info("scan: %d frames in %.1f s (%.1f frames/s)", stats.frames, stats.wall_s, stats.fps)
    return rec, stats
