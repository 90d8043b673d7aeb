"""Random views of rooms searched in room maps: the record behind the map search's acceptance
(``VisualLocalizationConfig.search_min_kappa``, ``search_strong_kappa``, ``search_min_rare``,
``search_min_rare_agreement``, ``search_weak_rare_agreement``; docs/mobile_base.md, "Images
taken off the scan's path").

For each ordered pair of the tune rooms (the shipped mobile suites' rooms: the default room
and generated room 1), ``--views`` random upright views at 1.1 m on the first room's free
floor, pitched 6-34 degrees down, are localised in the *first* room's map ("pos": where were
they taken?), and as many views of the *second* room in the same map ("neg": they must not
be found). Per view: whether feature matching alone localised it (and how far off), and each
of the search's best candidate poses (refined) as the photometric check scores it, and the result as
the map is configured. Printed: that result, and for a grid of acceptance settings (applied
to the searched poses only; matched poses as feature matching alone accepts them), how
many "pos" views end within 1 m of the truth, how many far off, and how many "neg" views were
localised at all. The held-out rooms are never used.

Usage (about 10 minutes per room on two cores; maps and scans come from the eval cache)::

    python tools/image_search_calibration.py --views 30 --out out/image-search.json
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
from pathlib import Path

import numpy as np

from tabletop.eval.harness import cached_map
from tabletop.eval.images import render_view
from tabletop.eval.room import cached_room_recording, room_map_settings, room_recording_key
from tabletop.eval.room_suites import ROOM_SUITES
from tabletop.eval.tasks import ImageView, room_ref
from tabletop.mapping.visual.localize import searched_poses
from tabletop.sim.room_world import RoomWorld, mast_camera_config


def _views(spec, n: int, seed: int) -> list[ImageView]:
    rng = np.random.default_rng(seed)
    occ = spec.occupancy(0.05, inflate=0.3)
    out = []
    while len(out) < n:
        eye = np.array([rng.uniform(0.5, spec.size[0] - 0.5), rng.uniform(0.5, spec.size[1] - 0.5)])
        if occ[int(eye[0] / 0.05), int(eye[1] / 0.05)]:
            continue
        yaw, pitch = rng.uniform(0, 2 * np.pi), rng.uniform(-0.6, -0.1)
        e = (*eye, 1.1)
        d = np.array([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), np.sin(pitch)])
        out.append(ImageView(eye=e, look_at=tuple(np.array(e) + d), up=(0.0, 0.0, 1.0)))
    return out


def _rows(m, spec, label: str, views: list[ImageView]) -> list[dict]:
    db = m.images.database
    config = db.config
    search, check = m.images.panorama_search(), m.images.photometric_check()
    rows = []
    h, w = db.image_size[1], db.image_size[0]
    with RoomWorld(spec, mast_camera_config(width=w, height=h)) as world:
        for v in views:
            rgb = render_view(world, v)
            truth = np.asarray(v.eye[:2])
            cands = [
                {**d, "err": float(np.linalg.norm(T[:2, 3] - truth))}
                for T, d in searched_poses(lambda: search, check, rgb, db.K, config)
            ]
            db.config = dataclasses.replace(config, search=False)
            try:
                loc = m.images.localize(rgb)
            finally:
                db.config = config
            err = float(np.linalg.norm(loc.position[:2] - truth)) if loc.ok else None
            full = m.images.localize(rgb)  # as the map is configured: matches, then the search
            full_err = float(np.linalg.norm(full.position[:2] - truth)) if full.ok else None
            rows.append(
                {
                    "label": label,
                    "cands": cands,
                    "feat_ok": loc.ok,
                    "feat_err": err,
                    "ok": full.ok,
                    "err": full_err,
                    "searched": full.searched,
                }
            )
    return rows


def outcome(rows: list[dict], rules, rare: int, base) -> dict:
    """What the acceptance settings give on ``rows``: pos views within 1 m, pos views
    localised 1 m or more off, neg views localised (by matches or by the search). A searched
    pose passes with ``rare`` rare sample pixels and one of ``rules``, (kappa, rare agreement)
    pairs it must reach both of."""
    out = {"pos_within_1m": 0, "pos_wrong": 0, "pos": 0, "neg_found": 0, "neg": 0}
    for r in rows:
        res = r["feat_err"] if r["feat_ok"] else None
        if not r["feat_ok"]:
            ok = [
                c
                for c in r["cands"]
                if c["coverage"] >= base.min_coverage
                and c["agreement"] >= base.min_agreement
                and c["rare"] >= rare
                and any(c["kappa"] >= k and c["rare_agreement"] >= ra for k, ra in rules)
            ]
            res = max(ok, key=lambda c: c["agreement"])["err"] if ok else None
        out[r["label"]] += 1
        if r["label"] == "pos":
            out["pos_within_1m"] += res is not None and res < 1.0
            out["pos_wrong"] += res is not None and res >= 1.0
        else:
            out["neg_found"] += res is not None
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--views", type=int, default=30)
    p.add_argument("--cache-dir", default="out/eval-cache")
    p.add_argument("--out", default="out/image-search.json")
    a = p.parse_args(argv)
    cache = Path(a.cache_dir)
    rooms = {}
    for name, (room, scan, _) in ROOM_SUITES.items():
        spec = room_ref(room, name).load()
        rec, _, _ = cached_room_recording(name, dict(scan), spec, cache)
        key = room_recording_key(spec, dict(scan))
        m, _, _ = cached_map(name, room_map_settings(spec), rec, "oracle", cache, key, None)
        rooms[name] = (spec, m)
    rows = []
    names = list(rooms)
    for i, (own, other) in enumerate(itertools.permutations(names, 2)):
        spec, m = rooms[own]
        rows += _rows(m, spec, "pos", _views(spec, a.views, 1000 + 2 * i))
        rows += _rows(m, rooms[other][0], "neg", _views(rooms[other][0], a.views, 1001 + 2 * i))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(rows))
    pos = [r for r in rows if r["label"] == "pos"]
    neg = [r for r in rows if r["label"] == "neg"]
    within = sum(r["ok"] and r["err"] < 1.0 for r in pos)
    wrong = sum(r["ok"] and r["err"] >= 1.0 for r in pos)
    print(
        f"as configured: own room {within} of {len(pos)} within 1 m, {wrong} 1 m or more off "
        f"({sum(r['ok'] and r['searched'] for r in pos)} by the search); other room "
        f"{sum(r['ok'] for r in neg)} of {len(neg)} found"
    )
    base = rooms[names[0]][1].images.database.config
    print("(kappa, rare agreement) rules, rare -> pos within 1 m / wrong / pos | neg found / neg")
    grid = [[(k, ra)] for k, ra in itertools.product((0.3, 0.45, 0.6), (0.1, 0.2, 0.35))]
    grid += [[(base.search_strong_kappa, base.search_min_rare_agreement),
              (base.search_min_kappa, base.search_weak_rare_agreement)]]  # fmt: skip
    for rules in grid:
        o = outcome(rows, rules, base.search_min_rare, base)
        print(
            f"{rules} {base.search_min_rare} -> {o['pos_within_1m']} / {o['pos_wrong']} / "
            f"{o['pos']} | {o['neg_found']} / {o['neg']}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
