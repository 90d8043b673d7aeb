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

Whether words name anything of the vocabulary at all is decided by the reader's refusal head
(:class:`RefusalHead`) where the file holds one: a logistic regression on the evidence the
object module's fixed rules look at (the cosine with the nearest name, the nearest thing of no
kind, whether the words are one name's own, the reader's reading), fitted on readings of
authors the reader had not seen (each tune pool read by a reader fitted without it).

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

__all__ = [
    "KIND_READER_PATH",
    "OTHER",
    "REFUSAL_FEATURES",
    "KindReader",
    "RefusalHead",
    "fit_kind_reader",
    "fit_refusal_head",
]

#: The committed reader (``tabletop train kind-reader``).
KIND_READER_PATH = DATA_DIR / "weights" / "kind_reader.json"
#: The class of words that name none of the kinds.
OTHER = "<other>"
#: What the refusal head weighs, in this order (see :class:`RefusalHead`): the words' best
#: cosine with a vocabulary name or description, their best cosine with a thing of no kind
#: (the object module's ``others``), whether they are one name's own words (1 or 0), the
#: reader's probability where it reads no kind (else 0), its probability where it reads a
#: kind (else 0), and a constant 1.
REFUSAL_FEATURES = ("text_score", "other_score", "described", "read_other", "read_kind", "bias")


class RefusalHead:
    """Whether a query's words name nothing of the vocabulary: a logistic regression on
    :data:`REFUSAL_FEATURES`, fitted on how words of authors the reader had not seen read
    (each tune pool's names and absent things, by a reader fitted without that pool;
    ``tabletop train kind-reader``). It replaces the object module's fixed rules (a cosine
    floor, a nearer other thing, the reader's rescue) with one weighing of the same evidence.
    """

    def __init__(self, weights, accept_at: float = 1.0, refuse_below: float = 0.0) -> None:
        self.accept_at = float(accept_at)
        """Words whose cosine with a vocabulary name or description reaches this are never
        refused: nearer than any word of no kind came in training (by a margin). A name or a
        description a user adds is then found though the reader never saw it."""
        self.refuse_below = float(refuse_below)
        """Words whose cosine stays below this are refused unless the reader is sure of a
        kind: farther from every name than all but 0.1 % of the names people used in
        training ("off to the right" is no object, whatever the reader half makes of it)."""
        if not (np.isfinite(self.accept_at) and np.isfinite(self.refuse_below)):
            raise AssetError(
                f"a refusal head's accept_at and refuse_below must be finite, got "
                f"{accept_at!r}, {refuse_below!r}"
            )
        self.weights = np.asarray(weights, np.float64)
        if self.weights.shape != (len(REFUSAL_FEATURES),) or not np.all(np.isfinite(self.weights)):
            raise AssetError(
                f"a refusal head holds {len(REFUSAL_FEATURES)} finite weights "
                f"({', '.join(REFUSAL_FEATURES)}), got {self.weights.tolist()}"
            )

    @staticmethod
    def vector(features) -> np.ndarray:
        """(len(REFUSAL_FEATURES),) of ``features`` (a mapping of :data:`REFUSAL_FEATURES`
        less "bias"), in order, the constant 1 last: a row of :func:`fit_refusal_head`'s."""
        return np.array([1.0 if k == "bias" else float(features[k]) for k in REFUSAL_FEATURES])

    def logit(self, features) -> float:
        """The log-odds that words with ``features`` (a mapping of :data:`REFUSAL_FEATURES`
        less "bias") name nothing of the vocabulary; refuse above 0."""
        return float(self.vector(features) @ self.weights)

    def refuses(self, features, reader_min: float = 0.7) -> bool:
        """Whether words with ``features`` name nothing of the vocabulary: below
        ``refuse_below`` unless the reader reads a kind at ``reader_min`` or more (a word the
        reader knows though the vocabulary describes it in none of its words), else by the
        head's log-odds, never at ``accept_at`` or above."""
        t = features["text_score"]
        if t < self.refuse_below and features["read_kind"] < reader_min:
            return True
        return t < self.accept_at and self.logit(features) > 0

    def to_dict(self) -> dict:
        return {
            "features": list(REFUSAL_FEATURES),
            "weights": self.weights.round(6).tolist(),
            "accept_at": round(self.accept_at, 4),
            "refuse_below": round(self.refuse_below, 4),
        }

    @classmethod
    def from_dict(cls, d) -> RefusalHead:
        if not isinstance(d, dict) or tuple(d.get("features", ())) != REFUSAL_FEATURES:
            raise AssetError(f"a refusal head must weigh {list(REFUSAL_FEATURES)}, got {d!r}")
        return cls(d["weights"], d.get("accept_at", 1.0), d.get("refuse_below", 0.0))


def fit_refusal_head(
    features: np.ndarray,
    refuse: np.ndarray,
    refuse_weight: float = 2.0,
    l2: float = 1e-3,
    accept_margin: float = 0.05,
) -> RefusalHead:
    """The :class:`RefusalHead` of ``features`` ((n, len(REFUSAL_FEATURES)), the last column
    1) labelled ``refuse`` ((n,) bool: words of no kind): class-weighted cross-entropy (a word
    of no kind weighs ``refuse_weight`` as much as a name: a thing found that is not there
    sends the robot somewhere wrong), plus ``l2`` times the squared weights but the constant's,
    minimised by L-BFGS from zero (deterministic). Its ``accept_at`` is the cosine that only 1 %
    of the words of no kind reached, plus ``accept_margin`` (not the highest: one absent thing
    a description names nearly word for word, "a six-sided die" against "six-sided, like a
    die", would otherwise let the head refuse every name or description a user adds below it);
    its ``refuse_below`` the cosine that only 0.1 % of the names (words of a kind) fell below."""
    from scipy.optimize import minimize

    x = np.asarray(features, np.float64)
    y = np.asarray(refuse, bool)
    if x.ndim != 2 or x.shape[1] != len(REFUSAL_FEATURES) or len(x) != len(y):
        raise ValueError(f"features must be (n, {len(REFUSAL_FEATURES)}) with n labels")
    if y.all() or not y.any():
        raise ValueError("a refusal head needs words of a kind and words of none")
    sw = np.where(y, refuse_weight, 1.0)
    sw = sw / sw.sum()
    free = np.array([k != "bias" for k in REFUSAL_FEATURES], float)

    def loss(w):
        z = x @ w
        # log(1 + e^z) and its derivative, stable for large |z|
        soft = np.logaddexp(0.0, z)
        p = np.exp(z - soft)
        value = (sw * (soft - y * z)).sum() + l2 * ((w * free) ** 2).sum()
        grad = x.T @ (sw * (p - y)) + 2 * l2 * w * free
        return value, grad

    res = minimize(loss, np.zeros(x.shape[1]), jac=True, method="L-BFGS-B")
    cosine = x[:, REFUSAL_FEATURES.index("text_score")]
    nearest_none = float(np.quantile(cosine[y], 0.99))
    farthest_name = float(np.quantile(cosine[~y], 0.001))
    return RefusalHead(res.x, min(1.0, nearest_none + accept_margin), farthest_name)


class KindReader:
    """Softmax regression from a unit text embedding to :attr:`classes` (vocabulary names and
    :data:`OTHER`)."""

    def __init__(
        self,
        classes,
        space: str,
        weights: np.ndarray,
        bias: np.ndarray,
        meta=None,
        refusal: RefusalHead | None = None,
    ):
        self.refusal = refusal
        """Its refusal head (None: the object module's fixed rules decide)."""
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
            **({"refusal": self.refusal.to_dict()} if self.refusal is not None else {}),
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
            head = d.get("refusal")
            reader = cls(
                d["classes"],
                d["space"],
                d["weights"],
                d["bias"],
                d.get("meta"),
                RefusalHead.from_dict(head) if head is not None else None,
            )
        except (OSError, ValueError, KeyError, TypeError, AttributeError, AssetError) as e:
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
