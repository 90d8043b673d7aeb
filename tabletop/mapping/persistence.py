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

import hashlib
import json
import logging
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tabletop.atomic import atomic_path, check_writable
from tabletop.errors import ConfigError, count_problem
from tabletop.mapping.errors import MapFormatError
from tabletop.paths import input_file_problem

__all__ = [
    "MAP_FORMAT",
    "MAP_VERSION",
    "READABLE_VERSIONS",
    "MapFormatError",
    "MapPreview",
    "check_map_encoders",
    "check_map_fingerprints",
    "check_map_output",
    "check_map_scene",
    "encoder_fingerprint",
    "header_fingerprint",
    "read_map_file",
    "read_map_preview",
    "save_map",
    "scene_fingerprint",
    "source_of",
    "weights_fingerprints",
]

log = logging.getLogger(__name__)

MAP_FORMAT = "tabletop-avlmap"
MAP_VERSION = 5
#: Versions this code reads: 1 (no visual module), 2 (no saved calibration), 3 (no saved
#: object instances), 4 (no point heights) and 5.
READABLE_VERSIONS = (1, 2, 3, 4, 5)
#: The first version saved with its calibration: from it on, a map without one was edited.
FIRST_CALIBRATED_VERSION = 3


def _digest(obj) -> str:
    """A short content hash of a JSON-serialisable value (keys sorted)."""
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def header_fingerprint(header: dict) -> str:
    """The fingerprint of a whole map header but its ``fingerprints`` (each of which guards
    its own part): any field edited after the save (its version, scene, source, config,
    segments) changes it."""
    return _digest({k: v for k, v in header.items() if k != "fingerprints"})


def scene_fingerprint(scene: dict) -> str | None:
    """The fingerprint of a scene spec's content (``SceneSpec.to_dict()``, as a simulated
    recording's ground truth keeps it under ``scene``): its table and objects, not its name.
    None when ``scene`` is not such a dict."""
    if not isinstance(scene, dict) or "objects" not in scene:
        return None
    return _digest({"table": scene.get("table"), "objects": scene.get("objects")})


def source_of(recording) -> dict:
    """What a map built from ``recording`` was built from: the scene's name and fingerprint
    (:func:`scene_fingerprint`; None for a recording without ground truth), the room's name
    (a room scan's), and a fingerprint of the recording's poses and timestamps."""
    gt = recording.ground_truth if isinstance(recording.ground_truth, dict) else {}
    meta = recording.meta if isinstance(recording.meta, dict) else {}
    h = hashlib.sha256()
    for a in (recording.timestamps, recording.T_world_hand):
        h.update(np.ascontiguousarray(a).tobytes())
    return {
        "scene": meta.get("scene"),
        "room": meta.get("room"),
        "scene_fingerprint": scene_fingerprint(gt.get("scene")),
        "recording_fingerprint": h.hexdigest()[:16],
        "frames": len(recording),
    }


#: Files hashed whole up to this size [bytes]; larger ones (foundation-model checkpoints) by
#: their size and first and last MiB.
_WHOLE_FILE_BYTES = 64 * 2**20


def _file_fingerprint(path: Path) -> str:
    h = hashlib.sha256()
    size = path.stat().st_size
    h.update(str(size).encode())
    with open(path, "rb") as f:
        if size <= _WHOLE_FILE_BYTES:
            h.update(f.read())
        else:
            h.update(f.read(2**20))
            f.seek(-(2**20), 2)
            h.update(f.read())
    return h.hexdigest()[:16]


def _weight_files(encoder_set: str, rebuild: dict) -> dict[str, Path]:
    """The weights files the encoder set ``encoder_set`` with ``rebuild`` loads, by role."""
    if encoder_set == "default":
        from tabletop.mapping.encoders.audio import DEFAULT_AUDIO_WEIGHTS
        from tabletop.mapping.encoders.registry import vision_network_path
        from tabletop.mapping.encoders.yamnet_audio import DEFAULT_HEAD_WEIGHTS

        kind = rebuild.get("audio_encoder") or "melcnn"
        audio = DEFAULT_HEAD_WEIGHTS if kind == "yamnet" else DEFAULT_AUDIO_WEIGHTS
        return {
            "vision": Path(
                rebuild.get("vision_weights")
                or vision_network_path(rebuild.get("vision_network") or "table")
            ),
            "audio": Path(rebuild.get("audio_weights") or audio),
        }
    if encoder_set == "openclip":
        keys = (("image_text", "checkpoint"), ("audio", "clap_checkpoint"))
        return {role: Path(rebuild[k]) for role, k in keys if rebuild.get(k)}
    return {}  # the oracle reads the recording's labels, kept in ``rebuild``


def weights_fingerprints(encoder_set: str, rebuild: dict) -> dict[str, str | None]:
    """Per role, the fingerprint of the weights file the encoder set loads (None: the file is
    missing)."""
    out: dict[str, str | None] = {}
    for role, path in _weight_files(encoder_set, rebuild).items():
        out[role] = _file_fingerprint(path) if path.is_file() else None
    return out


def encoder_fingerprint(encoder_set: str, encoders: dict, rebuild: dict) -> str:
    """The fingerprint of a map's encoder fields as written (set, names, rebuild info)."""
    return _digest({"encoder_set": encoder_set, "encoders": encoders, "rebuild": rebuild})


def check_map_fingerprints(path: str | Path, h: dict) -> None:
    """Check a map header's encoder fields against what the map was written with: the set its
    names say (``encoders.set``) is its ``encoder_set``; the fields match the fingerprint
    written with them; the weights files the set loads are the ones it was built with; the
    calibration is there (versions from :data:`FIRST_CALIBRATED_VERSION` on are saved with
    it) and matches its fingerprint. :class:`MapFormatError` names the file, the field and
    what differs."""
    names = h.get("encoders") or {}
    said = str(names.get("set", "")).split(" ", 1)[0]
    if said and said != h["encoder_set"]:
        raise MapFormatError(
            f"{path}: header field 'encoder_set' is {h['encoder_set']!r} but its encoders are "
            f"{names.get('set')!r}: the header was edited; build the map again with "
            f"--encoders {h['encoder_set']}"
        )
    if h["version"] >= FIRST_CALIBRATED_VERSION and h.get("calibration") is None:
        raise MapFormatError(
            f"{path}: header field 'calibration' is missing: a map of version "
            f"{h['version']} is saved with the confidence calibration it was built with, so it "
            "was removed after the build (its answers would use the uncalibrated prior); "
            "build the map again (tabletop build-map)"
        )
    prints = h.get("fingerprints")
    if prints is None:
        return  # written before maps carried fingerprints
    if not isinstance(prints, dict):
        raise MapFormatError(f"{path}: header field 'fingerprints' must be an object")
    fields = encoder_fingerprint(h["encoder_set"], names, h["rebuild"])
    if prints.get("encoders") != fields:
        raise MapFormatError(
            f"{path}: its encoder fields (encoder_set {h['encoder_set']!r}, encoders, rebuild) "
            "do not match the fingerprint written with the map: they were edited after it "
            "was built; build the map again"
        )
    cal = prints.get("calibration")
    if cal is not None and h.get("calibration") is not None and cal != _digest(h["calibration"]):
        raise MapFormatError(
            f"{path}: header field 'calibration' does not match the fingerprint written with "
            "the map: it was edited after the build (its confidences and found decisions would "
            "not be the ones it was built with); build the map again (tabletop build-map)"
        )
    whole = prints.get("header")  # (maps written before it carry none)
    if whole is not None and whole != header_fingerprint(h):
        raise MapFormatError(
            f"{path}: its header does not match the fingerprint written with the map: a field "
            "(its version, scene, source, config or segments) was edited after the build, so "
            "the map would not answer as it was built to; build the map again (tabletop "
            "build-map)"
        )
    saved = prints.get("weights") or {}
    now = weights_fingerprints(h["encoder_set"], h["rebuild"])
    for role, fp in saved.items():
        if now.get(role) != fp:
            file = _weight_files(h["encoder_set"], h["rebuild"]).get(role)
            state = "is missing" if now.get(role) is None else "has changed (retrained?)"
            raise MapFormatError(
                f"{path}: built with {role} weights {str(file)!r} of fingerprint {fp}; that "
                f"file {state}: the map's embeddings no longer match its encoder; build the "
                "map again"
            )


def check_map_scene(path: str | Path, source: dict | None, spec_dict: dict, name: str) -> None:
    """Check that the map at ``path``, built from ``source`` (its header's ``source``), was
    built from the scene ``spec_dict`` (``SceneSpec.to_dict()``) called ``name``:
    :class:`MapFormatError` naming both scenes when not, or when the map does not say."""
    built = (source or {}).get("scene_fingerprint")
    if built is None:
        raise MapFormatError(
            f"{path} does not record the scene it was built from (a map written before maps "
            "carried it, or of a recording without ground truth): it cannot be checked "
            f"against --scene {name!r}"
        )
    if built != scene_fingerprint(spec_dict):
        said = (source or {}).get("scene")
        if said == name:  # same name, another scene: the name hides it (a random seed, an edit)
            raise MapFormatError(
                f"{path} names its scene {name!r} as --scene does, but was built from another "
                f"scene of that name (fingerprint {built}, --scene's "
                f"{scene_fingerprint(spec_dict)}): another seed or layout, or a header edited "
                "since; give the scene spec the map was built from"
            )
        raise MapFormatError(
            f"{path} was built from scene {(source or {}).get('scene')!r} (fingerprint "
            f"{built}), not from --scene {name!r} (fingerprint {scene_fingerprint(spec_dict)}): "
            "the arm would reach the map's places in another world; give the scene the map "
            "was built from"
        )


def _header_bytes(member) -> bytes:
    """The bytes of a map file's ``header`` member; ``ValueError`` when it is no array (numpy
    hands back the raw bytes of a member that is no ``.npy`` file)."""
    if not isinstance(member, np.ndarray):
        raise ValueError("its header member is not an array")
    return member.tobytes()


def _read_header(path: Path) -> dict:
    """The JSON header of a map file, read without its arrays (:class:`MapFormatError` when
    there is none)."""
    problem = input_file_problem(path)
    if problem:
        raise MapFormatError(f"map file {str(path)!r} {problem}")
    try:
        with np.load(path, allow_pickle=False) as z:
            header = json.loads(_header_bytes(z["header"]).decode())
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
    _refuse_other_file(path, "--overwrite only replaces a previous map")
    return path


def _refuse_other_file(path: Path, why: str) -> None:
    """ConfigError where ``path`` exists and is no map file: the user's data is not ours to
    replace. ``why``: what may be replaced, for the message."""
    if path.exists() and not _is_map_file(path):
        raise ConfigError(
            f"{path} exists and is not a map (no header of format {MAP_FORMAT!r}); {why}: "
            "choose another path"
        )


@dataclass(frozen=True)
class MapPreview:
    """What a picture of a map needs, read from its file without its features or encoders
    (:func:`read_map_preview`): a viewer draws it while the map itself loads."""

    header: dict
    """The file's JSON header (config, encoders, source, segments)."""
    grid: object
    """The map's :class:`~tabletop.grid.VoxelGrid`."""
    linear: np.ndarray
    """(n,) int64 the occupied voxels' linear grid indices."""
    centers: np.ndarray
    """(n, 3) float64 [m] the occupied voxels' centres."""
    colors: np.ndarray
    """(n, 3) uint8 their mean colours."""
    instance: np.ndarray
    """(n,) int64 each voxel's object instance id (-1: none; all -1 in a file without them)."""
    frame_poses: np.ndarray
    """(F, 4, 4) the area module's camera poses (the fused frames')."""
    segment_positions: np.ndarray
    """(S, 3) [m] where each audio segment was heard."""


def read_map_preview(path: str | Path) -> MapPreview:
    """The voxels, colours, instances, camera poses and sound places of the map file at
    ``path``, read lazily from the archive (no features, no encoders: milliseconds for a
    1 cm table). :class:`MapFormatError` for a file that is not a map or whose arrays
    disagree with its header; the full checks are :func:`read_map_file`'s."""
    from tabletop.grid import VoxelGrid

    path = _map_path(path)
    names = ("voxel_linear", "voxel_counts", "voxel_color_sums", "frame_poses",
             "segment_positions")  # fmt: skip
    try:
        with np.load(path, allow_pickle=False) as z:
            h = json.loads(_header_bytes(z["header"]).decode())
            a = {k: z[k] for k in names}
            inst = z["voxel_instance"] if "voxel_instance" in z.files else None
    except (ValueError, KeyError, UnicodeDecodeError):  # numpy takes it for a pickle, ...
        raise _not_a_map(path) from None
    except (OSError, EOFError, zipfile.BadZipFile) as e:
        raise MapFormatError(f"{path} is not a readable map file (truncated?): {e}") from None
    if not isinstance(h, dict) or h.get("format") != MAP_FORMAT:
        raise MapFormatError(f"{path}: not a {MAP_FORMAT} file")
    try:
        g = h["config"]["grid"]
        grid = VoxelGrid(tuple(g["lower"]), tuple(g["upper"]), float(g["voxel_size"]))
    except (KeyError, TypeError, ValueError, ConfigError) as e:
        raise MapFormatError(f"{path}: its grid is invalid: {e}") from None
    lin, n = a["voxel_linear"], len(a["voxel_linear"])
    if (
        lin.ndim != 1
        or a["voxel_counts"].shape != (n,)
        or a["voxel_color_sums"].shape != (n, 3)
        or (n and (lin.min() < 0 or lin.max() >= grid.size))
        or (inst is not None and inst.shape != (n,))
    ):
        raise MapFormatError(f"{path}: its voxel arrays disagree with each other or its grid")
    counts = np.maximum(a["voxel_counts"], 1)[:, None]
    colors = np.clip(np.round(a["voxel_color_sums"] / counts), 0, 255).astype(np.uint8)
    return MapPreview(
        header=h,
        grid=grid,
        linear=lin.astype(np.int64),
        centers=grid.centers(grid.unravel(lin)),
        colors=colors,
        instance=np.full(n, -1, np.int64) if inst is None else inst.astype(np.int64),
        frame_poses=np.asarray(a["frame_poses"], np.float64).reshape(-1, 4, 4),
        segment_positions=np.asarray(a["segment_positions"], np.float64).reshape(-1, 3),
    )


def save_map(m, path: str | Path, *, rebuild: dict | None = None) -> Path:
    """Write map ``m`` to ``path`` (``.npz``; any other suffix is an error, never renamed)
    atomically. ``rebuild`` is what the encoder set needs to be re-created on load (the
    registry fills it for the oracle). A previous map at ``path`` is replaced; any other file
    there is not (the user's data is not ours to delete: :class:`ConfigError`)."""
    path = check_writable(path, what="map file")  # before the arrays are gathered
    _check_suffix(path)
    _refuse_other_file(path, "a map replaces only a previous map")
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
        "source": dict(getattr(m, "source", None) or {}),
    }
    rebuild_info = header["rebuild"]
    header["fingerprints"] = {
        "encoders": encoder_fingerprint(m.encoder_set, m.encoder_names, rebuild_info),
        "weights": weights_fingerprints(m.encoder_set, rebuild_info),
        "calibration": _digest(header["calibration"]),
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
    header["fingerprints"]["header"] = header_fingerprint(header)
    arrays["header"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, **arrays)
    return path


def _map_path(path: str | Path) -> Path:
    """``path`` as a map file that can be read: MapFormatError for no path or no such file."""
    if not isinstance(path, (str, Path)):
        raise MapFormatError(f"a map file is a path, got {type(path).__name__}")
    problem = input_file_problem(path)
    if problem:
        raise MapFormatError(f"map file {str(path)!r} {problem}")
    return Path(path)


def _not_a_map(path) -> MapFormatError:
    return MapFormatError(
        f"{path} is not a map file: a map is a .npz archive of format {MAP_FORMAT!r} "
        "(tabletop build-map --out); this file is something else"
    )


def read_map_file(path: str | Path) -> tuple[dict, dict[str, np.ndarray]]:
    """The header and arrays of a map file, validated."""
    path = _map_path(path)
    try:
        z = np.load(path, allow_pickle=False)
        if not isinstance(z, np.lib.npyio.NpzFile):  # one array (.npy), not an archive
            raise ValueError("one array")
        with z:
            arrays = {k: z[k] for k in z.files}
    except ValueError:  # not a zip of arrays: numpy takes it for a pickle or another format
        raise _not_a_map(path) from None
    except (zipfile.BadZipFile, OSError, EOFError) as e:
        raise MapFormatError(f"{path} is not a readable map file (truncated?): {e}") from None
    if "header" not in arrays:
        raise MapFormatError(f"{path} has no header: not a {MAP_FORMAT} file")
    try:
        h = json.loads(_header_bytes(arrays.pop("header")).decode())
    except (UnicodeDecodeError, json.JSONDecodeError, ValueError) as e:
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
        if why := count_problem(h.get(k)):
            raise MapFormatError(f"{path}: header field {k!r} {why}")
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
    for k in ("calibration", "visual", "source", "fingerprints"):
        if h.get(k) is not None and not isinstance(h[k], dict):
            raise MapFormatError(f"{path}: header field {k!r} must be an object or null")
    check_map_fingerprints(path, h)
    return h, arrays
