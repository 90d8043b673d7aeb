"""`tabletop import`: a simulator scan written out as a ROS 2 bag (with rosbags' own writer) and
as a TUM-style RGB-D folder (PNGs through cv2) comes back as the same map; each classic frame
mistake injected into either is named by its typed error."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from tabletop.arm.recording_kinematics import PandaRecordingKinematics
from tabletop.cli.app import main
from tabletop.ingest import (
    BagTopics,
    CameraFrameError,
    CameraInsideArmError,
    DepthScaleError,
    FrameCheckError,
    ImportOptions,
    InvertedPoseError,
    TimestampError,
    import_recording,
)
from tabletop.ingest.checks import R_BODY_OPTICAL
from tabletop.ingest.common import matrix_to_quat
from tabletop.recording import load_recording

BAG_BASE_NS = 1_700_000_000 * 10**9  # ROS time of the scan's t = 0
TUM_BASE_S = 1305031102.0
HAS_ROSBAGS = True
try:
    import rosbags  # noqa: F401
except ImportError:
    HAS_ROSBAGS = False
needs_rosbags = pytest.mark.skipif(
    not HAS_ROSBAGS,
    reason="rosbags is not installed (the 'import' extra; scripts/bootstrap installs it with "
    "TABLETOP_BACKENDS=1)",
)


# ---------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def rec():
    from tabletop.sim.scan import ScanConfig, run_scan
    from tabletop.sim.scene import load_scene_spec

    cfg = ScanConfig(seed=3, speed=0.45, rate_hz=5, episodes=1, episode_s=2.0, repeat_sounds=0)
    return run_scan(load_scene_spec("default"), cfg)[0]


@pytest.fixture(scope="module")
def short(rec):
    """30 frames of the mapping sweep: enough for the checks (the mistake tests build no map)."""
    s = slice(10, 40)
    return replace(
        rec,
        timestamps=rec.timestamps[s],
        rgb=rec.rgb[s],
        depth=rec.depth[s],
        joint_positions=rec.joint_positions[s],
        T_world_hand=rec.T_world_hand[s],
        segmentation=None,
        T_world_hand_true=None,
        segments=(),
    )


@pytest.fixture(scope="module")
def arm():
    return PandaRecordingKinematics()


def _map(recording, original):
    """The oracle map of ``recording``, with the simulator's segmentation and ground truth of
    ``original`` (what the oracle encoders read; a real recording has neither)."""
    from tabletop.eval.harness import build_map, map_config
    from tabletop.mapping.visual import VisualLocalizationConfig

    r = replace(recording, segmentation=original.segmentation, ground_truth=original.ground_truth)
    config = map_config(frame_step=2, visual=VisualLocalizationConfig(matcher="sift", stride=10))
    return build_map(r, "oracle", config)


@pytest.fixture(scope="module")
def original_map(rec):
    return _map(rec, rec)


# ---------------------------------------------------------------------- TUM writer
def write_tum(rec, path: Path, *, depth_scale=10000.0, mistake=None) -> Path:
    """``rec`` as a TUM folder (camera poses in groundtruth.txt), with one mistake injected."""
    (path / "rgb").mkdir(parents=True)
    (path / "depth").mkdir()
    t = TUM_BASE_S + rec.timestamps
    T_wc = rec.T_world_cam
    if mistake == "inverted":
        T_wc = np.linalg.inv(T_wc)
    if mistake == "camera_frame":
        T_wc = T_wc @ np.linalg.inv(R_BODY_OPTICAL)
    rgb_lines, depth_lines = ["# timestamp filename"], ["# timestamp filename"]
    for i in range(len(rec)):
        cv2.imwrite(str(path / f"rgb/{i:06d}.png"), rec.rgb[i][..., ::-1])
        units = np.round(rec.depth[i].astype(np.float64) * depth_scale).astype(np.uint16)
        cv2.imwrite(str(path / f"depth/{i:06d}.png"), units)
        rgb_lines.append(f"{t[i]:.6f} rgb/{i:06d}.png")
        depth_lines.append(f"{t[i]:.6f} depth/{i:06d}.png")
    if mistake == "out_of_order":
        rgb_lines[5], rgb_lines[6] = rgb_lines[6], rgb_lines[5]
    gt_t = t + (3600.0 if mistake == "other_clock" else 0.0)
    gt = ["# timestamp tx ty tz qx qy qz qw"]
    for i in range(len(rec)):
        xyz, q = matrix_to_quat(T_wc[i])
        gt.append(" ".join(f"{v:.17g}" for v in (gt_t[i], *xyz, *q)))
    joints = [
        " ".join(f"{v:.17g}" for v in (t[i], *rec.joint_positions[i][:7])) for i in range(len(rec))
    ]
    T_hand_cam = np.linalg.inv(rec.T_hand_cam) if mistake == "inside_arm" else rec.T_hand_cam
    for name, lines in (
        ("rgb.txt", rgb_lines),
        ("depth.txt", depth_lines),
        ("groundtruth.txt", gt),
        ("joints.txt", joints),
    ):
        (path / name).write_text("\n".join(lines) + "\n")
    (path / "camera.json").write_text(
        json.dumps({"K": rec.K.tolist(), "T_hand_cam": T_hand_cam.tolist()})
    )
    return path


# ---------------------------------------------------------------------- bag writer
def write_bag(rec, path: Path, *, poses="joints", mistake=None, compressed=False) -> Path:
    """``rec`` as a ROS 2 bag: colour, depth (32FC1 metres), camera info, joint states, the
    hand-eye extrinsic on /tf_static, the hand on /tf (``poses="tf"``), mono F32LE audio."""
    from rosbags.rosbag2 import Writer

    from tabletop.ingest.rosbag2 import typestore

    ts = typestore()
    T = ts.types
    Header, Time = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]

    def header(ns, frame):
        return Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)

    def transform(ns, parent, child, M):
        xyz, q = matrix_to_quat(M)
        G = T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=xyz[0], y=xyz[1], z=xyz[2]),
            rotation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
        )
        return T["geometry_msgs/msg/TransformStamped"](
            header=header(ns, parent), child_frame_id=child, transform=G
        )

    ns = BAG_BASE_NS + np.round(rec.timestamps * 1e9).astype(np.int64)
    img_ns = ns.copy()
    if mistake == "out_of_order":
        img_ns[5], img_ns[6] = img_ns[6], img_ns[5]
    joint_ns = ns - (BAG_BASE_NS - 12_345 * 10**9 if mistake == "other_clock" else 0)
    cam_frame = "camera_color_optical_frame"
    T_hand_cam = rec.T_hand_cam
    if mistake == "camera_frame":
        T_hand_cam = T_hand_cam @ np.linalg.inv(R_BODY_OPTICAL)
    if mistake == "inside_arm":
        T_hand_cam = np.linalg.inv(T_hand_cam)
    h, w = rec.rgb.shape[1:3]
    with Writer(path, version=9) as wr:

        def conn(topic, msgtype):
            return wr.add_connection(topic, msgtype, typestore=ts)

        c_rgb = conn(
            "/camera/color/image_raw",
            "sensor_msgs/msg/CompressedImage" if compressed else "sensor_msgs/msg/Image",
        )
        c_depth = conn("/camera/aligned_depth_to_color/image_raw", "sensor_msgs/msg/Image")
        c_info = conn("/camera/color/camera_info", "sensor_msgs/msg/CameraInfo")
        c_js = conn("/joint_states", "sensor_msgs/msg/JointState")
        c_static = conn("/tf_static", "tf2_msgs/msg/TFMessage")
        c_tf = conn("/tf", "tf2_msgs/msg/TFMessage") if poses == "tf" else None
        c_audio = conn("/audio/audio", "audio_common_msgs/msg/AudioDataStamped")
        c_ainfo = conn("/audio/audio_info", "audio_common_msgs/msg/AudioInfo")

        def put(c, t_ns, msg):
            wr.write(c, int(t_ns), ts.serialize_cdr(msg, c.msgtype))

        put(
            c_static,
            ns[0],
            T["tf2_msgs/msg/TFMessage"](
                transforms=[transform(int(ns[0]), "panda_hand", cam_frame, T_hand_cam)]
            ),
        )
        put(
            c_ainfo,
            ns[0],
            T["audio_common_msgs/msg/AudioInfo"](
                channels=1,
                sample_rate=rec.audio_rate,
                sample_format="F32LE",
                bitrate=0,
                coding_format="wave",
            ),
        )
        chunk = rec.audio_rate // 10
        for k in range(0, len(rec.audio), chunk):
            a_ns = BAG_BASE_NS + round(k / rec.audio_rate * 1e9)
            data = np.frombuffer(rec.audio[k : k + chunk].astype("<f4").tobytes(), np.uint8)
            put(
                c_audio,
                a_ns,
                T["audio_common_msgs/msg/AudioDataStamped"](
                    header=header(a_ns, "panda_hand"),
                    audio=T["audio_common_msgs/msg/AudioData"](data=data),
                ),
            )
        for i in range(len(rec)):
            t_ns = int(ns[i])
            if compressed:
                ok, png = cv2.imencode(".png", rec.rgb[i][..., ::-1])
                assert ok
                put(
                    c_rgb,
                    t_ns,
                    T["sensor_msgs/msg/CompressedImage"](
                        header=header(int(img_ns[i]), cam_frame),
                        format="rgb8; png compressed bgr8",
                        data=png.ravel(),
                    ),
                )
            else:
                put(
                    c_rgb,
                    t_ns,
                    T["sensor_msgs/msg/Image"](
                        header=header(int(img_ns[i]), cam_frame),
                        height=h,
                        width=w,
                        encoding="rgb8",
                        is_bigendian=0,
                        step=w * 3,
                        data=rec.rgb[i].ravel(),
                    ),
                )
            d = rec.depth[i] * (1000.0 if mistake == "mm_as_m" else 1.0)
            put(
                c_depth,
                t_ns,
                T["sensor_msgs/msg/Image"](
                    header=header(int(img_ns[i]), cam_frame),
                    height=h,
                    width=w,
                    encoding="32FC1",
                    is_bigendian=0,
                    step=w * 4,
                    data=np.frombuffer(d.astype("<f4").tobytes(), np.uint8),
                ),
            )
            if i == 0:
                put(
                    c_info,
                    t_ns,
                    T["sensor_msgs/msg/CameraInfo"](
                        header=header(t_ns, cam_frame),
                        height=h,
                        width=w,
                        distortion_model="plumb_bob",
                        d=np.zeros(5),
                        k=rec.K.ravel(),
                        r=np.eye(3).ravel(),
                        p=np.c_[rec.K, np.zeros(3)].ravel(),
                        binning_x=0,
                        binning_y=0,
                        roi=T["sensor_msgs/msg/RegionOfInterest"](
                            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
                        ),
                    ),
                )
            names = [f"panda_joint{j}" for j in range(1, 8)] + [
                "panda_finger_joint1",
                "panda_finger_joint2",
            ]
            q = np.r_[rec.joint_positions[i][:7], 0.04, 0.04]
            put(
                c_js,
                t_ns,
                T["sensor_msgs/msg/JointState"](
                    header=header(int(joint_ns[i]), ""),
                    name=names,
                    position=q,
                    velocity=np.zeros(0),
                    effort=np.zeros(0),
                ),
            )
            if c_tf is not None:
                M = rec.T_world_hand[i]
                if mistake == "inverted":
                    M = np.linalg.inv(M)
                put(
                    c_tf,
                    t_ns,
                    T["tf2_msgs/msg/TFMessage"](
                        transforms=[transform(t_ns, "panda_link0", "panda_hand", M)]
                    ),
                )
    return path


# ---------------------------------------------------------------------- tests: clean imports
def _same_targets(m_import, m_orig, rec, atol=1e-6):
    for obj in rec.ground_truth["objects"]:
        h0, h1 = m_orig.object_heatmap(obj["label"]), m_import.object_heatmap(obj["label"])
        assert h1.found == h0.found
        np.testing.assert_allclose(h1.values, h0.values, atol=atol)
        np.testing.assert_allclose(
            m_import.get_max_pos_3d(h1), m_orig.get_max_pos_3d(h0), atol=atol
        )


def test_tum_folder_comes_back_as_the_same_map(rec, arm, original_map, tmp_path):
    src = write_tum(rec, tmp_path / "tum")
    out = tmp_path / "rec"
    assert main(["import", str(src), "--out", str(out), "--depth-scale", "10000"]) == 0
    back = load_recording(out)
    assert back.meta["source"] == "tum" and back.meta["poses_from"] == "camera"
    assert back.meta["import_checks"]["agreement"] >= 0.5
    np.testing.assert_array_equal(back.rgb, rec.rgb)
    np.testing.assert_array_equal(back.depth, rec.depth)
    np.testing.assert_allclose(back.T_world_cam, rec.T_world_cam, atol=1e-9)
    np.testing.assert_allclose(back.timestamps, rec.timestamps, atol=2e-6)
    _same_targets(_map(back, rec), original_map, rec)


@needs_rosbags
def test_bag_with_joint_states_comes_back_as_the_same_map(rec, arm, original_map, tmp_path):
    src = write_bag(rec, tmp_path / "bag")
    out = tmp_path / "rec"
    assert main(["import", str(src), "--out", str(out)]) == 0
    back = load_recording(out)
    assert back.meta["poses_from"] == "joints"  # forward kinematics through the arm model
    np.testing.assert_array_equal(back.rgb, rec.rgb)
    np.testing.assert_array_equal(back.depth, rec.depth)
    np.testing.assert_allclose(back.T_world_hand, rec.T_world_hand, atol=1e-6)
    np.testing.assert_allclose(back.joint_positions, rec.joint_positions[:, :7], atol=0)
    np.testing.assert_allclose(back.timestamps, rec.timestamps, atol=1e-6)
    np.testing.assert_array_equal(back.audio[: len(rec.audio)], rec.audio)
    m = _map(back, rec)
    _same_targets(m, original_map, rec)
    for e in rec.ground_truth["sound_events"]:
        p0 = original_map.get_max_pos_3d(original_map.sound_heatmap(e["caption"]))
        np.testing.assert_allclose(m.get_max_pos_3d(m.sound_heatmap(e["caption"])), p0, atol=1e-6)


@needs_rosbags
def test_bag_with_tf_poses_and_png_colour_reads_the_scan(short, arm, tmp_path):
    src = write_bag(short, tmp_path / "bag", poses="tf", compressed=True)
    back, report = import_recording(src, kinematics=arm, arm=arm)
    assert back.meta["poses_from"] == "hand"
    np.testing.assert_array_equal(back.rgb, short.rgb)
    np.testing.assert_allclose(back.T_world_hand, short.T_world_hand, atol=1e-9)
    np.testing.assert_allclose(back.T_hand_cam, short.T_hand_cam, atol=1e-12)
    assert report.agreement >= 0.5 and report.level >= 0.25
    assert abs(report.table_z) < 0.05  # the default scene's table top is the base frame's z = 0


# ---------------------------------------------------------------------- tests: mistakes
MISTAKES = {
    "inverted": InvertedPoseError,
    "camera_frame": CameraFrameError,
    "mm_as_m": DepthScaleError,
    "out_of_order": TimestampError,
    "other_clock": TimestampError,
    "inside_arm": CameraInsideArmError,
}
WORDS = {
    "inverted": "inverted",
    "camera_frame": "optical frame",
    "mm_as_m": "millimetres read as metres",
    "out_of_order": "out of order",
    "other_clock": "another clock",
    "inside_arm": "inside the arm",
}


@pytest.mark.parametrize("mistake", list(MISTAKES))
def test_tum_mistake_is_named(short, arm, tmp_path, mistake):
    scale = 1000.0 if mistake == "mm_as_m" else 10000.0
    src = write_tum(short, tmp_path / "tum", depth_scale=scale, mistake=mistake)
    # millimetre PNGs read as if they held metres (one unit per metre)
    opts = ImportOptions(depth_scale=1.0 if mistake == "mm_as_m" else scale)
    with pytest.raises(MISTAKES[mistake]) as e:
        import_recording(src, tmp_path / "rec", "tum", options=opts, kinematics=arm, arm=arm)
    assert WORDS[mistake] in str(e.value)
    assert "Likely fix" in str(e.value) or "pass the inverse" in str(e.value)
    assert not (tmp_path / "rec").exists()  # nothing half-written


def test_tum_wrong_depth_scale_is_named_from_disagreeing_views(short, arm, tmp_path):
    # millimetre PNGs read with TUM's 5000 units per metre: depth 5 times too short, still a
    # plausible 0.1 m, so only the views' disagreement tells
    src = write_tum(short, tmp_path / "tum", depth_scale=1000.0)
    with pytest.raises(DepthScaleError, match="multiplied by 5") as e:
        import_recording(src, None, "tum", kinematics=arm, arm=arm)
    assert "agree" in str(e.value)


@needs_rosbags
@pytest.mark.parametrize("mistake", list(MISTAKES))
def test_bag_mistake_is_named(short, arm, tmp_path, mistake):
    src = write_bag(short, tmp_path / "bag", poses="tf", mistake=mistake)
    with pytest.raises(MISTAKES[mistake]) as e:
        import_recording(src, None, "rosbag2", kinematics=arm, arm=arm)
    assert WORDS[mistake] in str(e.value)


def test_views_that_disagree_for_no_known_reason_are_refused(short, arm):
    # every pose shuffled: no single mistake explains it
    order = np.random.default_rng(0).permutation(len(short))
    bad = replace(short, T_world_hand=short.T_world_hand[order])
    from tabletop.ingest.checks import check_recording

    with pytest.raises(FrameCheckError, match="none of the known mistakes"):
        check_recording(bad, pose_of="hand", arm=arm)


def test_the_first_camera_frame_taken_as_the_world_is_refused(short, arm):
    # a SLAM-style world: the first camera frame; the views agree, the table is "level" in it
    # (it faces the camera) but lies above the cameras
    from tabletop.ingest.checks import check_recording

    world = np.linalg.inv(short.T_world_cam[0])
    bad = replace(short, T_world_hand=world @ short.T_world_hand)
    with pytest.raises(FrameCheckError, match="first camera frame taken"):
        check_recording(bad, pose_of="hand", arm=None)


def test_cli_names_the_mistake_and_exits_2(short, tmp_path, capsys):
    src = write_tum(short, tmp_path / "tum", mistake="inverted")
    assert main(["import", str(src), "--out", str(tmp_path / "rec"), "--depth-scale", "10000"]) == 2
    err = capsys.readouterr().err
    assert "inverted camera poses" in err and not (tmp_path / "rec").exists()


def test_missing_topic_option_names_the_choices(short, tmp_path):
    if not HAS_ROSBAGS:
        pytest.skip("rosbags is not installed (the 'import' extra)")
    src = write_bag(short, tmp_path / "bag")
    from tabletop.ingest import ImportFormatError

    with pytest.raises(ImportFormatError, match="no topic '/nope'.*topics:"):
        import_recording(src, None, "rosbag2", topics=BagTopics(rgb="/nope"))


def test_a_source_that_does_not_exist_is_named_before_its_format_is_guessed(tmp_path, capsys):
    from tabletop.ingest import ImportFormatError, guess_format

    with pytest.raises(ImportFormatError, match="does not exist"):
        guess_format(tmp_path / "nope.bag")
    # a folder of neither kind still asks for --format
    with pytest.raises(ImportFormatError, match="cannot tell the format"):
        guess_format(tmp_path)
    assert main(["import", str(tmp_path / "nope.bag"), "--out", str(tmp_path / "o")]) == 2
    assert "nope.bag does not exist" in capsys.readouterr().err
