"""The values of visual localization: how it is done and what it found.

- :class:`VisualLocalizationConfig`: how reference frames are kept and how a query image is
  localised (one typed config, checked where it is built).
- :class:`VisualLocalization`: where a query image was taken (``ok`` with the pose), or why
  that is not known (``ok=False`` with a reason).
- :func:`look_at_point`: where a camera's optical axis meets the table plane.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from tabletop.errors import ConfigError

__all__ = ["MATCHERS", "VisualLocalization", "VisualLocalizationConfig", "look_at_point"]

#: Local feature backends by name.
MATCHERS = ("xfeat", "sift")


# ---------------------------------------------------------------------------- config
@dataclass(frozen=True)
class VisualLocalizationConfig:
    """How reference frames are kept and how a query image is localised."""

    matcher: str = "xfeat"
    """Local feature backend: one of :data:`MATCHERS`."""
    stride: int = 5
    """Keep every ``stride``-th frame as a reference frame (at the scans' 30 Hz and
    0.15-0.45 m/s, one every 2.5-7.5 cm of camera travel)."""
    max_keypoints: int = 1024
    """Most keypoints extracted per image."""
    top_n: int = 3
    """Reference frames matched per query (most retrieval votes first); their 2D-3D matches
    enter one PnP-RANSAC together."""
    min_inliers: int = 15
    """Fewest PnP-RANSAC inliers for a pose to count as localised."""
    min_inlier_ratio: float = 0.2
    """Smallest inliers / 2D-3D matches for a pose to count as localised."""
    reprojection_px: float = 5.0
    """RANSAC inlier threshold [px]. 3 px lost true poses of oblique close-ups whose correct
    matches reproject 3-10 px off (measured on the default scene; 5 px and 8 px did equally)."""
    ransac_iterations: int = 2000
    """Most RANSAC iterations."""
    min_depth_m: float = 0.12
    """Reference keypoints nearer than this [m] are dropped (the gripper fingers)."""
    max_depth_m: float = 2.0
    """Reference keypoints farther than this [m] are dropped."""
    max_depth_jump_m: float = 0.02
    """Reference keypoints whose 5x5 depth neighbourhood spans more than this [m] (an object
    silhouette, where a keypoint may belong to either surface) are dropped."""
    sift_ratio: float = 0.8
    """Lowe's ratio for the SIFT matcher."""
    lighterglue_min_confidence: float = 0.1
    """Smallest LighterGlue match confidence."""
    min_image_std: float = 2.0
    """A query image whose grey values vary less than this (std, 0..255) is blank."""
    verify_min_inliers: int = 6
    """With a :class:`PhotometricCheck` (a map to check poses against): fewest PnP inliers of
    a candidate pose. The check, not the inlier count, then decides; a plain table seen with
    one or two smooth objects gives 8-14 correct inliers, fewer than ``min_inliers``."""
    min_agreement: float = 0.75
    """With a :class:`PhotometricCheck`: smallest share of the image's sample pixels whose
    colour the map, seen from the candidate pose, reproduces. On the eval-map image goals
    (103 goals, 3 seeds; ``tools/image_candidates.py``) the true camera poses scored
    0.83-0.96, and 22 of 360 wrong candidates passed (``min_kappa`` refuses 13 of those)."""
    require_look_down: bool = True
    """A pose must look down at the table (its optical axis meets the plane z = 0 in front
    of it): a wrist camera over a table does; a mobile base's mast camera looking across a
    room need not (False)."""
    upright: bool = False
    """Query images are taken upright (a mast camera, a person standing in a room): feature
    matching tries the image as it is, not its quarter turns as well (a wrist camera rolls, so
    the arm's maps try all four). The map search is upright either way."""
    min_kappa: float = 0.3
    """With a :class:`PhotometricCheck`: smallest agreement beyond chance (Cohen's kappa). On
    the eval-map image goals the true camera poses scored 0.39-0.89 (a view of plain table
    and a smooth object agrees with plain table anywhere; kappa discounts that)."""
    sure_agreement: float = 0.85
    """With a :class:`PhotometricCheck`: a candidate with this agreement and ``sure_kappa``
    ends the search (the remaining quarter turns are not tried). A one-off simulation over the
    eval-map image goals' scored candidates: 43 % of the turns skipped, no result changed."""
    sure_kappa: float = 0.5
    """See ``sure_agreement``."""
    min_coverage: float = 0.25
    """With a :class:`PhotometricCheck`: smallest share of the sample pixels whose ray meets
    the map (a pose looking mostly past the table cannot be checked)."""
    colour_tolerance: float = 40.0
    """A sample pixel agrees when its colour (5x5 Gaussian blur) lies within this Euclidean
    RGB distance (0..255 per channel) of the map's voxel colour."""
    check_step_px: int = 8
    """Sample pixels of the photometric check: every ``check_step_px``-th row and column."""
    search: bool = False
    """With a photometric check: when feature matching finds no pose, search the map itself
    (:class:`~tabletop.mapping.visual.panorama.PanoramaSearch`: panoramas of the coloured
    voxels from free places at the reference cameras' height) and let the check judge its
    best ``search_candidates`` poses. For images taken far from the scan's path (a room);
    the poses are as fine as the search grid."""
    search_step_m: float = 0.25
    """Spacing of the search's places [m]."""
    search_azimuth_deg: float = 2.0
    """Panorama bin [deg] (azimuth and elevation); also the yaw step."""
    search_pitch_min_deg: float = -45.0
    """Lowest camera pitch searched [deg] (negative: looking down)..."""
    search_pitch_max_deg: float = 10.0
    """...highest..."""
    search_pitch_step_deg: float = 5.0
    """...and the step between them."""
    search_clearance_m: float = 0.15
    """A place has no voxel within this [m] in the column up to above the camera."""
    search_candidates: int = 8
    """Best places whose poses the photometric check judges."""
    search_rare_share: float = 0.02
    """A colour is rare when at most this share of the map's voxels has it (within
    ``colour_tolerance``): an object's colour, not a floor's, a wall's or a table top's."""
    search_min_rare: int = 15
    """A searched pose counts only where the map shows this many of the check's sample
    pixels with a rare colour (an image of a bare wall or floor singles out no place)..."""
    search_min_rare_agreement: float = 0.2
    """...and reproduces this share of them..."""
    search_min_kappa: float = 0.45
    """...and agrees with the map this far beyond chance (a searched pose is the best of
    some 10^5 poses, so chance agreement is stricter to beat than for a pose from matches)..."""
    search_strong_kappa: float = 0.6
    """...and, below this kappa, reproduces ``search_weak_rare_agreement`` of the rare
    colours: a pose that reproduces the image less well overall must show more of what sets
    the place apart."""
    search_weak_rare_agreement: float = 0.35
    """Calibrated on 120 random upright views at 1.1 m (``tools/image_search_calibration.py``:
    60 of the two tune rooms in their own maps, 60 of the other room), poses refined
    (:meth:`~tabletop.mapping.visual.photometric.PhotometricCheck.refine_upright`): with these
    settings the search localised 29 of the 43 own-room views feature matching did not, all
    within 1 m, and none of the other room's 56 that matching did not find; a single test of
    kappa 0.6 and rare agreement 0.1 found as many own-room views and one of the other room's."""

    def __post_init__(self) -> None:
        if self.matcher not in MATCHERS:
            raise ConfigError(f"unknown matcher {self.matcher!r}; valid: {list(MATCHERS)}")
        for name in ("stride", "max_keypoints", "top_n", "ransac_iterations", "check_step_px"):
            if int(getattr(self, name)) < 1:
                raise ConfigError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.min_inliers < 4:
            raise ConfigError(
                f"min_inliers must be >= 4 (PnP needs 4 points), got {self.min_inliers}"
            )
        if not 0 <= self.min_inlier_ratio <= 1:
            raise ConfigError(f"min_inlier_ratio must be in [0, 1], got {self.min_inlier_ratio}")
        if self.reprojection_px <= 0:
            raise ConfigError(f"reprojection_px must be > 0, got {self.reprojection_px}")
        if not 0 <= self.min_depth_m < self.max_depth_m:
            raise ConfigError(
                f"need 0 <= min_depth_m < max_depth_m, got {self.min_depth_m}, {self.max_depth_m}"
            )
        if not 0 < self.sift_ratio < 1:
            raise ConfigError(f"sift_ratio must be in (0, 1), got {self.sift_ratio}")
        if not 4 <= self.verify_min_inliers <= self.min_inliers:
            raise ConfigError(
                f"verify_min_inliers must be in [4, min_inliers={self.min_inliers}], "
                f"got {self.verify_min_inliers}"
            )
        for name in ("min_agreement", "min_coverage", "min_kappa", "sure_agreement", "sure_kappa"):
            if not 0 <= getattr(self, name) <= 1:
                raise ConfigError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if self.colour_tolerance <= 0:
            raise ConfigError(f"colour_tolerance must be > 0, got {self.colour_tolerance}")
        for name in ("search_step_m", "search_azimuth_deg", "search_pitch_step_deg"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"{name} must be > 0, got {getattr(self, name)}")
        if not -90 <= self.search_pitch_min_deg <= self.search_pitch_max_deg <= 90:
            raise ConfigError(
                f"need -90 <= search_pitch_min_deg <= search_pitch_max_deg <= 90 [deg], got "
                f"{self.search_pitch_min_deg}, {self.search_pitch_max_deg}"
            )
        for name in (
            "search_rare_share",
            "search_min_rare_agreement",
            "search_weak_rare_agreement",
            "search_min_kappa",
            "search_strong_kappa",
        ):
            if not 0 <= getattr(self, name) <= 1:
                raise ConfigError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if self.search_min_rare < 0:
            raise ConfigError(f"search_min_rare must be >= 0, got {self.search_min_rare}")
        if not self.search_clearance_m >= 0 or self.search_candidates < 1:
            raise ConfigError(
                f"need search_clearance_m >= 0 and search_candidates >= 1, got "
                f"{self.search_clearance_m}, {self.search_candidates}"
            )

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class VisualLocalization:
    """Where a query image was taken (``ok``), or why that is not known (``not ok``).

    ``T_world_cam`` is the query camera's pose (OpenCV optical frame). ``look_at_point`` is
    where its optical axis meets the table plane ``z = 0`` (``None`` when the axis does not
    point down at the table); the map refines it to the surface the image centre shows.
    """

    ok: bool
    reason: str  # "" when ok; otherwise what failed, for a person to read
    T_world_cam: np.ndarray | None  # (4, 4) float64 [m], OpenCV camera in the world frame
    look_at_point: np.ndarray | None  # (3,) float64 [m], world frame, on the table plane
    inliers: int = 0  # PnP-RANSAC inliers
    matches: int = 0  # 2D-3D matches that entered PnP
    references: tuple[int, ...] = ()  # recording frame indices matched, most votes first
    time_s: float = 0.0  # wall-clock time of the query [s]
    agreement: float | None = None  # photometric check of the pose (None: not checked)
    kappa: float | None = None  # its agreement beyond chance
    coverage: float | None = None  # share of the check's sample pixels that met the map
    searched: bool = False  # the pose came from the map search (PanoramaSearch), not matches

    def __post_init__(self) -> None:
        for name in ("T_world_cam", "look_at_point"):
            v = getattr(self, name)
            if v is not None:
                a = np.array(v, dtype=np.float64)
                a.setflags(write=False)
                object.__setattr__(self, name, a)

    @property
    def position(self) -> np.ndarray | None:
        """(3,) float64 [m]: the query camera's optical centre, world frame."""
        return None if self.T_world_cam is None else self.T_world_cam[:3, 3]

    @property
    def inlier_ratio(self) -> float:
        """Inliers / matches, in [0, 1] (0 without matches)."""
        return self.inliers / self.matches if self.matches else 0.0


def look_at_point(T_world_cam: np.ndarray, table_z: float = 0.0) -> np.ndarray | None:
    """(3,) world point [m] where the camera's optical axis (+z) meets ``z = table_z``, or
    ``None`` when the axis points level or up, or the camera is below that plane."""
    T = np.asarray(T_world_cam, dtype=np.float64)
    c, d = T[:3, 3], T[:3, 2]
    if d[2] >= -1e-6 or c[2] <= table_z:
        return None
    return c + (table_z - c[2]) / d[2] * d
