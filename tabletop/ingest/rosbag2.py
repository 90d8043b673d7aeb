"""A ROS 2 bag (read through ``rosbags``, pure Python: the ``import`` extra) as a recording.

Topics, found by type where there is one of a kind, else named by the options:

- colour: ``sensor_msgs/msg/Image`` (rgb8, bgr8, rgba8, bgra8, mono8) or
  ``sensor_msgs/msg/CompressedImage`` (png, jpeg);
- depth, registered to the colour image: ``Image`` 16UC1 / mono16 (``depth_scale`` units per
  metre, 1000 by ROS's REP 118) or 32FC1 (metres), or a ``compressedDepth`` PNG;
- ``sensor_msgs/msg/CameraInfo``: the intrinsics K;
- poses: ``tf2_msgs/msg/TFMessage`` on ``/tf`` and ``/tf_static``; the hand pose is the chain
  from ``world_frame`` to ``hand_frame`` where ``/tf`` moves it, else forward kinematics of
  ``sensor_msgs/msg/JointState`` (panda_joint1..7) through the project's arm model; the
  extrinsic ``T_hand_cam`` is the chain from ``hand_frame`` to the colour image's ``frame_id``;
- audio, where present: ``audio_common_msgs/msg/AudioDataStamped`` chunks (each stamped with its
  first sample, played back to back), format from an ``audio_common_msgs/msg/AudioInfo`` topic
  (S16LE or F32LE, mono; 16 kHz S16LE without one).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from tabletop.ingest.common import (
    ImportOptions,
    Kinematics,
    assemble,
    interpolate_poses,
    match_depth,
    quat_to_matrix,
)
from tabletop.ingest.errors import ImportFormatError, MissingExtraError
from tabletop.recording import Recording

__all__ = ["AUDIO_MSGS", "BagTopics", "read_rosbag2", "typestore"]

#: audio_common_msgs (ROS 2), which the stock type stores lack.
AUDIO_MSGS = {
    "audio_common_msgs/msg/AudioData": "uint8[] data\n",
    "audio_common_msgs/msg/AudioDataStamped": (
        "std_msgs/Header header\naudio_common_msgs/AudioData audio\n"
    ),
    "audio_common_msgs/msg/AudioInfo": (
        "uint8 channels\nuint32 sample_rate\nstring sample_format\nuint32 bitrate\n"
        "string coding_format\n"
    ),
}
IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
INFO = "sensor_msgs/msg/CameraInfo"
JOINTS = "sensor_msgs/msg/JointState"
TF = "tf2_msgs/msg/TFMessage"
AUDIO = "audio_common_msgs/msg/AudioDataStamped"
AUDIO_INFO = "audio_common_msgs/msg/AudioInfo"


def _rosbags():
    try:
        import rosbags.rosbag2
        import rosbags.typesys
    except ImportError:
        raise MissingExtraError(
            "reading ROS 2 bags needs the rosbags library: pip install 'tabletop[import]' "
            "(or scripts/bootstrap with TABLETOP_BACKENDS=1)"
        ) from None
    return rosbags.rosbag2, rosbags.typesys


def typestore():
    """ROS 2 Humble's message types plus :data:`AUDIO_MSGS` (for reading and for writing)."""
    _, typesys = _rosbags()
    store = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    types = {}
    for name, text in AUDIO_MSGS.items():
        types.update(typesys.get_types_from_msg(text, name))
    store.register(types)
    return store


@dataclass(frozen=True)
class BagTopics:
    """Topics and frames to read (None: found by type, or by the colour image's header)."""

    rgb: str | None = None
    depth: str | None = None
    camera_info: str | None = None
    joint_states: str | None = None
    audio: str | None = None
    world_frame: str = "panda_link0"
    hand_frame: str = "panda_hand"


def _stamp(header) -> float:
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def _pick(
    conns: dict[str, str],
    types: tuple[str, ...],
    given: str | None,
    what: str,
    prefer=None,
    required=True,
) -> str | None:
    if given is not None:
        if given not in conns:
            raise ImportFormatError(
                f"no topic {given!r} in the bag ({what}); topics: {sorted(conns)}"
            )
        return given
    cands = [t for t, ty in conns.items() if ty in types]
    if prefer is not None and len(cands) > 1:
        cands = [t for t in cands if prefer(t)] or cands
    if len(cands) == 1:
        return cands[0]
    if not cands and not required:
        return None
    raise ImportFormatError(
        f"{'no' if not cands else 'more than one'} {what} topic ({' or '.join(types)}): "
        f"{cands or sorted(conns)}; name it with the option for {what}"
    )


def _decode_image(msg, msgtype: str, where: str) -> np.ndarray:
    """Colour (H, W, 3) uint8 RGB, or depth (H, W) uint16 / float32 as stored."""
    if msgtype == COMPRESSED:
        data = np.frombuffer(bytes(msg.data), np.uint8)
        if "compresseddepth" in msg.format.lower():
            data = data[12:]  # the compressedDepth header before the PNG
            img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
        else:
            img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
            if img is not None and img.ndim == 3:
                img = img[..., :3][..., ::-1]
        if img is None:
            raise ImportFormatError(
                f"{where}: compressed image of format {msg.format!r} does not decode"
            )
        return img
    enc = msg.encoding.lower()
    h, w, step = msg.height, msg.width, msg.step
    buf = np.frombuffer(bytes(msg.data), np.uint8)
    layouts = {
        "rgb8": (np.uint8, 3),
        "bgr8": (np.uint8, 3),
        "rgba8": (np.uint8, 4),
        "bgra8": (np.uint8, 4),
        "mono8": (np.uint8, 1),
        "16uc1": (np.uint16, 1),
        "mono16": (np.uint16, 1),
        "32fc1": (np.float32, 1),
    }
    if enc not in layouts:
        raise ImportFormatError(
            f"{where}: image encoding {msg.encoding!r}; valid: {sorted(layouts)}"
        )
    dtype, ch = layouts[enc]
    dt = np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<")
    rows = buf.reshape(h, step)[:, : w * ch * dt.itemsize]
    img = rows.copy().view(dt).reshape(h, w, ch).astype(dtype)
    if enc in ("bgr8", "bgra8"):
        img = img[..., 2::-1]
    elif enc == "rgba8":
        img = img[..., :3]
    elif enc == "mono8":
        img = np.repeat(img, 3, axis=2)
    return img[..., 0] if ch == 1 and enc != "mono8" else np.ascontiguousarray(img)


class _TfTree:
    """Edges parent -> child with their stamped transforms (static ones without time)."""

    def __init__(self) -> None:
        self.dynamic: dict[tuple[str, str], list[tuple[float, np.ndarray]]] = defaultdict(list)
        self.static: dict[tuple[str, str], np.ndarray] = {}

    def add(self, msg, static: bool) -> None:
        for tr in msg.transforms:
            t = tr.transform
            T = quat_to_matrix(
                (t.translation.x, t.translation.y, t.translation.z),
                (t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w),
            )
            key = (tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/"))
            if static:
                self.static[key] = T
            else:
                self.dynamic[key].append((_stamp(tr.header), T))

    def path(self, a: str, b: str) -> list[tuple[str, str, bool]] | None:
        """Edges (parent, child, forward) from frame a to frame b, or None."""
        nbrs = defaultdict(list)
        for p, c in [*self.static, *self.dynamic]:
            nbrs[p].append((c, (p, c), True))
            nbrs[c].append((p, (p, c), False))
        prev = {a: None}
        todo = [a]
        while todo:
            f = todo.pop(0)
            if f == b:
                out = []
                while prev[f] is not None:
                    f0, edge, fwd = prev[f]
                    out.append((*edge, fwd))
                    f = f0
                return out[::-1]
            for g, edge, fwd in nbrs[f]:
                if g not in prev:
                    prev[g] = (f, edge, fwd)
                    todo.append(g)
        return None

    def moves(self, path) -> bool:
        return any((p, c) not in self.static for p, c, _ in path)

    def chain(self, path, t: np.ndarray) -> np.ndarray:
        out = np.repeat(np.eye(4)[None], len(t), axis=0)
        for p, c, fwd in path:
            if (p, c) in self.static:
                T = np.repeat(self.static[(p, c)][None], len(t), axis=0)
            else:
                series = sorted(self.dynamic[(p, c)], key=lambda x: x[0])
                keys = np.array([s for s, _ in series])
                T = interpolate_poses(t, keys, np.stack([m for _, m in series]))
            out = out @ (T if fwd else np.linalg.inv(T))
        return out

    def stamps(self, path) -> np.ndarray:
        s = [x for p, c, _ in path if (p, c) not in self.static for x, _ in self.dynamic[(p, c)]]
        return np.unique(np.array(s, np.float64))


def _audio(chunks, info, where: str) -> tuple[np.ndarray, int, float] | None:
    if not chunks:
        return None
    rate, fmt, channels = 16000, "S16LE", 1
    if info is not None:
        rate, fmt, channels = int(info.sample_rate), info.sample_format.upper(), int(info.channels)
    kinds = {"S16LE": ("<i2", 32768.0), "F32LE": ("<f4", 1.0)}
    if fmt not in kinds or channels != 1:
        raise ImportFormatError(
            f"{where}: audio is {channels} channel(s) of {fmt!r}; valid: mono {sorted(kinds)}"
        )
    dt, full = kinds[fmt]
    chunks = sorted(chunks, key=lambda c: c[0])
    data = b"".join(bytes(c[1]) for c in chunks)
    samples = (np.frombuffer(data, dt).astype(np.float64) / full).astype(np.float32)
    return samples, rate, chunks[0][0]


def read_rosbag2(
    src: str | Path,
    options: ImportOptions | None = None,
    topics: BagTopics | None = None,
    kinematics: Kinematics | None = None,
) -> tuple[Recording, str]:
    """(recording, pose_of) of a ROS 2 bag directory; ``pose_of`` is "hand" (TF) or "joints"
    (forward kinematics through ``kinematics``)."""
    rosbag2, _ = _rosbags()
    src = Path(src)
    options = options or ImportOptions()
    topics = topics or BagTopics()
    store = typestore()
    try:
        reader = rosbag2.Reader(src)
        reader.open()
    except Exception as e:
        raise ImportFormatError(f"{src} is not a readable ROS 2 bag: {e}") from None
    try:
        conns = {c.topic: c.msgtype for c in reader.connections}
        rgb_t = _pick(
            conns,
            (IMAGE, COMPRESSED),
            topics.rgb,
            "colour image (--rgb-topic)",
            prefer=lambda t: "depth" not in t.lower(),
        )
        depth_t = _pick(
            conns,
            (IMAGE, COMPRESSED),
            topics.depth,
            "depth image (--depth-topic)",
            prefer=lambda t: "depth" in t.lower(),
        )
        if rgb_t == depth_t:
            raise ImportFormatError(f"the colour and depth topics are both {rgb_t!r}: name them")
        info_t = _pick(
            conns,
            (INFO,),
            topics.camera_info,
            "camera info (--info-topic)",
            prefer=lambda t: rgb_t.rsplit("/", 2)[0] in t,
            required=options.K is None,
        )
        joints_t = _pick(
            conns, (JOINTS,), topics.joint_states, "joint states (--joints-topic)", required=False
        )
        audio_t = _pick(conns, (AUDIO,), topics.audio, "audio (--audio-topic)", required=False)
        wanted = {rgb_t, depth_t, info_t, joints_t, audio_t} - {None}
        wanted |= {t for t, ty in conns.items() if ty in (TF, AUDIO_INFO)}
        rgb, rgb_s, depth, depth_s, frame_ids = [], [], [], [], []
        joint_s, joint_q, chunks = [], [], []
        K, audio_info, tree = None, None, _TfTree()
        names = (
            kinematics.joint_names
            if kinematics is not None
            else tuple(f"panda_joint{i}" for i in range(1, 8))
        )
        sel = [c for c in reader.connections if c.topic in wanted]
        for conn, _, raw in reader.messages(connections=sel):
            try:
                msg = store.deserialize_cdr(raw, conn.msgtype)
            except Exception as e:
                raise ImportFormatError(
                    f"{src}: a {conn.msgtype} message on {conn.topic} does not decode: {e}"
                ) from None
            where = f"{src}:{conn.topic}"
            if conn.topic == rgb_t:
                img = _decode_image(msg, conn.msgtype, where)
                if img.ndim != 3:
                    raise ImportFormatError(
                        f"{where}: the colour topic holds one-channel images (is it depth?)"
                    )
                rgb.append(img)
                rgb_s.append(_stamp(msg.header))
                frame_ids.append(msg.header.frame_id.lstrip("/"))
            elif conn.topic == depth_t:
                img = _decode_image(msg, conn.msgtype, where)
                if img.ndim != 2:
                    raise ImportFormatError(f"{where}: the depth topic holds colour images")
                depth.append(img)
                depth_s.append(_stamp(msg.header))
            elif conn.topic == info_t and K is None:
                K = np.asarray(msg.k, np.float64).reshape(3, 3)
            elif conn.topic == joints_t:
                pos = dict(zip(msg.name, msg.position, strict=False))
                missing = [n for n in names if n not in pos]
                if missing:
                    raise ImportFormatError(
                        f"{where}: joint states lack {missing}; they name {list(msg.name)}"
                    )
                joint_s.append(_stamp(msg.header))
                joint_q.append([pos[n] for n in names])
            elif conn.topic == audio_t:
                chunks.append((_stamp(msg.header), msg.audio.data))
            elif conn.msgtype == AUDIO_INFO:
                audio_info = msg
            elif conn.msgtype == TF:
                tree.add(msg, static="static" in conn.topic)
    finally:
        reader.close()
    if not rgb:
        raise ImportFormatError(f"{src}: no colour frames on {rgb_t}")
    if options.K is not None:
        K = np.asarray(options.K, np.float64)
    rgb_s = np.array(rgb_s)
    depth_s = np.array(depth_s)
    from tabletop.ingest.checks import check_order

    check_order(f"colour frame ({rgb_t})", rgb_s)
    check_order(f"depth frame ({depth_t})", depth_s)
    pair = match_depth(rgb_s, depth_s, options.max_pair_dt)
    raw_depth = [depth[k] for k in pair]
    if raw_depth[0].dtype == np.uint16:
        scale = 1000.0 if options.depth_scale is None else float(options.depth_scale)
        resolution = min(max(1.0 / scale, 1e-6), 0.01)
    else:
        scale = 1.0 if options.depth_scale is None else float(options.depth_scale)
        resolution = 1e-4
    d = np.stack([(x.astype(np.float64) * (1.0 / scale)).astype(np.float32) for x in raw_depth])
    d[~np.isfinite(d)] = 0.0
    if d.max(initial=0) * (1 / resolution) > 65535:  # far depth (or a unit error the checks name)
        resolution = min(float(d.max()) / 65535 * 1.0001, 0.01)
    rgb = np.stack(rgb)
    if d.shape[1:] != rgb.shape[1:3]:
        raise ImportFormatError(
            f"depth images are {d.shape[2]}x{d.shape[1]}, colour {rgb.shape[2]}x{rgb.shape[1]}: "
            "depth must be registered (aligned) to the colour image"
        )

    cam_frame = frame_ids[0]
    if options.T_hand_cam is not None:
        T_hand_cam = np.asarray(options.T_hand_cam, np.float64)
    else:
        p = tree.path(topics.hand_frame, cam_frame)
        if p is None:
            raise ImportFormatError(
                f"{src}: no TF chain from {topics.hand_frame!r} to the camera frame {cam_frame!r} "
                "(the image header's frame_id): publish the hand-eye calibration on /tf_static "
                "or pass --hand-cam FILE"
            )
        T_hand_cam = tree.chain(p, rgb_s[:1])[0]
    off = options.pose_time_offset
    hand_path = tree.path(topics.world_frame, topics.hand_frame)
    common = dict(
        stamps=rgb_s,
        rgb=rgb,
        depth=d,
        K=K,
        T_hand_cam=T_hand_cam,
        depth_resolution=resolution,
        ee_frame=topics.hand_frame,
        audio=_audio(chunks, audio_info, f"{src}:{audio_t}"),
        meta={"source": "rosbag2", "path": str(src), "rgb_topic": rgb_t, "depth_topic": depth_t},
    )
    jq = np.array(joint_q) if joint_q else None
    js = np.array(joint_s) + off if joint_s else None
    if hand_path is not None and tree.moves(hand_path):
        keys = tree.stamps(hand_path) + off
        from tabletop.ingest.checks import check_clock

        check_order("/tf", keys)
        check_clock("colour frame", rgb_s, "/tf", keys)
        # the chain at the frame stamps (each moving edge interpolated on its own stamps)
        T_world_hand = tree.chain(hand_path, rgb_s - off)
        rec = assemble(
            **common,
            pose_stamps=rgb_s,
            pose_name="/tf",
            hand_poses=T_world_hand,
            joint_stamps=js,
            joints=jq,
            joint_names=names if jq is not None else (),
        )
        return rec, "hand"
    if jq is None:
        raise ImportFormatError(
            f"{src}: no poses: /tf does not move {topics.hand_frame!r} in {topics.world_frame!r} "
            "and there is no JointState topic"
        )
    if kinematics is None:
        raise ImportFormatError("joint states need the arm's kinematics to give hand poses")
    rec = assemble(
        **common,
        pose_stamps=js,
        pose_name=f"joint state ({joints_t})",
        joint_stamps=js,
        joints=jq,
        joint_names=names,
        kinematics=kinematics,
    )
    return rec, "joints"
