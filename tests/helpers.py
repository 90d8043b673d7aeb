"""Shared test helpers."""

import functools

import numpy as np


def assert_on_table(points: np.ndarray, tol: float = 0.005) -> None:
    """Points labelled "table" lie on the default table: on its top (z = 0) or its slab's
    sides (x in [-0.2, 0.8], y in [-0.6, 0.6], z in [-0.05, 0]), or on a leg below it."""
    assert len(points) > 0
    lo, hi = np.array([-0.2, -0.6, -0.05]), np.array([0.8, 0.6, 0.0])
    slab = points[points[:, 2] > -0.05 - tol]
    d = np.linalg.norm(np.maximum(lo - slab, 0) + np.maximum(slab - hi, 0), axis=1)
    # EGL renders segmentation in a second pass; along object silhouettes a rare pixel
    # labelled "table" carries the object's depth. Allow one in a thousand.
    assert np.mean(d > tol) <= 1e-3, (np.mean(d > tol), d.max())
    assert d.max() <= 0.15, d.max()  # and then it is an object's surface on the table
    legs = points[points[:, 2] <= -0.05 - tol]
    assert (legs[:, :2] >= lo[:2] - tol).all() and (legs[:, :2] <= hi[:2] + tol).all()
    assert np.mean(np.abs(points[:, 2]) <= tol) > 0.9  # most of what is seen is the top


@functools.cache
def visual_scene():
    """(rec, queries, avlmap) of the visual localization tests, built once per test session.

    ``rec``: a ~320-frame scan of the default scene. ``queries``: image goals of the grey tray,
    the red lego brick and the green toy cube (textured or coloured objects, each with
    neighbours in view) as (goal, object label), rendered by a second simulator of the scene,
    the arm holding the wrist camera at poses the scan never took. ``avlmap``: its oracle map
    with a SIFT visual module keeping every 10th frame as a reference frame (about 7 cm of
    camera travel apart); SIFT keeps the map tests fast, the map code is the same for XFeat.
    """
    from tabletop.eval.harness import build_map, map_config
    from tabletop.eval.map_goals import ImageGoalConfig, image_goals
    from tabletop.mapping.visual import VisualLocalizationConfig
    from tabletop.sim.scan import ScanConfig, run_scan
    from tabletop.sim.scene import load_scene_spec
    from tabletop.sim.world import SimWorld

    cfg = ScanConfig(seed=3, speed=0.45, episodes=0, repeat_sounds=0)
    rec = run_scan(load_scene_spec("default"), cfg)[0]
    labels = ("grey tray", "red lego brick", "green toy cube")
    objs = [o for o in rec.ground_truth["objects"] if o["label"] in labels]
    with SimWorld(load_scene_spec("default")) as world:
        goals = image_goals(
            {**rec.ground_truth, "objects": objs},
            world,
            ImageGoalConfig(seed=2, table_points=0),
            rec.T_world_cam,
        )
    queries = [(g, o["label"]) for g, o in zip(goals, objs, strict=True)]
    config = map_config(frame_step=4, visual=VisualLocalizationConfig(matcher="sift", stride=10))
    return rec, queries, build_map(rec, "oracle", config)
