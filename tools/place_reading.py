"""How the place readers read the paraphrase pools' area phrasings: counts only.

For each pool, the grammar alone and the grammar with the learned classifier
(:class:`tabletop.reader.places.PlaceReader`) read every ``[areas]`` phrase (a region of the
table: right, wrong, unread; a place named after a thing: kept a subject or taken for a region)
and every ``[absent.areas]`` phrase (kept off the table or taken for a region). No phrase is
printed, so the held-out pools can be measured without being read.

Usage: python tools/place_reading.py [POOL ...]   (default: the held-out pools)
"""

from __future__ import annotations

import collections
import sys

from tabletop.eval.paraphrase import HELDOUT_POOLS, load_bank
from tabletop.reader.places import REGION_OF_CLASS, PlaceReader


def _class(ref) -> str | None:
    if ref.region is None:
        return None
    pair = (ref.region.lateral, ref.region.depth)
    return next((n for n, lr in REGION_OF_CLASS.items() if lr == pair), "corner")


def counts(pool: str, reader: PlaceReader) -> dict[str, int]:
    bank = load_bank(pool)
    c: collections.Counter = collections.Counter()
    for key, phrases in bank.areas.items():
        for p in phrases:
            got = _class(reader.read(p))
            if key in REGION_OF_CLASS:
                c["region right" if got == key else "region wrong" if got else "region unread"] += 1
            else:
                c["subject kept" if got is None else "subject read as region"] += 1
    for p in bank.absent_areas:
        off = _class(reader.read(p)) is None
        c["absent kept off table" if off else "absent read as region"] += 1
    return dict(sorted(c.items()))


def main(pools) -> None:
    readers = {"grammar": PlaceReader(learned=False), "grammar+learned": PlaceReader(learned=True)}
    for pool in pools:
        for name, reader in readers.items():
            print(f"{pool:12s} {name:16s} {counts(pool, reader)}")


if __name__ == "__main__":
    main(sys.argv[1:] or HELDOUT_POOLS)
