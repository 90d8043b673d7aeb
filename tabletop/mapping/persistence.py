"""Saving and loading an AVLMap: one ``.npz`` file with a JSON header (``tabletop-avlmap`` v2).

The header holds the format name and version, the map config (grid, fusion and query
parameters), the encoder set's name and what is needed to re-create it (the oracle's labels and
sound events), and the counts every array must agree with. Arrays: the voxel state (linear
indices, feature sums, point counts, colour sums), per-frame global embeddings and camera poses,
audio segments with their embeddings and positions, and (version 2) the visual localization
module's reference frames (``visual_*`` arrays, described by the header's ``visual`` entry).
Version 1 files (no visual module) still load; their maps answer image goals "not found".
Writing is atomic (a temporary file, then a rename); loading validates and names what is wrong.
See ``docs/mapping.md``.
"""

from __future__ import annotations

import json
import os
import tempfile
import zipfile
from dataclasses import asdict
from pathlib import Path

import numpy as np

from tabletop.errors import TabletopError

__all__ = ["MAP_FORMAT", "MAP_VERSION", "MapFormatError", "read_map_file", "save_map"]

MAP_FORMAT = "tabletop-avlmap"
MAP_VERSION = 2
#: Versions this code reads: 1 (no visual module) and 2.
READABLE_VERSIONS = (1, 2)


class MapFormatError(TabletopError, ValueError):
    """A map file is missing, truncated, of another version, or inconsistent."""


def save_map(m, path: str | Path, *, rebuild: dict | None = None) -> Path:
    """Write map ``m`` to ``path`` (``.npz``) atomically. ``rebuild`` is what the encoder set
    needs to be re-created on load (the registry fills it for the oracle)."""
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_suffix(".npz")
    path.parent.mkdir(parents=True, exist_ok=True)
    cfg = m.config
    header = {
        "format": MAP_FORMAT,
        "version": MAP_VERSION,
        "config": {
            "grid": cfg.grid.to_dict(),
            "pixel_step": cfg.pixel_step,
            "frame_step": cfg.frame_step,
            "categories": list(cfg.categories),
            "major_decay": cfg.major_decay,
            "aux_decay": cfg.aux_decay,
            "select_margin": cfg.select_margin,
            "min_confidence": cfg.min_confidence,
            "gate": asdict(cfg.gate),
            "self_filter_margin": cfg.self_filter_margin,
        },
        "encoders": m.encoder_names,
        "encoder_set": m.encoder_set,
        "rebuild": rebuild if rebuild is not None else m.rebuild_info,
        "dim": m.voxels.dim,
        "space": m.text.space,
        "n_voxels": m.voxels.n,
        "n_frames": len(m.frame_embeddings),
        "frames_seen": m._frames_seen,
        "n_segments": len(m.segments),
        "segments": [[s.start_s, s.end_s] for s in m.segments],
        "visual": None,
    }
    st = m.voxels.state()
    d = m.voxels.dim
    arrays = {
        "voxel_linear": st["linear"],
        "voxel_feature_sums": st["feature_sums"],
        "voxel_counts": st["counts"],
        "voxel_color_sums": st["color_sums"],
        "frame_embeddings": np.array(m.frame_embeddings, np.float32).reshape(-1, d),
        "frame_poses": np.array(m.frame_poses, np.float64).reshape(-1, 4, 4),
        "segment_embeddings": np.array(m.segment_embeddings, np.float32).reshape(-1, d),
        "segment_positions": np.array(m.segment_positions, np.float64).reshape(-1, 3),
    }
    if m.visual is not None:
        header["visual"], visual = m.visual.state()
        arrays.update({f"visual_{k}": v for k, v in visual.items()})
    arrays["header"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    os.close(fd)
    try:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def read_map_file(path: str | Path) -> tuple[dict, dict[str, np.ndarray]]:
    """The header and arrays of a map file, validated."""
    path = Path(path)
    if not path.is_file():
        raise MapFormatError(f"map file {path} not found")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as e:
        raise MapFormatError(f"{path} is not a readable map file (truncated?): {e}") from None
    if "header" not in arrays:
        raise MapFormatError(f"{path} has no header: not a {MAP_FORMAT} file")
    try:
        h = json.loads(arrays.pop("header").tobytes().decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise MapFormatError(f"{path}: header is not valid JSON: {e}") from None
    if h.get("format") != MAP_FORMAT:
        raise MapFormatError(f"{path}: format {h.get('format')!r}, expected {MAP_FORMAT!r}")
    if h.get("version") not in READABLE_VERSIONS:
        raise MapFormatError(
            f"{path}: version {h.get('version')!r} is not supported; this tabletop reads "
            f"versions {list(READABLE_VERSIONS)}"
        )
    expect = {
        "voxel_linear": (h["n_voxels"],),
        "voxel_feature_sums": (h["n_voxels"], h["dim"]),
        "voxel_counts": (h["n_voxels"],),
        "voxel_color_sums": (h["n_voxels"], 3),
        "frame_embeddings": (h["n_frames"], h["dim"]),
        "frame_poses": (h["n_frames"], 4, 4),
        "segment_embeddings": (h["n_segments"], h["dim"]),
        "segment_positions": (h["n_segments"], 3),
    }
    for name, shape in expect.items():
        if name not in arrays:
            raise MapFormatError(f"{path}: array {name!r} is missing")
        if arrays[name].shape != tuple(shape):
            raise MapFormatError(
                f"{path}: array {name!r} has shape {arrays[name].shape}, header says {shape}"
            )
    return h, arrays
