"""Object evidence on room maps: every catalogue colour and kind asked of a room's map, split by
whether the room holds it. Shows where an object operating point for rooms would fall.

    python tools/room_object_scores.py MAP_OF_ROOM_DEFAULT.npz MAP_OF_ROOM_RANDOM_1.npz

The maps are the default-encoder maps `tabletop eval mobile --encoders default` caches (the tune
rooms, in that order); they load with the weights they were built with.
"""

import sys

from tabletop.eval.tasks import load_tasks
from tabletop.mapping import AVLMap
from tabletop.paths import DATA_DIR
from tabletop.sim.catalog import OBJECT_KINDS


def main(paths: list[str]) -> None:
    names = ("room-default", "room-random-1")
    present, absent = [], []
    for name, path in zip(names, paths, strict=True):
        spec = load_tasks(DATA_DIR / "tasks" / "mobile" / f"{name}.toml").scene.load()
        m = AVLMap.load(path, encoders="default")
        have = {(o.kind, o.color) for _, o in spec.objects}
        for kind, k in OBJECT_KINDS.items():
            for c in k.colors:
                h = m.object_heatmap(f"{c} {k.label}")
                e = h.evidence if h.evidence is not None else float("nan")
                (present if (kind, c) in have else absent).append(e)
    present.sort()
    absent.sort()
    print("present:", " ".join(f"{e:.2f}" for e in present))
    print("absent, highest 10:", " ".join(f"{e:.2f}" for e in absent[-10:]))
    for thr in (0.93, 0.9, 0.8, 0.7, 0.6, 0.5):
        tp = sum(e >= thr for e in present)
        fp = sum(e >= thr for e in absent)
        print(f"threshold {thr}: present {tp}/{len(present)}, absent {fp}/{len(absent)} found")


if __name__ == "__main__":
    main(sys.argv[1:])
