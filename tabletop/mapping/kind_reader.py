"""The kind reader: which of the catalog's object kinds a person's words name, or none.

A softmax regression on the text encoder's sentence embedding, trained on how people have named
each kind (the tune paraphrase pools' names, the kinds' labels and descriptions) and on things
none of the kinds is (the pools' absent objects, the object module's ``others``)
(``tabletop train kind-reader``, :mod:`tabletop.train.kind_reader`). Where the cosine with the
nearest label or description is too low to call a name found ("the tin can toy" lies nearer
"tin can" than "toy cylinder"), the reader, which has learned which directions of the embedding
tell the kinds apart, may still name the kind
(:class:`~tabletop.mapping.object_module.ObjectConfig` ``reader_min``). It learns "none of the
kinds" too, so that a thing outside the catalog is not read as the kind nearest it.

The reader belongs to one text encoder's space and one vocabulary: the object module uses it
only where the map's text encoder embeds into :attr:`KindReader.space` and every vocabulary
name is one of :attr:`KindReader.classes`.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError
from tabletop.paths import DATA_DIR

__all__ = ["KIND_READER_PATH", "OTHER", "KindReader", "fit_kind_reader"]

#: The committed reader (``tabletop train kind-reader``).
KIND_READER_PATH = DATA_DIR / "weights" / "kind_reader.json"
#: The class of words that name none of the kinds.
OTHER = "<other>"


class KindReader:
    """Softmax regression from a unit text embedding to :attr:`classes` (vocabulary names and
    :data:`OTHER`)."""

    def __init__(self, classes, space: str, weights: np.ndarray, bias: np.ndarray, meta=None):
        self.classes = tuple(str(c) for c in classes)
        self.space = str(space)
        self.weights = np.asarray(weights, np.float64)
        self.bias = np.asarray(bias, np.float64)
        self.meta = dict(meta or {})
        if OTHER not in self.classes or len(set(self.classes)) != len(self.classes):
            raise AssetError(f"a kind reader's classes must be distinct and hold {OTHER!r}")
        if self.weights.ndim != 2 or self.weights.shape[1] != len(self.classes):
            raise AssetError(
                f"kind reader weights of shape {self.weights.shape} do not fit "
                f"{len(self.classes)} classes"
            )
        if self.bias.shape != (len(self.classes),):
            raise AssetError(f"kind reader bias of shape {self.bias.shape}, expected one per class")

    @property
    def dim(self) -> int:
        return self.weights.shape[0]

    def covers(self, vocabulary) -> bool:
        """Whether every name of ``vocabulary`` is one of the reader's classes."""
        return bool(vocabulary) and set(vocabulary) <= set(self.classes) - {OTHER}

    def probabilities(self, embeddings: np.ndarray) -> np.ndarray:
        """(n, len(classes)) of ``embeddings`` ((n, dim) or (dim,), unit rows)."""
        x = np.atleast_2d(np.asarray(embeddings, np.float64))
        if x.shape[1] != self.dim:
            raise ValueError(f"embeddings of dimension {x.shape[1]}, the reader takes {self.dim}")
        z = x @ self.weights + self.bias
        p = np.exp(z - z.max(axis=1, keepdims=True))
        return p / p.sum(axis=1, keepdims=True)

    def read(self, embedding: np.ndarray) -> tuple[str, float]:
        """The most probable class of one embedding, and its probability."""
        p = self.probabilities(embedding)[0]
        j = int(np.argmax(p))
        return self.classes[j], float(p[j])

    def to_dict(self) -> dict:
        return {
            "format": "tabletop-kind-reader",
            "version": 1,
            "space": self.space,
            "classes": list(self.classes),
            "weights": self.weights.round(6).tolist(),
            "bias": self.bias.round(6).tolist(),
            "meta": self.meta,
        }

    def save(self, path: str | Path) -> None:
        from tabletop.atomic import atomic_path

        with atomic_path(Path(path)) as tmp:
            Path(tmp).write_text(json.dumps(self.to_dict(), allow_nan=False))

    @classmethod
    def load(cls, path: str | Path = KIND_READER_PATH) -> KindReader:
        path = Path(path)
        try:
            d = json.loads(path.read_text())
            if d.get("format") != "tabletop-kind-reader" or d.get("version") != 1:
                raise ValueError("not a 'tabletop-kind-reader' version 1 file")
            reader = cls(d["classes"], d["space"], d["weights"], d["bias"], d.get("meta"))
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
            raise AssetError(
                f"cannot read the kind reader {path} ({e}); `tabletop train kind-reader` writes it"
            ) from e
        if not (np.all(np.isfinite(reader.weights)) and np.all(np.isfinite(reader.bias))):
            raise AssetError(f"the kind reader {path} holds non-finite weights")
        return reader


def fit_kind_reader(
    embeddings: np.ndarray, labels, space: str, l2: float = 1e-6, max_iter: int = 500
) -> KindReader:
    """The :class:`KindReader` of unit ``embeddings`` ((n, D)) labelled ``labels`` (class names,
    :data:`OTHER` among them): the class-balanced cross-entropy plus ``l2`` times the squared
    weights, minimised by L-BFGS from zero (deterministic)."""
    from scipy.optimize import minimize

    x = np.asarray(embeddings, np.float64)
    labels = [str(v) for v in labels]
    if OTHER not in labels:
        raise ValueError(f"training labels must include {OTHER!r} examples")
    classes = (*sorted(set(labels) - {OTHER}), OTHER)
    y = np.array([classes.index(v) for v in labels])
    d = x.shape[1]
    c = len(classes)
    counts = np.bincount(y, minlength=c).astype(np.float64)
    w_class = 1.0 / counts
    w_class /= w_class.mean()
    sample = w_class[y] / w_class[y].sum()
    onehot = np.eye(c)[y]

    def loss(theta):
        w, b = theta[: d * c].reshape(d, c), theta[d * c :]
        z = x @ w + b
        z = z - z.max(axis=1, keepdims=True)
        logp = z - np.log(np.exp(z).sum(axis=1, keepdims=True))
        p = np.exp(logp)
        value = -(sample * (onehot * logp).sum(axis=1)).sum() + l2 * (w**2).sum()
        g = (p - onehot) * sample[:, None]
        grad = np.concatenate([(x.T @ g + 2 * l2 * w).ravel(), g.sum(axis=0)])
        return value, grad

    res = minimize(
        loss, np.zeros(d * c + c), jac=True, method="L-BFGS-B", options={"maxiter": max_iter}
    )
    w, b = res.x[: d * c].reshape(d, c), res.x[d * c :]
    return KindReader(classes, space, w, b, {"l2": l2, "iterations": int(res.nit)})
