"""Room scans: a short drive of the wheeled base records a valid recording in the arm's format,
without a collision, with a sound inserted where the base stood."""

import math

import numpy as np
import pytest
from test_recording import assert_same

from tabletop.base import load_base_description
from tabletop.base.description import WHEEL_JOINTS
from tabletop.errors import ConfigError
from tabletop.eval.room_bench import ROOM_BENCH_SCAN
from tabletop.recording import load_recording, save_recording
from tabletop.sim.ground_truth import GroundTruth
from tabletop.sim.room import load_room_spec
from tabletop.sim.room_scan import (
    RoomScanConfig,
    _plan,
    base_pose_of,
    run_room_scan,
    scan_room,
)

#: A few seconds: to the work table (about 1 m from the start), one look, one audio episode
#: (the room image bench's scan, on whichever renderer the test asks for).
SHORT = {k: v for k, v in ROOM_BENCH_SCAN.items() if k != "renderer"}


@pytest.fixture(scope="module")
def spec():
    return load_room_spec("default")


@pytest.fixture(scope="module")
def scan(spec):
    return scan_room(spec, RoomScanConfig(**SHORT))


def test_a_short_scan_records_without_collision(scan):
    rec, stats = scan
    assert stats.collisions == 0 and rec.meta["collisions"] == 0
    assert rec.meta["robot"] == "mobile_base" and rec.meta["room"] == "default"
    assert 30 <= stats.frames == len(rec) <= 150
    assert stats.simulated_s == pytest.approx(len(rec) / 10.0)
    assert np.allclose(np.diff(rec.timestamps), 0.1)
    assert rec.ee_frame == "base_footprint" and rec.joint_names == WHEEL_JOINTS
    assert rec.joint_positions.shape == (len(rec), 2)
    d = load_base_description()
    assert np.array_equal(rec.T_hand_cam, d.T_base_cam)
    assert np.array_equal(rec.T_hand_mic, d.T_base_mic)
    # the wheels turned forward while the base drove about a metre
    assert np.all(rec.joint_positions[-1] - rec.joint_positions[0] > 5.0)
    assert 0.5 < stats.distance_m < 2.0
    assert rec.meta["distance_m"] == round(stats.distance_m, 4)
    # odometry in T_world_hand, the simulator's pose beside it: they agree (no drift asked)
    err = np.linalg.norm(rec.T_world_hand[:, :2, 3] - rec.T_world_hand_true[:, :2, 3], axis=1)
    assert err.max() < 0.01
    kinds = [s.kind for s in rec.segments]
    assert kinds.count("episode") == 1 and "transit" in kinds and "mapping" in kinds
    assert rec.depth.max() <= 5.0 and (rec.depth > 0).mean() > 0.5
    # the work table's objects are in view at the end
    gt = GroundTruth.of(rec)
    seen = set(np.unique(rec.segmentation[-1]).tolist())
    assert {o.instance_id for o in gt.objects_on("work_table")} & seen


def test_the_sound_event_is_where_the_base_stood(scan):
    rec, _ = scan
    gt = GroundTruth.of(rec)
    (event,) = gt.sound_events
    ep = rec.segment("episode_0")
    assert event.place == "work_table" and event.episode == "episode_0"
    assert ep.start <= event.frames[0] <= event.frames[1] < ep.stop
    assert rec.timestamps[ep.start] <= event.onset_s < event.offset_s
    pose = base_pose_of(rec, event.frames[0])
    mic = rec.T_world_mic[event.frames[0], :3, 3]
    assert np.allclose(event.tcp_mean, mic, atol=0.01)
    assert math.dist(event.table_point[:2], pose.xy) < 0.1 and event.table_point[2] == 0.0
    assert event.region_center.tolist() == [2.6, 1.1, 0.625]
    assert len(rec.audio) == pytest.approx(len(rec) / 10.0 * rec.audio_rate, abs=rec.audio_rate)
    assert gt.table is None and len(gt.furniture_of("wall")) == 4


def test_the_scan_saves_and_loads_identically(scan, tmp_path):
    rec, _ = scan
    save_recording(rec, tmp_path / "room")
    back = load_recording(tmp_path / "room")
    assert_same(rec, back)
    assert GroundTruth.of(back) == GroundTruth.of(rec)


def test_the_default_plan_visits_every_table_from_free_viewpoints(spec):
    config = RoomScanConfig()
    blocked = spec.occupancy(0.05, inflate=spec.robot_radius + config.clearance)
    visits = _plan(spec, config, blocked)
    assert {v.table.name for v in visits} == {t.name for t in spec.tables}
    for v in visits:
        assert 1 <= len(v.viewpoints) <= 2
        for x, y in v.viewpoints:
            assert not blocked[int(x / 0.05), int(y / 0.05)]


def test_every_table_of_a_generated_room_can_be_scanned():
    from tabletop.sim.room import generate_room

    config = RoomScanConfig()
    for seed in range(8):
        room = generate_room(seed)
        blocked = room.occupancy(0.05, inflate=room.robot_radius + config.clearance)
        visits = _plan(room, config, blocked)  # raises when a table has no reachable viewpoint
        assert {v.table.name for v in visits} == {t.name for t in room.tables}


@pytest.mark.parametrize(
    "kw, needle",
    [
        (dict(rate_hz=0.0), "rate_hz must be > 0"),
        (dict(episodes=2, repeat_sounds=2), r"repeat_sounds must be in \[0, episodes // 2"),
        (dict(views_per_table=0), "views_per_table must be >= 1"),
        (dict(clip_split="test"), "clip_split must be 'heldout', 'train' or 'any'"),
        (dict(look_s="long"), "look_s must be a finite float"),
    ],
)
def test_bad_config_names_the_field(kw, needle):
    with pytest.raises(ConfigError, match=needle):
        RoomScanConfig(**kw)


def test_more_episodes_than_tables_is_refused_before_driving(spec):
    config = RoomScanConfig(**{**SHORT, "episodes": 2})
    with pytest.raises(ConfigError, match=r"2 audio episodes need as many tables .* \['work_"):
        run_room_scan(spec, config)


def test_unknown_tables_are_named(spec):
    config = RoomScanConfig(tables=("kitchen_table",))
    with pytest.raises(ConfigError, match=r"no furniture \['kitchen_table'\]; furniture: \["):
        _plan(spec, config, spec.occupancy(0.05, inflate=0.4))


def test_run_room_scan_returns_the_same_recording_again(spec, scan):
    """run_room_scan is scan_room without the timing figures, and a scan is deterministic.

    Both scans name one renderer (TinyRenderer, which every machine has): with "auto", whether
    another PyBullet world holds EGL in this process picks the renderer, and EGL on a software
    GL stack is not promised to give bit-equal pictures twice (a clean-clone run once saw RGB
    differ while nothing else did)."""
    tiny = RoomScanConfig(**{**SHORT, "renderer": "tiny"})
    a, b = scan_room(spec, tiny)[0], run_room_scan(spec, tiny)
    assert a.meta["renderer"] == b.meta["renderer"] == "tiny"
    assert_same(a, b)
    # the shared scan was the same drive: everything but the pictures' renderer agrees
    for name in ("timestamps", "joint_positions", "T_world_hand", "audio"):
        assert np.array_equal(getattr(a, name), getattr(scan[0], name)), name
