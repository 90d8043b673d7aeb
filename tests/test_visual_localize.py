"""The query pipeline (tabletop/mapping/visual/localize.py) on real PyBullet renders: a short
scan of the default scene is the reference; queries are rendered by a second simulator of the
scene, the arm holding the wrist camera at poses the scan never took (``helpers.visual_scene``).
Also the image goals of the map that use it: heatmaps, calibration samples, ``tabletop query``."""

import numpy as np
import pytest
from helpers import visual_scene

from tabletop.errors import ConfigError
from tabletop.mapping.visual import (
    VisualLocalizationConfig,
    build_visual_database,
    localize_image,
    look_at_point,
)
from tabletop.mapping.visual.localize import _checked, _unturn
from tabletop.sim.ground_truth import GroundTruth

#: Reference frames: every 10th of a ~320-frame scan (about 7 cm of camera travel apart), as
#: in the map of ``helpers.visual_scene``.
STRIDE = 10
#: Queries: views of these objects (textured or coloured ones, each with neighbours in view),
#: those of ``helpers.visual_scene``.
QUERY_OBJECTS = ("grey tray", "red lego brick", "green toy cube")


@pytest.fixture(scope="module")
def rec():
    return visual_scene()[0]


@pytest.fixture(scope="module")
def queries():
    """Image goals of the objects in QUERY_OBJECTS: (goal, object label)."""
    return visual_scene()[1]


@pytest.fixture(scope="module")
def avlmap():
    """The scan's oracle map, SIFT reference frames every STRIDE-th frame."""
    return visual_scene()[2]


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


def test_a_saved_map_keeps_what_its_image_goals_name(avlmap, queries, tmp_path):
    from dataclasses import replace

    from tabletop.mapping import AVLMap

    g = queries[0][0]
    view = avlmap.image_heatmap(g.image).target
    own = (avlmap.config, avlmap.images.target)
    avlmap.config = replace(own[0], visual=replace(own[0].visual, target="camera"))
    avlmap.images.target = "camera"  # a room's map: where the picture was taken
    try:
        back = AVLMap.load(avlmap.save(tmp_path / "camera.npz"))
    finally:
        avlmap.config, avlmap.images.target = own
    assert back.config.visual.target == back.images.target == "camera"
    where = back.image_heatmap(g.image).target
    # the floor beneath the camera, not the point the picture shows
    assert abs(where[2] - back.grid.lower[2]) < 0.05 < np.linalg.norm(where[:2] - view[:2])
    assert np.linalg.norm(where[:2] - g.T_world_cam[:2, 3]) < 0.05
    plain = AVLMap.load(avlmap.save(tmp_path / "view.npz"))
    assert plain.images.target == plain.config.visual.target == "view"


def test_broad_image_heatmap_and_failure_is_not_found_not_an_exception(avlmap, queries):
    g = queries[0][0]
    h, broad = avlmap.image_heatmap(g.image), avlmap.image_heatmap(g.image, major=False)
    assert broad.decay == avlmap.config.aux_decay and broad.values.sum() > h.values.sum()
    np.testing.assert_array_equal(broad.target, h.target)
    h = avlmap.image_heatmap(np.full((240, 320, 3), 90, np.uint8))
    assert not h.found and "blank image" in h.reason and not h.values.any()
    with pytest.raises(ConfigError, match="give the camera.s intrinsics K with it"):
        avlmap.image_heatmap(np.full((480, 640, 3), 90, np.uint8))


def shifted(T: np.ndarray, dx: float, dy: float) -> np.ndarray:
    out = T.copy()
    out[:2, 3] += (dx, dy)
    return out


def test_the_check_refuses_a_pose_the_matches_support_but_the_map_does_not(avlmap, queries):
    g = queries[0][0]
    cfg, K, check = avlmap.config.visual.localization, avlmap.visual.K, avlmap.photometric_check()
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


def test_calibration_samples_label_every_modality(avlmap, queries, rec):
    from tabletop.eval.calibration import calibration_samples
    from tabletop.reader.place_words import parse_region

    rng = np.random.default_rng(5)
    foreign = np.zeros((240, 320, 3), np.uint8)  # a picture of no scene: random rectangles
    for _ in range(60):
        x, y = rng.integers(0, 300), rng.integers(0, 220)
        foreign[y : y + rng.integers(5, 40), x : x + rng.integers(5, 40)] = rng.integers(0, 255, 3)
    goals = [g for g, _ in queries]
    s = calibration_samples(avlmap, GroundTruth.of(rec), goals, [foreign])
    by = {m: [x for x in s if x["modality"] == m] for m in ("object", "sound", "area", "image")}
    # areas named by where they are on the table are geometry (nothing to calibrate)
    named_by_content = [a for a in rec.ground_truth["areas"] if parse_region(a["name"]) is None]
    assert len(by["image"]) == len(goals) + 1 and len(by["area"]) == len(named_by_content) > 0
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
    # every area named by what is there is queried once
    assert {x["query"] for x in by["area"]} == {a["name"] for a in named_by_content}
    # an operating point that refuses every object changes no label: the calibration sees where
    # each refused query's target would be, and the map keeps its own calibration afterwards
    from dataclasses import replace

    own = avlmap.calibration
    avlmap.calibration = replace(own, thresholds={**own.thresholds, "object": 2.0})
    try:
        assert not avlmap.object_heatmap(sorted(labels)[0]).found
        refused = calibration_samples(avlmap, GroundTruth.of(rec))
        assert avlmap.calibration.thresholds["object"] == 2.0
    finally:
        avlmap.calibration = own
    objects = [(x["query"], x["correct"]) for x in by["object"]]
    assert [(x["query"], x["correct"]) for x in refused if x["modality"] == "object"] == objects


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


def test_upright_pictures_are_matched_only_as_they_are(databases, queries, monkeypatch):
    import dataclasses

    from tabletop.mapping.visual import localize as loc_mod

    db = databases["xfeat"]  # not rotation-invariant: it tries quarter turns unless upright
    tried: list[int] = []
    real = loc_mod._TurnedQuery

    class Counted(real):  # the real query, its turns noted
        def __init__(self, database, backend, rgb, k):
            tried.append(k)
            super().__init__(database, backend, rgb, k)

    monkeypatch.setattr(loc_mod, "_TurnedQuery", Counted)
    g, _ = queries[0]
    turned = np.ascontiguousarray(np.rot90(g.image, 1))
    four = db.config
    try:
        db.config = dataclasses.replace(four, upright=True)
        localize_image(db, g.image)
        localize_image(db, turned)
        assert set(tried) == {0}  # the picture as it is, never turned (a wrist camera rolls:
        # the arm's maps keep the turns, which the pose below needs)
        db.config = four
        tried.clear()
        loc = localize_image(db, turned)  # a rolled wrist picture: the turns find it
        assert loc.ok and np.linalg.norm(loc.position - g.T_world_cam[:3, 3]) <= 0.08
        assert len(set(tried)) > 1
    finally:
        db.config = four
