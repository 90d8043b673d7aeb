"""Online mapping: a recording's frames given to the map as the camera delivered them, the lag
reported, frames dropped only where the drop policy says so; the map equals a batch build of
the same (unregistered) frames."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import ground_truth_dict, small_recording

from tabletop.cli.app import main
from tabletop.errors import ConfigError, RecordingError
from tabletop.eval.harness import build_map_online, map_config
from tabletop.mapping import AVLMap
from tabletop.mapping.online import replay_online
from tabletop.recording import Recording, save_recording


def _recording(n: int = 6) -> Recording:
    """A camera looking down at a labelled patch of table (oracle segmentation), moving."""
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = np.diag([1.0, -1.0, -1.0])
    T[:, :3, 3] = (0.3, 0.0, 0.5)
    T[:, 0, 3] += np.linspace(0.0, 0.05, n)  # the camera moves along x
    seg = np.zeros((n, 48, 64), np.uint16)
    seg[:, 16:32, 20:40] = 4
    truth = ground_truth_dict(
        objects=[{"name": "red_mug", "aabb_min": [0.25, -0.05, 0.0], "aabb_max": [0.4, 0.05, 0.1]}]
    )
    return small_recording(
        n, T_world_hand=T, audio=None, segmentation=seg, ground_truth=truth, meta={"source": "test"}
    )


def test_every_frame_is_fused_in_order_and_the_map_equals_a_batch_of_the_same_frames():
    rec = _recording()
    config = map_config(self_filter_margin=None)
    m, report = build_map_online(rec, "oracle", config, rate=4.0)
    assert (report.frames, report.fused, report.dropped) == (6, 6, 0)
    assert report.camera_fps == pytest.approx(120.0)  # 30 frames/s replayed 4x as fast
    assert 0.0 <= report.lag_median_s <= report.lag_p95_s <= report.lag_max_s
    assert report.wall_s >= 5 / 120.0  # the frames were waited for, not taken at once
    # the same frames added by hand in a batch give the same map
    batch = AVLMap.empty(rec, config, "oracle")
    T_cam = rec.T_world_hand @ rec.T_hand_cam
    for i in range(len(rec)):
        batch.add_frame(
            rec.rgb[i], rec.depth[i], rec.K, T_cam[i], {"segmentation": rec.segmentation[i]}
        )
    assert m.voxels.n == batch.voxels.n > 0
    np.testing.assert_array_equal(m.voxels.linear_indices, batch.voxels.linear_indices)


def test_a_map_that_cannot_keep_up_drops_only_under_the_late_policy():
    rec = _recording(8)
    # replayed a million times as fast, every frame has arrived before the first is fused
    m, late = build_map_online(rec, "oracle", map_config(), rate=1e6, drop="late")
    assert (late.fused, late.dropped) == (1, 7) and m.frames_seen == 1  # the newest frame
    assert not late.keeps_up
    _, every = build_map_online(rec, "oracle", map_config(), rate=1e6, drop="none")
    assert (every.fused, every.dropped) == (8, 0) and not every.keeps_up
    assert every.lag_max_s > every.lag_median_s >= 0.0  # the queue grows behind the camera


def test_bad_replay_settings_are_named():
    rec = _recording(3)
    m = AVLMap.empty(rec, map_config(), "oracle")
    with pytest.raises(ConfigError, match="drop must be one of"):
        replay_online(m, rec, drop="sometimes")
    for rate in (0, -1, float("nan"), True):
        with pytest.raises(ConfigError, match="rate must be a number"):
            replay_online(m, rec, rate=rate)
    kw = {k: getattr(rec, k) for k in rec.__dataclass_fields__}
    for k in ("timestamps", "rgb", "depth", "T_world_hand", "joint_positions", "segmentation"):
        kw[k] = kw[k][:0]
    with pytest.raises(RecordingError, match="no frame to replay"):
        replay_online(m, Recording(**kw))


def test_build_map_online_prints_the_lag(tmp_path, capsys):
    save_recording(_recording(), tmp_path / "rec")
    out = tmp_path / "m.npz"
    args = ["build-map", str(tmp_path / "rec"), "--out", str(out), "--online", "--rate", "2"]
    main(args)  # a map this small is reported as too sparse (exit 1); the replay is what counts
    text = capsys.readouterr().out
    assert "online:    camera 60.0 frames/s; 6 of 6 frames given to the map, 0 dropped" in text
    assert "lag median" in text and out.is_file()
    assert main(["build-map", str(tmp_path / "rec"), "--out", str(out), "--drop", "late"]) == 2
    assert "--drop: only with --online" in capsys.readouterr().err


def test_judge_and_image_target_name_a_wrong_argument():
    # the eighth probe: a 3x3 pose raised IndexError, a margin of "big" ValueError, and a
    # margin of nan answered a confidence of nan
    rec = _recording(3)
    m = AVLMap.empty(rec, map_config(), "oracle")
    for margin in ("big", float("nan"), None, True):
        with pytest.raises(ConfigError, match="margin must be a finite number"):
            m.judge("object", margin)
    assert 0.0 <= m.judge("object", 0.2)[0] <= 1.0
    K = rec.K
    for T, why in ((np.eye(3), r"T_world_cam must be a \(4, 4\) matrix"), ("x", "T_world_cam")):
        with pytest.raises(ConfigError, match=why):
            m.image_target(T, K, (64, 48))
    for size in ((64,), (0, 48), ("a", "b")):
        with pytest.raises(ConfigError, match="image_size must be"):
            m.image_target(np.eye(4), K, size)
    # the ninth probe: a pose that is no rigid transform, and intrinsics with no focal length
    sheared, mirrored = np.eye(4), np.diag([1.0, 1.0, -1.0, 1.0])
    sheared[0, 1] = 0.5
    for T in (sheared, mirrored, 2 * np.eye(4)):
        with pytest.raises(ConfigError, match="T_world_cam must be a rigid transform"):
            m.image_target(T, K, (64, 48))
    for bad in (np.zeros((3, 3)), np.diag([500.0, -500.0, 1.0])):
        with pytest.raises(ConfigError, match="K must be pinhole intrinsics"):
            m.image_target(np.eye(4), bad, (64, 48))
    # and a decay asked with a word for a boolean
    for major in ("yes", 1, None):
        with pytest.raises(ConfigError, match=r"decay\(major=...\): major takes True or False"):
            m.decay(major)
    assert m.decay(True) == m.config.major_decay and m.decay(False) == m.config.aux_decay
