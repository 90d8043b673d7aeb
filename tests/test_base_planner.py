"""The grid planner: shortest collision-free paths, shortened to the waypoints that matter."""

import itertools

import numpy as np
import pytest

from tabletop.base import PathError, grid_path, line_is_free

CELL = 0.1


def wall_with_gap():
    """A 4 x 3 m grid with a wall at x = 2 m, open only for y in [2.5, 2.8) m."""
    blocked = np.zeros((40, 30), bool)
    blocked[19:21, :25] = True
    blocked[19:21, 28:] = True
    return blocked


def test_the_path_goes_through_the_gap_and_every_leg_is_free():
    blocked = wall_with_gap()
    path = grid_path(blocked, CELL, (0.5, 0.5), (3.5, 0.5))
    assert np.allclose(path[0], (0.5, 0.5)) and np.allclose(path[-1], (3.5, 0.5))
    assert any(2.5 <= p[1] <= 2.8 for p in path)  # through the gap
    for a, b in itertools.pairwise(path):
        assert line_is_free(blocked, a, b, CELL)
    assert 3 <= len(path) <= 6  # shortened: only the corners remain
    length = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
    assert length < 2 * np.hypot(1.5, 2.15) + 0.3  # near the shortest, via the gap


def test_free_space_is_one_straight_leg_and_no_path_is_none():
    blocked = np.zeros((20, 20), bool)
    path = grid_path(blocked, CELL, (0.15, 0.15), (1.85, 1.2))
    assert path.shape == (2, 2)
    closed = wall_with_gap()
    closed[19:21, :] = True
    assert grid_path(closed, CELL, (0.5, 0.5), (3.5, 0.5)) is None


def test_a_start_just_inside_an_obstacle_snaps_to_free_space():
    blocked = wall_with_gap()
    start = (1.93, 0.5)  # in the wall's cells, 0.08 m from a free cell's centre
    with pytest.raises(PathError, match=r"start \[1.93, 0.5\] is in a blocked cell"):
        grid_path(blocked, CELL, start, (0.5, 0.5))
    path = grid_path(blocked, CELL, start, (0.5, 0.5), snap_start=0.15)
    assert (
        np.allclose(path[0], start) and not blocked[int(path[1][0] / CELL), int(path[1][1] / CELL)]
    )
    with pytest.raises(PathError, match="goal .* is outside the grid"):
        grid_path(blocked, CELL, (0.5, 0.5), (9.0, 0.5))
