"""Heatmaps: the query layer's value. A :class:`Heatmap` is a dense float32 array in [0, 1] over
the map's grid, with what produced it and whether it found anything, as in the paper.

Object module (3D, Euclidean):  H_o(p) = max(1 - eps * d_min(p), 0), d_min = distance from p to
the nearest target voxel, computed with a Euclidean distance transform (not an O(N*M) loop).
Area/audio modules (top-down):  H(p) = max(max_i (s_i - eps * d_xy(p, p_i)), 0).
Visual module:                  H_v(p) = max(1 - eps * d_xy(p, p_v), 0).
Fusion is the element-wise product (:func:`fuse`, or ``a * b``); the target of a heatmap is
chosen by :mod:`tabletop.mapping.targets` (``get_max_pos_3d``).

Decay rates ``eps`` are in 1/m, so a heatmap means the same at any voxel size. Presets, tuned for
a tabletop: ``MAJOR_DECAY`` = 10 /m (heat reaches 0 at 10 cm: "where exactly"), and
``AUX_DECAY`` = 2.5 /m (0 at 40 cm: "near", a broad constraint). The paper used 2 /m and
0.2 /m for rooms (0.1 and 0.01 per 5 cm voxel).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import ndimage

from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid, mask_box

__all__ = [
    "AUX_DECAY",
    "MAJOR_DECAY",
    "MODALITIES",
    "Heatmap",
    "Judge",
    "fuse",
    "point_heatmap_3d",
    "point_heatmap_3d_at",
    "scored_points_heatmap_xy",
    "sharpest_part",
]

Judge = Callable[[str, float], tuple[float, bool]]
"""``judge(modality, margin) -> (confidence, found)``: how a module turns its evidence into a
verdict (the map's calibration, :meth:`tabletop.mapping.avlmap.AVLMap.judge`)."""

#: What produced a heatmap: one of the four modules, or a product of several ("fused").
MODALITIES = ("object", "sound", "area", "image", "fused")

MAJOR_DECAY = 10.0  # [1/m]
AUX_DECAY = 2.5  # [1/m]


def _check_decay(decay: float) -> float:
    if not (np.isfinite(decay) and decay > 0):
        raise ConfigError(f"decay must be a positive rate in 1/m, got {decay}")
    return float(decay)


def point_heatmap_3d(grid: VoxelGrid, target_mask: np.ndarray, decay: float) -> np.ndarray:
    """H(p) = max(1 - decay * d_min(p), 0) with d_min the distance [m] to the nearest target
    voxel centre; ``target_mask`` is a boolean array of the grid's shape."""
    target_mask = np.asarray(target_mask, bool)
    if target_mask.shape != grid.shape:
        raise ConfigError(f"target mask {target_mask.shape} is not the grid's {grid.shape}")
    box = mask_box(target_mask)
    if box is None:
        _check_decay(decay)
        return np.zeros(grid.shape, np.float32)
    return _heat_around(grid, target_mask, box, decay)


def point_heatmap_3d_at(grid: VoxelGrid, idx: np.ndarray, decay: float) -> np.ndarray:
    """:func:`point_heatmap_3d` of the target voxels ``idx`` ((N, 3) grid indices), without a
    pass over the whole grid to find them."""
    idx = np.asarray(idx, np.intp).reshape(-1, 3)
    if not len(idx):
        _check_decay(decay)
        return np.zeros(grid.shape, np.float32)
    if (idx < 0).any() or (idx >= np.array(grid.shape)).any():
        raise ConfigError(f"target voxel indices outside the grid {grid.shape}")
    lo, hi = idx.min(axis=0), idx.max(axis=0) + 1
    box = tuple(slice(int(a), int(b)) for a, b in zip(lo, hi, strict=True))
    mask = np.zeros(grid.shape, bool)
    mask[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    return _heat_around(grid, mask, box, decay)


def _heat_around(grid: VoxelGrid, target_mask, box, decay: float) -> np.ndarray:
    decay = _check_decay(decay)
    # Only voxels within 1/decay of a target get heat: work in that sub-box.
    r = int(np.ceil(1.0 / decay / grid.voxel_size)) + 1
    lo = [max(b.start - r, 0) for b in box]
    hi = [min(b.stop + r, n) for b, n in zip(box, grid.shape, strict=True)]
    sub = ~target_mask[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]]
    d = ndimage.distance_transform_edt(sub, sampling=grid.voxel_size)
    out = np.zeros(grid.shape, np.float32)
    out[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]] = np.maximum(1.0 - decay * d, 0.0)
    return out


def scored_points_heatmap_xy(
    grid: VoxelGrid, points_xy: np.ndarray, scores: np.ndarray, decay: float
) -> np.ndarray:
    """H(p) = max(max_i (s_i - decay * d_xy(p, p_i)), 0), constant along z.

    ``points_xy`` (M, 2) [m], ``scores`` (M,) in [0, 1].
    """
    decay = _check_decay(decay)
    pts = np.asarray(points_xy, np.float64).reshape(-1, 2)
    s = np.asarray(scores, np.float64).reshape(-1)
    if len(pts) != len(s):
        raise ConfigError(f"{len(pts)} points but {len(s)} scores")
    xs, ys, _ = grid.axes()
    best = np.zeros((len(xs), len(ys)))
    # Points with a score that cannot beat the current floor anywhere are skipped; the rest
    # are applied in chunks, vectorised over the grid.
    order = np.argsort(-s)
    for start in range(0, len(order), 64):
        chunk = order[start : start + 64]
        chunk = chunk[s[chunk] > 0]
        if not len(chunk):
            break
        dx = xs[None, :, None] - pts[chunk, 0, None, None]
        dy = ys[None, None, :] - pts[chunk, 1, None, None]
        best = np.maximum(best, (s[chunk, None, None] - decay * np.hypot(dx, dy)).max(axis=0))
    return np.repeat(np.clip(best, 0, 1)[:, :, None], grid.shape[2], axis=2).astype(np.float32)


@dataclass(frozen=True, eq=False)
class Heatmap:
    """A query's heatmap over a grid, with what produced it (a value; its array is read-only).

    ``found`` is the query's verdict: False means the map holds nothing that matches (``reason``
    says why) and the values carry no target. ``a * b`` fuses two heatmaps (:func:`fuse`);
    ``a == b`` compares what they say, values included (:meth:`__eq__`), and equal heatmaps
    hash alike.
    """

    grid: VoxelGrid
    values: np.ndarray  # grid.shape float32 in [0, 1], read-only
    query: str
    modality: str  # one of MODALITIES
    decay: float | None  # [1/m]; None for a fused heatmap
    confidence: float  # calibrated, in [0, 1]
    found: bool
    reason: str = ""
    evidence: float | None = None
    """The raw margin the confidence was computed from (see :mod:`tabletop.mapping.calibration`);
    None when nothing matched at all."""
    target: np.ndarray | None = field(default=None, repr=False)
    """(3,) [m] world frame: the point the query names, for a module that locates one point
    (image: the surface point the image shows at its centre); else None."""
    parts: tuple[Heatmap, ...] = field(default=(), repr=False)
    """The heatmaps a fused heatmap is the product of (empty for a module's heatmap)."""

    def __post_init__(self) -> None:
        if not isinstance(self.grid, VoxelGrid):
            raise ConfigError(f"Heatmap.grid must be a VoxelGrid, got {type(self.grid).__name__}")
        if self.modality not in MODALITIES:
            raise ConfigError(f"unknown modality {self.modality!r}; valid: {list(MODALITIES)}")
        v = np.asarray(self.values)
        if v.shape != self.grid.shape:
            raise ConfigError(f"heatmap {v.shape} is not on the grid {self.grid.shape}")
        if v.dtype != np.float32 or v.flags.writeable:
            v = np.array(v, dtype=np.float32)
        # NaN makes the minimum and the maximum NaN, and inf is one of them: two passes
        lo, hi = (float(v.min()), float(v.max())) if v.size else (0.0, 0.0)
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise ConfigError(f"heatmap {self.query!r} has non-finite values (NaN or inf)")
        if lo < 0 or hi > 1:
            raise ConfigError(
                f"heatmap {self.query!r} values must be in [0, 1], got [{lo:.3g}, {hi:.3g}]"
            )
        v.setflags(write=False)
        object.__setattr__(self, "values", v)
        object.__setattr__(self, "_peak", max(hi, 0.0))
        if not 0.0 <= float(self.confidence) <= 1.0:
            raise ConfigError(f"confidence must be in [0, 1], got {self.confidence}")
        if self.target is not None:
            t = np.array(self.target, dtype=np.float64)
            if t.shape != (3,) or not np.all(np.isfinite(t)):
                raise ConfigError(f"target must be a finite (3,) point [m], got {t.tolist()}")
            t.setflags(write=False)
            object.__setattr__(self, "target", t)

    @classmethod
    def not_found(
        cls,
        grid: VoxelGrid,
        query: str,
        modality: str,
        decay: float | None,
        reason: str,
        evidence: float | None = None,
    ) -> Heatmap:
        """A not-found result: all zeros, confidence 0, with the reason."""
        return cls(
            grid,
            np.zeros(grid.shape, np.float32),
            query,
            modality,
            decay,
            0.0,
            False,
            reason,
            evidence,
        )

    @property
    def peak(self) -> float:
        """The largest value (found when the heatmap was made: its values are read-only)."""
        return self._peak

    def with_values(self, values: np.ndarray, **changes) -> Heatmap:
        """A copy with other values (and any other field changed)."""
        return replace(self, values=values, **changes)

    def __mul__(self, other: object) -> Heatmap:
        if not isinstance(other, Heatmap):
            raise TypeError(_arithmetic_refused("*", other))
        return fuse(self, other)

    def __rmul__(self, other: object) -> Heatmap:
        raise TypeError(_arithmetic_refused("*", other))

    def _refuse(self, other: object, op: str = "") -> Heatmap:
        raise TypeError(_arithmetic_refused(op, other))

    __add__ = __radd__ = lambda self, other: self._refuse(other, "+")
    __sub__ = __rsub__ = lambda self, other: self._refuse(other, "-")
    __truediv__ = __rtruediv__ = lambda self, other: self._refuse(other, "/")
    __floordiv__ = __rfloordiv__ = lambda self, other: self._refuse(other, "//")
    __pow__ = __rpow__ = lambda self, other: self._refuse(other, "**")
    __matmul__ = __rmatmul__ = lambda self, other: self._refuse(other, "@")
    __lt__ = lambda self, other: self._refuse(other, "<")  # noqa: E731
    __le__ = lambda self, other: self._refuse(other, "<=")  # noqa: E731
    __gt__ = lambda self, other: self._refuse(other, ">")  # noqa: E731
    __ge__ = lambda self, other: self._refuse(other, ">=")  # noqa: E731
    __neg__ = __pos__ = __abs__ = lambda self: self._refuse(None, "(unary)")

    def __eq__(self, other: object) -> bool:
        """Two heatmaps are equal when all they say is: grid, values (exactly: compare heat
        within a tolerance with ``numpy.allclose(a.values, b.values)``), query, modality,
        decay, confidence, verdict, reason, evidence, target and parts. A heatmap is never
        compared with a number or an array (refused by name: compare ``h.values``)."""
        if isinstance(other, Heatmap):
            return self is other or (
                self.grid == other.grid
                and all(getattr(self, f) == getattr(other, f) for f in _SAID)
                and np.array_equal(self.values, other.values)
                and (
                    (self.target is None and other.target is None)
                    or (
                        self.target is not None
                        and other.target is not None
                        and np.array_equal(self.target, other.target)
                    )
                )
                and self.parts == other.parts
            )
        if isinstance(other, (np.ndarray, np.generic, int, float)) and not isinstance(other, bool):
            raise TypeError(_compare_refused(other))
        return NotImplemented

    def __hash__(self) -> int:
        # of fields equal heatmaps share (a heatmap is a value: its arrays are read-only)
        return hash((self.grid, self.query, self.modality, self.found, self.values.shape))

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        return np.array(self.values, dtype=dtype)

    # numpy's operators defer to the heatmap's own (an array or numpy scalar times a heatmap is
    # refused by name, not turned into a bare array that has lost what the heatmap says)
    __array_ufunc__ = None


#: The fields besides the arrays that :meth:`Heatmap.__eq__` compares.
_SAID = ("query", "modality", "decay", "confidence", "found", "reason", "evidence")


def _compare_refused(other: object) -> str:
    """Why a heatmap is not compared with a number or an array."""
    what = type(other).__name__
    if isinstance(other, np.ndarray):
        what += f" of shape {other.shape}"
    return (
        f"Heatmap == {what}: a heatmap equals only another Heatmap (grid, values and what "
        "produced them); to compare its heat, use h.values (a float32 array of the grid's "
        "shape): h.values == x, or numpy.allclose(a.values, b.values) for two heatmaps"
    )


def _arithmetic_refused(op: str, other: object) -> str:
    """Why heatmap arithmetic other than ``Heatmap * Heatmap`` is refused."""
    what = "" if other is None else type(other).__name__
    if isinstance(other, np.ndarray):
        what += f" of shape {other.shape}"
    return (
        f"Heatmap {op} {what}: the only arithmetic on heatmaps is a * b between two Heatmaps "
        "of the same grid (it fuses them, tabletop.mapping.heatmaps.fuse); to scale or mask "
        "the heat, compute on h.values (a read-only float32 array of the grid's shape) and "
        "make a heatmap with h.with_values(new_values)"
    )


#: Heat a broad part lends beyond its reach, at the distance where its linear heat ends
#: (:func:`fuse`): far below any heat within reach.
NEAR_TAIL = 1e-3


def _product(values) -> np.ndarray:
    out = np.array(values[0], np.float32)
    for v in values[1:]:
        out *= v
    return out


def sharpest_part(parts) -> int:
    """Index of the sharpest of a fused heatmap's ``parts``: the largest decay (the primary
    part, an object's "where exactly"); the first of equals."""
    return int(np.argmax([h.decay if h.decay is not None else 0.0 for h in parts]))


def _nearest_product(parts: list[Heatmap]) -> np.ndarray:
    """The product of ``parts`` where every part but the sharpest (:func:`sharpest_part`) and
    the ``area`` parts lends :data:`NEAR_TAIL` heat beyond its reach, fading with the distance
    from it at the part's decay rate."""
    sharp = sharpest_part(parts)
    values = []
    for i, h in enumerate(parts):
        v = np.asarray(h.values, np.float32)
        if i == sharp or h.modality == "area" or h.decay is None or not (v > 0).any():
            values.append(v)
            continue
        d = ndimage.distance_transform_edt(~(v > 0), sampling=h.grid.voxel_size)
        values.append(v + np.float32(NEAR_TAIL) * np.exp(-h.decay * d).astype(np.float32))
    return _product(values)


def _describe(h: Heatmap) -> str:
    return h.query if h.modality == "fused" else f"{h.modality} {h.query!r}"


def fuse(*heatmaps: Heatmap) -> Heatmap:
    """The element-wise product of heatmaps of one grid (the paper's cross-modal reasoning).

    The result is found when every part is found and some place has heat from every part; its
    confidence is the smallest part's; ``parts`` lists the (flattened) factors.

    "Near" is relative: where the sharpest part's heat lies beyond the reach of a broad one
    (a sound heard 0.6 m from every mug, beyond the auxiliary decay's 0.4 m), the product is
    taken with a faint tail (:data:`NEAR_TAIL`, decaying at each broad part's own rate) beyond
    the broad parts' reach: the mug nearest the sound is the answer, not "not found". An
    ``area`` part has no tail: a place on the table contains, it is not near.
    """
    if not heatmaps:
        raise ConfigError("fuse needs at least one heatmap")
    bad = [type(h).__name__ for h in heatmaps if not isinstance(h, Heatmap)]
    if bad:
        raise ConfigError(
            f"fuse takes Heatmap values (from a map's queries), got {bad}; wrap an array with "
            "Heatmap(grid, values, ...)"
        )
    grid = heatmaps[0].grid
    for h in heatmaps[1:]:
        if h.grid != grid:
            raise ConfigError(f"heatmaps of different grids: {grid} vs {h.grid}")
    parts: list[Heatmap] = []
    for h in heatmaps:
        parts += list(h.parts) if h.modality == "fused" and h.parts else [h]
    out = _product([h.values for h in parts])
    missing = [h for h in parts if not h.found]
    query = " * ".join(_describe(h) for h in parts)
    reason = ""
    if missing:
        reason = "; ".join(f"{_describe(h)}: {h.reason or 'not found'}" for h in missing)
    elif not out.max(initial=0.0) > 0:
        out = _nearest_product(parts)
        if not out.max(initial=0.0) > 0:
            reason = "no place in the map has heat from every part"
    return Heatmap(
        grid,
        out,
        query,
        "fused",
        None,
        min(h.confidence for h in parts) if not reason else 0.0,
        not reason,
        reason,
        parts=tuple(parts),
    )
