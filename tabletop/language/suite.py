"""The instruction suite: instructions with hand-written expected code, and how to score a
code generator against it.

A case matches when the generated code and the expected code, both run dry in the sandbox
against the same robot (same map), produce the same motion targets (same count, each within
``tol_m``). The code text may differ: only where the robot would go counts.

The suite ships with a reference map: :func:`reference_map` builds a real
:class:`~tabletop.mapping.avlmap.AVLMap` straight from a scene spec's geometry (no rendering):
object boxes as voxels carrying their label's text embedding, the suite's sounds heard at given
table points, one frame per named table area, and a stand-in for the visual localization
module that knows the suite's goal images. Any other map (a scanned one) works too.
"""

from __future__ import annotations

import functools
import math
import tomllib
import zlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from tabletop.errors import ConfigError, TabletopError
from tabletop.language.errors import LanguageError
from tabletop.mapping import AVLMap, Heatmap, MapConfig
from tabletop.mapping.audio_segments import AudioSegment
from tabletop.robot.api import RobotAPI

__all__ = [
    "DEFAULT_SUITE",
    "BadCase",
    "CaseResult",
    "ImageGoal",
    "PointRobot",
    "ReferenceMap",
    "Suite",
    "SuiteCase",
    "SuiteReport",
    "SuiteSound",
    "evaluate_suite",
    "load_suite",
    "reference_map",
    "suite_image",
    "write_suite_images",
]

DEFAULT_SUITE = Path(__file__).resolve().parent.parent / "data" / "instructions" / "suite.toml"


@dataclass(frozen=True)
class SuiteCase:
    id: str
    family: str
    instruction: str
    expected: str
    """Hand-written robot code whose motion targets the generated code must reproduce."""


@dataclass(frozen=True)
class BadCase:
    """An instruction the offline parser must refuse, naming ``fragment`` in its error."""

    instruction: str
    fragment: str


@dataclass(frozen=True)
class SuiteSound:
    caption: str
    at: tuple[float, float]  # [m] table point beneath the arm while it was heard


@dataclass(frozen=True)
class ImageGoal:
    path: str
    """As written in the instructions (relative to the suite's image directory)."""
    object: str
    """Scene object name the picture looks at (the reference map's stand-in localizes it)."""


@dataclass(frozen=True)
class Suite:
    scene: str
    start: tuple[float, float, float]  # [m] TCP at the start of every case
    sounds: tuple[SuiteSound, ...]
    images: tuple[ImageGoal, ...]
    cases: tuple[SuiteCase, ...]
    unparseable: tuple[BadCase, ...]

    @property
    def families(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for c in self.cases:
            out[c.family] = out.get(c.family, 0) + 1
        return out


SUITE_FORM = (
    'a suite file is TOML with [scene] (name = "...", start = [x, y, z] in m) and one or more '
    "[[case]] tables (id, family, instruction, expected: strings); optional [[sounds]] "
    "(caption, at = [x, y]), [[images]] (path, object) and [[unparseable]] (instruction, "
    "fragment)"
)
"""What :func:`load_suite` needs, quoted in its errors."""

_SUITE_TABLES = {
    "case": ("id", "family", "instruction", "expected"),
    "sounds": ("caption", "at"),
    "images": ("path", "object"),
    "unparseable": ("instruction", "fragment"),
}


def _check_suite_shape(d: dict, where: str) -> None:
    """The suite's tables and fields present with the right types, else a ``ConfigError``
    naming the first that is not and :data:`SUITE_FORM`."""

    def bad(what: str) -> ConfigError:
        return ConfigError(f"suite {where} is malformed: {what}; {SUITE_FORM}")

    if not d:
        raise bad("the file is empty (no tables)")
    scene = d.get("scene")
    if not isinstance(scene, dict):
        raise bad("no [scene] table")
    if not isinstance(scene.get("name"), str) or not scene["name"]:
        raise bad("[scene] has no name (a string)")
    start = scene.get("start")
    if not (
        isinstance(start, list)
        and len(start) == 3
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in start)
        and all(math.isfinite(v) for v in start)
    ):
        raise bad(f"[scene] start must be [x, y, z] in m, three finite numbers, got {start!r}")
    if "case" not in d:
        raise bad("no [[case]] tables")
    for name, keys in _SUITE_TABLES.items():
        items = d.get(name, [])
        if not isinstance(items, list) or (name == "case" and not items):
            raise bad(f"'{name}' must be one or more [[{name}]] tables")
        for i, item in enumerate(items):
            if not isinstance(item, dict):
                raise bad(f"[[{name}]] #{i + 1} is not a table")
            missing = [k for k in keys if k not in item]
            if missing:
                raise bad(f"KeyError: [[{name}]] #{i + 1} lacks {', '.join(missing)}")
            for k in keys:
                v = item[k]
                if k == "at":
                    ok = isinstance(v, list) and len(v) == 2
                    ok = ok and all(isinstance(x, (int, float)) for x in v)
                    if not ok:
                        raise bad(f"[[{name}]] #{i + 1} at must be [x, y] in m, got {v!r}")
                elif not isinstance(v, str):
                    raise bad(f"[[{name}]] #{i + 1} {k} must be a string, got {v!r}")
    unknown = sorted(set(d) - {"scene", *_SUITE_TABLES})
    if unknown:
        raise bad(f"unknown tables {unknown}")


def load_suite(path=None) -> Suite:
    """Read a suite TOML (default: the shipped ``tabletop/data/instructions/suite.toml``); a
    file not of :data:`SUITE_FORM` is a ``ConfigError`` naming what is missing or wrong."""
    p = Path(path) if path is not None else DEFAULT_SUITE
    from tabletop.paths import input_file_problem

    problem = input_file_problem(p)
    if problem is not None:
        raise ConfigError(f"suite file {str(p)!r} {problem}; give a suite TOML file")
    try:
        d = tomllib.loads(p.read_text())
    except UnicodeDecodeError:
        raise ConfigError(f"suite {str(p)!r} is not UTF-8 text; {SUITE_FORM}") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"suite {str(p)!r} is not valid TOML: {e}; {SUITE_FORM}") from None
    _check_suite_shape(d, repr(str(p)))
    try:
        cases = tuple(
            SuiteCase(c["id"], c["family"], c["instruction"], c["expected"]) for c in d["case"]
        )
        suite = Suite(
            scene=d["scene"]["name"],
            start=tuple(float(v) for v in d["scene"]["start"]),
            sounds=tuple(SuiteSound(s["caption"], tuple(s["at"])) for s in d.get("sounds", [])),
            images=tuple(ImageGoal(i["path"], i["object"]) for i in d.get("images", [])),
            cases=cases,
            unparseable=tuple(
                BadCase(b["instruction"], b["fragment"]) for b in d.get("unparseable", [])
            ),
        )
    except (KeyError, TypeError, ValueError) as e:
        raise ConfigError(
            f"suite {str(p)!r} is malformed: {type(e).__name__}: {e}; {SUITE_FORM}"
        ) from None
    ids = [c.id for c in cases]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        raise ConfigError(f"suite {str(p)!r}: duplicate case ids {dup}")
    return suite


# ---------------------------------------------------------------------- the reference map
def suite_image(name: str, size: tuple[int, int] = (48, 64)) -> np.ndarray:
    """(H, W, 3) uint8: the deterministic picture standing for a view of object ``name``."""
    rng = np.random.default_rng(zlib.crc32(name.encode()))
    return rng.integers(0, 256, size=(*size, 3), dtype=np.uint8)


def write_suite_images(suite: Suite, directory) -> Path:
    """Write the suite's goal images (PNG) under ``directory``; return it."""
    import cv2

    d = Path(directory)
    for im in suite.images:
        p = d / im.path
        p.parent.mkdir(parents=True, exist_ok=True)
        if not cv2.imwrite(str(p), suite_image(im.object)[:, :, ::-1]):
            raise ConfigError(f"could not write {str(p)!r}")
    return d


class ReferenceMap(AVLMap):
    """An AVLMap with a stand-in for visual localization: a picture equal to one of
    ``image_views`` localizes to that view's object (the object module's heat, modality
    "image"); any other picture is not found."""

    image_views: dict[str, tuple[np.ndarray, str]]  # path -> (picture, object label)

    def image_heatmap(self, rgb: np.ndarray, major: bool = True) -> Heatmap:
        for name, (view, label) in self.image_views.items():
            if view.shape == rgb.shape and np.array_equal(view, rgb):
                h = self.object_heatmap(label, major=major)
                return replace(h, query=f"image {name}", modality="image")
        return Heatmap.not_found(
            self.grid, "image", "image", self.decay(major), "no view matches the picture"
        )


def reference_map(suite: Suite | None = None, voxel_size: float = 0.02) -> ReferenceMap:
    """A real AVLMap of the suite's scene built from geometry (see the module docstring).

    Loads the text encoder (MiniLM, a few seconds); the rest takes well under a second. The map
    is cached per (suite, voxel size): the same object comes back, so do not change it.
    """
    return _reference_map(suite or load_suite(), voxel_size)


@functools.lru_cache(maxsize=2)
def _reference_map(suite: Suite, voxel_size: float) -> ReferenceMap:
    from tabletop.grid import VoxelGrid
    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder
    from tabletop.sim.scene import load_scene_spec

    spec = load_scene_spec(suite.scene)
    text = MiniLMTextEncoder()
    grid = VoxelGrid(voxel_size=voxel_size)
    m = ReferenceMap(MapConfig(grid=grid), text, None, None, None, {"text": "minilm-l6-v2"})
    labels = ["table"] + [o.label for o in spec.objects]
    table = text.encode_text(labels)
    h = voxel_size / 2
    # the table top: a lattice of surface points
    t = spec.table
    xs = np.arange(max(t.x[0], grid.lower[0]) + h, min(t.x[1], grid.upper[0]), voxel_size)
    ys = np.arange(max(t.y[0], grid.lower[1]) + h, min(t.y[1], grid.upper[1]), voxel_size)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    pts = [np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, -h)], axis=1)]
    idx = [np.zeros(gx.size, np.int64)]
    # each object: the surface of its box (what a camera sees), with its label's embedding
    for i, obj in enumerate(spec.objects, start=1):
        lo, hi = obj.aabb()
        axes = [np.arange(lo[k] + h / 2, hi[k], h) for k in range(3)]
        bx, by, bz = np.meshgrid(*axes, indexing="ij")
        box = np.stack([bx.ravel(), by.ravel(), bz.ravel()], axis=1)
        shell = np.any((box - lo < h) | (hi - box < h), axis=1)
        pts.append(box[shell])
        idx.append(np.full(int(shell.sum()), i, np.int64))
    points = np.concatenate(pts)
    colors = np.full((len(points), 3), 128, np.uint8)
    m.voxels.integrate(points, table, colors, feature_index=np.concatenate(idx))
    # sounds: one segment per suite sound, heard above its table point
    for s in suite.sounds:
        m.sounds.segments.append(AudioSegment(0.0, 0.0))
        m.sounds.embeddings.append(text.encode_text([s.caption])[0])
        m.sounds.positions.append(np.array([s.at[0], s.at[1], 0.3]))
    # areas: one downward view at each named area's centre
    R = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # optical axis down
    for a in spec.areas:
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = [*a.center[:2], 0.4]
        m.areas.add(text.encode_text([a.name])[0], T)
    m._frames_seen = len(spec.areas)
    names = {o.name: o.label for o in spec.objects}
    views = {}
    for im in suite.images:
        if im.object not in names:
            raise ConfigError(f"suite image {im.path!r}: no object {im.object!r}; {sorted(names)}")
        views[im.path] = (suite_image(im.object), names[im.object])
    m.image_views = views
    return m


class PointRobot(RobotAPI):
    """A robot that is only a map and a point: ``move_to`` jumps there (dry runs, suites)."""

    def __init__(self, avlmap, start=(0.3, 0.0, 0.3), spatial=None) -> None:
        super().__init__(avlmap, spatial)
        self._pos = np.array(start, dtype=np.float64)

    def move_to(self, pos):
        self._pos = np.array(pos, dtype=np.float64)
        return None

    def current_position(self) -> np.ndarray:
        return self._pos.copy()


# ---------------------------------------------------------------------- scoring
@dataclass(frozen=True)
class CaseResult:
    case: SuiteCase
    code: str | None
    """The generated code (None: generation failed)."""
    expected_targets: np.ndarray | None  # (K, 3) [m]
    targets: np.ndarray | None  # (K, 3) [m]
    match: bool
    error_m: float | None
    """Largest distance [m] between corresponding targets (None: counts differ or failed)."""
    reason: str = ""
    skipped: bool = False
    """The expected code itself fails on this map (e.g. image goals on a map without visual
    localization): the case is left out of the share."""


@dataclass(frozen=True)
class SuiteReport:
    results: tuple[CaseResult, ...]
    tol_m: float

    @property
    def matched(self) -> int:
        return sum(r.match for r in self.results)

    @property
    def evaluated(self) -> int:
        """Cases whose expected code runs on the map (the share's denominator)."""
        return sum(not r.skipped for r in self.results)

    @property
    def skipped(self) -> int:
        return len(self.results) - self.evaluated

    @property
    def share(self) -> float:
        return self.matched / self.evaluated if self.evaluated else 0.0

    def by_family(self) -> dict[str, tuple[int, int]]:
        """family -> (matched, evaluated)."""
        out: dict[str, list[int]] = {}
        for r in self.results:
            if r.skipped:
                continue
            f = out.setdefault(r.case.family, [0, 0])
            f[0] += r.match
            f[1] += 1
        return {k: (v[0], v[1]) for k, v in out.items()}


def _targets(code: str, robot, start, image_dir) -> np.ndarray:
    from tabletop.language.run import TracingRobot
    from tabletop.language.sandbox import run_code

    tracer = TracingRobot(robot, execute=False, image_dir=image_dir, start=start)
    run_code(code, tracer)
    return tracer.targets


def evaluate_suite(
    robot,
    generate: Callable[[str], str] | None = None,
    suite: Suite | None = None,
    *,
    image_dir=None,
    tol_m: float = 0.005,
    cases: list[str] | None = None,
) -> SuiteReport:
    """Score ``generate`` (default: the offline parser) on ``suite`` against ``robot``'s map.

    Each case's expected code and generated code run dry (nothing moves) from the suite's start
    point; ``image_dir`` holds the suite's goal images (see :func:`write_suite_images`).
    """
    if generate is None:
        from tabletop.language.codegen import instruction_to_code as generate
    suite = suite or load_suite()
    chosen = suite.cases
    if cases is not None:
        known = {c.id for c in suite.cases}
        unknown = [c for c in cases if c not in known]
        if unknown:
            raise ConfigError(f"unknown case ids {unknown}; valid: {sorted(known)}")
        chosen = tuple(c for c in suite.cases if c.id in cases)
    results = []
    for case in chosen:
        try:
            expected = _targets(case.expected, robot, suite.start, image_dir)
        except TabletopError as e:  # e.g. no image goals on this map: the case says nothing
            reason = f"skipped: the expected code fails on this map: {e}"
            results.append(CaseResult(case, None, None, None, False, None, reason, skipped=True))
            continue
        try:
            code = generate(case.instruction)
        except LanguageError as e:
            results.append(CaseResult(case, None, expected, None, False, None, str(e)))
            continue
        try:
            got = _targets(code, robot, suite.start, image_dir)
        except TabletopError as e:
            results.append(CaseResult(case, code, expected, None, False, None, str(e)))
            continue
        if got.shape != expected.shape:
            reason = f"{len(got)} targets, expected {len(expected)}"
            results.append(CaseResult(case, code, expected, got, False, None, reason))
            continue
        err = float(np.linalg.norm(got - expected, axis=1).max()) if len(got) else 0.0
        ok = err <= tol_m
        reason = "" if ok else f"targets differ by {err * 100:.1f} cm"
        results.append(CaseResult(case, code, expected, got, ok, err, reason))
    return SuiteReport(tuple(results), tol_m)
