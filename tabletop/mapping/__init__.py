"""Mapping: encoders, voxel fusion, the four localisation modules, heatmaps, targets and the
AVLMap. Imports neither the simulator nor the arm: a map is built from a recording.

    from tabletop.mapping import AVLMap, MapConfig, fuse

The names below are imported on first use (PEP 562), so that a light submodule
(``tabletop.mapping.persistence``'s :func:`~tabletop.mapping.persistence.read_map_preview`,
which the viewer draws its first picture from) does not pull in the whole package.
"""

import importlib

#: Each exported name -> the submodule that defines it.
_EXPORTS = {
    "AVLMap": "avlmap",
    "MapStats": "avlmap",
    "SelfFilter": "avlmap",
    "Calibration": "calibration",
    "load_calibration": "calibration",
    "MapConfig": "config",
    "AUX_DECAY": "heatmaps",
    "MAJOR_DECAY": "heatmaps",
    "Heatmap": "heatmaps",
    "fuse": "heatmaps",
    "BACKGROUND": "object_module",
    "approach_point": "targets",
    "max_position": "targets",
    "region_box": "targets",
}

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


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'tabletop.mapping' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"tabletop.mapping.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
