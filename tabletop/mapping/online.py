"""Online mapping: a recording's frames fed to a map as a camera delivers them, at the recorded
rate, with how far the map lags behind the camera.

Frame ``i`` arrives at ``start + (t_i - t_0) / rate`` (``t``: the recording's timestamps).
The map fuses each frame when it arrives or, when it is still busy with an earlier one, as
soon as it is free; its *lag* is the time from a frame's arrival until it is fused. Under
``drop="none"`` every frame is fused however late; under ``drop="late"`` a frame is skipped
when the next one has already arrived by the time it could start (the map stays with the
camera and fuses the newest frame; the last frame is never skipped). Nothing else drops a
frame: ``MapConfig.frame_step`` (fuse every n-th frame's pixels) and the visual module's
stride are the map's own config, as in a batch build.

The poses are the recorded ones: the table registration of a batch build
(:mod:`~tabletop.mapping.registration`) fits corrections on the whole scan, which an online
map does not have. The audio track is segmented once the frames are in.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tabletop.errors import ConfigError, RecordingError

__all__ = ["DROP_POLICIES", "ReplayReport", "replay_online"]

#: What a map does with a frame it cannot start before the next one arrives.
DROP_POLICIES = ("none", "late")


@dataclass(frozen=True)
class ReplayReport:
    """How an online replay kept up (times in seconds)."""

    frames: int
    """Frames the recording delivered."""
    fused: int
    """Frames given to the map."""
    dropped: int
    """Frames skipped under ``drop="late"``."""
    camera_fps: float
    """The rate frames arrived at (the recording's rate times ``rate``)."""
    lag_median_s: float
    lag_p95_s: float
    lag_max_s: float
    """From a fused frame's arrival until the map had fused it."""
    wall_s: float

    @property
    def keeps_up(self) -> bool:
        """Every frame fused, and 95 % of them within one frame period of their arrival."""
        return self.dropped == 0 and self.lag_p95_s <= 1.0 / self.camera_fps

    def as_dict(self) -> dict:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        return {**d, "keeps_up": self.keeps_up}


def replay_online(
    m,
    recording,
    *,
    rate: float = 1.0,
    drop: str = "none",
    progress: Callable[[int, int], None] | None = None,
    clock: Callable[[], float] = time.perf_counter,
) -> ReplayReport:
    """Feed ``recording``'s frames to the map ``m`` (:meth:`AVLMap.empty`) as they arrive at
    ``rate`` times the recorded rate (see the module docstring); then its audio. Returns how
    the map kept up. ``clock``: the time source the arrivals are scheduled on."""
    if drop not in DROP_POLICIES:
        raise ConfigError(f"drop must be one of {list(DROP_POLICIES)}, got {drop!r}")
    if isinstance(rate, bool) or not isinstance(rate, int | float) or not 0 < rate <= 1e6:
        raise ConfigError(f"rate must be a number in (0, 1e6] (1: as recorded), got {rate!r}")
    n = len(recording)
    if n == 0:
        raise RecordingError("the recording holds no frame to replay")
    ts = np.asarray(recording.timestamps, float)  # increasing: a Recording checks them
    arrive_in = (ts - ts[0]) / float(rate)
    T_hand = np.asarray(recording.T_world_hand)
    lags: list[float] = []
    dropped = 0
    start = clock()
    for i in range(n):
        now = clock() - start
        if now < arrive_in[i]:
            time.sleep(arrive_in[i] - now)
        elif drop == "late" and i + 1 < n and now >= arrive_in[i + 1]:
            dropped += 1  # the next frame is already here: the map takes the newer
            continue
        m.add_recorded_frame(recording, i, T_hand[i])
        lags.append(clock() - start - arrive_in[i])
        if progress is not None:
            progress(i + 1, n)
    wall = clock() - start
    m.add_recorded_audio(recording, T_hand)
    period = (ts[-1] - ts[0]) / (n - 1) / rate if n > 1 else 1.0
    lag = np.asarray(lags)
    return ReplayReport(
        frames=n,
        fused=len(lags),
        dropped=dropped,
        camera_fps=1.0 / period,
        lag_median_s=float(np.median(lag)),
        lag_p95_s=float(np.percentile(lag, 95)),
        lag_max_s=float(lag.max()),
        wall_s=wall,
    )
