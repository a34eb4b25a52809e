"""Object types of the Dynamic2D environments (pure data: importing this imports no simulator).

Every Dynamic2D object except the two-finger robot shares the base features of
:data:`DYNAMIC2D_OBJECT`: pose (``x, y, theta``), velocity (``vx, vy`` of the centre of mass and
``omega``), ``static``, ``held``, colour and ``z_order``. Positions are body origins: the centre
for rectangles, squares and circles; the outer corner of an L-object; the top-centre of a T-object's
bar.

``z_order`` decides which objects collide, as in Kinematic2D: two objects collide when either is
:data:`Z_ALL` or both have the same z-order; :data:`Z_NONE` objects collide with nothing (they are
not simulated).
"""

from __future__ import annotations

from kinder_core import Type

# z-orders (the Kinematic2D values).
Z_FLOOR = 1.0
Z_SURFACE = 2.0
Z_ALL = 100.0
Z_NONE = 101.0

BASE_FEATURES = (
    "x",
    "y",
    "theta",
    "vx",
    "vy",
    "omega",
    "static",
    "held",
    "color_r",
    "color_g",
    "color_b",
    "z_order",
)

DYNAMIC2D_OBJECT = Type("dynamic2d_object", BASE_FEATURES)
KIN_RECTANGLE = Type("kin_rectangle", ("width", "height"), parent=DYNAMIC2D_OBJECT)
DYN_RECTANGLE = Type("dyn_rectangle", ("width", "height", "mass"), parent=DYNAMIC2D_OBJECT)
LOBJECT = Type(
    "lobject", ("width", "length_side1", "length_side2", "mass"), parent=DYNAMIC2D_OBJECT
)
TOBJECT = Type(
    "tobject", ("width", "length_horizontal", "length_vertical", "mass"), parent=DYNAMIC2D_OBJECT
)
SMALL_CIRCLE = Type("small_circle", ("radius", "mass"), parent=DYNAMIC2D_OBJECT)
SMALL_SQUARE = Type("small_square", ("size", "mass"), parent=DYNAMIC2D_OBJECT)
DOT_ROBOT = Type("dot_robot", ("radius",), parent=DYNAMIC2D_OBJECT)

# Task-specific subtypes (no extra features; they let predicates tell objects apart by type).
TARGET_SURFACE = Type("target_surface", (), parent=KIN_RECTANGLE)
TARGET_BLOCK = Type("target_block", (), parent=DYN_RECTANGLE)
HOOK = Type("hook", (), parent=LOBJECT)

KIN_ROBOT_FEATURES = (
    "x",
    "y",
    "theta",
    "vx_base",
    "vy_base",
    "omega_base",
    "vx_arm",
    "vy_arm",
    "omega_arm",
    "vx_gripper_l",
    "vy_gripper_l",
    "omega_gripper_l",
    "vx_gripper_r",
    "vy_gripper_r",
    "omega_gripper_r",
    "static",
    "base_radius",
    "arm_joint",
    "arm_length",
    "gripper_base_width",
    "gripper_base_height",
    "finger_gap",
    "finger_height",
    "finger_width",
)
KIN_ROBOT = Type("kin_robot", KIN_ROBOT_FEATURES)

# Colours (RGB in [0, 1]), as upstream.
PURPLE = (128 / 255, 0.0, 128 / 255)
BLACK = (0.1, 0.1, 0.1)
BROWN = (0.4, 0.2, 0.1)
ORANGE = (1.0, 165 / 255, 0.0)
RED = (0.75, 0.1, 0.1)
GREY = (0.5, 0.5, 0.5)
LIGHT_GREEN = (0.6, 0.9, 0.6)
BLUE = (0.0, 0.3, 1.0)
