"""Vectorized 2D geometry for rectangles, circles and the shapes built from them.

Every Kinematic2D body is an oriented box or a circle, so all collision work reduces to three
pairwise kernels that take whole arrays of shapes and return a boolean matrix:

* :func:`obb_obb_overlap` (separating axis test on the four box axes),
* :func:`obb_circle_overlap` (closest point on the box to the circle centre),
* :func:`circle_circle_overlap`.

An oriented box ("OBB") is a row ``[cx, cy, cos θ, sin θ, hw, hh]``: centre, the unit vector of
its first axis, and half-extents along its two axes. A circle is a row ``[cx, cy, r]``. Shapes
that touch count as overlapping (closed sets), which matches "intersects".

Kinematic2D rectangles are anchored at their bottom-left corner and rotate about it;
:func:`obbs_from_anchor` converts them. An L-shape is the union of two boxes
(:func:`lshape_obbs`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def wrap_angle(theta: ArrayLike) -> FloatArray:
    """Angles wrapped into [−π, π)."""
    out: FloatArray = np.mod(np.asarray(theta, dtype=np.float64) + np.pi, 2 * np.pi) - np.pi
    return out


def obbs_from_anchor(
    x: ArrayLike, y: ArrayLike, theta: ArrayLike, width: ArrayLike, height: ArrayLike
) -> FloatArray:
    """``(n, 6)`` OBB rows of rectangles anchored at their bottom-left corner ``(x, y)``, rotated
    by ``theta`` about that corner, ``width`` along the rotated x axis (scalars give one row)."""
    x, y, theta = np.asarray(x, float), np.asarray(y, float), np.asarray(theta, float)
    w, h = np.asarray(width, float), np.asarray(height, float)
    c, s = np.cos(theta), np.sin(theta)
    hw, hh = 0.5 * w, 0.5 * h
    out: FloatArray = np.stack(
        np.broadcast_arrays(x + c * hw - s * hh, y + s * hw + c * hh, c, s, hw, hh), axis=-1
    ).reshape(-1, 6)
    return out


def obb_corners(obbs: ArrayLike) -> FloatArray:
    """``(n, 4, 2)`` corners of OBB rows, counter-clockwise."""
    b = np.asarray(obbs, dtype=np.float64).reshape(-1, 6)
    cx, cy, c, s, hw, hh = b.T
    ux, uy = c * hw, s * hw  # half first axis
    vx, vy = -s * hh, c * hh  # half second axis
    xs = np.stack([cx - ux - vx, cx + ux - vx, cx + ux + vx, cx - ux + vx], axis=1)
    ys = np.stack([cy - uy - vy, cy + uy - vy, cy + uy + vy, cy - uy + vy], axis=1)
    out: FloatArray = np.stack([xs, ys], axis=2)
    return out


def lshape_obbs(
    x: float, y: float, theta: float, width: float, side1: float, side2: float
) -> FloatArray:
    """The two boxes of an L-shape (``(2, 6)`` OBB rows).

    The anchor ``(x, y)`` is the outer corner of the L. In the shape's own frame (rotated by
    ``theta`` about the anchor) the first arm spans ``[−side1, 0] × [−width, 0]`` and the second
    ``[−width, 0] × [−side2, 0]``: at ``theta = 0`` the L looks like ``‾‾‾‾|`` with the anchor
    at its top-right corner.
    """
    c, s = np.cos(theta), np.sin(theta)
    # Centres in the local frame, then rotated about the anchor.
    lx = np.array([-0.5 * side1, -0.5 * width])
    ly = np.array([-0.5 * width, -0.5 * side2])
    out = np.empty((2, 6))
    out[:, 0] = x + c * lx - s * ly
    out[:, 1] = y + s * lx + c * ly
    out[:, 2] = c
    out[:, 3] = s
    out[:, 4] = [0.5 * side1, 0.5 * width]
    out[:, 5] = [0.5 * width, 0.5 * side2]
    return out


def obb_obb_overlap(a: FloatArray, b: FloatArray) -> BoolArray:
    """``(n, m)``: does box ``a[i]`` overlap box ``b[j]``? (Separating axis test.)"""
    acx, acy, ac, as_, ahw, ahh = (a[:, k, None] for k in range(6))
    bcx, bcy, bc, bs, bhw, bhh = (b[None, :, k] for k in range(6))
    dx = bcx - acx
    dy = bcy - acy
    # cos and sin of the relative angle; |.| gives the projections of one box's axes on the other's.
    cr = np.abs(ac * bc + as_ * bs)
    sr = np.abs(ac * bs - as_ * bc)
    sep = np.abs(dx * ac + dy * as_) > ahw + bhw * cr + bhh * sr
    sep |= np.abs(dy * ac - dx * as_) > ahh + bhw * sr + bhh * cr
    sep |= np.abs(dx * bc + dy * bs) > bhw + ahw * cr + ahh * sr
    sep |= np.abs(dy * bc - dx * bs) > bhh + ahw * sr + ahh * cr
    out: BoolArray = ~sep
    return out


def _circle_in_box_frame(
    a: FloatArray, circles: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Circle centres in each box's frame (``(n, m)`` each), and the boxes' half-extents."""
    acx, acy, ac, as_, ahw, ahh = (a[:, k, None] for k in range(6))
    dx = circles[None, :, 0] - acx
    dy = circles[None, :, 1] - acy
    return dx * ac + dy * as_, dy * ac - dx * as_, ahw, ahh


def obb_circle_overlap(a: FloatArray, circles: FloatArray) -> BoolArray:
    """``(n, m)``: does box ``a[i]`` overlap circle ``circles[j]``?"""
    lx, ly, hw, hh = _circle_in_box_frame(a, circles)
    ex = np.abs(lx) - hw
    ey = np.abs(ly) - hh
    np.maximum(ex, 0.0, out=ex)
    np.maximum(ey, 0.0, out=ey)
    r = circles[None, :, 2]
    out: BoolArray = ex * ex + ey * ey <= r * r
    return out


def circle_circle_overlap(p: FloatArray, q: FloatArray) -> BoolArray:
    """``(n, m)``: does circle ``p[i]`` overlap circle ``q[j]``?"""
    dx = q[None, :, 0] - p[:, 0, None]
    dy = q[None, :, 1] - p[:, 1, None]
    rr = q[None, :, 2] + p[:, 2, None]
    out: BoolArray = dx * dx + dy * dy <= rr * rr
    return out


def points_in_obbs(points: ArrayLike, obbs: FloatArray, tol: float = 0.0) -> BoolArray:
    """``(k, n)``: is ``points[k]`` inside box ``obbs[n]`` (grown by ``tol`` on each side)?"""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    cx, cy, c, s, hw, hh = (obbs[None, :, k] for k in range(6))
    dx = p[:, 0, None] - cx
    dy = p[:, 1, None] - cy
    out: BoolArray = (np.abs(dx * c + dy * s) <= hw + tol) & (np.abs(dy * c - dx * s) <= hh + tol)
    return out


def circle_push_out_of_obb(box: FloatArray, circle: FloatArray) -> FloatArray:
    """The smallest translation of ``circle`` (a row ``[cx, cy, r]``) that separates it from
    ``box`` (an OBB row); zero if they do not overlap."""
    cx, cy, c, s, hw, hh = (float(v) for v in box)
    dx, dy, r = float(circle[0]) - cx, float(circle[1]) - cy, float(circle[2])
    lx, ly = dx * c + dy * s, dy * c - dx * s
    qx, qy = float(np.clip(lx, -hw, hw)), float(np.clip(ly, -hh, hh))
    ex, ey = lx - qx, ly - qy
    d = float(np.hypot(ex, ey))
    if d > r:
        return np.zeros(2)
    if d > 0.0:  # centre outside the box: push along the centre's offset from the box
        mx, my = ex / d * (r - d), ey / d * (r - d)
    else:  # centre inside: leave through the nearest face
        gap_x, gap_y = hw - abs(lx), hh - abs(ly)
        if gap_x <= gap_y:
            mx, my = np.copysign(gap_x + r, lx), 0.0
        else:
            mx, my = 0.0, np.copysign(gap_y + r, ly)
    return np.array([mx * c - my * s, mx * s + my * c])
