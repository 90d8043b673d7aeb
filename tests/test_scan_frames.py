"""The scan loop the table's and the rooms' scans share: frames at a rate of simulated time,
labelled segments, and one world base under both worlds."""

import numpy as np

from tabletop.sim.room_world import RoomWorld
from tabletop.sim.scan_frames import FrameRecorder, FrameState
from tabletop.sim.world import CameraImage, PyBulletWorld, SimWorld


class _World:
    """A stand-in world: renders a frame whose pixels say how many frames came before."""

    class camera:
        T_hand_cam = np.eye(4)

    def __init__(self) -> None:
        self.rendered = 0

    def render(self, T_world_cam):
        self.rendered += 1
        v = self.rendered
        return CameraImage(
            rgb=np.full((2, 3, 3), v, np.uint8),
            depth=np.full((2, 3), v, np.float32),
            segmentation=np.zeros((2, 3), np.uint16),
        )


def _state() -> FrameState:
    T = np.eye(4)
    return FrameState(T, T, (0.0, 0.0), np.zeros(3))


def test_frames_are_captured_at_the_rate_of_simulated_time():
    counts = []
    rec = FrameRecorder(_World(), 10.0, _state, counts.append, t0=1.0)
    for k in range(0, 100):  # physics at 100 Hz for 1 s from t0
        rec(1.0 + k / 100)
    assert len(rec.labels) == 10 and counts == list(range(1, 11))
    f = rec.arrays()
    assert f["rgb"].shape == (10, 2, 3, 3) and f["rgb"].dtype == np.uint8
    assert f["pose"].shape == (10, 4, 4) and f["joints"].shape == (10, 2)
    assert rec.frames == {}


def test_segments_are_runs_of_equal_labels():
    rec = FrameRecorder(_World(), 10.0, _state)
    for label in [("a", "transit")] * 2 + [("b", "episode")] * 3 + [("a", "transit")]:
        rec.segment = label
        rec.capture()
    segs = [(s.name, s.kind, s.start, s.stop) for s in rec.segments()]
    assert segs == [("a", "transit", 0, 2), ("b", "episode", 2, 5), ("a", "transit", 5, 6)]


def test_both_worlds_share_one_base():
    assert issubclass(SimWorld, PyBulletWorld) and issubclass(RoomWorld, PyBulletWorld)
    for name in ("link_pose", "T_world_cam", "render", "ground_truth", "close", "__exit__"):
        assert getattr(SimWorld, name) is getattr(RoomWorld, name), name
