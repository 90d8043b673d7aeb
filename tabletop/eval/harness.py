"""The one experiment harness: scene -> scan -> map, cached. The evaluation, the calibration,
the map-goal scoring, the suite generator and the tools all build their recordings and maps
here, so a map means the same wherever it was built.

- :func:`map_config`: a :class:`~tabletop.mapping.MapConfig` whose vocabulary is the simulator
  catalog's object names (what the simulated scenes hold) and the background concepts.
- :func:`build_map`: :meth:`AVLMap.build` with the encoder set's committed calibration and the
  Panda's self-filter, as every experiment builds its maps.
- :func:`generated_scene`: the seeded generated tables of the calibration, eval-map and tools.
- :func:`scene_map`: scene -> scan -> map in one call (through the cache when given one).
- :func:`scan_recording` / :func:`cached_recording` / :func:`cached_map`: the steps through the
  cache (``cache_dir``, default ``out/eval-cache``): one recording per scene + scan settings
  and one map per recording + encoder set + map settings; the keys include a fingerprint of
  the simulator and mapping source, so editing either invalidates old entries.
"""

from __future__ import annotations

import hashlib
import json
import logging
import time
import tomllib
from collections.abc import Callable
from pathlib import Path

from tabletop.errors import AssetError, ConfigError, TabletopError
from tabletop.paths import DATA_DIR

__all__ = [
    "DEFAULT_CACHE_DIR",
    "build_map",
    "cached_map",
    "cached_recording",
    "generated_scene",
    "map_config",
    "recording_key",
    "scan_recording",
    "scene_map",
]

log = logging.getLogger(__name__)

DEFAULT_CACHE_DIR = Path("out/eval-cache")

Progress = Callable[[str, int, int], None]
"""``progress(stage, done, total)``: stage is "scan <name>" or "map <name>"."""


def map_config(**overrides):
    """A :class:`~tabletop.mapping.MapConfig` with the simulator catalog's vocabulary and its
    descriptions (unless ``categories`` is given) and ``overrides`` (MapConfig fields;
    ``voxel_size`` [m] sets the grid's voxel size; ``object``, ``area`` and ``audio`` may be
    dicts of the module config fields that change)."""
    from tabletop.grid import VoxelGrid
    from tabletop.mapping import BACKGROUND, MapConfig
    from tabletop.sim.catalog import OBJECT_KINDS

    kw = dict(overrides)
    nested = {
        k: kw.pop(k)
        for k in ("object", "area", "audio", "registration", "visual")
        if isinstance(kw.get(k), dict)
    }
    if nested:  # module configs given as dicts of the fields that change
        base = MapConfig().to_dict()
        full = MapConfig.from_dict({k: {**base[k], **v} for k, v in nested.items()})
        kw.update({k: getattr(full, k) for k in nested})
    if isinstance(kw.get("grid"), dict):  # a room's box: {lower, upper, voxel_size}
        g = kw["grid"]
        try:
            kw["grid"] = VoxelGrid(tuple(g["lower"]), tuple(g["upper"]), g["voxel_size"])
        except (KeyError, TypeError):
            raise ConfigError(
                f"grid must be {{lower: [x, y, z], upper: [x, y, z], voxel_size: m}}, got {g!r}"
            ) from None
    if "voxel_size" in kw:
        v = kw.pop("voxel_size")
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConfigError(f"voxel_size must be a number [m], got {v!r}")
        g = kw.get("grid", VoxelGrid())
        kw["grid"] = VoxelGrid(g.lower, g.upper, voxel_size=float(v))
    if "categories" not in kw:
        kw["categories"] = (*(k.label for k in OBJECT_KINDS.values()), *BACKGROUND)
        desc = catalog_descriptions()
        kw.setdefault(
            "descriptions", {k.label: desc[n] for n, k in OBJECT_KINDS.items() if n in desc}
        )
    return MapConfig(**kw)


DESCRIPTIONS_PATH = DATA_DIR / "descriptions.toml"


def catalog_descriptions(path: Path = DESCRIPTIONS_PATH) -> dict[str, tuple[str, ...]]:
    """Catalog kind name -> descriptions of it (``tabletop/data/descriptions.toml``)."""
    try:
        d = tomllib.loads(Path(path).read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise AssetError(f"cannot read the object descriptions {path}: {e}") from None
    bad = [
        k for k, v in d.items() if not isinstance(v, list) or not all(isinstance(t, str) for t in v)
    ]
    if bad:
        raise AssetError(f"{path}: {bad} must be lists of strings")
    return {k: tuple(v) for k, v in d.items()}


def committed_calibration(encoders: str, config):
    """The committed calibration of the encoder set ``encoders`` as ``config`` (a
    :class:`~tabletop.mapping.MapConfig`) runs it: the default set with the room-aware image
    network is another encoder, with its own calibration (``calibration/default-room.json``,
    ``tabletop calibrate --rooms``) where one was fitted."""
    from tabletop.mapping import load_calibration
    from tabletop.mapping.calibration import CALIBRATION_DIR

    if encoders == "default" and config.image_network != "table":
        path = CALIBRATION_DIR / f"{encoders}-{config.image_network}.json"
        if path.is_file():
            return load_calibration(encoders, path)
    return load_calibration(encoders)


def build_map_online(
    recording, encoders: str, config=None, *, rate=1.0, drop="none", progress=None
):
    """(map, :class:`~tabletop.mapping.online.ReplayReport`): ``recording`` replayed into a
    map as a camera delivers it (:func:`~tabletop.mapping.online.replay_online`), with the
    encoders, calibration and self-filter of :func:`build_map`."""
    from tabletop.mapping import AVLMap
    from tabletop.mapping.online import replay_online

    config = config or map_config()
    calibration = committed_calibration(encoders, config)
    m = AVLMap.empty(recording, config, encoders, None, calibration, _self_filter(config))
    report = replay_online(m, recording, rate=rate, drop=drop, progress=progress)
    return m, report


def build_map(recording, encoders: str, config=None, progress=None, **kwargs):
    """The map of ``recording`` with encoder set ``encoders``, its committed calibration and the
    Panda's self-filter (``config``: :func:`map_config` by default; ``kwargs``: the rest of
    :meth:`AVLMap.build`'s options)."""
    from tabletop.mapping import AVLMap

    config = config or map_config()
    return AVLMap.build(
        recording,
        config,
        encoders=encoders,
        progress=progress,
        calibration=kwargs.pop("calibration", None) or committed_calibration(encoders, config),
        self_filter=_self_filter(config),
        **kwargs,
    )


def _self_filter(config):
    """The Panda's self-filter at the config's margin (None: no filter)."""
    from tabletop.arm import RobotSelfFilter

    margin = config.self_filter_margin
    return None if margin is None else RobotSelfFilter(margin)


#: Modules that only answer queries on a built map (or render their query images), or move the
#: arm on it: nothing a saved map or a scan holds comes from them, so editing them keeps cached
#: maps (the calibration, also read at query time, is applied afresh to every map taken from
#: the cache). Of the arm, a map reads only the
#: self-filter (``arm/self_filter.py`` on ``arm/model.py``). A map holds a sound vocabulary's
#: texts, but they come from the audio weights (fingerprinted); ``sound_vocabulary.py`` only
#: reads queries against them. The words a query is read with (``reader/lexicon/``) are no
#: package a map's fingerprint hashes.
QUERY_TIME_SOURCES = frozenset(
    (
        "mapping/object_module.py",
        "mapping/sound_vocabulary.py",
        "mapping/kind_reader.py",
        "mapping/shape.py",
        "mapping/heatmaps.py",
        "mapping/targets.py",
        "mapping/render.py",
        "mapping/bench.py",
        "mapping/visual/localize.py",
        "mapping/visual/photometric.py",
        "mapping/visual/panorama.py",
        "sim/views.py",
        *(
            f"arm/{m}.py"
            for m in (
                "bench",
                "collision",
                "diffik",
                "driver",
                "ik",
                "mjcf",
                "obstacles",
                "panda_py_driver",
                "planner",
                "reach",
                "success",
                "trajectory",
                "workspace",
            )
        ),
    )
)


#: Data files read only at query time (a cached map is given today's: :func:`cached_map`; the
#: readers' and the shape prior's weights are loaded by the query code itself, which the map
#: layer does not import at build time).
QUERY_TIME_DATA = frozenset(
    {
        "descriptions.toml",
        "sound_words.toml",
        "kind_reader.json",
        "reader.pt",
        "place_reader.json",
        "shape_prior.json",
    }
)


def _fingerprint(*packages: str) -> str:
    """Hash of the Python source (and the shipped weights, texts and sound bank manifest) a
    cached artefact depends on (not :data:`QUERY_TIME_SOURCES`)."""
    from tabletop.paths import DATA_DIR, PACKAGE_DIR

    h = hashlib.sha1()
    for pkg in packages:
        for f in sorted((PACKAGE_DIR / pkg).rglob("*.py")):
            if f.relative_to(PACKAGE_DIR).as_posix() in QUERY_TIME_SOURCES:
                continue
            h.update(f.name.encode())
            h.update(f.read_bytes())
    data = []
    if "mapping" in packages:  # the weights and the texts a map reads
        data += [
            f for f in sorted((DATA_DIR / "weights").rglob("*")) if f.name not in QUERY_TIME_DATA
        ]
        data += [f for f in sorted(DATA_DIR.glob("*.toml")) if f.name not in QUERY_TIME_DATA]
    if "sim" in packages:  # the clips a scan inserts
        data.append(DATA_DIR / "sounds" / "manifest.json")
    for f in data:
        if f.is_file():
            h.update(f.name.encode())
            h.update(hashlib.sha1(f.read_bytes()).digest())
    return h.hexdigest()[:10]


def _key(obj) -> str:
    return hashlib.sha1(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:12]


def recording_key(spec, scan: dict, noise: dict | None = None) -> str:
    """The cache key of the recording of ``spec`` scanned with ``scan``, with the sensor
    ``noise`` (:class:`~tabletop.sim.noise.NoiseConfig` fields) applied when given."""
    key = {"scene": spec.to_dict(), "scan": scan, "sim": _fingerprint("sim")}
    return _key({**key, "noise": noise} if noise else key)


def cached_recording(name: str, scan: dict, spec, cache: Path | None, progress: Progress | None):
    """(recording, scan seconds, cached?) for a scene and scan settings (``ScanConfig``
    fields), through the cache."""
    from tabletop.sim.scan import ScanConfig, run_scan

    path = cached_recording_path(spec, scan, cache)

    def scan_it():
        t0 = time.perf_counter()
        cb = (lambda d, n: progress(f"scan {name}", d, n)) if progress else None
        rec, _ = run_scan(spec, ScanConfig(**scan), progress=cb)
        return rec, time.perf_counter() - t0

    return through_cache(path, scan_it)


def through_cache(path: Path | None, scan):
    """(recording, scan seconds, cached?): the recording cached at ``path``, or ``scan()``'s
    ``(recording, seconds)`` stored there. One process at a time per entry: a second process
    that needs the same missing recording waits and loads the first's."""
    from tabletop.atomic import exclusive
    from tabletop.recording import load_recording, save_recording

    if path is None:
        return (*scan(), False)
    with exclusive(path):
        if path.is_dir():
            try:
                return load_recording(path), 0.0, True
            except TabletopError as e:
                log.warning("cached recording %s is unusable (%s); scanning again", path, e)
        rec, scan_s = scan()
        save_recording(rec, path, overwrite=True)
    return rec, scan_s, False


def scan_recording(scene: dict, scan: dict, cache_dir: str | Path | None = DEFAULT_CACHE_DIR):
    """(recording, cached?) of a task file's ``[scene]`` and ``[scan]`` sections, scanned or
    taken from the cache (what the suite generator reads the ground truth from)."""
    from tabletop.eval.tasks import _check_scan, scene_ref

    _check_scan(scan)
    spec = scene_ref(scene).load()
    cache = Path(cache_dir) if cache_dir is not None else None
    rec, _, cached = cached_recording(spec.name, dict(scan), spec, cache, None)
    return rec, cached


def cached_map_path(map_settings: dict, encoders: str, cache: Path | None, rec_key: str):
    """Where :func:`cached_map` keeps the map of the recording ``rec_key`` with ``encoders`` and
    ``map_settings`` (None without a cache)."""
    if cache is None:
        return None
    settings = map_config(**map_settings).to_dict()
    settings.pop("descriptions")  # query-time text: given afresh to a map from the cache
    key = _key({"rec": rec_key, "map": settings, "mapping": _fingerprint("mapping", "arm")})
    return Path(cache) / f"map-{encoders}-{key}.npz"


def cached_recording_path(spec, scan: dict, cache: Path | None):
    """Where :func:`cached_recording` keeps the recording of ``spec`` scanned with ``scan``
    (None without a cache)."""
    return Path(cache) / f"rec-{spec.name}-{recording_key(spec, scan)}" if cache else None


def cached_map(
    name: str, map_settings: dict, rec, encoders: str, cache: Path | None, rec_key: str, progress
):
    """(AVLMap, map seconds, cached?) of a recording with the encoder set and ``map_settings``
    (:func:`map_config` overrides), through the cache. One process at a time per entry: a
    second process that needs the same missing map waits and loads the first's."""
    from tabletop.atomic import exclusive

    config = map_config(**map_settings)
    path = cached_map_path(map_settings, encoders, cache, rec_key)
    if path is None:
        return _load_or_build_map(name, config, rec, encoders, None, progress)
    with exclusive(path):
        return _load_or_build_map(name, config, rec, encoders, path, progress)


def _load_or_build_map(name: str, config, rec, encoders: str, path: Path | None, progress):
    from tabletop.mapping import AVLMap

    if path is not None and path.is_file():
        try:
            m = AVLMap.load(path, encoders=encoders)
            m.calibration = committed_calibration(encoders, config)  # the committed one, today's
            m.set_descriptions(config.descriptions)  # today's
            return m, 0.0, True
        except TabletopError as e:
            log.warning("cached map %s is unusable (%s); building again", path, e)
    t0 = time.perf_counter()
    cb = (lambda d, n: progress(f"map {name}", d, n)) if progress else None
    m = build_map(rec, encoders, config, progress=cb)
    map_s = time.perf_counter() - t0
    if path is not None:
        m.save(path)
    return m, map_s, False


def generated_scene(seed: int, name: str = "random", count: int = 9, duplicates: int = 2):
    """The seeded generated scene (``count`` objects, ``duplicates`` kinds twice in different
    colours) named ``name``: the tables of the calibration, eval-map and the tools."""
    from tabletop.sim.scene import SceneSpec

    random = {"seed": int(seed), "count": int(count), "duplicates": int(duplicates)}
    return SceneSpec.from_dict({"random": random}, source=name)


def scene_map(
    spec,
    scan: dict,
    encoders: str,
    *,
    map_settings: dict | None = None,
    cache_dir: str | Path | None = None,
    progress: Progress | None = None,
):
    """(recording, AVLMap) of scene ``spec`` scanned with ``scan`` (``ScanConfig`` fields) and
    mapped with ``encoders`` and ``map_settings`` (:func:`map_config` overrides), through the
    cache in ``cache_dir`` when given."""
    cache = Path(cache_dir) if cache_dir is not None else None
    rec, _, _ = cached_recording(spec.name, dict(scan), spec, cache, progress)
    settings = dict(map_settings or {})
    m, _, _ = cached_map(
        spec.name, settings, rec, encoders, cache, recording_key(spec, dict(scan)), progress
    )
    return rec, m
