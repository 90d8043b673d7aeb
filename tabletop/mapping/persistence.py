"""Saving and loading an AVLMap: one ``.npz`` file with a JSON header (``tabletop-avlmap`` v5).

The header holds the format name and version, the map config (:meth:`MapConfig.to_dict`: every
field, so a loaded map answers exactly as the saved one), the encoder set's name and what is
needed to re-create it (the oracle's labels and sound events), the confidence calibration the
map was given, and the counts every array must agree with. Arrays: the voxel state (linear
indices, feature sums, point counts, colour sums, point height sums), the object instances
(``voxel_instance``: per voxel its instance id, -1 for none), the area module's per-frame
embeddings and camera poses, the audio module's segments' embeddings and positions, and the visual
localization module's reference frames (``visual_*`` arrays, described by the header's
``visual`` entry).

Older files still load and say what they lack (:attr:`AVLMap.lacks`, filled by
:meth:`AVLMap.load`): version 1 has no visual module (image goals are not found), versions 1-2
have no saved calibration (the prior, unless one is passed to :meth:`AVLMap.load`), nor the
image target's size and the area module's config (defaults), versions 1-3 have no saved
object instances (segmented again on load, with this version's segmentation), versions 1-4
have no point heights (object heights judged by voxel centres).
Writing is atomic (a temporary file, then a rename); loading validates and names what is wrong.
See ``docs/mapping.md``.
"""

from __future__ import annotations

import json
import logging
import math
import zipfile
from pathlib import Path

import numpy as np

from tabletop.atomic import atomic_path
from tabletop.errors import ConfigError
from tabletop.mapping.errors import MapFormatError

__all__ = [
    "MAP_FORMAT",
    "MAP_VERSION",
    "READABLE_VERSIONS",
    "MapFormatError",
    "check_map_encoders",
    "check_map_output",
    "read_map_file",
    "save_map",
]

log = logging.getLogger(__name__)

MAP_FORMAT = "tabletop-avlmap"
MAP_VERSION = 5
#: Versions this code reads: 1 (no visual module), 2 (no saved calibration), 3 (no saved
#: object instances), 4 (no point heights) and 5.
READABLE_VERSIONS = (1, 2, 3, 4, 5)


def _read_header(path: Path) -> dict:
    """The JSON header of a map file, read without its arrays (:class:`MapFormatError` when
    there is none)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            header = json.loads(z["header"].tobytes().decode())
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, UnicodeDecodeError):
        raise MapFormatError(f"{path} is not a readable {MAP_FORMAT} file") from None
    if not isinstance(header, dict) or header.get("format") != MAP_FORMAT:
        raise MapFormatError(f"{path} is not a {MAP_FORMAT} file")
    return header


def check_map_encoders(path: str | Path, expected: str) -> str:
    """Check, from the header only, that the map at ``path`` was built with the encoder set
    ``expected`` (``oracle``, ``default``, ...); :class:`MapFormatError` names both when not.
    Returns the set's name."""
    path = Path(path)
    built = _read_header(path).get("encoder_set")
    if built != expected:
        raise MapFormatError(
            f"{path} was built with the encoder set {built!r}, not {expected!r}: build a map "
            f"with --encoders {expected}, or query this one as {built!r}"
        )
    return built


def _is_map_file(path: Path) -> bool:
    """Whether ``path`` is a file this package wrote as a map (its header names the format);
    only the header is read."""
    try:
        _read_header(path)
        return True
    except MapFormatError:
        return False


def _check_suffix(path: Path) -> None:
    if path.suffix != ".npz":
        raise ConfigError(
            f"map path {path} must end in .npz (a map is one .npz file); got suffix "
            f"{path.suffix or 'none'!r}"
        )
    if path.is_dir():
        raise ConfigError(f"{path} is a directory; give a .npz file path for the map")


def check_map_output(path: str | Path, overwrite: bool = False) -> Path:
    """Check before any work that a map may be written to ``path``: a ``.npz`` path that does
    not exist, or (with ``overwrite``) a map file this package wrote. Any other existing file is
    never replaced: the user's data is not ours to delete."""
    path = Path(path)
    _check_suffix(path)
    if not path.exists():
        return path
    if not overwrite:
        raise ConfigError(f"{path} exists; pass --overwrite to replace it")
    if not _is_map_file(path):
        raise ConfigError(
            f"{path} exists and is not a map (no header of format {MAP_FORMAT!r}); "
            "--overwrite only replaces a previous map: choose another path"
        )
    return path


def save_map(m, path: str | Path, *, rebuild: dict | None = None) -> Path:
    """Write map ``m`` to ``path`` (``.npz``; any other suffix is an error, never renamed)
    atomically. ``rebuild`` is what the encoder set needs to be re-created on load (the
    registry fills it for the oracle)."""
    path = Path(path)
    _check_suffix(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    sounds, areas = m.sounds, m.areas
    header = {
        "format": MAP_FORMAT,
        "version": MAP_VERSION,
        "config": m.config.to_dict(),
        "encoders": m.encoder_names,
        "encoder_set": m.encoder_set,
        "rebuild": rebuild if rebuild is not None else m.rebuild_info,
        "calibration": m.calibration.to_json(),
        "dim": m.voxels.dim,
        "space": m.text.space,
        "n_voxels": m.voxels.n,
        "n_frames": len(areas),
        "frames_seen": m.frames_seen,
        "n_segments": len(sounds),
        "segments": [[s.start_s, s.end_s] for s in sounds.segments],
        "visual": None,
    }
    st = m.voxels.state()
    d = m.voxels.dim
    arrays = {
        "voxel_linear": st["linear"],
        "voxel_feature_sums": st["feature_sums"],
        "voxel_counts": st["counts"],
        "voxel_color_sums": st["color_sums"],
        "voxel_instance": m.objects.instances.labels(),
        **({"voxel_height_sums": st["height_sums"]} if "height_sums" in st else {}),
        "frame_embeddings": np.array(areas.embeddings, np.float32).reshape(-1, d),
        "frame_poses": np.array(areas.poses, np.float64).reshape(-1, 4, 4),
        "segment_embeddings": np.array(sounds.embeddings, np.float32).reshape(-1, d),
        "segment_positions": np.array(sounds.positions, np.float64).reshape(-1, 3),
    }
    if sounds.class_logits and len(sounds.class_logits) == len(sounds):
        # the segments' AudioSet logits (the open sound vocabulary) and their class names
        header["class_names"] = list(sounds.class_names)
        arrays["segment_class_logits"] = np.stack(sounds.class_logits).astype(np.float32)
    if m.visual is not None:
        header["visual"], visual = m.visual.state()
        arrays.update({f"visual_{k}": v for k, v in visual.items()})
    arrays["header"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, **arrays)
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
    if not isinstance(h, dict) or h.get("format") != MAP_FORMAT:
        got = h.get("format") if isinstance(h, dict) else h
        raise MapFormatError(f"{path}: format {got!r}, expected {MAP_FORMAT!r}")
    if h.get("version") not in READABLE_VERSIONS:
        raise MapFormatError(
            f"{path}: version {h.get('version')!r} is not supported; this tabletop reads "
            f"versions {list(READABLE_VERSIONS)}"
        )
    counts = ("n_voxels", "dim", "n_frames", "n_segments", "frames_seen")
    for k in counts:
        v = h.get(k)
        if not isinstance(v, int) or isinstance(v, bool) or v < 0:
            raise MapFormatError(f"{path}: header field {k!r} must be a count >= 0, got {v!r}")
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
    if h["version"] >= 4:
        expect["voxel_instance"] = (h["n_voxels"],)
    if "voxel_height_sums" in arrays:
        expect["voxel_height_sums"] = (h["n_voxels"],)
    if "segment_class_logits" in arrays:
        names = h.get("class_names")
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise MapFormatError(f"{path}: segment_class_logits need a list of class_names")
        expect["segment_class_logits"] = (h["n_segments"], len(names))
    for name, shape in expect.items():
        if name not in arrays:
            raise MapFormatError(f"{path}: array {name!r} is missing")
        if arrays[name].shape != tuple(shape):
            raise MapFormatError(
                f"{path}: array {name!r} has shape {arrays[name].shape}, header says {shape}"
            )
        kind = arrays[name].dtype.kind
        if kind not in ("iu" if name in ("voxel_linear", "voxel_instance") else "fiu"):
            raise MapFormatError(f"{path}: array {name!r} has dtype {arrays[name].dtype}")
        if kind == "f" and not np.all(np.isfinite(arrays[name])):
            raise MapFormatError(f"{path}: array {name!r} holds NaN or infinite values")
    lin = arrays["voxel_linear"]
    if len(np.unique(lin)) != len(lin):
        raise MapFormatError(f"{path}: array 'voxel_linear' repeats voxel indices")
    if np.any(arrays["voxel_counts"] <= 0):
        raise MapFormatError(f"{path}: array 'voxel_counts' must be > 0 for every stored voxel")
    segs = h.get("segments")
    if not isinstance(segs, list) or len(segs) != h["n_segments"]:
        raise MapFormatError(f"{path}: header 'segments' must list {h['n_segments']} [start, end]")
    for s in segs:
        if not (
            isinstance(s, list)
            and len(s) == 2
            and all(isinstance(t, (int, float)) and not isinstance(t, bool) for t in s)
            and all(math.isfinite(t) for t in s)
            and s[0] <= s[1]
        ):
            raise MapFormatError(
                f"{path}: header 'segments' entry {s!r:.60} is not [start, end] seconds"
            )
    from tabletop.mapping.encoders.registry import ENCODER_SETS

    fields = (
        ("config", dict, "an object of map config fields"),
        ("encoders", dict, "an object naming the encoders"),
        ("encoder_set", str, f"one of {list(ENCODER_SETS)}"),
        ("rebuild", dict, "an object"),
        ("space", str, "the text embedding space's name"),
    )
    for k, kind, valid in fields:
        if not isinstance(h.get(k), kind):
            raise MapFormatError(f"{path}: header field {k!r} is {h.get(k)!r:.60}; valid: {valid}")
    if h["encoder_set"] not in ENCODER_SETS:
        raise MapFormatError(
            f"{path}: header field 'encoder_set' is {h['encoder_set']!r:.60}; valid: "
            f"{list(ENCODER_SETS)}"
        )
    for k in ("calibration", "visual"):
        if h.get(k) is not None and not isinstance(h[k], dict):
            raise MapFormatError(f"{path}: header field {k!r} must be an object or null")
    return h, arrays
