"""What an object instance's geometry says about its kind: a shape prior learned from maps.

The image encoder confuses kinds that look alike in a wrist camera's pixels but not in 3D (a
toy cube and a toy prism of one colour: the prism's top is a ridge, the cube's a flat square).
The map already holds each instance's voxels, so its shape is measured, not guessed:

:func:`shape_features` describes an instance's voxels standing on the fitted table by numbers
that do not change when the object turns about the vertical (:data:`FEATURES`): its height, its
footprint's extents along its own principal axes, how much of its bounding rectangle the
footprint fills, and how its top surface is shaped (how much of it lies near the highest point,
the mean and spread of its column heights).

:class:`ShapePrior` is a multinomial logistic regression from those features to the kinds it
was trained on (``tabletop train shape``: instances of maps of generated scenes that no
evaluation, calibration or tuning uses, matched to the simulator's objects). The object module
multiplies an instance's image-based kind probabilities by the prior's raised to a fitted
weight (a product of experts);
a vocabulary name the prior was not trained on gets the prior's uniform share, neither
favoured nor penalised, and a map of another voxel size than the prior's training maps is
judged by its pixels alone (the features depend on the resolution). The weights are a small
JSON file (:data:`SHAPE_PRIOR_PATH`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError
from tabletop.paths import DATA_DIR

__all__ = ["FEATURES", "SHAPE_PRIOR_PATH", "ShapePrior", "shape_features"]

#: The committed shape prior (``tabletop train shape``).
SHAPE_PRIOR_PATH = DATA_DIR / "weights" / "shape_prior.json"

#: What :func:`shape_features` returns, in order (lengths in metres, log where marked).
FEATURES = (
    "log_height",
    "log_major_extent",
    "log_minor_extent",
    "minor_over_major",
    "footprint_fill",
    "top_flat_share",
    "mean_top_over_height",
    "top_spread_over_height",
    "log_voxels_per_column",
)


def shape_features(centers: np.ndarray, voxel_size: float, table_z: float) -> np.ndarray:
    """(len(FEATURES),) of an instance whose voxel centres are ``centers`` ((n, 3) [m], robot
    frame) on a table top at ``table_z`` [m] (see :data:`FEATURES`)."""
    c = np.asarray(centers, np.float64).reshape(-1, 3)
    if not len(c):
        raise ValueError("an instance without voxels has no shape")
    vs = float(voxel_size)
    top = c[:, 2] + vs / 2 - table_z
    height = max(float(top.max()), vs)
    xy = c[:, :2] - c[:, :2].mean(axis=0)
    if len(c) > 1:
        _, vecs = np.linalg.eigh(np.cov(xy.T) + 1e-12 * np.eye(2))
        proj = xy @ vecs[:, ::-1]  # major axis first
    else:
        proj = np.zeros((1, 2))
    major, minor = proj.max(axis=0) - proj.min(axis=0) + vs
    cols, inv = np.unique(np.floor(c[:, :2] / vs).astype(np.int64), axis=0, return_inverse=True)
    col_top = np.full(len(cols), -np.inf)
    np.maximum.at(col_top, inv.reshape(-1), top)
    fill = len(cols) * vs * vs / (major * minor)
    return np.array(
        [
            np.log(height),
            np.log(major),
            np.log(minor),
            minor / major,
            min(fill, 1.5),
            float(np.mean(col_top >= height - 1.5 * vs)),
            float(col_top.mean() / height),
            float(col_top.std() / height),
            np.log(len(c) / len(cols)),
        ]
    )


@dataclass(frozen=True)
class ShapePrior:
    """A multinomial logistic regression from :func:`shape_features` to object kinds."""

    kinds: tuple[str, ...]
    """The kinds' names (what a map's vocabulary calls them)."""
    mean: np.ndarray
    """(F,) feature means of the training instances."""
    std: np.ndarray
    """(F,) their standard deviations."""
    weights: np.ndarray
    """(2F + 1, K): linear, squared and bias terms of the standardised features."""
    meta: dict
    weight: float = 1.0
    """The exponent of its probabilities against the image encoder's (fitted by
    ``tabletop train shape``: 0 ignores the shape)."""
    voxel_size: float = 0.01
    """[m] the voxel size of the maps it was trained on: the features of another resolution
    are not what it learned (:meth:`applies_to`)."""

    def applies_to(self, voxel_size: float) -> bool:
        """Whether a map of ``voxel_size`` [m] is one it can judge (within 5 % of its own)."""
        return abs(float(voxel_size) - self.voxel_size) <= 0.05 * self.voxel_size

    @staticmethod
    def design(z: np.ndarray) -> np.ndarray:
        """(n, 2F + 1): standardised features, their squares and a bias column."""
        z = np.atleast_2d(z)
        return np.hstack([z, z * z, np.ones((len(z), 1))])

    def probabilities(self, features: np.ndarray) -> np.ndarray:
        """(n, K): each instance's probability of each of :attr:`kinds`."""
        z = (np.atleast_2d(features) - self.mean) / self.std
        logits = self.design(np.clip(z, -6, 6)) @ self.weights
        p = np.exp(logits - logits.max(axis=1, keepdims=True))
        return p / p.sum(axis=1, keepdims=True)

    def for_names(self, features: np.ndarray, names) -> np.ndarray:
        """(n, len(names)): :meth:`probabilities` in the order of ``names``; a name the prior
        does not know gets its uniform share ``1 / K``."""
        p = self.probabilities(features)
        out = np.full((len(p), len(names)), 1.0 / len(self.kinds))
        for j, name in enumerate(names):
            if name in self.kinds:
                out[:, j] = p[:, self.kinds.index(name)]
        return out

    def fuse(self, logits: np.ndarray, features: np.ndarray, names, weight=None) -> np.ndarray:
        """(n, C) the object module's kind probabilities: the softmax of the image ``logits``
        ((n, C); the first ``len(names)`` columns are ``names``, any others background
        classes) times this prior's probabilities (:meth:`for_names`; the background
        classes: its uniform share) to ``weight`` (default :attr:`weight`), normalised."""
        w = self.weight if weight is None else float(weight)
        logp = np.asarray(logits, np.float64)
        logp = logp - logp.max(axis=1, keepdims=True)
        if w:
            g = np.full(logp.shape, 1.0 / len(self.kinds))
            g[:, : len(names)] = self.for_names(features, names)
            logp = logp + w * np.log(np.maximum(g, 1e-300))
        p = np.exp(logp - logp.max(axis=1, keepdims=True))
        return p / p.sum(axis=1, keepdims=True)

    def to_dict(self) -> dict:
        return {
            "features": list(FEATURES),
            "kinds": list(self.kinds),
            "mean": self.mean.tolist(),
            "std": self.std.tolist(),
            "weights": self.weights.tolist(),
            "weight": self.weight,
            "voxel_size": self.voxel_size,
            "meta": self.meta,
        }

    def save(self, path: str | Path) -> None:
        from tabletop.atomic import atomic_path

        with atomic_path(Path(path)) as tmp:
            Path(tmp).write_text(json.dumps(self.to_dict(), indent=1, allow_nan=False))

    @classmethod
    def load(cls, path: str | Path = SHAPE_PRIOR_PATH) -> ShapePrior:
        path = Path(path)
        try:
            d = json.loads(path.read_text())
            kinds = tuple(str(k) for k in d["kinds"])
            mean = np.asarray(d["mean"], np.float64)
            std = np.asarray(d["std"], np.float64)
            w = np.asarray(d["weights"], np.float64)
            features = tuple(d["features"])
            weight = float(d["weight"])
            voxel_size = float(d["voxel_size"])
        except (OSError, ValueError, KeyError, TypeError) as e:
            raise AssetError(
                f"cannot read the shape prior {path} ({e}); `tabletop train shape` writes it"
            ) from e
        nf = len(FEATURES)
        if (
            features != FEATURES
            or mean.shape != (nf,)
            or std.shape != (nf,)
            or w.shape != (2 * nf + 1, len(kinds))
            or not len(kinds)
            or not (np.all(np.isfinite(w)) and np.all(np.isfinite(mean)) and np.all(std > 0))
            or not (np.isfinite(weight) and weight >= 0)
            or not (np.isfinite(voxel_size) and voxel_size > 0)
        ):
            raise AssetError(
                f"the shape prior {path} does not fit this version's features {list(FEATURES)}; "
                "`tabletop train shape` writes it"
            )
        return cls(kinds, mean, std, w, dict(d.get("meta", {})), weight, voxel_size)


def fit_shape_prior(
    features: np.ndarray, labels, l2: float = 1e-2, steps: int = 3000, lr: float = 0.5
) -> ShapePrior:
    """The :class:`ShapePrior` of training ``features`` ((n, F)) with kind names ``labels``
    ((n,)): full-batch gradient descent on the L2-regularised cross-entropy (deterministic)."""
    x = np.asarray(features, np.float64)
    labels = [str(v) for v in labels]
    kinds = tuple(sorted(set(labels)))
    y = np.array([kinds.index(v) for v in labels])
    mean, std = x.mean(axis=0), x.std(axis=0) + 1e-6
    d = ShapePrior.design((x - mean) / std)
    onehot = np.eye(len(kinds))[y]
    w = np.zeros((d.shape[1], len(kinds)))
    for _ in range(steps):
        logits = d @ w
        p = np.exp(logits - logits.max(axis=1, keepdims=True))
        p /= p.sum(axis=1, keepdims=True)
        grad = d.T @ (p - onehot) / len(d) + l2 * np.vstack([w[:-1], np.zeros((1, w.shape[1]))])
        w -= lr * grad
    return ShapePrior(kinds, mean, std, w, {})
