"""LimbRepositioning3D: drive a passive human limb to a goal configuration with joint torques."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as pb
from gymnasium import spaces
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState, ObjectCentricStateSpace, Type
from kinder_core.state import FloatArray
from kinder_garden3d.kinematic3d.scene import _GRIPPER_TO_FLANGE, TOOL_OFFSET, PyBulletScene
from kinder_garden3d.limb3d.limbs import (
    END_LINK,
    LIMB_NAMES,
    LIMBS,
    NUM_LIMB_JOINTS,
    SKIN,
    LimbSpec,
    limb_urdf_path,
)
from kinder_garden3d.robot.description import RETRACT, robot_description

Vec3 = tuple[float, float, float]
Rgba = tuple[float, float, float, float]
Quat = tuple[float, float, float, float]
NUM_ROBOT_JOINTS = 7

#: The torque-controlled arm: base pose (fixed during an episode), 7 joints and their velocities.
ROBOT_TYPE = Type(
    "Limb3DRobot",
    (
        "pos_base_x",
        "pos_base_y",
        "pos_base_rot",
        *(f"joint_{i}" for i in range(1, 8)),
        *(f"joint_vel_{i}" for i in range(1, 8)),
    ),
)
#: The passive limb: 6 joints, their velocities, and the goal configuration.
LIMB_TYPE = Type(
    "Limb3DLimb",
    (
        *(f"joint_{i}" for i in range(1, 7)),
        *(f"joint_vel_{i}" for i in range(1, 7)),
        *(f"goal_joint_{i}" for i in range(1, 7)),
    ),
)
#: Static furniture (wheelchair, bed): its pose, quaternion ordered (x, y, z, w).
FIXTURE_TYPE = Type(
    "Limb3DFixture",
    ("pose_x", "pose_y", "pose_z", "pose_qx", "pose_qy", "pose_qz", "pose_qw"),
)
ALL_TYPES = (ROBOT_TYPE, LIMB_TYPE, FIXTURE_TYPE)

_R_JOINTS = slice(3, 10)
_R_VELS = slice(10, 17)
_L_JOINTS = slice(0, 6)
_L_VELS = slice(6, 12)
_L_GOAL = slice(12, 18)


@dataclass(frozen=True)
class LimbVariant:
    """One (scene, limb) pair: where the limb and the robot are, and the task.

    Attributes:
        scene: ``"isolated"`` (the limb alone) or ``"human"`` (the limb attached to a torso with
            a head and the three other limbs, all static at zero joint angles).
        limb: A key of :data:`~kinder_garden3d.limb3d.limbs.LIMBS`.
        limb_base_pos, limb_base_rpy: The limb's anchor (shoulder or hip) in the world.
        init_joints: The nominal initial limb configuration a reset perturbs.
        goal_joints: The goal limb configuration.
        robot_base: The robot base's (x, y, yaw).
        robot_base_z: Height of the robot base frame.
        torso: The torso's world (position, roll-pitch-yaw) where the scene places the person
            (wheelchair, bed); ``None``: behind the limb's anchor (human scene).
        resting: The joint configurations of the other limbs, in ``LIMB_NAMES`` order (the
            repositioned limb's entry is unused).
        noise_joints: The limb joints a reset perturbs (``None``: all six).
        furniture: ``"wheelchair"``, ``"bed"`` or ``None``; it stands at ``furniture_pos``.
        camera: The orbit camera's (target, distance, yaw, pitch).
        ik_start: An arm configuration the grasp IK tries first (``None``: none): upstream's
            settled arm for the variant (measured), so that the solve lands on its branch.
        seated_shapes: Whether the person's limbs carry the seated shapes (the thighs'
            undersides and the fuller hands of ``limbs.limb_description(seated=True)``), which
            the reset's clearance to the seat and the resting hands depends on (wheelchair
            legs).
    """

    scene: str
    limb: str
    limb_base_pos: Vec3
    limb_base_rpy: Vec3
    init_joints: tuple[float, ...]
    goal_joints: tuple[float, ...]
    robot_base: Vec3
    robot_base_z: float
    torso: tuple[Vec3, Vec3] | None = None
    resting: tuple[tuple[float, ...], ...] = ((0.0,) * NUM_LIMB_JOINTS,) * len(LIMB_NAMES)
    noise_joints: tuple[int, ...] | None = None
    furniture: str | None = None
    furniture_pos: Vec3 = (0.0, 0.0, 0.0)
    camera: tuple[Vec3, float, float, float] = ((0.730, -0.396, 0.270), 2.0, 140.0, -20.0)
    ik_start: tuple[float, ...] | None = None
    seated_shapes: bool = False


# Upstream's isolated tasks: one nominal right-arm start and goal, mirrored or knee-flipped for
# the other limbs; the limb floats at (0.730, -0.396, 0.270) turned by pi about z.
_ARM_INIT = (-0.40335719438145545, 0.05292781876657404, -0.09289427173389816, -0.5010609575327076)
_LEG_INIT = (-0.40335719438145545, -0.44707218123342596, -0.09289427173389816, -0.5010609575327076)
_GOAL = (-0.7, 0.0, -0.03, -0.8)
_FREE_POS: Vec3 = (0.730, -0.396, 0.270)
_FREE_RPY: Vec3 = (0.0, 0.0, math.pi)


def _six(q: tuple[float, ...]) -> tuple[float, ...]:
    return (*q, 0.0, 0.0)


def _mirror_arm(q: tuple[float, ...]) -> tuple[float, ...]:
    """An arm configuration mirrored across the body's sagittal plane."""
    return (-q[0], q[1], -q[2], -q[3], -q[4], q[5])


def _flip_knee(q: tuple[float, ...]) -> tuple[float, ...]:
    return (q[0], q[1], q[2], -q[3], q[4], q[5])


def _mirror_leg(q: tuple[float, ...]) -> tuple[float, ...]:
    return (q[0], -q[1], -q[2], q[3], q[4], -q[5])


VARIANTS: dict[str, LimbVariant] = {
    "isolated-left-arm": LimbVariant(
        "isolated",
        "left-arm",
        _FREE_POS,
        _FREE_RPY,
        _mirror_arm(_six(_ARM_INIT)),
        _mirror_arm(_six(_GOAL)),
        (1.0787, 0.1832, -0.8140),
        -0.3948,
    ),
    "isolated-right-arm": LimbVariant(
        "isolated",
        "right-arm",
        _FREE_POS,
        _FREE_RPY,
        _six(_ARM_INIT),
        _six(_GOAL),
        (0.3566, 0.4849, -0.6971),
        -0.3948,
    ),
    "isolated-left-leg": LimbVariant(
        "isolated",
        "left-leg",
        _FREE_POS,
        _FREE_RPY,
        _flip_knee(_six(_LEG_INIT)),
        _flip_knee(_six(_GOAL)),
        (0.1548, -0.1575, 2.1953),
        -0.7948,
    ),
    "isolated-right-leg": LimbVariant(
        "isolated",
        "right-leg",
        _FREE_POS,
        _FREE_RPY,
        _mirror_leg(_flip_knee(_six(_LEG_INIT))),
        _mirror_leg(_flip_knee(_six(_GOAL))),
        (0.4548, -0.1575, 0.1009),
        -0.7948,
    ),
}

#: Upstream's robot placements for the human scene (the limb sits where it floats in the
#: isolated scene; the torso is placed behind it).
_HUMAN_ROBOT: dict[str, tuple[Vec3, float]] = {
    "left-arm": ((0.8787, 0.1832, -0.8140), -0.3948),
    "right-arm": ((0.3566, 0.4849, -0.6971), -0.3948),
    "left-leg": ((0.1651, 0.4351, 0.4988), -0.7948),
    "right-leg": ((0.4126, 0.1349, -0.5421), -0.7948),
}
for _limb, (_base, _z) in _HUMAN_ROBOT.items():
    _iso = VARIANTS[f"isolated-{_limb}"]
    VARIANTS[f"human-{_limb}"] = LimbVariant(
        "human", _limb, _FREE_POS, _FREE_RPY, _iso.init_joints, _iso.goal_joints, _base, _z
    )

#: Where each limb attaches in the torso frame (no rotation): shoulders and hips.
TORSO_TO_LIMB: dict[str, Vec3] = {
    "left-arm": (0.24, 0.048, 0.45),
    "right-arm": (-0.24, 0.048, 0.45),
    "left-leg": (0.11, 0.0, 0.0),
    "right-leg": (-0.11, 0.0, 0.0),
}
#: The torso (a box from the hips to the shoulders) and the head (a sphere), in the torso frame.
TORSO_CENTER: Vec3 = (0.0, 0.01, 0.23)
TORSO_HALF: Vec3 = (0.17, 0.12, 0.32)
HEAD_CENTER: Vec3 = (0.0, 0.02, 0.68)
HEAD_RADIUS = 0.1


def _limb_base_from_torso(limb: str, torso: tuple[Vec3, Vec3]) -> tuple[Vec3, Vec3]:
    """The limb's anchor (position, roll-pitch-yaw) for a torso pose: the torso composed with
    the limb's attachment offset."""
    pos, quat = pb.multiplyTransforms(
        torso[0], pb.getQuaternionFromEuler(torso[1]), TORSO_TO_LIMB[limb], (0.0, 0.0, 0.0, 1.0)
    )
    rpy = pb.getEulerFromQuaternion(quat)
    return (pos[0], pos[1], pos[2]), (rpy[0], rpy[1], rpy[2])


def _resting(by_limb: dict[str, tuple[float, ...]]) -> tuple[tuple[float, ...], ...]:
    return tuple(by_limb.get(name, (0.0,) * NUM_LIMB_JOINTS) for name in LIMB_NAMES)


# Upstream's wheelchair scene: the torso sits at (0, −0.15, 0.75), leaning back 0.2 rad, facing
# −y; the other arms rest bent on the armrests and the legs hang from the seat (hips flexed 1.3
# rad, knees 1.57). Each limb has its own start and goal; the camera looks at the torso.
_WHEELCHAIR_TORSO: tuple[Vec3, Vec3] = ((0.0, -0.15, 0.75), (-0.2, 0.0, 0.0))
_SEATED_ARM = (0.0, 0.3, 0.2, -1.1, 0.0, 0.0)
_SEATED_LEG = (-1.3, 0.0, 0.0, 1.57, 0.0, 0.0)
_WHEELCHAIR_RESTING = _resting(
    {
        "left-arm": _mirror_arm(_SEATED_ARM),
        "right-arm": _SEATED_ARM,
        "left-leg": _SEATED_LEG,
        "right-leg": _SEATED_LEG,
    }
)
_ARM_SWING = (0.40335719438145545, 0.44707218123342596, -0.09289427173389816, 0.5010609575327076)
#: Upstream's arm configuration after it settles at construction, per limb (measured from
#: kindergarden 0.2.5): the grasp IK's first start.
_WHEELCHAIR_IK_START: dict[str, tuple[float, ...]] = {
    "left-arm": (0.7553, 0.9131, 2.9896, -1.8688, 0.9401, -0.8859, 2.7603),
    "right-arm": (-0.5997, 1.0722, -2.6489, -1.4815, 1.6679, 0.8814, 2.8273),
    "left-leg": (1.4733, 0.9042, 1.9787, -0.6633, 1.3977, -1.6625, -2.6971),
    "right-leg": (0.4803, 0.8671, -2.8205, -0.4237, -0.7663, -2.2148, 0.492),
}
_BED_IK_START: dict[str, tuple[float, ...]] = {
    "left-arm": (-1.7143, -0.9082, -1.736, -2.0243, 0.4383, -1.1993, 2.7636),
    "right-arm": (-1.2648, 1.3256, -1.0911, -0.4493, -1.3502, -2.0359, 0.0472),
    "left-leg": (-1.7143, -1.4023, -0.9361, -0.2075, 1.0976, -1.633, 3.0439),
    "right-leg": (-2.0379, -1.5032, -2.0501, -0.237, 1.8675, -1.6545, -0.538),
}
_WHEELCHAIR_TASKS: dict[str, tuple[tuple[float, ...], tuple[float, ...], Vec3, float]] = {
    "left-arm": (
        _six(_ARM_SWING),
        (0.7, 0.0, -0.03, 0.8, 0.0, 0.0),
        (0.9111, -0.6310, -2.6352),
        0.5052,
    ),
    "right-arm": (
        (-_ARM_SWING[0], _ARM_SWING[1], -_ARM_SWING[2], -_ARM_SWING[3], 0.0, 0.0),
        (-0.7, 0.0, -0.03, -0.8, 0.0, 0.0),
        (-0.7040, -1.1983, 0.7716),
        0.5052,
    ),
    "left-leg": (
        (-1.3, -0.2, 0.0, 0.5, 0.0, 0.0),
        _SEATED_LEG,
        (0.9145, -1.2718, -2.4336),
        -0.1948,
    ),
    "right-leg": (
        (-1.3, 0.2, 0.0, 0.5, 0.0, 0.0),
        _SEATED_LEG,
        (-0.8161, -0.5696, -0.3190),
        -0.1948,
    ),
}
for _limb, (_init, _goal, _base, _z) in _WHEELCHAIR_TASKS.items():
    _pos, _rpy = _limb_base_from_torso(_limb, _WHEELCHAIR_TORSO)
    VARIANTS[f"wheelchair-{_limb}"] = LimbVariant(
        "wheelchair",
        _limb,
        _pos,
        _rpy,
        _init,
        _goal,
        _base,
        _z,
        torso=_WHEELCHAIR_TORSO,
        resting=_WHEELCHAIR_RESTING,
        furniture="wheelchair",
        camera=(_WHEELCHAIR_TORSO[0], 3.0, 320.0, -30.0),
        ik_start=_WHEELCHAIR_IK_START[_limb],
        seated_shapes=_limb.endswith("leg"),
    )

# Upstream's bed scene: the bed stands 0.35 m up; the person lies on it face up (the torso turned
# −π/2 about x, head toward +y) at height 0.6143, moved 0.10 m toward the repositioned limb's
# side, the other limbs straight. Arms start abducted, legs nearly straight (knee 0.18 rad); a
# leg's reset perturbs only the hip abduction (joint 2).
_BED_POS: Vec3 = (0.0, 0.0, 0.35)
_BED_KNEE = 0.18
_BED_TASKS: dict[str, tuple[tuple[float, ...], tuple[float, ...], Vec3]] = {
    "left-arm": (
        _mirror_arm((0.0, 0.3, 0.0, -0.5, 0.0, 0.0)),
        _mirror_arm((-0.3, 0.0, -0.03, -0.8, 0.0, 0.0)),
        (0.9078, 0.0224, -2.9401),
    ),
    "right-arm": (
        (0.0, 0.3, 0.0, -0.5, 0.0, 0.0),
        (-0.3, 0.0, -0.03, -0.8, 0.0, 0.0),
        (-1.2057, 0.0837, -0.9312),
    ),
    "left-leg": (
        (0.0, 0.0, 0.0, _BED_KNEE, 0.0, 0.0),
        (-0.5, -0.1, 0.0, 0.8, 0.0, 0.0),
        (0.9599, -0.7180, -1.7739),
    ),
    "right-leg": (
        (0.0, 0.0, 0.0, _BED_KNEE, 0.0, 0.0),
        (-0.5, 0.1, 0.0, 0.8, 0.0, 0.0),
        (-0.8962, -1.2672, 1.4083),
    ),
}
for _limb, (_init, _goal, _base) in _BED_TASKS.items():
    _side = 1.0 if _limb.startswith("left") else -1.0
    _torso: tuple[Vec3, Vec3] = ((_side * 0.10, 0.0, 0.6143), (-math.pi / 2, 0.0, 0.0))
    _pos, _rpy = _limb_base_from_torso(_limb, _torso)
    VARIANTS[f"bed-{_limb}"] = LimbVariant(
        "bed",
        _limb,
        _pos,
        _rpy,
        _init,
        _goal,
        _base,
        0.1552,
        torso=_torso,
        noise_joints=(1,) if _limb.endswith("leg") else None,
        furniture="bed",
        furniture_pos=_BED_POS,
        camera=(_torso[0], 3.0, 60.0, -40.0),
        ik_start=_BED_IK_START[_limb],
    )
#: A box of furniture or room: centre and half extents (m) in the furniture frame, and its
#: roll-pitch-yaw.
BoxPart = tuple[Vec3, Vec3, Vec3]
_FLAT: Vec3 = (0.0, 0.0, 0.0)


def _span(lo: Vec3, hi: Vec3) -> BoxPart:
    """An axis-aligned box from its two corners."""
    return (
        ((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0, (lo[2] + hi[2]) / 2.0),
        ((hi[0] - lo[0]) / 2.0, (hi[1] - lo[1]) / 2.0, (hi[2] - lo[2]) / 2.0),
        _FLAT,
    )


def _both_sides(lo: Vec3, hi: Vec3) -> tuple[BoxPart, BoxPart]:
    """A box on the +x side and its mirror image across x = 0."""
    return _span(lo, hi), _span((-hi[0], lo[1], lo[2]), (-lo[0], hi[1], hi[2]))


#: The wheelchair (its frame: floor at z = 0, the occupant facing −y), boxes at the extents of
#: upstream's collision model: seat, reclined backrest and headrest, armrests with their
#: supports, front wheels, rear casters, footrest with its rails and the under-frame.
WHEELCHAIR_PARTS: tuple[BoxPart, ...] = (
    _span((-0.254, -0.438, 0.455), (0.258, 0.097, 0.613)),
    _span((-0.254, -0.227, 0.357), (0.258, 0.097, 0.455)),
    ((0.0, 0.113, 0.89), (0.232, 0.055, 0.287), (-0.255, 0.0, 0.0)),
    _span((-0.118, 0.111, 1.217), (0.116, 0.175, 1.348)),
    *_both_sides((0.252, -0.364, 0.792), (0.356, 0.131, 0.847)),
    *_both_sides((0.247, -0.124, 0.76), (0.323, 0.146, 0.792)),
    *_both_sides((0.205, -0.57, 0.0), (0.298, -0.256, 0.357)),
    *_both_sides((0.129, 0.151, 0.0), (0.2, 0.361, 0.258)),
    _span((-0.132, -0.742, 0.106), (0.132, -0.497, 0.166)),
    *_both_sides((0.132, -0.742, 0.106), (0.209, -0.389, 0.171)),
    _span((-0.205, -0.52, 0.079), (0.23, 0.1, 0.111)),
)
#: The hospital bed (its frame: the mattress centred at the origin, head toward +y): mattress,
#: headboard, head and foot ends, side and inner rails, lower frame and legs, boxes at the
#: extents of upstream's collision model.
BED_PARTS: tuple[BoxPart, ...] = (
    _span((-0.562, -1.007, -0.131), (0.562, 1.011, 0.122)),
    _span((-0.452, 1.181, 0.122), (0.459, 1.266, 0.586)),
    _span((-0.563, 1.011, -0.25), (0.563, 1.245, 0.122)),
    _span((-0.563, -1.251, -0.237), (0.563, -1.007, 0.122)),
    *_both_sides((0.487, -1.007, -0.37), (0.561, -0.327, -0.131)),
    *_both_sides((0.487, 0.289, -0.37), (0.561, 1.011, -0.131)),
    *_both_sides((0.273, -0.954, -0.37), (0.368, 0.958, -0.131)),
    _span((-0.552, -1.007, -0.476), (0.552, 1.011, -0.37)),
    *_both_sides((0.33, -1.19, -0.635), (0.45, -1.007, -0.383)),
    *_both_sides((0.33, 1.011, -0.635), (0.45, 1.19, -0.383)),
)
FURNITURE_PARTS: dict[str, tuple[BoxPart, ...]] = {"wheelchair": WHEELCHAIR_PARTS, "bed": BED_PARTS}
#: The room of the wheelchair and bed scenes: a 10 m floor slab centred at the origin and three
#: walls (behind at y = 2.5, sides at x = ±3), drawn only.
ROOM_PARTS: tuple[BoxPart, ...] = (
    ((0.0, 0.0, 0.0), (5.0, 5.0, 0.05), _FLAT),
    ((0.0, 2.5, 0.0), (0.1, 3.0, 5.0), (math.pi / 2, 0.0, math.pi / 2)),
    ((3.0, 0.0, 0.0), (0.1, 3.0, 5.0), (math.pi / 2, 0.0, 0.0)),
    ((-3.0, 0.0, 0.0), (0.1, 3.0, 5.0), (math.pi / 2, 0.0, 0.0)),
)
FURNITURE_RGBA = (0.83, 0.83, 0.83, 1.0)
FLOOR_RGBA = (0.8, 0.6, 0.4, 1.0)
WALL_RGBA = (0.75, 0.86, 0.95, 1.0)

#: Further arm configurations the grasp IK starts from, in order, when the previous start ends
#: outside the joint limits or away from the target: the retract pose turned about the first
#: joint, the zero pose, then 24 fixed configurations drawn once (uniform within ±2 rad, a
#: constant of the module, so resets stay a function of the seed alone).
IK_STARTS: tuple[tuple[float, ...], ...] = (
    tuple(RETRACT[0] + math.pi / 2 if i == 0 else v for i, v in enumerate(RETRACT)),
    tuple(RETRACT[0] - math.pi / 2 if i == 0 else v for i, v in enumerate(RETRACT)),
    tuple(RETRACT[0] + math.pi if i == 0 else v for i, v in enumerate(RETRACT)),
    (0.0,) * 7,
    *(tuple(float(v) for v in row) for row in np.random.default_rng(0).uniform(-2.0, 2.0, (24, 7))),
)
#: How far inside the arm's joint limits ``grasp_arm_joints(within_limits=True)`` keeps its
#: null-space IK (rad).
IK_LIMIT_MARGIN = 0.05
#: Reset draws before falling back to the nominal start, and the shrink of the noise per draw.
MAX_INIT_DRAWS = 20
INIT_NOISE_DECAY = 0.75
#: Distances are queried within this radius and saturate at it.
CLEARANCE_RADIUS = 0.5

#: The end effector relative to the limb's grasp frame: the gripper approaches along the grasp
#: frame's −x axis (arms) or, for legs, turned a further −π/2 about z first; then a quarter turn
#: about the approach axis. Quaternions (x, y, z, w).
_ARM_GRASP_RPY: Vec3 = (0.0, -math.pi / 2, 0.0)
_LEG_GRASP_RPY: Vec3 = (0.0, -math.pi / 2, -math.pi / 2)
_APPROACH_SPIN_RPY: Vec3 = (0.0, 0.0, math.pi / 2)


def _grasp_transform(arm: bool) -> tuple[Vec3, Quat]:
    rpy = _ARM_GRASP_RPY if arm else _LEG_GRASP_RPY
    pos, quat = pb.multiplyTransforms(
        (0.0, 0.0, 0.0),
        pb.getQuaternionFromEuler(rpy),
        (0.0, 0.0, 0.0),
        pb.getQuaternionFromEuler(_APPROACH_SPIN_RPY),
    )
    return (pos[0], pos[1], pos[2]), (quat[0], quat[1], quat[2], quat[3])


def _tool_to_gripper() -> tuple[Vec3, Quat]:
    """The gripper_base_link frame in the tool frame (see ``kinematic3d.scene.ee_pose``: the
    tool frame is TOOL_OFFSET along the gripper's z axis, turned a quarter about it)."""
    p, q = pb.invertTransform([0.0, 0.0, TOOL_OFFSET], list(_GRIPPER_TO_FLANGE))
    return (p[0], p[1], p[2]), (q[0], q[1], q[2], q[3])


@dataclass(frozen=True)
class LimbRepositioning3DConfig:
    """LimbRepositioning3D settings (defaults are upstream's).

    Attributes:
        torque_limit: Bound of each of the 7 joint torques (N m).
        timestep: pybullet's fixed time step (s); one env step is one simulation step.
        goal_atol: Summed absolute joint error (rad, continuous joints wrapped) below which the
            goal holds.
        init_joint_noise: Half width (rad) of the uniform perturbation of every limb joint around
            the nominal start, intersected with the limb's range of motion.
        init_max_penetration: How much deeper (m) than at the nominal start a drawn limb may
            overlap the rest of the body (human scene); deeper draws are redrawn.
        robot_initial_joints: The arm configuration the grasp IK starts from.
        ik_iterations: pybullet IK refinements toward the grasp pose at reset, per start.
        ik_tolerance: Gripper position error (m) at which an IK solution is accepted.
        image_width, image_height: Size of rendered frames.
        camera_distance, camera_yaw, camera_pitch: Override the scene's orbit camera (upstream's
            per scene: 2 m, 140°, −20° around the limb's anchor in the isolated and human
            scenes; 3 m, 320°, −30° around the torso in the wheelchair; 3 m, 60°, −40° around
            the torso on the bed).
    """

    torque_limit: float = 1.0
    timestep: float = 1.0 / 240.0
    goal_atol: float = 0.1
    init_joint_noise: float = 0.26
    init_max_penetration: float = 0.002
    robot_initial_joints: tuple[float, ...] = RETRACT
    ik_iterations: int = 50
    ik_tolerance: float = 1e-4
    image_width: int = 512
    image_height: int = 512
    camera_distance: float | None = None
    camera_yaw: float | None = None
    camera_pitch: float | None = None

    def __post_init__(self) -> None:
        if not self.torque_limit > 0:
            raise ValueError(f"torque_limit must be > 0, got {self.torque_limit}")
        if not self.timestep > 0:
            raise ValueError(f"timestep must be > 0, got {self.timestep}")
        if not self.goal_atol > 0:
            raise ValueError(f"goal_atol must be > 0, got {self.goal_atol}")
        if self.init_joint_noise < 0:
            raise ValueError(f"init_joint_noise must be >= 0, got {self.init_joint_noise}")
        if len(self.robot_initial_joints) != NUM_ROBOT_JOINTS:
            raise ValueError(
                f"robot_initial_joints needs {NUM_ROBOT_JOINTS} values, got "
                f"{len(self.robot_initial_joints)}"
            )
        if self.ik_iterations < 1:
            raise ValueError(f"ik_iterations must be >= 1, got {self.ik_iterations}")


def wrapped_joint_distance(q: NDArray[np.float64], goal: NDArray[np.float64]) -> float:
    """Sum over the (continuous) joints of the absolute difference wrapped into [−π, π)."""
    diff = (np.asarray(q) - np.asarray(goal) + math.pi) % (2.0 * math.pi) - math.pi
    return float(np.sum(np.abs(diff)))


class LimbRepositioning3DEnv(ObjectCentricEnv):
    """Reposition a passive human limb with joint torques, its hand or foot welded to the gripper.

    ## Description
    An assistive-robotics task: the mobile manipulator's end effector is rigidly attached to the
    grasp frame of a human limb (the palm side of the hand, or the sole of the foot) and must
    drive the limb to a goal joint configuration by applying torques to its 7 arm joints. The
    limb has no actuation of its own. It is a fixed-base chain of six continuous joints (a
    three-axis shoulder or hip, an elbow or knee, a two-axis wrist or ankle) built from
    capsules and a box, with body-segment masses of a 54.4 kg person (`limb3d/limbs.py`). The
    robot's base stays where the variant puts it. Physics is pybullet forward dynamics at
    240 Hz, one simulation step per env step, with gravity off and collision response disabled
    for the robot and the limb (nothing pushes back but inertia); joint damping, link damping
    and friction are zero and the joint motors are off. The weld is a fixed constraint at the
    nominal grasp (a constant of the variant), so a state fully determines the next one.

    Variants pair a scene with a limb: `isolated-{left,right}-{arm,leg}` (the limb floats alone
    at (0.730, −0.396, 0.270), turned π about z) and `human-{left,right}-{arm,leg}` (the same
    limb, attached to a static torso (a box), head (a sphere) and the three other limbs at zero
    joint angles; they are drawn, and the reset keeps the limb out of them, but nothing
    collides), `wheelchair-{left,right}-{arm,leg}` (the person seated in a wheelchair in a room:
    torso at (0, −0.15, 0.75) leaning back 0.2 rad, the other arms bent on the armrests, the
    legs hanging from the seat with hips flexed 1.3 rad and knees 1.57 rad) and
    `bed-{left,right}-{arm,leg}` (the person lying face up on a hospital bed 0.35 m up, moved
    0.10 m toward the repositioned limb, the other limbs straight). The wheelchair and the bed
    are boxes at the extents of upstream's collision models, the room a floor and three walls
    (drawn only); the furniture is one more obstacle the reset keeps the limb out of. Each
    variant has upstream's nominal start, goal and robot placement.

    ## Observation Space
    A 35-D float64 vector: `robot` (17) then `limb` (18). `Limb3DRobot`: `pos_base_x,
    pos_base_y, pos_base_rot, joint_1..joint_7, joint_vel_1..joint_vel_7`; `Limb3DLimb`:
    `joint_1..joint_6, joint_vel_1..joint_vel_6, goal_joint_1..goal_joint_6`. The wheelchair
    and bed variants append `fixture` (7), a `Limb3DFixture`: the furniture's constant pose
    `pose_x, pose_y, pose_z, pose_qx, pose_qy, pose_qz, pose_qw` (42-D). All unbounded.

    ## Action Space
    A 7-D float32 Box in [−1, 1]: the torque (N m) applied to each arm joint for the step.

    ## Reward
    −1 on every step.

    ## Starting State
    Each limb joint (for the bed's legs, only the hip abduction, joint 2) is drawn uniformly
    within ±0.26 rad of the variant's nominal start,
    intersected with the limb's anatomical range of motion (AAOS normal adult values); a draw
    that overlaps the rest of the body more than 2 mm deeper than the nominal start does is
    redrawn with the half width shrunk by 0.75 (up to 20 draws, then the nominal start); all
    velocities are zero. The arm is solved by pybullet's IK for the end-effector pose at the
    limb's grasp frame, from upstream's settled arm (wheelchair and bed variants), the Kinova
    retract configuration and then from fixed further starts
    until a solution lies within the arm's joint limits and 0.1 mm of the target (else the
    closest one is kept).

    ## Episode End
    Terminates when the summed absolute joint error to the goal (each wrapped into [−π, π)) is
    below 0.1 rad. The registered ids truncate after 2400 steps (10 s of simulated time).

    ## Arguments
    `variant` (default `"isolated-right-arm"`), `config` (a `LimbRepositioning3DConfig`),
    `render_mode`.

    ## Version History
    * v0: first release in kinder-garden3d.

    ## Deviations
    Upstream loads mesh limbs and a Kinova URDF; here the limb is primitives (see above) and the
    robot is the project's primitive model, so inertias differ and trajectories under the same
    torques are not upstream's. Upstream settles the robot for 1000 steps at construction and
    solves the grasp with IKFast; here pybullet's damped least squares solves it from the
    retract configuration and further fixed starts. The weld is the nominal grasp (upstream
    welds wherever its IK left the arm), so on the draws our IK does not reach within 1 mm (on
    seeds 1000–1019: isolated-right-leg 6 of 20, up to 11 cm off; human-right-leg 5 and
    isolated-left-arm 1, up to 3 cm; wheelchair-left-leg 10, up to 15 cm; wheelchair-right-leg
    14, up to 8 cm; bed-right-arm 8, up to 8 cm; none for the other variants) the first steps
    pull the gripper onto the grasp frame.
    The wheelchair, bed and room are boxes at the extents of upstream's meshes (its collision
    meshes are convex pieces, which the boxes cover but do not follow), so the clearances the
    reset compares differ by millimetres: upstream draws the bed's leg abduction within ±0.010
    rad of the start, these ids within −0.025 to +0.005 rad. In the wheelchair-leg variants the
    person's thighs carry an underside capsule and the hands are capsules, fitted to upstream's
    mesh hulls (`limbs.py`), so that the seat under the buttock and the resting hands are the
    nearest pieces the reset's clearance compares, as upstream's (without them an armrest corner
    and a forearm were, and the hip draws were 0.036 rad more flexed); they serve the distance
    queries only, the thigh keeps the plain limb's inertia. Upstream enables contact between
    the limb and the furniture (friction 0.5, zero contact stiffness and damping); here nothing
    collides (from seed 0, 20 steps of constant torque, upstream's own runs with that contact
    switched off were identical for wheelchair-left-arm, wheelchair-left-leg, bed-left-arm and
    bed-left-leg). Upstream draws the goal as a translucent copy of the limb; these ids do not.
    Upstream registers no step limit; these ids use 2400.
    """

    def __init__(
        self,
        variant: str = "isolated-right-arm",
        config: LimbRepositioning3DConfig | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        if variant not in VARIANTS:
            raise ValueError(f"Unknown variant {variant!r}; expected one of {sorted(VARIANTS)}")
        super().__init__(render_mode=render_mode)
        self.variant = VARIANTS[variant]
        self.config = config or LimbRepositioning3DConfig()
        self.limb_spec: LimbSpec = LIMBS[self.variant.limb]
        self.robot = Object("robot", ROBOT_TYPE)
        self.limb = Object("limb", LIMB_TYPE)
        #: The wheelchair or bed (static; its pose is observed, as upstream), else ``None``.
        self.fixture = Object("fixture", FIXTURE_TYPE) if self.variant.furniture else None
        lim = self.config.torque_limit
        self.action_space = spaces.Box(-lim, lim, shape=(NUM_ROBOT_JOINTS,), dtype=np.float32)
        self.observation_space = ObjectCentricStateSpace(ALL_TYPES)
        self.metadata["render_fps"] = round(1.0 / self.config.timestep)
        self._scene = PyBulletScene(self.variant.robot_base_z)
        self._generation = -1
        self._limb_body = -1
        self._limb_joints: list[int] = []
        self._limb_end = -1
        self._constraint = -1
        self._obstacles: list[int] = []
        self._resting_limbs: list[tuple[int, tuple[float, ...]]] = []
        self._rest_clearance: list[float] = []
        self._grasp_tf = _grasp_transform(self.limb_spec.is_arm)
        self._arm_low, self._arm_high = robot_description().arm_joint_limits

    # -- the simulator --------------------------------------------------------------------------
    def _client(self) -> int:
        """The pybullet client, with the limb loaded and dynamics configured (once per client)."""
        scene = self._scene
        cid = scene.client
        if self._generation == scene.generation:
            return cid
        v = self.variant
        pb.setGravity(0.0, 0.0, 0.0, physicsClientId=cid)
        pb.setPhysicsEngineParameter(fixedTimeStep=self.config.timestep, physicsClientId=cid)
        self._limb_body = pb.loadURDF(
            str(limb_urdf_path(v.limb, seated=v.seated_shapes)),
            basePosition=list(v.limb_base_pos),
            baseOrientation=pb.getQuaternionFromEuler(v.limb_base_rpy),
            useFixedBase=True,
            physicsClientId=cid,
        )
        if v.seated_shapes:
            self._keep_plain_inertia(cid)
        names: dict[str, int] = {}
        for j in range(pb.getNumJoints(self._limb_body, physicsClientId=cid)):
            info = pb.getJointInfo(self._limb_body, j, physicsClientId=cid)
            names[info[1].decode()] = j
            if info[12].decode() == END_LINK:
                self._limb_end = j
        self._limb_joints = [names[n] for n in ("ball_x", "ball_y", "ball_z")] + [
            names[n] for n in ("hinge", "distal_x", "distal_y")
        ]
        for body in (scene.robot, self._limb_body):
            n = pb.getNumJoints(body, physicsClientId=cid)
            pb.setJointMotorControlArray(
                body,
                list(range(n)),
                pb.VELOCITY_CONTROL,
                forces=[0.0] * n,
                physicsClientId=cid,
            )
            for link in range(-1, n):
                pb.changeDynamics(
                    body,
                    link,
                    jointDamping=0.0,
                    linearDamping=0.0,
                    angularDamping=0.0,
                    maxJointVelocity=5000.0,
                    lateralFriction=0.0,
                    spinningFriction=0.0,
                    rollingFriction=0.0,
                    physicsClientId=cid,
                )
                pb.setCollisionFilterGroupMask(body, link, 0, 0, physicsClientId=cid)
        self._resting_limbs = []
        self._obstacles = self._build_body(cid) if v.scene != "isolated" else []
        self._pose_resting_limbs(cid)
        if v.furniture is not None:
            self._build_room(cid)
            self._obstacles.append(
                self._build_boxes(
                    cid, FURNITURE_PARTS[v.furniture], v.furniture_pos, FURNITURE_RGBA
                )
            )
        self._set_limb(cid, np.array(v.init_joints))
        self._rest_clearance = [self._distance(cid, b) for b in self._obstacles]
        self._constraint = -1
        self._generation = scene.generation
        return cid

    def _keep_plain_inertia(self, cid: int) -> None:
        """Give the limb's links the inertias of the plain limb. pybullet derives a link's
        inertia from the bounding box of its collision shapes, and the seated shapes are there
        for the reset's distance queries only, so the dynamics stay those of the plain limb."""
        plain = pb.loadURDF(
            str(limb_urdf_path(self.variant.limb)), useFixedBase=True, physicsClientId=cid
        )
        for link in range(pb.getNumJoints(plain, physicsClientId=cid)):
            inertia = pb.getDynamicsInfo(plain, link, physicsClientId=cid)[2]
            pb.changeDynamics(
                self._limb_body, link, localInertiaDiagonal=inertia, physicsClientId=cid
            )
        pb.removeBody(plain, physicsClientId=cid)

    def torso_pose(self) -> tuple[Vec3, Quat]:
        """The torso's world pose: where the scene seats or lays the person, else (human
        scene) behind the limb's anchor by the limb's attachment offset."""
        v = self.variant
        if v.torso is not None:
            q = pb.getQuaternionFromEuler(v.torso[1])
            return v.torso[0], (q[0], q[1], q[2], q[3])
        inv = pb.invertTransform(TORSO_TO_LIMB[v.limb], [0.0, 0.0, 0.0, 1.0])
        p, q = pb.multiplyTransforms(
            v.limb_base_pos, pb.getQuaternionFromEuler(v.limb_base_rpy), *inv
        )
        return (p[0], p[1], p[2]), (q[0], q[1], q[2], q[3])

    def _build_body(self, cid: int) -> list[int]:
        """The torso, head and the three other limbs (static; the limb's obstacles)."""
        torso_p, torso_q = self.torso_pose()
        rgba = list(SKIN)
        bodies = []
        for center, shape in (
            (TORSO_CENTER, ("box", TORSO_HALF)),
            (HEAD_CENTER, ("sphere", HEAD_RADIUS)),
        ):
            if shape[0] == "box":
                col = pb.createCollisionShape(
                    pb.GEOM_BOX, halfExtents=list(TORSO_HALF), physicsClientId=cid
                )
                vis = pb.createVisualShape(
                    pb.GEOM_BOX, halfExtents=list(TORSO_HALF), rgbaColor=rgba, physicsClientId=cid
                )
            else:
                col = pb.createCollisionShape(
                    pb.GEOM_SPHERE, radius=HEAD_RADIUS, physicsClientId=cid
                )
                vis = pb.createVisualShape(
                    pb.GEOM_SPHERE, radius=HEAD_RADIUS, rgbaColor=rgba, physicsClientId=cid
                )
            pos, quat = pb.multiplyTransforms(torso_p, torso_q, center, [0.0, 0.0, 0.0, 1.0])
            bodies.append(pb.createMultiBody(0.0, col, vis, pos, quat, physicsClientId=cid))
        for other, offset in TORSO_TO_LIMB.items():
            if other == self.variant.limb:
                continue
            pos, quat = pb.multiplyTransforms(torso_p, torso_q, offset, [0.0, 0.0, 0.0, 1.0])
            body = pb.loadURDF(
                str(limb_urdf_path(other, seated=self.variant.seated_shapes)),
                pos,
                quat,
                useFixedBase=True,
                physicsClientId=cid,
            )
            self._resting_limbs.append((body, self.variant.resting[LIMB_NAMES.index(other)]))
            bodies.append(body)
        for body in bodies:
            for link in range(-1, pb.getNumJoints(body, physicsClientId=cid)):
                pb.setCollisionFilterGroupMask(body, link, 0, 0, physicsClientId=cid)
        return bodies

    @staticmethod
    def _build_boxes(cid: int, parts: tuple[BoxPart, ...], pos: Vec3, rgba: Rgba) -> int:
        """One static body of boxes at ``pos``; nothing collides with it (distance queries
        still see it)."""
        centers = [list(c) for c, _, _ in parts]
        halves = [list(h) for _, h, _ in parts]
        quats = [list(pb.getQuaternionFromEuler(r)) for _, _, r in parts]
        col = pb.createCollisionShapeArray(
            [pb.GEOM_BOX] * len(parts),
            halfExtents=halves,
            collisionFramePositions=centers,
            collisionFrameOrientations=quats,
            physicsClientId=cid,
        )
        vis = pb.createVisualShapeArray(
            [pb.GEOM_BOX] * len(parts),
            halfExtents=halves,
            visualFramePositions=centers,
            visualFrameOrientations=quats,
            rgbaColors=[list(rgba)] * len(parts),
            physicsClientId=cid,
        )
        body = int(pb.createMultiBody(0.0, col, vis, list(pos), physicsClientId=cid))
        pb.setCollisionFilterGroupMask(body, -1, 0, 0, physicsClientId=cid)
        return body

    def _build_room(self, cid: int) -> None:
        """The floor and walls (drawn only)."""
        self._build_boxes(cid, ROOM_PARTS[:1], (0.0, 0.0, 0.0), FLOOR_RGBA)
        self._build_boxes(cid, ROOM_PARTS[1:], (0.0, 0.0, 0.0), WALL_RGBA)

    def _pose_resting_limbs(self, cid: int) -> None:
        """Put the limb's anchor back at its pose, and the other limbs at the scene's resting
        configuration, at rest. Done on every load, so that nothing a step leaves in them
        carries over to the next (a step renormalises a tilted fixed base's quaternion, which
        moves its last bit)."""
        v = self.variant
        pb.resetBasePositionAndOrientation(
            self._limb_body,
            list(v.limb_base_pos),
            pb.getQuaternionFromEuler(v.limb_base_rpy),
            physicsClientId=cid,
        )
        for body, joints in self._resting_limbs:
            for j, q in zip(self._limb_joints, joints, strict=True):
                pb.resetJointState(body, j, q, 0.0, physicsClientId=cid)

    def _set_limb(self, cid: int, joints: NDArray[np.float64]) -> None:
        for idx, q in zip(self._limb_joints, joints, strict=True):
            pb.resetJointState(self._limb_body, idx, float(q), 0.0, physicsClientId=cid)

    def _distance(self, cid: int, body: int) -> float:
        """The limb's closest distance to ``body`` (negative: overlap), saturating at
        CLEARANCE_RADIUS. Distance queries ignore the collision filters."""
        points = pb.getClosestPoints(self._limb_body, body, CLEARANCE_RADIUS, physicsClientId=cid)
        return min((pt[8] for pt in points), default=CLEARANCE_RADIUS)

    def limb_penetration(self, limb_joints: NDArray[np.float64]) -> float:
        """How much deeper (m, as a negative number; 0 if not) the limb at ``limb_joints``
        overlaps the rest of the body than it does at the nominal start."""
        cid = self._client()
        self._set_limb(cid, limb_joints)
        worst = 0.0
        for body, rest in zip(self._obstacles, self._rest_clearance, strict=True):
            worst = min(worst, self._distance(cid, body) - rest)
        return worst

    def _load(self, state: ObjectCentricState) -> int:
        """Put ``state`` into the simulator and rebuild the weld from the resulting poses."""
        cid = self._client()
        r, limb = state[self.robot], state[self.limb]
        scene = self._scene
        scene.set_robot(r[:10], 0.0)
        for idx, q, dq in zip(scene._arm_idx, r[_R_JOINTS], r[_R_VELS], strict=True):
            pb.resetJointState(scene.robot, idx, float(q), float(dq), physicsClientId=cid)
        # The fingers are not observed: hold them open and at rest, so that nothing a step
        # leaves in them carries over to the next.
        for idx in scene._finger_idx:
            q = pb.getJointState(scene.robot, idx, physicsClientId=cid)[0]
            pb.resetJointState(scene.robot, idx, q, 0.0, physicsClientId=cid)
        for idx, q, dq in zip(self._limb_joints, limb[_L_JOINTS], limb[_L_VELS], strict=True):
            pb.resetJointState(self._limb_body, idx, float(q), float(dq), physicsClientId=cid)
        self._pose_resting_limbs(cid)
        if self._constraint >= 0:
            pb.removeConstraint(self._constraint, physicsClientId=cid)
        self._constraint = self._weld(cid)
        return cid

    def _weld(self, cid: int) -> int:
        """A fixed constraint holding the gripper at the nominal grasp: the tool frame at the
        limb's grasp frame composed with the grasp transform. pybullet poses constraint frames
        in the links' centre-of-mass frames, so the child frame is
        ``inv(limb COM) · grasp offset · grasp transform · inv(tool in gripper) · gripper COM``.
        The weld is a constant of the variant, so a state fully determines the next one."""
        robot_link = self._scene._link_idx["gripper_base_link"]
        rp = pb.getLinkState(self._scene.robot, robot_link, physicsClientId=cid)
        lp = pb.getLinkState(self._limb_body, self._limb_end, physicsClientId=cid)
        inv_lc = pb.invertTransform(lp[2], lp[3])
        rel = pb.multiplyTransforms(*inv_lc, list(self.limb_spec.grasp_offset), [0, 0, 0, 1])
        rel = pb.multiplyTransforms(*rel, *self._grasp_tf)
        rel = pb.multiplyTransforms(*rel, *_tool_to_gripper())
        rel_p, rel_q = pb.multiplyTransforms(*rel, rp[2], rp[3])
        return int(
            pb.createConstraint(
                self._scene.robot,
                robot_link,
                self._limb_body,
                self._limb_end,
                pb.JOINT_FIXED,
                [0.0, 0.0, 0.0],
                [0.0, 0.0, 0.0],
                list(rel_p),
                [0.0, 0.0, 0.0, 1.0],
                list(rel_q),
                physicsClientId=cid,
            )
        )

    def grasp_frame_pose(self) -> tuple[Vec3, Quat]:
        """World pose of the limb's grasp frame in the simulator's current configuration."""
        cid = self._client()
        ls = pb.getLinkState(
            self._limb_body, self._limb_end, computeForwardKinematics=True, physicsClientId=cid
        )
        pos, quat = pb.multiplyTransforms(
            ls[4], ls[5], list(self.limb_spec.grasp_offset), [0.0, 0.0, 0.0, 1.0]
        )
        return (pos[0], pos[1], pos[2]), (quat[0], quat[1], quat[2], quat[3])

    def _solve_grasp(self, limb_joints: NDArray[np.float64]) -> NDArray[np.float64]:
        """Arm joints that put the end effector at the grasp frame composed with the grasp
        transform: iterated pybullet IK from the variant's ``ik_start`` (if any), then
        ``robot_initial_joints``, then each of :data:`IK_STARTS` in turn, keeping the first
        solution within the arm's joint limits and ``ik_tolerance`` of the target, else the
        one closest to the target."""
        return self.grasp_arm_joints(limb_joints)[0]

    def grasp_arm_joints(
        self,
        limb_joints: NDArray[np.float64],
        first: tuple[float, ...] | None = None,
        only_first: bool = False,
        within_limits: bool = False,
    ) -> tuple[NDArray[np.float64], float]:
        """The arm joints holding the grasp of the limb at ``limb_joints`` and their gripper
        position error (m), solved as the reset solves it, trying ``first`` (e.g. the arm's
        current joints, to stay on its branch) before the reset's starts (``only_first``: no
        others, so the answer stays near ``first`` even when it misses). Planners use it to
        turn a limb path into an arm path. ``within_limits``: solve with pybullet's null-space
        IK instead, bounded :data:`IK_LIMIT_MARGIN` inside the arm's joint limits and drawn
        toward each start (the reset never uses it). Moves the simulator's bodies (every
        transition loads its state first)."""
        cid = self._client()
        scene = self._scene
        self._set_limb(cid, limb_joints)
        gp, gq = self.grasp_frame_pose()
        tool_p, tool_q = pb.multiplyTransforms(gp, gq, *self._grasp_tf)
        target_p, target_q = pb.multiplyTransforms(tool_p, tool_q, *_tool_to_gripper())
        link = scene._link_idx["gripper_base_link"]
        movable = [
            j
            for j in range(pb.getNumJoints(scene.robot, physicsClientId=cid))
            if pb.getJointInfo(scene.robot, j, physicsClientId=cid)[2] != pb.JOINT_FIXED
        ]
        arm_pos = [movable.index(j) for j in scene._arm_idx]
        bounds = self._ik_bounds(movable, arm_pos) if within_limits else None
        base = self.variant.robot_base
        best, best_err = np.array(self.config.robot_initial_joints), math.inf
        starts = [] if first is None else [first]
        if not (only_first and first is not None):
            if self.variant.ik_start is not None:
                starts.append(self.variant.ik_start)
            starts += [self.config.robot_initial_joints, *IK_STARTS]
        for start in starts:
            q = np.array(start, dtype=np.float64)
            scene.set_robot(np.array([*base, *q]), 0.0)
            for _ in range(self.config.ik_iterations):
                null_space: dict[str, list[float]] = {}
                if bounds is not None:
                    rest = [
                        pb.getJointState(scene.robot, j, physicsClientId=cid)[0] for j in movable
                    ]
                    for i, k in enumerate(arm_pos):
                        rest[k] = float(start[i])
                    null_space = {
                        "lowerLimits": bounds[0],
                        "upperLimits": bounds[1],
                        "jointRanges": bounds[2],
                        "restPoses": rest,
                    }
                sol = pb.calculateInverseKinematics(
                    scene.robot,
                    link,
                    target_p,
                    target_q,
                    maxNumIterations=100,
                    residualThreshold=1e-6,
                    physicsClientId=cid,
                    **null_space,
                )
                # pybullet's IK ignores joint ranges; a full turn is the same pose, so wrap
                # into [-pi, pi).
                q = np.array([sol[i] for i in arm_pos], dtype=np.float64)
                q = (q + math.pi) % (2.0 * math.pi) - math.pi
                scene.set_robot(np.array([*base, *q]), 0.0)
            pos = pb.getLinkState(
                scene.robot, link, computeForwardKinematics=True, physicsClientId=cid
            )[4]
            err = float(np.linalg.norm(np.subtract(pos, target_p)))
            inside = bool(np.all(q >= self._arm_low) and np.all(q <= self._arm_high))
            if inside and err < self.config.ik_tolerance:
                return q, err
            if err < best_err:
                best, best_err = q, err
        return best, best_err

    def _ik_bounds(
        self, movable: list[int], arm_pos: list[int]
    ) -> tuple[list[float], list[float], list[float]]:
        """Lower and upper limits and ranges of the robot's movable joints for pybullet's
        null-space IK: the arm's limits less :data:`IK_LIMIT_MARGIN` (continuous joints: ±2π),
        the fingers' own."""
        cid = self._scene.client
        lo, hi = [], []
        for j in movable:
            info = pb.getJointInfo(self._scene.robot, j, physicsClientId=cid)
            lo.append(float(info[8]))
            hi.append(max(float(info[9]), float(info[8])))
        for i, k in enumerate(arm_pos):
            low, high = float(self._arm_low[i]), float(self._arm_high[i])
            lo[k] = low + IK_LIMIT_MARGIN if math.isfinite(low) else -2.0 * math.pi
            hi[k] = high - IK_LIMIT_MARGIN if math.isfinite(high) else 2.0 * math.pi
        return lo, hi, [h - lo_ for lo_, h in zip(lo, hi, strict=True)]

    # -- the contract ---------------------------------------------------------------------------
    def box_objects(self) -> list[Object]:
        return [self.robot, self.limb] + ([self.fixture] if self.fixture else [])

    def limb_joint_limits(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The limb's range of motion (rad), which bounds the reset perturbation."""
        lo, hi = self.limb_spec.limits_rad
        return np.array(lo), np.array(hi)

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        v, cfg = self.variant, self.config
        nominal = np.array(v.init_joints)
        lo, hi = self.limb_joint_limits()
        free = np.ones(NUM_LIMB_JOINTS)
        if v.noise_joints is not None:
            free = np.zeros(NUM_LIMB_JOINTS)
            free[list(v.noise_joints)] = 1.0
        limb_q = nominal
        for attempt in range(MAX_INIT_DRAWS):
            noise = free * cfg.init_joint_noise * INIT_NOISE_DECAY**attempt
            draw = rng.uniform(np.maximum(nominal - noise, lo), np.minimum(nominal + noise, hi))
            if self.limb_penetration(draw) > -cfg.init_max_penetration:
                limb_q = draw
                break
        arm_q = self._solve_grasp(limb_q)
        features: dict[Object, list[float]] = {
            self.robot: [*v.robot_base, *arm_q, *([0.0] * NUM_ROBOT_JOINTS)],
            self.limb: [*limb_q, *([0.0] * NUM_LIMB_JOINTS), *v.goal_joints],
        }
        if self.fixture is not None:
            features[self.fixture] = [*v.furniture_pos, 0.0, 0.0, 0.0, 1.0]
        return ObjectCentricState.from_features(features)

    def _transition(self, state: ObjectCentricState, action: FloatArray) -> ObjectCentricState:
        cid = self._load(state)
        scene = self._scene
        pb.setJointMotorControlArray(
            scene.robot,
            scene._arm_idx,
            pb.TORQUE_CONTROL,
            forces=[float(t) for t in action],
            physicsClientId=cid,
        )
        pb.setJointMotorControlArray(
            self._limb_body,
            self._limb_joints,
            pb.TORQUE_CONTROL,
            forces=[0.0] * NUM_LIMB_JOINTS,
            physicsClientId=cid,
        )
        pb.stepSimulation(physicsClientId=cid)
        arm = pb.getJointStates(scene.robot, scene._arm_idx, physicsClientId=cid)
        limb = pb.getJointStates(self._limb_body, self._limb_joints, physicsClientId=cid)
        r, lf = state[self.robot], state[self.limb]
        r[_R_JOINTS] = [s[0] for s in arm]
        r[_R_VELS] = [s[1] for s in arm]
        lf[_L_JOINTS] = [s[0] for s in limb]
        lf[_L_VELS] = [s[1] for s in limb]
        state[self.robot], state[self.limb] = r, lf
        return state

    def distance_to_goal(self, state: ObjectCentricState) -> float:
        """Summed wrapped joint error of the limb to its goal (rad)."""
        f = state[self.limb]
        return wrapped_joint_distance(f[_L_JOINTS], f[_L_GOAL])

    def goal_reached(self, state: ObjectCentricState) -> bool:
        return self.distance_to_goal(state) < self.config.goal_atol

    def _render_state(self, state: ObjectCentricState) -> NDArray[np.uint8]:
        cfg = self.config
        self._load(state)
        target, distance, yaw, pitch = self.variant.camera
        return self._scene.capture_orbit(
            target,
            distance if cfg.camera_distance is None else cfg.camera_distance,
            yaw if cfg.camera_yaw is None else cfg.camera_yaw,
            pitch if cfg.camera_pitch is None else cfg.camera_pitch,
            cfg.image_width,
            cfg.image_height,
        )

    def close(self) -> None:
        """Release the pybullet client."""
        self._scene.close()
        self._generation = -1
        super().close()
