"""Score every candidate camera pose of eval-map's image goals: the record behind the
photometric check's thresholds (``VisualLocalizationConfig.min_agreement``, ``min_kappa``,
``sure_agreement``, ``sure_kappa``; docs/mapping.md, "Checked against the map").

For the scans of ``tabletop eval-map --seeds N`` (oracle encoders), every image and
image-ambiguous goal is matched at each quarter turn with the best 3 and the best 6 reference
frames; each candidate pose with >= ``verify_min_inliers`` inliers is scored by the map's
:class:`~tabletop.mapping.visual.PhotometricCheck`, and so is the goal camera's
true pose. A candidate is *right* when its image target lies within 5 cm of the true pose's.
Printed: the check's figures at the true poses, how far wrong candidates reach, and what the
selection rule (best agreement passing both thresholds, 3 frames before 6) gives per goal.

Usage (about 15 minutes on two cores)::

    python tools/image_candidates.py --seeds 3
"""

from __future__ import annotations

import argparse

import numpy as np

from tabletop.eval.harness import generated_scene, scene_map
from tabletop.eval.map_goals import ImageGoalConfig, image_goals
from tabletop.mapping import AVLMap
from tabletop.mapping.visual import localize as vl
from tabletop.sim.ground_truth import GroundTruth
from tabletop.sim.scene import load_scene_spec
from tabletop.sim.world import SimWorld


def scan_goals(seed: int, scene: str) -> tuple[AVLMap, list]:
    """The map and image goals of one eval-map scan (the same scene, scan and goal seeds)."""
    spec = load_scene_spec("default") if scene == "default" else generated_scene(seed + 10)
    rec, m = scene_map(spec, {"seed": seed, "speed": 0.3, "episodes": 6}, "oracle")
    with SimWorld(spec) as world:
        goals = image_goals(GroundTruth.of(rec), world, ImageGoalConfig(seed=seed), rec.T_world_cam)
    return m, goals


def candidates(m: AVLMap, g) -> tuple[tuple, list[dict]]:
    """The check's (coverage, agreement, kappa) at the true pose, and every candidate."""
    db, K = m.visual, m.visual.K
    cfg, check = db.config, m.photometric_check()
    size = (g.image.shape[1], g.image.shape[0])
    truth = m.image_target(g.T_world_cam, K, size)
    out = []
    for k in range(4):
        q = vl._TurnedQuery(db, vl._backend(cfg.matcher), g.image, k)
        for n in (cfg.top_n, 2 * cfg.top_n):
            c = vl._localize_turned(db, q, K, n, cfg.verify_min_inliers)
            if c["T"] is None:
                continue
            err = float(np.linalg.norm(m.image_target(c["T"], K, size) - truth))
            out.append({"n": n, "score": check.score(c["T"], K, g.image, cfg), "err": err})
    return check.score(g.T_world_cam, K, g.image, cfg), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    cfg = vl.VisualLocalizationConfig()
    true_scores, wrong, picks = [], [], {"right": 0, "wrong": 0, "none": 0}
    for seed in range(args.seeds):
        for scene in ("default", "random"):
            m, goals = scan_goals(seed, scene)
            for g in goals:
                if g.kind not in ("image", "image_ambiguous"):
                    continue
                t, cands = candidates(m, g)
                true_scores.append(t)
                wrong += [c["score"] for c in cands if c["err"] > 0.05]
                ok = [
                    c
                    for c in cands
                    if c["score"][0] >= cfg.min_coverage
                    and c["score"][1] >= cfg.min_agreement
                    and c["score"][2] >= cfg.min_kappa
                ]
                first = [c for c in ok if c["n"] == cfg.top_n] or ok
                pick = max(first, key=lambda c: c["score"][1]) if first else None
                picks["none" if pick is None else "right" if pick["err"] <= 0.05 else "wrong"] += 1
            print(
                f"{scene} seed {seed}: {len(true_scores)} goals so far, picks {picks}", flush=True
            )
    t, w = np.array(true_scores), np.array(wrong).reshape(-1, 3)
    w = w[w[:, 0] >= cfg.min_coverage]
    agree = w[:, 1] >= cfg.min_agreement
    print(
        f"true poses ({len(t)}): agreement {t[:, 1].min():.2f}-{t[:, 1].max():.2f}, "
        f"kappa {t[:, 2].min():.2f}-{t[:, 2].max():.2f}"
    )
    print(
        f"wrong candidates seeing the map ({len(w)}): agreement 99th percentile "
        f"{np.quantile(w[:, 1], 0.99):.2f}; passing agreement {np.sum(agree)}, passing both "
        f"{np.sum(agree & (w[:, 2] >= cfg.min_kappa))}"
    )
    print(f"selection rule per goal: {picks}")


if __name__ == "__main__":
    main()
