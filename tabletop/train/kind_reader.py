"""Training the kind reader (:mod:`tabletop.mapping.kind_reader`; ``tabletop train
kind-reader``).

Its texts (:func:`tabletop.eval.kind_texts.reader_texts`, which the CLI passes in): each
catalog kind's label and descriptions (``descriptions.toml``) and every name the tune
paraphrase pools give it, labelled with the kind's label; a name with a colour's place comes
once without a colour, once with a colour word of the same pool and twice in a colour form of
that pool ("{n}, kind of {c}"), words and forms drawn seeded, so that the reader learns
to pass over what a colour phrase leaves behind. The pools' absent objects and the object
module's ``others`` are labelled :data:`~tabletop.mapping.kind_reader.OTHER`. The held-out
pools (:data:`~tabletop.eval.paraphrase.HELDOUT_POOLS`) are never read.

Before fitting on every pool it measures, pool by pool, a reader fitted without that pool on
that pool's names and absent objects (leave one pool out: how it reads an author it has not
seen), and writes the figures into the file's ``meta``. Those readings, made by an object
module with the map's vocabulary and descriptions, are what its refusal head
(:class:`~tabletop.mapping.kind_reader.RefusalHead`) is fitted on.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from tabletop.mapping.kind_reader import (
    OTHER,
    REFUSAL_FEATURES,
    KindReader,
    RefusalHead,
    fit_kind_reader,
    fit_refusal_head,
)

__all__ = ["train_kind_reader"]

log = logging.getLogger(__name__)


def _figures(reader: KindReader, x: np.ndarray, labels: list[str], threshold: float) -> dict:
    """How ``reader`` reads texts ``x`` labelled ``labels``: names read as their kind (at
    ``threshold``), as another kind, refused; absent objects read as a kind."""
    p = reader.probabilities(x)
    best = p.argmax(axis=1)
    read = [reader.classes[j] if p[i, j] >= threshold else OTHER for i, j in enumerate(best)]
    names = [i for i, v in enumerate(labels) if v != OTHER]
    absent = [i for i, v in enumerate(labels) if v == OTHER]
    n = max(1, len(names))
    return {
        "names": len(names),
        "read_as_kind": round(sum(read[i] == labels[i] for i in names) / n, 4),
        "read_as_another": round(sum(read[i] not in (labels[i], OTHER) for i in names) / n, 4),
        "refused": round(sum(read[i] == OTHER for i in names) / n, 4),
        "absent": len(absent),
        "absent_read_as_kind": round(
            sum(read[i] != OTHER for i in absent) / max(1, len(absent)), 4
        ),
    }


def _object_module(text, vocabulary, descriptions):
    """An object module of no map (no voxels) that reads words as a map's does."""
    from tabletop.grid import VoxelGrid
    from tabletop.mapping.object_module import ObjectModule
    from tabletop.mapping.voxel_map import VoxelMap

    return ObjectModule(VoxelMap(VoxelGrid(), text.dim), text, None, vocabulary, descriptions)


def _refusal_rates(refused: np.ndarray, none: np.ndarray) -> dict:
    """Names refused, and words of no kind let through, of one way of deciding."""
    return {
        "names_refused": round(float(refused[~none].mean()), 4),
        "absent_accepted": round(float((~refused[none]).mean()), 4),
    }


def _refusal_head(records: list[tuple[str, np.ndarray, bool, bool]]) -> tuple[object, dict]:
    """The head fitted on every pool's records ((pool, features, of no kind, the rules'
    refusal)), and pool by pool the head fitted without a pool against the rules on it."""
    pools = tuple(dict.fromkeys(p for p, _, _, _ in records))
    src = np.array([p for p, _, _, _ in records])
    x = np.array([f for _, f, _, _ in records])
    none = np.array([n for _, _, n, _ in records])
    rules = np.array([r for _, _, _, r in records])
    head_refuses = np.zeros(len(records), bool)
    for pool in pools:
        test = src == pool
        held = fit_refusal_head(x[~test], none[~test])
        head_refuses[test] = [
            held.refuses(dict(zip(REFUSAL_FEATURES, f, strict=True))) for f in x[test]
        ]
    figures = {
        "rules": _refusal_rates(rules, none),
        "head": _refusal_rates(head_refuses, none),
        "texts": len(records),
    }
    return fit_refusal_head(x, none), figures


def train_kind_reader(
    out: Path,
    rows: list[tuple[str, str, str]],
    l2: float = 1e-6,
    threshold: float = 0.7,
    cross_validate: bool = True,
    vocabulary: tuple[str, ...] = (),
    descriptions: dict[str, tuple[str, ...]] | None = None,
) -> Path:
    """Fit the reader on ``rows`` ((source, text, class): a pool's name or "base", see
    :func:`tabletop.eval.kind_texts.reader_texts`) and write it to ``out``, with its
    leave-one-pool-out figures at ``threshold`` (unless not ``cross_validate``: the same
    reader, sooner, without them).

    With a ``vocabulary`` (and its ``descriptions``: what a map's object module reads words
    against) it also fits the reader's refusal head
    (:class:`~tabletop.mapping.kind_reader.RefusalHead`): each pool's texts are matched by an
    object module whose reader was fitted without that pool, so the head learns from readings
    of authors the reader had not seen; its own figures come from fitting it without each
    pool in turn, beside the fixed rules' on the same readings.

    It runs on one thread (torch, BLAS and OpenMP), whatever the caller set: the fit's sums
    differ in their last bits with the thread count, and the refusal head is fitted on
    readings made at thresholds, so one and two threads gave heads 0.03 apart; one thread
    gives the same reader on every machine (the slow test holds the committed one to it)."""
    import torch
    from threadpoolctl import threadpool_limits

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with threadpool_limits(limits=1):
            return _train(out, rows, l2, threshold, cross_validate, vocabulary, descriptions)
    finally:
        torch.set_num_threads(threads)


def _train(out, rows, l2, threshold, cross_validate, vocabulary, descriptions) -> Path:
    from tabletop.mapping.encoders.minilm import MINILM_SPACE, MiniLMTextEncoder

    t0 = time.monotonic()
    pools = tuple(dict.fromkeys(s for s, _, _ in rows if s != "base"))
    encoder = MiniLMTextEncoder()
    x = encoder.encode_text([t for _, t, _ in rows])
    labels = [c for _, _, c in rows]
    source = np.array([s for s, _, _ in rows])
    module = _object_module(encoder, vocabulary, descriptions) if vocabulary else None
    if module is not None:  # every text the matches below embed, in batches
        module.prefetch([t for _, t, _ in rows])
    per_pool, records = {}, []
    for pool in pools if cross_validate or module is not None else ():
        train, test = source != pool, np.nonzero(source == pool)[0]
        r = fit_kind_reader(x[train], [labels[i] for i in np.nonzero(train)[0]], MINILM_SPACE, l2)
        per_pool[pool] = _figures(r, x[test], [labels[i] for i in test], threshold)
        log.info("kind reader without %s: %s", pool, per_pool[pool])
        if module is not None:
            module.set_kind_reader(r)
            for i in test:
                m = module.match(rows[i][1])
                f = RefusalHead.vector(module.refusal_features(m))
                records.append((pool, f, labels[i] == OTHER, bool(module.refusal(m))))
    keys = ("read_as_kind", "read_as_another", "refused", "absent_read_as_kind")
    mean = {
        k: round(float(np.mean([f[k] for f in per_pool.values()])), 4) if per_pool else None
        for k in keys
    }
    reader = fit_kind_reader(x, labels, MINILM_SPACE, l2)
    if records:
        reader.refusal, refusal_figures = _refusal_head(records)
        reader.meta["refusal_leave_one_pool_out"] = refusal_figures
        log.info("refusal head, leave one pool out: %s", refusal_figures)
    reader.meta.update(
        {
            "pools": list(pools),
            "texts": len(rows),
            "threshold": threshold,
            "leave_one_pool_out": per_pool if cross_validate else {},
            "leave_one_pool_out_mean": mean if cross_validate else dict.fromkeys(keys),
            "seconds": round(time.monotonic() - t0, 1),
        }
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    reader.save(out)
    return out
