"""Shortest collision-free paths on a 2D occupancy grid, for a base that is a disc.

The grid is the configuration space: obstacles already inflated by the base's radius (and a
margin). :func:`grid_path` runs A* over 8-connected cells and then shortens the cell path to
the waypoints a path follower needs (each kept only where a straight line would cross a
blocked cell).
"""

from __future__ import annotations

import heapq
import math

import numpy as np

from tabletop.base.errors import PathError

__all__ = ["cells_on_segment", "grid_path", "line_is_free"]

_STEPS = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]


def _cell(xy, origin, cell: float) -> tuple[int, int]:
    return (
        math.floor((xy[0] - origin[0]) / cell),
        math.floor((xy[1] - origin[1]) / cell),
    )


def cells_on_segment(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(K, 2) int: every cell the straight segment from ``a`` to ``b`` (continuous cell
    coordinates: cell (i, j) covers [i, i+1) x [j, j+1)) passes through, in order (a grid
    traversal; a segment through a cell corner takes both cells beside it too)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    cell = np.floor(a).astype(np.int64)
    end = np.floor(b).astype(np.int64)
    d = b - a
    step = np.sign(d).astype(np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_delta = np.where(d != 0, 1.0 / np.abs(d), np.inf)
        t_max = np.where(d != 0, np.where(step > 0, cell + 1 - a, a - cell) * t_delta, np.inf)
    out = [cell.copy()]
    for _ in range(int(np.abs(end - cell).sum()) + 2):
        if np.array_equal(cell, end):
            break
        if abs(t_max[0] - t_max[1]) < 1e-12:  # through a corner: both neighbours, then diagonal
            out.append(cell + np.array([step[0], 0]))
            out.append(cell + np.array([0, step[1]]))
            cell = cell + step
            t_max = t_max + t_delta
        elif t_max[0] < t_max[1]:
            cell = cell + np.array([step[0], 0])
            t_max[0] += t_delta[0]
        else:
            cell = cell + np.array([0, step[1]])
            t_max[1] += t_delta[1]
        out.append(cell.copy())
    return np.array(out)


def line_is_free(
    blocked: np.ndarray, a: np.ndarray, b: np.ndarray, cell: float, origin=(0.0, 0.0)
) -> bool:
    """Whether the segment from ``a`` to ``b`` [m] crosses no blocked cell (every cell it
    passes through, :func:`cells_on_segment`; leaving the grid counts as blocked)."""
    o = np.asarray(origin, float)
    c = cells_on_segment((np.asarray(a, float) - o) / cell, (np.asarray(b, float) - o) / cell)
    inside = np.all((c >= 0) & (c < blocked.shape), axis=1)
    if not inside.all():
        return False
    return not blocked[c[:, 0], c[:, 1]].any()


def grid_path(
    blocked: np.ndarray,
    cell: float,
    start_xy,
    goal_xy,
    origin=(0.0, 0.0),
    *,
    snap_start: float = 0.0,
) -> np.ndarray | None:
    """Waypoints (K, 2) [m] from ``start_xy`` to ``goal_xy`` avoiding ``blocked`` cells, or None
    when the goal cannot be reached.

    Args:
        blocked: (nx, ny) bool, True where the base's centre may not go; cell (i, j) spans
            ``origin + [i, i + 1) * cell`` along x and ``[j, j + 1) * cell`` along y.
        cell: cell size [m].
        start_xy, goal_xy: (2,) [m]; both must lie in free cells, but see ``snap_start``.
        snap_start: a start in a blocked cell but within this distance [m] of a free one (a
            base that stopped within its goal tolerance of a free cell) leaves from the
            nearest free cell: the path's first waypoint is the start, its second that cell.

    Raises:
        PathError: a malformed grid, or a start or goal outside it or in a blocked cell.
    """
    blocked = np.asarray(blocked, dtype=bool)
    if blocked.ndim != 2 or not cell > 0:
        raise PathError(f"blocked must be a 2D grid and cell > 0, got {blocked.shape}, {cell}")
    start, goal = np.asarray(start_xy, float), np.asarray(goal_xy, float)
    s, g = _cell(start, origin, cell), _cell(goal, origin, cell)
    lead = None
    if snap_start > 0 and 0 <= s[0] < blocked.shape[0] and 0 <= s[1] < blocked.shape[1]:
        if blocked[s]:
            free = np.argwhere(~blocked)
            centres = (free + 0.5) * cell + np.asarray(origin)
            d = np.linalg.norm(centres - start, axis=1)
            k = int(np.argmin(d)) if len(d) else -1
            if k >= 0 and d[k] <= snap_start:
                lead = start
                start = centres[k]
                s = (int(free[k][0]), int(free[k][1]))
    for name, c, p in (("start", s, start), ("goal", g, goal)):
        if not (0 <= c[0] < blocked.shape[0] and 0 <= c[1] < blocked.shape[1]):
            raise PathError(f"{name} {p.tolist()} is outside the grid")
        if blocked[c]:
            raise PathError(f"{name} {p.tolist()} is in a blocked cell")
    r2 = math.sqrt(2.0)

    def h(c):
        dx, dy = abs(c[0] - g[0]), abs(c[1] - g[1])
        return max(dx, dy) + (r2 - 1.0) * min(dx, dy)

    cost = {s: 0.0}
    parent: dict = {s: None}
    heap = [(h(s), 0.0, s)]
    done = set()
    nx, ny = blocked.shape
    while heap:
        _, gc, c = heapq.heappop(heap)
        if c in done:
            continue
        if c == g:
            break
        done.add(c)
        for dx, dy in _STEPS:
            n = (c[0] + dx, c[1] + dy)
            if not (0 <= n[0] < nx and 0 <= n[1] < ny) or blocked[n] or n in done:
                continue
            if dx and dy and (blocked[c[0] + dx, c[1]] or blocked[c[0], c[1] + dy]):
                continue
            ng = gc + (r2 if dx and dy else 1.0)
            if ng < cost.get(n, math.inf):
                cost[n] = ng
                parent[n] = c
                heapq.heappush(heap, (ng + h(n), ng, n))
    else:
        return None
    cells = [g]
    while parent[cells[-1]] is not None:
        cells.append(parent[cells[-1]])
    pts = (np.array(cells[::-1], dtype=float) + 0.5) * cell + np.asarray(origin)
    pts[0], pts[-1] = start, goal
    # shortcut: keep a waypoint only where the straight line from the last kept one is blocked
    out = [pts[0]]
    i = 0
    while i < len(pts) - 1:
        j = len(pts) - 1
        while j > i + 1 and not line_is_free(blocked, pts[i], pts[j], cell, origin):
            j -= 1
        out.append(pts[j])
        i = j
    if lead is not None:
        out.insert(0, lead)
    return np.array(out)
