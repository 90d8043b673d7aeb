"""Where the project's shipped assets live (the repository is installed in editable mode)."""

from __future__ import annotations

from pathlib import Path

from tabletop.errors import AssetError

__all__ = [
    "DATA_DIR",
    "PACKAGE_DIR",
    "REPO_DIR",
    "URDF_DIR",
    "input_file_problem",
    "panda_urdf_path",
]

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


def input_file_problem(path: str | Path) -> str | None:
    """Why ``path`` cannot be read as a file, in words ("is empty", "is a directory, not a
    file", "does not exist", ...), or None when it is a readable regular file. Every loader
    says the same thing about the same problem."""
    if str(path) == "":
        return "is empty: give a file path"
    p = Path(path)
    try:
        if p.is_dir():
            return "is a directory, not a file"
        if not p.exists():
            parent = next((a for a in p.parents if a.exists()), None)
            if parent is not None and not parent.is_dir():
                return (
                    f"is not found: it does not exist ({str(parent)!r} is a file, not a directory)"
                )
            return "is not found: it does not exist"
        if not p.is_file():
            return "is not a regular file"
    except OSError as e:  # a name too long, a loop of links
        return f"cannot be looked up ({e.strerror or e})"
    return None
