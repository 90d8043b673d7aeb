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
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tabletop.atomic import atomic_path
from tabletop.errors import AssetError, ConfigError
from tabletop.paths import DATA_DIR

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

    def judge(self, modality: str, margin: float, min_confidence: float) -> tuple[float, bool]:
        """(confidence, found) of a query of ``modality`` with ``margin``."""
        conf = self.confidence(modality, margin)
        return conf, self.found(modality, margin, conf, min_confidence)

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

    @classmethod
    def from_json(cls, d: dict, where: str = "calibration") -> Calibration:
        """The calibration :meth:`to_json` wrote; a malformed one raises :class:`AssetError`
        naming ``where`` and the problem."""
        try:
            if d.get("format") != "tabletop-calibration" or d.get("version") != 1:
                raise ValueError(f"format {d.get('format')!r} v{d.get('version')!r} is not v1")
            models = {}
            for k, v in d["models"].items():
                if k not in MODALITIES:
                    raise ValueError(f"unknown modality {k!r} (valid: {list(MODALITIES)})")
                models[k] = Platt(float(v["a"]), float(v["b"]))
                if not (math.isfinite(models[k].a) and math.isfinite(models[k].b)):
                    raise ValueError(f"models.{k}: a and b must be finite numbers, got {v!r}")
            thresholds = {str(k): float(v) for k, v in d.get("thresholds", {}).items()}
            for k, v in thresholds.items():
                if not math.isfinite(v):
                    raise ValueError(f"thresholds.{k} must be a finite number, got {v!r}")
            bad = sorted(set(thresholds) - set(MODALITIES))
            if bad:
                raise ValueError(f"thresholds for unknown modalities {bad}")
            return cls(str(d["encoder_set"]), models, dict(d.get("report", {})), thresholds)
        except (ValueError, KeyError, TypeError, AttributeError) as e:
            raise AssetError(f"{where} is malformed: {e}") from None

    def to_json(self) -> dict:
        return {
            "format": "tabletop-calibration",
            "version": 1,
            "encoder_set": self.encoder_set,
            "models": {k: {"a": v.a, "b": v.b} for k, v in self.models.items()},
            "thresholds": self.thresholds,
            "report": self.report,
        }

    def save(self, path: str | Path) -> Path:
        """Write the calibration file to ``path`` atomically (the shipped files live in
        :data:`CALIBRATION_DIR`; pass that path explicitly to replace one)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(self.to_json(), indent=1) + "\n")
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
    except (OSError, ValueError) as e:
        raise AssetError(f"calibration file {p} is unreadable: {e}") from None
    return Calibration.from_json(d, f"calibration file {p}")


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
