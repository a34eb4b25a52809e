"""Batched geometry kernels: the single-env kernels of :mod:`kinder_garden2d.geometry` over a
leading batch axis.

Every kernel evaluates the same floating-point expressions, in the same order, as its single-env
counterpart (``obb_obb_overlap``, ``obb_circle_overlap``, ``circle_circle_overlap``,
``_obbs_aabb``, ``_aabb_hits``), so that each batched answer equals the single env's bit for
bit. OBB sets are ``(N, A, 6)`` arrays of rows ``[cx, cy, cos, sin, hw, hh]``, circle sets
``(N, A, 3)`` arrays of ``[cx, cy, r]`` and axis-aligned boxes ``(..., 4)`` arrays of
``[xmin, xmax, ymin, ymax]``.

:func:`py_hypot` reproduces Python's ``math.hypot`` (which the single envs call, and which
differs from C's ``hypot``, hence ``np.hypot``, in the last bit for about 0.5 % of inputs).
"""

from __future__ import annotations

import numpy as np

from kinder_garden2d.geometry import BoolArray, FloatArray


def obb_obb(a: FloatArray, b: FloatArray) -> BoolArray:
    """``(N, A, B)``: does box ``a[n, i]`` overlap box ``b[n, j]``? (``obb_obb_overlap``.)"""
    acx, acy, ac, as_, ahw, ahh = (a[:, :, None, k] for k in range(6))
    bcx, bcy, bc, bs, bhw, bhh = (b[:, None, :, k] for k in range(6))
    dx = bcx - acx
    dy = bcy - acy
    cr = np.abs(ac * bc + as_ * bs)
    sr = np.abs(ac * bs - as_ * bc)
    sep = np.abs(dx * ac + dy * as_) > ahw + bhw * cr + bhh * sr
    sep |= np.abs(dy * ac - dx * as_) > ahh + bhw * sr + bhh * cr
    sep |= np.abs(dx * bc + dy * bs) > bhw + ahw * cr + ahh * sr
    sep |= np.abs(dy * bc - dx * bs) > bhh + ahw * sr + ahh * cr
    out: BoolArray = ~sep
    return out


def obb_circle(a: FloatArray, circles: FloatArray) -> BoolArray:
    """``(N, A, C)``: does box ``a[n, i]`` overlap circle ``circles[n, j]``?
    (``obb_circle_overlap``.)"""
    acx, acy, ac, as_, hw, hh = (a[:, :, None, k] for k in range(6))
    dx = circles[:, None, :, 0] - acx
    dy = circles[:, None, :, 1] - acy
    ex = np.abs(dx * ac + dy * as_) - hw
    ey = np.abs(dy * ac - dx * as_) - hh
    np.maximum(ex, 0.0, out=ex)
    np.maximum(ey, 0.0, out=ey)
    r = circles[:, None, :, 2]
    out: BoolArray = ex * ex + ey * ey <= r * r
    return out


def circle_circle(p: FloatArray, q: FloatArray) -> BoolArray:
    """``(N, P, Q)``: does circle ``p[n, i]`` overlap circle ``q[n, j]``?
    (``circle_circle_overlap``.)"""
    dx = q[:, None, :, 0] - p[:, :, None, 0]
    dy = q[:, None, :, 1] - p[:, :, None, 1]
    rr = q[:, None, :, 2] + p[:, :, None, 2]
    out: BoolArray = dx * dx + dy * dy <= rr * rr
    return out


def obbs_aabb(b: FloatArray) -> FloatArray:
    """``(..., 4)`` axis-aligned bounds of OBB rows ``(..., 6)``."""
    ac, as_ = np.abs(b[..., 2]), np.abs(b[..., 3])
    ex = ac * b[..., 4] + as_ * b[..., 5]
    ey = as_ * b[..., 4] + ac * b[..., 5]
    out: FloatArray = np.stack([b[..., 0] - ex, b[..., 0] + ex, b[..., 1] - ey, b[..., 1] + ey], -1)
    return out


def circles_aabb(c: FloatArray) -> FloatArray:
    """``(..., 4)`` axis-aligned bounds of circle rows ``(..., 3)``."""
    r = c[..., 2]
    out: FloatArray = np.stack([c[..., 0] - r, c[..., 0] + r, c[..., 1] - r, c[..., 1] + r], -1)
    return out


def aabb_hits(aabbs: FloatArray, box: FloatArray) -> BoolArray:
    """``(N, A)``: does ``aabbs[n, i]`` meet ``box[n]`` (closed intervals)?"""
    out: BoolArray = (
        (aabbs[..., 0] <= box[:, None, 1])
        & (aabbs[..., 1] >= box[:, None, 0])
        & (aabbs[..., 2] <= box[:, None, 3])
        & (aabbs[..., 3] >= box[:, None, 2])
    )
    return out


def anchored_obbs(
    x: FloatArray, y: FloatArray, theta: FloatArray, w: FloatArray, h: FloatArray
) -> FloatArray:
    """``(..., 6)`` OBB rows of anchored rectangles (``obbs_from_anchor`` elementwise)."""
    c, s = np.cos(theta), np.sin(theta)
    hw, hh = 0.5 * w, 0.5 * h
    out: FloatArray = np.stack([x + c * hw - s * hh, y + s * hw + c * hh, c, s, hw, hh], -1)
    return out


def lshape_pairs(
    x: FloatArray, y: FloatArray, theta: FloatArray, w: FloatArray, s1: FloatArray, s2: FloatArray
) -> FloatArray:
    """``(..., 2, 6)``: the two boxes of L-shapes (``lshape_obbs`` elementwise)."""
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
    lx = np.stack([-0.5 * s1, -0.5 * w], -1)
    ly = np.stack([-0.5 * w, -0.5 * s2], -1)
    cx = x[..., None] + c * lx - s * ly
    cy = y[..., None] + s * lx + c * ly
    hw = np.stack([0.5 * s1, 0.5 * w], -1)
    hh = np.stack([0.5 * w, 0.5 * s2], -1)
    out: FloatArray = np.stack(
        [cx, cy, np.broadcast_to(c, cx.shape), np.broadcast_to(s, cx.shape), hw, hh], -1
    )
    return out


def _split(x: FloatArray) -> tuple[FloatArray, FloatArray]:
    t = x * 134217729.0  # Veltkamp's constant 2**27 + 1
    hi = t - (t - x)
    return hi, x - hi


def _exact_mul(x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Dekker's product: ``x * y`` as a rounded value and its exact error."""
    xh, xl = _split(x)
    yh, yl = _split(y)
    p = xh * yh
    q = xh * yl + xl * yh
    z = p + q
    return z, p - z + q + xl * yl


def py_hypot(x: FloatArray, y: FloatArray) -> FloatArray:
    """Elementwise ``math.hypot(x, y)`` exactly as CPython 3.11 computes it for finite inputs:
    the scaled, compensated sum of squares with one differential correction of the root."""
    ax, ay = np.abs(x), np.abs(y)
    m = np.maximum(ax, ay)
    _, e = np.frexp(m)
    scale = np.ldexp(1.0, -e)
    csum = np.ones_like(m)
    frac1 = np.zeros_like(m)
    frac2 = np.zeros_like(m)
    for v in (ax, ay):
        hi, lo = _exact_mul(v * scale, v * scale)
        total = csum + hi
        frac2 = frac2 + ((csum - total) + hi)
        frac1 = frac1 + lo
        csum = total
    with np.errstate(invalid="ignore", divide="ignore"):
        h = np.sqrt(csum - 1.0 + (frac1 + frac2))
        hi, lo = _exact_mul(-h, h)
        total = csum + hi
        frac2 = frac2 + ((csum - total) + hi)
        frac1 = frac1 + lo
        h = h + (total - 1.0 + (frac1 + frac2)) / (2.0 * h)
        out: FloatArray = np.where(m == 0.0, m, h / scale)
    return out


def obb_obb_pairs(a: FloatArray, b: FloatArray) -> BoolArray:
    """``(P,)``: does box ``a[p]`` overlap box ``b[p]``? (``obb_obb_overlap`` on pairs.)"""
    acx, acy, ac, as_, ahw, ahh = a.T
    bcx, bcy, bc, bs, bhw, bhh = b.T
    dx = bcx - acx
    dy = bcy - acy
    cr = np.abs(ac * bc + as_ * bs)
    sr = np.abs(ac * bs - as_ * bc)
    sep = np.abs(dx * ac + dy * as_) > ahw + bhw * cr + bhh * sr
    sep |= np.abs(dy * ac - dx * as_) > ahh + bhw * sr + bhh * cr
    sep |= np.abs(dx * bc + dy * bs) > bhw + ahw * cr + ahh * sr
    sep |= np.abs(dy * bc - dx * bs) > bhh + ahw * sr + ahh * cr
    out: BoolArray = ~sep
    return out


def obb_circle_pairs(a: FloatArray, circles: FloatArray) -> BoolArray:
    """``(P,)``: does box ``a[p]`` overlap circle ``circles[p]``? (``obb_circle_overlap`` on
    pairs.)"""
    acx, acy, ac, as_, hw, hh = a.T
    dx = circles[:, 0] - acx
    dy = circles[:, 1] - acy
    ex = np.abs(dx * ac + dy * as_) - hw
    ey = np.abs(dy * ac - dx * as_) - hh
    np.maximum(ex, 0.0, out=ex)
    np.maximum(ey, 0.0, out=ey)
    r = circles[:, 2]
    out: BoolArray = ex * ex + ey * ey <= r * r
    return out


def circle_circle_pairs(p: FloatArray, q: FloatArray) -> BoolArray:
    """``(P,)``: does circle ``p[k]`` overlap circle ``q[k]``? (``circle_circle_overlap`` on
    pairs.)"""
    dx = q[:, 0] - p[:, 0]
    dy = q[:, 1] - p[:, 1]
    rr = q[:, 2] + p[:, 2]
    out: BoolArray = dx * dx + dy * dy <= rr * rr
    return out
