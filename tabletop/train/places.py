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

__all__ = ["MAX_OTHER_AS_REGION", "THRESHOLDS", "fit_classifier", "train_places"]

log = logging.getLogger(__name__)

#: Thresholds tried on the left-out pools, and the share of "other" phrases (things, places
#: off the table) that may be read as a region there.
THRESHOLDS = (0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
MAX_OTHER_AS_REGION = 0.005
#: Logit scale (unit embeddings have small dot products) and L2 weight decay.
SCALE = 10.0
WEIGHT_DECAY = 1e-3


def fit_classifier(x: np.ndarray, y: np.ndarray, n_classes: int, seed: int = 0):
    """(W, b) of a softmax regression on rows ``x`` with labels ``y`` (L-BFGS, deterministic)."""
    import torch

    torch.manual_seed(seed)
    xt = torch.tensor(np.asarray(x, np.float32))
    yt = torch.tensor(np.asarray(y, np.int64))
    w = torch.zeros(xt.shape[1], n_classes, requires_grad=True)
    b = torch.zeros(n_classes, requires_grad=True)
    opt = torch.optim.LBFGS([w, b], max_iter=300, line_search_fn="strong_wolfe")

    def closure():
        opt.zero_grad()
        loss = torch.nn.functional.cross_entropy(xt @ w * SCALE + b, yt)
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


def train_places(texts, out: str | Path, seed: int = 0):
    """Fit the classifier on ``texts`` (:class:`~tabletop.eval.place_texts.PlaceText`), write
    it to ``out`` (atomically) and return it."""
    from tabletop.mapping.encoders.minilm import MINILM_SPACE, MiniLMTextEncoder
    from tabletop.reader.place_words import parse_region
    from tabletop.reader.places import PLACE_CLASSES, PlaceClassifier

    texts = list(texts)
    pools = list(dict.fromkeys(t.pool for t in texts))
    if len(pools) < 2:
        raise ConfigError(f"train places needs phrases of at least two pools, got {pools}")
    t0 = time.monotonic()
    emb = MiniLMTextEncoder().encode_text([t.text for t in texts]).astype(np.float64)
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
    )
    with atomic_path(out) as tmp:
        Path(tmp).write_text(json.dumps(clf.to_json()) + "\n")
    log.info("place classifier written to %s (threshold %.2f)", out, threshold)
    return clf
