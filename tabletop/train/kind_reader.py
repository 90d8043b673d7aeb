"""Training the kind reader (:mod:`tabletop.mapping.kind_reader`; ``tabletop train
kind-reader``).

Its texts: each catalog kind's label and descriptions (``descriptions.toml``) and every name the
tune paraphrase pools give it, labelled with the kind's label; a name with a colour's place
comes once without a colour, once with a colour word of the same pool and twice in a colour
form of that pool ("{n}, kind of {c}"), words and forms drawn seeded, so that the reader learns
to pass over what a colour phrase leaves behind. The pools' absent objects and the object
module's ``others`` are labelled :data:`~tabletop.mapping.kind_reader.OTHER`. The held-out
pools (:data:`~tabletop.eval.paraphrase.HELDOUT_POOLS`) are never read.

Before fitting on every pool it measures, pool by pool, a reader fitted without that pool on
that pool's names and absent objects (leave one pool out: how it reads an author it has not
seen), and writes the figures into the file's ``meta``.
"""

from __future__ import annotations

import logging
import random
import time
from pathlib import Path

import numpy as np

from tabletop.mapping.kind_reader import OTHER, KindReader, fit_kind_reader

__all__ = ["reader_texts", "train_kind_reader"]

log = logging.getLogger(__name__)


def reader_texts(pools, seed: int = 0) -> list[tuple[str, str, str]]:
    """(source, text, class) of every training text: source is a pool's name or "base" (labels,
    descriptions, others)."""
    from tabletop.eval.harness import catalog_descriptions
    from tabletop.eval.paraphrase import HELDOUT_POOLS, load_bank
    from tabletop.mapping.object_module import load_other_objects
    from tabletop.sim.catalog import OBJECT_KINDS

    held = sorted(set(pools) & set(HELDOUT_POOLS))
    if held:
        raise ValueError(f"{held} are held-out pools: the reader never trains on them")
    rng = random.Random(seed)
    label = {k: OBJECT_KINDS[k].label for k in OBJECT_KINDS}
    rows: list[tuple[str, str, str]] = []
    descriptions = catalog_descriptions()
    for kind in sorted(OBJECT_KINDS):
        rows.append(("base", label[kind], label[kind]))
        rows += [("base", d, label[kind]) for d in descriptions.get(kind, ())]
    rows += [("base", o, OTHER) for o in load_other_objects()]
    for pool in pools:
        bank = load_bank(pool)
        colour_words = [w for ws in bank.colours.values() for w in ws]
        for kind, phrases in bank.objects.items():
            for name in phrases.names:
                rows.append((pool, " ".join(f"the {name.replace('{c}', '')}".split()), label[kind]))
                if "{c}" in name and colour_words:
                    coloured = name.replace("{c}", rng.choice(colour_words))
                    rows.append((pool, " ".join(f"the {coloured}".split()), label[kind]))
                    plain = " ".join(name.replace("{c}", "").split())
                    for _ in range(2 if bank.colour_forms else 0):
                        form = rng.choice(bank.colour_forms).replace("{n}", plain)
                        text = form.replace("{c}", rng.choice(colour_words))
                        rows.append((pool, " ".join(f"the {text}".split()), label[kind]))
        for absent in bank.absent_objects:
            text = absent if absent.startswith(("the ", "a ", "an ")) else f"the {absent}"
            rows.append((pool, text, OTHER))
    return rows


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


def train_kind_reader(
    out: Path,
    pools=None,
    seed: int = 0,
    l2: float = 1e-6,
    threshold: float = 0.7,
    cross_validate: bool = True,
) -> Path:
    """Fit the reader on ``pools`` (default: the tune pools) and write it to ``out``, with its
    leave-one-pool-out figures at ``threshold`` (unless not ``cross_validate``: the same
    reader, sooner, without them)."""
    from tabletop.eval.paraphrase import TUNE_POOLS
    from tabletop.mapping.encoders.minilm import MINILM_SPACE, MiniLMTextEncoder

    t0 = time.monotonic()
    pools = tuple(TUNE_POOLS if pools is None else pools)
    rows = reader_texts(pools, seed)
    x = MiniLMTextEncoder().encode_text([t for _, t, _ in rows])
    labels = [c for _, _, c in rows]
    source = np.array([s for s, _, _ in rows])
    per_pool = {}
    for pool in pools if cross_validate else ():
        train, test = source != pool, np.nonzero(source == pool)[0]
        r = fit_kind_reader(x[train], [labels[i] for i in np.nonzero(train)[0]], MINILM_SPACE, l2)
        per_pool[pool] = _figures(r, x[test], [labels[i] for i in test], threshold)
        log.info("kind reader without %s: %s", pool, per_pool[pool])
    keys = ("read_as_kind", "read_as_another", "refused", "absent_read_as_kind")
    mean = {
        k: round(float(np.mean([f[k] for f in per_pool.values()])), 4) if per_pool else None
        for k in keys
    }
    reader = fit_kind_reader(x, labels, MINILM_SPACE, l2)
    reader.meta.update(
        {
            "pools": list(pools),
            "seed": seed,
            "texts": len(rows),
            "threshold": threshold,
            "leave_one_pool_out": per_pool,
            "leave_one_pool_out_mean": mean,
            "seconds": round(time.monotonic() - t0, 1),
        }
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    reader.save(out)
    return out
