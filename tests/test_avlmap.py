"""The AVLMap with the simulator-oracle encoders on a short scan of the default scene."""

import copy
import re
from dataclasses import replace

import numpy as np
import pytest

from tabletop.arm import RobotSelfFilter
from tabletop.errors import ConfigError
from tabletop.eval.harness import build_map, map_config
from tabletop.mapping import AVLMap, MapConfig
from tabletop.mapping.encoders.registry import ENCODER_SETS
from tabletop.mapping.errors import MapFormatError
from tabletop.mapping.heatmaps import fuse
from tabletop.sim.ground_truth import GroundTruth
from tabletop.sim.scan import ScanConfig, run_scan
from tabletop.sim.scene import load_scene_spec


def box_distance(p, obj):
    lo, hi = np.array(obj["aabb_min"]), np.array(obj["aabb_max"])
    return float(np.linalg.norm(np.maximum(lo - p, 0) + np.maximum(p - hi, 0)))


@pytest.fixture(scope="module")
def rec():
    cfg = ScanConfig(seed=3, speed=0.45, episodes=4, episode_s=2.5, repeat_sounds=1)
    return run_scan(load_scene_spec("default"), cfg)[0]


@pytest.fixture(scope="module")
def avlmap(rec):
    return build_map(rec, "oracle")


def test_every_object_label_lands_on_its_box(avlmap, rec):
    for obj in rec.ground_truth["objects"]:
        h = avlmap.object_heatmap(obj["label"])
        assert h.found and h.values.max() == pytest.approx(1.0)
        assert 0.0 <= h.values.min()
        p = avlmap.get_max_pos_3d(h)
        assert box_distance(p, obj) <= 0.02, (obj["label"], p)


def test_category_query_is_ambiguous_and_a_sound_disambiguates(avlmap, rec):
    objs = rec.ground_truth["objects"]
    mugs = [o for o in objs if o["kind"] == "mug"]
    p = avlmap.get_max_pos_3d(avlmap.object_heatmap("mug"))
    assert min(box_distance(p, m) for m in mugs) <= 0.02
    # Fused with a broad heatmap around one mug, the product picks that mug.
    for target in mugs:
        near = avlmap.object_heatmap(target["label"], major=False)
        fused = fuse(avlmap.object_heatmap("mug"), near)
        q = avlmap.get_max_pos_3d(fused)
        assert box_distance(q, target) <= 0.02


def test_sounds_are_found_where_they_were_heard(avlmap, rec):
    events = rec.ground_truth["sound_events"]
    assert len(avlmap.sounds) >= len(events) - 1  # the gate may miss a very short clip
    unique = [e for e in events if [x["category"] for x in events].count(e["category"]) == 1]
    hits = 0
    for e in unique:
        p = avlmap.get_max_pos_3d(avlmap.sound_heatmap(e["caption"]))
        hits += np.linalg.norm(p - e["table_point"]) <= 0.10
    assert hits >= len(unique) - 1
    # a repeated sound is ambiguous: the answer is one of the places it was heard
    rep = [e for e in events if e not in unique]
    p = avlmap.get_max_pos_3d(avlmap.sound_heatmap(rep[0]["caption"]))
    assert min(np.linalg.norm(p - e["table_point"]) for e in rep) <= 0.10


def test_self_filter_keeps_the_robot_out_of_the_map(avlmap):
    # No voxel of the map is labelled "robot arm" by the oracle: the fingers and links the
    # wrist camera saw were filtered with the recorded joint positions.
    s = avlmap.voxels.mean_features() @ avlmap.text.encode_text(["robot arm"])[0]
    assert (s > 0.99).sum() <= 5


def test_unknown_object_is_not_found(avlmap):
    h = avlmap.object_heatmap("a laptop computer")
    assert not h.found and h.reason


def test_map_is_small_and_online_equals_batch(avlmap, rec):
    assert avlmap.voxels.nbytes < 150e6
    part = (0, 80)  # the first 80 frames, one at a time and as one recording
    from dataclasses import replace

    sub = replace(
        rec,
        **{
            k: getattr(rec, k)[: part[1]]
            for k in (
                "timestamps",
                "rgb",
                "depth",
                "joint_positions",
                "T_world_hand",
                "segmentation",
            )
        },
        segments=(),
        audio=None,
    )
    batch = build_map(sub, "oracle", avlmap.config)
    online = AVLMap(
        avlmap.config,
        avlmap.text,
        avlmap.dense,
        avlmap.global_image,
        avlmap.audio_encoder,
        self_filter=RobotSelfFilter(),
    )
    for f in sub:
        online.add_frame(
            f.rgb,
            f.depth,
            sub.K,
            f.T_world_cam,
            {"segmentation": f.segmentation},
            f.joint_positions,
        )
    a, b = np.argsort(online.voxels.linear_indices), np.argsort(batch.voxels.linear_indices)
    np.testing.assert_array_equal(online.voxels.linear_indices[a], batch.voxels.linear_indices[b])
    np.testing.assert_allclose(
        online.voxels.mean_features()[a], batch.voxels.mean_features()[b], atol=1e-5
    )


def test_oracle_needs_ground_truth(rec):
    from dataclasses import replace

    with pytest.raises(ConfigError, match="oracle encoders need a simulator recording"):
        AVLMap.build(replace(rec, ground_truth=None), encoders="oracle")
    with pytest.raises(ConfigError, match=re.escape(f"valid: {list(ENCODER_SETS)}")):
        AVLMap.build(rec, encoders="clip")


def test_save_load_round_trip_and_errors(avlmap, rec, tmp_path):
    from tabletop.mapping.persistence import MapFormatError

    path = avlmap.save(tmp_path / "map.npz")
    assert avlmap.save(path) == path  # a previous map is replaced
    back = AVLMap.load(path)
    np.testing.assert_array_equal(back.voxels.linear_indices, avlmap.voxels.linear_indices)
    np.testing.assert_array_equal(back.voxels.mean_features(), avlmap.voxels.mean_features())
    assert back.sounds.segments == avlmap.sounds.segments
    assert back.encoder_names == avlmap.encoder_names
    for q in ("red mug", "blue mug"):
        np.testing.assert_array_equal(
            back.object_heatmap(q).values, avlmap.object_heatmap(q).values
        )
    cap = rec.ground_truth["sound_events"][0]["caption"]
    np.testing.assert_array_equal(back.sound_heatmap(cap).values, avlmap.sound_heatmap(cap).values)
    # the open sound vocabulary's per-segment class scores come back with the map
    n = len(avlmap.sounds.segments)
    names = ("Dog", "Doorbell", "Speech")
    logits = [np.arange(3, dtype=np.float32) + i for i in range(n)]
    avlmap.sounds.class_logits, avlmap.sounds.class_names = logits, names
    try:
        again = AVLMap.load(avlmap.save(tmp_path / "open.npz"))
    finally:
        avlmap.sounds.class_logits, avlmap.sounds.class_names = [], ()
        (tmp_path / "open.npz").unlink(missing_ok=True)
    assert again.sounds.class_names == names
    np.testing.assert_array_equal(np.stack(again.sounds.class_logits), np.stack(logits))
    # corrupted files name the problem
    data = path.read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(MapFormatError, match=r"cut\.npz is not a readable map file"):
        AVLMap.load(tmp_path / "cut.npz")
    with pytest.raises(MapFormatError, match="not found"):
        AVLMap.load(tmp_path / "none.npz")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(MapFormatError, match="no header"):
        AVLMap.load(tmp_path / "other.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.npz", "map.npz", "other.npz"]
    notes = tmp_path / "mine" / "notes.npz"
    notes.parent.mkdir()
    notes.write_text("mine")  # a map replaces no other file
    with pytest.raises(ConfigError, match="exists and is not a map"):
        avlmap.save(notes)
    assert notes.read_text() == "mine" and list(notes.parent.iterdir()) == [notes]


def test_map_goal_evaluation_scores_the_oracle_map(avlmap, rec):
    from tabletop.eval.map_goals import evaluate_map_goals, map_goals

    truth = GroundTruth.of(rec)
    goals = map_goals(truth)
    assert {g.kind for g in goals} >= {"object", "sound"}
    r = evaluate_map_goals(avlmap, truth)
    assert r["object"]["goals"] == len(truth.objects)
    assert r["object"]["success_rate"] == 1.0
    assert r["sound"]["success_rate"] >= 0.75
    # a sound's truth is the column above where it was inserted, up to where it was heard
    e = truth.sound_events[0]
    s = next(g for g in goals if g.kind == "sound" and g.sound == e.caption)
    lo, hi = s.truth_boxes[0]
    np.testing.assert_allclose(lo, e.table_point)
    np.testing.assert_allclose(hi, [*lo[:2], e.tcp_mean[2]])
    # a goal scored against the wrong truth fails: the scoring can say no
    far = (np.array([9.0, 9, 9]), np.array([9.1, 9.1, 9.1]))
    gt = replace(
        truth,
        objects=tuple(replace(o, aabb_min=far[0], aabb_max=far[1]) for o in truth.objects),
    )
    assert evaluate_map_goals(avlmap, gt)["object"]["success_rate"] == 0.0
    assert r["object"]["not_found"] == 0
    # a query the map refuses is a failed goal even where its argmax would land right
    strict = replace(avlmap.calibration, thresholds={"object": 10.0, "sound": 10.0})
    m = copy.copy(avlmap)
    m.calibration = strict
    r = evaluate_map_goals(m, truth)
    assert r["object"]["successes"] == 0 and r["object"]["not_found"] == r["object"]["goals"]


def test_a_5_mm_map_finds_every_object(rec):
    from tabletop.grid import VoxelGrid

    config = map_config(grid=VoxelGrid(voxel_size=0.005), pixel_step=2, frame_step=8, visual=None)
    m = build_map(rec, "oracle", config)
    assert m.grid.shape == (200, 240, 72)
    coarse = {tuple(c) for c in np.floor(m.voxels.centers / 0.01).astype(int)}
    assert m.voxels.n > 1.5 * len(coarse)  # finer than 1 cm where the scan saw surfaces
    for obj in rec.ground_truth["objects"]:
        p = m.get_max_pos_3d(m.object_heatmap(obj["label"]))
        lo, hi = np.array(obj["aabb_min"]), np.array(obj["aabb_max"])
        assert np.linalg.norm(np.maximum(lo - p, 0) + np.maximum(p - hi, 0)) <= 0.02, obj["label"]


def _empty_like(avlmap, config=None, **kw):
    return AVLMap(
        config or avlmap.config,
        avlmap.text,
        avlmap.dense,
        avlmap.global_image,
        avlmap.audio_encoder,
        avlmap.encoder_names,
        avlmap.encoder_set,
        avlmap.rebuild_info,
        **kw,
    )


def test_a_saved_map_keeps_every_config_field_and_its_calibration(avlmap, tmp_path):
    from tabletop.mapping.area_module import AreaConfig
    from tabletop.mapping.object_module import ObjectConfig

    config = replace(
        avlmap.config,
        object=ObjectConfig(select_margin=0.2),
        area=AreaConfig(top_score=0.6),
        visual=replace(avlmap.config.visual, target_px=0.35),
    )
    cal = replace(avlmap.calibration, thresholds={"object": 0.123})
    m = _empty_like(avlmap, config, calibration=cal)
    back = AVLMap.load(m.save(tmp_path / "m.npz"))
    assert back.config == config and back.config.to_dict() == config.to_dict()
    assert back.images.target_px == 0.35 and back.areas.config.top_score == 0.6
    assert back.objects.config.select_margin == 0.2
    assert back.calibration.thresholds == {"object": 0.123} and back.lacks == ()
    assert MapConfig.from_dict(config.to_dict()) == config
    with pytest.raises(ConfigError, match="unknown map config fields"):
        MapConfig.from_dict({**config.to_dict(), "voxel": 1})


def test_a_map_is_given_its_calibration_not_loading_one(avlmap):
    m = _empty_like(avlmap)
    assert m.calibration.models == {} and m.calibration.encoder_set == avlmap.encoder_set


def test_one_or_two_sound_segments_are_judged_not_found_by_fiat(avlmap):
    from tabletop.mapping.audio_segments import AudioSegment

    m = _empty_like(avlmap, calibration=avlmap.calibration)
    m.sounds.segments.append(AudioSegment(0.0, 1.0))
    m.sounds.embeddings.append(m.audio_text.encode_text(["a dog barking"])[0])
    m.sounds.positions.append(np.array([0.4, 0.0, 0.3]))
    # the oracle reads words through a vocabulary (which refuses the submarine by its words);
    # the reference sounds stand in for an encoder without one
    assert m.sounds.vocabulary is not None
    assert "names no sound" in m.sound_heatmap("a submarine sonar ping").reason
    m.sounds.vocabulary = None
    assert m.sound_heatmap("a dog barking").found
    absent = m.sound_heatmap("a submarine sonar ping")
    assert not absent.found and "confidence" in absent.reason


@pytest.mark.parametrize(
    ("query", "subject"),
    [
        ("the kitchen", "kitchen"),
        ("the ceiling", "ceiling"),
        ("the top shelf", "top shelf"),
        ("the area around the giraffe", "giraffe"),
    ],
)
def test_an_area_that_names_nothing_on_this_table_is_not_found(avlmap, query, subject):
    h = avlmap.area_heatmap(_place(query))
    assert not h.found and h.confidence == 0.0 and not h.values.any()
    assert h.reason.startswith(f"{subject!r} names no region of this table and nothing on it")
    assert "as a thing: " in h.reason and "as a sound: " in h.reason  # each module's refusal


def test_a_place_is_a_thing_only_where_its_own_words_name_one(avlmap):
    # the object module's cosine rules, without the kind reader's rescue (the reader learnt
    # names of things and may name a kind for a place it never saw)
    assert avlmap._unnamed("playground").startswith(
        "'playground' is like nothing in this map's vocabulary (nearest: "
    )
    assert avlmap._unnamed("tray") == "" and avlmap._unnamed("serving tray") == ""
    assert avlmap._unnamed("something red") == ""  # no content words: any object
    h = avlmap.area_heatmap(_place("the playground"))
    assert not h.found and "(as a thing: " in h.reason
    # a region of it is off the map before the map is asked: its ground is no work surface
    h = avlmap.area_heatmap(_place("the far end of the playground"))
    assert not h.found and "'playground' is not the table" in h.reason


def test_a_place_is_a_sound_only_where_its_words_are_nearer_a_sound_than_any_thing(avlmap):
    # a place evokes sounds (a sink: water, a toilet flushing), but its words name a thing
    why = avlmap._rather_a_thing("bathroom sink")
    assert why.startswith("'bathroom sink' names a thing rather than a sound: nearer 'sink' (")
    assert avlmap._rather_a_thing("dog barked") == ""  # nearer a dog barking than a dog
    assert avlmap._rather_a_thing("phone rang") == ""


def _place(text: str):
    """An area's words as the default reader reads them (the map scores the reading)."""
    from tabletop.reader.reading import get_reader

    return get_reader().reference("area", text)


def test_the_map_takes_an_area_as_the_reader_read_it_not_its_words(avlmap):
    with pytest.raises(ConfigError, match=r"an area is read by the reader before the map scores"):
        avlmap.area_heatmap("the left side of the table")
    with pytest.raises(ConfigError, match="must be an AreaRef, got int"):
        avlmap.query("area", 3)


def test_place_words_alone_name_no_area(avlmap):
    h = avlmap.area_heatmap(_place("the area over there"))
    assert not h.found
    assert h.reason == (
        "'the area over there' names no region of this table and nothing on it "
        "(words for a place only)"
    )


def test_words_one_thing_s_query_cannot_honour_are_not_found_with_the_reason(avlmap):
    # scored anyway, they found the red mug, any mug, or the mug or the duck
    for q, word in (
        ("not the red mug", "'not'"),
        ("the mug that isn't red", '"isn\'t"'),
        ("the second mug", "'second'"),
        ("the mug near the duck", "'near'"),
        ("the mug to the left of the tray", "'to the left of'"),
    ):
        h = avlmap.object_heatmap(q)
        assert not h.found and not h.values.any(), q
        assert word in h.reason and "tabletop.reader.understand()" in h.reason, h.reason
    # words that describe the thing are no negation
    assert avlmap.object_heatmap("the mug with no handle").reason.find("negates") < 0


def test_a_superlative_keeps_the_one_thing_it_ranks_first(avlmap, rec):
    mugs = [o for o in rec.ground_truth["objects"] if o["kind"] == "mug"]
    assert len(mugs) == 2

    def reach(o):
        return float(np.hypot(*(np.add(o["aabb_min"], o["aabb_max"])[:2] / 2)))

    both = avlmap.object_heatmap("the mug")
    for q, want in (
        ("the farthest mug", max(mugs, key=reach)),
        ("the nearest mug", min(mugs, key=reach)),
    ):
        h = avlmap.object_heatmap(q)
        assert h.found and h.query == q
        assert box_distance(avlmap.get_max_pos_3d(h), want) <= 0.02, q
        # only the one is hot: the other mug is as cold as far heat leaves it
        other = next(o for o in mugs if o is not want)
        c = np.add(other["aabb_min"], other["aabb_max"]) / 2
        idx, _ = h.grid.world_to_index(c[None])
        assert h.values[tuple(idx[0])] < 0.5 < both.values[tuple(idx[0])], q


@pytest.mark.parametrize("query", ["🦒🦒", "...", "123", "?! 42"])
def test_a_query_of_no_words_is_not_found_in_any_modality(avlmap, query):
    for kind in ("obj", "sound", "area"):
        h = avlmap.query(kind, _place(query) if kind == "area" else query)
        assert not h.found and not h.values.any(), (kind, query)
        assert h.reason == f"{query!r} holds no words (no letter): it names nothing"


def test_an_area_named_after_a_sound_is_where_it_was_heard(avlmap, rec):
    events = rec.ground_truth["sound_events"]
    unique = [e for e in events if [x["category"] for x in events].count(e["category"]) == 1]
    hits = 0
    for e in unique:
        q = f"the spot near {e['caption']}"
        h = avlmap.area_heatmap(_place(q))
        assert h.modality == "area" and h.query == q
        hits += h.found and np.linalg.norm(avlmap.get_max_pos_3d(h) - e["table_point"]) <= 0.10
    assert hits >= len(unique) - 1  # as the sound queries themselves


def test_a_heatmap_without_heat_has_no_target(avlmap):
    from tabletop.errors import GoalNotFound
    from tabletop.mapping import Heatmap

    zero = Heatmap.not_found(avlmap.grid, "nothing", "object", 10.0, "test")
    with pytest.raises(GoalNotFound, match="nothing: not found"):
        avlmap.get_max_pos_3d(zero)
    with pytest.raises(ConfigError, match="takes a Heatmap"):
        avlmap.get_max_pos_3d(np.zeros(avlmap.grid.shape, np.float32))


def test_named_table_regions_come_from_the_map_geometry(avlmap, rec):
    from tabletop.sim.ground_truth import GroundTruth

    gt = GroundTruth.of(rec)
    for name in ("left side of the table", "front of the table", "center of the table"):
        a = gt.area(name)
        h = avlmap.area_heatmap(_place("the " + name))
        assert h.found and h.evidence is None  # geometry, not an image embedding
        p = avlmap.get_max_pos_3d(h)
        assert a.x[0] <= p[0] <= a.x[1] and a.y[0] <= p[1] <= a.y[1]
    tray = avlmap.area_heatmap(_place("the tray area"))
    assert tray.found and tray.evidence is not None  # named by what is there: the object module


def test_query_dispatches_by_kind_and_names_the_valid_ones(avlmap):
    np.testing.assert_array_equal(
        avlmap.query("obj", "red mug").values, avlmap.object_heatmap("red mug").values
    )
    assert avlmap.query("area", _place("the tray area"), major=False).decay == avlmap.decay(False)
    with pytest.raises(ConfigError, match=r"unknown query kind 'smell'; valid: \['obj'"):
        avlmap.query("smell", "roses")


def _rewrite(path, out, drop=(), remove=(), **header):
    """A copy of map file ``path`` with arrays dropped, header fields ``remove``d and header
    fields replaced."""
    import json

    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files if k not in drop}
    h = json.loads(arrays["header"].tobytes().decode())
    for k in remove:
        del h[k]
    h.update(header)
    if "version" in header:  # an older file: written before the whole header's fingerprint
        h.get("fingerprints", {}).pop("header", None)
    arrays["header"] = np.frombuffer(json.dumps(h).encode(), dtype=np.uint8)
    np.savez(out, **arrays)
    return out


def test_object_instances_are_saved_and_an_older_file_segments_again(avlmap, rec, tmp_path):
    from tabletop.mapping.persistence import MAP_VERSION

    truth = GroundTruth.of(rec)
    inst = avlmap.objects.instances.items
    assert len(inst) == len(truth.objects)  # one instance per object of the scene
    path = avlmap.save(tmp_path / "map.npz")
    # the saved labels are what a load uses: change them and the loaded instances follow
    labels = avlmap.objects.instances.labels().copy()
    merged = labels.copy()
    merged[merged == 1] = 0
    merged[merged > 1] -= 1
    edited = _rewrite(path, tmp_path / "edited.npz", drop=("voxel_instance",))
    with np.load(edited) as z:
        arrays = {k: z[k] for k in z.files}
    np.savez(edited, voxel_instance=merged, **arrays)
    assert len(AVLMap.load(edited).objects.instances) == len(inst) - 1
    back = AVLMap.load(path)
    assert back.lacks == () and MAP_VERSION == 5
    np.testing.assert_array_equal(back.objects.instances.labels(), labels)
    np.testing.assert_allclose(back.voxels.mean_heights(), avlmap.voxels.mean_heights())
    v4 = AVLMap.load(_rewrite(path, tmp_path / "v4.npz", drop=("voxel_height_sums",), version=4))
    assert v4.lacks == ("point heights (object heights judged by voxel centres)",)
    assert v4.voxels.mean_heights() is None
    np.testing.assert_array_equal(v4.objects.instances.labels(), labels)
    old = _rewrite(path, tmp_path / "v3.npz", drop=("voxel_instance",), version=3)
    m3 = AVLMap.load(old)
    assert any("instances" in w for w in m3.lacks)
    np.testing.assert_array_equal(m3.objects.instances.labels(), labels)
    with pytest.raises(Exception, match="voxel_instance"):
        AVLMap.load(_rewrite(path, tmp_path / "bad.npz", drop=("voxel_instance",)))


def test_an_area_named_after_an_object_is_around_its_instance(avlmap, rec):
    tray = next(o for o in rec.ground_truth["objects"] if o["kind"] == "tray")
    for q in ("the area around the tray", "the spot by the tray"):
        h = avlmap.area_heatmap(_place(q))
        assert h.found and h.modality == "area" and h.query == q
        assert box_distance(avlmap.get_max_pos_3d(h), tray) <= 0.02


def _with_array(path, out, name, fn):
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays[name] = fn(arrays[name].copy())
    np.savez(out, **arrays)
    return out


def test_a_map_with_bad_arrays_or_another_encoder_set_is_refused_by_name(avlmap, tmp_path):
    from tabletop.mapping.persistence import MapFormatError

    path = avlmap.save(tmp_path / "map.npz")
    assert AVLMap.load(path, encoders="oracle").encoder_set == "oracle"
    with pytest.raises(MapFormatError, match="built with the encoder set 'oracle', not 'default'"):
        AVLMap.load(path, encoders="default")

    def nan(a):
        a[0, 0] = np.nan
        return a

    cases = [
        ("voxel_feature_sums", nan, "'voxel_feature_sums' holds NaN or infinite values"),
        ("frame_poses", lambda a: a + np.inf, "'frame_poses' holds NaN or infinite"),
        ("voxel_linear", lambda a: np.full_like(a, a[0]), "repeats voxel indices"),
        ("voxel_counts", lambda a: a * 0, "'voxel_counts' must be > 0"),
        ("voxel_linear", lambda a: a.astype(np.float64), "'voxel_linear' has dtype float64"),
    ]
    for i, (name, fn, needle) in enumerate(cases):
        bad = _with_array(path, tmp_path / f"bad{i}.npz", name, fn)
        with pytest.raises(MapFormatError) as e:
            AVLMap.load(bad)
        assert needle in str(e.value)


def test_a_map_whose_calibration_was_removed_or_edited_is_refused(avlmap, tmp_path):
    import json

    from tabletop.mapping.persistence import MapFormatError

    # it loaded with the uncalibrated prior and no word
    m = _empty_like(avlmap, calibration=replace(avlmap.calibration, thresholds={"object": 0.5}))
    path = m.save(tmp_path / "map.npz")
    assert AVLMap.load(path).calibration.thresholds == {"object": 0.5}
    removed = _rewrite(path, tmp_path / "removed.npz", remove=("calibration",))
    nulled = _rewrite(path, tmp_path / "null.npz", calibration=None)
    for bad in (removed, nulled):
        with pytest.raises(MapFormatError, match="header field 'calibration' is missing") as e:
            AVLMap.load(bad)
        assert "uncalibrated prior" in str(e.value) and "build the map again" in str(e.value)
    with np.load(path) as z:
        cal = json.loads(z["header"].tobytes().decode())["calibration"]
    edited = _rewrite(path, tmp_path / "edited.npz", calibration={**cal, "thresholds": {}})
    with pytest.raises(MapFormatError, match="'calibration' does not match the fingerprint"):
        AVLMap.load(edited)
    # a map of version 2 was saved without one: it loads, and says so
    old = AVLMap.load(_rewrite(path, tmp_path / "v2.npz", remove=("calibration",), version=2))
    assert "a saved calibration (the uncalibrated prior is used)" in old.lacks
    assert old.calibration.models == {} and old.calibration.thresholds == {}


def test_a_recording_that_puts_nothing_in_the_grid_builds_no_map(rec):
    from dataclasses import fields

    from tabletop.errors import RecordingError
    from tabletop.recording import Recording

    kw = {f.name: getattr(rec, f.name) for f in fields(Recording)}
    n = 20
    far = np.array(rec.T_world_hand[:n])
    far[:, :3, 3] += (50.0, 0.0, 0.0)  # 50 m away: legal poses, but no point lands in the grid
    for k in ("timestamps", "rgb", "depth", "joint_positions", "segmentation"):
        kw[k] = kw[k][:n]
    kw.update(T_world_hand=far, T_world_hand_true=None, segments=(), audio=None)
    with pytest.raises(RecordingError, match="no depth point of the recording's 20 frames fell"):
        build_map(Recording(**kw), "oracle")


def test_a_sound_query_that_names_a_thing_and_no_sound_is_not_found(avlmap):
    assert len(avlmap.sounds) and "mug" in avlmap.objects.vocabulary
    for words in ("the red mug", "a teddy bear"):
        h = avlmap.sound_heatmap(words)
        assert not h.found and "names a thing rather than a sound" in h.reason, h.reason
    # a thing that sounds is asked for as a sound still
    assert "names a thing" not in avlmap.sound_heatmap("the duck").reason
    # the margin decides: without one, "the duck" (a toy here) would be a thing too
    assert avlmap._rather_a_thing("the duck", 0.0)


def test_a_header_count_given_as_text_is_named_as_text(avlmap, tmp_path):
    from tabletop.errors import count_problem

    assert count_problem(3) == ""
    assert "the text '60' (a number in quotes)" in count_problem("60")
    assert "got -1" in count_problem(-1) and "(bool)" in count_problem(True)
    path = tmp_path / "m.npz"
    avlmap.save(path)
    bad = _rewrite(path, tmp_path / "bad.npz", n_segments="60")
    with pytest.raises(MapFormatError, match="'n_segments' must be a count .*the text '60'"):
        AVLMap.load(bad)
