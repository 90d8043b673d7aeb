"""Calibrated query confidence: the probability that a query's target is right.

A query's raw evidence is the *margin* of its best match over the map's typical match
(object: best voxel score minus the median voxel score; sound: best segment minus the median
segment; image: the photometric agreement beyond chance, kappa, of the best camera pose). A
confidence must mean something: of the queries answered with confidence 0.8, about 80 %
should land within 10 cm of the truth. :func:`fit_platt` fits a logistic
``p = 1 / (1 + exp(-(a * margin + b)))`` (Platt scaling) to labelled queries: queries of
things in the scene (right when the target lands within 10 cm) and queries of things that
are not there (always wrong: the right answer is "not found").

Fitted parameters live per encoder set and modality in ``tabletop/data/calibration/<set>.json``
(written by ``tabletop calibrate``, which also records the held-out reliability: expected
calibration error and the accuracy of the found / not-found decision). A map whose encoder
set has no calibration file uses :data:`UNCALIBRATED` and says so in its reports.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, ConfigError
from tabletop.paths import DATA_DIR
from tabletop.transforms import aabb_distance

__all__ = [
    "CALIBRATION_DIR",
    "MODALITIES",
    "UNCALIBRATED",
    "Calibration",
    "Platt",
    "expected_calibration_error",
    "fit_platt",
    "load_calibration",
]

CALIBRATION_DIR = DATA_DIR / "calibration"
MODALITIES = ("object", "sound", "area", "image")


@dataclass(frozen=True)
class Platt:
    """``p = sigmoid(a * margin + b)``."""

    a: float
    b: float

    def __call__(self, margin) -> np.ndarray | float:
        z = self.a * np.asarray(margin, dtype=np.float64) + self.b
        p = 1.0 / (1.0 + np.exp(-np.clip(z, -50, 50)))
        return float(p) if np.ndim(p) == 0 else p


#: The prior used without a fitted file: 0.5 at a cosine margin of 0.2, steep around it.
UNCALIBRATED = Platt(a=20.0, b=-4.0)


@dataclass(frozen=True)
class Calibration:
    """Per-modality Platt parameters of one encoder set, and how well they held out."""

    encoder_set: str
    models: dict  # modality -> Platt
    report: dict  # held-out figures written by ``tabletop calibrate``
    thresholds: dict = field(default_factory=dict)
    """modality -> the smallest margin reported as found (the operating point); a modality
    without one is found when its confidence reaches ``MapConfig.min_confidence``."""

    def found(self, modality: str, margin: float, confidence: float, min_confidence: float):
        """The found / not-found decision for a query of ``modality``."""
        t = self.thresholds.get(modality)
        return bool(margin >= t) if t is not None else bool(confidence >= min_confidence)

    def confidence(self, modality: str, margin: float) -> float:
        """Calibrated confidence in [0, 1] of a query of ``modality`` with ``margin``."""
        if modality not in MODALITIES:
            raise ConfigError(f"unknown modality {modality!r}; valid: {list(MODALITIES)}")
        return float(self.models.get(modality, UNCALIBRATED)(margin))

    @property
    def calibrated(self) -> tuple[str, ...]:
        """The modalities with fitted parameters."""
        return tuple(m for m in MODALITIES if m in self.models)

    def keep_prior(self, modalities) -> Calibration:
        """This calibration with the fits of ``modalities`` set aside: they answer with the
        prior again, and their fits and held-out figures move to ``report["prior_kept"]``."""
        modalities = list(modalities)
        bad = sorted(set(modalities) - set(MODALITIES))
        if bad:
            raise ConfigError(f"unknown modalities {bad}; valid: {list(MODALITIES)}")
        kept = {
            m: {
                "model": {"a": self.models[m].a, "b": self.models[m].b}
                if m in self.models
                else None,
                "threshold": self.thresholds.get(m),
                "report": self.report.get(m),
            }
            for m in modalities
        }
        report = {k: v for k, v in self.report.items() if k not in modalities}
        return Calibration(
            self.encoder_set,
            {k: v for k, v in self.models.items() if k not in modalities},
            report | {"prior_kept": kept},
            {k: v for k, v in self.thresholds.items() if k not in modalities},
        )

    def to_json(self) -> dict:
        return {
            "format": "tabletop-calibration",
            "version": 1,
            "encoder_set": self.encoder_set,
            "models": {k: {"a": v.a, "b": v.b} for k, v in self.models.items()},
            "thresholds": self.thresholds,
            "report": self.report,
        }

    def save(self, path: str | Path | None = None) -> Path:
        path = Path(path) if path is not None else CALIBRATION_DIR / f"{self.encoder_set}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(self.to_json(), indent=1) + "\n")
        tmp.replace(path)
        return path


def load_calibration(encoder_set: str, path: str | Path | None = None) -> Calibration:
    """The calibration of ``encoder_set`` (every modality :data:`UNCALIBRATED` when no file
    exists); a malformed file raises :class:`AssetError` naming the problem."""
    p = Path(path) if path is not None else CALIBRATION_DIR / f"{encoder_set}.json"
    if not p.is_file():
        if path is not None:
            raise AssetError(f"calibration file {p} does not exist")
        return Calibration(encoder_set, {}, {})
    try:
        d = json.loads(p.read_text())
        if d.get("format") != "tabletop-calibration" or d.get("version") != 1:
            raise ValueError(f"format {d.get('format')!r} v{d.get('version')!r} is not v1")
        models = {}
        for k, v in d["models"].items():
            if k not in MODALITIES:
                raise ValueError(f"unknown modality {k!r} (valid: {list(MODALITIES)})")
            models[k] = Platt(float(v["a"]), float(v["b"]))
        thresholds = {str(k): float(v) for k, v in d.get("thresholds", {}).items()}
        bad = sorted(set(thresholds) - set(MODALITIES))
        if bad:
            raise ValueError(f"thresholds for unknown modalities {bad}")
        return Calibration(str(d["encoder_set"]), models, dict(d.get("report", {})), thresholds)
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        raise AssetError(f"calibration file {p} is malformed: {e}") from None


def fit_platt(margins, correct, l2: float = 0.01, iterations: int = 100) -> Platt:
    """Logistic regression of ``correct`` (bool) on ``margins`` by Newton's method with a
    small L2 penalty on the slope (keeps separable data finite). Needs both classes."""
    x = np.asarray(margins, dtype=np.float64).ravel()
    y = np.asarray(correct, dtype=np.float64).ravel()
    if x.shape != y.shape or x.size < 4:
        raise ConfigError(f"fit_platt needs >= 4 paired samples, got {x.size} and {y.size}")
    if y.min() == y.max():
        raise ConfigError("fit_platt needs right and wrong queries (only one class given)")
    X = np.stack([x, np.ones_like(x)], axis=1)
    w = np.zeros(2)
    reg = np.diag([l2, 0.0])
    for _ in range(iterations):
        p = 1.0 / (1.0 + np.exp(-np.clip(X @ w, -50, 50)))
        g = X.T @ (p - y) + reg @ w
        H = X.T @ (X * (p * (1 - p))[:, None]) + reg + 1e-9 * np.eye(2)
        step = np.linalg.solve(H, g)
        w -= step
        if np.abs(step).max() < 1e-10:
            break
    return Platt(float(w[0]), float(w[1]))


def expected_calibration_error(confidence, correct, bins: int = 10) -> float:
    """Mean |accuracy - confidence| over equal-width confidence bins, weighted by count."""
    c = np.asarray(confidence, dtype=np.float64).ravel()
    y = np.asarray(correct, dtype=np.float64).ravel()
    if c.size == 0:
        return float("nan")
    idx = np.minimum((c * bins).astype(int), bins - 1)
    err = 0.0
    for b in range(bins):
        m = idx == b
        if m.any():
            err += m.sum() * abs(y[m].mean() - c[m].mean())
    return float(err / c.size)


# --------------------------------------------------------------------------- fitting from maps
SUCCESS_M = 0.10
#: An area's truth is its rectangle from the table top up to this height [m] (as in the
#: evaluation's ground truth).
AREA_HEIGHT_M = 0.30

#: Modalities whose module decides found / not found itself (the image module's photometric
#: check; a named table area is always there); calibration gives them a confidence but no
#: operating point.
GATED = ("image", "area")


def calibration_samples(m, ground_truth: dict, image_goals=(), foreign_images=()) -> list[dict]:
    """Labelled queries of one map: ``{"modality", "query", "margin", "correct"}`` each.

    Objects: every object label and every kind name present (right when the target lands
    within 10 cm of an object carrying it) and every catalog kind absent from the scene
    (always wrong). Sounds: the caption of every inserted category (right within 10 cm of the
    column above a place it was inserted, up to where it was heard) and of sound-bank
    categories never inserted (always wrong). Areas: each named table area (right within
    10 cm of its rectangle, up to :data:`AREA_HEIGHT_M`). Images: ``image_goals``
    (:class:`~tabletop.eval.map_goals.MapGoal` of kind ``"image"``, pictures of this scene:
    right when found and within 10 cm of the truth) and ``foreign_images`` ((H, W, 3) uint8
    pictures of other scenes: always wrong).
    """
    from tabletop.eval.map_goals import heard_column
    from tabletop.sim.catalog import OBJECT_KINDS
    from tabletop.sim.sound_bank import SoundBank

    out = []

    def add(modality, query, h, truth):
        if not h.found and h.evidence is None:
            margin, ok = -1.0, False  # nothing matched at all: the weakest evidence there is
        else:
            margin = float(h.evidence)
            ok = bool(truth) and h.values.max() > 0 and min(truth(m.get_max_pos_3d(h))) <= SUCCESS_M
        out.append(
            {
                "modality": modality,
                "query": query,
                "margin": margin,
                "correct": ok,
                "found": h.found,
            }
        )

    objs = ground_truth["objects"]
    by_query: dict[str, list] = {}
    for o in objs:
        by_query.setdefault(o["label"], []).append(o)
        by_query.setdefault(OBJECT_KINDS[o["kind"]].label, []).append(o)
    for q, os_ in sorted(by_query.items()):
        boxes = [(o["aabb_min"], o["aabb_max"]) for o in os_]
        add("object", q, m.object_heatmap(q), lambda p, b=boxes: [aabb_distance(p, *x) for x in b])
    present = {o["kind"] for o in objs}
    for k in sorted(set(OBJECT_KINDS) - present):
        add("object", OBJECT_KINDS[k].label, m.object_heatmap(OBJECT_KINDS[k].label), None)

    events = ground_truth.get("sound_events", [])
    if events:
        heard: dict[str, list] = {}
        for e in events:
            heard.setdefault(e["category"], []).append(e)
        for _cat, es in sorted(heard.items()):
            cols = [heard_column(e) for e in es]
            add(
                "sound",
                es[0]["caption"],
                m.sound_heatmap(es[0]["caption"]),
                lambda p, cols=cols: [aabb_distance(p, *c) for c in cols],
            )
        bank = SoundBank.default()
        for cat in sorted(set(bank.categories) - set(heard)):
            cap = bank.caption(cat)
            add("sound", cap, m.sound_heatmap(cap), None)

    for a in ground_truth.get("areas", []):
        lo, hi = (a["x"][0], a["y"][0], 0.0), (a["x"][1], a["y"][1], AREA_HEIGHT_M)
        add(
            "area",
            a["name"],
            m.area_heatmap(a["name"]),
            lambda p, b=(lo, hi): [aabb_distance(p, *b)],
        )

    def add_image(query, h, truth) -> None:
        # a refused pose is no answer at all: the weakest evidence there is
        margin = float(h.evidence) if h.found else -1.0
        right = h.found and truth is not None and min(truth(h.target)) <= SUCCESS_M
        out.append(
            {"modality": "image", "query": query, "margin": margin, "correct": right}
            | {"found": h.found}
        )

    for i, g in enumerate(image_goals):
        add_image(
            f"goal {i}",
            m.image_heatmap(g.image),
            lambda p, g=g: (
                [aabb_distance(p, *b) for b in g.truth_boxes]
                + [float(np.linalg.norm(p - np.asarray(x))) for x in g.truth_points]
            ),
        )
    for i, img in enumerate(foreign_images):
        add_image(f"foreign {i}", m.image_heatmap(img), None)
    return out


def fit_calibration(
    encoder_set: str, train: list[dict], test: list[dict], keep_right: float = 0.95
) -> Calibration:
    """Platt parameters per modality fitted on ``train``, and an operating point: the margin
    threshold that keeps ``keep_right`` of the right answers of ``train`` reported as found
    (a query of something present is rarely refused; what a weak encoder cannot tell apart
    is then reported with a low confidence instead). The report holds ``test`` figures:
    samples, expected calibration error (fitted and uncalibrated prior), share of right
    answers kept and of wrong ones refused at the operating point."""
    models, report, thresholds = {}, {}, {}
    for mod in MODALITIES:
        tr = [s for s in train if s["modality"] == mod]
        te = [s for s in test if s["modality"] == mod]
        if not tr or len({s["correct"] for s in tr}) < 2:
            continue
        f = fit_platt([s["margin"] for s in tr], [s["correct"] for s in tr])
        models[mod] = f
        right = np.array([s["margin"] for s in tr if s["correct"]])
        t = float(np.quantile(right, 1 - keep_right, method="lower"))
        if mod not in GATED:
            thresholds[mod] = t
        if te:
            x = np.array([s["margin"] for s in te])
            y = np.array([s["correct"] for s in te], dtype=bool)
            p = np.asarray(f(x))
            if mod in GATED:  # the module's own found / not-found decision, not a threshold
                kept = np.array([s["found"] for s in te], dtype=bool)
                empty = None
            else:
                kept, empty = x >= t, float("nan")
            report[mod] = {
                "train_samples": len(tr),
                "test_samples": len(te),
                "test_right": int(y.sum()),
                "ece_test": expected_calibration_error(p, y),
                "ece_test_uncalibrated": expected_calibration_error(UNCALIBRATED(x), y),
                "decision_accuracy_test": float(np.mean((p >= 0.5) == y)),
                "threshold_margin": None if mod in GATED else t,
                "right_kept_test": float(np.mean(kept[y])) if y.any() else empty,
                "wrong_refused_test": float(np.mean(~kept[~y])) if (~y).any() else empty,
            }
    return Calibration(encoder_set, models, report, thresholds)


#: Generator seeds of the calibration scenes (apart from the evaluation suites' seeds).
CALIBRATION_SEEDS = tuple(range(700, 706))


def run_calibration(
    encoder_set: str = "default",
    seeds=CALIBRATION_SEEDS,
    speed: float = 0.3,
    progress=None,
    images: bool = True,
) -> Calibration:
    """Scan a generated scene per seed, build its map with ``encoder_set``, label queries,
    fit on the first half of the scenes and report on the second (held-out scenes). With
    ``images``, each scene's image goals (rendered by a second simulator of it, at poses the
    scan never took) and the previous scene's pictures (foreign: always wrong) are queried too.
    """
    import tempfile

    from tabletop.eval.map_goals import ImageGoalConfig, image_goals
    from tabletop.mapping.avlmap import AVLMap
    from tabletop.sim.scan import ScanConfig, run_scan
    from tabletop.sim.scene import load_scene_spec
    from tabletop.sim.world import SimWorld

    seeds = list(seeds)
    if len(seeds) < 2:
        raise ConfigError("calibration needs at least 2 scene seeds (fit and held-out halves)")
    per_scene, previous = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            path = Path(tmp) / f"calib-{seed}.toml"
            path.write_text(f"[random]\nseed = {seed}\ncount = 9\nduplicates = 2\n")
            spec = load_scene_spec(path)
            rec, _ = run_scan(spec, ScanConfig(seed=seed, speed=speed))
            m = AVLMap.build(rec, encoders=encoder_set)
            goals = []
            if images:
                with SimWorld(spec) as world:
                    cfg = ImageGoalConfig(seed=seed)
                    goals = image_goals(rec.ground_truth, world, cfg, rec.T_world_cam)
                goals = [g for g in goals if g.kind == "image"]
            per_scene.append(calibration_samples(m, rec.ground_truth, goals, previous))
            previous = [g.image for g in goals]
            if progress is not None:
                progress(seed, per_scene[-1])
    half = len(per_scene) // 2
    train = [s for scene in per_scene[:half] for s in scene]
    test = [s for scene in per_scene[half:] for s in scene]
    cal = fit_calibration(encoder_set, train, test)
    cal.report["seeds_fit"] = seeds[:half]
    cal.report["seeds_heldout"] = seeds[half:]
    return cal
