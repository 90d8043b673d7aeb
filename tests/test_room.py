"""Room specs: the shipped room, dict/TOML round trips, typed errors, the seeded generator."""

import tomllib

import numpy as np
import pytest

from tabletop.errors import SceneError
from tabletop.sim.room import (
    CORRIDOR,
    FurnitureSpec,
    RoomSpec,
    _separated,
    generate_room,
    list_default_rooms,
    load_room_spec,
)


@pytest.fixture(scope="module")
def room():
    return load_room_spec("default")


def test_the_default_room(room):
    assert "default" in list_default_rooms()
    assert room.size == (6.0, 5.0) and room.wall_height == 2.4
    assert len(room.tables) >= 3 and all(3 <= len(t.objects) <= 5 for t in room.tables)
    cats = {f.category for f in room.furniture}
    assert {"table", "shelf", "cabinet", "sofa"} <= cats
    # objects stand on their table's top, in the room frame
    for table, obj in room.objects:
        lo, hi = table.object_aabb(obj)
        tlo, thi = table.aabb()
        assert lo[2] == pytest.approx(table.top_z, abs=1e-6)
        assert np.all(lo[:2] >= tlo[:2]) and np.all(hi[:2] <= thi[:2])


def test_round_trips_through_dict_and_toml(room, tmp_path):
    assert RoomSpec.from_dict(room.to_dict()) == room
    path = tmp_path / "r.toml"
    path.write_text(room.to_toml())
    back = load_room_spec(path)
    assert back == room and back.to_dict() == room.to_dict()
    g = generate_room(5)
    assert RoomSpec.from_dict(tomllib.loads(g.to_toml())) == g


def _with(room, fn):
    d = room.to_dict()
    fn(d)
    return d


@pytest.mark.parametrize(
    "change, needle",
    [
        (lambda d: d.update(kitchen={}), r"unknown sections \['kitchen'\]"),
        (lambda d: d["room"].update(size=[6.0]), r"room.size must be two finite numbers"),
        (lambda d: d["furniture"][0].update(model="bed"), r"unknown model 'bed'; valid: \["),
        (lambda d: d["furniture"][0].pop("category"), r"furniture\[0\]: missing required field"),
        (lambda d: d["furniture"][0].update(legs=4), r"furniture\[0\]: unknown field 'legs'"),
        (lambda d: d["furniture"][0].update(position=[0.2, 3.7]), "pokes through a wall"),
        (lambda d: d["furniture"][1].update(position=[2.0, 3.5]), "'dining_table' and 'work"),
        (
            lambda d: d["furniture"][0]["objects"][0].update(position=[0.9, 0.0]),
            "object 'red_mug' .* overhangs furniture 'dining_table'",
        ),
        (
            lambda d: d["furniture"][0]["objects"][0].update(kind="giraffe"),
            "unknown object kind 'giraffe'|giraffe",
        ),
        (lambda d: d["start"].update(position=[2.0, 3.7]), "start.position .* on furniture"),
        (lambda d: d["furniture"][4].pop("size"), "a 'box' needs size"),
        (
            lambda d: d["furniture"][3].update(objects=d["furniture"][2]["objects"]),
            "no flat top to hold objects",
        ),
    ],
)
def test_bad_input_names_the_field(room, change, needle):
    with pytest.raises(SceneError, match=needle):
        RoomSpec.from_dict(_with(room, change))


def test_generator_is_deterministic_and_leaves_corridors():
    a, b, c = generate_room(11), generate_room(11), generate_room(12)
    assert a == b and a != c
    for seed in range(6):
        r = generate_room(seed)
        assert len(r.tables) == 3
        assert all(3 <= len(t.objects) <= 5 for t in r.tables)
        f = r.furniture
        for i in range(len(f)):
            for j in range(i + 1, len(f)):
                assert _separated(f[i].footprint(), f[j].footprint(), CORRIDOR - 1e-6)
        for t in r.tables:  # a corridor to the walls too
            lo, hi = t.aabb()
            assert lo[0] >= CORRIDOR - 1e-6 and lo[1] >= CORRIDOR - 1e-6
            assert hi[0] <= r.size[0] - CORRIDOR + 1e-6 and hi[1] <= r.size[1] - CORRIDOR + 1e-6
        # the start is free, with room for the base around it
        occ = r.occupancy(0.05, inflate=r.robot_radius)
        i, j = (np.array(r.start.position) / 0.05).astype(int)
        assert not occ[i, j]
    with pytest.raises(SceneError, match="no layout of 8 tables"):
        generate_room(0, size=(3.0, 3.0), tables=8)


def test_occupancy_marks_furniture_and_walls(room):
    occ = room.occupancy(0.1)
    assert occ[20, 37] and not occ[6, 6]  # the dining table; the start
    inflated = room.occupancy(0.1, inflate=0.3)
    assert inflated.sum() > occ.sum() and inflated[0].all()
    with pytest.raises(SceneError, match="fixed size"):
        FurnitureSpec("t", "table", "table", (2, 2), size=(1.0, 1.0, 1.0))
