"""The visual localization module of a map: an image of the table becomes a heatmap around the
surface point it shows at its centre.

The image is localised against the reference frames (:func:`localize_image`), each candidate
pose checked against the map's voxel colours (:class:`PhotometricCheck`); the target is where
rays through the image's centre meet the map's surface, and
``H_v(p) = max(1 - eps * d_xy(p, p_v), 0)``. The evidence is the pose's photometric agreement
beyond chance (kappa).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from tabletop.errors import ConfigError
from tabletop.mapping.heatmaps import Heatmap, Judge, scored_points_heatmap_xy
from tabletop.mapping.visual.database import VisualDatabase
from tabletop.mapping.visual.inputs import check_rgb
from tabletop.mapping.visual.localization import VisualLocalization, VisualLocalizationConfig
from tabletop.mapping.visual.localize import localize_image
from tabletop.mapping.visual.panorama import PanoramaSearch
from tabletop.mapping.visual.photometric import PhotometricCheck
from tabletop.mapping.voxel_map import VoxelMap
from tabletop.transforms import pixel_rays

__all__ = ["TARGETS", "VisualModule", "VisualModuleConfig"]

#: What an image goal may name (:attr:`VisualModuleConfig.target`).
TARGETS = ("view", "camera")


@dataclass(frozen=True)
class VisualModuleConfig:
    """The visual localization module: how it localises an image, and what the image names."""

    localization: VisualLocalizationConfig = field(default_factory=VisualLocalizationConfig)
    """Reference frames, matcher and pose checks."""
    target_px: float = 0.2
    """An image's target is the median surface point of the rays through the central
    ``target_px`` fraction of its width and height."""
    target: str = "view"
    """What an image goal names: "view", the point the image shows (a wrist camera over a
    table: reach what it looks at), or "camera", where it was taken, on the floor beneath the
    camera (a mobile base goes to where the picture was taken, as in the paper)."""

    def __post_init__(self) -> None:
        if self.target not in TARGETS:
            raise ConfigError(f"target must be one of {list(TARGETS)}, got {self.target!r}")
        if not isinstance(self.localization, VisualLocalizationConfig):
            raise ConfigError(
                "localization must be a VisualLocalizationConfig, got "
                f"{type(self.localization).__name__}"
            )
        if not 0 < self.target_px <= 1:
            raise ConfigError(f"target_px must be in (0, 1], got {self.target_px}")


class VisualModule:
    """Image queries on a map's voxels and reference frames.

    Args:
        voxels: the map's voxels (occupancy for the image target, colours for the check).
        database: the reference frames (``None``: the map has no visual module; every image
            query is then not found, with that reason).
        target_px: see :attr:`VisualModuleConfig.target_px`.
    """

    def __init__(
        self,
        voxels: VoxelMap,
        database: VisualDatabase | None,
        target_px: float = 0.2,
        target: str = "view",
    ) -> None:
        if not 0 < target_px <= 1:
            raise ConfigError(f"target_px must be in (0, 1], got {target_px}")
        if target not in TARGETS:
            raise ConfigError(f"target must be one of {list(TARGETS)}, got {target!r}")
        self.voxels = voxels
        self.database = database
        self.target_px = float(target_px)
        self.target = target
        self._check: tuple[tuple[int, int], PhotometricCheck] | None = None
        self._search: tuple[tuple[int, int], PanoramaSearch | None] | None = None

    def photometric_check(self) -> PhotometricCheck:
        """The map's voxel colours as a :class:`PhotometricCheck` of candidate camera poses
        (built on first use, again after the voxels changed)."""
        key = (self.voxels.n, self.voxels.version)
        if self._check is None or self._check[0] != key:
            v = self.voxels
            self._check = (key, PhotometricCheck(v.grid, v.indices, v.mean_colors()))
        return self._check[1]

    def panorama_search(self) -> PanoramaSearch | None:
        """The map's :class:`PanoramaSearch` (built on first use, again after the voxels
        changed), at the median height of the reference cameras; None where the config does
        not search or there are no reference frames."""
        db = self.database
        if db is None or not db.config.search or not len(db):
            return None
        key = (self.voxels.n, self.voxels.version)
        if self._search is None or self._search[0] != key:
            v = self.voxels
            height = float(np.median(db.T_world_cam[:, 2, 3]))
            search = PanoramaSearch(v.grid, v.indices, v.mean_colors(), height, db.config)
            self._search = (key, search)
        return self._search[1]

    def localize(self, rgb: np.ndarray, K: np.ndarray | None = None) -> VisualLocalization:
        """Where the camera was when it took ``rgb`` (H, W, 3) uint8; ``ok=False`` with a
        reason when that is not known. ``K`` (3, 3) [px] is needed for an image of another
        size than the reference frames (another camera)."""
        rgb = check_rgb(rgb)
        db = self.database
        if db is None:
            return VisualLocalization(
                False,
                "the map has no visual localization module (MapConfig.visual=None)",
                None,
                None,
            )
        size = (rgb.shape[1], rgb.shape[0])
        if K is None and len(db) and size != db.image_size:
            raise ConfigError(
                f"the image is {size[0]}x{size[1]} px but the map's camera "
                f"{db.image_size[0]}x{db.image_size[1]}: give the camera's intrinsics K with "
                f"it (AVLMap.image_heatmap's or localize's K=), or, from the command line, an "
                f"image of {db.image_size[0]}x{db.image_size[1]} px taken by the map's camera"
            )
        return localize_image(
            db, rgb, K, check=self.photometric_check(), search=self.panorama_search
        )

    def image_target(
        self, T_world_cam: np.ndarray, K: np.ndarray, image_size: tuple[int, int]
    ) -> np.ndarray:
        """(3,) [m] world point an image taken from ``T_world_cam`` shows at its centre.

        Rays through a 5 x 5 grid over the central ``target_px`` of the image (``K`` (3, 3)
        [px], ``image_size`` = (width, height) [px]) are marched through the map's occupancy
        to the first occupied voxel, or to the table plane z = 0; the target is their per-axis
        median, which one ray grazing an object's edge does not sway.
        """
        w, h = image_size
        f = self.target_px / 2
        u, v = np.meshgrid(
            np.linspace(0.5 - f, 0.5 + f, 5) * w, np.linspace(0.5 - f, 0.5 + f, 5) * h
        )
        rays = pixel_rays(K, T_world_cam, u, v)
        c = np.asarray(T_world_cam, np.float64)[:3, 3]
        # March to the table plane (2 m at most).
        s_max = np.where(rays[:, 2] < -1e-6, -c[2] / np.minimum(rays[:, 2], -1e-6), 2.0)
        grid = self.voxels.grid
        hit, first = grid.march(c, rays, self.voxels.occupancy(), np.minimum(s_max, 2.0))
        table = ~hit & (s_max < 2.0)
        hits = np.concatenate([first[hit], c + s_max[table, None] * rays[table]])
        if not len(hits):
            return c + s_max[len(rays) // 2] * rays[len(rays) // 2]
        return np.median(hits, axis=0)

    def heatmap(
        self, rgb: np.ndarray, decay: float, judge: Judge, K: np.ndarray | None = None
    ) -> Heatmap:
        """Heat around the table point an image shows (or, with ``target="camera"``, the
        floor beneath where it was taken); a failed localisation is not found with its reason
        (``evidence``: the refused best pose's kappa, None without a pose)."""
        grid = self.voxels.grid
        rgb = check_rgb(rgb)
        query = f"image {rgb.shape[1]}x{rgb.shape[0]}"
        loc = self.localize(rgb, K)
        if not loc.ok:
            h = Heatmap.not_found(grid, query, "image", decay, loc.reason)
            return replace(h, evidence=loc.kappa)
        conf, _ = judge("image", loc.kappa)
        K = self.database.K if K is None else K
        if self.target == "camera":  # where it was taken, on the floor beneath the camera
            target = np.asarray(loc.T_world_cam, np.float64)[:3, 3] * [1.0, 1.0, 0.0]
        else:
            target = self.image_target(loc.T_world_cam, K, (rgb.shape[1], rgb.shape[0]))
        values = scored_points_heatmap_xy(grid, target[None, :2], [1.0], decay)
        return Heatmap(grid, values, query, "image", decay, conf, True, "", loc.kappa, target)
