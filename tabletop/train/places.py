"""``tabletop train places``: the learned place reader's classifier
(:class:`tabletop.reader.places.PlaceClassifier`) on labelled phrases of the tune pools
(:func:`tabletop.eval.place_texts.place_texts`).

The fit is a multinomial logistic regression on frozen MiniLM sentence embeddings (L-BFGS
from zeros, so the same phrases give the same weights), in seconds on one core. Before the
committed fit, each pool is left out once and predicted by a fit on the others; those
predictions choose the threshold (the lowest that reads at most :data:`MAX_OTHER_AS_REGION`
of the left-out "other" phrases as a region) and give the figures in the weights' ``meta``:
on the phrases the grammar refuses, how many regions the classifier reads right, and how many
other phrases it takes for a region.
"""

from __future__ import annotations

import json
import logging
import time
from pathlib import Path

import numpy as np

from tabletop.atomic import atomic_path
from tabletop.errors import ConfigError

__all__ = [
    "GROUND_FOLDS",
    "GROUND_THRESHOLDS",
    "MAX_ELSEWHERE_AS_SURFACE",
    "MAX_OTHER_AS_REGION",
    "THRESHOLDS",
    "fit_classifier",
    "fit_ground",
    "train_places",
]

log = logging.getLogger(__name__)

#: Thresholds tried on the left-out pools, and the share of "other" phrases (things, places
#: off the table) that may be read as a region there.
THRESHOLDS = (0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
MAX_OTHER_AS_REGION = 0.005
#: Logit scale (unit embeddings have small dot products) and L2 weight decay.
SCALE = 10.0
WEIGHT_DECAY = 1e-3


#: The ground classifier's thresholds tried on folds left out of its fit, the share of grounds
#: that are no work surface (rooms, furniture, things) it may take for one there, and the folds.
GROUND_THRESHOLDS = (0.5, 0.6, 0.7, 0.8, 0.9, 0.95)
MAX_ELSEWHERE_AS_SURFACE = 0.01
GROUND_FOLDS = 5


def fit_classifier(
    x: np.ndarray, y: np.ndarray, n_classes: int, seed: int = 0, balanced: bool = False
):
    """(W, b) of a softmax regression on rows ``x`` with labels ``y`` (L-BFGS, deterministic)."""
    import torch

    torch.manual_seed(seed)
    xt = torch.tensor(np.asarray(x, np.float32))
    yt = torch.tensor(np.asarray(y, np.int64))
    w = torch.zeros(xt.shape[1], n_classes, requires_grad=True)
    b = torch.zeros(n_classes, requires_grad=True)
    opt = torch.optim.LBFGS([w, b], max_iter=300, line_search_fn="strong_wolfe")

    weight = None
    if balanced:  # each class weighs as much as the others in all
        counts = torch.bincount(yt, minlength=n_classes).clamp(min=1).float()
        weight = counts.sum() / (n_classes * counts)

    def closure():
        opt.zero_grad()
        loss = torch.nn.functional.cross_entropy(xt @ w * SCALE + b, yt, weight=weight)
        loss = loss + WEIGHT_DECAY * (w**2).sum()
        loss.backward()
        return loss

    opt.step(closure)
    return w.detach().double().numpy() * SCALE, b.detach().double().numpy()


def _probabilities(x, w, b) -> np.ndarray:
    z = x @ w + b
    z -= z.max(axis=1, keepdims=True)
    p = np.exp(z)
    return p / p.sum(axis=1, keepdims=True)


def _ground(w: np.ndarray, b: np.ndarray, threshold: float = 0.5, meta=None):
    """The :class:`~tabletop.reader.places.GroundClassifier` of a two-class softmax fit
    (class 1: a surface): its logit is the difference of the two classes'."""
    from tabletop.reader.places import GroundClassifier

    return GroundClassifier(w[:, 1] - w[:, 0], float(b[1] - b[0]), threshold, meta or {})


def fit_ground(grounds, encoder, seed: int = 0):
    """The ground classifier (:class:`~tabletop.reader.places.GroundClassifier`) on
    ``grounds`` (:func:`~tabletop.eval.place_texts.ground_texts`): a class-balanced logistic
    regression on their embeddings. Its threshold is the lowest of :data:`GROUND_THRESHOLDS`
    that takes at most :data:`MAX_ELSEWHERE_AS_SURFACE` of the grounds that are no surface for
    one, each ground predicted by a fit without its fold (:data:`GROUND_FOLDS`, seeded)."""
    grounds = list(grounds)
    y = np.array([1 if t.label == "surface" else 0 for t in grounds])
    if y.sum() < GROUND_FOLDS or (1 - y).sum() < GROUND_FOLDS:
        raise ConfigError(
            f"the ground classifier needs at least {GROUND_FOLDS} surfaces and {GROUND_FOLDS} "
            f"other grounds, got {int(y.sum())} and {int((1 - y).sum())}"
        )
    x = encoder.encode_text([t.text for t in grounds]).astype(np.float64)
    fold = np.random.default_rng(seed).permutation(len(grounds)) % GROUND_FOLDS
    held_p = np.zeros(len(grounds))
    for k in range(GROUND_FOLDS):
        held = _ground(*fit_classifier(x[fold != k], y[fold != k], 2, seed, balanced=True))
        held_p[fold == k] = held.probability(x[fold == k])
    sweep = {
        str(th): {
            "surfaces_taken": int((held_p[y == 1] >= th).sum()),
            "surfaces": int(y.sum()),
            "elsewhere_taken_for_surface": int((held_p[y == 0] >= th).sum()),
            "elsewhere": int((1 - y).sum()),
        }
        for th in GROUND_THRESHOLDS
    }
    ok = [
        th
        for th in GROUND_THRESHOLDS
        if sweep[str(th)]["elsewhere_taken_for_surface"]
        <= MAX_ELSEWHERE_AS_SURFACE * sweep[str(th)]["elsewhere"]
    ]
    threshold = min(ok) if ok else max(GROUND_THRESHOLDS)
    missed = [
        t.text
        for t, p in zip(grounds, held_p, strict=True)
        if t.label == "surface" and p < threshold
    ]
    return _ground(
        *fit_classifier(x, y, 2, seed, balanced=True),
        threshold,
        {
            "grounds": len(grounds),
            "surfaces": int(y.sum()),
            "folds": GROUND_FOLDS,
            "seed": seed,
            "held_out_folds": sweep,
            "surfaces_missed_held_out": missed,
        },
    )


def train_places(texts, out: str | Path, seed: int = 0, grounds=None):
    """Fit the classifier on ``texts`` (:class:`~tabletop.eval.place_texts.PlaceText`), and
    its ground classifier on ``grounds`` where given (:func:`fit_ground`), write it to ``out``
    (atomically) and return it."""
    from tabletop.mapping.encoders.minilm import MINILM_SPACE, MiniLMTextEncoder
    from tabletop.reader.place_words import parse_region
    from tabletop.reader.places import PLACE_CLASSES, PlaceClassifier

    texts = list(texts)
    pools = list(dict.fromkeys(t.pool for t in texts))
    if len(pools) < 2:
        raise ConfigError(f"train places needs phrases of at least two pools, got {pools}")
    t0 = time.monotonic()
    encoder = MiniLMTextEncoder()
    emb = encoder.encode_text([t.text for t in texts]).astype(np.float64)
    y = np.array([PLACE_CLASSES.index(t.label) for t in texts])
    pool_of = np.array([pools.index(t.pool) for t in texts])
    refused = np.array([parse_region(t.text) is None for t in texts])
    # each pool predicted by a fit on the others
    probs = np.zeros((len(texts), len(PLACE_CLASSES)))
    for i in range(len(pools)):
        fit = pool_of != i
        w, b = fit_classifier(emb[fit], y[fit], len(PLACE_CLASSES), seed)
        probs[~fit] = _probabilities(emb[~fit], w, b)
    other = PLACE_CLASSES.index("other")
    best = np.argmax(probs, axis=1)
    sweep = {}
    for th in THRESHOLDS:
        pred = np.where((best != other) & (probs.max(axis=1) >= th), best, other)
        region, oth = (y != other) & refused, (y == other) & refused
        sweep[th] = {
            "grammar_refused_regions_right": int((pred[region] == y[region]).sum()),
            "grammar_refused_regions_wrong_region": int(
                ((pred[region] != y[region]) & (pred[region] != other)).sum()
            ),
            "grammar_refused_regions": int(region.sum()),
            "other_read_as_region": int((pred[oth] != other).sum()),
            "other": int(oth.sum()),
        }
    ok = [
        th
        for th, s in sweep.items()
        if s["other_read_as_region"] <= MAX_OTHER_AS_REGION * s["other"]
    ]
    threshold = min(ok) if ok else max(THRESHOLDS)
    w, b = fit_classifier(emb, y, len(PLACE_CLASSES), seed)
    counts = {c: int((y == k).sum()) for k, c in enumerate(PLACE_CLASSES)}
    clf = PlaceClassifier(
        PLACE_CLASSES,
        w,
        b,
        threshold,
        MINILM_SPACE,
        {
            "pools": pools,
            "phrases": len(texts),
            "per_class": counts,
            "seed": seed,
            "leave_one_pool_out": {str(k): v for k, v in sweep.items()},
            "seconds": round(time.monotonic() - t0, 1),
        },
        fit_ground(grounds, encoder, seed) if grounds is not None else None,
    )
    with atomic_path(out) as tmp:
        Path(tmp).write_text(json.dumps(clf.to_json()) + "\n")
    log.info("place classifier written to %s (threshold %.2f)", out, threshold)
    return clf
