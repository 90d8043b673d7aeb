"""Mobile-base task files and room maps: the [robot] and [room] sections, distances on the
floor, the oracle's labels of a room, and the map settings of a room."""

import copy

import numpy as np
import pytest

from tabletop.eval.harness import map_config
from tabletop.eval.room import ROOM_CONCEPTS, room_map_settings
from tabletop.eval.tasks import RoomRef, SceneRef, TaskFileError, parse_tasks
from tabletop.eval.truth import Region
from tabletop.mapping.encoders.oracle import oracle_labels
from tabletop.sim.room import load_room_spec

MOBILE = {
    "format": "tabletop-tasks",
    "version": 1,
    "name": "room",
    "robot": {"kind": "mobile"},
    "room": {"name": "default"},
    "scan": {"seed": 3},
    "goals": [
        {
            "id": "o",
            "type": "object",
            "text": "the red mug",
            "query": {"obj": "red mug"},
            "truth": {"object": "red_mug"},
        }
    ],
}


def _doc(**changes):
    d = copy.deepcopy(MOBILE)
    for k, v in changes.items():
        if v is None:
            d.pop(k, None)
        else:
            d[k] = v
    return d


def test_a_mobile_task_file_names_its_room_and_radius():
    tf = parse_tasks(_doc())
    assert tf.robot.kind == "mobile" and tf.robot.success_radius == 1.0
    assert tf.robot.embodiment == "ground"
    assert isinstance(tf.scene, RoomRef) and tf.scene.load().name == "default"
    tf = parse_tasks(_doc(robot={"kind": "mobile", "success_radius": 0.5, "embodiment": "flyer"}))
    assert tf.robot.success_radius == 0.5 and tf.robot.embodiment == "flyer"
    tf = parse_tasks(_doc(room={"random": {"seed": 4}}))
    assert tf.scene.load().to_dict() == tf.scene.load().to_dict()  # a seeded draw
    # an arm's file without [robot] is what it always was
    arm = _doc(robot=None, room=None, scene={"name": "default"}, scan={"seed": 1})
    tf = parse_tasks(arm)
    assert tf.robot.kind == "arm" and tf.robot.success_radius == 0.10
    assert isinstance(tf.scene, SceneRef)


@pytest.mark.parametrize(
    "changes, words",
    [
        ({"room": None, "scene": {"name": "default"}}, "needs a [room]"),
        ({"robot": None}, "needs a [scene]"),
        ({"robot": {"kind": "drone"}}, "kind must be one of ['arm', 'mobile']"),
        ({"robot": {"kind": "mobile", "success_radius": 0}}, "success_radius must be"),
        ({"robot": {"kind": "mobile", "success_radius": "far"}}, "success_radius must be"),
        ({"robot": {"kind": "mobile", "embodiment": "boat"}}, "embodiment must be one of"),
        ({"robot": {"kind": "mobile", "speed": 1}}, "[robot]"),
        ({"room": {"name": "default", "random": {"seed": 1}}}, "exactly one of name, path"),
        ({"room": {"random": {"seed": -1}}}, "must be an integer >= 0"),
        ({"scan": {"seed": 1, "tremor_m": 0.01}}, "[scan]"),
    ],
)
def test_bad_robot_and_room_sections_are_named(changes, words):
    with pytest.raises(TaskFileError) as e:
        parse_tasks(_doc(**changes))
    assert words in str(e.value)


def test_an_arm_file_may_not_choose_an_embodiment():
    arm = _doc(robot={"embodiment": "flyer"}, room=None, scene={"name": "default"}, scan={})
    with pytest.raises(TaskFileError, match="the arm robot has no obstacle embodiments to choose"):
        parse_tasks(arm)


def test_distance_on_the_floor_ignores_height():
    r = Region(np.array([[[1.0, 1.0, 0.6], [1.2, 1.1, 0.7]]]), "a mug on a table")
    assert r.distance_xy([1.1, 1.05, 0.0]) == 0.0  # under it
    assert r.distance_xy([2.2, 1.05]) == pytest.approx(1.0)
    assert r.distance([1.1, 1.05, 0.0]) == pytest.approx(0.6)
    assert Region(np.zeros((0, 2, 3)), "nowhere").distance_xy([0, 0]) == np.inf


def test_the_oracle_names_a_rooms_furniture_by_category():
    from tabletop.sim.room_world import RoomWorld

    with RoomWorld(load_room_spec("default"), renderer="tiny") as world:
        gt = world.ground_truth().to_dict()
    labels = oracle_labels(gt)
    names = {int(k): v for k, v in gt["instances"].items()}
    by_name = {n: i for i, n in names.items()}
    assert labels[by_name["floor"]] == "floor" and labels[by_name["robot"]] == "robot"
    for f in gt["furniture"]:
        assert labels[f["instance_id"]] == f["category"]
    cats = {f["category"] for f in gt["furniture"]}
    assert {"table", "wall", "shelf"} <= cats
    for o in gt["objects"]:
        assert labels[o["instance_id"]] == o["label"]
    assert "robot arm" not in labels.values()  # the arm's background ids are not a room's


def test_room_map_settings_cover_the_room_with_its_concepts():
    spec = load_room_spec("default")
    cfg = map_config(**room_map_settings(spec))
    lo, hi = np.array(cfg.grid.lower), np.array(cfg.grid.upper)
    assert np.all(lo[:2] < 0) and hi[0] > spec.size[0] and hi[1] > spec.size[1]
    assert hi[2] > spec.wall_height and lo[2] < 0
    assert cfg.grid.voxel_size == 0.03
    assert set(ROOM_CONCEPTS) <= set(cfg.categories) and "other" in cfg.categories
    assert cfg.object.segmentation.supports == "surfaces"
    assert not cfg.registration.enabled and cfg.self_filter_margin is None
    # an image goal is where the picture was taken; a mast camera need not look down
    assert cfg.visual.target == "camera" and not cfg.visual.localization.require_look_down
    assert cfg.aux_decay < map_config().aux_decay and cfg.major_decay < map_config().major_decay
    from tabletop.errors import ConfigError
    from tabletop.mapping.visual.module import VisualModuleConfig

    with pytest.raises(ConfigError, match=r"target must be one of \['view', 'camera'\]"):
        VisualModuleConfig(target="above")
    # the task file's voxel size keeps the room's box
    cfg5 = map_config(**{**room_map_settings(spec), "voxel_size": 0.05})
    assert cfg5.grid.voxel_size == 0.05 and cfg5.grid.upper == cfg.grid.upper
