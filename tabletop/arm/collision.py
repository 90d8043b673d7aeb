"""Collision checking on convex hulls of the Panda's links with python-fcl.

Each link's collision mesh (from the URDF, through Pinocchio's geometry model) is replaced by
its convex hull: distance queries between hulls are exact for the hulls, fast (a few
microseconds), and the hulls contain the meshes, so a positive hull clearance is a safe
clearance. The hulls are held in their joint's frame (the hand's and the fingers' URDF
placement applied to their vertices), so each joint's pose is handed to FCL once per query.
The checker answers three questions for an arm configuration ``q``:

- how far the robot is from the environment (table, objects, occupied map voxels),
- how far it is from itself, over the link pairs that can meet (adjacent links and links on
  the same rigid body are filtered out, like an SRDF's ``disable_collisions``),
- whether the motion from one configuration to the next keeps a clearance margin
  (:meth:`CollisionChecker.check_motion`), using a bound on how far any robot point can move.

Distances are capped at ``max_distance`` [m], and negative values are penetration depths.

Only the smallest distance of each kind is needed, so a query is a branch and bound: every
pair gets a cheap lower bound on its distance (the broad phase), the pairs are taken in the
order of their bounds, and the exact (narrow, FCL) distance is computed only while a pair's
bound is below both the cap and the smallest distance found so far. The bounds are either
spatial (each link's bounding sphere against an obstacle's box or another link's sphere) or,
when the arm has moved little since the previous query, temporal: the previous query's
distance (or bound) of the pair less how far the pair can have moved towards each other
(:meth:`CollisionChecker.max_displacement`'s lever arms, over the joints between the two links
for a pair of links). Both kinds are true lower bounds, so the answer is the same as from
computing every pair.
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import fcl
import numpy as np
import pinocchio as pin

from tabletop.arm.model import PandaModel, as_arm_q
from tabletop.arm.obstacles import Box, ConvexObstacle, Cylinder, Obstacle, obstacle_aabb
from tabletop.errors import ConfigError

__all__ = [
    "SELF_COLLISION_DISABLED",
    "Clearance",
    "CollisionChecker",
    "MotionCheck",
    "convex_hull",
]

log = logging.getLogger(__name__)

#: Link pairs never checked against each other, beyond those on adjacent joints or on the same
#: rigid body (the hand, the fingers and link7). As in an SRDF's ``disable_collisions``: pairs
#: two joints apart whose hulls stayed > 4 cm apart over 1000 random configurations ("Never"),
#: and link5-link7, whose hulls overlap although the meshes do not (link5 is hollowed out where
#: link7 turns).
SELF_COLLISION_DISABLED: frozenset[frozenset[str]] = frozenset(
    frozenset(p)
    for p in [
        ("panda_link0", "panda_link2"),
        ("panda_link0", "panda_link3"),
        ("panda_link1", "panda_link3"),
        ("panda_link1", "panda_link4"),
        ("panda_link2", "panda_link4"),
        ("panda_link3", "panda_link5"),
        ("panda_link5", "panda_link7"),
    ]
)


_F64 = np.dtype(np.float64)


def _arm_q(q: object) -> np.ndarray:
    """``as_arm_q(q)`` with a fast path for a finite float64 (7,) array (a copy, as there)."""
    if type(q) is np.ndarray and q.dtype == _F64 and q.shape == (7,):
        # a sum of finite values is finite or overflows to inf: both fall back
        if math.isfinite(sum(q.tolist())):
            return q.copy()
    return as_arm_q(q)


def _read_obj_vertices(path: Path) -> np.ndarray:
    verts = [
        [float(x) for x in ln.split()[1:4]]
        for ln in path.read_text().splitlines()
        if ln.startswith("v ")
    ]
    return np.asarray(verts, dtype=np.float64)


def convex_hull(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hull of (N, 3) points: (V, 3) vertices and (F, 3) int triangles indexing them."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(points)
    used = np.unique(hull.simplices)
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return points[used].copy(), remap[hull.simplices]


def _fcl_convex(verts: np.ndarray, tris: np.ndarray) -> fcl.Convex:
    faces = np.hstack([np.full((len(tris), 1), 3, dtype=np.int64), tris]).ravel()
    return fcl.Convex(verts, len(tris), faces)


def _fcl_geometry(ob: Obstacle) -> tuple[object, np.ndarray, np.ndarray]:
    """(fcl geometry, R_world_geom, t_world_geom) of an obstacle."""
    if isinstance(ob, Box):
        he = ob.half_extents
        return fcl.Box(*(2 * he)), ob.rotation, ob.center
    if isinstance(ob, Cylinder):
        return fcl.Cylinder(ob.radius, ob.height), np.eye(3), ob.center
    if isinstance(ob, ConvexObstacle):
        verts, tris = convex_hull(np.asarray(ob.vertices))
        c = verts.mean(axis=0)
        return _fcl_convex(verts - c, tris), np.eye(3), c
    if isinstance(ob, fcl.OcTree):
        return ob, np.eye(3), np.zeros(3)
    raise ConfigError(
        f"unsupported obstacle type {type(ob).__name__}; valid: Box, Cylinder, ConvexObstacle, "
        "fcl.OcTree"
    )


@dataclass(frozen=True)
class Clearance:
    """Distances [m] from the robot to the environment and to itself, capped at the checker's
    ``max_distance``; negative values are penetration depths."""

    distance: float  # min(environment, self_distance)
    environment: float
    self_distance: float
    closest_pair: tuple[str, str] | None  # (link, obstacle or link) of the minimum, if any


@dataclass(frozen=True)
class MotionCheck:
    """Outcome of :meth:`CollisionChecker.check_motion`."""

    ok: bool  # True when the swept lower bound keeps the margin
    clearance_start: Clearance
    clearance_end: Clearance
    swept_lower_bound: float  # [m] no robot point comes closer than this during the motion
    max_displacement: float  # [m] bound on how far any robot point moves


@dataclass
class _Link:
    name: str
    joint: int  # parent joint index in the Pinocchio model (1..7)
    placement: pin.SE3  # geometry placement relative to the joint
    obj: fcl.CollisionObject
    center_local: np.ndarray  # (3,) bounding-sphere centre in the joint frame
    radius: float  # [m] bounding-sphere radius


class CollisionChecker:
    """Distances between the Panda's link hulls, the environment and the robot itself.

    Args:
        model: the Panda model (a private ``pin.Data`` is used; ``model.data`` is untouched).
        obstacles: the environment (boxes, cylinders, convex sets, or an ``fcl.OcTree``).
        max_distance: distances are exact below this [m] and capped at it above.
        self_collision: also check link pairs of the robot against each other.
    """

    def __init__(
        self,
        model: PandaModel,
        obstacles: Sequence[Obstacle] = (),
        *,
        max_distance: float = 0.10,
        self_collision: bool = True,
    ) -> None:
        if not max_distance > 0:
            raise ConfigError(f"max_distance must be positive [m], got {max_distance}")
        self.model = model
        self.max_distance = float(max_distance)
        self.self_collision = bool(self_collision)
        self._data = model.model.createData()
        geom = pin.buildGeomFromUrdf(
            model.model,
            str(model.urdf_path),
            pin.GeometryType.COLLISION,
            package_dirs=[str(model.package_dir)],
        )
        self._links: list[_Link] = []
        self._hulls: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for go in geom.geometryObjects:
            link = model.model.frames[go.parentFrame].name
            pts = _read_obj_vertices(Path(go.meshPath)) * np.asarray(go.meshScale)
            verts, tris = convex_hull(pts)
            self._hulls[link] = (verts, tris)
            lo, hi = verts.min(axis=0), verts.max(axis=0)
            c = (lo + hi) / 2
            r = float(np.linalg.norm(verts - c, axis=1).max())
            pl = go.placement
            # the hull in its joint's frame (the hand and the fingers are placed on joint 7),
            # so that a link's pose is its joint's, shared by the links on that joint
            placed = not np.allclose(pl.homogeneous, np.eye(4))
            in_joint = verts @ pl.rotation.T + pl.translation if placed else verts
            self._links.append(
                _Link(
                    name=link,
                    joint=int(go.parentJoint),
                    placement=pl,
                    obj=fcl.CollisionObject(_fcl_convex(in_joint, tris), fcl.Transform()),
                    center_local=pl.rotation @ c + pl.translation,
                    radius=r,
                )
            )
        self.link_names = tuple(lk.name for lk in self._links)
        self._sphere_c = np.array([lk.center_local for lk in self._links])
        self._sphere_r = np.array([lk.radius for lk in self._links])
        self._joint_of = np.array([lk.joint for lk in self._links])
        # Links that move (link0 is bolted to the table: its clearance never changes).
        self._moving = np.array([lk.joint > 0 for lk in self._links])
        self.self_pairs = self._self_pairs()
        self._self_i = np.array([i for i, _ in self.self_pairs], dtype=np.int64)
        self._self_j = np.array([j for _, j in self.self_pairs], dtype=np.int64)
        self._lever = self._lever_arms()
        self._req = fcl.DistanceRequest(enable_nearest_points=False, enable_signed_distance=True)
        # fcl.distance copies the nearest points into a result whose min_distance is larger
        # than the query's; one that starts at -inf is never written (the distance is returned)
        self._res = fcl.DistanceResult(-np.inf)
        # per joint, its pose and the query that last set it; per link, the query that last
        # moved it (links on joint 0, the fixed base, stay where they were made)
        self._joint_tfs = [fcl.Transform() for _ in range(self.model.model.njoints)]
        self._stamp = 0
        self._joint_tf_stamp = [0] * len(self._joint_tfs)
        self._link_tf_stamp = [0] * len(self._links)
        self._self_ij = (self._self_i.tolist(), self._self_j.tolist())
        #: Narrow-phase (FCL) distance queries made so far, by every method.
        self.narrow_queries = 0
        #: The temporal bounds are used while no robot point can have moved more than this [m]
        #: since the previous query (beyond it the spatial bounds are the tighter ones).
        self.coherence_limit = 0.25 * self.max_distance
        self.set_obstacles(obstacles)
        self.timings_s: list[float] = []  # wall time of each clearance() call [s]

    # ------------------------------------------------------------------ setup
    def _self_pairs(self) -> list[tuple[int, int]]:
        pairs = []
        for i, j in itertools.combinations(range(len(self._links)), 2):
            a, b = self._links[i], self._links[j]
            if abs(a.joint - b.joint) <= 1:  # same rigid body or adjacent links
                continue
            if frozenset((a.name, b.name)) in SELF_COLLISION_DISABLED:
                continue
            pairs.append((i, j))
        return pairs

    def _lever_arms(self) -> np.ndarray:
        """(7,) bound [m] on the distance from joint k's origin to any hull point it moves.

        By the triangle inequality along the chain: the joint offsets after joint k plus each
        downstream link's farthest hull point from its joint origin.
        """
        m = self.model.model
        offsets = np.array([np.linalg.norm(m.jointPlacements[j].translation) for j in range(8)])
        reach = np.zeros(8)  # farthest hull point from joint j's origin, per joint
        for lk in self._links:
            verts, _ = self._hulls[lk.name]
            pts = verts @ lk.placement.rotation.T + lk.placement.translation
            reach[lk.joint] = max(reach[lk.joint], float(np.linalg.norm(pts, axis=1).max()))
        lever = np.zeros(7)
        for k in range(1, 8):
            best, dist = 0.0, 0.0
            for j in range(k, 8):
                if j > k:
                    dist += offsets[j]
                best = max(best, dist + reach[j])
            lever[k - 1] = best
        # The same bound per link: from joint k's origin to link l's hull points, k <= joint.
        self._link_lever = np.zeros((len(self._links), 7))
        for i, lk in enumerate(self._links):
            verts, _ = self._hulls[lk.name]
            pts = verts @ lk.placement.rotation.T + lk.placement.translation
            dist = float(np.linalg.norm(pts, axis=1).max())
            for k in range(lk.joint, 0, -1):
                self._link_lever[i, k - 1] = dist
                dist += offsets[k]
        return lever

    def set_obstacles(self, obstacles: Sequence[Obstacle]) -> None:
        """Replace the environment (the table, objects, voxel boxes, an ``fcl.OcTree``)."""
        self.obstacles = tuple(obstacles)
        self._obs_objs: list[fcl.CollisionObject] = []
        self._obs_names: list[str] = []
        lo_all, hi_all = [], []
        for k, ob in enumerate(self.obstacles):
            g, R, t = _fcl_geometry(ob)
            self._obs_objs.append(fcl.CollisionObject(g, fcl.Transform(R, t)))
            self._obs_names.append(getattr(ob, "name", f"obstacle{k}"))
            if isinstance(ob, fcl.OcTree):
                lo, hi = np.full(3, -np.inf), np.full(3, np.inf)  # never pruned
            else:
                lo, hi = obstacle_aabb(ob)
            lo_all.append(lo)
            hi_all.append(hi)
        self._obs_lo = np.array(lo_all).reshape(-1, 3)
        self._obs_hi = np.array(hi_all).reshape(-1, 3)
        n_obs = len(self._obs_objs)
        # The pairs' bounds are one array: environment pair p = link i, obstacle k at
        # p = i * n_obs + k, then the self pairs. Row p of _closing bounds how fast [m/rad]
        # each joint's motion can bring pair p closer: the joints up to the link's, each with
        # its lever arm over that link, for an environment pair; for a self pair, the joints
        # between the two links' (their distance depends on the relative pose only), with
        # their lever arms over the farther link.
        n_self = len(self._self_i)  # bounded even when self_collision is off (it may be set)
        self._n_env = len(self._links) * n_obs
        closing = np.zeros((self._n_env + n_self, 7))
        closing[: self._n_env] = np.repeat(self._link_lever, n_obs, axis=0)
        si, sj = self._self_i[:n_self], self._self_j[:n_self]
        between = np.arange(1, 8)[None] > self._joint_of[si][:, None]
        closing[self._n_env :] = self._link_lever[sj] * between
        self._closing = closing
        self._prev_q: np.ndarray | None = None  # the previous query (none yet: spatial bounds)
        self._prev_bounds = np.empty(0)

    @property
    def lever_arms(self) -> np.ndarray:
        """(7,) [m] per-joint bound used by :meth:`max_displacement` (a copy)."""
        return self._lever.copy()

    def hull(self, link: str) -> tuple[np.ndarray, np.ndarray]:
        """(V, 3) vertices [m] in the mesh's frame (on the parent joint by the link's URDF
        collision placement; the identity but for the hand and the fingers) and (F, 3)
        triangles."""
        v, t = self._hulls[link]
        return v.copy(), t.copy()

    # ------------------------------------------------------------------ queries
    def _spatial_bounds(self, oMi) -> np.ndarray:
        """Lower bounds [m] of the pairs' distances (environment pairs, then self pairs):
        bounding spheres against obstacle boxes, and against each other."""
        H = np.array([oMi[j].homogeneous for j in range(8)])[self._joint_of]
        centers = np.einsum("lij,lj->li", H[:, :3, :3], self._sphere_c) + H[:, :3, 3]
        out = np.empty(len(self._closing))
        if self._n_env:
            c = centers[:, None]
            gap = np.maximum(self._obs_lo[None] - c, c - self._obs_hi[None])
            np.maximum(gap, 0.0, out=gap)
            env = np.sqrt(np.einsum("lkj,lkj->lk", gap, gap)) - self._sphere_r[:, None]
            env[~self._moving] = np.inf  # link0 is bolted to the table
            out[: self._n_env] = env.ravel()
        if len(out) > self._n_env:
            d = centers[self._self_i] - centers[self._self_j]
            slf = out[self._n_env :]
            np.sqrt(np.einsum("pj,pj->p", d, d), out=slf)
            slf -= self._sphere_r[self._self_i]
            slf -= self._sphere_r[self._self_j]
        return out

    def _temporal_bounds(self, q: np.ndarray) -> np.ndarray | None:
        """The previous query's distances and bounds less how far each pair can have closed
        in since (None when a robot point can have moved more than ``coherence_limit``, or
        when there is no previous query)."""
        if self._prev_q is None:
            return None
        dq = np.abs(q - self._prev_q)
        if dq.dot(self._lever) > self.coherence_limit:  # max_displacement
            return None
        return self._prev_bounds - self._closing.dot(dq)

    def _place(self, i: int, oMi) -> None:
        """Move link i's collision object to its joint's pose in ``oMi`` (each joint's pose
        converted once per query)."""
        lk = self._links[i]
        j = lk.joint
        if not j:  # on the fixed base: at the identity, where it was made, for good
            return
        tf = self._joint_tfs[j]
        if self._joint_tf_stamp[j] != self._stamp:
            H = oMi[j].homogeneous
            tf.setRotation(H[:3, :3])
            tf.setTranslation(H[:3, 3])
            self._joint_tf_stamp[j] = self._stamp
        lk.obj.setTransform(tf)

    def _set_tf(self, i: int, oMi, done: set[int]) -> fcl.CollisionObject:
        lk = self._links[i]
        if i not in done:
            M = oMi[lk.joint]
            lk.obj.setTransform(fcl.Transform(M.rotation, M.translation))
            done.add(i)
        return lk.obj

    def _distance(self, a: fcl.CollisionObject, b: fcl.CollisionObject) -> float:
        self.narrow_queries += 1
        return float(fcl.distance(a, b, self._req, self._res))

    def clearance(self, q: object) -> Clearance:
        """Robot-environment and robot-robot clearance [m] at arm configuration ``q`` [rad]."""
        t0 = time.perf_counter()
        q = _arm_q(q)
        pin.forwardKinematics(self.model.model, self._data, q)
        oMi = self._data.oMi
        bounds = self._temporal_bounds(q)
        if bounds is None:
            bounds = self._spatial_bounds(oMi)
        n_obs, n_env = len(self._obs_objs), self._n_env
        links, cap = self._links, self.max_distance
        # Branch and bound, per kind: the pairs in increasing order of their bounds while a
        # bound is below the smallest distance so far; each pair computed gets its exact
        # distance written into ``bounds``. A bound that is not positive says nothing (two
        # bodies that may overlap can overlap by more than either's bounding sphere), so such
        # a pair is always computed. Each link's transform is set at most once per query.
        placed = self._link_tf_stamp
        stamp = self._stamp = self._stamp + 1
        req, res, distance = self._req, self._res, fcl.distance
        narrow = 0
        env, slf = cap, cap
        env_pair = slf_pair = None
        if n_env:
            env_b = bounds[:n_env]
            obs = self._obs_objs
            for p in env_b.argsort():  # numpy scalars: only the first few are taken
                b = env_b[p]
                if b >= env and b > 0.0:
                    break
                i, k = divmod(int(p), n_obs)
                if placed[i] != stamp:
                    self._place(i, oMi)
                    placed[i] = stamp
                d = distance(links[i].obj, obs[k], req, res)
                narrow += 1
                env_b[p] = d
                if d < env:
                    env, env_pair = d, p
            if env_pair is not None:
                env_pair = (links[env_pair // n_obs].name, self._obs_names[env_pair % n_obs])
        if self.self_collision and len(bounds) > n_env:
            slf_b = bounds[n_env:]
            si, sj = self._self_ij
            for p in slf_b.argsort():
                b = slf_b[p]
                if b >= slf and b > 0.0:
                    break
                p = int(p)
                i, j = si[p], sj[p]
                if placed[i] != stamp:
                    self._place(i, oMi)
                    placed[i] = stamp
                if placed[j] != stamp:
                    self._place(j, oMi)
                    placed[j] = stamp
                d = distance(links[i].obj, links[j].obj, req, res)
                narrow += 1
                slf_b[p] = d
                if d < slf:
                    slf, slf_pair = d, p
            if slf_pair is not None:
                slf_pair = (links[si[slf_pair]].name, links[sj[slf_pair]].name)
        self.narrow_queries += narrow
        self._prev_q, self._prev_bounds = q, bounds
        self.timings_s.append(time.perf_counter() - t0)
        if env <= slf:
            return Clearance(env, env, slf, env_pair)
        return Clearance(slf, env, slf, slf_pair)

    def clearance_all_pairs(self, q: object) -> Clearance:
        """:meth:`clearance` with every pair's distance computed (no bounds, no pruning, no
        memory of earlier queries): the reference the faster query must agree with."""
        q = as_arm_q(q)
        data = self.model.model.createData()
        pin.forwardKinematics(self.model.model, data, q)
        oMi, done = data.oMi, set()
        cap = self.max_distance
        env, env_pair = cap, None
        for i, lk in enumerate(self._links):
            if not self._moving[i]:
                continue
            for k, ob in enumerate(self._obs_objs):
                d = self._distance(self._set_tf(i, oMi, done), ob)
                if d < env:
                    env, env_pair = d, (lk.name, self._obs_names[k])
        slf, slf_pair = cap, None
        if self.self_collision:
            for i, j in self.self_pairs:
                d = self._distance(self._set_tf(i, oMi, done), self._set_tf(j, oMi, done))
                if d < slf:
                    slf, slf_pair = d, (self._links[i].name, self._links[j].name)
        if env <= slf:
            return Clearance(env, env, slf, env_pair)
        return Clearance(slf, env, slf, slf_pair)

    def max_displacement(self, q_from: object, q_to: object) -> float:
        """Bound [m] on how far any robot point moves on the joint-space segment q_from → q_to."""
        dq = np.abs(as_arm_q(q_to, "q_to") - as_arm_q(q_from, "q_from"))
        return float(dq @ self._lever)

    def check_motion(
        self,
        q_from: object,
        q_to: object,
        margin: float,
        clearance_from: Clearance | None = None,
    ) -> MotionCheck:
        """Whether the straight joint-space motion q_from → q_to keeps ``margin`` [m].

        A robot point that moves at most ``D`` along the segment is, at any instant, within
        ``D t`` of its start and ``D (1 - t)`` of its end, so no point comes closer than
        ``(c_from + c_to - D) / 2`` to an obstacle (or another link): this is the swept lower
        bound, and the motion is accepted when it is at least ``margin``.
        """
        c0 = clearance_from if clearance_from is not None else self.clearance(q_from)
        c1 = self.clearance(q_to)
        D = self.max_displacement(q_from, q_to)
        bound = min(c0.distance, c1.distance, (c0.distance + c1.distance - D) / 2)
        return MotionCheck(
            ok=bound >= margin,
            clearance_start=c0,
            clearance_end=c1,
            swept_lower_bound=bound,
            max_displacement=D,
        )
