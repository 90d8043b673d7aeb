"""The texts the kind reader (:mod:`tabletop.mapping.kind_reader`) is trained on, from the
catalog's labels and descriptions, the object module's other things and the tune paraphrase
pools (:func:`reader_texts`; trained by :mod:`tabletop.train.kind_reader`)."""

from __future__ import annotations

import random

from tabletop.mapping.kind_reader import OTHER

__all__ = ["reader_texts"]


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
