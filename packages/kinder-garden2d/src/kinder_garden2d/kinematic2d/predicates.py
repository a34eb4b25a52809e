"""Goal predicates of the Kinematic2D environments, as plain functions of a state.

Skills, planners and the environments themselves use these same functions, so "success" means
one thing everywhere. Rectangles follow the Kinematic2D convention (anchored at the bottom-left
corner, rotated about it).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from kinder_core import Object, ObjectCentricState
from kinder_garden2d.geometry import FloatArray
from kinder_garden2d.kinematic2d.object_types import BUTTON_GREEN

# Containment tests allow this much floating-point slack.
EPS = 1e-9


def _rect(state: ObjectCentricState, obj: Object, prefix: str = "") -> list[float]:
    """``[x, y, theta, width, height]`` of a rectangle (or of a shelf's part with ``"1"``)."""
    idx = state.layout.index
    d = state.data
    return [float(d[idx(obj, f"{k}{prefix}")]) for k in ("x", "y", "theta", "width", "height")]


def _corners(x: float, y: float, th: float, w: float, h: float) -> list[tuple[float, float]]:
    c, s = math.cos(th), math.sin(th)
    return [
        (x, y),
        (x + c * w, y + s * w),
        (x + c * w - s * h, y + s * w + c * h),
        (x - s * h, y + c * h),
    ]


def _inside(points: Iterable[Sequence[float]], rect: Sequence[float], tol: float) -> bool:
    """Do all points lie in the rectangle ``[x, y, theta, width, height]`` (grown by ``tol``)?"""
    x, y, th, w, h = rect
    c, s = math.cos(th), math.sin(th)
    for px, py in points:
        dx, dy = px - x, py - y
        u, v = dx * c + dy * s, dy * c - dx * s
        if not (-tol <= u <= w + tol and -tol <= v <= h + tol):
            return False
    return True


def rectangle_vertices(state: ObjectCentricState, obj: Object) -> FloatArray:
    """The 4×2 corners of a rectangle object, counter-clockwise from its anchor."""
    return np.array(_corners(*_rect(state, obj)))


def points_in_rectangle(
    points: ArrayLike, state: ObjectCentricState, rect: Object, tol: float = EPS
) -> bool:
    """Do all ``points`` (``(k, 2)``) lie in the rectangle object ``rect``?"""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2).tolist()
    return _inside(pts, _rect(state, rect), tol)


def robot_in_region(state: ObjectCentricState, robot: Object, region: Object) -> bool:
    """Motion2D's goal: the robot's base centre lies in the rectangle ``region``."""
    p = (state.get(robot, "x"), state.get(robot, "y"))
    return _inside([p], _rect(state, region), EPS)


def is_on(state: ObjectCentricState, block: Object, surface: Object, tol: float = 0.025) -> bool:
    """Obstruction2D's goal: the block's two lowest vertices, each moved down by ``tol``, lie in
    the rectangle ``surface``."""
    v = sorted(_corners(*_rect(state, block)), key=lambda p: p[1])[:2]
    return _inside([(px, py - tol) for px, py in v], _rect(state, surface), EPS)


def is_inside(state: ObjectCentricState, obj: Object, region: Object) -> bool:
    """ClutteredRetrieval2D's goal: all four vertices of the rectangle ``obj`` lie in the
    rectangle ``region``."""
    return _inside(_corners(*_rect(state, obj)), _rect(state, region), EPS)


def shelf_opening_vertices(state: ObjectCentricState, shelf: Object) -> FloatArray:
    """The 4×2 corners of a shelf's opening (its inner "part 1" rectangle)."""
    return np.array(_corners(*_rect(state, shelf, "1")))


def is_inside_shelf(state: ObjectCentricState, block: Object, shelf: Object) -> bool:
    """ClutteredStorage2D's per-block goal: all four vertices of ``block`` lie in the shelf's
    opening."""
    return _inside(_corners(*_rect(state, block)), _rect(state, shelf, "1"), EPS)


def is_pressed(state: ObjectCentricState, button: Object) -> bool:
    """A button is pressed when its colour is the pressed green."""
    rgb = (state.get(button, k) for k in ("color_r", "color_g", "color_b"))
    return all(abs(v - g) <= 1e-6 for v, g in zip(rgb, BUTTON_GREEN))


def all_pressed(state: ObjectCentricState, buttons: Iterable[Object]) -> bool:
    """StickButton2D's and PushPullHook2D's goal: every button is pressed."""
    return all(is_pressed(state, b) for b in buttons)
