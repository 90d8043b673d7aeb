"""How a map is built and queried: :class:`MapConfig`, saved with the map and restored exactly.

Each module's parameters live in its own config, next to the module: :class:`ObjectConfig`,
:class:`AreaConfig`, :class:`AudioConfig` and :class:`VisualModuleConfig`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields
from types import MappingProxyType

from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid
from tabletop.mapping.area_module import AreaConfig
from tabletop.mapping.audio_module import AudioConfig
from tabletop.mapping.audio_segments import NoiseGateConfig
from tabletop.mapping.heatmaps import AUX_DECAY, MAJOR_DECAY
from tabletop.mapping.instances import InstanceConfig
from tabletop.mapping.object_module import BACKGROUND, ObjectConfig
from tabletop.mapping.registration import RegistrationConfig
from tabletop.mapping.visual.localization import VisualLocalizationConfig
from tabletop.mapping.visual.module import VisualModuleConfig

__all__ = ["MapConfig"]

#: Fields of map files of format 1-2, before the modules had their own configs.
_LEGACY = {"select_margin", "gate", "image_target_px"}


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
    image_network: str = "table"
    """The default set's committed image network: "table" (trained on the wrist's views) or
    "room" (also on rooms seen from the mobile base's mast). Other encoder sets ignore it."""
    image_scale: int = 1
    """The default image encoder enlarges each frame this many times (1 or 2) before its
    network: a room's objects seen from metres away then look as large as a table's from
    the wrist (about four times the encoding time at 2). Other encoder sets ignore it."""
    categories: tuple[str, ...] = BACKGROUND
    """The map's vocabulary: the object names it is asked about (the scene's catalog, passed
    in by whoever builds the map) and the background concepts, "other" among them. The robot
    layer's obstacle maps label voxels with it."""
    descriptions: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    """Vocabulary name -> descriptions of it (what it is, its shape, material, use): extra text
    targets the object module matches a query's words against."""
    major_decay: float = MAJOR_DECAY
    """Decay [1/m] of primary heatmaps (``get_major_map``)."""
    aux_decay: float = AUX_DECAY
    """Decay [1/m] of auxiliary heatmaps (``get_map``)."""
    min_confidence: float = 0.5
    """Below this calibrated confidence a query is not found (for a modality whose calibration
    has no operating point)."""
    self_filter_margin: float | None = 0.01
    """Drop points within this margin [m] of the robot's links, when the map is given a
    self-filter (None: keep them)."""
    object: ObjectConfig = field(default_factory=ObjectConfig)
    """The object module."""
    area: AreaConfig = field(default_factory=AreaConfig)
    """The area module."""
    audio: AudioConfig = field(default_factory=AudioConfig)
    """The audio module (noise gate, segmentation)."""
    registration: RegistrationConfig = field(default_factory=RegistrationConfig)
    """How :meth:`AVLMap.build` corrects recorded poses onto the table (see
    :mod:`tabletop.mapping.registration`)."""
    visual: VisualModuleConfig | None = field(default_factory=VisualModuleConfig)
    """The visual localization module (None: no image goals). A
    :class:`VisualLocalizationConfig` given here is taken as that module's localization."""

    def __post_init__(self) -> None:
        for name in ("pixel_step", "frame_step"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ConfigError(f"{name} must be an integer >= 1, got {v!r}")
        if self.image_network not in ("table", "room"):
            raise ConfigError(
                f"image_network must be one of ['table', 'room'], got {self.image_network!r}"
            )
        if self.image_scale not in (1, 2) or isinstance(self.image_scale, bool):
            raise ConfigError(f"image_scale must be 1 or 2, got {self.image_scale!r}")
        object.__setattr__(self, "categories", tuple(self.categories))
        if not isinstance(self.descriptions, Mapping):
            raise ConfigError(f"descriptions must map names to texts, got {self.descriptions!r}")
        desc = {}
        for name, texts in self.descriptions.items():
            texts = (texts,) if isinstance(texts, str) else tuple(texts)
            if name not in self.categories or not all(isinstance(t, str) and t for t in texts):
                raise ConfigError(
                    f"descriptions[{name!r}] must describe a vocabulary name with non-empty "
                    f"texts; vocabulary: {list(self.categories)}"
                )
            desc[name] = texts
        object.__setattr__(self, "descriptions", MappingProxyType(desc))
        if "other" not in self.categories:
            raise ConfigError("categories must include 'other'")
        for name in ("major_decay", "aux_decay"):
            v = getattr(self, name)
            if not v > 0:
                raise ConfigError(f"{name} must be a positive rate in 1/m, got {v}")
        if isinstance(self.visual, VisualLocalizationConfig):
            object.__setattr__(self, "visual", VisualModuleConfig(localization=self.visual))
        for name, cls in (
            ("object", ObjectConfig),
            ("area", AreaConfig),
            ("audio", AudioConfig),
            ("registration", RegistrationConfig),
        ):
            if not isinstance(getattr(self, name), cls):
                raise ConfigError(
                    f"{name} must be {cls.__name__}, got {type(getattr(self, name)).__name__}"
                )
        if self.visual is not None and not isinstance(self.visual, VisualModuleConfig):
            raise ConfigError(f"visual must be a VisualModuleConfig or None, got {self.visual!r}")

    @property
    def objects(self) -> tuple[str, ...]:
        """The vocabulary's object names (``categories`` without the background)."""
        return tuple(c for c in self.categories if c not in self.object.background)

    def to_dict(self) -> dict:
        """Plain JSON-able values of every field."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out["grid"] = self.grid.to_dict()
        out["categories"] = list(self.categories)
        out["descriptions"] = {k: list(v) for k, v in self.descriptions.items()}
        for name in ("object", "area", "audio", "registration", "visual"):
            v = getattr(self, name)
            out[name] = None if v is None else _lists(asdict(v))
        return out

    @classmethod
    def from_dict(cls, d: dict) -> MapConfig:
        """The config ``to_dict`` wrote (or a map file of format 1-2's flat one); missing fields
        take their defaults, unknown ones are an error naming the valid fields."""
        if not isinstance(d, dict):
            raise ConfigError(f"a map config is a dict, got {type(d).__name__}")
        valid = [f.name for f in fields(cls)]
        unknown = sorted(set(d) - set(valid) - _LEGACY - {"visual"})
        if unknown:
            raise ConfigError(f"unknown map config fields {unknown}; valid: {valid}")
        kw = {k: v for k, v in d.items() if k not in _LEGACY}
        try:
            if "grid" in kw:
                g = kw["grid"]
                kw["grid"] = VoxelGrid(tuple(g["lower"]), tuple(g["upper"]), g["voxel_size"])
            if "categories" in kw:
                kw["categories"] = tuple(kw["categories"])
            obj = dict(kw.get("object") or {})
            if "segmentation" in obj:
                obj["segmentation"] = InstanceConfig(**obj["segmentation"])
            if "select_margin" in d:
                obj["select_margin"] = d["select_margin"]
            if "background" in obj:
                obj["background"] = tuple(obj["background"])
            kw["object"] = ObjectConfig(**obj)
            kw["area"] = AreaConfig(**(kw.get("area") or {}))
            kw["registration"] = RegistrationConfig(**(kw.get("registration") or {}))
            audio = dict(kw.get("audio") or {})
            if "gate" in d:
                audio["gate"] = d["gate"]
            if "gate" in audio:
                audio["gate"] = NoiseGateConfig(**audio["gate"])
            if "reference_sounds" in audio:
                audio["reference_sounds"] = tuple(audio["reference_sounds"])
            kw["audio"] = AudioConfig(**audio)
            if kw.get("visual") is not None:
                v = dict(kw["visual"])
                v["localization"] = VisualLocalizationConfig(**v.get("localization", {}))
                kw["visual"] = VisualModuleConfig(**v)
            return cls(**kw)
        except (KeyError, TypeError) as e:
            raise ConfigError(f"map config is invalid: {e}") from None


def _lists(d: dict) -> dict:
    """Tuples as lists (JSON has no tuples), recursively."""
    return {
        k: _lists(v) if isinstance(v, dict) else list(v) if isinstance(v, tuple) else v
        for k, v in d.items()
    }
