"""The photometric check of a candidate camera pose against the map (:class:`PhotometricCheck`)."""

from __future__ import annotations

import itertools

import cv2
import numpy as np
from scipy import ndimage

from tabletop.errors import ConfigError
from tabletop.mapping.visual.localization import VisualLocalizationConfig
from tabletop.transforms import pixel_rays

__all__ = ["REFINE_MAX_TRIES", "REFINE_STEPS", "PhotometricCheck", "upright_pose"]

#: Colour bins per RGB channel of the map's colour histogram (:meth:`PhotometricCheck.commonness`).
_BINS = 16


def voxel_colours(indices, colours, owner: str) -> tuple[np.ndarray, np.ndarray]:
    """``indices`` (n, 3) int voxel indices and ``colours`` (n, 3) their colours as arrays,
    checked for ``owner`` (a class name, for the message)."""
    indices = np.asarray(indices)
    colours = np.asarray(colours)
    if indices.ndim != 2 or indices.shape[1] != 3 or colours.shape != indices.shape:
        raise ConfigError(
            f"{owner} needs (n, 3) indices and (n, 3) colours, got "
            f"{indices.shape} and {colours.shape}"
        )
    return indices, colours


#: Camera optical frame (x right, y down, z forward) to world for a camera looking along +x.
_CAM_TO_WORLD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
#: First steps of :meth:`PhotometricCheck.refine_upright`: x, y, z [m], pitch, yaw [rad].
REFINE_STEPS = (0.08, 0.08, 0.04, np.radians(2.0), np.radians(1.0))
#: Poses :meth:`PhotometricCheck.refine_upright` tries at most.
REFINE_MAX_TRIES = 120


def _samples(rgb: np.ndarray, step: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample pixels of ``rgb``, every ``step``-th row and column: ``u``, ``v`` (n,) and their
    colours (n, 3) float after a 5x5 Gaussian blur."""
    h, w = rgb.shape[:2]
    v, u = np.mgrid[step // 2 : h : step, step // 2 : w : step]
    u, v = u.ravel(), v.ravel()
    return u, v, cv2.GaussianBlur(rgb, (5, 5), 0)[v, u].astype(np.float64)


def upright_pose(position, pitch: float, yaw: float) -> np.ndarray:
    """(4, 4) ``T_world_cam`` (OpenCV optical frame) of an upright camera at ``position``
    (3,) [m] looking along azimuth ``yaw`` [rad] (0: +x, counter-clockwise), ``pitch`` [rad]
    above the horizontal (negative: looking down)."""
    c, s = np.cos(-pitch), np.sin(-pitch)
    tilt = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    cz, sz = np.cos(yaw), np.sin(yaw)
    turn = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    T = np.eye(4)
    T[:3, :3] = turn @ tilt @ _CAM_TO_WORLD
    T[:3, 3] = position
    return T


def _upright(p: np.ndarray) -> np.ndarray:
    """(4, 4) the upright camera pose of parameters ``p`` = (x, y, z, pitch, yaw)."""
    return upright_pose(p[:3], p[3], p[4])


class PhotometricCheck:
    """Does the map, seen from a candidate camera pose, look like the query image?

    Built from the map's occupied voxels and their mean colours. For a pose, rays through a
    grid of sample pixels (every ``check_step_px``-th row and column) are marched through the
    voxels in half-voxel steps to the first occupied one; a pixel *agrees* when its colour
    (after a 5x5 Gaussian blur) lies within ``colour_tolerance`` of that voxel's colour.
    :meth:`score` returns ``(coverage, agreement, kappa)``: the share of sample pixels whose
    ray met the map, the share of those that agree, and Cohen's kappa, the agreement beyond
    what unrelated pixels of the same colours reach by chance (a plain table agrees with a
    plain table anywhere; kappa discounts that). A right pose reproduces most of the image; a
    wrong pose that a handful of matches happen to support does not, however many inliers it
    has. (The check is the verification step of localization pipelines that render the map
    at a candidate pose, here with the fused voxel colours instead of a mesh.)
    """

    def __init__(self, grid, indices: np.ndarray, colours: np.ndarray) -> None:
        """``grid`` a :class:`~tabletop.grid.VoxelGrid`; ``indices`` (n, 3) int voxel
        indices of the occupied voxels; ``colours`` (n, 3) uint8 their mean colours."""
        indices, colours = voxel_colours(indices, colours, "PhotometricCheck")
        self.grid = grid
        self._colour = np.full((*grid.shape, 3), -1, np.int16)  # -1: empty voxel
        self._colour[tuple(indices.T)] = colours
        self._occupied = self._colour[..., 0] >= 0
        self._common: dict[float, np.ndarray] = {}  # tolerance -> commonness per colour bin

    def __len__(self) -> int:
        """Occupied voxels."""
        return int(np.count_nonzero(self._occupied))

    def commonness(self, colours: np.ndarray, tolerance: float) -> np.ndarray:
        """(n,) the share of the map's voxels whose colour lies within about ``tolerance``
        (RGB distance) of each of ``colours`` (n, 3): near 1 for the floor's colour, near 0
        for a colour only one small object has (counted in 16-level RGB bins)."""
        if tolerance not in self._common:
            # the map's voxels counted in 16 x 16 x 16 RGB bins, summed over a ball
            step = 256 // _BINS
            colours_in_map = self._colour[self._occupied].astype(np.int64) // step
            hist = np.zeros((_BINS,) * 3)
            np.add.at(hist, tuple(colours_in_map.T), 1.0)
            hist /= max(len(colours_in_map), 1)
            r = int(np.ceil(tolerance / step))
            o = np.arange(-r, r + 1)
            ball = np.add.outer(np.add.outer(o**2, o**2), o**2) * step**2 <= tolerance**2
            self._common[tolerance] = ndimage.convolve(
                hist, ball.astype(np.float64), mode="constant"
            )
        bins = np.clip(np.asarray(colours, np.int64) // (256 // _BINS), 0, _BINS - 1)
        return self._common[tolerance][tuple(bins.T)]

    def _first_colours(self, T_world_cam, K, u, v) -> tuple[np.ndarray, np.ndarray]:
        """Which rays through pixels ``(u, v)`` meet the map (R,) and the colours (n, 3) float
        of the first voxels they meet."""
        rays = pixel_rays(K, T_world_cam, u, v)
        lo, hi = np.asarray(self.grid.lower), np.asarray(self.grid.upper)
        c = np.asarray(T_world_cam)[:3, 3]
        far = float(np.linalg.norm(np.maximum(np.abs(lo - c), np.abs(hi - c))))
        hit, point = self.grid.march(c, rays, self._occupied, far)
        first = self._colour[tuple(self.grid.world_to_index(point[hit])[0].T)]
        return hit, first.astype(np.float64)

    def refine_upright(
        self, T_world_cam: np.ndarray, K: np.ndarray, rgb: np.ndarray, config=None
    ) -> tuple[np.ndarray, int]:
        """An upright camera pose near ``T_world_cam`` that reproduces more of ``rgb`` from the
        map: a compass search over position, pitch and yaw (no roll) that maximises the share
        of sample pixels (every ``2 * check_step_px``-th row and column) whose ray meets a
        voxel of their colour, from steps of :data:`REFINE_STEPS` halved twice when no move
        gains. A map search's grid poses are a decimetre and a few degrees off; the right
        place then reproduces the image nearly as well as the true pose does, a wrong place
        gains little. Returns the pose and the number of poses tried (at most
        :data:`REFINE_MAX_TRIES`)."""
        config = config or VisualLocalizationConfig()
        u, v, seen = _samples(rgb, 2 * config.check_step_px)
        tol = config.colour_tolerance
        T0 = np.asarray(T_world_cam, np.float64)
        forward = T0[:3, 2]
        x = np.array(
            [
                *T0[:3, 3],
                np.arcsin(np.clip(forward[2], -1.0, 1.0)),
                np.arctan2(forward[1], forward[0]),
            ]
        )

        def gain(p: np.ndarray) -> float:
            hit, first = self._first_colours(_upright(p), K, u, v)
            return float(np.count_nonzero(np.linalg.norm(first - seen[hit], axis=1) <= tol))

        best, tries = gain(x), 1
        steps = np.array(REFINE_STEPS, np.float64)
        for _ in range(3):  # the steps, then halved twice
            moved = True
            while moved and tries < REFINE_MAX_TRIES:
                moved = False
                for i, sign in itertools.product(range(len(x)), (1.0, -1.0)):
                    trial = x.copy()
                    trial[i] += sign * steps[i]
                    g = gain(trial)
                    tries += 1
                    if g > best:  # first gain taken: start over from the new pose
                        best, x, moved = g, trial, True
                        break
            steps /= 2
        return _upright(x), tries

    def score(
        self, T_world_cam: np.ndarray, K: np.ndarray, rgb: np.ndarray, config=None
    ) -> tuple[float, float, float]:
        """``(coverage, agreement, kappa)`` of the pose ``T_world_cam`` (4, 4) for the image
        ``rgb`` (H, W, 3) uint8 with intrinsics ``K`` (3, 3) [px]: coverage and agreement in
        [0, 1], kappa (agreement beyond chance) in [-1, 1]."""
        d = self.details(T_world_cam, K, rgb, config)
        return d["coverage"], d["agreement"], d["kappa"]

    def details(self, T_world_cam: np.ndarray, K: np.ndarray, rgb: np.ndarray, config=None):
        """:meth:`score`'s ``coverage``, ``agreement`` and ``kappa`` with what sets a place
        apart: ``rare`` (how many sample pixels the map shows whose colour at most
        ``config.search_rare_share`` of the map has: an object's, not the floor's or a wall's)
        and ``rare_agreement`` (the share of those that agree). An image of another room
        agrees with this map on floors, walls and table tops; only the right place reproduces
        its rare colours."""
        config = config or VisualLocalizationConfig()
        u, v, seen = _samples(rgb, config.check_step_px)
        hit, first = self._first_colours(T_world_cam, K, u, v)
        if not hit.any():
            none = {"coverage": 0.0, "agreement": 0.0, "kappa": 0.0}
            return {**none, "rare": 0, "rare_agreement": 0.0}
        seen = seen[hit]
        tol = config.colour_tolerance
        agree = np.linalg.norm(first - seen, axis=1) <= tol
        agreement = float(np.mean(agree))
        rare = self.commonness(seen, tol) <= config.search_rare_share
        # Chance agreement: each seen colour against the map colours of (a quarter of) the
        # other sample pixels, as if the pose were unrelated to the image.
        chance = float(np.mean(np.linalg.norm(seen[:, None] - first[None, ::4], axis=2) <= tol))
        kappa = (agreement - chance) / (1.0 - chance) if chance < 1.0 else 0.0
        return {
            "coverage": float(hit.mean()),
            "agreement": agreement,
            "kappa": float(kappa),
            "rare": int(rare.sum()),
            "rare_agreement": float(agree[rare].mean()) if rare.any() else 0.0,
        }
