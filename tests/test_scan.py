"""Teleop-style scans: motion, coverage, timing, audio ground truth, noise, and the whole
recording's geometry after a round trip through disk."""

import copy

import numpy as np
import pytest
from helpers import FAST_SCAN, assert_on_table, fast_scan, fast_scan_reloaded

from tabletop.errors import ConfigError
from tabletop.sim.noise import NoiseConfig, apply_noise
from tabletop.sim.scan import ScanConfig, plan_scan
from tabletop.sim.world import INSTANCE_TABLE
from tabletop.transforms import backproject, transform_points

# A faster sweep than the default keeps the test short; the path is the same shape.
FAST = {k: v for k, v in FAST_SCAN.items() if k != "seed"}


@pytest.fixture(scope="module")
def scan():
    return fast_scan()  # seed 1; shared with test_ground_truth.py


@pytest.fixture(scope="module")
def reloaded():
    return fast_scan_reloaded()  # fast_scan through save_recording and load_recording


def test_frames_are_30hz_and_motion_is_smooth(scan):
    rec, stats = scan
    assert stats.frames == len(rec) > 100
    np.testing.assert_allclose(np.diff(rec.timestamps), 1 / 30, atol=1e-9)
    dq = np.abs(np.diff(rec.joint_positions, axis=0)) * 30  # [rad/s]
    assert dq.max() < 2.0, dq.max()  # within Panda joint velocity limits (>= 2.17 rad/s)
    v = np.linalg.norm(np.diff(rec.T_world_hand[:, :3, 3], axis=0), axis=1) * 30
    assert v.max() < 1.0  # a person's hand, not a jump
    acc = np.abs(np.diff(rec.joint_positions, 2, axis=0)) * 900
    assert np.percentile(acc, 99) < 20.0


def test_poses_are_forward_kinematics_of_the_joints(scan):
    from tabletop.arm import PandaModel

    rec, _ = scan
    model = PandaModel()
    for i in range(0, len(rec), max(1, len(rec) // 15)):
        T = model.fk(rec.joint_positions[i], frame="panda_hand")
        np.testing.assert_allclose(T, rec.T_world_hand[i], atol=1e-6)


def test_sweep_covers_the_table_from_varied_heights(scan):
    rec, _ = scan
    mapping = rec.segment("mapping")
    cams = rec.T_world_cam[mapping.start : mapping.stop]
    heights = cams[:, 2, 3]
    assert heights.max() - heights.min() > 0.12
    tilt = np.degrees(np.arccos(np.clip(-cams[:, 2, 2], -1, 1)))  # optical axis vs down
    assert tilt.max() - tilt.min() > 20
    seen = np.zeros((60, 110), bool)  # x 0.2..0.8, y -0.55..0.55 at 1 cm
    for i in range(mapping.start, mapping.stop, 3):
        f = rec.frame(i)
        pts = transform_points(f.T_world_cam, backproject(f.depth, rec.K, f.segmentation >= 2))
        ix = np.floor((pts[:, 0] - 0.2) / 0.01).astype(int)
        iy = np.floor((pts[:, 1] + 0.55) / 0.01).astype(int)
        ok = (ix >= 0) & (ix < 60) & (iy >= 0) & (iy < 110)
        seen[ix[ok], iy[ok]] = True
    assert seen.mean() > 0.95, seen.mean()


def test_round_trip_keeps_everything_and_geometry_holds(scan, reloaded):
    rec, _ = scan
    for name in (
        "timestamps",
        "rgb",
        "depth",
        "segmentation",
        "joint_positions",
        "T_world_hand",
        "audio",
        "K",
        "T_hand_cam",
    ):
        assert np.array_equal(getattr(rec, name), getattr(reloaded, name)), name
    assert reloaded.ground_truth == rec.ground_truth
    assert reloaded.segments == rec.segments
    # The geometry check, on the recorded (reloaded) T_world_cam.
    objs = {o["instance_id"]: o for o in reloaded.ground_truth["objects"]}
    checked = 0
    for i in range(0, len(reloaded), 40):
        f = reloaded.frame(i)
        for inst, o in objs.items():
            mask = f.segmentation == inst
            if mask.sum() < 20:
                continue
            pts = transform_points(f.T_world_cam, backproject(f.depth, reloaded.K, mask))
            lo, hi = np.array(o["aabb_min"]), np.array(o["aabb_max"])
            d = np.linalg.norm(np.maximum(lo - pts, 0) + np.maximum(pts - hi, 0), axis=1)
            assert d.max() <= 0.005, (i, o["name"], d.max())
            checked += 1
        table = transform_points(
            f.T_world_cam, backproject(f.depth, reloaded.K, f.segmentation == INSTANCE_TABLE)
        )
        assert_on_table(table)
    assert checked > 20


def test_sound_ground_truth_matches_the_audio_and_poses(scan):
    rec, _ = scan
    events = rec.ground_truth["sound_events"]
    assert len(events) == 3
    cats = [e["category"] for e in events]
    assert len(set(cats)) == 2  # one category inserted in two regions
    assert rec.audio is not None and rec.audio.dtype == np.float32
    assert len(rec.audio) >= rec.timestamps[-1] * rec.audio_rate
    rate = rec.audio_rate
    for e in events:
        seg = rec.segment(e["episode"])
        assert rec.timestamps[seg.start] <= e["onset_s"] < e["offset_s"]
        assert e["offset_s"] <= rec.timestamps[seg.stop - 1] + 1 / 30
        f0, f1 = e["frames"]
        assert seg.start <= f0 <= f1 < seg.stop
        # the table point is beneath the hovering tool, near the region's centre
        assert np.hypot(*np.subtract(e["table_point"][:2], e["region_center"][:2])) < 0.12
        # the clip is audible where the ground truth says, not before the episode
        a, b = int(e["onset_s"] * rate), int(e["offset_s"] * rate)
        inside = np.sqrt(np.mean(rec.audio[a:b] ** 2))
        before = np.sqrt(np.mean(rec.audio[max(0, a - rate) : a] ** 2))
        assert inside > 2 * before
    t1, t2 = [e for e in events if cats.count(e["category"]) == 2]
    assert np.hypot(*np.subtract(t1["table_point"][:2], t2["table_point"][:2])) > 0.15


def test_same_seed_same_plan_different_seed_different_path():
    a = plan_scan(ScanConfig(seed=5, **FAST))
    b = plan_scan(ScanConfig(seed=5, **FAST))
    c = plan_scan(ScanConfig(seed=6, **FAST))
    assert np.array_equal(a.T_world_cam, b.T_world_cam) and a.segments == b.segments
    assert len(a.T_world_cam) != len(c.T_world_cam) or not np.allclose(a.T_world_cam, c.T_world_cam)


def test_noise_is_seeded_and_keeps_the_truth(scan):
    clean, _ = scan
    noise = NoiseConfig(
        seed=2,
        pose_translation_m=0.003,
        pose_rotation_rad=0.005,
        depth_relative=0.003,
        depth_dropout=0.05,
        drop_frames=0.1,
    )
    before = copy.deepcopy(clean.ground_truth)
    noisy = apply_noise(clean, noise)
    assert clean.ground_truth == before  # the input is not modified
    again = apply_noise(clean, noise)
    other = apply_noise(clean, NoiseConfig(seed=3, depth_relative=0.003))
    assert np.array_equal(noisy.depth, again.depth)
    assert np.array_equal(noisy.T_world_hand, again.T_world_hand)
    assert not np.array_equal(
        other.depth, apply_noise(clean, NoiseConfig(seed=4, depth_relative=0.003)).depth
    )
    assert 0.8 * len(clean) < len(noisy) < len(clean)
    assert noisy.meta["dropped_frames"] == len(clean) - len(noisy)
    assert np.diff(noisy.timestamps).max() > 1.5 / 30  # the gaps show where frames were lost
    err = np.linalg.norm(noisy.T_world_hand[:, :3, 3] - noisy.T_world_hand_true[:, :3, 3], axis=1)
    assert 0.002 < err.mean() < 0.008
    # the true poses are the clean scan's poses at the kept timestamps
    kept = np.round(noisy.timestamps * 30).astype(int)
    np.testing.assert_allclose(noisy.T_world_hand_true, clean.T_world_hand[kept], atol=1e-12)
    np.testing.assert_array_equal(noisy.rgb, clean.rgb[kept])
    invalid = lambda r: (r.depth == 0).mean()  # noqa: E731
    assert invalid(noisy) > invalid(clean) + 0.03
    # depth noise grows with depth squared: about 0.003 * z^2
    both = (noisy.depth > 0) & (clean.depth[kept] > 0)
    z = clean.depth[kept][both].astype(np.float64)
    d = noisy.depth[both] - z
    far = z > 0.5
    assert np.std(d[far]) == pytest.approx(0.003 * np.sqrt(np.mean(z[far] ** 4)), rel=0.1)
    for e in noisy.ground_truth["sound_events"]:
        f0, f1 = e["frames"]
        assert (
            e["onset_s"] - 1 / 30 <= noisy.timestamps[f0] <= noisy.timestamps[f1] <= e["offset_s"]
        )
    assert clean.meta.get("dropped_frames") is None and clean.T_world_hand_true is None
    for s in noisy.segments:
        s0 = clean.segment(s.name)
        assert clean.timestamps[s0.start] <= noisy.timestamps[s.start]
        assert noisy.timestamps[s.stop - 1] <= clean.timestamps[s0.stop - 1]


def test_config_errors_name_the_options():
    with pytest.raises(ConfigError, match="clip_split must be 'heldout', 'train' or 'any'"):
        ScanConfig(clip_split="test")
    with pytest.raises(ConfigError, match=r"repeat_sounds must be in \[0, episodes // 2 = 1\]"):
        ScanConfig(episodes=3, repeat_sounds=2)
    with pytest.raises(ConfigError, match="drop_frames must be in"):
        NoiseConfig(drop_frames=1.5)


def test_extrinsic_error_is_one_fixed_transform_and_the_clock_offset_delays_the_audio(scan):
    clean, _ = scan
    noise = NoiseConfig(
        extrinsic_translation_m=0.005, extrinsic_rotation_rad=np.radians(1.0), clock_offset_s=0.05
    )
    noisy = apply_noise(clean, noise)
    dT = np.linalg.inv(clean.T_hand_cam) @ noisy.T_hand_cam
    assert np.linalg.norm(dT[:3, 3]) == pytest.approx(0.005, rel=1e-9)
    angle = np.arccos(np.clip((np.trace(dT[:3, :3]) - 1) / 2, -1, 1))
    assert angle == pytest.approx(np.radians(1.0), rel=1e-6)
    # the images are those of the true camera; only the recorded calibration is off
    np.testing.assert_array_equal(noisy.rgb, clean.rgb)
    np.testing.assert_array_equal(noisy.T_world_hand, clean.T_world_hand)
    shift = round(0.05 * clean.audio_rate)
    assert len(noisy.audio) == len(clean.audio)
    np.testing.assert_array_equal(noisy.audio[shift:], clean.audio[:-shift])
    assert not noisy.audio[:shift].any()
    early = apply_noise(clean, NoiseConfig(clock_offset_s=-0.05))
    np.testing.assert_array_equal(early.audio[:-shift], clean.audio[shift:])
    # another seed, another direction of the same size
    other = apply_noise(clean, NoiseConfig(seed=1, extrinsic_translation_m=0.005))
    d2 = (np.linalg.inv(clean.T_hand_cam) @ other.T_hand_cam)[:3, 3]
    assert np.linalg.norm(d2) == pytest.approx(0.005) and not np.allclose(d2, dT[:3, 3])


@pytest.mark.parametrize(
    "bad, match",
    [
        (dict(pose_translation_m=float("nan")), "pose_translation_m must be a finite number"),
        (dict(clock_offset_s=float("inf")), "clock_offset_s must be a finite number"),
        (dict(depth_relative="0.1"), "depth_relative must be a finite number"),
        (dict(extrinsic_rotation_rad=-0.1), "extrinsic_rotation_rad must be >= 0"),
        (dict(pose_translation_m=5.0), "beyond 0.5: not sensor noise"),
        (dict(seed=-1), "seed must be an integer >= 0"),
        (dict(seed=1.5), "seed must be an integer >= 0"),
    ],
)
def test_bad_noise_settings_are_refused_by_name(bad, match):
    with pytest.raises(ConfigError, match=match):
        NoiseConfig(**bad)


def test_noise_from_a_table_names_unknown_keys_and_the_valid_ones():
    with pytest.raises(ConfigError, match=r"unknown settings \['pose'\]; valid: \['seed'"):
        NoiseConfig.from_dict({"pose": 0.1})
    with pytest.raises(ConfigError, match="must be a table"):
        NoiseConfig.from_dict([1, 2])
    assert NoiseConfig.from_dict({"drop_frames": 0.2}).any
    assert not NoiseConfig.from_dict({"seed": 3}).any


@pytest.mark.parametrize(
    "bad, match",
    [
        (dict(speed=float("nan")), "speed must be a finite float"),
        (dict(episodes=2.5), "episodes must be a finite int"),
        (dict(seed=True), "seed must be a finite int"),
        (dict(renderer="gl"), "renderer must be 'auto', 'egl' or 'tiny'"),
        (dict(noise={"drop_frames": 2}), "drop_frames must be in"),
        (dict(noise=3), "noise must be a table"),
        (dict(tremor_m=-1.0), "tremor_m and min_clearance must be >= 0"),
    ],
)
def test_bad_scan_settings_are_refused_by_name(bad, match):
    with pytest.raises(ConfigError, match=match):
        ScanConfig(**bad)
