"""Human limbs built from primitives, for LimbRepositioning3D.

Each limb is a fixed-base chain of six continuous joints, the kinematic structure upstream
kindergarden 0.2.5 uses (so that its initial and goal joint configurations mean the same poses
here): a three-axis ball joint at the shoulder or hip (rotations about the limb frame's x, y and z
axes, in that order), one elbow or knee joint, and a two-axis wrist or ankle (x, then y). The
segment lengths are upstream's joint offsets; the shapes are ours: capsules for the upper and
lower segments, a box for the hand or foot.

Masses are body-segment fractions of a 54.4 kg person (the fractions assistive-gym uses: upper
arm 3.30 %, forearm 1.90 %, hand 0.65 %, thigh 10.5 %, shank 4.75 %, foot 1.40 %); inertias are
those of the primitives. The two intermediate links of the ball joint and the one of the wrist
carry 10 g each so that the articulated-body solve stays well conditioned.

Joint limits are not simulated (the joints are continuous, as upstream): they bound only the
perturbation a reset draws, from the AAOS normal adult ranges of motion (degrees, upstream's
mapping onto joint coordinates).

The seated person of the wheelchair-leg scenes (``seated=True``) has two further shapes where
upstream's mesh limbs reach well beyond these primitives and the reset's clearance to the chair
and the resting hands depends on it: the underside of the thigh (upstream's thigh hull reaches
11.3 cm below the hip joint, under the buttock, where our 7 cm capsule leaves 6.7 cm to the
seat) and the hand (upstream's hand hull is 19 cm long and 8 to 10 cm thick, our box 15 by 3
cm). Both are capsules fitted to upstream's convex hulls by least squares on their support
functions (the thigh's over the directions within 30 degrees of straight down at the seated
start, the hand's over all directions). The thigh shape is for distance queries: the env keeps
the thigh's inertia that of the plain limb.

A limb is described as a :class:`~kinder_garden3d.robot.description.RobotDescription` and loaded
into pybullet through the robot package's URDF writer.
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from kinder_garden3d.robot.description import (
    Geom,
    Inertial,
    Joint,
    Link,
    RobotDescription,
)
from kinder_garden3d.robot.urdf import to_urdf

Vec3 = tuple[float, float, float]
Rgba = tuple[float, float, float, float]

SKIN: Rgba = (0.87, 0.72, 0.6, 1.0)
#: Total body mass (kg) the segment fractions apply to.
BODY_MASS = 54.4
#: Mass (kg) of each massless-in-spirit intermediate link of a multi-axis joint.
_SPACER_MASS = 0.01
_SPACER_INERTIA: Vec3 = (1e-5, 1e-5, 1e-5)
NUM_LIMB_JOINTS = 6
LIMB_NAMES = ("left-arm", "right-arm", "left-leg", "right-leg")


@dataclass(frozen=True)
class LimbSpec:
    """The geometry, masses and joint conventions of one limb.

    Attributes:
        name: ``"left-arm"``, ``"right-arm"``, ``"left-leg"`` or ``"right-leg"``.
        axes: The six joint axes, each in its own joint frame.
        upper_length: Shoulder→elbow or hip→knee (m).
        lower_length: Elbow→wrist or knee→ankle (m).
        middle_yaw: Rotation about z of the elbow joint frame (the arms' forearm frame is turned).
        upper_radius, lower_radius: Capsule radii (m).
        end_half: Half extents of the hand or foot box (m), centred at ``end_center``.
        masses: (upper, lower, end) segment masses (kg).
        grasp_offset: The grasp frame in the hand or foot frame (position only, no rotation).
        lower_limits, upper_limits: Range of motion per joint (degrees, joint coordinates).
    """

    name: str
    axes: tuple[Vec3, Vec3, Vec3, Vec3, Vec3, Vec3]
    upper_length: float
    lower_length: float
    middle_yaw: float
    upper_radius: float
    lower_radius: float
    end_center: Vec3
    end_half: Vec3
    masses: tuple[float, float, float]
    grasp_offset: Vec3
    lower_limits: tuple[float, ...]
    upper_limits: tuple[float, ...]

    @property
    def is_arm(self) -> bool:
        """Whether this limb is an arm (else a leg)."""
        return self.name.endswith("arm")

    @property
    def limits_rad(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(lower, upper) range of motion in radians."""
        return (
            tuple(math.radians(v) for v in self.lower_limits),
            tuple(math.radians(v) for v in self.upper_limits),
        )


_ARM_MASSES = (0.0330 * BODY_MASS, 0.0190 * BODY_MASS, 0.0065 * BODY_MASS)
_LEG_MASSES = (0.1050 * BODY_MASS, 0.0475 * BODY_MASS, 0.0140 * BODY_MASS)
_X: Vec3 = (1.0, 0.0, 0.0)
_Y: Vec3 = (0.0, 1.0, 0.0)
_Z: Vec3 = (0.0, 0.0, 1.0)
_NX: Vec3 = (-1.0, 0.0, 0.0)
_NY: Vec3 = (0.0, -1.0, 0.0)
# AAOS ranges (degrees): wrist deviation ±20 (the smaller of radial 20 and ulnar 30), wrist
# extension 70 / flexion 80, ankle dorsiflexion 20 / plantarflexion 50, eversion 15 / inversion 35.
_ARM_COMMON = dict(
    upper_length=0.24102,
    lower_length=0.296366,
    middle_yaw=-1.57,
    upper_radius=0.045,
    lower_radius=0.035,
    end_center=(0.035, 0.0, -0.075),
    end_half=(0.045, 0.015, 0.075),
    masses=_ARM_MASSES,
    grasp_offset=(0.07, 0.0, -0.07),
)
_LEG_COMMON = dict(
    upper_length=0.430301,
    lower_length=0.35039,
    middle_yaw=0.0,
    upper_radius=0.07,
    lower_radius=0.05,
    end_center=(0.0, -0.06, -0.04),
    end_half=(0.045, 0.11, 0.03),
    masses=_LEG_MASSES,
    grasp_offset=(0.0, -0.1, -0.02),
)

LIMBS: dict[str, LimbSpec] = {
    "left-arm": LimbSpec(
        name="left-arm",
        axes=(_NX, _NY, _Z, _NY, _X, _Y),
        lower_limits=(-60.0, -40.0, -70.0, 0.0, -20.0, -70.0),
        upper_limits=(180.0, 180.0, 90.0, 150.0, 20.0, 80.0),
        **_ARM_COMMON,  # type: ignore[arg-type]
    ),
    "right-arm": LimbSpec(
        name="right-arm",
        axes=(_X, _Y, _Z, _Y, _X, _Y),
        lower_limits=(-180.0, -40.0, -90.0, -150.0, -20.0, -70.0),
        upper_limits=(60.0, 180.0, 70.0, 0.0, 20.0, 80.0),
        **_ARM_COMMON,  # type: ignore[arg-type]
    ),
    "left-leg": LimbSpec(
        name="left-leg",
        axes=(_X, _Y, _Z, _X, _X, _Y),
        lower_limits=(-120.0, -45.0, -45.0, 0.0, -20.0, -15.0),
        upper_limits=(30.0, 30.0, 45.0, 135.0, 50.0, 35.0),
        **_LEG_COMMON,  # type: ignore[arg-type]
    ),
    "right-leg": LimbSpec(
        name="right-leg",
        axes=(_X, _Y, _Z, _X, _X, _Y),
        lower_limits=(-120.0, -30.0, -45.0, 0.0, -20.0, -35.0),
        upper_limits=(30.0, 45.0, 45.0, 135.0, 50.0, 15.0),
        **_LEG_COMMON,  # type: ignore[arg-type]
    ),
}

#: A capsule by its segment's two end points (link frame) and its radius.
Capsule = tuple[Vec3, Vec3, float]
#: The seated thigh's underside, in the left thigh's frame (the right leg's is mirrored in x): at
#: the seated start it ends 2.4 cm above the wheelchair's seat, 1 cm in front of the hip, and
#: tapers toward the knee (upstream's thigh: 2.6 cm, 1.1 cm in front).
SEATED_THIGH_UNDERSIDE: Capsule = ((0.0208, 0.0625, -0.0098), (-0.0043, 0.0118, -0.4077), 0.05)
#: The seated person's hand, in the right hand's frame (the left hand's is mirrored in y).
SEATED_HAND: Capsule = ((0.0179, 0.0013, -0.0339), (-0.008, 0.0251, -0.1419), 0.0391)

#: The joint names in chain order (the six observed joints).
JOINT_NAMES = ("ball_x", "ball_y", "ball_z", "hinge", "distal_x", "distal_y")
#: The link whose frame carries the grasp frame.
END_LINK = "end"


def _capsule_inertial(mass: float, radius: float, length: float) -> Inertial:
    """A solid cylinder's inertia about its centre, hanging along −z from the joint."""
    ixx = mass * (3.0 * radius * radius + length * length) / 12.0
    return Inertial(mass, (0.0, 0.0, -length / 2.0), (ixx, ixx, 0.5 * mass * radius * radius))


def _box_inertial(mass: float, center: Vec3, half: Vec3) -> Inertial:
    x, y, z = (2.0 * h for h in half)
    diag = (
        mass * (y * y + z * z) / 12.0,
        mass * (x * x + z * z) / 12.0,
        mass * (x * x + y * y) / 12.0,
    )
    return Inertial(mass, center, diag)


def _capsule_geom(name: str, capsule: Capsule, mirror_axis: int | None, rgba: Rgba) -> Geom:
    """A capsule geom between two points, optionally mirrored across the plane normal to axis
    ``mirror_axis`` (0: x, 1: y)."""
    p1, p2, radius = capsule
    a, b = list(p1), list(p2)
    if mirror_axis is not None:
        a[mirror_axis], b[mirror_axis] = -a[mirror_axis], -b[mirror_axis]
    d = [bi - ai for ai, bi in zip(a, b, strict=True)]
    length = math.sqrt(sum(v * v for v in d))
    dx, dy, dz = (v / length for v in d)
    # The rotation Ry(pitch) · Rx(roll) takes the capsule's z axis onto d.
    rpy = (math.atan2(-dy, math.hypot(dx, dz)), math.atan2(dx, dz), 0.0)
    center = ((a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0, (a[2] + b[2]) / 2.0)
    return Geom(name, "capsule", (radius, length / 2.0), center, rpy, rgba=rgba)


def limb_description(spec: LimbSpec, rgba: Rgba = SKIN, seated: bool = False) -> RobotDescription:
    """The limb as a fixed-base chain: anchor → ball_x → ball_y → ball_z (upper segment) →
    hinge (lower segment) → distal_x → distal_y (hand or foot). ``seated``: the seated
    person's shapes (module docstring): a leg gains :data:`SEATED_THIGH_UNDERSIDE` on its upper
    segment, an arm's hand is :data:`SEATED_HAND` instead of the box."""
    a = spec.axes
    spacer = Inertial(_SPACER_MASS, (0.0, 0.0, 0.0), _SPACER_INERTIA)
    m_up, m_low, m_end = spec.masses
    up_len, low_len = spec.upper_length, spec.lower_length
    upper_geom = Geom(
        "upper", "capsule", (spec.upper_radius, up_len / 2.0), (0.0, 0.0, -up_len / 2.0), rgba=rgba
    )
    lower_geom = Geom(
        "lower",
        "capsule",
        (spec.lower_radius, low_len / 2.0),
        (0.0, 0.0, -low_len / 2.0),
        rgba=rgba,
    )
    end_geom = Geom("end", "box", spec.end_half, spec.end_center, rgba=rgba)
    upper_geoms: tuple[Geom, ...] = (upper_geom,)
    if seated and spec.is_arm:
        left = spec.name.startswith("left")
        end_geom = _capsule_geom("end", SEATED_HAND, 1 if left else None, rgba)
    elif seated:
        right = spec.name.startswith("right")
        underside = _capsule_geom("underside", SEATED_THIGH_UNDERSIDE, 0 if right else None, rgba)
        upper_geoms = (upper_geom, underside)
    links = (
        Link("anchor", None, None, inertial=Inertial(0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))),
        Link("ball_1", "anchor", Joint("ball_x", "continuous", a[0]), inertial=spacer),
        Link("ball_2", "ball_1", Joint("ball_y", "continuous", a[1]), inertial=spacer),
        Link(
            "upper",
            "ball_2",
            Joint("ball_z", "continuous", a[2]),
            inertial=_capsule_inertial(m_up, spec.upper_radius, up_len),
            geoms=upper_geoms,
        ),
        Link(
            "lower",
            "upper",
            Joint("hinge", "continuous", a[3]),
            pos=(0.0, 0.0, -up_len),
            rpy=(0.0, 0.0, spec.middle_yaw),
            inertial=_capsule_inertial(m_low, spec.lower_radius, low_len),
            geoms=(lower_geom,),
        ),
        Link(
            "distal",
            "lower",
            Joint("distal_x", "continuous", a[4]),
            pos=(0.0, 0.0, -low_len),
            inertial=spacer,
        ),
        Link(
            END_LINK,
            "distal",
            Joint("distal_y", "continuous", a[5]),
            inertial=_box_inertial(m_end, spec.end_center, spec.end_half),
            geoms=(end_geom,),
        ),
    )
    return RobotDescription(
        name=f"human_{spec.name.replace('-', '_')}{'_seated' if seated else ''}",
        links=links,
        frames=(),
        cameras=(),
        arm_joint_names=JOINT_NAMES,
        finger_joint_names=(),
        base_mass=0.0,
    )


@cache
def _limb_urdf_text(name: str, rgba: Rgba, seated: bool) -> str:
    return to_urdf(limb_description(LIMBS[name], rgba, seated))


def limb_urdf_path(name: str, rgba: Rgba = SKIN, seated: bool = False) -> Path:
    """Write limb ``name``'s URDF (``seated``: with the seated person's shapes) to a
    content-addressed temp file and return its path.

    pybullet loads URDFs only from disk; the name carries a hash of the content and the file is
    written atomically, so concurrent processes never read a partial or stale file.
    """
    if name not in LIMBS:
        raise ValueError(f"Unknown limb {name!r}; expected one of {list(LIMBS)}")
    text = _limb_urdf_text(name, rgba, seated)
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    directory = Path(tempfile.gettempdir()) / "kinder_garden3d"
    path = directory / f"limb_{name}_{digest}.urdf"
    if not path.exists():
        directory.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=directory, suffix=".urdf.tmp")
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
        os.replace(tmp, path)
    return path
