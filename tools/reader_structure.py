"""Reader alone on the instruction goals of paraphrase suites: does each reader read the step
the goal's truth asks (go to a thing or a sound, between, which side), or refuse it?

    python tools/reader_structure.py heldout-10,heldout-11,heldout-12 out/weights/reader_val.pt

The weights should be a network trained without the pools asked (``tabletop train reader``
writes one trained without its validation pools beside the committed one). A "near" goal's
truth names only its object, so a reading that keeps the near part is counted as a miss: the
figure is a lower bound. Tune pools only: never point it at a held-out pool.
"""

import glob
import json
import sys
import tomllib

from tabletop.eval.paraphrase import HELDOUT_POOLS
from tabletop.reader.errors import ParseError
from tabletop.reader.plan import Between, GoTo, Side
from tabletop.reader.reading import LearnedReader, get_reader

SIDE = {"left_of": "left", "right_of": "right", "in_front_of": "front", "behind": "behind"}


def expect(truth):
    if "relation" in truth:
        r = truth["relation"]
        if r == "between":
            return ("Between",)
        return ("Side", SIDE.get(r, r))
    if "near" in truth or ("object" in truth and "sound" in truth):
        return ("GoTo", "obj", "near")
    if "object" in truth:
        return ("GoTo", "obj")
    if "sound" in truth:
        return ("GoTo", "sound")
    if "area" in truth:
        return ("GoTo", "area")
    return ("?", json.dumps(truth))


def got(steps):
    if len(steps) != 1:
        return ("steps", len(steps))
    a = steps[0].action
    if isinstance(a, Between):
        return ("Between",)
    if isinstance(a, Side):
        return ("Side", a.side)
    if isinstance(a, GoTo):
        return ("GoTo", a.goal.primary.kind) + (("near",) if a.goal.near else ())
    return (type(a).__name__,)


pools = sys.argv[1].split(",")
weights = sys.argv[2]
show = sys.argv[3].split(",") if len(sys.argv) > 3 else []  # readers whose misses to print
if any(p in HELDOUT_POOLS for p in pools):
    raise SystemExit(f"tune pools only; held out: {HELDOUT_POOLS}")
goals = []
for p in pools:
    for f in sorted(glob.glob(f"tabletop/data/tasks/paraphrase-{p}/*.toml")):
        for g in tomllib.loads(open(f).read()).get("goals", []):
            if g.get("type") == "instruction":
                goals.append((g["instruction"], g["truth"]))
readers = {
    "rules": get_reader("rules"),
    "rules+spelling": get_reader("rules+spelling"),
    "learned": LearnedReader(weights),
    "rules+learned": LearnedReader(weights, fallback=True),
}
print(len(goals), "instructions; truth kinds:", sorted({expect(t)[:2] for _, t in goals}))
for name, r in readers.items():
    right = refused = 0
    for text, truth in goals:
        try:
            g = got(r.understand(text).steps)
            right += g == expect(truth)
            if name in show and g != expect(truth):
                print(f"  MISS {text!r}: {g} want {expect(truth)}")
        except ParseError as e:
            refused += 1
            if name in show:
                print(f"  REFUSED {text!r}: {e}")
    share = right / len(goals)
    print(f"{name}: structure right {right}/{len(goals)} = {share:.3f}, refused {refused}")
