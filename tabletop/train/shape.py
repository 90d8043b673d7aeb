"""Fitting the object module's shape prior (:mod:`tabletop.mapping.shape`) from scenes'
matched instances (``tabletop train shape``; the instances come from maps of generated scenes,
:mod:`tabletop.eval.shape_data`).

:func:`fit_from_scenes` fits a logistic regression on the training scenes, chooses its weight
against the image encoder by leaving one training scene out at a time, and measures top-1 kind
(image alone, shape alone, both) on the validation scenes; the figures go into the file's
``meta``.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from tabletop.errors import ConfigError

__all__ = ["WEIGHTS", "fit_from_scenes", "fused_probabilities"]

log = logging.getLogger(__name__)


def fused_probabilities(prior, scene: dict, weight: float, temperature: float) -> np.ndarray:
    """(n, V) the object module's kind probabilities over a scene's vocabulary
    (:meth:`~tabletop.mapping.shape.ShapePrior.fuse` of the image cosines at ``temperature``)
    with the prior at ``weight``."""
    return prior.fuse(scene["cos"] / temperature, scene["x"], scene["vocabulary"], weight)


#: Exponents of the prior tried when fitting how much it counts against the image encoder.
WEIGHTS = (0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0)


def fit_from_scenes(
    train: list[dict], val: list[dict], temperature: float, out, t0=None, about=None
):
    """Fit the prior on ``train`` scenes and its weight against the image encoder (the
    smallest of :data:`WEIGHTS` within one nat of the best log-likelihood of the true kinds,
    each training scene judged by a prior fitted without it), measure both on ``val``, save to
    ``out``. Scenes are :func:`tabletop.eval.shape_data.collect_scene` dicts; ``about``: more
    ``meta`` (where the scenes came from)."""
    from tabletop.mapping.shape import ShapePrior, fit_shape_prior

    t0 = time.monotonic() if t0 is None else t0
    train = [s for s in train if len(s["y"])]
    if len(train) < 2 or not any(len(s["y"]) for s in val):
        raise ConfigError("the shape prior needs instances in 2 training scenes and 1 validation")
    stack = lambda ss, k: np.vstack([s[k] for s in ss])  # noqa: E731
    labels = lambda ss: [t for s in ss for t in s["y"]]  # noqa: E731
    prior = fit_shape_prior(stack(train, "x"), labels(train))

    def loglik(prior_of, scenes, w):
        total = 0.0
        for s, p_ in zip(scenes, prior_of, strict=True):
            p = fused_probabilities(p_, s, w, temperature)
            idx = [s["vocabulary"].index(t) for t in s["y"]]
            total += float(np.log(np.maximum(p[np.arange(len(idx)), idx], 1e-12)).sum())
        return total

    # Cross-fitted priors: each training scene judged by a prior that never saw it.
    held = [
        fit_shape_prior(
            stack([t for t in train if t is not s], "x"), labels([t for t in train if t is not s])
        )
        for s in train
    ]
    fits = {w: loglik(held, train, w) for w in WEIGHTS}
    # The smallest weight within one nat of the best: the image encoder keeps a say wherever
    # trusting the shape more buys (almost) nothing.
    weight = min(w for w, v in fits.items() if v >= max(fits.values()) - 1.0)

    def accuracy(scenes, probs) -> float:
        ok = [
            names[int(i)] == t
            for s in scenes
            for names, p in [probs(s)]
            for i, t in zip(p.argmax(1), s["y"], strict=True)
        ]
        return float(np.mean(ok))

    def top1(scenes, w):
        return accuracy(
            scenes, lambda s: (s["vocabulary"], fused_probabilities(prior, s, w, temperature))
        )

    def shape_top1(scenes):
        return accuracy(scenes, lambda s: (prior.kinds, prior.probabilities(s["x"])))

    meta = {
        "train_scenes": len(train),
        "val_scenes": len(val),
        **(about or {}),
        "train_instances": len(labels(train)),
        "val_instances": len(labels(val)),
        "shape_only_val_top1": shape_top1(val),
        "image_only_val_top1": top1(val, 0.0),
        "fused_val_top1": top1(val, weight),
        "weight": weight,
        "weight_loglik": {str(k): round(v, 2) for k, v in fits.items()},
        "temperature": temperature,
        "seconds": round(time.monotonic() - t0, 1),
    }
    sizes = {float(s.get("voxel_size", 0.01)) for s in train + val}
    if len(sizes) != 1:
        raise ConfigError(f"the scenes' maps have different voxel sizes {sorted(sizes)}")
    prior = ShapePrior(prior.kinds, prior.mean, prior.std, prior.weights, meta, weight, *sizes)
    prior.save(out)
    log.info("shape prior: weight %.2f, validation top-1 image %.3f -> fused %.3f",
             weight, meta["image_only_val_top1"], meta["fused_val_top1"])  # fmt: skip
    return Path(out)
