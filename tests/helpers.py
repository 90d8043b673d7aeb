"""Shared test helpers."""

import atexit
import functools
import shutil
import tempfile
from pathlib import Path

import numpy as np


def assert_on_table(points: np.ndarray, tol: float = 0.005) -> None:
    """Points labelled "table" lie on the default table: on its top (z = 0) or its slab's
    sides (x in [-0.2, 0.8], y in [-0.6, 0.6], z in [-0.05, 0]), or on a leg below it."""
    assert len(points) > 0
    lo, hi = np.array([-0.2, -0.6, -0.05]), np.array([0.8, 0.6, 0.0])
    slab = points[points[:, 2] > -0.05 - tol]
    d = np.linalg.norm(np.maximum(lo - slab, 0) + np.maximum(slab - hi, 0), axis=1)
    # EGL renders segmentation in a second pass; along object silhouettes a rare pixel
    # labelled "table" carries the object's depth. Allow one in a thousand.
    assert np.mean(d > tol) <= 1e-3, (np.mean(d > tol), d.max())
    assert d.max() <= 0.15, d.max()  # and then it is an object's surface on the table
    legs = points[points[:, 2] <= -0.05 - tol]
    assert (legs[:, :2] >= lo[:2] - tol).all() and (legs[:, :2] <= hi[:2] + tol).all()
    assert np.mean(np.abs(points[:, 2]) <= tol) > 0.9  # most of what is seen is the top


def small_recording(n: int = 3, **changes):
    """A valid recording of ``n`` 64x48 frames 30 ms apart (random colours, depth 0.5 m, the
    camera 0.5 m above (0.3, 0)) with fields replaced by ``changes``."""
    from tabletop.recording import Recording

    rng = np.random.default_rng(0)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, 3] = (0.3, 0.0, 0.5)
    fields = {
        "timestamps": np.arange(n) / 30.0,
        "rgb": rng.integers(0, 256, (n, 48, 64, 3), dtype=np.uint8),
        "depth": np.full((n, 48, 64), 0.5, np.float32),
        "joint_positions": np.zeros((n, 7)),
        "T_world_hand": T,
        "K": np.array([[40.0, 0, 32], [0, 40.0, 24], [0, 0, 1]]),
        "T_hand_cam": np.eye(4),
        "audio": np.zeros(1600, np.float32),
        "audio_rate": 16000,
        "segments": (),
        "meta": {"source": "fuzz"},
    }
    return Recording(**{**fields, **changes})


def ground_truth_dict(objects=(), sound_events=(), areas=()) -> dict:
    """A valid ground truth as a recording stores it, from partial entries; what a test leaves
    out gets a plain value. Objects need ``name``, ``aabb_min`` and ``aabb_max``; sound events
    ``category``, ``onset_s`` and ``table_point``; areas ``name``, ``x`` and ``y``."""
    objs = []
    for i, o in enumerate(objects):
        lo, hi = np.array(o["aabb_min"], float), np.array(o["aabb_max"], float)
        c = (lo + hi) / 2
        T = np.eye(4)
        T[:2, 3] = c[:2]
        kind = o.get("kind", o["name"].split("_")[-1])
        objs.append(
            {
                "name": o["name"],
                "kind": kind,
                "label": o.get("label", o["name"].replace("_", " ")),
                "category": o.get("category", kind),
                "color": o.get("color", "red"),
                "instance_id": 4 + i,
                "position": c[:2].tolist(),
                "yaw_deg": 0.0,
                "T_world_obj": T.tolist(),
                "aabb_min": lo.tolist(),
                "aabb_max": hi.tolist(),
                "center": c.tolist(),
            }
        )
    events = [
        {
            "episode": e.get("episode", f"episode_{i}"),
            "category": e["category"],
            "caption": e.get("caption", f"a {e['category']}"),
            "clip_id": e.get("clip_id", f"{e['category']}-{i}"),
            "onset_s": e["onset_s"],
            "offset_s": e.get("offset_s", e["onset_s"] + 1.0),
            "frames": e.get("frames", [0, 1]),
            "tcp_mean": e.get("tcp_mean", [*e["table_point"][:2], 0.3]),
            "table_point": e["table_point"],
            "region_center": e.get("region_center", e["table_point"]),
        }
        for i, e in enumerate(sound_events)
    ]
    return {
        "scene": {"name": "test"},
        "frame": "world = robot base frame; table top at z = 0; metres",
        "table": {"x": [-0.2, 0.8], "y": [-0.6, 0.6], "top_z": 0.0, "height": 0.75},
        "objects": objs,
        "areas": [
            {
                "name": a["name"],
                "aliases": a.get("aliases", []),
                "x": a["x"],
                "y": a["y"],
                "center": [sum(a["x"]) / 2, sum(a["y"]) / 2, 0.0],
            }
            for a in areas
        ],
        "instances": {"0": "none", "1": "floor", "2": "table", "3": "robot"}
        | {str(o["instance_id"]): o["name"] for o in objs},
        "sound_events": events,
    }


@functools.cache
def visual_scene():
    """(rec, queries, avlmap) of the visual localization tests, built once per test session.

    ``rec``: a ~320-frame scan of the default scene. ``queries``: image goals of the grey tray,
    the red lego brick and the green toy cube (textured or coloured objects, each with
    neighbours in view) as (goal, object label), rendered by a second simulator of the scene,
    the arm holding the wrist camera at poses the scan never took. ``avlmap``: its oracle map
    with a SIFT visual module keeping every 10th frame as a reference frame (about 7 cm of
    camera travel apart); SIFT keeps the map tests fast, the map code is the same for XFeat.
    """
    from dataclasses import replace

    from tabletop.eval.harness import build_map, map_config
    from tabletop.eval.map_goals import ImageGoalConfig, image_goals
    from tabletop.mapping.visual import VisualLocalizationConfig
    from tabletop.sim.ground_truth import GroundTruth
    from tabletop.sim.scan import ScanConfig, run_scan
    from tabletop.sim.scene import load_scene_spec
    from tabletop.sim.world import SimWorld

    cfg = ScanConfig(seed=3, speed=0.45, episodes=0, repeat_sounds=0)
    rec = run_scan(load_scene_spec("default"), cfg)[0]
    labels = ("grey tray", "red lego brick", "green toy cube")
    truth = GroundTruth.of(rec)
    objs = tuple(o for o in truth.objects if o.label in labels)
    with SimWorld(load_scene_spec("default")) as world:
        goals = image_goals(
            replace(truth, objects=objs),
            world,
            ImageGoalConfig(seed=2, table_points=0),
            rec.T_world_cam,
        )
    queries = [(g, o.label) for g, o in zip(goals, objs, strict=True)]
    config = map_config(frame_step=4, visual=VisualLocalizationConfig(matcher="sift", stride=10))
    return rec, queries, build_map(rec, "oracle", config)


#: the fast scan of test_scan.py and test_ground_truth.py: three audio episodes, one sound
#: category inserted twice
FAST_SCAN = dict(seed=1, speed=0.45, episodes=3, episode_s=2.5, repeat_sounds=1)


@functools.lru_cache(maxsize=1)
def fast_scan():
    """(recording, stats) of the ``FAST_SCAN`` scan of the default scene, built once per test
    session for the modules that read it (conftest runs them on one worker)."""
    from tabletop.sim.scan import ScanConfig, run_scan
    from tabletop.sim.scene import load_scene_spec

    return run_scan(load_scene_spec("default"), ScanConfig(**FAST_SCAN))


@functools.lru_cache(maxsize=1)
def fast_scan_reloaded():
    """The ``fast_scan`` recording written to disk and read back, once per test session."""
    from tabletop.recording import load_recording, save_recording

    tmp = Path(tempfile.mkdtemp(prefix="tabletop-fast-scan-"))
    atexit.register(shutil.rmtree, tmp, ignore_errors=True)
    path = tmp / "rec"
    save_recording(fast_scan()[0], path)
    return load_recording(path)


def package_modules(root: Path):
    """(dotted module name, path) of every Python file under the package folder ``root``
    ("tabletop/mapping/__init__.py" -> "tabletop.mapping"), in path order."""
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root.parent).with_suffix("")
        yield ".".join(rel.parts).removesuffix(".__init__"), path


def plant_package(tmp_path: Path, files: dict[str, str]) -> Path:
    """A package ``tabletop`` under ``tmp_path`` holding ``files`` (path inside the package ->
    text), with an empty ``__init__.py`` in it and in every folder above a file unless given."""
    pkg = tmp_path / "tabletop"
    folders = {pkg} | {(pkg / rel).parent for rel in files}
    for folder in list(folders):
        folders |= {p for p in folder.parents if pkg in p.parents}
    for folder in folders:
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "__init__.py").write_text("")
    for rel, text in files.items():
        (pkg / rel).write_text(text)
    return pkg
