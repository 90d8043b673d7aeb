"""Simulation: tabletop scenes, the Panda with its wrist RGB-D camera, teleop-style scans with
inserted audio, the sound bank, and recordings on disk."""

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
    GroundTruth,
    GroundTruthError,
    NotInGroundTruth,
    ObjectTruth,
    SoundEventTruth,
    TableTruth,
)
from tabletop.sim.noise import NoiseConfig, apply_noise
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
    "GroundTruth",
    "GroundTruthError",
    "NoiseConfig",
    "NotInGroundTruth",
    "ObjectKind",
    "ObjectSpec",
    "ObjectTruth",
    "RandomSpec",
    "Recording",
    "ScanConfig",
    "ScanStats",
    "SceneSpec",
    "Segment",
    "SimWorld",
    "SoundBank",
    "SoundClip",
    "SoundEventTruth",
    "TableSpec",
    "TableTruth",
    "WristCameraConfig",
    "apply_noise",
    "list_default_scenes",
    "load_esc50",
    "load_recording",
    "load_scene_spec",
    "plan_scan",
    "run_scan",
    "save_recording",
]
