"""Object types, z-orders and colours shared by the Kinematic2D environments.

Every geometric type has the eight base features ``x, y, theta, static, color_r, color_g,
color_b, z_order``; the robot type ``crv_robot`` has its own nine features. Colours are RGB in
[0, 1].
"""

from __future__ import annotations

from kinder_core import Type

BASE_FEATURES = ("x", "y", "theta", "static", "color_r", "color_g", "color_b", "z_order")

GEOM2D = Type("geom2d", BASE_FEATURES)
RECTANGLE = Type("rectangle", ("width", "height"), parent=GEOM2D)
CIRCLE = Type("circle", ("radius",), parent=GEOM2D)
LOBJECT = Type("lobject", ("width", "length_side1", "length_side2"), parent=GEOM2D)
DOUBLE_RECTANGLE = Type(
    "double_rectangle",
    (
        "width",
        "height",
        "x1",
        "y1",
        "theta1",
        "width1",
        "height1",
        "z_order1",
        "color_r1",
        "color_g1",
        "color_b1",
    ),
    parent=GEOM2D,
)
ROBOT_FEATURES = (
    "x",
    "y",
    "theta",
    "base_radius",
    "arm_joint",
    "arm_length",
    "vacuum",
    "gripper_height",
    "gripper_width",
)
CRV_ROBOT = Type("crv_robot", ROBOT_FEATURES)

# Env-specific subtypes only rename their parent.
TARGET_BLOCK = Type("target_block", (), parent=RECTANGLE)
TARGET_SURFACE = Type("target_surface", (), parent=RECTANGLE)
TARGET_REGION = Type("target_region", (), parent=RECTANGLE)
SHELF = Type("shelf", (), parent=DOUBLE_RECTANGLE)

KINEMATIC2D_TYPES = (GEOM2D, CRV_ROBOT)


class ZOrder:
    """Collision layers. Two bodies may collide unless either is NONE; if either is ALL they
    may; otherwise only when their layers are equal."""

    FLOOR = 1
    SURFACE = 2
    ALL = 100
    NONE = 101


Color = tuple[float, float, float]

PURPLE: Color = (128 / 255, 0.0, 128 / 255)
BLACK: Color = (0.1, 0.1, 0.1)
BROWN: Color = (0.4, 0.2, 0.1)
ORANGE: Color = (1.0, 0.647, 0.0)
OBSTRUCTION_RED: Color = (0.75, 0.1, 0.1)
TABLE_GREY: Color = (0.75, 0.75, 0.75)
BLOCK_BLUE: Color = (0.0, 0.3, 1.0)
BUTTON_RED: Color = (0.9, 0.0, 0.0)
BUTTON_GREEN: Color = (0.0, 0.9, 0.0)
BUTTON_BLUE: Color = (0.0, 0.0, 0.9)
