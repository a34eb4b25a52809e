"""Plain-numpy geometry of Dynamic2D objects: shapes, overlap tests and goal predicates.

Used by initial-state sampling, goals, rendering and tests; the simulator builds its shapes from
the same local parts (:func:`local_parts`), so what is drawn and checked is what is simulated.
Every shape is a union of convex polygons (counter-clockwise, body-local or world coordinates)
and at most one circle.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Poly = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def box(xmin: float, xmax: float, ymin: float, ymax: float) -> Poly:
    """An axis-aligned box as a counter-clockwise (4, 2) polygon."""
    return np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]], dtype=np.float64)


@dataclass(frozen=True)
class LocalShape:
    """A body-local shape: convex polygons and/or a circle centred at the body origin."""

    polys: tuple[Poly, ...] = ()
    radius: float = 0.0  # > 0: a circle of this radius at the origin

    @property
    def area(self) -> float:
        return sum(polygon_area(p) for p in self.polys) + math.pi * self.radius**2

    @property
    def centroid(self) -> tuple[float, float]:
        """Centre of area (= centre of mass for uniform density), body-local."""
        if self.radius > 0 and not self.polys:
            return (0.0, 0.0)
        areas = np.array([polygon_area(p) for p in self.polys])
        cents = np.array([polygon_centroid(p) for p in self.polys])
        c = (areas[:, None] * cents).sum(axis=0) / areas.sum()
        return (float(c[0]), float(c[1]))


def rect_shape(width: float, height: float) -> LocalShape:
    """A rectangle centred at the origin."""
    return LocalShape((box(-width / 2, width / 2, -height / 2, height / 2),))


def lobject_shape(width: float, side1: float, side2: float) -> LocalShape:
    """An L: origin at the outer corner, arm 1 (``side1`` long) along local −x, arm 2 (``side2``
    long) along local −y, both ``width`` thick (two non-overlapping convex parts)."""
    side2 = max(side2, width * (1 + 1e-9))
    return LocalShape(
        (box(-side1, 0.0, -width, 0.0), box(-width, 0.0, -side2, -width)),
    )


def tobject_shape(width: float, length_h: float, length_v: float) -> LocalShape:
    """A T: origin at the top-centre of the bar (``length_h`` × ``width``), the stem
    (``width`` × ``length_v``) hanging below its middle."""
    return LocalShape(
        (
            box(-length_h / 2, length_h / 2, -width, 0.0),
            box(-width / 2, width / 2, -width - length_v, -width),
        )
    )


def circle_shape(radius: float) -> LocalShape:
    return LocalShape((), radius)


def polygon_area(p: Poly) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def polygon_centroid(p: Poly) -> NDArray[np.float64]:
    x, y = p[:, 0], p[:, 1]
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    a = 0.5 * cross.sum()
    cx = ((x + np.roll(x, -1)) * cross).sum() / (6 * a)
    cy = ((y + np.roll(y, -1)) * cross).sum() / (6 * a)
    return np.array([cx, cy])


def transform(points: Poly, x: float, y: float, theta: float) -> Poly:
    """Body-local points to world coordinates for a body at (x, y, theta)."""
    c, s = math.cos(theta), math.sin(theta)
    out: Poly = points @ np.array([[c, s], [-s, c]]) + np.array([x, y])
    return out


@dataclass(frozen=True)
class WorldShape:
    """A shape placed in the world: convex polygons and optional circles (centre, radius)."""

    polys: tuple[Poly, ...] = ()
    circles: tuple[tuple[float, float, float], ...] = ()


def place(shape: LocalShape, x: float, y: float, theta: float) -> WorldShape:
    polys = tuple(transform(p, x, y, theta) for p in shape.polys)
    circles = ((x, y, shape.radius),) if shape.radius > 0 else ()
    return WorldShape(polys, circles)


# -- overlap tests (separating axis theorem) -----------------------------------------------------
def _axes(p: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit edge normals of a polygon ``(K, 2)``, or of each polygon of a stack ``(N, K, 2)``."""
    e = np.roll(p, -1, axis=-2) - p
    n = np.stack([-e[..., 1], e[..., 0]], axis=-1)
    out: NDArray[np.float64] = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return out


def convex_penetration(p: Poly, q: Poly) -> float:
    """Penetration depth of two convex polygons (> 0 overlap, <= 0 separated or touching)."""
    axes = np.concatenate([_axes(p), _axes(q)])
    pp, qq = p @ axes.T, q @ axes.T
    hi = np.minimum(pp.max(axis=0), qq.max(axis=0))
    overlap = hi - np.maximum(pp.min(axis=0), qq.min(axis=0))
    return float(overlap.min())


def convex_penetrations(p: NDArray[np.float64], q: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(N,)``: :func:`convex_penetration` of each row's polygons ``p[n]`` and ``q[n]``
    (``(N, K, 2)`` and ``(N, M, 2)``), with the same operations per row (one product of each
    polygon with its row's axes), so each equals the single call bit for bit."""
    at = np.concatenate([_axes(p), _axes(q)], axis=1).transpose(0, 2, 1)
    pp, qq = p @ at, q @ at
    hi = np.minimum(pp.max(axis=1), qq.max(axis=1))
    overlap = hi - np.maximum(pp.min(axis=1), qq.min(axis=1))
    depth: NDArray[np.float64] = overlap.min(axis=1)
    return depth


def circle_poly_penetration(cx: float, cy: float, r: float, p: Poly) -> float:
    """Penetration depth of a circle and a convex polygon (> 0 overlap)."""
    c = np.array([cx, cy])
    # Closest point of the polygon's boundary, and whether the centre is inside.
    a = p
    b = np.roll(p, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", c - a, ab) / np.einsum("ij,ij->i", ab, ab), 0.0, 1.0)
    closest = a + t[:, None] * ab
    d = float(np.min(np.linalg.norm(closest - c, axis=1)))
    ac = c - a
    inside = bool(np.all(ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0] >= 0))
    return r + d if inside else r - d


def penetration(a: WorldShape, b: WorldShape) -> float:
    """The largest penetration depth between any parts of two shapes (> 0 means overlap)."""
    best = -math.inf
    for p in a.polys:
        for q in b.polys:
            best = max(best, convex_penetration(p, q))
        for cx, cy, r in b.circles:
            best = max(best, circle_poly_penetration(cx, cy, r, p))
    for cx, cy, r in a.circles:
        for q in b.polys:
            best = max(best, circle_poly_penetration(cx, cy, r, q))
        for dx, dy, dr in b.circles:
            best = max(best, r + dr - math.hypot(cx - dx, cy - dy))
    return best


def bounds(a: WorldShape) -> tuple[float, float, float, float]:
    """Axis-aligned bounding box (xmin, xmax, ymin, ymax) of a shape."""
    xs = [float(p[:, 0].min()) for p in a.polys] + [c[0] - c[2] for c in a.circles]
    xm = [float(p[:, 0].max()) for p in a.polys] + [c[0] + c[2] for c in a.circles]
    ys = [float(p[:, 1].min()) for p in a.polys] + [c[1] - c[2] for c in a.circles]
    ym = [float(p[:, 1].max()) for p in a.polys] + [c[1] + c[2] for c in a.circles]
    return min(xs), max(xm), min(ys), max(ym)


def overlaps(a: WorldShape, b: WorldShape, tol: float = 0.0) -> bool:
    """True if the shapes overlap by more than ``tol``."""
    ax0, ax1, ay0, ay1 = bounds(a)
    bx0, bx1, by0, by1 = bounds(b)
    if ax1 - bx0 <= tol or bx1 - ax0 <= tol or ay1 - by0 <= tol or by1 - ay0 <= tol:
        return False
    return penetration(a, b) > tol


def point_in_convex(pt: Sequence[float], p: Poly) -> bool:
    ab = np.roll(p, -1, axis=0) - p
    ap = np.asarray(pt, dtype=np.float64) - p
    return bool(np.all(ab[:, 0] * ap[:, 1] - ab[:, 1] * ap[:, 0] >= 0))


def is_on(block: Poly, surface: Poly, tol: float) -> bool:
    """Kinematic2D's ``is_on``: the block's two lowest vertices, moved down by ``tol``, both lie
    inside the (convex) surface."""
    lowest = block[np.argsort(block[:, 1], kind="stable")[:2]] - np.array([0.0, tol])
    return all(point_in_convex(v, surface) for v in lowest)


#: A rectangle's pose and size features, in the order :func:`rect_polys` takes them.
RECT_FEATURES = ("x", "y", "theta", "width", "height")

#: The corners of ``box(-hw, hw, -hh, hh)`` as signs of ``(hw, hh)`` (a sign flip is exact).
_BOX_SIGNS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def rect_polys(x: Poly, y: Poly, theta: Poly, width: Poly, height: Poly) -> NDArray[np.float64]:
    """``(N, 4, 2)``: row ``n`` is ``transform(rect_shape(width[n], height[n]).polys[0], x[n],
    y[n], theta[n])``, computed with the same operations (``math.cos`` and ``math.sin``, one
    4×2 by 2×2 product per row), so it equals that polygon bit for bit."""
    local = _BOX_SIGNS * np.stack([width / 2, height / 2], -1)[:, None, :]
    angles = theta.tolist()
    c = np.array([math.cos(t) for t in angles])
    s = np.array([math.sin(t) for t in angles])
    rot = np.stack([c, s, -s, c], -1).reshape(-1, 2, 2)
    out: NDArray[np.float64] = local @ rot + np.stack([x, y], -1)[:, None, :]
    return out


def are_on(blocks: NDArray[np.float64], surfaces: NDArray[np.float64], tol: float) -> BoolArray:
    """``(N,)``: :func:`is_on` of each row's block and surface ``(N, K, 2)``, with its
    operations elementwise."""
    rows = np.arange(len(blocks))[:, None]
    order = np.argsort(blocks[..., 1], axis=1, kind="stable")[:, :2]
    lowest = blocks[rows, order] - np.array([0.0, tol])  # (N, 2, 2)
    edge = np.roll(surfaces, -1, axis=1) - surfaces  # (N, K, 2)
    to_pt = lowest[:, :, None, :] - surfaces[:, None, :, :]  # (N, 2, K, 2)
    cross = edge[:, None, :, 0] * to_pt[..., 1] - edge[:, None, :, 1] * to_pt[..., 0]
    out: BoolArray = np.all(cross >= 0, axis=(1, 2))
    return out


def wrap_angle(theta: float) -> float:
    """An angle wrapped into [−π, π)."""
    return (theta + math.pi) % (2 * math.pi) - math.pi


# -- the two-finger robot ------------------------------------------------------------------------
@dataclass(frozen=True)
class KinRobotGeometry:
    """World geometry of the two-finger robot (see :func:`kin_robot_geometry`)."""

    base: tuple[float, float, float]  # centre x, y and radius
    arm: Poly
    gripper: Poly
    finger_l: Poly
    finger_r: Poly

    @property
    def shape(self) -> WorldShape:
        return WorldShape((self.arm, self.gripper, self.finger_l, self.finger_r), (self.base,))

    @property
    def upper(self) -> WorldShape:
        """Everything but the base (the parts that pass over FLOOR-level objects)."""
        return WorldShape((self.arm, self.gripper, self.finger_l, self.finger_r))


def kin_robot_local(
    arm_joint: float,
    arm_length: float,
    gripper_w: float,
    gripper_h: float,
    finger_gap: float,
    finger_h: float,
    finger_w: float,
) -> tuple[Poly, Poly, Poly, Poly]:
    """Arm, gripper base and the two fingers in the base frame (x along the arm), as upstream
    builds them.

    The gripper base (``gripper_w`` along the arm × ``gripper_h`` across) is centred at distance
    ``arm_joint``; the arm is a bar of length ``arm_length`` and thickness ``gripper_w`` behind it;
    the fingers (``finger_w`` along × ``finger_h`` across) start at the gripper base's centre with
    centres ``finger_gap`` apart, the left one (+y) first.
    """
    gx = arm_joint
    arm = box(gx - gripper_w / 2 - arm_length, gx - gripper_w / 2, -gripper_w / 2, gripper_w / 2)
    gripper = box(gx - gripper_w / 2, gx + gripper_w / 2, -gripper_h / 2, gripper_h / 2)
    f0, f1 = gx, gx + finger_w
    half = finger_gap / 2
    left = box(f0, f1, half - finger_h / 2, half + finger_h / 2)
    right = box(f0, f1, -half - finger_h / 2, -half + finger_h / 2)
    return arm, gripper, left, right


def kin_robot_geometry(f: Sequence[float] | NDArray[np.float64]) -> KinRobotGeometry:
    """World geometry of a ``kin_robot`` from its 24 features (in type order)."""
    x, y, th = float(f[0]), float(f[1]), float(f[2])
    radius, arm_joint, arm_length = float(f[16]), float(f[17]), float(f[18])
    gw, gh, gap, fh, fw = (float(v) for v in f[19:24])
    parts = kin_robot_local(arm_joint, arm_length, gw, gh, gap, fh, fw)
    arm, gripper, left, right = (transform(p, x, y, th) for p in parts)
    return KinRobotGeometry((x, y, radius), arm, gripper, left, right)
