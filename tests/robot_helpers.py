"""One short scan of the default scene and its oracle map, shared by the robot test modules
(built once per test session)."""

import functools

from tabletop.eval.harness import build_map, map_config
from tabletop.sim.scan import ScanConfig, run_scan
from tabletop.sim.scene import load_scene_spec


@functools.lru_cache(maxsize=1)
def scan_and_map():
    """(recording, AVLMap) of a short scan (3 audio episodes, one sound repeated)."""
    cfg = ScanConfig(speed=0.45, episodes=3, episode_s=2.5, repeat_sounds=1)
    rec = run_scan(load_scene_spec("default"), cfg)[0]
    return rec, build_map(rec, "oracle", map_config(frame_step=3))


def box_distance(p, obj) -> float:
    """Distance [m] from a point to an object's ground-truth box (0 inside)."""
    import numpy as np

    lo, hi = np.array(obj["aabb_min"]), np.array(obj["aabb_max"])
    return float(np.linalg.norm(np.maximum(lo - p, 0) + np.maximum(p - hi, 0)))
