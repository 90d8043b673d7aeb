"""The simulator's ground truth as a typed value: the round trip of a real scan's dict,
validation errors that name the field, lookups that name the valid options."""

import copy
import json
from dataclasses import replace

import numpy as np
import pytest
from helpers import FAST_SCAN, fast_scan, fast_scan_reloaded, ground_truth_dict

from tabletop.errors import RecordingError, TabletopError
from tabletop.sim import (
    GroundTruth,
    GroundTruthError,
    NotInGroundTruth,
    ObjectTruth,
    SoundEventTruth,
)
from tabletop.sim.noise import NoiseConfig, apply_noise
from tabletop.sim.scene import load_scene_spec

# test_scan.py's fast scan: three audio episodes, one sound category inserted twice.
FAST = FAST_SCAN


@pytest.fixture(scope="module")
def rec():
    return fast_scan()[0]  # shared with test_scan.py


@pytest.fixture(scope="module")
def small() -> dict:
    return ground_truth_dict(
        objects=[
            {"name": "red_mug", "aabb_min": [0.3, 0.2, 0.0], "aabb_max": [0.4, 0.3, 0.1]},
            {"name": "blue_mug", "aabb_min": [0.5, 0.2, 0.0], "aabb_max": [0.6, 0.3, 0.1]},
            {"name": "tray", "aabb_min": [0.5, -0.1, 0.0], "aabb_max": [0.7, 0.1, 0.02]},
        ],
        sound_events=[
            {"category": "dog", "onset_s": 5.0, "table_point": [0.6, 0.3, 0.0]},
            {"category": "rain", "onset_s": 3.0, "table_point": [0.4, 0.0, 0.0]},
            {"category": "dog", "onset_s": 1.0, "table_point": [0.3, -0.3, 0.0]},
        ],
        areas=[
            {"name": "left side of the table", "aliases": ["left"], "x": [0.2, 0.7], "y": [0, 1]},
            {"name": "tray area", "x": [0.5, 0.7], "y": [-0.1, 0.1]},
        ],
    )


# ---------------------------------------------------------------------------- round trip
def test_a_real_scan_round_trips_exactly(rec):
    d = json.loads(json.dumps(rec.ground_truth))
    gt = GroundTruth.from_dict(d)
    assert gt.to_dict() == d
    assert json.dumps(gt.to_dict()) == json.dumps(d)  # same keys in the same order
    assert GroundTruth.of(rec) == gt
    # through disk (save_recording, load_recording): what the recording stores is the JSON form
    assert GroundTruth.of(fast_scan_reloaded()) == gt


def test_a_real_scan_reads_as_typed_values(rec):
    gt = GroundTruth.of(rec)
    spec = load_scene_spec("default")
    assert gt.object_names == tuple(o.name for o in spec.objects)
    assert gt.area_names == tuple(a.name for a in spec.areas)
    for o in gt.objects:
        for a, shape in [
            (o.position, (2,)),
            (o.T_world_obj, (4, 4)),
            (o.aabb_min, (3,)),
            (o.aabb_max, (3,)),
            (o.center, (3,)),
        ]:
            assert a.shape == shape and a.dtype == np.float64 and not a.flags.writeable
        np.testing.assert_allclose(o.center, (o.aabb_min + o.aabb_max) / 2)
        assert gt.instances[o.instance_id] == o.name
    assert len(gt.sound_events) == FAST["episodes"]
    assert len(gt.categories_heard) == FAST["episodes"] - FAST["repeat_sounds"]
    for e in gt.sound_events:
        assert isinstance(e, SoundEventTruth) and len(e.frames) == 2
        assert e.onset_s < e.offset_s and e.table_point[2] == 0.0
        with pytest.raises(ValueError):
            e.table_point[0] = 1.0  # read-only


def test_noise_keeps_a_valid_ground_truth_and_leaves_the_input_alone(rec):
    before = copy.deepcopy(rec.ground_truth)
    noisy = apply_noise(rec, NoiseConfig(seed=1, drop_frames=0.3))
    assert rec.ground_truth == before
    gt = GroundTruth.of(noisy)
    for e in gt.sound_events:
        assert not e.frames or 0 <= e.frames[0] <= e.frames[1] < len(noisy)
    assert gt.objects == GroundTruth.of(rec).objects


# ---------------------------------------------------------------------------- validation
def _error(d) -> str:
    with pytest.raises(GroundTruthError) as e:
        GroundTruth.from_dict(d)
    return str(e.value)


def test_validation_names_the_missing_or_wrong_field(small):
    assert issubclass(GroundTruthError, RecordingError)

    def broken(mutate) -> str:
        d = copy.deepcopy(small)
        mutate(d)
        return _error(d)

    assert "ground_truth: missing field 'table'" in broken(lambda d: d.pop("table"))
    assert "ground_truth: unknown field 'extra'" in broken(lambda d: d.update(extra=1))
    msg = broken(lambda d: d["objects"][1].pop("kind"))
    assert msg.startswith("ground_truth.objects[1]: missing field 'kind'; expected fields: [")
    msg = broken(lambda d: d["objects"][2].update(aabb_max=[0.1, 0.2]))
    assert msg == "ground_truth.objects[2].aabb_max: expected shape (3,), got (2,)"
    msg = broken(lambda d: d["objects"][0].update(instance_id=True))
    assert msg == "ground_truth.objects[0].instance_id: expected an integer, got True"
    msg = broken(lambda d: d["objects"][0].update(T_world_obj="eye"))
    assert msg.startswith("ground_truth.objects[0].T_world_obj: expected")
    msg = broken(lambda d: d["sound_events"][2].update(frames=[3]))
    assert msg.startswith("ground_truth.sound_events[2].frames: expected [first, last]")
    msg = broken(lambda d: d["sound_events"][0].update(onset_s="5"))
    assert msg == "ground_truth.sound_events[0].onset_s: expected a number, got '5'"
    assert "ground_truth.areas[0].x: expected shape (2,)" in broken(
        lambda d: d["areas"][0].update(x=[0.2])
    )
    assert "ground_truth.table.height: expected a number" in broken(
        lambda d: d["table"].update(height=None)
    )
    assert "ground_truth.instances: keys must be instance ids" in broken(
        lambda d: d["instances"].update(robot="robot")
    )
    assert "ground_truth: expected a mapping, got list" in _error([])
    assert "names must be unique; repeated: ['tray']" in broken(
        lambda d: d["objects"].append(d["objects"][2])
    )


def test_a_recording_without_ground_truth_is_a_clear_error(rec):
    real = replace(rec, ground_truth=None, meta={"source": "franka"})
    with pytest.raises(GroundTruthError) as e:
        GroundTruth.of(real)
    assert "the recording has no ground truth (source: 'franka'); only simulated" in str(e.value)


def test_direct_construction_normalises_and_freezes_arrays():
    o = ObjectTruth(
        "cube", "cube", "green cube", "cube", "green", 4, (0.4, 0.1), 15, np.eye(4),
        [0.38, 0.08, 0], [0.42, 0.12, 0.04], [0.4, 0.1, 0.02],
    )  # fmt: skip
    assert o.aabb_max.dtype == np.float64 and not o.aabb_max.flags.writeable
    assert o.yaw_deg == 15.0 and isinstance(o.yaw_deg, float)
    with pytest.raises(GroundTruthError, match=r"object.center: expected shape \(3,\)"):
        replace(o, center=[0.4, 0.1])


# ---------------------------------------------------------------------------- lookups
def test_lookups_return_typed_values(small):
    gt = GroundTruth.from_dict(small)
    assert gt.object("tray").aabb_max.tolist() == [0.7, 0.1, 0.02]
    assert gt.area("left") is gt.area("left side of the table") is gt.areas[0]
    assert [e.onset_s for e in gt.sound_events_of("dog")] == [1.0, 5.0]  # by onset
    assert gt.object_names == ("red_mug", "blue_mug", "tray")
    assert gt.categories_heard == ("dog", "rain")
    assert gt.duplicated_kinds == ("mug",)
    assert [o.name for o in gt.objects_of_kind("mug")] == ["red_mug", "blue_mug"]
    assert [e.onset_s for e in gt.sound_events_by_onset] == [1.0, 3.0, 5.0]


@pytest.mark.parametrize(
    ("lookup", "message"),
    [
        (
            lambda gt: gt.object("green_mug"),
            "no object 'green_mug' in the scene; objects: ['red_mug', 'blue_mug', 'tray']",
        ),
        (
            lambda gt: gt.area("kitchen"),
            "no area 'kitchen'; areas: ['left side of the table', 'tray area']",
        ),
        (
            lambda gt: gt.sound_events_of("cat"),
            "sound 'cat' was not inserted in this scan; inserted: ['dog', 'rain']",
        ),
    ],
)
def test_lookups_name_the_valid_options(small, lookup, message):
    with pytest.raises(NotInGroundTruth) as e:
        lookup(GroundTruth.from_dict(small))
    assert str(e.value) == message
    assert isinstance(e.value, TabletopError) and isinstance(e.value, LookupError)


def test_values_compare_by_content_and_are_not_hashable(small):
    a, b = GroundTruth.from_dict(small), GroundTruth.from_dict(copy.deepcopy(small))
    assert a == b and a.objects[0] == b.objects[0] and a.objects[0] != a.objects[1]
    assert replace(a, sound_events=()) != a
    with pytest.raises(TypeError):
        hash(a.objects[0])


def test_a_room_ground_truth_has_furniture_and_no_single_table(small):
    d = copy.deepcopy(small)
    assert "furniture" not in GroundTruth.from_dict(d).to_dict()  # the arm's stays as it was
    d["table"] = None
    d["objects"][0]["table"] = "dining_table"
    d["sound_events"][0]["place"] = "dining_table"
    item = {
        "name": "dining_table",
        "category": "table",
        "model": "table",
        "instance_id": 9,
        "T_world_item": np.eye(4).tolist(),
        "aabb_min": [1.0, 2.0, 0.0],
        "aabb_max": [2.5, 3.0, 0.625],
        "top_z": 0.625,
    }
    wall = {**item, "name": "wall_north", "category": "wall", "model": "wall", "top_z": None}
    d["furniture"] = [item, wall]
    gt = GroundTruth.from_dict(d)
    assert GroundTruth.from_dict(json.loads(json.dumps(gt.to_dict()))) == gt
    assert gt.table is None and gt.item("wall_north").top_z is None
    assert [f.name for f in gt.furniture_of("table")] == ["dining_table"]
    assert [o.name for o in gt.objects_on("dining_table")] == ["red_mug"]
    assert gt.sound_events[0].place == "dining_table"
    assert gt.item("dining_table").center.tolist() == [1.75, 2.5, 0.3125]
    with pytest.raises(NotInGroundTruth, match="furniture: \\['dining_table', 'wall_north'\\]"):
        gt.item("bed")
    d["furniture"][1].pop("category")
    assert "ground_truth.furniture[1]: missing field 'category'" in _error(d)
