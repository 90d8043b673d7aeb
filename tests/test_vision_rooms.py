"""Room views for the image encoder: cameras, labels, the vocabulary and the recipe's checks."""

from __future__ import annotations

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.sim.room import generate_room
from tabletop.train.vision import (
    ROOM_STUFF,
    VisionTrainConfig,
    training_texts,
    vision_classes,
)
from tabletop.train.vision_rooms import level_look_at, render_room_dataset, room_camera


def test_room_classes_follow_the_tables_so_table_labels_keep_their_ids():
    table, room = vision_classes(), vision_classes(rooms=True)
    assert room[: len(table)] == table
    assert [c["kind"] for c in room[len(table) :]] == list(ROOM_STUFF)


def test_with_rooms_other_no_longer_names_the_floor():
    plain, rooms = training_texts(ensemble=True), training_texts(ensemble=True, rooms=True)
    i_other = plain["kinds"].index("other")
    assert any("floor" in p for p in plain["kind"][i_other])
    assert not any("floor" in p or "ground" in p for p in rooms["kind"][i_other])
    i_floor = rooms["kinds"].index("floor")
    assert "the floor" in rooms["kind"][i_floor]
    assert len(rooms["cls"]) == len(vision_classes(rooms=True))


def test_level_look_at_points_at_the_target_with_the_image_down_along_minus_z():
    eye, target = np.array([1.0, 2.0, 1.1]), np.array([3.0, 1.0, 0.7])
    T = level_look_at(eye, target)
    fwd = (target - eye) / np.linalg.norm(target - eye)
    assert np.allclose(T[:3, 2], fwd)
    assert abs(T[2, 0]) < 1e-9  # the image's x axis is level
    assert T[2, 1] < 0  # the image's y (down) points down in the world
    assert np.allclose(T[:3, :3].T @ T[:3, :3], np.eye(3), atol=1e-9)
    assert np.isclose(np.linalg.det(T[:3, :3]), 1.0)
    rolled = level_look_at(eye, target, roll=0.3)
    assert np.allclose(rolled[:3, 2], fwd) and abs(rolled[2, 0]) > 0.1


def test_room_cameras_stand_on_free_floor_at_a_standing_height():
    spec = generate_room(20_000)
    cell = 0.05
    free = ~spec.occupancy(cell=cell, inflate=0.3)
    rng = np.random.default_rng(0)
    for _ in range(40):
        T = room_camera(rng, spec, free, cell)
        x, y, z = T[:3, 3]
        assert free[int(x // cell), int(y // cell)]
        assert 0.45 <= z <= 1.7
        assert abs(T[2, 0]) < 0.3  # held about level: only a small roll


def test_room_renders_are_labelled_with_room_classes_and_repeat_for_a_seed():
    rgbs, labels = render_room_dataset([20_001], views=3, seed=0)
    again_rgb, again = render_room_dataset([20_001], views=3, seed=0)
    assert rgbs.shape == (3, 240, 320, 3) and labels.shape == (3, 240, 320)
    assert np.array_equal(labels, again) and np.array_equal(rgbs, again_rgb)
    names = [c["name"] for c in vision_classes(rooms=True)]
    seen = {names[i] for i in np.unique(labels)}
    assert {"floor", "wall"} <= seen
    assert any(n not in ("table", "robot", "other", *ROOM_STUFF) for n in seen)  # an object
    assert labels.min() >= 0 and labels.max() < len(names)


def test_the_room_recipe_checks_its_fields_before_any_work(tmp_path):
    with pytest.raises(ConfigError, match="room_share"):
        VisionTrainConfig(room_layouts=4, room_share=1.0)
    with pytest.raises(ConfigError, match="room_layouts"):
        VisionTrainConfig(room_layouts=-1)
    with pytest.raises(ConfigError, match="not a file"):
        VisionTrainConfig(init=str(tmp_path / "missing.pt"))
