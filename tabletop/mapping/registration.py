"""Table registration: correct each frame's recorded pose so that the table it sees lies on the
table every other frame sees.

Recorded end-effector poses carry errors (joint encoders, timing, a mobile base's odometry).
Fused as they are, a few millimetres and a degree of error per frame smear the table top into
a slab centimetres thick, which then swallows the low objects standing on it. A wrist camera
over a table sees the table in most frames, and the table is one plane: a strong constraint on
three of a pose's six degrees of freedom (height, roll, pitch).

:func:`table_corrections` works in two passes over the depth images alone (no encoder runs):

1. each frame's dominant plane is fitted to its depth points in the world frame (RANSAC, then
   least squares on the inliers); the table's height is the one most frames' horizontal
   planes agree on (the floor past the table's edge is another), and each frame's plane is
   fitted again to its points near that height: a plane within ``max_tilt_rad`` of
   horizontal is the frame's view of the table;
2. the reference table is level (``level``: the world frame's z is up) at the median of those
   planes' heights (without ``level``: the median plane, height and normal); a frame whose plane
   differs from it is corrected by the rigid transform that rotates its plane onto the
   reference about the plane's centroid and lifts it onto the reference height.

Corrections smaller than the fit's own noise (``deadband_m``, ``deadband_rad``) are not
applied, so exact poses (the simulator's) are left exactly as they are; corrections larger than
``max_correction_m``/``max_correction_rad`` are refused as fits to something else (a box top,
a tray).

Horizontal position and yaw are not observable from a plane. With ``planar`` (on by default,
see :class:`RegistrationConfig`), a third pass registers them on what stands on the table:

3. each frame's points above the table are aligned in x, y and yaw to the points above the
   table of the *other* frames (the scan split into even and odd frames, each half aligned to
   the other, so a frame never pulls towards its own points): nearest neighbours within
   ``planar_match_m`` in 3D, a closed-form rigid fit in the horizontal plane, repeated
   ``planar_icp_iterations`` times or until a step moves less than a tenth of the
   deadband; the two halves' references are rebuilt from the corrected
   frames ``planar_rounds`` times. The same deadband and bounds apply
   (``planar_deadband_m``/``planar_deadband_rad``, ``planar_max_m``/``planar_max_rad``), and
   a correction is applied only where it brings the frame's points ``planar_min_gain_m``
   closer to the other frames' surfaces: exact poses already put them there, so an alignment
   that slides a frame along what pins it poorly (a yaw about one upright face) is refused.

Per-frame pose noise and a wrist camera's extrinsic error (which moves each view differently
as the hand turns) both show as frames that disagree with their neighbours; what all frames
agree on stays where it was recorded, except a tilt of the table (``level``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tabletop.errors import ConfigError
from tabletop.transforms import backproject, make_transform

__all__ = ["RegistrationConfig", "TableCorrections", "table_corrections"]


@dataclass(frozen=True)
class RegistrationConfig:
    """How frames are registered to the table (see the module)."""

    enabled: bool = True
    samples: int = 3000
    """Depth points sampled per frame for the plane fit."""
    inlier_m: float = 0.001
    """RANSAC inlier distance [m] from a plane."""
    iterations: int = 150
    """RANSAC hypotheses per frame."""
    min_inlier_fraction: float = 0.3
    """A frame's plane must explain this share of its sampled points to be the table."""
    max_tilt_rad: float = math.radians(10.0)
    """A plane tilted more than this from horizontal is not the table."""
    deadband_m: float = 0.0015
    """Height corrections below this [m] are fit noise: not applied (unless the tilt is)."""
    deadband_rad: float = math.radians(0.15)
    """Tilt corrections below this [rad] are fit noise: not applied (unless the height is)."""
    max_correction_m: float = 0.04
    """A frame whose table lies farther [m] from the reference is not corrected."""
    max_correction_rad: float = math.radians(5.0)
    """A frame whose table is tilted more [rad] against the reference is not corrected."""
    seed: int = 0
    level: bool = True
    """The table is level in the base frame (z up, as the world frame is defined): frames are
    corrected onto a horizontal plane. False: onto the median of the frames' planes (a table
    that is tilted in the base frame). A camera extrinsic that is off tilts every frame's view
    of the table alike; the median then keeps that tilt, and a map whose table rises a few
    millimetres across its width puts the high side's table top among the objects."""
    planar: bool = True
    """Register x, y and yaw on the points above the table (pass 3 of the module)."""
    planar_voxel_m: float = 0.02
    """The other frames' points are averaged in voxels of this size [m] before matching."""
    planar_match_m: float = 0.02
    """Nearest neighbours farther apart [m] are not matched."""
    planar_icp_iterations: int = 8
    """Alignment steps per frame and round."""
    planar_rounds: int = 6
    """Rounds of rebuilding the references from the corrected frames."""
    planar_min_points: int = 80
    """A frame needs this many matched points above the table to be registered."""
    planar_deadband_m: float = 0.001
    """Horizontal corrections below this [m] are noise: not applied (unless the yaw is)."""
    planar_deadband_rad: float = math.radians(0.1)
    """Yaw corrections below this [rad] are noise: not applied (unless the shift is)."""
    planar_max_m: float = 0.03
    """A frame that would move farther [m] is not corrected."""
    planar_max_rad: float = math.radians(4.0)
    """A frame that would turn more [rad] is not corrected."""
    planar_min_gain_m: float = 0.0005
    """A frame is corrected only where that brings its points at least this much [m] closer to
    the other frames' surfaces (median point-to-plane distance, in the last round). Exact
    poses put them on those surfaces already (0.05 mm on the shipped default scene), and an
    alignment may still slide a frame along what pins it poorly (a yaw about a lone upright
    face): nothing is gained."""

    def __post_init__(self) -> None:
        for name, least in (
            ("samples", 3),
            ("iterations", 3),
            ("planar_icp_iterations", 1),
            ("planar_rounds", 1),
            ("planar_min_points", 1),
        ):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < least:
                raise ConfigError(f"registration {name} must be an integer >= {least}, got {v!r}")
        for name in (
            "inlier_m",
            "max_tilt_rad",
            "deadband_m",
            "deadband_rad",
            "max_correction_m",
            "max_correction_rad",
            "planar_voxel_m",
            "planar_match_m",
            "planar_deadband_m",
            "planar_deadband_rad",
            "planar_max_m",
            "planar_max_rad",
            "planar_min_gain_m",
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < 10:
                raise ConfigError(f"registration {name} must be a number in [0, 10), got {v!r}")
        if not 0 < self.min_inlier_fraction <= 1:
            raise ConfigError(
                f"registration min_inlier_fraction must be in (0, 1], got "
                f"{self.min_inlier_fraction!r}"
            )


@dataclass(frozen=True)
class TableCorrections:
    """Per-frame world-frame corrections: a frame's corrected pose is ``C[i] @ T_world_x[i]``
    for its camera, hand and microphone alike."""

    C: np.ndarray
    """(N, 4, 4) rigid corrections (identity where nothing was corrected)."""
    corrected: np.ndarray
    """(N,) bool: frames whose pose was corrected."""
    table_frames: int
    """Frames that saw the table (a plane fit)."""
    height_m: float | None
    """The reference table height [m] (None: no frame saw a table)."""

    @property
    def any(self) -> bool:
        return bool(self.corrected.any())


def _fit_plane(p: np.ndarray, cfg: RegistrationConfig, rng) -> tuple | None:
    """(unit normal with n_z > 0, centroid, inlier fraction) of the dominant plane of ``p``:
    RANSAC, then least squares on inliers re-selected around each fit with a band that
    shrinks to three robust standard deviations of the residuals (so the edge of a low object
    inside the first band does not tilt the plane)."""
    n = len(p)
    if n < 50:
        return None
    tri = rng.integers(0, n, size=(cfg.iterations, 3))
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    normals = np.cross(b - a, c - a)
    norm = np.linalg.norm(normals, axis=1)
    ok = norm > 1e-9
    if not ok.any():
        return None
    normals, a = normals[ok] / norm[ok, None], a[ok]
    # (n, H) point-to-plane distances in one product (no (H, n, 3) differences)
    dist = np.abs(p @ normals.T - (a * normals).sum(axis=1))
    best = int(np.argmax((dist < cfg.inlier_m).sum(axis=0)))
    inl = dist[:, best] < cfg.inlier_m
    if inl.sum() < cfg.min_inlier_fraction * n or inl.sum() < 20:
        return None
    frac = float(inl.mean())
    for _ in range(3):
        q = p[inl]
        centroid = q.mean(axis=0)
        _, _, vt = np.linalg.svd(q - centroid, full_matrices=False)
        normal = vt[2] if vt[2, 2] >= 0 else -vt[2]
        r = np.abs((p - centroid) @ normal)
        sigma = 1.4826 * float(np.median(r[inl]))
        band = min(cfg.inlier_m, max(3.0 * sigma, 0.0005))
        inl = r < band
        if inl.sum() < 20:
            return None
    return normal, centroid, frac


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector ``a`` onto unit vector ``b``."""
    v = np.cross(a, b)
    s, c = np.linalg.norm(v), float(np.dot(a, b))
    if s < 1e-12:
        return np.eye(3)
    k = v / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    angle = math.atan2(s, c)
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def table_corrections(
    depth: np.ndarray,
    K: np.ndarray,
    T_world_cam: np.ndarray,
    config: RegistrationConfig | None = None,
) -> TableCorrections:
    """Corrections (see the module) for frames with depth images ``depth`` (N, H, W) [m],
    intrinsics ``K`` and recorded camera poses ``T_world_cam`` (N, 4, 4)."""
    cfg = config or RegistrationConfig()
    n = len(depth)
    C = np.tile(np.eye(4), (n, 1, 1))
    corrected = np.zeros(n, bool)
    if not cfg.enabled or n == 0:
        return TableCorrections(C, corrected, 0, None)
    rng = np.random.default_rng(cfg.seed)
    cos_tilt = math.cos(cfg.max_tilt_rad)
    points: list[np.ndarray | None] = []
    first: list[float] = []  # the heights of the frames' dominant horizontal planes
    for i in range(n):
        valid = np.flatnonzero(depth[i].ravel() > 0)
        if len(valid) < 50:
            points.append(None)
            continue
        pick = valid[rng.choice(len(valid), min(cfg.samples, len(valid)), replace=False)]
        mask = np.zeros(depth[i].size, bool)
        mask[pick] = True
        pc = backproject(depth[i], K, mask.reshape(depth[i].shape))
        pw = pc @ T_world_cam[i][:3, :3].T + T_world_cam[i][:3, 3]
        points.append(pw)
        fit = _fit_plane(pw, cfg, rng)
        if fit is not None and fit[0][2] >= cos_tilt:
            first.append(float(fit[1][2]))
    if not first:
        return TableCorrections(C, corrected, 0, None)
    # The table: the height most frames' dominant planes agree on (the floor, seen past the
    # table's edge, is another horizontal plane).
    h = np.array(first)
    votes = [(np.abs(h - x) < cfg.max_correction_m).sum() for x in h]
    table_h = float(np.median(h[np.abs(h - h[int(np.argmax(votes))]) < cfg.max_correction_m]))
    planes: list[tuple[int, np.ndarray, np.ndarray]] = []
    for i, pw in enumerate(points):
        if pw is None:
            continue
        near = pw[np.abs(pw[:, 2] - table_h) < cfg.max_correction_m]
        fit = _fit_plane(near, cfg, rng) if len(near) >= cfg.min_inlier_fraction * len(pw) else None
        if fit is not None and fit[0][2] >= cos_tilt:
            planes.append((i, fit[0], fit[1]))
    if not planes:
        return TableCorrections(C, corrected, 0, None)
    if cfg.level:
        ref_n = np.array([0.0, 0.0, 1.0])
    else:
        ref_n = np.median(np.stack([p[1] for p in planes]), axis=0)
        ref_n /= np.linalg.norm(ref_n)
    heights = np.array([float(np.dot(ref_n, p[2])) for p in planes])
    ref_h = float(np.median(heights))
    for (i, normal, centroid), h in zip(planes, heights, strict=True):
        dz = ref_h - h
        tilt = math.acos(min(1.0, float(np.dot(normal, ref_n))))
        if abs(dz) > cfg.max_correction_m or tilt > cfg.max_correction_rad:
            continue  # another plane (a box top, a tray), or a pose too wrong to trust
        if abs(dz) < cfg.deadband_m and tilt < cfg.deadband_rad:
            continue
        R = _rotation_between(normal, ref_n)
        # rotate about the plane's centroid, then lift the centroid onto the reference plane
        t = centroid - R @ centroid + dz * ref_n
        C[i] = make_transform(R, t)
        corrected[i] = True
    if cfg.planar:
        P = _planar_corrections(points, C, T_world_cam[:, :3, 3], ref_h, cfg)
        moved = np.any(P != np.eye(4), axis=(1, 2))
        C = P @ C
        corrected |= moved
    return TableCorrections(C, corrected, len(planes), ref_h)


def _yaw_transform(theta: float, t: np.ndarray) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return make_transform(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), [*t, 0.0])


def _normals(p: np.ndarray, tree, k: int = 30) -> np.ndarray:
    """(m, 3) unit surface normals at the points ``p`` (the least spread direction of their
    ``k`` nearest neighbours in ``tree``)."""
    _, j = tree.query(p, k=min(k, len(tree.data)))
    nb = tree.data[j] - tree.data[j].mean(axis=1, keepdims=True)
    _, _, vt = np.linalg.svd(nb, full_matrices=False)
    return vt[:, 2, :]


def _step_yaw(p: np.ndarray, q: np.ndarray, n: np.ndarray) -> tuple[float, np.ndarray]:
    """(yaw, (2,) shift): the small motion in the horizontal plane that best brings the points
    ``p`` onto the planes through ``q`` with normals ``n`` ((m, 3) each; point-to-plane, so a
    point may slide along the surface it lies on)."""
    J = np.stack([n[:, 1] * p[:, 0] - n[:, 0] * p[:, 1], n[:, 0], n[:, 1]], axis=1)
    r = ((q - p) * n).sum(axis=1)
    x = np.linalg.solve(J.T @ J + 1e-9 * np.eye(3), J.T @ r)
    return float(x[0]), x[1:]


def _residual(p: np.ndarray, tree, normals: np.ndarray, cfg: RegistrationConfig) -> float:
    """The median distance [m] of the points ``p`` (m, 3) from the reference's surfaces
    (point-to-plane, over the points with a neighbour within ``planar_match_m``; a point
    without one counts as that far)."""
    d, j = tree.query(p, distance_upper_bound=cfg.planar_match_m)
    ok = np.isfinite(d)
    r = np.full(len(p), cfg.planar_match_m)
    r[ok] = np.abs(((tree.data[j[ok]] - p[ok]) * normals[j[ok]]).sum(axis=1))
    return float(np.median(r))


def _voxel_means(p: np.ndarray, size: float) -> np.ndarray:
    """The mean of ``p``'s points in each ``size`` voxel: many noisy views of a surface averaged
    into one estimate of it (nearest neighbours in the raw union of views find some noisy
    copy of a point close by whatever the frame's error, and pull it nowhere)."""
    key = np.floor(p / size).astype(np.int64)
    key -= key.min(axis=0)
    span = key.max(axis=0) + 1
    # one integer per voxel, x most significant: the order of np.unique(key, axis=0), faster
    flat = (key[:, 0] * span[1] + key[:, 1]) * span[2] + key[:, 2]
    _, inv, counts = np.unique(flat, return_inverse=True, return_counts=True)
    out = np.zeros((len(counts), 3))
    for d in range(3):
        out[:, d] = np.bincount(inv, weights=p[:, d], minlength=len(counts))
    return out / counts[:, None]


def _planar_corrections(
    points: list[np.ndarray | None],
    C: np.ndarray,
    cameras: np.ndarray,
    table_h: float,
    cfg: RegistrationConfig,
) -> np.ndarray:
    """(N, 4, 4) x/y/yaw corrections (applied after ``C``): pass 3 of the module."""
    from scipy.spatial import cKDTree

    n = len(points)
    P = np.tile(np.eye(4), (n, 1, 1))
    above: list[np.ndarray | None] = []
    for i, pw in enumerate(points):
        if pw is None:
            above.append(None)
            continue
        q = pw @ C[i][:3, :3].T + C[i][:3, 3]
        # above the table, and not the gripper's own fingers in front of the camera
        far = np.linalg.norm(pw - cameras[i], axis=1) > 0.15
        keep = far & (q[:, 2] > table_h + 0.008) & (q[:, 2] < table_h + 0.35)
        above.append(q[keep] if keep.sum() >= cfg.planar_min_points else None)
    halves = (np.arange(n) % 2 == 0, np.arange(n) % 2 == 1)
    for round_ in range(cfg.planar_rounds):
        voxel = max(cfg.planar_voxel_m * 0.75**round_, 0.004)  # coarse to fine
        moved = [
            None if a is None else a @ P[i][:3, :3].T + P[i][:3, 3] for i, a in enumerate(above)
        ]
        trees = []
        for half in halves:
            ref = [moved[i] for i in np.flatnonzero(half) if moved[i] is not None]
            if not ref:
                trees.append(None)
                continue
            tree = cKDTree(_voxel_means(np.concatenate(ref), voxel))
            trees.append((tree, _normals(tree.data, tree)))
        for i, a in enumerate(above):
            ref = trees[1 - i % 2]
            if a is None or ref is None:
                continue
            tree, normals = ref
            # yaw about the frame's own points (well conditioned), then a shift
            centre = np.array([*a[:, :2].mean(axis=0), 0.0])
            local = a - centre
            theta, t = 0.0, np.zeros(2)
            lost = False
            for _ in range(cfg.planar_icp_iterations):
                cur = local @ _yaw_transform(theta, t)[:3, :3].T + [*t, 0.0] + centre
                d, j = tree.query(cur, distance_upper_bound=cfg.planar_match_m)
                ok = np.isfinite(d)
                if ok.sum() < cfg.planar_min_points:
                    lost = True
                    break
                dth, dt = _step_yaw(cur[ok] - centre, tree.data[j[ok]] - centre, normals[j[ok]])
                c, s = math.cos(dth), math.sin(dth)
                t = np.array([[c, -s], [s, c]]) @ t + dt
                theta += dth
                # settled: a step a tenth of the deadband changes nothing that is applied
                if np.hypot(*dt) < 0.1 * cfg.planar_deadband_m and (
                    abs(dth) < 0.1 * cfg.planar_deadband_rad
                ):
                    break
            if not lost:
                shift = float(np.linalg.norm(t))
                if shift > cfg.planar_max_m or abs(theta) > cfg.planar_max_rad:
                    continue
                if shift < cfg.planar_deadband_m and abs(theta) < cfg.planar_deadband_rad:
                    P[i] = np.eye(4)
                    continue
                if round_ == cfg.planar_rounds - 1:  # against the finest, final references
                    fin = local @ _yaw_transform(theta, t)[:3, :3].T + [*t, 0.0] + centre
                    gain = _residual(a, tree, normals, cfg) - _residual(fin, tree, normals, cfg)
                    if gain < cfg.planar_min_gain_m:
                        P[i] = np.eye(4)
                        continue
                Rz = _yaw_transform(theta, np.zeros(2))
                P[i] = make_transform(
                    Rz[:3, :3], centre + np.array([*t, 0.0]) - Rz[:3, :3] @ centre
                )
    return P
