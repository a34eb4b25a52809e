"""Generate the robot URDF (for pybullet) from :func:`robot_description`.

The planar base has no joints in the URDF: the root link ``base_link`` is placed with
``resetBasePositionAndOrientation``. Its inertial frame is the link frame, so pybullet's base pose
equals the link pose. Capsules use pybullet's ``<capsule>`` URDF extension.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from functools import cache
from pathlib import Path
from xml.sax.saxutils import quoteattr

from kinder_garden3d.robot.description import (
    Geom,
    Link,
    RobotDescription,
    robot_description,
)


def _f(values: tuple[float, ...]) -> str:
    return " ".join(repr(float(v)) for v in values)


def _geometry(geom: Geom) -> str:
    if geom.kind == "box":
        return f'<box size="{_f(tuple(2.0 * h for h in geom.size))}"/>'
    if geom.kind == "sphere":
        return f'<sphere radius="{geom.size[0]!r}"/>'
    radius, half = geom.size
    return f'<{geom.kind} radius="{radius!r}" length="{2.0 * half!r}"/>'


def _link_xml(link: Link) -> str:
    lines = [f"  <link name={quoteattr(link.name)}>"]
    if link.inertial is not None:
        ixx, iyy, izz = link.inertial.diag
        com = (0.0, 0.0, 0.0) if link.parent is None else link.inertial.com
        lines += [
            "    <inertial>",
            f'      <origin xyz="{_f(com)}" rpy="0 0 0"/>',
            f'      <mass value="{link.inertial.mass!r}"/>',
            f'      <inertia ixx="{ixx!r}" ixy="0" ixz="0" iyy="{iyy!r}" iyz="0" izz="{izz!r}"/>',
            "    </inertial>",
        ]
    for geom in link.geoms:
        origin = f'<origin xyz="{_f(geom.pos)}" rpy="{_f(geom.rpy)}"/>'
        lines += [
            f"    <visual name={quoteattr(geom.name)}>",
            f"      {origin}",
            f"      <geometry>{_geometry(geom)}</geometry>",
            f'      <material name="{geom.name}_mat"><color rgba="{_f(geom.rgba)}"/></material>',
            "    </visual>",
        ]
        if geom.collide:
            lines += [
                f"    <collision name={quoteattr(geom.name)}>",
                f"      {origin}",
                f"      <geometry>{_geometry(geom)}</geometry>",
                "    </collision>",
            ]
    lines.append("  </link>")
    return "\n".join(lines)


def _joint_xml(link: Link) -> str:
    joint = link.joint
    if joint is None or link.parent is None:
        raise ValueError(f"Link {link.name!r} has no parent joint")
    lines = [
        f"  <joint name={quoteattr(joint.name)} type={quoteattr(joint.kind)}>",
        f"    <parent link={quoteattr(link.parent)}/>",
        f"    <child link={quoteattr(link.name)}/>",
        f'    <origin xyz="{_f(link.pos)}" rpy="{_f(link.rpy)}"/>',
    ]
    if joint.kind != "fixed":
        lines.append(f'    <axis xyz="{_f(joint.axis)}"/>')
        if joint.lower is not None and joint.upper is not None:
            lines.append(
                f'    <limit lower="{joint.lower!r}" upper="{joint.upper!r}" '
                f'effort="{joint.effort!r}" velocity="{joint.velocity!r}"/>'
            )
        else:
            lines.append(f'    <limit effort="{joint.effort!r}" velocity="{joint.velocity!r}"/>')
    lines.append("  </joint>")
    return "\n".join(lines)


def to_urdf(desc: RobotDescription | None = None) -> str:
    """Return the URDF of the robot as a string."""
    desc = robot_description() if desc is None else desc
    parts = ['<?xml version="1.0"?>', f"<robot name={quoteattr(desc.name)}>"]
    for link in desc.links:
        parts.append(_link_xml(link))
        if link.parent is not None:
            parts.append(_joint_xml(link))
    parts.append("</robot>")
    return "\n".join(parts) + "\n"


@cache
def _urdf_text() -> str:
    return to_urdf()


def urdf_path() -> Path:
    """Write the URDF into a content-addressed temp file (once) and return its path.

    pybullet can only load URDF files from disk. The file name carries a hash of the content and
    is written atomically, so concurrent processes never read a partly written file or one of a
    different version; it is rewritten if the temp directory was cleaned meanwhile.
    """
    text = _urdf_text()
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    directory = Path(tempfile.gettempdir()) / "kinder_garden3d"
    path = directory / f"tidybot_gen3_2f85_{digest}.urdf"
    if not path.exists():
        directory.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=directory, suffix=".urdf.tmp")
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
        os.replace(tmp, path)
    return path
