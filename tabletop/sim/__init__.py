"""Simulation: tabletop scenes, the Panda with its wrist RGB-D camera, teleop-style scans with
inserted audio, the sound bank, and recordings on disk; rooms with the wheeled base and its
scans."""

from tabletop.recording import (
    FORMAT_VERSION,
    Frame,
    Recording,
    Segment,
    load_recording,
    save_recording,
)
from tabletop.sim.camera import CameraIntrinsics, WristCameraConfig
from tabletop.sim.catalog import COLORS, OBJECT_KINDS, ObjectKind
from tabletop.sim.esc50 import load_esc50
from tabletop.sim.ground_truth import (
    AreaTruth,
    FurnitureTruth,
    GroundTruth,
    GroundTruthError,
    NotInGroundTruth,
    ObjectTruth,
    SoundEventTruth,
    TableTruth,
)
from tabletop.sim.noise import NoiseConfig, apply_noise
from tabletop.sim.room import (
    FurnitureSpec,
    RoomSpec,
    StartPose,
    generate_room,
    list_default_rooms,
    load_room_spec,
)
from tabletop.sim.room_scan import RoomScanConfig, RoomScanStats, run_room_scan, scan_room
from tabletop.sim.room_world import PyBulletBaseDriver, RoomWorld, mast_camera_config
from tabletop.sim.scan import ScanConfig, ScanStats, plan_scan, run_scan
from tabletop.sim.scene import (
    AreaSpec,
    ObjectSpec,
    RandomSpec,
    SceneSpec,
    TableSpec,
    list_default_scenes,
    load_scene_spec,
)
from tabletop.sim.sound_bank import SoundBank, SoundClip
from tabletop.sim.world import CameraImage, SimWorld

__all__ = [
    "COLORS",
    "FORMAT_VERSION",
    "OBJECT_KINDS",
    "AreaSpec",
    "AreaTruth",
    "CameraImage",
    "CameraIntrinsics",
    "Frame",
    "FurnitureSpec",
    "FurnitureTruth",
    "GroundTruth",
    "GroundTruthError",
    "NoiseConfig",
    "NotInGroundTruth",
    "ObjectKind",
    "ObjectSpec",
    "ObjectTruth",
    "PyBulletBaseDriver",
    "RandomSpec",
    "Recording",
    "RoomScanConfig",
    "RoomScanStats",
    "RoomSpec",
    "RoomWorld",
    "ScanConfig",
    "ScanStats",
    "SceneSpec",
    "Segment",
    "SimWorld",
    "SoundBank",
    "SoundClip",
    "SoundEventTruth",
    "StartPose",
    "TableSpec",
    "TableTruth",
    "WristCameraConfig",
    "apply_noise",
    "generate_room",
    "list_default_rooms",
    "list_default_scenes",
    "load_esc50",
    "load_recording",
    "load_room_spec",
    "load_scene_spec",
    "mast_camera_config",
    "plan_scan",
    "run_room_scan",
    "run_scan",
    "save_recording",
    "scan_room",
]
