"""The visual localization module on real PyBullet renders: a short scan of the default scene
is the reference; queries are rendered by a second simulator of the scene, the arm holding the
wrist camera at poses the scan never took."""

import json

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.eval.map_goals import ImageGoalConfig, image_goals
from tabletop.mapping.avlmap import AVLMap, MapConfig
from tabletop.mapping.visual_localization import (
    PhotometricCheck,
    VisualDatabaseError,
    VisualLocalizationConfig,
    _unturn,
    build_visual_database,
    localize_image,
    look_at_point,
)
from tabletop.sim.scan import ScanConfig, run_scan
from tabletop.sim.scene import load_scene_spec
from tabletop.sim.world import SimWorld

#: Reference frames: every 10th of a ~320-frame scan (about 7 cm of camera travel apart).
STRIDE = 10
#: Queries: views of these objects (textured or coloured ones, each with neighbours in view).
QUERY_OBJECTS = ("grey tray", "red lego brick", "green toy cube")


@pytest.fixture(scope="module")
def rec():
    cfg = ScanConfig(seed=3, speed=0.45, episodes=0, repeat_sounds=0)
    return run_scan(load_scene_spec("default"), cfg)[0]


@pytest.fixture(scope="module")
def queries(rec):
    """Image goals of the objects in QUERY_OBJECTS: (goal, object label)."""
    objs = [o for o in rec.ground_truth["objects"] if o["label"] in QUERY_OBJECTS]
    with SimWorld(load_scene_spec("default")) as world:
        goals = image_goals(
            {**rec.ground_truth, "objects": objs},
            world,
            ImageGoalConfig(seed=2, table_points=0),
            rec.T_world_cam,
        )
    return [(g, o["label"]) for g, o in zip(goals, objs, strict=True)]


@pytest.fixture(scope="module")
def databases(rec):
    return {
        m: build_visual_database(rec, VisualLocalizationConfig(matcher=m, stride=STRIDE))
        for m in ("sift", "xfeat")
    }


def rotation_deg(R_a, R_b) -> float:
    c = (np.trace(R_a.T @ R_b) - 1) / 2
    return float(np.degrees(np.arccos(np.clip(c, -1, 1))))


def test_queries_are_new_poses(rec, queries):
    assert len(queries) == len(QUERY_OBJECTS)
    cams = rec.T_world_cam[:, :3, 3]
    for g, _ in queries:
        assert np.linalg.norm(cams - g.T_world_cam[:3, 3], axis=1).min() >= 0.05
        assert g.image.shape == (240, 320, 3) and g.image.dtype == np.uint8


@pytest.mark.parametrize("matcher", ["sift", "xfeat"])
def test_a_new_view_localises_within_cm_and_degrees(rec, databases, queries, matcher):
    db = databases[matcher]
    assert len(db) == -(-len(rec) // STRIDE) and db.frame_indices[1] == STRIDE
    for g, label in queries:
        loc = localize_image(db, g.image)
        assert loc.ok, (matcher, label, loc.reason)
        assert np.linalg.norm(loc.position - g.T_world_cam[:3, 3]) <= 0.03, (matcher, label)
        assert rotation_deg(loc.T_world_cam[:3, :3], g.T_world_cam[:3, :3]) <= 3.0
        truth = look_at_point(g.T_world_cam)
        assert np.linalg.norm(loc.look_at_point - truth) <= 0.02
        assert loc.inliers >= db.config.min_inliers and 0 < loc.inlier_ratio <= 1
        assert len(loc.references) == db.config.top_n


def test_blank_and_unrelated_images_fail_with_a_reason(databases):
    db = databases["sift"]
    blank = np.full((240, 320, 3), 128, np.uint8)
    loc = localize_image(db, blank)
    assert not loc.ok and loc.T_world_cam is None and "blank image" in loc.reason
    # An unrelated picture: seeded random rectangles, rich in corners, none of the scene.
    rng = np.random.default_rng(0)
    img = np.zeros((240, 320, 3), np.uint8)
    for _ in range(60):
        x, y = rng.integers(0, 300), rng.integers(0, 220)
        img[y : y + rng.integers(5, 40), x : x + rng.integers(5, 40)] = rng.integers(0, 255, 3)
    for matcher in ("sift", "xfeat"):
        loc = localize_image(databases[matcher], img)
        assert not loc.ok and loc.position is None, matcher
        assert loc.reason.startswith("no pose found"), loc.reason


def test_bad_input_names_the_problem(databases):
    db = databases["sift"]
    with pytest.raises(ConfigError, match="uint8"):
        localize_image(db, np.zeros((240, 320, 3), np.float32))
    with pytest.raises(ConfigError, match=r"shape \(H, W, 3\)"):
        localize_image(db, np.zeros((240, 320), np.uint8))
    with pytest.raises(ConfigError, match="fx, fy > 0"):
        localize_image(db, np.zeros((240, 320, 3), np.uint8), K=np.zeros((3, 3)))
    with pytest.raises(ConfigError, match=r"unknown matcher 'orb'; valid: \['xfeat', 'sift'\]"):
        VisualLocalizationConfig(matcher="orb")


def test_turned_keypoints_map_back_to_the_same_pixels():
    rng = np.random.default_rng(1)
    img = rng.integers(0, 255, (24, 32)).astype(np.int64)
    for k in range(4):
        turned = np.rot90(img, k)
        tv, tu = np.nonzero(turned >= 0)
        back = _unturn(np.stack([tu, tv], 1).astype(np.float32), k, 32, 24).astype(int)
        np.testing.assert_array_equal(img[back[:, 1], back[:, 0]], turned[tv, tu])


# ---------------------------------------------------------------------------- in the map
@pytest.fixture(scope="module")
def avlmap(rec):
    # SIFT keeps the map tests fast (XFeat is exercised above); the map code is the same.
    config = MapConfig(frame_step=4, visual=VisualLocalizationConfig(matcher="sift", stride=STRIDE))
    return AVLMap.build(rec, config, encoders="oracle")


def test_map_image_heatmap_peaks_on_what_the_image_shows(avlmap, queries, rec):
    objs = {o["label"]: o for o in rec.ground_truth["objects"]}
    assert avlmap.stats.reference_frames == len(avlmap.visual) == -(-len(rec) // STRIDE)
    for g, label in queries:
        h = avlmap.image_heatmap(g.image)
        assert h.found and h.modality == "image" and h.decay == avlmap.config.major_decay
        assert h.values.shape == avlmap.grid.shape and h.values.dtype == np.float32
        assert 0.0 <= h.values.min() and h.values.max() <= 1.0
        p = avlmap.get_max_pos_3d(h)
        lo, hi = np.array(objs[label]["aabb_min"]), np.array(objs[label]["aabb_max"])
        assert np.linalg.norm(np.maximum(lo - p, 0) + np.maximum(p - hi, 0)) <= 0.10, label
        # The paper's H_v(p) = max(1 - eps * d_xy(p, p_v), 0), checked at every voxel.
        xs, ys, _ = avlmap.grid.axes()
        d = np.hypot(xs[:, None] - h.target[0], ys[None, :] - h.target[1])
        ref = np.maximum(1 - h.decay * d, 0)
        np.testing.assert_allclose(h.values[:, :, 0], ref, atol=1e-5)


def test_broad_image_heatmap_and_failure_is_not_found_not_an_exception(avlmap, queries):
    g = queries[0][0]
    h, broad = avlmap.image_heatmap(g.image), avlmap.image_heatmap(g.image, major=False)
    assert broad.decay == avlmap.config.aux_decay and broad.values.sum() > h.values.sum()
    np.testing.assert_array_equal(broad.target, h.target)
    h = avlmap.image_heatmap(np.full((240, 320, 3), 90, np.uint8))
    assert not h.found and "blank image" in h.reason and not h.values.any()
    with pytest.raises(ConfigError, match="pass its intrinsics K"):
        avlmap.image_heatmap(np.full((480, 640, 3), 90, np.uint8))


def shifted(T: np.ndarray, dx: float, dy: float) -> np.ndarray:
    out = T.copy()
    out[:2, 3] += (dx, dy)
    return out


def test_the_map_seen_from_the_true_pose_reproduces_the_image(avlmap, queries):
    check, K = avlmap.photometric_check(), avlmap.visual.K
    assert len(check) == len(avlmap.voxels.indices)
    cfg = avlmap.config.visual
    for g, label in queries:
        cov, agree, kappa = check.score(g.T_world_cam, K, g.image, cfg)
        assert cov > 0.5 and agree >= cfg.min_agreement and kappa >= cfg.min_kappa, label
        # 8 cm to the side, the same picture no longer agrees with the map beyond chance
        _, agree_off, kappa_off = check.score(shifted(g.T_world_cam, 0.08, 0.0), K, g.image, cfg)
        assert kappa_off < cfg.min_kappa < kappa and agree_off < agree, label
    # a camera looking away from the map sees none of it
    up = np.eye(4)
    up[2, 3] = 1.0  # 1 m above the table, optical axis (+z) pointing up
    assert check.score(up, K, queries[0][0].image, cfg) == (0.0, 0.0, 0.0)
    with pytest.raises(ConfigError, match=r"\(n, 3\) indices"):
        PhotometricCheck(avlmap.grid, np.zeros((4, 2), int), np.zeros((4, 3), np.uint8))


def test_the_check_refuses_a_pose_the_matches_support_but_the_map_does_not(avlmap, queries):
    from tabletop.mapping.visual_localization import _checked

    g = queries[0][0]
    cfg, K, check = avlmap.config.visual, avlmap.visual.K, avlmap.photometric_check()
    cand = {"T": shifted(g.T_world_cam, -0.1, 0.06), "inliers": 40, "reason": ""}
    out = _checked(cand, check, g.image, K, cfg)
    assert out["T"] is None and "40 inliers" in out["reason"] and out["kappa"] < cfg.min_kappa
    ok = _checked({**cand, "T": g.T_world_cam}, check, g.image, K, cfg)
    assert ok["T"] is not None and ok["agreement"] >= cfg.min_agreement
    # localisation through the map reports the check's figures; the confidence calibrates kappa
    loc, h = avlmap.localize(g.image), avlmap.image_heatmap(g.image)
    assert loc.ok and loc.agreement >= cfg.min_agreement and loc.kappa >= cfg.min_kappa
    assert h.evidence == loc.kappa and h.confidence == avlmap.calibration.confidence(
        "image", loc.kappa
    )
    # without the check only the inlier rule decides, and no check figures are reported
    plain = localize_image(avlmap.visual, g.image)
    assert plain.ok and plain.agreement is None and plain.inliers >= cfg.min_inliers


def test_check_settings_are_validated():
    with pytest.raises(ConfigError, match=r"verify_min_inliers must be in \[4, min_inliers=15\]"):
        VisualLocalizationConfig(verify_min_inliers=20)
    with pytest.raises(ConfigError, match="min_kappa must be in"):
        VisualLocalizationConfig(min_kappa=1.5)
    with pytest.raises(ConfigError, match="colour_tolerance"):
        VisualLocalizationConfig(colour_tolerance=0)


def test_online_and_batch_reference_frames_agree(avlmap, rec):
    batch = build_visual_database(rec, avlmap.config.visual)
    (h_map, a_map), (h_batch, a_batch) = avlmap.visual.state(), batch.state()
    assert h_map == h_batch
    for k in a_map:
        np.testing.assert_array_equal(a_map[k], a_batch[k], err_msg=k)


def test_save_load_round_trip_and_corrupted_visual_arrays(avlmap, queries, tmp_path):
    path = avlmap.save(tmp_path / "map.npz")
    back = AVLMap.load(path)
    assert back.config.visual == avlmap.config.visual
    (h0, a0), (h1, a1) = avlmap.visual.state(), back.visual.state()
    assert h0 == h1 and all(np.array_equal(a0[k], a1[k]) for k in a0)
    g = queries[0][0]
    np.testing.assert_array_equal(
        back.image_heatmap(g.image).values, avlmap.image_heatmap(g.image).values
    )

    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}

    def corrupt(name, **change):
        bad = {**arrays, **change}
        np.savez(tmp_path / name, **bad)
        return tmp_path / name

    offsets = arrays["visual_keypoint_offsets"].copy()
    offsets[-1] += 7
    with pytest.raises(VisualDatabaseError, match=r"bad1\.npz: visual database keypoint_offsets"):
        AVLMap.load(corrupt("bad1.npz", visual_keypoint_offsets=offsets))
    short = arrays["visual_descriptors"][:-1]
    with pytest.raises(VisualDatabaseError, match="'descriptors' has shape"):
        AVLMap.load(corrupt("bad2.npz", visual_descriptors=short))
    # A version 1 file (before the visual module) loads; its image goals are not found.
    header = json.loads(arrays["header"].tobytes())
    v1 = {k: v for k, v in arrays.items() if not k.startswith("visual_")}
    v1_header = {k: v for k, v in header.items() if k != "visual"} | {"version": 1}
    v1["header"] = np.frombuffer(json.dumps(v1_header).encode(), np.uint8)
    np.savez(tmp_path / "v1.npz", **v1)
    old = AVLMap.load(tmp_path / "v1.npz")
    h = old.image_heatmap(g.image)
    assert old.visual is None and not h.found and "no visual localization" in h.reason
    no_points = {k: v for k, v in arrays.items() if k != "visual_points_world"}
    np.savez(tmp_path / "bad3.npz", **no_points)
    with pytest.raises(VisualDatabaseError, match="array 'points_world' is missing"):
        AVLMap.load(tmp_path / "bad3.npz")


def test_calibration_samples_label_every_modality(avlmap, queries, rec):
    from tabletop.mapping.calibration import calibration_samples

    rng = np.random.default_rng(5)
    foreign = np.zeros((240, 320, 3), np.uint8)  # a picture of no scene: random rectangles
    for _ in range(60):
        x, y = rng.integers(0, 300), rng.integers(0, 220)
        foreign[y : y + rng.integers(5, 40), x : x + rng.integers(5, 40)] = rng.integers(0, 255, 3)
    goals = [g for g, _ in queries]
    s = calibration_samples(avlmap, rec.ground_truth, goals, [foreign])
    by = {m: [x for x in s if x["modality"] == m] for m in ("object", "sound", "area", "image")}
    assert len(by["image"]) == len(goals) + 1 and len(by["area"]) == len(rec.ground_truth["areas"])
    # the oracle finds every present object label; absent kinds are always wrong
    labels = {o["label"] for o in rec.ground_truth["objects"]}
    assert all(x["correct"] for x in by["object"] if x["query"] in labels)
    assert any(not x["correct"] for x in by["object"])
    # pictures of the scene are found and right; the foreign one is refused: margin -1, wrong
    assert all(x["correct"] and x["found"] and x["margin"] > 0 for x in by["image"][:-1])
    assert by["image"][-1] == {
        "modality": "image",
        "query": "foreign 0",
        "margin": -1.0,
        "correct": False,
        "found": False,
    }
    # every named table area is queried once
    assert {x["query"] for x in by["area"]} == {a["name"] for a in rec.ground_truth["areas"]}


def test_query_command_with_an_image(avlmap, queries, rec, tmp_path, capsys):
    import cv2

    from tabletop.cli import main

    path = avlmap.save(tmp_path / "map.npz")
    g, label = queries[1]
    cv2.imwrite(str(tmp_path / "goal.png"), g.image[:, :, ::-1])
    assert (
        main(
            ["query", str(path), "--img", str(tmp_path / "goal.png"), "--out", str(tmp_path / "q")]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "found" in out and "kappa" in out and "oracle" in out
    line = next(x for x in out.splitlines() if "the image shows" in x)
    x, y = (float(line.split(f"{c}=")[1].split()[0]) for c in "xy")
    o = next(o for o in rec.ground_truth["objects"] if o["label"] == label)
    assert np.hypot(x - o["center"][0], y - o["center"][1]) <= 0.10, line
    assert (tmp_path / "q_top.png").is_file() and (tmp_path / "q_side.png").is_file()
    # a blank picture is not found, with the reason, and exit status 1
    cv2.imwrite(str(tmp_path / "blank.png"), np.full((240, 320, 3), 90, np.uint8))
    assert main(["query", str(path), "--img", str(tmp_path / "blank.png")]) == 1
    out = capsys.readouterr().out
    assert "NOT FOUND (blank image" in out and "target:   none" in out
