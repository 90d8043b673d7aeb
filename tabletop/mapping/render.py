"""Pictures of a map and its heatmaps that a person can look at: a top-down and a side view of
the map's voxel colours with the heatmap over them in the JET colour scheme (red = hot)."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from tabletop.atomic import atomic_path, check_writable
from tabletop.errors import ConfigError

__all__ = ["VIEW_NAMES", "heatmap_view_paths", "heatmap_views", "write_heatmap_views"]

#: The views :func:`heatmap_views` draws, in order.
VIEW_NAMES = ("top", "side")


def _top_colors(m, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Colour of the outermost occupied voxel seen along ``axis`` (2: from above, 1: from the
    side, looking along +y), and a mask of where anything is."""
    shape = m.grid.shape
    idx = m.voxels.indices
    colors = m.voxels.mean_colors()
    img = np.zeros((*[n for a, n in enumerate(shape) if a != axis], 3), np.uint8)
    depth = np.full(img.shape[:2], -1)
    keep = [a for a in range(3) if a != axis]
    order = np.argsort(idx[:, axis] if axis == 2 else -idx[:, axis])
    for i in order:  # later (higher / nearer) voxels overwrite earlier ones
        u, v = idx[i, keep[0]], idx[i, keep[1]]
        img[u, v] = colors[i]
        depth[u, v] = idx[i, axis]
    return img, depth >= 0


def heatmap_views(
    m, heatmap: np.ndarray, target: np.ndarray | None = None, scale: int = 4
) -> dict[str, np.ndarray]:
    """{"top": image, "side": image} (BGR uint8): voxel colours with the heatmap blended in.

    Top view: x up the image (away from the robot), y to the left, as the robot sees the table.
    Side view: x to the right, z up.
    """
    out = {}
    for name, axis in zip(VIEW_NAMES, (2, 1), strict=True):
        base, mask = _top_colors(m, axis)
        heat = heatmap.max(axis=axis)
        jet = cv2.applyColorMap(np.clip(heat * 255, 0, 255).astype(np.uint8), cv2.COLORMAP_JET)
        rgb = np.where(mask[..., None], base, 40).astype(np.uint8)[..., ::-1]  # BGR
        alpha = (0.25 + 0.6 * heat)[..., None]
        img = (rgb * (1 - alpha) + jet * alpha).astype(np.uint8)
        if target is not None:
            t_idx, _ = m.grid.world_to_index(np.asarray(target)[None])
            u, v = [t_idx[0, a] for a in range(3) if a != axis]
            cv2.drawMarker(img, (int(v), int(u)), (255, 255, 255), cv2.MARKER_CROSS, 5, 1)
        if name == "top":
            img = img[::-1, ::-1]  # x up, y to the left
        else:
            img = np.transpose(img, (1, 0, 2))[::-1]  # x right, z up
        out[name] = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    return out


def heatmap_view_paths(path_prefix: str | Path, what: str = "picture prefix") -> list[Path]:
    """The pictures :func:`write_heatmap_views` writes for ``path_prefix``:
    ``<prefix>_top.png`` and ``<prefix>_side.png``, each checked writable
    (:func:`tabletop.atomic.check_writable`).

    Raises:
        ConfigError: ``path_prefix`` is empty, ends in a separator or is a directory (a prefix
            ends in a name the pictures' names start with), or a picture cannot be written.
    """
    text = str(path_prefix)
    if not text.strip():
        why = "is empty"
    elif text.endswith(("/", os.sep)) or Path(text).is_dir():
        why = "is a directory"
    else:
        prefix = Path(text)
        paths = [prefix.with_name(f"{prefix.name}_{name}.png") for name in VIEW_NAMES]
        for p in paths:
            check_writable(p, what=what)
        return paths
    example = str(Path(text.strip() or ".") / "query")
    raise ConfigError(
        f"{what} {text!r} {why}: a prefix ends in the name the pictures' names start with, "
        f"e.g. {example!r} writes {example}_top.png and {example}_side.png"
    )


def write_heatmap_views(
    m, heatmap: np.ndarray, path_prefix: str | Path, target: np.ndarray | None = None
) -> list[Path]:
    """Write ``<prefix>_top.png`` and ``<prefix>_side.png``; return their paths."""
    paths = heatmap_view_paths(path_prefix)  # every picture's path before the first is written
    views = heatmap_views(m, heatmap, target)
    for p, img in zip(paths, views.values(), strict=True):
        with atomic_path(p) as tmp:
            ok, data = cv2.imencode(".png", img)
            if not ok:
                raise ConfigError(f"picture {str(p)!r}: the view could not be encoded as PNG")
            tmp.write_bytes(data.tobytes())
    return paths
