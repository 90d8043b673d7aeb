"""A mobile base behind the same robot API: a disc on the map's 2D obstacle grid, with A*
(:func:`tabletop.base.planner.grid_path`).

This shows the API serving a second embodiment. It is KINEMATIC: a point (a disc of
``radius``, by inflating the obstacles) that jumps along its planned path; no dynamics, no
controller, no simulator. A real base implements :meth:`MobileBase.move_to` by handing the path
(or just the goal and the grid) to its navigation stack.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from tabletop.arm.success import SUCCESS_RADIUS_M
from tabletop.base.planner import grid_path
from tabletop.errors import ConfigError
from tabletop.robot.api import RobotAPI, SpatialConfig, _point
from tabletop.robot.obstacles import MOBILE_BASE, Embodiment, OccupancyGrid, occupancy_grid

__all__ = ["BaseMoveResult", "MobileBase", "MobileConfig"]


@dataclass(frozen=True)
class MobileConfig:
    """Parameters of :class:`MobileBase`."""

    radius: float = 0.03
    """The base's radius [m]: obstacles are inflated by it."""
    max_goal_shift: float = 0.25
    """A goal inside an obstacle moves to the nearest free reachable cell if that is at most
    this far [m] (an object's position becomes a point beside it); else ``no_path``."""

    def __post_init__(self) -> None:
        if not (self.radius >= 0 and self.max_goal_shift >= 0):
            raise ConfigError("radius and max_goal_shift must be >= 0 [m]")


@dataclass(frozen=True)
class BaseMoveResult:
    """The outcome of :meth:`MobileBase.move_to` (a value)."""

    reached: bool
    reason: str  # "reached" | "below_table" | "outside_map" | "no_path" | "start_blocked"
    target: np.ndarray  # (3,) [m] as asked
    goal: np.ndarray  # (3,) [m] where the base was sent (target moved out of an obstacle)
    goal_shifted: bool  # the target was in an (inflated) obstacle
    final_position: np.ndarray  # (3,) [m] where the base is after the move
    path: np.ndarray  # (K, 3) [m] waypoints from start to goal; (0, 3) when no path
    length_m: float  # path length [m]
    error_m: float  # |final - target| in x, y [m]
    note: str = ""  # why the base did not go to the target, when a rule refused it


class MobileBase(RobotAPI):
    """A kinematic disc robot on the table top, planning with A* on the map's obstacle grid.

    Args:
        avlmap: the map (queries and the obstacle grid).
        start: (2,) or (3,) [m] base frame, the base's initial position.
        config: radius and goal handling.
        embodiment: the base's obstacle concepts (the table is free, objects block).
        keep_out: heatmaps whose heat >= ``keep_out_threshold`` the base must stay out of.
        spatial: offsets of the spatial primitives.
    """

    refuses_off_map = False  # a target off the grid: outside_map, nothing moves

    needs_map = True

    def __init__(
        self,
        avlmap,
        start=(0.15, 0.0),
        *,
        config: MobileConfig | None = None,
        embodiment: Embodiment = MOBILE_BASE,
        keep_out=(),
        keep_out_threshold: float = 0.5,
        spatial: SpatialConfig | None = None,
    ) -> None:
        super().__init__(avlmap, spatial)
        self.config = config or MobileConfig()
        self.grid: OccupancyGrid = occupancy_grid(avlmap, embodiment, keep_out, keep_out_threshold)
        """The obstacle grid (not inflated)."""
        self.blocked: OccupancyGrid = self.grid.inflated(self.config.radius)
        """The configuration space: obstacles inflated by the radius."""
        try:
            s = np.asarray(start, np.float64)
        except (TypeError, ValueError):
            why = f"start must be a finite (2,) or (3,) point [m], got {start!r}"
            raise ConfigError(why) from None
        if s.shape not in ((2,), (3,)) or not np.all(np.isfinite(s)):
            raise ConfigError(f"start must be a finite (2,) or (3,) point [m], got {s.tolist()}")
        lo, hi = avlmap.grid.lower, avlmap.grid.upper
        if not (lo[0] <= s[0] <= hi[0] and lo[1] <= s[1] <= hi[1]):
            raise ConfigError(
                f"start ({s[0]:g}, {s[1]:g}) m lies off the map: it must be within x "
                f"{lo[0]:g} .. {hi[0]:g}, y {lo[1]:g} .. {hi[1]:g} m (the map's bounds)"
            )
        self._pos = np.array([s[0], s[1], 0.0])
        self.history: list[BaseMoveResult] = []

    def current_position(self) -> np.ndarray:
        """(3,) [m] base frame: the base's centre on the table top (z = 0)."""
        return self._pos.copy()

    def _viewpoint(self) -> tuple[float, float]:
        """Where the base stands: "the nearest chair" is nearest it."""
        return float(self._pos[0]), float(self._pos[1])

    def _nearest_free(self, goal_cell: np.ndarray, start_cell: tuple[int, int]):
        """The free cell reachable from the start nearest to ``goal_cell`` (or None)."""
        free = ~self.blocked.occupied
        lab, _ = ndimage.label(free, structure=np.ones((3, 3)))
        region = lab == lab[start_cell]
        cells = np.argwhere(region)
        d = np.linalg.norm(cells - goal_cell, axis=1) * self.blocked.cell_size
        k = int(np.argmin(d))
        if d[k] > self.config.max_goal_shift:
            return None
        return tuple(int(v) for v in cells[k])

    def _result(
        self, reached, reason, target, goal, shifted, path_xy, note: str = ""
    ) -> BaseMoveResult:
        path = np.zeros((0, 3))
        length = 0.0
        if path_xy is not None and len(path_xy):
            path = np.column_stack([path_xy, np.zeros(len(path_xy))])
            length = float(np.linalg.norm(np.diff(path_xy, axis=0), axis=1).sum())
        if reached:
            self._pos = np.array([goal[0], goal[1], 0.0])
        r = BaseMoveResult(
            reached=reached,
            reason=reason,
            target=target,
            goal=goal,
            goal_shifted=shifted,
            final_position=self._pos.copy(),
            path=path,
            length_m=length,
            error_m=float(np.hypot(*(self._pos[:2] - target[:2]))),
            note=note,
        )
        self.history.append(r)
        return r

    def move_to(self, pos) -> BaseMoveResult:
        """Plan a collision-free path to ``pos`` (x, y used) and follow it.

        The base drives on the table's top (z = 0): a point more than the success radius below
        it is refused (``below_table``, nothing moves), as the base on the top above it would
        not be within that radius of it."""
        target = _point(pos)
        if target[2] < -SUCCESS_RADIUS_M:
            note = (
                f"the target lies {-target[2]:.2f} m below the table's top (z = 0), where the "
                f"base drives: beyond the {SUCCESS_RADIUS_M * 100:.0f} cm success radius of any "
                "point it can reach, so nothing moved"
            )
            return self._result(False, "below_table", target, target, False, None, note)
        occ = self.blocked
        sc, s_in = occ.to_cell(self._pos)
        gc, g_in = occ.to_cell(target)
        if not g_in:
            return self._result(False, "outside_map", target, target, False, None)
        sc = (int(sc[0]), int(sc[1]))
        if not s_in or occ.occupied[sc]:
            return self._result(False, "start_blocked", target, target, False, None)
        shifted = bool(occ.occupied[tuple(gc)])
        goal_cell = self._nearest_free(gc, sc) if shifted else (int(gc[0]), int(gc[1]))
        if goal_cell is None:
            return self._result(False, "no_path", target, target, shifted, None)
        # the last cell is free: finish on the exact point (or the shifted cell's centre)
        end = target[:2] if not shifted else occ.to_world(np.array([goal_cell]))[0]
        xy = grid_path(occ.occupied, occ.cell_size, self._pos[:2], end, occ.lower)
        if xy is None:
            return self._result(False, "no_path", target, target, shifted, None)
        goal = np.array([xy[-1][0], xy[-1][1], 0.0])
        return self._result(True, "reached", target, goal, shifted, xy)
