"""Mapping: encoders, voxel fusion, the four localisation modules, heatmaps, targets and the
AVLMap. Imports neither the simulator nor the arm: a map is built from a recording.

    from tabletop.mapping import AVLMap, MapConfig, fuse
"""

from tabletop.mapping.avlmap import AVLMap, MapStats, SelfFilter
from tabletop.mapping.calibration import Calibration, load_calibration
from tabletop.mapping.config import MapConfig
from tabletop.mapping.heatmaps import AUX_DECAY, MAJOR_DECAY, Heatmap, fuse
from tabletop.mapping.object_module import BACKGROUND
from tabletop.mapping.targets import approach_point, max_position, region_box

__all__ = [
    "AUX_DECAY",
    "BACKGROUND",
    "MAJOR_DECAY",
    "AVLMap",
    "Calibration",
    "Heatmap",
    "MapConfig",
    "MapStats",
    "SelfFilter",
    "approach_point",
    "fuse",
    "load_calibration",
    "max_position",
    "region_box",
]
