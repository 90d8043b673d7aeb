"""The wheeled base's planner and motions: paths never cross an inflated obstacle, goals in
obstacles move beside them, the driven path keeps out of the obstacles, and the base's own
motions (forward, turn, face) do what they say."""

import itertools
import math

import numpy as np
import pytest

from tabletop.base.description import TABLETOP_BASE
from tabletop.base.driver import KinematicBaseDriver
from tabletop.base.pose import BasePose
from tabletop.errors import ConfigError
from tabletop.robot.obstacles import OccupancyGrid
from tabletop.robot.wheeled import RoomMoveConfig, _pooled, plan_path

CELL = 0.05


def _room(walls: bool = True) -> OccupancyGrid:
    """A 4 x 3 m room at 5 cm: walls round it, a table-sized block in the middle and a
    wall stub that makes the straight line from the left to the right blocked."""
    occ = np.zeros((80, 60), bool)
    if walls:
        occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    occ[30:50, 20:40] = True  # a 1 x 1 m table
    occ[20:22, 0:40] = True  # a wall stub from the right side
    return OccupancyGrid(occ, (0.0, 0.0), CELL)


def _crosses(grid: OccupancyGrid, xy: np.ndarray) -> bool:
    """Whether the polyline ``xy`` (K, 2) passes through an occupied cell (sampled densely)."""
    for a, b in itertools.pairwise(xy):
        n = max(int(np.linalg.norm(b - a) / (grid.cell_size / 8)), 1)
        for t in np.linspace(0, 1, n + 1):
            c, inside = grid.to_cell(a + t * (b - a))
            if not inside or grid.occupied[tuple(c)]:
                return True
    return False


def test_planned_paths_never_cross_an_inflated_obstacle():
    blocked = _room().inflated(0.25)
    rng = np.random.default_rng(3)
    free = np.argwhere(~blocked.occupied)
    planned = 0
    for _ in range(40):
        a, b = blocked.to_world(free[rng.choice(len(free), 2, replace=False)])
        reason, xy, goal, shifted = plan_path(blocked, a, b, max_goal_shift=0.5)
        if reason != "reached":
            continue  # two sides of the stub may be apart
        planned += 1
        assert not shifted and np.allclose(goal, b) and np.allclose(xy[[0, -1]], [a, b])
        assert not _crosses(blocked, xy)
    assert planned >= 30


def test_a_goal_in_an_obstacle_moves_to_the_nearest_reachable_free_point():
    blocked = _room().inflated(0.25)
    table_centre = np.array([2.0, 1.5])
    reason, _, goal, shifted = plan_path(blocked, (0.5, 2.5), table_centre, 1.0)
    assert reason == "reached" and shifted
    c, _ = blocked.to_cell(goal)
    assert not blocked.occupied[tuple(c)]
    # the nearest free cell beside the 1 x 1 m table grown by 0.25 m: 0.75-0.8 m away
    assert 0.7 <= np.linalg.norm(goal - table_centre) <= 0.85
    assert plan_path(blocked, (0.5, 2.5), table_centre, 0.5)[0] == "no_path"
    assert plan_path(blocked, (0.5, 2.5), (9.0, 1.0), 1.0)[0] == "outside_map"
    assert plan_path(blocked, (2.0, 1.5), (0.5, 2.5), 1.0)[0] == "start_blocked"


def test_pooling_keeps_every_obstacle():
    occ = np.zeros((10, 7), bool)
    occ[9, 6] = occ[3, 2] = True
    fine = OccupancyGrid(occ, (1.0, -1.0), 0.01)
    coarse = _pooled(fine, 0.03)
    assert coarse.cell_size == pytest.approx(0.03) and coarse.shape == (4, 3)
    assert coarse.occupied.sum() == 2
    for p in fine.to_world(np.argwhere(occ)):
        c, inside = coarse.to_cell(p)
        assert inside and coarse.occupied[tuple(c)]


def test_the_follower_drives_a_planned_path_without_touching_the_obstacles():
    room = _room()
    params = TABLETOP_BASE
    cfg = RoomMoveConfig()
    blocked = room.inflated(cfg.radius + cfg.clearance_m)
    start, goal = np.array([0.5, 0.5]), np.array([3.5, 0.5])  # the stub is between them
    reason, xy, _, _ = plan_path(blocked, start, goal, 1.0)
    assert reason == "reached" and len(xy) > 2  # it has to go round the stub
    from tabletop.base.follower import follow_path

    driver = KinematicBaseDriver(params, BasePose(*start, math.pi / 2))
    run = follow_path(driver, xy, cfg.follow)
    assert run.reached
    assert np.linalg.norm(run.final.xy - goal) <= cfg.follow.goal_tolerance + 1e-9
    # the footprint's centre never comes within the radius of an obstacle cell
    d = _clearance(room, run.driven[:, :2])
    assert d.min() >= cfg.radius


def _clearance(grid: OccupancyGrid, xy: np.ndarray) -> np.ndarray:
    """Distance [m] of each point to the nearest occupied cell's square."""
    cells = grid.to_world(np.argwhere(grid.occupied))
    half = grid.cell_size / 2
    return np.array(
        [np.min(np.linalg.norm(np.maximum(np.abs(cells - p) - half, 0), axis=1)) for p in xy]
    )


def test_config_is_checked():
    with pytest.raises(ConfigError, match="cell_m"):
        RoomMoveConfig(cell_m=0.0)
    with pytest.raises(ConfigError, match="radius"):
        RoomMoveConfig(radius=-1)
