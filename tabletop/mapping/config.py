"""How a map is built and queried: :class:`MapConfig`, saved with the map and restored exactly."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid
from tabletop.mapping.audio_segments import NoiseGateConfig
from tabletop.mapping.heatmaps import AUX_DECAY, MAJOR_DECAY
from tabletop.mapping.object_module import BACKGROUND
from tabletop.mapping.visual.localization import VisualLocalizationConfig

__all__ = ["MapConfig"]


@dataclass(frozen=True)
class MapConfig:
    """How a map is built and queried. ``to_dict``/``from_dict`` round-trip every field."""

    grid: VoxelGrid = field(default_factory=VoxelGrid)
    """The workspace box and voxel size (1 cm by default)."""
    pixel_step: int = 3
    """Fuse every ``pixel_step``-th pixel row and column. At 320x240 and the scans' 0.3-0.7 m
    range a pixel spans 1.4-3.3 mm, so every third pixel still samples each 1 cm voxel a
    camera sees several times; use 1 for 5 mm voxels or distant views."""
    frame_step: int = 1
    """Encode and fuse every ``frame_step``-th frame (voxels and area-module embeddings)."""
    categories: tuple[str, ...] = BACKGROUND
    """The map's vocabulary: the object names it is asked about (the scene's catalog, passed
    in by whoever builds the map) and the background concepts, "other" among them. The robot
    layer's obstacle maps label voxels with it."""
    major_decay: float = MAJOR_DECAY
    """Decay [1/m] of primary heatmaps (``get_major_map``)."""
    aux_decay: float = AUX_DECAY
    """Decay [1/m] of auxiliary heatmaps (``get_map``)."""
    select_margin: float = 0.1
    """Object module: target voxels score within this fraction of (best - median) of the
    best."""
    min_confidence: float = 0.5
    """Below this calibrated confidence a query is not found (for a modality whose calibration
    has no operating point)."""
    gate: NoiseGateConfig = field(default_factory=NoiseGateConfig)
    """Audio module: the noise gate and silence segmentation."""
    area_top_score: float = 0.8
    """Area module: frames whose min-max normalised score reaches this carry the area."""
    self_filter_margin: float | None = 0.01
    """Drop points within this margin [m] of the robot's links, when the map is given a
    self-filter (None: keep them)."""
    visual: VisualLocalizationConfig | None = field(default_factory=VisualLocalizationConfig)
    """The visual localization module's reference frames and matcher (None: no image goals)."""
    image_target_px: float = 0.2
    """An image goal's target is the median surface point of the rays through the central
    ``image_target_px`` fraction of the image's width and height."""

    def __post_init__(self) -> None:
        if self.pixel_step < 1 or self.frame_step < 1:
            raise ConfigError("pixel_step and frame_step must be >= 1")
        if "other" not in self.categories:
            raise ConfigError("categories must include 'other'")
        if not 0 < self.image_target_px <= 1:
            raise ConfigError(f"image_target_px must be in (0, 1], got {self.image_target_px}")
        if not 0 < self.area_top_score <= 1:
            raise ConfigError(f"area_top_score must be in (0, 1], got {self.area_top_score}")
        for name in ("major_decay", "aux_decay"):
            v = getattr(self, name)
            if not v > 0:
                raise ConfigError(f"{name} must be a positive rate in 1/m, got {v}")

    @property
    def objects(self) -> tuple[str, ...]:
        """The vocabulary's object names (``categories`` without the background)."""
        return tuple(c for c in self.categories if c not in BACKGROUND)

    def to_dict(self) -> dict:
        """Plain JSON-able values of every field."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out["grid"] = self.grid.to_dict()
        out["categories"] = list(self.categories)
        out["gate"] = asdict(self.gate)
        out["visual"] = None if self.visual is None else asdict(self.visual)
        return out

    @classmethod
    def from_dict(cls, d: dict) -> MapConfig:
        """The config ``to_dict`` wrote; missing fields take their defaults, unknown ones are
        an error naming the valid fields."""
        if not isinstance(d, dict):
            raise ConfigError(f"a map config is a dict, got {type(d).__name__}")
        valid = [f.name for f in fields(cls)]
        unknown = sorted(set(d) - set(valid))
        if unknown:
            raise ConfigError(f"unknown map config fields {unknown}; valid: {valid}")
        kw = dict(d)
        try:
            if "grid" in kw:
                g = kw["grid"]
                kw["grid"] = VoxelGrid(tuple(g["lower"]), tuple(g["upper"]), g["voxel_size"])
            if "categories" in kw:
                kw["categories"] = tuple(kw["categories"])
            if "gate" in kw:
                kw["gate"] = NoiseGateConfig(**kw["gate"])
            if kw.get("visual") is not None:
                kw["visual"] = VisualLocalizationConfig(**kw["visual"])
            return cls(**kw)
        except (KeyError, TypeError) as e:
            raise ConfigError(f"map config is invalid: {e}") from None
