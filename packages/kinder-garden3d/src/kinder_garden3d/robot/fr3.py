"""The Franka Research 3 (FR3) arm with a Robotiq 2F-85-style gripper, from primitive shapes.

A second robot model beside the mobile manipulator of :mod:`~kinder_garden3d.robot.description`:
a fixed-base 7-DoF arm (upstream kindergarden's ``FrankaPickPlace3D`` mounts it on a desk). It is
described with the same dataclasses (:class:`~kinder_garden3d.robot.description.RobotDescription`),
so the shared pure-numpy forward kinematics, the MJCF generator and the mink IK all take it::

    desc = fr3_description()
    forward_kinematics((x, y, yaw), q, desc=desc, base_z=mount_height)["pinch_site"]
    InverseKinematics(desc=desc).solve(position, quat_xyzw, base_pose=(x, y, yaw), base_z=...)
    mujoco.MjModel.from_xml_string(fr3_mjcf())

Kinematics (joint origins, axes, limits) are Franka's published FR3 values, the same as the
modified Denavit-Hartenberg table in Franka's robot documentation (d1 = 0.333, d3 = 0.316,
a4 = 0.0825, a5 = -0.0825, d5 = 0.384, a7 = 0.088, flange d = 0.107 m); ``tests/test_fr3_model.py``
checks the chain against that table. Sources and what is approximate are listed in ``README.md``.

Conventions are those of the mobile manipulator: the root link ``fr3_link0`` is the mount (placed
at ``(x, y, base_z)`` with yaw), the finger state ``s`` in [0, 0.8] drives two prismatic pads
(85 mm stroke), and the end effector is the site ``pinch_site`` between the pads with z the
approach direction and y the closing direction. Upstream's FR3 ``pinch_site`` has the same origin
and is turned -90 degrees about z (its x axis is the closing direction).
"""

from __future__ import annotations

import math
import re
from functools import cache

from kinder_garden3d.robot.description import (
    ARM_DARK,
    ARM_GREY,
    GRIPPER_COLOR,
    GRIPPER_STROKE,
    PAD_COLOR,
    Frame,
    Geom,
    Inertial,
    Joint,
    Link,
    RobotDescription,
    Vec3,
    _box_inertia,
    _cyl_inertia,
)
from kinder_garden3d.robot.mjcf import MjcfParts, mjcf_parts

_HALF_PI = math.pi / 2.0

#: Joint limits (rad) of the FR3's 7 joints (Franka FR3 datasheet).
FR3_JOINT_LIMITS: tuple[tuple[float, float], ...] = (
    (-2.7437, 2.7437),
    (-1.7837, 1.7837),
    (-2.9007, 2.9007),
    (-3.0421, -0.1518),
    (-2.8065, 2.8065),
    (0.5445, 4.5169),
    (-3.0159, 3.0159),
)
#: Maximum joint speeds (rad/s) and torques (N m) (Franka FR3 datasheet).
FR3_JOINT_VELOCITIES = (2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26)
FR3_JOINT_TORQUES = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)
#: Link masses (kg) of links 1-7 and their centres of mass in the link frames (MuJoCo Menagerie's
#: ``franka_fr3`` inertials, the figures upstream's model uses).
FR3_LINK_MASSES = (2.92747, 2.93554, 2.2449, 2.6156, 2.32712, 1.81704, 0.627143)
FR3_LINK_COMS: tuple[Vec3, ...] = (
    (4.128e-07, -0.0181251, -0.0386036),
    (0.00318289, -0.0743222, 0.00881461),
    (0.0407016, -0.00482006, -0.0289731),
    (-0.0459101, 0.0630493, -0.00851879),
    (-0.00160396, 0.0292536, -0.0972966),
    (0.0597131, -0.0410295, -0.0101693),
    (0.00452258, 0.00862619, -0.0161633),
)
#: Home configuration (rad), as upstream's ``FR3RobotEnv.HOME_QPOS``.
FR3_HOME: tuple[float, ...] = (0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853)
#: Flange distance along link 7's z axis (m) and the pinch point beyond the flange (m).
FR3_FLANGE_OFFSET = 0.107
FR3_PINCH_OFFSET = 0.112038
#: Gains of the arm's joint position servos (as upstream's FR3 actuators: kv = kp / 10).
FR3_POSITION_KP = (4500.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0)
#: Joint dynamics of the arm (MuJoCo Menagerie's ``franka_fr3``, upstream's model): viscous
#: damping (N m s/rad), rotor armature (kg m^2) and dry friction (N m) per joint.
FR3_JOINT_DAMPING = 0.21
FR3_JOINT_ARMATURE = (0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074)
FR3_JOINT_FRICTIONLOSS = (1.137, 1.137, 1.137, 1.137, 0.763, 0.44, 0.248)
#: Gripper masses (kg): the base with its housing, and each finger's linkage and pad.
_GRIPPER_MASS = 0.777441
_FINGER_MASS = 0.06


def _capsule(name: str, start: Vec3, end: Vec3, radius: float, rgba: tuple[float, ...]) -> Geom:
    """A capsule whose straight part runs from ``start`` to ``end`` (link frame)."""
    dx, dy, dz = (e - s for s, e in zip(start, end, strict=True))
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    mid: Vec3 = ((start[0] + end[0]) / 2, (start[1] + end[1]) / 2, (start[2] + end[2]) / 2)
    # Orient the capsule's z axis along the segment: roll about x, then pitch about y.
    roll = math.atan2(-dy, math.hypot(dx, dz))
    pitch = math.atan2(dx, dz)
    r, g, b, a = rgba
    return Geom(name, "capsule", (radius, length / 2.0), mid, (roll, pitch, 0.0), (r, g, b, a))


def _housing(name: str, radius: float, half_length: float, pos: Vec3 = (0.0, 0.0, 0.0)) -> Geom:
    """An actuator housing: a cylinder on the link's own joint axis (z)."""
    return Geom(name, "cylinder", (radius, half_length), pos, rgba=ARM_DARK)


def _joint(i: int) -> Joint:
    lower, upper = FR3_JOINT_LIMITS[i]
    return Joint(
        f"fr3_joint{i + 1}",
        "revolute",
        lower=lower,
        upper=upper,
        velocity=FR3_JOINT_VELOCITIES[i],
        effort=FR3_JOINT_TORQUES[i],
    )


def _inertial(i: int, radius: float, half_length: float) -> Inertial:
    mass = FR3_LINK_MASSES[i]
    return Inertial(mass, FR3_LINK_COMS[i], _cyl_inertia(mass, radius, half_length))


@cache
def fr3_description() -> RobotDescription:
    """Build (once) and return the FR3 / 2F-85 description (see the module docstring)."""
    grey = ARM_GREY
    # Link frames: origin and roll of each joint in its parent (Franka's FR3 kinematics); each
    # link's shapes follow the arm's outline between its joint and the next.
    link0 = Link(
        "fr3_link0",
        None,
        None,
        geoms=(
            Geom("link0_foot", "box", (0.11, 0.09, 0.01), (-0.03, 0.0, 0.01), rgba=ARM_DARK),
            _capsule("link0_body", (-0.01, 0.0, 0.06), (-0.01, 0.0, 0.11), 0.065, grey),
        ),
    )
    links = (
        Link(
            "fr3_link1", "fr3_link0", _joint(0), (0.0, 0.0, 0.333), (0.0, 0.0, 0.0),
            _inertial(0, 0.06, 0.1),
            (_capsule("link1_body", (0.0, 0.0, -0.16), (0.0, 0.0, -0.04), 0.06, grey),),
        ),
        Link(
            "fr3_link2", "fr3_link1", _joint(1), (0.0, 0.0, 0.0), (-_HALF_PI, 0.0, 0.0),
            _inertial(1, 0.06, 0.13),
            (
                _housing("link2_housing", 0.06, 0.06),
                _capsule("link2_body", (0.0, -0.05, 0.0), (0.0, -0.2, 0.0), 0.06, grey),
            ),
        ),
        Link(
            "fr3_link3", "fr3_link2", _joint(2), (0.0, -0.316, 0.0), (_HALF_PI, 0.0, 0.0),
            _inertial(2, 0.055, 0.08),
            (
                _capsule("link3_body", (0.0, 0.0, -0.1), (0.0, 0.0, -0.02), 0.055, grey),
                _capsule("link3_elbow", (0.0, 0.0, -0.02), (0.0825, 0.0, 0.0), 0.055, grey),
            ),
        ),
        Link(
            "fr3_link4", "fr3_link3", _joint(3), (0.0825, 0.0, 0.0), (_HALF_PI, 0.0, 0.0),
            _inertial(3, 0.055, 0.08),
            (
                _housing("link4_housing", 0.055, 0.055),
                _capsule("link4_body", (0.0, 0.0, 0.0), (-0.0825, 0.06, 0.0), 0.055, grey),
            ),
        ),
        Link(
            "fr3_link5", "fr3_link4", _joint(4), (-0.0825, 0.384, 0.0), (-_HALF_PI, 0.0, 0.0),
            _inertial(4, 0.05, 0.15),
            (_capsule("link5_body", (0.0, 0.0, -0.3), (0.0, 0.0, -0.06), 0.05, grey),),
        ),
        Link(
            "fr3_link6", "fr3_link5", _joint(5), (0.0, 0.0, 0.0), (_HALF_PI, 0.0, 0.0),
            _inertial(5, 0.045, 0.05),
            (
                _housing("link6_housing", 0.05, 0.05),
                _capsule("link6_body", (0.0, 0.0, 0.0), (0.088, 0.0, 0.0), 0.045, grey),
            ),
        ),
        Link(
            "fr3_link7", "fr3_link6", _joint(6), (0.088, 0.0, 0.0), (_HALF_PI, 0.0, 0.0),
            _inertial(6, 0.04, 0.04),
            (_capsule("link7_body", (0.0, 0.0, -0.02), (0.0, 0.0, 0.06), 0.045, grey),),
        ),
    )  # fmt: skip

    # Robotiq 2F-85 (simplified as in the mobile manipulator's model): the gripper frame is the
    # flange, z points out of the gripper and the pads close along y.
    palm_half: Vec3 = (0.03, 0.045, 0.04)
    gripper = Link(
        "gripper_base_link",
        "fr3_link7",
        Joint("end_effector", "fixed"),
        (0.0, 0.0, FR3_FLANGE_OFFSET),
        (0.0, 0.0, 0.0),
        Inertial(_GRIPPER_MASS, (0.0, 0.0, 0.035), _box_inertia(_GRIPPER_MASS, palm_half)),
        (Geom("palm", "box", palm_half, (0.0, 0.0, palm_half[2]), rgba=GRIPPER_COLOR),),
    )
    pad_half: Vec3 = (0.011, 0.0045, 0.0225)
    pad_z = FR3_PINCH_OFFSET + 0.013
    inner = 0.5 * GRIPPER_STROKE
    fingers = []
    for side, sign in (("left", 1.0), ("right", -1.0)):
        pad_y = sign * (inner + pad_half[1])
        fingers.append(
            Link(
                f"{side}_finger_link",
                "gripper_base_link",
                Joint(
                    f"{side}_finger_joint", "prismatic", (0.0, -sign, 0.0), 0.0, inner, 0.15, 235.0
                ),
                (0.0, 0.0, 0.0),
                (0.0, 0.0, 0.0),
                Inertial(_FINGER_MASS, (0.0, pad_y, pad_z), _box_inertia(_FINGER_MASS, pad_half)),
                (
                    Geom(f"{side}_pad", "box", pad_half, (0.0, pad_y, pad_z), rgba=PAD_COLOR),
                    Geom(
                        f"{side}_link",
                        "box",
                        (0.011, 0.006, 0.0125),
                        (0.0, sign * (inner + 0.006), 0.0925),
                        rgba=GRIPPER_COLOR,
                    ),
                ),
            )
        )
    frames = (
        Frame("pinch_site", "gripper_base_link", (0.0, 0.0, FR3_PINCH_OFFSET)),
        Frame("flange", "gripper_base_link", (0.0, 0.0, 0.0)),
        Frame("arm_base", "fr3_link0", (0.0, 0.0, 0.0)),
    )
    arm_joint_names = tuple(f"fr3_joint{i}" for i in range(1, 8))
    return RobotDescription(
        name="kinder_fr3_2f85",
        links=(link0, *links, gripper, *fingers),
        frames=frames,
        cameras=(),
        arm_joint_names=arm_joint_names,
        finger_joint_names=("left_finger_joint", "right_finger_joint"),
        retract=FR3_HOME,
    )


def fr3_mjcf_parts(prefix: str = "") -> MjcfParts:
    """The FR3's MJCF fragments (see :func:`~kinder_garden3d.robot.mjcf.mjcf_parts`), with the
    arm's joint dynamics and actuators replaced by upstream's FR3 values.

    Joints: damping :data:`FR3_JOINT_DAMPING`, armature :data:`FR3_JOINT_ARMATURE`, friction
    loss :data:`FR3_JOINT_FRICTIONLOSS`. Actuators: ``arm_1`` … ``arm_7``, joint position servos
    (ctrl in rad, ctrlrange = the joint range, kp :data:`FR3_POSITION_KP`, kv = kp / 10, force
    limited to :data:`FR3_JOINT_TORQUES`); ``fingers_actuator``, the gripper servo of the mobile
    manipulator's model (ctrl 0 = open … 255 = closed). The root body is the mount.
    """
    desc = fr3_description()
    parts = mjcf_parts(desc, prefix, free_base=False)
    body = parts.worldbody
    for i, name in enumerate(desc.arm_joint_names):
        found = re.search(rf'<joint name="{prefix}{name}"[^>]*/>', body)
        if found is None:
            raise RuntimeError(f"FR3 MJCF has no joint {prefix}{name}")
        new = re.sub(r'armature="[^"]*"', f'armature="{FR3_JOINT_ARMATURE[i]!r}"', found.group(0))
        new = re.sub(r'damping="[^"]*"', f'damping="{FR3_JOINT_DAMPING!r}"', new)
        new = new.replace("/>", f' frictionloss="{FR3_JOINT_FRICTIONLOSS[i]!r}"/>')
        body = body[: found.start()] + new + body[found.end() :]
    acts = []
    for i, name in enumerate(desc.arm_joint_names):
        lower, upper = FR3_JOINT_LIMITS[i]
        kp, torque = FR3_POSITION_KP[i], FR3_JOINT_TORQUES[i]
        acts.append(
            f'    <position name="{prefix}arm_{i + 1}" joint="{prefix}{name}" kp="{kp!r}" '
            f'kv="{kp / 10.0!r}" ctrlrange="{lower!r} {upper!r}" ctrllimited="true" '
            f'forcerange="{-torque!r} {torque!r}" forcelimited="true"/>'
        )
    fingers = [line for line in parts.actuator.splitlines() if "fingers_actuator" in line]
    if len(fingers) != 1:
        raise RuntimeError("the shared gripper model must define exactly one fingers_actuator")
    return MjcfParts(body, "\n".join([*acts, *fingers]), parts.equality, parts.default)


def fr3_mjcf(prefix: str = "", with_floor: bool = False) -> str:
    """A standalone MJCF of the FR3 on a fixed mount at the origin (:func:`fr3_mjcf_parts`)."""
    desc = fr3_description()
    parts = fr3_mjcf_parts(prefix)
    floor = (
        '    <geom name="floor" type="plane" size="5 5 0.1" rgba="0.8 0.8 0.8 1"/>\n'
        if with_floor
        else ""
    )
    return (
        f'<mujoco model="{desc.name}">\n'
        '  <compiler angle="radian" autolimits="true"/>\n'
        '  <option timestep="0.002" integrator="implicitfast"/>\n'
        "  <default>\n"
        f"{parts.default}\n"
        "  </default>\n"
        "  <worldbody>\n"
        f"{floor}"
        f"{parts.worldbody}\n"
        "  </worldbody>\n"
        "  <equality>\n"
        f"{parts.equality}\n"
        "  </equality>\n"
        "  <actuator>\n"
        f"{parts.actuator}\n"
        "  </actuator>\n"
        "</mujoco>\n"
    )
