"""Pure-numpy geometry for the Kinematic3D families: poses, shapes and exact convex overlap.

Poses are (position (3,), quaternion (x, y, z, w) (4,)). Shapes of observed objects are derived
from their features; everything here is backend-free so goal predicates and reset samplers can be
tested without pybullet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from kinder_garden3d.kinematic3d.object_types import (
    CONTAINER,
    EQUILATERAL,
    WALL_THICKNESS,
)

Array = NDArray[np.float64]

#: Grasp pegs on Packing3D parts (half extents), centred on the part's top face.
PEG_HALF = (0.01, 0.01, 0.025)


# --------------------------------------------------------------------------------------------
# Quaternions (x, y, z, w) and rigid transforms.


def quat_multiply(a: Array, b: Array) -> Array:
    """Hamilton product a ⊗ b of (x, y, z, w) quaternions."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def quat_conjugate(q: Array) -> Array:
    """The inverse of a unit quaternion."""
    return np.array([-q[0], -q[1], -q[2], q[3]])


def quat_to_matrix(q: Array) -> Array:
    """Rotation matrix of a unit (x, y, z, w) quaternion."""
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def yaw_quat(yaw: float) -> Array:
    """The quaternion of a rotation by ``yaw`` about +z."""
    return np.array([0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)])


def quat_yaw(q: Array) -> float:
    """The yaw (rotation about z) of a quaternion."""
    x, y, z, w = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def compose(p1: Array, q1: Array, p2: Array, q2: Array) -> tuple[Array, Array]:
    """(p1, q1) ∘ (p2, q2)."""
    return p1 + quat_to_matrix(q1) @ p2, quat_multiply(q1, q2)


def invert(p: Array, q: Array) -> tuple[Array, Array]:
    """The inverse transform of (p, q)."""
    qi = quat_conjugate(q)
    return -(quat_to_matrix(qi) @ p), qi


def normalize_quat(q: Array) -> Array:
    """A unit quaternion with w >= 0 (a canonical sign keeps states comparable)."""
    q = q / np.linalg.norm(q)
    return -q if q[3] < 0 else q


# --------------------------------------------------------------------------------------------
# Shapes.


@dataclass(frozen=True)
class Part:
    """One convex piece of an object, in the object's frame.

    ``kind`` "box": ``params`` = half extents; "prism": ``params`` = the triangle's 2-D vertices
    (3×2, flattened) followed by the half depth; "cylinder": ``params`` = (radius, half height),
    axis along the local z axis (no vertex form: :func:`part_vertices` rejects it).
    """

    kind: Literal["box", "prism", "cylinder"]
    params: tuple[float, ...]
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)


def triangle_vertices_2d(triangle_type: float, side_a: float, side_b: float) -> Array:
    """The triangle's 3 vertices (3×2) in its frame, centroid at the origin."""
    if triangle_type == EQUILATERAL:
        h = side_a * math.sqrt(3.0) / 2.0
        pts = np.array([[0.0, 0.0], [side_a, 0.0], [side_a / 2.0, h]])
    else:
        pts = np.array([[0.0, 0.0], [side_a, 0.0], [0.0, side_b]])
    centred: Array = pts - pts.mean(axis=0)
    return centred


def cuboid_parts(object_type: float, half: Array) -> list[Part]:
    """Convex pieces of a cuboid: one box, or a floor plus four walls for a container."""
    hx, hy, hz = (float(v) for v in half)
    if object_type != CONTAINER:
        return [Part("box", (hx, hy, hz))]
    t = WALL_THICKNESS / 2.0
    return [
        Part("box", (hx, hy, t), (0.0, 0.0, -hz + t)),
        Part("box", (t, hy, hz), (hx - t, 0.0, 0.0)),
        Part("box", (t, hy, hz), (-hx + t, 0.0, 0.0)),
        Part("box", (hx - 2 * t, t, hz), (0.0, hy - t, 0.0)),
        Part("box", (hx - 2 * t, t, hz), (0.0, -hy + t, 0.0)),
    ]


def triangle_parts(triangle_type: float, side_a: float, side_b: float, depth: float) -> list[Part]:
    """The prism of a triangle part (no peg)."""
    verts = triangle_vertices_2d(triangle_type, side_a, side_b)
    return [Part("prism", (*verts.reshape(-1).tolist(), depth / 2.0))]


def peg_part(top_z: float) -> Part:
    """The grasp peg standing on a part's top face at the centroid."""
    return Part("box", PEG_HALF, (0.0, 0.0, top_z + PEG_HALF[2]))


def part_vertices(part: Part, pos: Array, quat: Array) -> Array:
    """World vertices of a part of an object at (pos, quat)."""
    if part.kind == "cylinder":
        raise ValueError("a cylinder part has no vertices; use the pybullet scene's queries")
    if part.kind == "box":
        hx, hy, hz = part.params
        signs = np.array(
            [[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float
        )
        local = signs * np.array([hx, hy, hz])
    else:
        tri = np.array(part.params[:6]).reshape(3, 2)
        hd = part.params[6]
        local = np.concatenate(
            [np.column_stack([tri, np.full(3, -hd)]), np.column_stack([tri, np.full(3, hd)])]
        )
    local = local + np.array(part.pos)
    return np.asarray(local @ quat_to_matrix(quat).T + pos)


def _axes(part: Part, rot: Array) -> tuple[Array, Array]:
    """Face normals and edge directions of a part in the world frame."""
    if part.kind == "box":
        return rot.T.copy(), rot.T.copy()
    tri = np.array(part.params[:6]).reshape(3, 2)
    edges2d = np.roll(tri, -1, axis=0) - tri
    normals = [np.array([e[1], -e[0], 0.0]) for e in edges2d] + [np.array([0.0, 0.0, 1.0])]
    edges = [np.array([e[0], e[1], 0.0]) for e in edges2d] + [np.array([0.0, 0.0, 1.0])]
    return np.array(normals) @ rot.T, np.array(edges) @ rot.T


def convex_penetration(
    a: Part, a_pos: Array, a_quat: Array, b: Part, b_pos: Array, b_quat: Array
) -> float:
    """Exact separating-axis test between two convex parts.

    Returns the smallest overlap along any candidate axis: positive means the parts interpenetrate
    by that much, zero or negative means they are separated (or touching).
    """
    va, vb = part_vertices(a, a_pos, a_quat), part_vertices(b, b_pos, b_quat)
    na, ea = _axes(a, quat_to_matrix(a_quat))
    nb, eb = _axes(b, quat_to_matrix(b_quat))
    cross = np.cross(ea[:, None, :], eb[None, :, :]).reshape(-1, 3)
    axes = np.concatenate([na, nb, cross])
    norms = np.linalg.norm(axes, axis=1)
    axes = axes[norms > 1e-9] / norms[norms > 1e-9, None]
    pa, pb = va @ axes.T, vb @ axes.T
    overlap = np.minimum(pa.max(axis=0), pb.max(axis=0)) - np.maximum(
        pa.min(axis=0), pb.min(axis=0)
    )
    return float(overlap.min())


Xy = tuple[float, float]


def rects_overlap_2d(c1: Xy, h1: Xy, c2: Xy, h2: Xy, margin: float = 0.0) -> bool:
    """Axis-aligned rectangles (centre, half extents) overlap, with ``margin`` of clearance."""
    return (
        abs(c1[0] - c2[0]) < h1[0] + h2[0] + margin and abs(c1[1] - c2[1]) < h1[1] + h2[1] + margin
    )


def rect_distance_2d(c1: Xy, h1: Xy, c2: Xy, h2: Xy) -> float:
    """Distance between two axis-aligned rectangles (centre, half extents); 0 when they
    overlap. Two upright boxes whose heights overlap are this far apart in 3D."""
    dx = max(abs(c1[0] - c2[0]) - h1[0] - h2[0], 0.0)
    dy = max(abs(c1[1] - c2[1]) - h1[1] - h2[1], 0.0)
    return math.hypot(dx, dy)
