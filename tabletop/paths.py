"""Where the project's shipped assets live (the repository is installed in editable mode)."""

from __future__ import annotations

from pathlib import Path

from tabletop.errors import AssetError

__all__ = ["DATA_DIR", "PACKAGE_DIR", "REPO_DIR", "URDF_DIR", "panda_urdf_path"]

PACKAGE_DIR = Path(__file__).resolve().parent
REPO_DIR = PACKAGE_DIR.parent
DATA_DIR = PACKAGE_DIR / "data"
URDF_DIR = REPO_DIR / "urdf"


def panda_urdf_path() -> Path:
    """Path of the one Panda URDF that PyBullet, Pinocchio and MuJoCo all load."""
    path = URDF_DIR / "panda" / "panda.urdf"
    if not path.is_file():
        raise AssetError(
            f"Panda URDF not found at {path}; install tabletop from a clone of the repository "
            "with `pip install -e .` so that urdf/ sits beside the package"
        )
    return path
