"""tabletop: audio-visual-language maps for a Panda arm on a tabletop."""

from tabletop.errors import (
    AssetError,
    ConfigError,
    RecordingError,
    SceneError,
    SimulationError,
    TabletopError,
)

__version__ = "0.1.0"

__all__ = [
    "AssetError",
    "ConfigError",
    "RecordingError",
    "SceneError",
    "SimulationError",
    "TabletopError",
    "__version__",
]
