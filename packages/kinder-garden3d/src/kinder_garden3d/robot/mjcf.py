"""Generate the robot MJCF (for MuJoCo) from :func:`robot_description`.

The model contains:

* the planar base joints ``joint_x``, ``joint_y`` (slide) and ``joint_th`` (hinge) on the root
  body ``base_link`` (omitted with ``free_base=False``, for fixed-base inverse kinematics);
* the 7 Gen3 hinges ``joint_1`` … ``joint_7`` and the two finger slides, coupled by an equality
  constraint;
* actuators: position servos ``base_x``, ``base_y``, ``base_th`` on the base joints; torque motors
  ``arm_1`` … ``arm_7`` (limits 200/100 N m as in the TidyBot++ model), or joint position servos
  with ``arm_actuators="position"``; ``fingers_actuator``, a
  position-like servo with ctrl in [0, 255] (0 = open, 255 = closed);
* sites ``pinch_site`` (the tool centre point), ``flange`` and ``arm_base``; cameras ``base`` and
  ``wrist``;
* collision geoms (class ``collision``) with contype 2 / conaffinity 1, so the robot collides with
  world geoms of the default contype 1 but never with itself.

Every name can be prefixed (``prefix="robot_"``) so the robot can be embedded in a larger scene,
e.g. with ``mujoco.MjSpec.from_string(to_mjcf()).attach`` or by splicing the strings returned by
:func:`mjcf_parts`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal
from xml.sax.saxutils import quoteattr

import numpy as np

from kinder_garden3d.robot.description import (
    FINGER_STATE_MAX,
    GRIPPER_STROKE,
    Geom,
    Link,
    RobotDescription,
    robot_description,
    rpy_to_quat_xyzw,
)

#: Torque limits of the arm motors (N m), as in the TidyBot++ MJCF used by Dynamic3D.
ARM_TORQUE_LIMITS = (200.0, 200.0, 200.0, 200.0, 100.0, 100.0, 100.0)
#: Gains of the optional arm position servos (kp as in the prbench TidyBot++ copy; kv ours).
ARM_POSITION_KP = (2000.0, 2000.0, 2000.0, 2000.0, 500.0, 500.0, 500.0)
ARM_POSITION_KV = (100.0, 100.0, 100.0, 100.0, 30.0, 30.0, 30.0)


def _f(values: tuple[float, ...] | list[float]) -> str:
    return " ".join(repr(float(v)) for v in values)


def _quat_wxyz(rpy: tuple[float, float, float]) -> str:
    x, y, z, w = rpy_to_quat_xyzw(rpy)
    return _f((w, x, y, z))


@dataclass(frozen=True)
class MjcfParts:
    """The pieces of the robot MJCF, for splicing into another model."""

    worldbody: str
    actuator: str
    equality: str
    default: str


def _geom_xml(geom: Geom, prefix: str, indent: str) -> str:
    attrs = [
        f"name={quoteattr(prefix + geom.name)}",
        f'type="{geom.kind}"',
        f'size="{_f(geom.size)}"',
        f'pos="{_f(geom.pos)}"',
        f'quat="{_quat_wxyz(geom.rpy)}"',
        f'rgba="{_f(geom.rgba)}"',
    ]
    attrs.append('class="collision"' if geom.collide else 'class="visual"')
    return f"{indent}<geom {' '.join(attrs)}/>"


def mjcf_parts(
    desc: RobotDescription | None = None,
    prefix: str = "",
    free_base: bool = True,
    arm_actuators: Literal["motor", "position"] = "motor",
) -> MjcfParts:
    """Return the worldbody/actuator/equality/default fragments of the robot MJCF.

    ``arm_actuators="motor"`` gives torque motors (ctrl in N m, for a PD + gravity-compensation
    loop in Python, as upstream Dynamic3D); ``"position"`` gives joint position servos (ctrl in
    rad; kp :data:`ARM_POSITION_KP`, force limited to the same torque limits).
    """
    if arm_actuators not in ("motor", "position"):
        raise ValueError(f"arm_actuators must be 'motor' or 'position', got {arm_actuators!r}")
    desc = robot_description() if desc is None else desc
    children: dict[str | None, list[Link]] = {}
    for link in desc.links:
        children.setdefault(link.parent, []).append(link)

    def body(link: Link, depth: int) -> list[str]:
        ind = "  " * depth
        out = [
            f'{ind}<body name={quoteattr(prefix + link.name)} pos="{_f(link.pos)}" '
            f'quat="{_quat_wxyz(link.rpy)}">'
        ]
        if link.inertial is not None:
            com = (0.0, 0.0, 0.0) if link.parent is None else link.inertial.com
            out.append(
                f'{ind}  <inertial pos="{_f(com)}" mass="{link.inertial.mass!r}" '
                f'diaginertia="{_f(link.inertial.diag)}"/>'
            )
        if link.parent is None and free_base:
            for name, kind, axis in (
                (desc.base_joint_names[0], "slide", "1 0 0"),
                (desc.base_joint_names[1], "slide", "0 1 0"),
                (desc.base_joint_names[2], "hinge", "0 0 1"),
            ):
                out.append(
                    f'{ind}  <joint name={quoteattr(prefix + name)} type="{kind}" axis="{axis}" '
                    'damping="0" armature="0"/>'
                )
        joint = link.joint
        if joint is not None and joint.kind != "fixed":
            kind = "slide" if joint.kind == "prismatic" else "hinge"
            attrs = [
                f"name={quoteattr(prefix + joint.name)}",
                f'type="{kind}"',
                f'axis="{_f(joint.axis)}"',
            ]
            if joint.lower is not None and joint.upper is not None:
                attrs += ['limited="true"', f'range="{joint.lower!r} {joint.upper!r}"']
            else:
                attrs.append('limited="false"')
            attrs.append('armature="0.1"' if kind == "hinge" else 'armature="0.01"')
            attrs.append('damping="0.1"' if kind == "hinge" else 'damping="1.0"')
            out.append(f"{ind}  <joint {' '.join(attrs)}/>")
        out += [_geom_xml(geom, prefix, ind + "  ") for geom in link.geoms]
        for frame in desc.frames:
            if frame.link == link.name:
                out.append(
                    f'{ind}  <site name={quoteattr(prefix + frame.name)} pos="{_f(frame.pos)}" '
                    f'quat="{_quat_wxyz(frame.rpy)}" size="0.005" rgba="1 0 0 0.5" group="4"/>'
                )
        for camera in desc.cameras:
            if camera.link == link.name:
                out.append(
                    f"{ind}  <camera name={quoteattr(prefix + camera.name)} "
                    f'pos="{_f(camera.pos)}" quat="{_quat_wxyz(camera.rpy)}" '
                    f'fovy="{camera.fovy!r}"/>'
                )
        for child in children.get(link.name, []):
            out += body(child, depth + 1)
        out.append(f"{ind}</body>")
        return out

    roots = children[None]
    worldbody = "\n".join(line for root in roots for line in body(root, 2))

    acts: list[str] = []
    if free_base:
        for name, act, kp, kv in (
            (desc.base_joint_names[0], "base_x", 1.0e6, 5.0e4),
            (desc.base_joint_names[1], "base_y", 1.0e6, 5.0e4),
            (desc.base_joint_names[2], "base_th", 5.0e4, 1.0e3),
        ):
            acts.append(
                f"    <position name={quoteattr(prefix + act)} joint={quoteattr(prefix + name)} "
                f'kp="{kp!r}" kv="{kv!r}" ctrllimited="false"/>'
            )
    gains = zip(desc.arm_joint_names, ARM_TORQUE_LIMITS, ARM_POSITION_KP, ARM_POSITION_KV)
    for i, (name, limit, kp_arm, kv_arm) in enumerate(gains):
        act_name, joint_name = quoteattr(f"{prefix}arm_{i + 1}"), quoteattr(prefix + name)
        if arm_actuators == "motor":
            acts.append(
                f"    <motor name={act_name} joint={joint_name} "
                f'ctrlrange="{-limit!r} {limit!r}" ctrllimited="true"/>'
            )
        else:
            acts.append(
                f'    <position name={act_name} joint={joint_name} kp="{kp_arm!r}" '
                f'kv="{kv_arm!r}" forcerange="{-limit!r} {limit!r}" forcelimited="true" '
                'ctrllimited="false"/>'
            )
    # Finger servo: force = kp * (ctrl * stroke/2/255 - q) - kv * qdot on the left pad.
    kp, kv = 2000.0, 50.0
    gain = kp * 0.5 * GRIPPER_STROKE / 255.0
    acts.append(
        f"    <general name={quoteattr(prefix + 'fingers_actuator')} "
        f"joint={quoteattr(prefix + desc.finger_joint_names[0])} "
        f'ctrlrange="0 255" ctrllimited="true" forcerange="-235 235" forcelimited="true" '
        f'biastype="affine" gainprm="{gain!r}" biasprm="0 {-kp!r} {-kv!r}"/>'
    )
    actuator = "\n".join(acts)
    left, right = (prefix + n for n in desc.finger_joint_names)
    equality = f'    <joint joint1="{right}" joint2="{left}" polycoef="0 1 0 0 0"/>'
    default = (
        # contype 2 / conaffinity 1: the robot touches the world (contype 1) but not itself.
        '    <default class="collision"><geom group="3" contype="2" conaffinity="1"/></default>\n'
        '    <default class="visual"><geom group="2" contype="0" conaffinity="0"/></default>'
    )
    return MjcfParts(worldbody, actuator, equality, default)


def to_mjcf(
    desc: RobotDescription | None = None,
    prefix: str = "",
    free_base: bool = True,
    with_floor: bool = False,
    arm_actuators: Literal["motor", "position"] = "motor",
) -> str:
    """Return a standalone MJCF model of the robot as a string (see :func:`mjcf_parts`)."""
    parts = mjcf_parts(desc, prefix, free_base, arm_actuators)
    floor = (
        '    <geom name="floor" type="plane" size="5 5 0.1" rgba="0.8 0.8 0.8 1"/>\n'
        if with_floor
        else ""
    )
    return (
        f'<mujoco model="{(desc or robot_description()).name}">\n'
        '  <compiler angle="radian" autolimits="true"/>\n'
        '  <option timestep="0.0005" integrator="implicitfast"/>\n'
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


def finger_ctrl(finger_state: float) -> float:
    """The ``fingers_actuator`` ctrl (0-255) that closes the gripper to ``finger_state``."""
    return float(np.clip(finger_state / FINGER_STATE_MAX, 0.0, 1.0) * 255.0)
