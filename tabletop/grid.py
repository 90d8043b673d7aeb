"""The workspace grid: a bounded box of cubic voxels in the world (= robot base) frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tabletop.errors import ConfigError

__all__ = ["VoxelGrid", "box_argwhere", "mask_box"]


MAX_CELLS = 50_000_000
"""The most cells a grid may have (its index table takes 4 bytes a cell)."""


#: Steps of every ray still going that :meth:`VoxelGrid.march` samples at a time.
MARCH_CHUNK = 32


@dataclass(frozen=True)
class VoxelGrid:
    """Voxels of ``voxel_size`` [m] filling ``[lower, upper)`` [m], world frame.

    Voxel (i, j, k) covers ``lower + [i, i+1) * voxel_size`` on x (and likewise y, z); its centre
    is ``lower + (i + 0.5) * voxel_size``. Linear index = ``(i * ny + j) * nz + k``.
    """

    lower: tuple[float, float, float] = (-0.20, -0.60, -0.02)
    upper: tuple[float, float, float] = (0.80, 0.60, 0.34)
    voxel_size: float = 0.01

    def __post_init__(self) -> None:
        def numbers(v) -> bool:
            return isinstance(v, (tuple, list, np.ndarray)) and all(
                isinstance(x, (int, float, np.number)) and not isinstance(x, bool) for x in v
            )

        if not numbers(self.lower) or not numbers(self.upper):
            raise ConfigError(
                f"grid bounds must be 3-vectors of numbers [m], got {self.lower!r}, {self.upper!r}"
            )
        lo, hi = np.asarray(self.lower, float), np.asarray(self.upper, float)
        if (
            lo.shape != (3,)
            or hi.shape != (3,)
            or not np.all(np.isfinite(lo) & np.isfinite(hi))
            or np.any(hi <= lo)
        ):
            raise ConfigError(
                f"grid bounds must be finite 3-vectors with lower < upper, got {lo}, {hi}"
            )
        v = self.voxel_size
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.001 <= v <= 0.2:
            raise ConfigError(f"voxel_size must be in [0.001, 0.2] m, got {v!r}")
        object.__setattr__(self, "lower", tuple(float(x) for x in lo))
        object.__setattr__(self, "upper", tuple(float(x) for x in hi))
        if self.size > MAX_CELLS:
            raise ConfigError(
                f"a grid of {lo.tolist()} .. {hi.tolist()} m at {v} m has {self.size:.3g} cells; "
                f"at most {MAX_CELLS:.0e} (a larger box or coarser voxels)"
            )

    @property
    def shape(self) -> tuple[int, int, int]:
        ext = (np.asarray(self.upper) - np.asarray(self.lower)) / self.voxel_size
        n = np.ceil(ext - 1e-9).astype(int)
        return int(n[0]), int(n[1]), int(n[2])

    @property
    def size(self) -> int:
        nx, ny, nz = self.shape
        return nx * ny * nz

    def world_to_index(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) int voxel indices of (N, 3) points [m], and a mask of those inside the grid."""
        idx = np.floor((np.asarray(points, float) - self.lower) / self.voxel_size).astype(np.int64)
        # one comparison per axis: a negative index read as unsigned is larger than any shape
        u = idx.view(np.uint64)
        nx, ny, nz = self.shape
        inside = (u[:, 0] < nx) & (u[:, 1] < ny) & (u[:, 2] < nz)
        return idx, inside

    def linear(self, idx: np.ndarray) -> np.ndarray:
        """Linear indices of (N, 3) voxel indices."""
        _, ny, nz = self.shape
        return (idx[:, 0] * ny + idx[:, 1]) * nz + idx[:, 2]

    def unravel(self, lin: np.ndarray) -> np.ndarray:
        """(N, 3) voxel indices of linear indices."""
        return np.stack(np.unravel_index(np.asarray(lin), self.shape), axis=1)

    def centers(self, idx: np.ndarray) -> np.ndarray:
        """(N, 3) voxel centres [m] of (N, 3) voxel indices."""
        return np.asarray(self.lower) + (np.asarray(idx) + 0.5) * self.voxel_size

    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Voxel-centre coordinates [m] along x, y and z."""
        return tuple(
            self.lower[a] + (np.arange(n) + 0.5) * self.voxel_size for a, n in enumerate(self.shape)
        )

    def march(
        self, origin: np.ndarray, rays: np.ndarray, occupied: np.ndarray, max_dist
    ) -> tuple[np.ndarray, np.ndarray]:
        """First occupied voxel along each ray: ``rays`` (R, 3) unit directions from
        ``origin`` (3,) [m] are sampled in half-voxel steps up to ``max_dist`` [m] (a scalar or
        one per ray) and looked up in ``occupied`` (a dense boolean array of the grid's shape).
        Returns ``hit`` (R,) bool and ``point`` (R, 3) [m], the first occupied sample of each
        ray (meaningless where not ``hit``)."""
        rays = np.asarray(rays, np.float64)
        origin = np.asarray(origin, np.float64)
        max_dist = np.broadcast_to(np.asarray(max_dist, np.float64), (len(rays),))
        steps = np.arange(0.0, float(max_dist.max(initial=0.0)), self.voxel_size / 2)
        # a ray that has left the grid's box never comes back: it stops a voxel past its exit
        reach = np.minimum(max_dist, self._exit(origin, rays) + self.voxel_size)
        hit = np.zeros(len(rays), bool)
        point = np.broadcast_to(origin, (len(rays), 3)).copy()  # the first sample: the origin
        if not len(steps):
            return hit, np.zeros((len(rays), 3))
        flat = np.asarray(occupied, bool).reshape(-1)
        # a few steps of the rays still going at a time: a ray stops at its first occupied
        # sample (most hit within a fraction of their length) or its length
        live = np.arange(len(rays))
        lower, size = np.asarray(self.lower, np.float64), self.voxel_size
        nx, ny, nz = self.shape
        for start in range(0, len(steps), MARCH_CHUNK):
            st = steps[start : start + MARCH_CHUNK]
            r = rays[live]
            # the samples' voxel indices axis by axis, as world_to_index computes them
            ix, iy, iz = (
                np.floor((origin[a] + st[None, :] * r[:, a, None] - lower[a]) / size).astype(
                    np.int64
                )
                for a in range(3)
            )
            inside = (ix.view(np.uint64) < nx) & (iy.view(np.uint64) < ny)
            inside &= iz.view(np.uint64) < nz
            inside &= st[None, :] <= max_dist[live, None]
            occ = np.zeros(inside.shape, bool)
            occ[inside] = flat[((ix[inside] * ny + iy[inside]) * nz + iz[inside])]
            got = occ.any(axis=1)
            rows = np.flatnonzero(got)
            hit[live[rows]] = True
            first = st[occ[rows].argmax(axis=1)]
            point[live[rows]] = origin + first[:, None] * r[rows]
            live = live[~got]
            if start + MARCH_CHUNK < len(steps):
                live = live[reach[live] >= steps[start + MARCH_CHUNK]]
            if not len(live):
                break
        return hit, point

    def _exit(self, origin: np.ndarray, rays: np.ndarray) -> np.ndarray:
        """(R,) [m] how far along each ray from ``origin`` it leaves the grid's box for good
        (-inf: it never enters; the slab test)."""
        lo = np.asarray(self.lower, np.float64) - origin
        hi = np.asarray(self.upper, np.float64) - origin
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = lo / rays, hi / rays
        far = np.where(np.isnan(t1), np.inf, np.maximum(t1, t2))  # nan: 0/0, on a face
        parallel = rays == 0
        outside = parallel & ((lo > 0) | (hi < 0))  # parallel to a slab it is not in
        far = np.where(parallel & ~outside, np.inf, far)
        t = far.min(axis=1)
        t[outside.any(axis=1)] = -np.inf
        return t

    def to_dict(self) -> dict:
        return {"lower": list(self.lower), "upper": list(self.upper), "voxel_size": self.voxel_size}


def mask_box(mask: np.ndarray) -> tuple[slice, slice, slice] | None:
    """The smallest box of index slices holding every True cell of a 3D bool ``mask``, None
    when none is. Two passes over the mask (its projections), where ``np.argwhere`` lists
    every cell: the callers then work in the box alone."""
    xy = mask.any(axis=2)
    where = (np.flatnonzero(xy.any(axis=1)), np.flatnonzero(xy.any(axis=0)))
    if not len(where[0]):
        return None
    z = np.flatnonzero(mask[where[0][0] : where[0][-1] + 1].any(axis=(0, 1)))
    return tuple(slice(int(w[0]), int(w[-1]) + 1) for w in (*where, z))


def box_argwhere(mask: np.ndarray, box: tuple[slice, slice, slice] | None = None) -> np.ndarray:
    """``np.argwhere(mask)`` for a 3D bool mask, found in its :func:`mask_box` (same order);
    ``box``: that box where the caller has it already."""
    box = mask_box(mask) if box is None else box
    if box is None:
        return np.zeros((0, 3), np.intp)
    return np.argwhere(mask[box]) + np.array([b.start for b in box])
