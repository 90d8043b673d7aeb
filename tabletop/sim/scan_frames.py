"""What the table's and the rooms' scans share: frames captured at a rate of simulated time,
sound episodes inserted into the audio track, and the recording assembled.

A scan moves its robot its own way (the arm's joints set along retimed sweeps, the base's
wheels driven with physics on) and says, per frame, where the robot is through a
:class:`FrameState` callable; a :class:`FrameRecorder` renders and keeps the frames, and
:func:`assemble_recording` turns them, the segments and the episodes' places into a
:class:`~tabletop.recording.Recording` with its ground truth.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from tabletop.recording import Recording, Segment
from tabletop.sim.ground_truth import GroundTruth, SoundEventTruth
from tabletop.sim.noise import apply_noise

__all__ = ["FrameRecorder", "FrameState", "assemble_recording"]


@dataclass(frozen=True)
class FrameState:
    """Where the robot is at a frame."""

    T_world_hand: np.ndarray
    """(4, 4) [m] the recorded pose of the frame the camera rides on (what the robot
    believes: the arm's forward kinematics, the base's odometry)."""
    T_world_hand_true: np.ndarray
    """(4, 4) [m] where the simulator has it; the camera renders from here."""
    joints: Sequence[float]
    """The robot's joint positions (the arm's 7 joints, the base's 2 wheels)."""
    mic: np.ndarray
    """(3,) [m] the microphone's position in the world."""


class FrameRecorder:
    """Renders the world's camera and keeps a frame's images and :class:`FrameState`.

    A scan that moves in frame steps calls :meth:`capture` at each; one that steps physics
    calls the recorder with the simulated time after every step (``on_physics_step``), and a
    frame is captured whenever the time reaches the next frame's (``rate_hz``, from ``t0``).
    Each frame is labelled with :attr:`segment` (name, kind) at its capture.

    Args:
        world: the world rendered (a :class:`~tabletop.sim.world.PyBulletWorld`).
        rate_hz: frame rate [Hz] of simulated time.
        state: where the robot is now.
        progress: called with the number of frames after each one.
        t0: simulated time [s] of frame 0.
    """

    def __init__(
        self,
        world,
        rate_hz: float,
        state: Callable[[], FrameState],
        progress: Callable[[int], None] | None = None,
        t0: float = 0.0,
    ) -> None:
        self.world = world
        self.rate = rate_hz
        self.state = state
        self.progress = progress
        self.t0 = t0
        self.frames: dict[str, list] = {
            k: [] for k in ("rgb", "depth", "seg", "pose", "true", "joints", "mic")
        }
        self.labels: list[tuple[str, str]] = []
        self.segment = ("start", "transit")
        self.render_s = 0.0

    def __call__(self, t: float) -> None:
        if t - self.t0 + 1e-9 < len(self.labels) / self.rate:
            return
        self.capture()

    def capture(self) -> None:
        """Render and keep a frame where the robot is now."""
        s = self.state()
        t1 = time.perf_counter()
        img = self.world.render(s.T_world_hand_true @ self.world.camera.T_hand_cam)
        self.render_s += time.perf_counter() - t1
        f = self.frames
        f["rgb"].append(img.rgb)
        f["depth"].append(img.depth)
        f["seg"].append(img.segmentation)
        f["pose"].append(s.T_world_hand)
        f["true"].append(s.T_world_hand_true)
        f["joints"].append(s.joints)
        f["mic"].append(s.mic)
        self.labels.append(self.segment)
        if self.progress is not None:
            self.progress(len(self.labels))

    def segments(self) -> list[Segment]:
        """The runs of equally labelled frames."""
        out, start = [], 0
        for i in range(1, len(self.labels) + 1):
            if i == len(self.labels) or self.labels[i] != self.labels[start]:
                name, kind = self.labels[start]
                out.append(Segment(name, kind, start, i))
                start = i
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        """The frames as arrays (the recorder's lists are emptied: one list at a time becomes
        an array and is freed, as a scan's images are gigabytes)."""
        return {k: np.array(self.frames.pop(k)) for k in list(self.frames)}


def assemble_recording(
    frames: dict[str, np.ndarray],
    *,
    config,
    segments: Sequence[Segment],
    episode_centers: Sequence,
    ground_truth: GroundTruth,
    K: np.ndarray,
    T_hand_cam: np.ndarray,
    T_hand_mic: np.ndarray,
    meta: dict,
    annotate_events: Callable[[list[dict]], None] | None = None,
    **fields,
) -> Recording:
    """The recording of a scan's frames (:meth:`FrameRecorder.arrays`; images popped): frame
    times at ``config.rate_hz``, a sound-bank clip inserted at each of ``episode_centers``
    (x, y) when ``config.episodes`` (``annotate_events`` may amend the events), the events
    added to the ground truth, ``config.noise`` applied. ``fields``: further
    :class:`~tabletop.recording.Recording` fields (``T_world_hand_true``, ``ee_frame``, ...).
    """
    from tabletop.sim.sound_insertion import insert_sounds

    n = len(frames["pose"])
    timestamps = np.arange(n) / config.rate_hz
    audio, audio_rate, events = None, 16000, []
    if config.episodes:
        audio, audio_rate, events = insert_sounds(
            timestamps, frames["mic"], segments, episode_centers, config
        )
        if annotate_events is not None:
            annotate_events(events)
    ground_truth = replace(
        ground_truth,
        sound_events=tuple(
            SoundEventTruth.from_dict(e, f"sound_events[{i}]") for i, e in enumerate(events)
        ),
    )
    recording = Recording(
        timestamps=timestamps,
        rgb=frames.pop("rgb"),
        depth=frames.pop("depth"),
        joint_positions=frames["joints"],
        T_world_hand=frames["pose"],
        K=K,
        T_hand_cam=T_hand_cam,
        T_hand_mic=T_hand_mic,
        depth_resolution=config.camera.depth_resolution,
        audio=audio,
        audio_rate=audio_rate,
        segments=tuple(segments),
        segmentation=frames.pop("seg"),
        ground_truth=ground_truth.to_dict(),  # the recording keeps the JSON form
        meta=meta,
        **fields,
    )
    if config.noise.any:
        recording = apply_noise(recording, config.noise)
    return recording
