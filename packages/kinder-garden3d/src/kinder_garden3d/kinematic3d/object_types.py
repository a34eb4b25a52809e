"""Object types and the action space shared by the Kinematic3D families.

All quaternion features are ordered **(x, y, z, w)** (``pose_qx, pose_qy, pose_qz, pose_qw`` and
``grasp_tf_qx … grasp_tf_qw``), the order pybullet uses. Dynamic3D orders its quaternions
(w, x, y, z); see environments.md §9.10.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from kinder_core import Type

POSE_FEATURES = ("pose_x", "pose_y", "pose_z", "pose_qx", "pose_qy", "pose_qz", "pose_qw")

#: The mobile manipulator: base pose, 7 arm joints, gripper, and the held object's transform in
#: the end-effector frame (meaningful only while ``grasp_active`` is 1).
ROBOT_TYPE = Type(
    "Kinematic3DRobot",
    (
        "pos_base_x",
        "pos_base_y",
        "pos_base_rot",
        *(f"joint_{i}" for i in range(1, 8)),
        "finger_state",
        "grasp_active",
        "grasp_tf_x",
        "grasp_tf_y",
        "grasp_tf_z",
        "grasp_tf_qx",
        "grasp_tf_qy",
        "grasp_tf_qz",
        "grasp_tf_qw",
    ),
)

#: A box. ``object_type`` is :data:`SOLID` (−1) for a solid cuboid or :data:`CONTAINER` (1) for an
#: open-top hollow box whose walls and floor are :data:`WALL_THICKNESS` thick.
CUBOID_TYPE = Type(
    "Kinematic3DCuboid",
    (
        *POSE_FEATURES,
        "grasp_active",
        "object_type",
        "half_extent_x",
        "half_extent_y",
        "half_extent_z",
    ),
)

#: A triangular prism with its axis along the local z axis. ``triangle_type`` 0 = equilateral
#: with side ``side_a``; 1 = right triangle with legs ``side_a`` (x) and ``side_b`` (y). The pose
#: is that of the triangle's centroid at mid-depth; ``depth`` is the full prism height.
TRIANGLE_TYPE = Type(
    "Kinematic3DTriangle",
    (*POSE_FEATURES, "grasp_active", "triangle_type", "side_a", "side_b", "depth"),
)

#: A visual-only point (e.g. a navigation target).
POINT_TYPE = Type("Kinematic3DPoint", ("x", "y", "z"))

#: A static, observed object whose shape is fixed by its family (e.g. a shelf): only its pose.
FIXTURE_TYPE = Type("Kinematic3DFixture", POSE_FEATURES)

SOLID = -1.0
CONTAINER = 1.0
WALL_THICKNESS = 0.01
EQUILATERAL = 0.0
RIGHT = 1.0

ALL_TYPES = (ROBOT_TYPE, CUBOID_TYPE, TRIANGLE_TYPE, POINT_TYPE, FIXTURE_TYPE)


def robot_action_space(max_magnitude: float) -> spaces.Box:
    """The 11-D Kinematic3D action: Δbase (x, y, yaw), Δ7 joints, gripper command.

    Indices 0–9 are bounded by ±``max_magnitude``; index 10 lies in [−1, 1] (< −0.5 close,
    > 0.5 open, otherwise no change).
    """
    if not max_magnitude > 0:
        raise ValueError(f"max_magnitude must be positive, got {max_magnitude}")
    low = np.array([-max_magnitude] * 10 + [-1.0], dtype=np.float32)
    high = np.array([max_magnitude] * 10 + [1.0], dtype=np.float32)
    return spaces.Box(low, high, dtype=np.float32)


ACTION_TABLE = """| index | meaning | bounds |
|---|---|---|
| 0–2 | Δbase x, Δbase y (m), Δbase yaw (rad) | ±max_action_mag |
| 3–9 | Δjoint_1 … Δjoint_7 (rad) | ±max_action_mag |
| 10 | gripper command: < −0.5 close (grasp), > 0.5 open (release), else no-op | [−1, 1] |"""

ROBOT_FEATURE_DOC = (
    "`Kinematic3DRobot` (19): `pos_base_x, pos_base_y, pos_base_rot, joint_1..joint_7, "
    "finger_state, grasp_active, grasp_tf_x, grasp_tf_y, grasp_tf_z, grasp_tf_qx, grasp_tf_qy, "
    "grasp_tf_qz, grasp_tf_qw` (quaternion order x, y, z, w)"
)
CUBOID_FEATURE_DOC = (
    "`Kinematic3DCuboid` (12): `pose_x, pose_y, pose_z, pose_qx, pose_qy, pose_qz, pose_qw, "
    "grasp_active, object_type, half_extent_x, half_extent_y, half_extent_z` (object_type −1 = "
    "solid, 1 = open-top container)"
)
TRIANGLE_FEATURE_DOC = (
    "`Kinematic3DTriangle` (12): `pose_x … pose_qw, grasp_active, triangle_type, side_a, side_b, "
    "depth` (triangle_type 0 = equilateral, 1 = right)"
)
FIXTURE_FEATURE_DOC = (
    "`Kinematic3DFixture` (7): `pose_x, pose_y, pose_z, pose_qx, pose_qy, pose_qz, pose_qw`"
)
