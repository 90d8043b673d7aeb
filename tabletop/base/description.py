"""The project's wheeled base as its URDF describes it: wheel geometry, footprint, and where
the camera and the microphone sit on the mast.

``urdf/base/tabletop_base.urdf`` is read as XML (no simulator): the fixed joints from
``base_footprint`` to ``camera_optical`` and to ``mic`` give the mast's extrinsics, the wheel
joints and their cylinders give the :class:`DiffDriveParams`. :data:`TABLETOP_BASE` is the
same numbers written out; a test keeps the two equal.
"""

from __future__ import annotations

import functools
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tabletop.base.kinematics import DiffDriveParams
from tabletop.errors import AssetError
from tabletop.paths import URDF_DIR
from tabletop.transforms import make_transform, rotation_about

__all__ = [
    "BASE_FRAME",
    "CAMERA_FRAME",
    "MIC_FRAME",
    "TABLETOP_BASE",
    "WHEEL_JOINTS",
    "BaseDescription",
    "base_urdf_path",
    "load_base_description",
]

#: The base's frame on the floor, between the wheels: where :class:`BasePose` puts it.
BASE_FRAME = "base_footprint"
#: The camera's OpenCV optical frame on the mast.
CAMERA_FRAME = "camera_optical"
#: The microphone's frame on the mast.
MIC_FRAME = "mic"
#: The driven wheels' joints, (left, right).
WHEEL_JOINTS = ("left_wheel_joint", "right_wheel_joint")

#: The base of ``urdf/base/tabletop_base.urdf``: 5 cm wheels 0.24 m apart, up to 12 rad/s
#: (0.6 m/s), a chassis 0.35 m across.
TABLETOP_BASE = DiffDriveParams(
    wheel_radius=0.05, wheel_separation=0.24, max_wheel_speed=12.0, radius=0.175
)


def base_urdf_path() -> Path:
    """Path of the base's URDF (``urdf/base/tabletop_base.urdf``)."""
    path = URDF_DIR / "base" / "tabletop_base.urdf"
    if not path.is_file():
        raise AssetError(
            f"base URDF not found at {path}; install tabletop from a clone of the repository "
            "with `pip install -e .` so that urdf/ sits beside the package"
        )
    return path


@dataclass(frozen=True)
class BaseDescription:
    """What the URDF says about the base."""

    params: DiffDriveParams
    """Wheel radius and separation (wheel joints and cylinders), top wheel speed (the wheel
    joints' velocity limit), footprint radius (the chassis cylinder)."""
    T_base_cam: np.ndarray
    """(4, 4) float64 [m], read-only: the camera optical frame (OpenCV) in ``base_footprint``."""
    T_base_mic: np.ndarray
    """(4, 4) float64 [m], read-only: the microphone in ``base_footprint``."""
    wheel_joints: tuple[str, str] = WHEEL_JOINTS
    """(left, right) wheel joint names."""
    path: Path | None = None
    """The URDF it was read from."""


def _origin(el: ET.Element | None) -> np.ndarray:
    if el is None:
        return np.eye(4)
    xyz = [float(v) for v in el.get("xyz", "0 0 0").split()]
    r, p, y = (float(v) for v in el.get("rpy", "0 0 0").split())
    R = rotation_about("z", y) @ rotation_about("y", p) @ rotation_about("x", r)
    return make_transform(R, xyz)


def _frame(joints: dict, link: str, root: str, path: Path) -> np.ndarray:
    """(4, 4) pose of ``link`` in ``root`` through the joints' origins (at zero angle)."""
    T = np.eye(4)
    seen = set()
    while link != root:
        if link not in joints or link in seen:
            raise AssetError(f"{path}: link {link!r} is not connected to {root!r}")
        seen.add(link)
        parent, origin = joints[link]
        T = origin @ T
        link = parent
    return T


@functools.cache
def load_base_description(path: str | Path | None = None) -> BaseDescription:
    """Read the base's URDF (default: :func:`base_urdf_path`).

    Raises:
        AssetError: the file is missing or lacks a frame, wheel or chassis named above.
    """
    path = Path(path) if path is not None else base_urdf_path()
    try:
        robot = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as e:
        raise AssetError(f"cannot read the base URDF {path}: {e}") from None
    joints: dict[str, tuple[str, np.ndarray]] = {}
    joint_el: dict[str, ET.Element] = {}
    for j in robot.iter("joint"):
        child, parent = j.find("child").get("link"), j.find("parent").get("link")
        joints[child] = (parent, _origin(j.find("origin")))
        joint_el[j.get("name")] = j
    links = {lk.get("name"): lk for lk in robot.iter("link")}
    missing = [n for n in WHEEL_JOINTS if n not in joint_el]
    if missing or "chassis" not in links:
        raise AssetError(
            f"{path}: the base needs joints {list(WHEEL_JOINTS)} and a 'chassis' link; "
            f"missing: {missing or ['chassis']}"
        )

    def cylinder(link: str) -> ET.Element:
        el = links[link].find("visual/geometry/cylinder")
        if el is None:
            raise AssetError(f"{path}: link {link!r} needs a cylinder visual shape")
        return el

    wheels = []
    for name in WHEEL_JOINTS:
        j = joint_el[name]
        child = j.find("child").get("link")
        wheels.append(
            (
                _frame(joints, child, BASE_FRAME, path)[:3, 3],
                float(cylinder(child).get("radius")),
                float(j.find("limit").get("velocity")),
            )
        )
    (p_left, r_left, v_left), (p_right, r_right, v_right) = wheels
    if not math.isclose(r_left, r_right) or not math.isclose(v_left, v_right):
        raise AssetError(f"{path}: the two wheels differ in radius or velocity limit")
    params = DiffDriveParams(
        wheel_radius=r_left,
        wheel_separation=float(np.linalg.norm(p_left[:2] - p_right[:2])),
        max_wheel_speed=v_left,
        radius=float(cylinder("chassis").get("radius")),
    )
    T_cam = _frame(joints, CAMERA_FRAME, BASE_FRAME, path)
    T_mic = _frame(joints, MIC_FRAME, BASE_FRAME, path)
    for T in (T_cam, T_mic):
        T.setflags(write=False)
    return BaseDescription(params=params, T_base_cam=T_cam, T_base_mic=T_mic, path=path)
