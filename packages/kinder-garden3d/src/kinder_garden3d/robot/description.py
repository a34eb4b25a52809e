"""The single source of truth for the KinDER mobile manipulator.

A TidyBot++-style holonomic base, a Kinova Gen3 7-DoF arm and a Robotiq 2F-85-style two-finger
gripper, described with primitive shapes only. Both the URDF (pybullet, see ``urdf.py``) and the
MJCF (MuJoCo, see ``mjcf.py``) are generated from :func:`robot_description`. The numbers and their
sources are listed in ``README.md`` next to this file.

Conventions:

* Lengths in metres, angles in radians, masses in kilograms.
* Rotations of link origins are given as URDF roll-pitch-yaw (fixed-axis x, then y, then z);
  quaternions returned by helpers in this module are ordered (x, y, z, w).
* The planar base (x, y, yaw) is *not* a chain of links here: pybullet places the root link with
  ``resetBasePositionAndOrientation`` and the MJCF adds two slide joints and one hinge
  (``joint_x``, ``joint_y``, ``joint_th``) to the root body.
* The gripper opening is driven by one scalar, the *finger state* ``s`` in [0, 0.8] (0 = open,
  0.8 = closed, the range of the 2F-85 driver joint); each finger pad slides along the gripper's
  y axis by :func:`finger_joint_positions`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cache
from typing import Literal

import numpy as np
from numpy.typing import NDArray

GeomKind = Literal["box", "cylinder", "capsule", "sphere"]
JointKind = Literal["revolute", "continuous", "prismatic", "fixed"]

Vec3 = tuple[float, float, float]
Rgba = tuple[float, float, float, float]

_HALF_PI = math.pi / 2.0

ARM_GREY: Rgba = (0.62, 0.64, 0.67, 1.0)
ARM_DARK: Rgba = (0.25, 0.26, 0.28, 1.0)
BASE_COLOR: Rgba = (0.18, 0.19, 0.21, 1.0)
GRIPPER_COLOR: Rgba = (0.12, 0.12, 0.13, 1.0)
PAD_COLOR: Rgba = (0.35, 0.35, 0.37, 1.0)


@dataclass(frozen=True)
class Geom:
    """A primitive shape fixed to a link, posed in the link frame.

    ``size`` follows MuJoCo conventions: box = half extents (3), cylinder and capsule =
    (radius, half length of the straight part) along the geom's local z axis, sphere = (radius,).
    """

    name: str
    kind: GeomKind
    size: tuple[float, ...]
    pos: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)
    rgba: Rgba = ARM_GREY
    collide: bool = True


@dataclass(frozen=True)
class Inertial:
    """Mass and centre of mass in the link frame; the inertia tensor is diagonal (``diag``)."""

    mass: float
    com: Vec3
    diag: Vec3


@dataclass(frozen=True)
class Joint:
    """The joint that connects a link to its parent.

    ``lower``/``upper`` are ``None`` for continuous joints. ``velocity`` is the published maximum
    speed (rad/s or m/s) and ``effort`` the torque (N m) or force (N) limit.
    """

    name: str
    kind: JointKind
    axis: Vec3 = (0.0, 0.0, 1.0)
    lower: float | None = None
    upper: float | None = None
    velocity: float = 0.0
    effort: float = 0.0


@dataclass(frozen=True)
class Link:
    """One rigid link: its parent, the joint origin (``pos``, ``rpy``) and its geometry."""

    name: str
    parent: str | None
    joint: Joint | None
    pos: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)
    inertial: Inertial | None = None
    geoms: tuple[Geom, ...] = ()


@dataclass(frozen=True)
class Frame:
    """A named frame (site) rigidly attached to a link."""

    name: str
    link: str
    pos: Vec3
    rpy: Vec3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Camera:
    """A camera rigidly attached to a link.

    MuJoCo convention: the camera looks along its local −z axis with +y up. ``fovy`` in degrees.
    """

    name: str
    link: str
    pos: Vec3
    rpy: Vec3
    fovy: float


@dataclass(frozen=True)
class RobotDescription:
    """The complete robot: links in parent-before-child order, frames and cameras."""

    name: str
    links: tuple[Link, ...]
    frames: tuple[Frame, ...]
    cameras: tuple[Camera, ...]
    arm_joint_names: tuple[str, ...]
    finger_joint_names: tuple[str, ...]
    base_joint_names: tuple[str, str, str] = ("joint_x", "joint_y", "joint_th")
    base_mass: float = 60.0
    retract: tuple[float, ...] = field(default_factory=tuple)

    def link(self, name: str) -> Link:
        """Return the link called ``name``; raise ValueError naming the valid links otherwise."""
        for link in self.links:
            if link.name == name:
                return link
        valid = ", ".join(link.name for link in self.links)
        raise ValueError(f"Unknown link {name!r}; expected one of: {valid}")

    def frame(self, name: str) -> Frame:
        """Return the frame called ``name``."""
        for frame in self.frames:
            if frame.name == name:
                return frame
        valid = ", ".join(frame.name for frame in self.frames)
        raise ValueError(f"Unknown frame {name!r}; expected one of: {valid}")

    def camera(self, name: str) -> Camera:
        """Return the camera called ``name``."""
        for camera in self.cameras:
            if camera.name == name:
                return camera
        valid = ", ".join(camera.name for camera in self.cameras)
        raise ValueError(f"Unknown camera {name!r}; expected one of: {valid}")

    @property
    def arm_joint_limits(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower and upper limits of the 7 arm joints (±inf for continuous joints)."""
        lower, upper = [], []
        for name in self.arm_joint_names:
            joint = _joint_by_name(self, name)
            lower.append(-math.inf if joint.lower is None else joint.lower)
            upper.append(math.inf if joint.upper is None else joint.upper)
        return np.array(lower), np.array(upper)


def _joint_by_name(desc: RobotDescription, name: str) -> Joint:
    for link in desc.links:
        if link.joint is not None and link.joint.name == name:
            return link.joint
    raise ValueError(f"Unknown joint {name!r}")


# ---------------------------------------------------------------------------------------------
# Published parameters (see README.md for sources).

#: Kinova Gen3 arm mount on the TidyBot++ base, in the base frame.
ARM_MOUNT: Vec3 = (0.1199, 0.0, 0.3948)

#: Retract configuration of the 7 arm joints (rad): [0, -20, 180, -143, 0, -50, 90] degrees.
RETRACT: tuple[float, ...] = (0.0, -0.35, -math.pi, -2.5, 0.0, -0.87, math.pi / 2)

#: Robotiq 2F-85 stroke (m) and the driver-joint range that maps onto it.
GRIPPER_STROKE = 0.085
FINGER_STATE_MAX = 0.8

#: Distance from the gripper coupling face (the Gen3 end-effector flange) to the pinch point.
PINCH_OFFSET = 0.145

#: Offset of the flange from the Gen3 bracelet link frame (Kinova URDF ``end_effector`` joint).
FLANGE_OFFSET = 0.061525

_LARGE_VEL = 1.3963  # 80 deg/s, Gen3 large actuators (joints 1-4)
_SMALL_VEL = 1.2218  # 70 deg/s, Gen3 small actuators (joints 5-7)
_LARGE_EFFORT = 39.0
_SMALL_EFFORT = 9.0


def finger_joint_positions(finger_state: float) -> tuple[float, float]:
    """Slide of the (left, right) finger pads for a finger state in [0, FINGER_STATE_MAX].

    Each pad travels half the 85 mm stroke linearly from fully open (0) to closed; values outside
    the range are clipped.
    """
    s = min(max(float(finger_state), 0.0), FINGER_STATE_MAX)
    travel = 0.5 * GRIPPER_STROKE * s / FINGER_STATE_MAX
    return travel, travel


def gripper_opening(finger_state: float) -> float:
    """Distance between the inner faces of the pads for a finger state."""
    left, right = finger_joint_positions(finger_state)
    return GRIPPER_STROKE - left - right


def _box_inertia(mass: float, half: Vec3) -> Vec3:
    x, y, z = (2.0 * h for h in half)
    return (
        mass * (y * y + z * z) / 12.0,
        mass * (x * x + z * z) / 12.0,
        mass * (x * x + y * y) / 12.0,
    )


def _cyl_inertia(mass: float, radius: float, half_length: float) -> Vec3:
    length = 2.0 * half_length
    ixx = mass * (3.0 * radius * radius + length * length) / 12.0
    return (ixx, ixx, 0.5 * mass * radius * radius)


def _arm_link(
    name: str,
    parent: str,
    joint: Joint,
    pos: Vec3,
    rpy: Vec3,
    mass: float,
    com: Vec3,
    segment_to: Vec3,
    radius: float,
    color: Rgba = ARM_GREY,
) -> Link:
    """An arm link drawn as a capsule from the joint axis to the next joint origin.

    ``segment_to`` is the next joint's origin expressed in this link's frame; an actuator housing
    cylinder sits on this link's own joint axis.
    """
    sx, sy, sz = segment_to
    length = math.sqrt(sx * sx + sy * sy + sz * sz)
    mid: Vec3 = (sx / 2.0, sy / 2.0, sz / 2.0)
    # Orient the capsule's z axis along the segment: roll about x then pitch about y.
    roll = math.atan2(-sy, math.hypot(sx, sz)) if length > 0 else 0.0
    pitch = math.atan2(sx, sz) if length > 0 else 0.0
    geoms = (
        Geom(f"{name}_housing", "cylinder", (radius, radius * 0.9), (0.0, 0.0, 0.0), rgba=ARM_DARK),
        Geom(
            f"{name}_body",
            "capsule",
            (radius * 0.92, max(length / 2.0 - radius, 1e-3)),
            mid,
            (roll, pitch, 0.0),
            rgba=color,
        ),
    )
    inertia = _cyl_inertia(mass, radius, max(length / 2.0, radius))
    return Link(name, parent, joint, pos, rpy, Inertial(mass, com, inertia), geoms)


@cache
def robot_description() -> RobotDescription:
    """Build (once) and return the TidyBot++ / Gen3 / 2F-85 description."""
    # --- Mobile base (root link). The chassis top carries the arm mount.
    chassis_half: Vec3 = (0.2, 0.2, 0.18)
    base_geoms = (
        Geom("chassis", "box", chassis_half, (0.0, 0.0, 0.02 + chassis_half[2]), rgba=BASE_COLOR),
        Geom(
            "top_plate",
            "box",
            (0.2, 0.2, 0.0074),
            (0.0, 0.0, ARM_MOUNT[2] - 0.0074),
            rgba=(0.55, 0.45, 0.32, 1.0),
        ),
        Geom(
            "camera_mount",
            "box",
            (0.02, 0.04, 0.02),
            (0.2525 - 0.025, 0.0, 0.335),
            rgba=ARM_DARK,
            collide=False,
        ),
    )
    base = Link(
        "base_link",
        None,
        None,
        inertial=Inertial(60.0, (0.0, 0.0, 0.0), _box_inertia(60.0, chassis_half)),
        geoms=base_geoms,
    )

    # --- Kinova Gen3 base (fixed on the mount).
    gen3_base = Link(
        "gen3_base_link",
        "base_link",
        Joint("arm_mount", "fixed"),
        ARM_MOUNT,
        (0.0, 0.0, 0.0),
        Inertial(1.697, (-0.000648, -0.000166, 0.084487), _cyl_inertia(1.697, 0.05, 0.078)),
        (Geom("gen3_base", "cylinder", (0.05, 0.066), (0.0, 0.0, 0.066), rgba=ARM_GREY),),
    )

    lv, sv, le, se = _LARGE_VEL, _SMALL_VEL, _LARGE_EFFORT, _SMALL_EFFORT
    j = [
        Joint("joint_1", "continuous", velocity=lv, effort=le),
        Joint("joint_2", "revolute", lower=-2.2497, upper=2.2497, velocity=lv, effort=le),
        Joint("joint_3", "continuous", velocity=lv, effort=le),
        Joint("joint_4", "revolute", lower=-2.5796, upper=2.5796, velocity=lv, effort=le),
        Joint("joint_5", "continuous", velocity=sv, effort=se),
        Joint("joint_6", "revolute", lower=-2.0996, upper=2.0996, velocity=sv, effort=se),
        Joint("joint_7", "continuous", velocity=sv, effort=se),
    ]
    arm = (
        _arm_link(
            "shoulder_link", "gen3_base_link", j[0], (0.0, 0.0, 0.15643), (math.pi, 0.0, 0.0),
            1.3773, (-2.3e-05, -0.010364, -0.07336), (0.0, 0.005375, -0.12838), 0.046,
        ),
        _arm_link(
            "half_arm_1_link", "shoulder_link", j[1], (0.0, 0.005375, -0.12838),
            (_HALF_PI, 0.0, 0.0), 1.1636, (-4.4e-05, -0.09958, -0.013278),
            (0.0, -0.21038, -0.006375), 0.046,
        ),
        _arm_link(
            "half_arm_2_link", "half_arm_1_link", j[2], (0.0, -0.21038, -0.006375),
            (-_HALF_PI, 0.0, 0.0), 1.1636, (-4.4e-05, -0.006641, -0.117892),
            (0.0, 0.006375, -0.21038), 0.046,
        ),
        _arm_link(
            "forearm_link", "half_arm_2_link", j[3], (0.0, 0.006375, -0.21038),
            (_HALF_PI, 0.0, 0.0), 0.9302, (-1.8e-05, -0.075478, -0.015006),
            (0.0, -0.20843, -0.006375), 0.042,
        ),
        _arm_link(
            "spherical_wrist_1_link", "forearm_link", j[4], (0.0, -0.20843, -0.006375),
            (-_HALF_PI, 0.0, 0.0), 0.6781, (1e-06, -0.009432, -0.063883),
            (0.0, 0.00017505, -0.10593), 0.036,
        ),
        _arm_link(
            "spherical_wrist_2_link", "spherical_wrist_1_link", j[5],
            (0.0, 0.00017505, -0.10593), (_HALF_PI, 0.0, 0.0), 0.6781,
            (1e-06, -0.045483, -0.00965), (0.0, -0.10593, -0.00017505), 0.036,
        ),
    )  # fmt: skip
    bracelet = Link(
        "bracelet_link",
        "spherical_wrist_2_link",
        j[6],
        (0.0, -0.10593, -0.00017505),
        (-_HALF_PI, 0.0, 0.0),
        Inertial(0.5006, (-9.3e-05, 0.000132, -0.022905), _cyl_inertia(0.5006, 0.04, 0.03)),
        (
            Geom("bracelet", "cylinder", (0.04, 0.028), (0.0, 0.0, -0.033), rgba=ARM_GREY),
            Geom(
                "vision_module",
                "box",
                (0.022, 0.02, 0.018),
                (0.0, -0.045, -0.045),
                rgba=ARM_DARK,
                collide=False,
            ),
        ),
    )

    # --- Robotiq 2F-85 (simplified). Its frame is the Gen3 flange: z points out of the gripper,
    # the pads close along y.
    palm_half: Vec3 = (0.03, 0.045, 0.04)
    gripper = Link(
        "gripper_base_link",
        "bracelet_link",
        Joint("end_effector", "fixed"),
        (0.0, 0.0, -FLANGE_OFFSET),
        # Kinova's flange frame (roll pi), turned a quarter so the pads close across the wrist
        # camera's view.
        (math.pi, 0.0, _HALF_PI),
        Inertial(0.725, (0.0, 0.0, 0.05), _box_inertia(0.725, palm_half)),
        (
            Geom("coupling", "cylinder", (0.0375, 0.007), (0.0, 0.0, 0.007), rgba=GRIPPER_COLOR),
            Geom("palm", "box", palm_half, (0.0, 0.0, 0.014 + palm_half[2]), rgba=GRIPPER_COLOR),
        ),
    )
    pad_half: Vec3 = (0.011, 0.0045, 0.03)
    pad_z = PINCH_OFFSET - 0.005
    inner = 0.5 * GRIPPER_STROKE
    fingers = (
        Link(
            "left_finger_link",
            "gripper_base_link",
            Joint("left_finger_joint", "prismatic", (0.0, -1.0, 0.0), 0.0, inner, 0.15, 235.0),
            (0.0, 0.0, 0.0),
            (0.0, 0.0, 0.0),
            Inertial(0.1, (0.0, inner + pad_half[1], pad_z), _box_inertia(0.1, pad_half)),
            (
                Geom(
                    "left_pad", "box", pad_half, (0.0, inner + pad_half[1], pad_z), rgba=PAD_COLOR
                ),
                Geom(
                    "left_link",
                    "box",
                    (0.011, 0.006, 0.025),
                    (0.0, inner + 0.006, 0.085),
                    rgba=GRIPPER_COLOR,
                ),
            ),
        ),
        Link(
            "right_finger_link",
            "gripper_base_link",
            Joint("right_finger_joint", "prismatic", (0.0, 1.0, 0.0), 0.0, inner, 0.15, 235.0),
            (0.0, 0.0, 0.0),
            (0.0, 0.0, 0.0),
            Inertial(0.1, (0.0, -inner - pad_half[1], pad_z), _box_inertia(0.1, pad_half)),
            (
                Geom(
                    "right_pad", "box", pad_half, (0.0, -inner - pad_half[1], pad_z), rgba=PAD_COLOR
                ),
                Geom(
                    "right_link",
                    "box",
                    (0.011, 0.006, 0.025),
                    (0.0, -inner - 0.006, 0.085),
                    rgba=GRIPPER_COLOR,
                ),
            ),
        ),
    )

    frames = (
        # The tool centre point between the pads: z = approach, y = closing direction.
        Frame("pinch_site", "gripper_base_link", (0.0, 0.0, PINCH_OFFSET)),
        Frame("flange", "gripper_base_link", (0.0, 0.0, 0.0)),
        Frame("arm_base", "gen3_base_link", (0.0, 0.0, 0.0)),
    )
    cameras = (
        # TidyBot++ base camera: MuJoCo euler (0, -pi/4, -pi/2), i.e. looking forward, 45 deg down.
        Camera(
            "base",
            "base_link",
            (0.2525, 0.0, 0.335),
            mujoco_euler_to_rpy((0.0, -math.pi / 4, -_HALF_PI)),
            52.2,
        ),
        # On the Gen3 vision module, looking along the approach direction (bracelet -z).
        Camera("wrist", "bracelet_link", (0.0, -0.05639, -0.058475), (0.0, 0.0, math.pi), 41.8),
    )
    return RobotDescription(
        name="kinder_tidybot_gen3_2f85",
        links=(base, gen3_base, *arm, bracelet, gripper, *fingers),
        frames=frames,
        cameras=cameras,
        arm_joint_names=tuple(joint.name for joint in j),
        finger_joint_names=("left_finger_joint", "right_finger_joint"),
        retract=RETRACT,
    )


# ---------------------------------------------------------------------------------------------
# Rotation helpers (pure numpy, shared by the generators and the pybullet backend).


def rpy_to_matrix(rpy: Vec3) -> NDArray[np.float64]:
    """URDF roll-pitch-yaw (R = Rz(yaw) Ry(pitch) Rx(roll)) to a rotation matrix."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrix_to_quat_xyzw(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrix to a unit quaternion (x, y, z, w) with w >= 0."""
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    quat = np.array(q)
    quat /= np.linalg.norm(quat)
    if quat[3] < 0.0:
        quat = -quat
    return quat


def quat_xyzw_to_matrix(q: NDArray[np.float64] | tuple[float, ...]) -> NDArray[np.float64]:
    """Unit quaternion (x, y, z, w) to a rotation matrix."""
    x, y, z, w = (float(v) for v in q)
    n = x * x + y * y + z * z + w * w
    s = 2.0 / n if n > 0 else 0.0
    return np.array(
        [
            [1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)],
            [s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)],
            [s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)],
        ]
    )


def matrix_to_rpy(m: NDArray[np.float64]) -> Vec3:
    """Rotation matrix to URDF roll-pitch-yaw (inverse of :func:`rpy_to_matrix`)."""
    pitch = math.asin(max(-1.0, min(1.0, -float(m[2, 0]))))
    if abs(math.cos(pitch)) > 1e-9:
        roll = math.atan2(float(m[2, 1]), float(m[2, 2]))
        yaw = math.atan2(float(m[1, 0]), float(m[0, 0]))
    else:  # gimbal lock: put everything in yaw
        roll = 0.0
        yaw = math.atan2(-float(m[0, 1]), float(m[1, 1]))
    return (roll, pitch, yaw)


def mujoco_euler_to_rpy(euler: Vec3) -> Vec3:
    """MuJoCo's default ``euler`` (intrinsic x-y-z: R = Rx Ry Rz) as URDF roll-pitch-yaw."""
    rx = rpy_to_matrix((euler[0], 0.0, 0.0))
    ry = rpy_to_matrix((0.0, euler[1], 0.0))
    rz = rpy_to_matrix((0.0, 0.0, euler[2]))
    return matrix_to_rpy(rx @ ry @ rz)


def rpy_to_quat_xyzw(rpy: Vec3) -> NDArray[np.float64]:
    """URDF roll-pitch-yaw to a quaternion (x, y, z, w)."""
    return matrix_to_quat_xyzw(rpy_to_matrix(rpy))


def transform(pos: Vec3 | NDArray[np.float64], rot: NDArray[np.float64]) -> NDArray[np.float64]:
    """A 4x4 homogeneous transform from a position and a rotation matrix."""
    t = np.eye(4)
    t[:3, :3] = rot
    t[:3, 3] = pos
    return t


def forward_kinematics(
    base_pose: tuple[float, float, float],
    arm_joints: NDArray[np.float64] | tuple[float, ...],
    finger_state: float = 0.0,
    base_z: float = 0.0,
    desc: RobotDescription | None = None,
) -> dict[str, NDArray[np.float64]]:
    """Pure-numpy forward kinematics: a 4x4 world transform for every link and frame.

    ``base_pose`` is (x, y, yaw) of the base; ``arm_joints`` the 7 arm joint angles. ``desc`` is
    the robot (default: the mobile manipulator; e.g. :func:`~kinder_garden3d.robot.fr3.
    fr3_description` for the FR3 arm, whose root is its mount). This is the reference
    implementation the URDF and MJCF are both tested against.
    """
    desc = robot_description() if desc is None else desc
    if len(arm_joints) != len(desc.arm_joint_names):
        raise ValueError(f"Expected {len(desc.arm_joint_names)} arm joints, got {len(arm_joints)}")
    x, y, yaw = base_pose
    values = dict(zip(desc.arm_joint_names, (float(q) for q in arm_joints), strict=True))
    values.update(zip(desc.finger_joint_names, finger_joint_positions(finger_state), strict=True))
    world: dict[str, NDArray[np.float64]] = {}
    for link in desc.links:
        if link.parent is None:
            world[link.name] = transform((x, y, base_z), rpy_to_matrix((0.0, 0.0, yaw)))
            continue
        origin = world[link.parent] @ transform(link.pos, rpy_to_matrix(link.rpy))
        joint = link.joint
        if joint is not None and joint.kind != "fixed":
            q = values[joint.name]
            axis = np.array(joint.axis, dtype=float)
            if joint.kind == "prismatic":
                motion = transform(axis * q, np.eye(3))
            else:
                motion = transform((0.0, 0.0, 0.0), _axis_angle(axis, q))
            origin = origin @ motion
        world[link.name] = origin
    for frame in desc.frames:
        world[frame.name] = world[frame.link] @ transform(frame.pos, rpy_to_matrix(frame.rpy))
    return world


def _axis_angle(axis: NDArray[np.float64], angle: float) -> NDArray[np.float64]:
    axis = axis / np.linalg.norm(axis)
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    rot: NDArray[np.float64] = np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)
    return rot
