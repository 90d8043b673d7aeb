"""The simulated world: a PyBullet client holding the floor, the table, the Panda and objects.

Objects are static (they stand where the spec puts them); the Panda is moved by setting its
joints. Rendering goes through the EGL plugin when it is available (about 9 ms per 320x240
frame on 2 cores) and falls back to the TinyRenderer (about 45 ms).
"""

from __future__ import annotations

import contextlib
import logging
import os
import pkgutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Self

import numpy as np

from tabletop.arm.model import ARM_JOINT_NAMES, FINGER_JOINT_NAMES, HOME_Q
from tabletop.errors import ConfigError, SimulationError
from tabletop.paths import panda_urdf_path
from tabletop.sim.camera import (
    WristCameraConfig,
    depth_from_gl_buffer,
    gl_projection_matrix,
    gl_view_matrix,
)
from tabletop.sim.catalog import COLORS, load_mesh_geometry, object_kind, pybullet_data_dir
from tabletop.sim.ground_truth import AreaTruth, GroundTruth, ObjectTruth, TableTruth
from tabletop.sim.scene import ObjectSpec, SceneSpec
from tabletop.transforms import make_transform, quat_from_matrix, quat_to_matrix

__all__ = [
    "ARM_JOINT_NAMES",
    "HOME_Q",
    "INSTANCE_FLOOR",
    "INSTANCE_NONE",
    "INSTANCE_ROBOT",
    "INSTANCE_TABLE",
    "RENDERERS",
    "CameraImage",
    "PlacedObject",
    "PyBulletWorld",
    "SimWorld",
    "create_object_body",
    "egl_holder",
    "load_egl_plugin",
    "object_truth",
    "render_camera",
]

log = logging.getLogger(__name__)

FINGER_OPENING = 0.04  # [m] per finger

INSTANCE_NONE, INSTANCE_FLOOR, INSTANCE_TABLE, INSTANCE_ROBOT = 0, 1, 2, 3
_FIRST_OBJECT_INSTANCE = 4
RENDERERS = ("auto", "egl", "tiny")


@dataclass(frozen=True)
class CameraImage:
    """One rendered frame."""

    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W) float32 [m], 0 = invalid, quantised to the sensor resolution
    segmentation: np.ndarray  # (H, W) uint16 instance ids (simulator oracle only)


def _untextured_copy(mesh: Path) -> Path:
    """A copy of an OBJ mesh without ``mtllib``/``usemtl`` lines, cached in the temp dir."""
    out_dir = Path(tempfile.gettempdir()) / f"tabletop-meshes-{os.getuid()}"
    out = out_dir / f"{mesh.parent.name}-{mesh.stem}-{mesh.stat().st_size}.obj"
    if not out.is_file():
        out_dir.mkdir(parents=True, exist_ok=True)
        lines = mesh.read_text().splitlines(keepends=True)
        keep = [ln for ln in lines if not ln.startswith(("mtllib", "usemtl"))]
        tmp = out.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text("".join(keep))
        tmp.replace(out)  # atomic: concurrent builders never see half a file
    return out


@contextlib.contextmanager
def _quiet_stdout():
    """Silence C-level writes to stdout (file descriptor 1) for the duration."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


#: Clients that loaded PyBullet's EGL renderer plugin. The plugin keeps one scene per process:
#: a second client's bodies replace the first's, and the first then renders the second's scene.
_EGL_CLIENTS: set[int] = set()


def egl_holder(pb) -> int | None:
    """The connected client of this process that holds the EGL renderer (None: none)."""
    for c in list(_EGL_CLIENTS):
        if not pb.isConnected(c):
            _EGL_CLIENTS.discard(c)
    return min(_EGL_CLIENTS, default=None)


def load_egl_plugin(pb, client: int) -> bool:
    """Load PyBullet's EGL renderer plugin into ``client`` (before any body); False if the
    machine has none, or if another connected client holds it (:func:`egl_holder`: the
    plugin renders one scene per process, so a second world renders with TinyRenderer)."""
    holder = egl_holder(pb)
    if holder is not None and holder != client:
        log.warning(
            "PyBullet client %d holds the EGL renderer, which renders one scene per process; "
            "client %d renders with TinyRenderer",
            holder,
            client,
        )
        return False
    loader = pkgutil.get_loader("eglRenderer")
    if loader is None:
        return False
    try:
        with _quiet_stdout():  # the plugin prints its GL banner from C
            plugin = pb.loadPlugin(
                loader.get_filename(), "_eglRendererPlugin", physicsClientId=client
            )
    except Exception:  # pragma: no cover - depends on the machine's GL stack
        return False
    if plugin >= 0:
        _EGL_CLIENTS.add(client)
    return plugin >= 0


def egl_unavailable(pb) -> str:
    """Why ``renderer="egl"`` cannot be had, for an error message."""
    holder = egl_holder(pb)
    if holder is not None:
        return (
            f"another world (PyBullet client {holder}) holds the EGL renderer, which renders one "
            f"scene per process: close that world first, or use renderer='tiny'"
        )
    return "EGL renderer plugin could not be loaded; use renderer='tiny'"


def create_object_body(pb, client: int, kind_name: str, color: str, T_world_obj: np.ndarray) -> int:
    """A static PyBullet body of a catalog object (mesh visual and collision) at
    ``T_world_obj`` (its bottom centre), painted ``color`` unless the kind keeps its texture."""
    kind = object_kind(kind_name)
    geo = load_mesh_geometry(kind_name)
    data = pybullet_data_dir()
    mesh = str(data / kind.mesh)
    # The EGL renderer ignores texture changes, so painted kinds load a copy of the
    # mesh without its material library.
    vis_mesh = mesh if kind.keep_texture else str(_untextured_copy(data / kind.mesh))
    q_frame = quat_from_matrix(geo.frame_rotation).tolist()
    vis = pb.createVisualShape(
        pb.GEOM_MESH,
        fileName=vis_mesh,
        meshScale=list(kind.scale),
        visualFramePosition=geo.frame_offset.tolist(),
        visualFrameOrientation=q_frame,
        rgbaColor=None if kind.keep_texture else [*COLORS[color], 1.0],
        physicsClientId=client,
    )
    col = pb.createCollisionShape(
        pb.GEOM_MESH,
        fileName=mesh,
        meshScale=list(kind.scale),
        collisionFramePosition=geo.frame_offset.tolist(),
        collisionFrameOrientation=q_frame,
        physicsClientId=client,
    )
    T = np.asarray(T_world_obj, dtype=np.float64)
    return pb.createMultiBody(
        0,
        col,
        vis,
        T[:3, 3].tolist(),
        quat_from_matrix(T[:3, :3]).tolist(),
        physicsClientId=client,
    )


def object_truth(
    obj: ObjectSpec,
    instance_id: int,
    T_world_obj: np.ndarray,
    position,
    yaw_deg: float,
    aabb: tuple[np.ndarray, np.ndarray],
    table: str | None = None,
) -> ObjectTruth:
    """The ground truth of one placed object: its spec's name, kind, label and colour, the
    catalog's category, with where it stands given by the caller (the table's and the rooms'
    worlds place objects in different frames): ``T_world_obj`` (4, 4) [m], ``position`` (x, y)
    [m], ``yaw_deg`` [deg], ``aabb`` (lower, upper corner) [m], all in the world frame, and
    ``table``, the furniture it stands on (None on the arm's table)."""
    lo, hi = aabb
    return ObjectTruth(
        name=obj.name,
        kind=obj.kind,
        label=obj.label,
        category=object_kind(obj.kind).label,
        color=obj.color,
        instance_id=instance_id,
        position=position,
        yaw_deg=yaw_deg,
        T_world_obj=T_world_obj,
        aabb_min=lo,
        aabb_max=hi,
        center=(lo + hi) / 2,
        table=table,
    )


def render_camera(
    pb,
    client: int,
    camera: WristCameraConfig,
    projection: list[float],
    renderer: str,
    T_world_cam: np.ndarray,
    seg_lut: np.ndarray,
) -> CameraImage:
    """Render RGB, metric depth and instance segmentation (body id -> ``seg_lut``) from an
    OpenCV camera pose with the "egl" or "tiny" renderer."""
    W, H = camera.width, camera.height
    kind = pb.ER_BULLET_HARDWARE_OPENGL if renderer == "egl" else pb.ER_TINY_RENDERER
    _, _, rgba, buf, seg = pb.getCameraImage(
        W,
        H,
        gl_view_matrix(T_world_cam),
        projection,
        renderer=kind,
        lightDirection=[0.4, 0.3, 1.0],
        shadow=0,
        physicsClientId=client,
    )
    rgb = np.asarray(rgba, dtype=np.uint8).reshape(H, W, 4)[..., :3].copy()
    depth = depth_from_gl_buffer(np.asarray(buf).reshape(H, W), camera.near, camera.far)
    res = camera.depth_resolution
    depth = (np.round(depth / res) * res).astype(np.float32)
    seg = np.asarray(seg, dtype=np.int64).reshape(H, W)
    inst = np.where(seg >= 0, seg_lut[np.clip(seg, 0, len(seg_lut) - 1)], 0)
    inst = inst.astype(np.uint16)
    inst[depth == 0] = INSTANCE_NONE
    return CameraImage(rgb=rgb, depth=depth, segmentation=inst)


class PyBulletClient:
    """The lifetime of a world's own PyBullet client (``self._pb``, ``self._client``):
    :meth:`close` disconnects it once; a world is a context manager that closes it."""

    _client: int | None

    def close(self) -> None:
        if self._client is not None and self._pb.isConnected(self._client):
            with _quiet_stdout():
                self._pb.disconnect(self._client)
        _EGL_CLIENTS.discard(self._client)
        self._client = None

    def __enter__(self) -> Self:
        return self

    def _start_renderer(self, renderer: str) -> None:
        """Load the EGL renderer where ``renderer`` ("auto", "egl", "tiny") asks for it and it
        can be had (before any body); ``self.renderer`` says which renders."""
        self.renderer = "tiny"
        if renderer in ("auto", "egl") and load_egl_plugin(self._pb, self._client):
            self.renderer = "egl"
        elif renderer == "egl":
            why = egl_unavailable(self._pb)
            self.close()
            raise SimulationError(why)

    def _check_renderer(self, renderer: str) -> None:
        """After building: an EGL renderer that renders nothing falls back to TinyRenderer
        (or raises where ``renderer`` insisted on EGL)."""
        if self.renderer == "egl" and not self._egl_renders():
            if renderer == "egl":
                self.close()
                raise SimulationError("EGL renderer produced an empty image")
            log.warning("EGL renderer produced an empty image; falling back to TinyRenderer")
            self.renderer = "tiny"

    def _render_at(self, T_world_cam: np.ndarray) -> CameraImage:
        """Render RGB, metric depth and instance segmentation from an OpenCV camera pose
        ``T_world_cam`` (4, 4) [m] with the world's camera, projection and segmentation
        lookup (``self.camera``, ``self._projection``, ``self._seg_lut``, set by the world)."""
        return render_camera(
            self._pb,
            self._client,
            self.camera,
            self._projection,
            self.renderer,
            T_world_cam,
            self._seg_lut,
        )

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True)
class PlacedObject:
    """One object of a world's spec where the world puts it (all in the world frame): the
    table's and the rooms' worlds build each object's body and its ground truth from this."""

    obj: ObjectSpec
    T_world_obj: np.ndarray  # (4, 4) [m], the object's bottom centre
    position: object  # (x, y) [m]
    yaw_deg: float  # [deg]
    aabb: tuple[np.ndarray, np.ndarray]  # (lower, upper corner) [m]
    table: str | None = None  # the furniture it stands on (None on the arm's table)


class PyBulletWorld(PyBulletClient):
    """What the table's and the rooms' worlds share: a PyBullet client with a renderer, a
    spec's bodies built and numbered as segmentation instances, the robot's joints and links
    indexed, a camera riding on a link of the robot, and ground truth assembled from the
    placed objects.

    A world says what differs as class data and hooks: ``camera_link`` (the link its camera
    rides on), ``truth_frame`` (the ground truth's frame), ``_egl_probe`` (a pose and instance
    an EGL frame must show), :meth:`_default_camera`, :meth:`_configure` (checks and settings
    before the client connects), :meth:`_build` (its bodies), :meth:`_built` (after them),
    :meth:`_placed_objects` and :meth:`_scene_truth` (the ground truth besides the objects).
    """

    camera_link: str
    """The robot link whose frame is the camera's "hand" (``camera.T_hand_cam``)."""
    truth_frame: str
    """The ground truth's ``frame``."""
    _egl_probe: tuple[np.ndarray | None, int | None] = (None, None)
    """A camera pose (None: the robot's camera) and an instance (None: any) that a working
    EGL renderer shows."""

    def __init__(self, spec, camera: WristCameraConfig | None, renderer: str) -> None:
        import pybullet as pb

        if renderer not in RENDERERS:
            raise ConfigError(f"unknown renderer {renderer!r}; valid: {list(RENDERERS)}")
        self._configure()
        self.spec = spec
        self.camera = camera or self._default_camera()
        self.intrinsics = self.camera.intrinsics
        self._pb = pb
        self._client = pb.connect(pb.DIRECT)
        self._projection = gl_projection_matrix(self.intrinsics, self.camera.near, self.camera.far)
        self._start_renderer(renderer)
        self._build()
        self._built()
        self._check_renderer(renderer)

    # ------------------------------------------------------------------ hooks
    def _configure(self) -> None:
        """Check and keep a world's own settings, before its client connects."""

    def _default_camera(self) -> WristCameraConfig:
        return WristCameraConfig()

    def _build(self) -> None:
        raise NotImplementedError

    def _built(self) -> None:
        """After the bodies are built, before the renderer is checked."""

    def _placed_objects(self) -> list[PlacedObject]:
        """The spec's objects where this world puts them, in the spec's order."""
        raise NotImplementedError

    def _scene_truth(self) -> dict:
        """The ground truth's fields besides its scene, frame, objects and instances."""
        raise NotImplementedError

    # ------------------------------------------------------------------ building
    def _start_bodies(self, instance_names: dict[int, str]) -> None:
        """Begin the body bookkeeping with the fixed instances (id -> name)."""
        self._body_instance: dict[int, int] = {}
        self.instance_names = dict(instance_names)
        self.body_name: dict[int, str] = {}
        """Body id -> the name of what it belongs to (furniture, wall, object, ...)."""

    def _add_body(self, body: int, instance: int, name: str) -> None:
        """Record that ``body`` renders as ``instance`` and belongs to ``name``."""
        self._body_instance[body] = instance
        self.body_name[body] = name

    def _add_objects(self, first_instance: int) -> int:
        """Create a static body for each placed object, numbered from ``first_instance``;
        return the next free instance."""
        self.object_ids: dict[str, int] = {}
        self.object_instance: dict[str, int] = {}
        inst = first_instance
        for p in self._placed_objects():
            obj = p.obj
            body = create_object_body(self._pb, self._client, obj.kind, obj.color, p.T_world_obj)
            self.object_ids[obj.name] = body
            self.object_instance[obj.name] = inst
            self._add_body(body, inst, obj.name)
            self.instance_names[inst] = obj.name
            inst += 1
        return inst

    def _load_robot(self, urdf: str, base_link: str, instance: int, *args, **kwargs) -> None:
        """Load the robot's URDF (``args`` and ``kwargs`` as ``pb.loadURDF`` takes them) as
        ``self.robot_id``; index its joints and links (``base_link``: the base)."""
        pb, cid = self._pb, self._client
        self.robot_id = pb.loadURDF(urdf, *args, physicsClientId=cid, **kwargs)
        self._add_body(self.robot_id, instance, "robot")
        self._joint_index: dict[str, int] = {}
        self._link_index: dict[str, int] = {base_link: -1}
        for j in range(pb.getNumJoints(self.robot_id, physicsClientId=cid)):
            info = pb.getJointInfo(self.robot_id, j, physicsClientId=cid)
            self._joint_index[info[1].decode()] = j
            self._link_index[info[12].decode()] = j

    def _finish_bodies(self) -> None:
        """The segmentation lookup (body id -> instance) of all bodies built."""
        self._seg_lut = np.zeros(max(self._body_instance) + 2, dtype=np.uint16)
        for body, inst in self._body_instance.items():
            self._seg_lut[body] = inst

    def _egl_renders(self) -> bool:
        T, instance = self._egl_probe
        with _quiet_stdout():  # the first EGL frame prints the GL vendor from C
            img = self.render(T)
        if instance is None:
            return bool(np.any(img.segmentation != INSTANCE_NONE))
        return bool(np.any(img.segmentation == instance))

    # ------------------------------------------------------------------ state
    def link_pose(self, link: str) -> np.ndarray:
        """(4, 4) world pose of a robot link frame (the URDF link frame, not its CoM), as the
        simulator has it."""
        try:
            idx = self._link_index[link]
        except KeyError:
            raise ConfigError(f"no link {link!r}; links: {sorted(self._link_index)}") from None
        pb, cid = self._pb, self._client
        if idx == -1:
            pos, quat = pb.getBasePositionAndOrientation(self.robot_id, physicsClientId=cid)
        else:
            st = pb.getLinkState(
                self.robot_id, idx, computeForwardKinematics=True, physicsClientId=cid
            )
            pos, quat = st[4], st[5]
        return make_transform(quat_to_matrix(quat), pos)

    def T_world_cam(self) -> np.ndarray:
        """(4, 4) the true pose of the robot's camera (OpenCV optical frame)."""
        return self.link_pose(self.camera_link) @ self.camera.T_hand_cam

    # ------------------------------------------------------------------ rendering
    def render(self, T_world_cam: np.ndarray | None = None) -> CameraImage:
        """Render RGB, metric depth and instance segmentation from the robot's camera (or a
        camera at ``T_world_cam``, OpenCV optical frame)."""
        T = self.T_world_cam() if T_world_cam is None else np.asarray(T_world_cam)
        return self._render_at(T)

    # ------------------------------------------------------------------ ground truth
    def ground_truth(self) -> GroundTruth:
        """The spec's ground truth: its objects, what :meth:`_scene_truth` adds (table,
        areas, furniture) and the segmentation instances; no sound events (a scan adds
        those it inserts)."""
        objects = [
            object_truth(
                p.obj,
                self.object_instance[p.obj.name],
                p.T_world_obj,
                p.position,
                p.yaw_deg,
                p.aabb,
                table=p.table,
            )
            for p in self._placed_objects()
        ]
        return GroundTruth(
            scene=self.spec.to_dict(),
            frame=self.truth_frame,
            objects=tuple(objects),
            instances=dict(sorted(self.instance_names.items())),
            **self._scene_truth(),
        )


class SimWorld(PyBulletWorld):
    """A PyBullet scene built from a :class:`SceneSpec`, with a wrist camera on the Panda."""

    camera_link = "panda_hand"
    truth_frame = "world = robot base frame; table top at z = 0; metres"
    _egl_probe = (make_transform(np.diag([1.0, -1.0, -1.0]), (0.4, 0.0, 0.8)), INSTANCE_TABLE)

    def __init__(
        self,
        spec: SceneSpec,
        camera: WristCameraConfig | None = None,
        renderer: str = "auto",
    ) -> None:
        super().__init__(spec, camera, renderer)

    # ------------------------------------------------------------------ building

    def _build(self) -> None:
        pb, cid = self._pb, self._client
        data = pybullet_data_dir()
        t = self.spec.table
        self._start_bodies(
            {
                INSTANCE_NONE: "none",
                INSTANCE_FLOOR: "floor",
                INSTANCE_TABLE: "table",
                INSTANCE_ROBOT: "robot",
            }
        )

        floor = pb.loadURDF(str(data / "plane.urdf"), [0, 0, -t.height], physicsClientId=cid)
        self._add_body(floor, INSTANCE_FLOOR, "floor")

        half = [(t.x[1] - t.x[0]) / 2, (t.y[1] - t.y[0]) / 2, t.thickness / 2]
        center = [(t.x[0] + t.x[1]) / 2, (t.y[0] + t.y[1]) / 2, -t.thickness / 2]
        vis = pb.createVisualShape(
            pb.GEOM_BOX, halfExtents=half, rgbaColor=[*t.color, 1], physicsClientId=cid
        )
        col = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, physicsClientId=cid)
        self.table_id = pb.createMultiBody(0, col, vis, center, physicsClientId=cid)
        self._add_body(self.table_id, INSTANCE_TABLE, "table")
        # Table legs, so views past the edge look like a table and not a floating slab.
        for sx in (t.x[0] + 0.05, t.x[1] - 0.05):
            for sy in (t.y[0] + 0.05, t.y[1] - 0.05):
                lh = (t.height - t.thickness) / 2
                lv = pb.createVisualShape(
                    pb.GEOM_BOX,
                    halfExtents=[0.03, 0.03, lh],
                    rgbaColor=[*t.color, 1],
                    physicsClientId=cid,
                )
                leg = pb.createMultiBody(
                    0, -1, lv, [sx, sy, -t.thickness - lh], physicsClientId=cid
                )
                self._add_body(leg, INSTANCE_TABLE, "table")

        self._load_robot(
            str(panda_urdf_path()),
            "panda_link0",
            INSTANCE_ROBOT,
            [0, 0, 0],
            useFixedBase=True,
            flags=pb.URDF_USE_SELF_COLLISION_EXCLUDE_PARENT,
        )
        self._arm_joints = [self._joint_index[n] for n in ARM_JOINT_NAMES]
        self._finger_joints = [self._joint_index[n] for n in FINGER_JOINT_NAMES]
        self._add_objects(_FIRST_OBJECT_INSTANCE)
        self._finish_bodies()
        self.set_arm(HOME_Q)

    def _placed_objects(self) -> list[PlacedObject]:
        return [
            PlacedObject(obj, obj.T_world_obj, obj.position, obj.yaw_deg, obj.aabb())
            for obj in self.spec.objects
        ]

    # ------------------------------------------------------------------ robot state
    def set_arm(self, q: np.ndarray, finger_opening: float = FINGER_OPENING) -> None:
        """Set the 7 arm joints [rad] (and both fingers [m]) kinematically."""
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (7,):
            raise ConfigError(f"arm configuration must have shape (7,), got {q.shape}")
        for j, v in zip(self._arm_joints, q, strict=True):
            self._pb.resetJointState(self.robot_id, j, float(v), physicsClientId=self._client)
        for j in self._finger_joints:
            self._pb.resetJointState(self.robot_id, j, finger_opening, physicsClientId=self._client)

    def arm_q(self) -> np.ndarray:
        """(7,) current arm joint positions [rad]."""
        states = self._pb.getJointStates(
            self.robot_id, self._arm_joints, physicsClientId=self._client
        )
        return np.array([s[0] for s in states])

    def T_world_hand(self) -> np.ndarray:
        return self.link_pose("panda_hand")

    def min_clearance(self, max_distance: float = 0.05) -> float:
        """Smallest distance [m] between the robot and the table or any object.

        Capped at ``max_distance``; negative values are penetrations. The base link, bolted
        to the table, is not checked against the table.
        """
        pb, cid = self._pb, self._client
        best = max_distance
        for body in [self.table_id, *self.object_ids.values()]:
            for c in pb.getClosestPoints(self.robot_id, body, max_distance, physicsClientId=cid):
                if body == self.table_id and c[3] == -1:
                    continue
                best = min(best, c[8])
        return best

    # ------------------------------------------------------------------ ground truth
    def _scene_truth(self) -> dict:
        """The table and its areas."""
        t = self.spec.table
        return dict(
            table=TableTruth(x=t.x, y=t.y, top_z=0.0, height=t.height),
            areas=tuple(
                AreaTruth(name=a.name, aliases=a.aliases, x=a.x, y=a.y, center=a.center)
                for a in self.spec.areas
            ),
        )
