"""Object types of the Dynamic3D environments (environments.md §5.1 "Object state types").

Quaternions are ordered (w, x, y, z). Velocities are in the world frame.
"""

from __future__ import annotations

from kinder_core import Type

POSE = ("x", "y", "z", "qw", "qx", "qy", "qz")

#: A fixture (cupboard, table, kitchen island, …): its pose (7). Fixtures do not move, but their
#: pose may be sampled at reset.
FIXTURE_TYPE = Type("Dynamic3DFixture", POSE)
#: A fixed obstacle observed with its bounding box (the spec's "static collider").
STATIC_COLLIDER_TYPE = Type("Dynamic3DStaticCollider", ("bb_x", "bb_y", "bb_z"), FIXTURE_TYPE)
#: A movable object: pose, linear and angular velocity, full bounding-box size (16).
MOVABLE_TYPE = Type(
    "Dynamic3DMovable",
    (*POSE, "vx", "vy", "vz", "wx", "wy", "wz", "bb_x", "bb_y", "bb_z"),
)
#: A seesaw: a movable pivot plus its beam's hinge angle (rad) and rate (18).
SEESAW_TYPE = Type("Dynamic3DSeesaw", ("hinge_pos", "hinge_vel"), MOVABLE_TYPE)
#: A drawer of a fixture: its slide position (m, 0 = closed), as upstream kindergarden 0.2.5.
DRAWER_TYPE = Type("Dynamic3DDrawer", ("pos",))
#: The TidyBot++-style robot (22).
ROBOT_TYPE = Type(
    "Dynamic3DRobot",
    (
        "pos_base_x", "pos_base_y", "pos_base_rot",
        *(f"pos_arm_joint{i}" for i in range(1, 8)),
        "pos_gripper",
        "vel_base_x", "vel_base_y", "vel_base_rot",
        *(f"vel_arm_joint{i}" for i in range(1, 8)),
        "vel_gripper",
    ),
)  # fmt: skip

ALL_TYPES = (FIXTURE_TYPE, STATIC_COLLIDER_TYPE, MOVABLE_TYPE, SEESAW_TYPE, DRAWER_TYPE, ROBOT_TYPE)

#: The desk-mounted Franka FR3 arm (19): its mount pose (fixed during an episode, so no base
#: velocities), arm joints, gripper, as upstream kindergarden 0.2.5's ``mujoco_fr3_robot``.
FR3_ROBOT_TYPE = Type(
    "Dynamic3DFR3Robot",
    (
        "pos_base_x", "pos_base_y", "pos_base_rot",
        *(f"pos_arm_joint{i}" for i in range(1, 8)),
        "pos_gripper",
        *(f"vel_arm_joint{i}" for i in range(1, 8)),
        "vel_gripper",
    ),
)  # fmt: skip
