"""Where in the map could an image have been taken? A render-and-compare search of the map's
coloured voxels, for images taken far from every reference frame.

Feature matching needs a reference frame that saw the scene from near the query's viewpoint.
A mobile base's scan drives one path through a room; an image taken a metre or two off it
(a person's photo, a goal image drawn anywhere on the floor, as in the paper's image goals)
shares few local features with any reference frame, and a room's repeated textures (a
chequered floor, a chessboard table) make the few matches ambiguous. The map itself still
shows what a camera there would see.

:class:`PanoramaSearch` renders the map once from a grid of candidate places: free floor
(no voxel in the column up to above the camera, for ``clearance_m`` around it, with the floor
seen nearby), at the height of the map's reference cameras (the robot's own camera). Each
place keeps a panorama: every occupied voxel splatted by azimuth and elevation, the nearest
winning, with its mean colour. A query image's sample pixels are turned into azimuths and
elevations for each camera pitch of a range (no roll: the camera is upright); a yaw is then a
shift of the azimuths, so every place, pitch and yaw is scored by a lookup: the share of the
sample pixels whose colour (5 x 5 Gaussian blur) lies within the check's tolerance of the
panorama's. :meth:`PanoramaSearch.candidates` returns the best-scoring poses; the
:class:`~tabletop.mapping.visual.photometric.PhotometricCheck` then judges them at full
resolution exactly as it judges poses from feature matches.

The search's poses are as good as its grid (``step_m``, ``azimuth_deg``, ``pitch_step_deg``):
about a decimetre and a few degrees, enough for a navigation goal ("go where this was taken"),
not for a tabletop image's target, which the arm's maps do not search for.
"""

from __future__ import annotations

import time

import cv2
import numpy as np
from scipy import ndimage

from tabletop.errors import ConfigError
from tabletop.mapping.visual.localization import VisualLocalizationConfig
from tabletop.mapping.visual.photometric import upright_pose, voxel_colours

__all__ = ["PanoramaSearch", "upright_pose"]

#: Sample pixels of a query image: every this many rows and columns.
_SAMPLE_PX = 16
#: Places nearer than this to a voxel do not splat it (it would cover the panorama).
_NEAR_M = 0.2


class PanoramaSearch:
    """Panoramas of a map's coloured voxels from a grid of free places (module docstring).

    Args:
        grid: the map's :class:`~tabletop.grid.VoxelGrid`.
        indices: (n, 3) int voxel indices of the occupied voxels.
        colours: (n, 3) uint8 their mean colours.
        camera_height: [m] the height of the places (the map's reference cameras').
        config: the search's settings (``search_*`` fields) and the colour tolerance.
    """

    def __init__(
        self,
        grid,
        indices: np.ndarray,
        colours: np.ndarray,
        camera_height: float,
        config: VisualLocalizationConfig | None = None,
    ) -> None:
        indices, colours = voxel_colours(indices, colours, "PanoramaSearch")
        if not np.isfinite(camera_height):
            raise ConfigError(f"camera_height must be finite [m], got {camera_height}")
        t0 = time.perf_counter()
        self.config = config or VisualLocalizationConfig()
        self.grid = grid
        self.camera_height = float(camera_height)
        c = self.config
        self.azimuths = max(round(360.0 / c.search_azimuth_deg), 4)
        self.elevations = max(round(90.0 / c.search_azimuth_deg), 2)
        self._el_lo, self._el_hi = np.radians(-70.0), np.radians(20.0)
        self.positions = self._places(indices)
        self.panoramas = self._render(grid.centers(indices), colours.astype(np.int16))
        # each panorama pixel as its colour's row in the palette of the colours shown (-1: no
        # voxel shows): a query tests each palette colour against its sample pixels once
        shown = self.panoramas[..., 0] >= 0
        self._palette, ids = np.unique(self.panoramas[shown], axis=0, return_inverse=True)
        self._palette = self._palette.astype(np.int32)
        self._ids = np.full(self.panoramas.shape[:3], -1, np.int32)
        self._ids[shown] = ids.reshape(-1)
        self.build_s = time.perf_counter() - t0

    def __len__(self) -> int:
        """Candidate places."""
        return len(self.positions)

    # ------------------------------------------------------------------ building
    def _places(self, indices: np.ndarray) -> np.ndarray:
        """(P, 3) [m] free places on the grid's x, y at the camera height."""
        g, c = self.grid, self.config
        occ = np.zeros(g.shape, bool)
        occ[tuple(indices.T)] = True
        zs = g.axes()[2]
        column = (zs >= 0.1) & (zs <= self.camera_height + 0.15)
        blocked = occ[:, :, column].any(axis=2)
        floor = occ[:, :, zs < 0.1].any(axis=2)
        r = max(int(np.ceil(c.search_clearance_m / g.voxel_size)), 1)
        disk = np.hypot(*np.mgrid[-r : r + 1, -r : r + 1]) <= r
        free = ~ndimage.binary_dilation(blocked, structure=disk)
        seen = ndimage.binary_dilation(floor, structure=disk)
        stride = max(round(c.search_step_m / g.voxel_size), 1)
        keep = np.zeros(free.shape, bool)
        keep[stride // 2 :: stride, stride // 2 :: stride] = True
        ij = np.argwhere(free & seen & keep)
        xs, ys, _ = g.axes()
        return np.stack([xs[ij[:, 0]], ys[ij[:, 1]], np.full(len(ij), self.camera_height)], 1)

    def _bins(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Azimuth and elevation bins of directions ``d`` (n, 3), and whether the elevation is
        within the panorama."""
        n = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
        az = np.arctan2(d[:, 1], d[:, 0])
        el = np.arcsin(np.clip(d[:, 2] / n, -1.0, 1.0))
        ai = np.floor((az + np.pi) / (2 * np.pi) * self.azimuths).astype(np.int64) % self.azimuths
        ef = (el - self._el_lo) / (self._el_hi - self._el_lo) * self.elevations
        ei = np.floor(ef).astype(np.int64)
        return ai, ei, (ei >= 0) & (ei < self.elevations)

    def _render(self, centers: np.ndarray, colours: np.ndarray) -> np.ndarray:
        """(P, E, A, 3) int16 panorama colours, -1 where no voxel shows."""
        pan = np.full((len(self.positions), self.elevations, self.azimuths, 3), -1, np.int16)
        for k, p in enumerate(self.positions):
            d = centers - p
            dist = np.linalg.norm(d, axis=1)
            ai, ei, ok = self._bins(d)
            ok &= dist > _NEAR_M
            # far first: the nearest voxel of each bin is written last
            order = np.nonzero(ok)[0][np.argsort(-dist[ok], kind="stable")]
            pan[k, ei[order], ai[order]] = colours[order]
        return pan

    # ------------------------------------------------------------------ searching
    def candidates(self, rgb: np.ndarray, K: np.ndarray, top: int = 8) -> list[tuple]:
        """The ``top`` best poses for image ``rgb`` (H, W, 3) uint8 with intrinsics ``K``:
        ``(score, T_world_cam)`` pairs, best first, at most one per place. The score is the
        share of sample pixels that agree among those the panorama shows, 0 where it shows
        fewer than half of them. Every place is scored with a quarter of the sample pixels
        first; the ``4 * top`` best are scored again with all of them."""
        if not len(self.positions):
            return []
        h, w = rgb.shape[:2]
        v, u = np.mgrid[_SAMPLE_PX // 2 : h : _SAMPLE_PX, _SAMPLE_PX // 2 : w : _SAMPLE_PX]
        seen = cv2.GaussianBlur(rgb, (5, 5), 0)[v, u].astype(np.int32)
        rays = np.linalg.inv(np.asarray(K, np.float64)) @ np.stack(
            [u.ravel() + 0.5, v.ravel() + 0.5, np.ones(u.size)]
        )
        coarse = np.zeros(v.shape, bool)
        coarse[::2, ::2] = True
        coarse = coarse.ravel()
        places = np.arange(len(self.positions))
        score, _ = self._score(places, rays[:, coarse], seen.reshape(-1, 3)[coarse])
        places = places[np.argsort(-score, kind="stable")[: 4 * top]]
        score, pose = self._score(places, rays, seen.reshape(-1, 3))
        order = np.argsort(-score, kind="stable")[:top]
        return [
            (float(score[k]), upright_pose(self.positions[places[k]], *pose[k]))
            for k in order
            if score[k] > 0
        ]

    def _score(self, places: np.ndarray, rays: np.ndarray, seen: np.ndarray):
        """Best score of each of ``places`` over every pitch and yaw for sample pixel
        ``rays`` (3, S) (camera frame) of colours ``seen`` (S, 3), and its (pitch, yaw) [rad]."""
        c = self.config
        tol2 = c.colour_tolerance**2
        step = 2 * np.pi / self.azimuths
        ids = self._ids[places]  # (P, E, A) palette rows, -1 where nothing shows
        # (palette colours + 1, S): which colours agree with each sample pixel; the last row
        # (index -1) is nothing shown, agreeing with none
        agrees = np.zeros((len(self._palette) + 1, len(seen)), bool)
        seen = np.asarray(seen, np.int32)
        for lo in range(0, len(self._palette), 4096):  # bounded temporaries
            pal = self._palette[lo : lo + 4096]
            d2 = np.zeros((len(pal), len(seen)), np.int32)
            for ch in range(3):
                d2 += (pal[:, ch, None] - seen[None, :, ch]) ** 2
            agrees[lo : lo + len(pal)] = d2 <= tol2
        n_samples = agrees.shape[1]
        agrees = agrees.reshape(-1)
        best = np.full(len(places), -1.0)
        best_pose = np.zeros((len(places), 2))
        pitches = np.arange(
            c.search_pitch_min_deg, c.search_pitch_max_deg + 1e-9, c.search_pitch_step_deg
        )
        shifts = np.arange(self.azimuths)
        for pitch in np.radians(pitches):
            d = (upright_pose(np.zeros(3), pitch, 0.0)[:3, :3] @ rays).T
            ai0, ei, ok = self._bins(d)
            if ok.mean() < 0.5:
                continue
            ai0, ei, cols = ai0[ok], ei[ok], np.flatnonzero(ok)
            for chunk in np.array_split(shifts, max(len(shifts) // 30, 1)):
                ai = (ai0[None, :] + chunk[:, None]) % self.azimuths  # (Y, S)
                v = ids[:, ei[None, :], ai]  # (P, Y, S)
                hit = v >= 0
                agree = agrees[v * n_samples + cols]  # row -1: the last, no colour
                n_hit = hit.sum(axis=2)
                score = agree.sum(axis=2) / np.maximum(n_hit, 1)
                score[n_hit < 0.5 * len(cols)] = 0.0
                j = score.argmax(axis=1)  # the chunk's best yaw per place
                sc = score[np.arange(len(j)), j]
                better = sc > best
                best[better] = sc[better]
                best_pose[better, 0] = pitch
                best_pose[better, 1] = chunk[j[better]] * step
        return best, best_pose
