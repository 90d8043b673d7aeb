"""A MuJoCo model of the Panda and its environment, generated at run time from the one URDF.

The URDF is rewritten in memory: ``package://`` mesh paths become absolute, a
``<mujoco><compiler fusestatic="false" discardvisual="true"/></mujoco>`` block keeps every URDF
link as a body (the TCP ``panda_grasptarget`` included) and drops visual meshes, and both
finger joints become fixed joints at the given opening, so the model has exactly the 7 arm
joints, in the same order as :class:`tabletop.arm.model.PandaModel`. Obstacles become world
geoms named after them (``obs_<k>_<name>``); robot geoms are named ``<link>_collision``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from tabletop.arm.model import ARM_JOINT_NAMES, FINGER_JOINT_NAMES
from tabletop.arm.obstacles import Box, ConvexObstacle, Cylinder, Obstacle
from tabletop.errors import ConfigError
from tabletop.paths import panda_urdf_path
from tabletop.transforms import quat_from_matrix

__all__ = ["build_mujoco_model", "obstacle_geom_names", "robot_geom_name", "urdf_for_mujoco"]


def robot_geom_name(link: str) -> str:
    """Name of the collision geom of a robot link in the generated model."""
    return f"{link}_collision"


def obstacle_geom_names(obstacles: Sequence[Obstacle]) -> list[str]:
    """Names of the obstacle geoms, in the order of ``obstacles``."""
    return [f"obs_{k}_{getattr(ob, 'name', 'obstacle')}" for k, ob in enumerate(obstacles)]


def urdf_for_mujoco(urdf_path: str | Path | None = None, finger_opening: float = 0.04) -> str:
    """The URDF text rewritten for MuJoCo (see the module docstring)."""
    path = Path(urdf_path) if urdf_path is not None else panda_urdf_path()
    root = ET.fromstring(path.read_text())
    pkg = path.parent.resolve()
    for mesh in root.iter("mesh"):
        fn = mesh.get("filename", "")
        if fn.startswith("package://"):
            mesh.set("filename", str(pkg / fn[len("package://") :]))
    for joint in root.findall("joint"):
        if joint.get("name") in FINGER_JOINT_NAMES:
            axis = np.array(joint.find("axis").get("xyz").split(), dtype=float)
            origin = joint.find("origin")
            xyz = np.array(origin.get("xyz").split(), dtype=float) + finger_opening * axis
            origin.set("xyz", " ".join(f"{v:.9g}" for v in xyz))
            joint.set("type", "fixed")
            for tag in ("axis", "limit", "mimic"):
                for el in joint.findall(tag):
                    joint.remove(el)
    mj = ET.Element("mujoco")
    ET.SubElement(
        mj, "compiler", {"fusestatic": "false", "discardvisual": "true", "balanceinertia": "true"}
    )
    root.insert(0, mj)
    return ET.tostring(root, encoding="unicode")


def build_mujoco_model(
    obstacles: Sequence[Obstacle] = (),
    *,
    urdf_path: str | Path | None = None,
    finger_opening: float = 0.04,
):
    """Compile a ``mujoco.MjModel`` of the Panda (7 joints) with ``obstacles`` as world geoms."""
    import mujoco

    spec = mujoco.MjSpec.from_string(urdf_for_mujoco(urdf_path, finger_opening))
    for body in spec.bodies:
        for i, g in enumerate(body.geoms):
            g.name = robot_geom_name(body.name) if i == 0 else f"{body.name}_collision{i}"
    for name, ob in zip(obstacle_geom_names(obstacles), obstacles, strict=True):
        if isinstance(ob, Box):
            q = quat_from_matrix(ob.rotation)  # (x, y, z, w)
            spec.worldbody.add_geom(
                name=name,
                type=mujoco.mjtGeom.mjGEOM_BOX,
                size=ob.half_extents.tolist(),
                pos=ob.center.tolist(),
                quat=[q[3], q[0], q[1], q[2]],
            )
        elif isinstance(ob, Cylinder):
            spec.worldbody.add_geom(
                name=name,
                type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                size=[ob.radius, ob.height / 2, 0.0],
                pos=ob.center.tolist(),
            )
        elif isinstance(ob, ConvexObstacle):
            c = ob.vertices.mean(axis=0)
            spec.add_mesh(name=f"{name}_mesh", uservert=(ob.vertices - c).ravel().tolist())
            spec.worldbody.add_geom(
                name=name, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"{name}_mesh", pos=c.tolist()
            )
        else:
            raise ConfigError(
                f"the MuJoCo model cannot hold a {type(ob).__name__}; valid: Box, Cylinder, "
                "ConvexObstacle"
            )
    model = spec.compile()
    names = tuple(model.joint(i).name for i in range(model.njnt))
    if names != ARM_JOINT_NAMES:
        raise ConfigError(f"generated MuJoCo model has joints {names}, expected {ARM_JOINT_NAMES}")
    return model
