"""Each Kinematic2D family's goal, reward and extra rules over a batch of states.

Every function mirrors the single env's predicate in :mod:`~kinder_garden2d.kinematic2d.predicates`
or its ``_transition`` extension expression for expression, so the batched answers equal the
single env's bit for bit. :func:`batched_world` picks the family's :class:`BatchedWorld`.
"""

from __future__ import annotations

import abc
from collections.abc import Callable

import numpy as np

from kinder_core import Object
from kinder_garden2d.geometry import BoolArray, FloatArray
from kinder_garden2d.kinematic2d.base import Kinematic2DEnv
from kinder_garden2d.kinematic2d.batched.kernels import lshape_pairs, obb_circle_pairs, py_hypot
from kinder_garden2d.kinematic2d.batched.world import BatchedWorld
from kinder_garden2d.kinematic2d.clutteredretrieval2d import ClutteredRetrieval2DEnv
from kinder_garden2d.kinematic2d.clutteredstorage2d import ClutteredStorage2DEnv
from kinder_garden2d.kinematic2d.crv import IntArray
from kinder_garden2d.kinematic2d.motion2d import Motion2DEnv
from kinder_garden2d.kinematic2d.object_types import BUTTON_GREEN
from kinder_garden2d.kinematic2d.obstruction2d import Obstruction2DConfig, Obstruction2DEnv
from kinder_garden2d.kinematic2d.predicates import EPS
from kinder_garden2d.kinematic2d.pushpullhook2d import PushPullHook2DConfig, PushPullHook2DEnv
from kinder_garden2d.kinematic2d.stickbutton2d import StickButton2DEnv

_RECT = ("x", "y", "theta", "width", "height")
_OPENING = ("x1", "y1", "theta1", "width1", "height1")


def corners(r: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``(..., 4)`` x and y of the corners of rectangles ``r`` (``(..., 5)`` rows
    ``[x, y, theta, width, height]``), counter-clockwise from the anchor (``_corners``)."""
    x, y, th, w, h = (r[..., k] for k in range(5))
    c, s = np.cos(th), np.sin(th)
    xs = np.stack([x, x + c * w, x + c * w - s * h, x - s * h], -1)
    ys = np.stack([y, y + s * w, y + s * w + c * h, y + c * h], -1)
    return xs, ys


def inside(px: FloatArray, py: FloatArray, rect: FloatArray, tol: float) -> BoolArray:
    """``(...)``: do all points ``(..., K)`` lie in the rectangles ``(..., 5)`` grown by ``tol``
    (``_inside``)?"""
    x, y, th, w, h = (rect[..., k, None] for k in range(5))
    c, s = np.cos(th), np.sin(th)
    dx, dy = px - x, py - y
    u, v = dx * c + dy * s, dy * c - dx * s
    ok = (-tol <= u) & (u <= w + tol) & (-tol <= v) & (v <= h + tol)
    out: BoolArray = np.logical_and.reduce(ok, axis=-1)
    return out


class _Rules(BatchedWorld, abc.ABC):
    """A batched world with the family's goal and reward (−1 per step by default)."""

    def rect(self, obj: Object, features: tuple[str, ...] = _RECT) -> FloatArray:
        """Indices of one object's rectangle features in the state array."""
        return np.array([self.env.layout.index(obj, f) for f in features], dtype=np.intp)

    @abc.abstractmethod
    def goal(self, data: FloatArray) -> BoolArray:
        """``(N,)``: the family's ``goal_reached`` of every state."""

    def reward(self, terminated: BoolArray) -> FloatArray:
        """``(N,)`` rewards of steps that end in ``terminated``."""
        return np.full(len(terminated), -1.0)


class Motion2DWorld(_Rules):
    """Motion2D: the robot's base centre in the target region (``robot_in_region``)."""

    def __init__(self, env: Kinematic2DEnv) -> None:
        super().__init__(env)
        assert isinstance(env, Motion2DEnv)
        self._region = self.rect(env.target_region)
        self._xy = self.robot_idx[:2]

    def goal(self, data: FloatArray) -> BoolArray:
        p = data[:, self._xy]
        return inside(p[:, :1], p[:, 1:], data[:, self._region], EPS)


class Obstruction2DWorld(_Rules):
    """Obstruction2D: the block's two lowest corners, moved down by the tolerance, in the
    target surface (``is_on``)."""

    def __init__(self, env: Kinematic2DEnv) -> None:
        super().__init__(env)
        assert isinstance(env, Obstruction2DEnv)
        assert isinstance(env.config, Obstruction2DConfig)
        self._block = self.rect(env.target_block)
        self._surface = self.rect(env.target_surface)
        self._tol = env.config.on_tolerance

    def goal(self, data: FloatArray) -> BoolArray:
        xs, ys = corners(data[:, self._block])
        low = np.argsort(ys, axis=1, kind="stable")[:, :2]
        px = np.take_along_axis(xs, low, axis=1)
        py = np.take_along_axis(ys, low, axis=1) - self._tol
        return inside(px, py, data[:, self._surface], EPS)


class ClutteredRetrieval2DWorld(_Rules):
    """ClutteredRetrieval2D: all corners of the target block in the region (``is_inside``)."""

    def __init__(self, env: Kinematic2DEnv) -> None:
        super().__init__(env)
        assert isinstance(env, ClutteredRetrieval2DEnv)
        self._block = self.rect(env.target_block)
        self._region = self.rect(env.target_region)

    def goal(self, data: FloatArray) -> BoolArray:
        xs, ys = corners(data[:, self._block])
        return inside(xs, ys, data[:, self._region], EPS)


class ClutteredStorage2DWorld(_Rules):
    """ClutteredStorage2D: every block inside the shelf's opening (``is_inside_shelf``)."""

    def __init__(self, env: Kinematic2DEnv) -> None:
        super().__init__(env)
        assert isinstance(env, ClutteredStorage2DEnv)
        self._blocks = np.stack([self.rect(b) for b in env.blocks])
        self._opening = self.rect(env.shelf, _OPENING)

    def goal(self, data: FloatArray) -> BoolArray:
        xs, ys = corners(data[:, self._blocks])
        opening = np.broadcast_to(data[:, None, self._opening], (*xs.shape[:2], 5))
        out: BoolArray = np.logical_and.reduce(inside(xs, ys, opening, EPS), axis=1)
        return out


def press_touched(
    data: FloatArray,
    robot_idx: IntArray,
    stick_idx: IntArray,
    circle_idx: IntArray,
    color_idx: IntArray,
) -> None:
    """Turn green (in place) every button that the robot's base, arm or gripper, its suction
    zone while the vacuum is on, or the stick touches (``press_touched_buttons``): the same
    bounding-circle prefilter and exact tests, for every sub-env and button at once."""
    colors = data[:, color_idx]  # (N, K, 3)
    unpressed = np.any(np.abs(colors - BUTTON_GREEN) > 1e-6, axis=2)
    if not unpressed.any():
        return
    x, y, th, br, aj, _, vac, gh, gw = (v[:, None] for v in data[:, robot_idx].T)
    c, s = np.cos(th), np.sin(th)
    on = vac > 0.5
    reach = np.where(on, aj + 2.0 * gw, aj + 0.5 * gw)
    px, py, pth, pw, ph = (v[:, None] for v in data[:, stick_idx].T)
    pc, ps = np.cos(pth), np.sin(pth)
    scx = px + 0.5 * (pc * pw - ps * ph)
    scy = py + 0.5 * (ps * pw + pc * ph)
    boxes = [
        (x + 0.5 * aj * c, y + 0.5 * aj * s, c, s, 0.5 * aj, 0.25 * gw),  # arm
        (x + aj * c, y + aj * s, c, s, 0.5 * gw, 0.5 * gh),  # gripper
        (scx, scy, pc, ps, 0.5 * pw, 0.5 * ph),  # stick
    ]
    suction = (x + (aj + 1.5 * gw) * c, y + (aj + 1.5 * gw) * s, c, s, 0.5 * gw, 0.5 * gh)
    b = data[:, circle_idx]  # (N, K, 3)
    bx, by, r = b[..., 0], b[..., 1], b[..., 2]
    (near, near_unsure), (touch, touch_unsure) = _distance_tests(
        np.hypot, bx, by, r, x, y, br, reach, gh, scx, scy, pw, ph
    )
    # C's hypot (np.hypot) and Python's math.hypot differ by at most a couple of ulps, so only
    # a comparison within far less than 1e-9 of its threshold can differ: redo those with
    # math.hypot's exact algorithm.
    unsure = np.flatnonzero(np.ravel(near_unsure | touch_unsure))
    if unsure.size:
        n, k = np.unravel_index(unsure, bx.shape)
        (exact_near, _), (exact_touch, _) = _distance_tests(
            py_hypot,
            *(v[n, k] for v in (bx, by, r)),
            *(v[n, 0] for v in (x, y, br, reach, gh, scx, scy, pw, ph)),
        )
        near[n, k], touch[n, k] = exact_near, exact_touch
    for box in boxes:
        touch |= _circle_touches_box(bx, by, r, box)
    touch |= on & _circle_touches_box(bx, by, r, suction)
    pressed = unpressed & near & touch
    if pressed.any():
        rows, k = np.nonzero(pressed)
        data[rows[:, None], color_idx[k]] = BUTTON_GREEN


_SLACK = 1e-9


def _distance_tests(
    hypot: Callable[[FloatArray, FloatArray], FloatArray],
    bx: FloatArray,
    by: FloatArray,
    r: FloatArray,
    x: FloatArray,
    y: FloatArray,
    br: FloatArray,
    reach: FloatArray,
    gh: FloatArray,
    scx: FloatArray,
    scy: FloatArray,
    pw: FloatArray,
    ph: FloatArray,
) -> tuple[tuple[BoolArray, BoolArray], tuple[BoolArray, BoolArray]]:
    """``press_touched_buttons``'s distance tests with a given ``hypot``: is each button within
    the robot's or the stick's bounding circle, and does it touch the robot's base? Each comes
    with where its comparison lies within ``_SLACK`` of its threshold."""
    d_robot = hypot(bx - x, by - y)
    d_stick = hypot(bx - scx, by - scy)
    t_robot = np.maximum(br, hypot(reach, 0.5 * gh)) + r
    t_stick = 0.5 * hypot(pw, ph) + r
    t_base = br + r
    near = (d_robot <= t_robot) | (d_stick <= t_stick)
    near_unsure = (np.abs(d_robot - t_robot) <= _SLACK) | (np.abs(d_stick - t_stick) <= _SLACK)
    return (near, near_unsure), (d_robot <= t_base, np.abs(d_robot - t_base) <= _SLACK)


def _circle_touches_box(
    x: FloatArray, y: FloatArray, r: FloatArray, box: tuple[FloatArray, ...]
) -> BoolArray:
    cx, cy, c, s, hw, hh = box
    dx, dy = x - cx, y - cy
    ex = np.maximum(np.abs(dx * c + dy * s) - hw, 0.0)
    ey = np.maximum(np.abs(dy * c - dx * s) - hh, 0.0)
    out: BoolArray = ex * ex + ey * ey <= r * r
    return out


def all_green(data: FloatArray, color_idx: IntArray) -> BoolArray:
    """``(N,)``: is every button (colour indices ``(K, 3)``) pressed (``all_pressed``)?"""
    ok = np.abs(data[:, color_idx] - BUTTON_GREEN) <= 1e-6
    out: BoolArray = np.logical_and.reduce(ok.reshape(len(data), -1), axis=1)
    return out


class StickButton2DWorld(_Rules):
    """StickButton2D: buttons latch green when touched; the goal is all of them green, with
    reward 0 on the step that reaches it."""

    def __init__(self, env: Kinematic2DEnv) -> None:
        super().__init__(env)
        assert isinstance(env, StickButton2DEnv)
        idx = env.layout.indices
        self._stick = idx([env.stick], ["x", "y", "theta", "width", "height"])[0]
        self._circles = idx(env.buttons, ["x", "y", "radius"])
        self._colors = idx(env.buttons, ["color_r", "color_g", "color_b"])

    def transition(self, data: FloatArray, action: FloatArray) -> FloatArray:
        new = super().transition(data, action)
        press_touched(new, self.robot_idx, self._stick, self._circles, self._colors)
        return new

    def goal(self, data: FloatArray) -> BoolArray:
        return all_green(data, self._colors)

    def reward(self, terminated: BoolArray) -> FloatArray:
        out: FloatArray = np.where(terminated, 0.0, -1.0)
        return out


class PushPullHook2DWorld(_Rules):
    """PushPullHook2D: a held hook pushes the movable button (a held button pushes the hook) by
    the vector from the hook outline's closest point to the button's centre; both buttons turn
    green when their centres are closer than the press distance."""

    def __init__(self, env: Kinematic2DEnv) -> None:
        super().__init__(env)
        assert isinstance(env, PushPullHook2DEnv)
        assert isinstance(env.config, PushPullHook2DConfig)
        idx = env.layout.indices
        self._hook_m = self.movable.index(env.hook)
        self._button_m = self.movable.index(env.movable_button)
        self._hook = idx([env.hook], ["x", "y", "theta", "width", "length_side1", "length_side2"])[
            0
        ]
        self._button = idx([env.movable_button], ["x", "y", "radius"])[0]
        self._target = idx([env.target_button], ["x", "y", "radius"])[0]
        self._colors = idx(
            [env.movable_button, env.target_button], ["color_r", "color_g", "color_b"]
        )
        self._press_distance = env.config.press_distance

    def push(self, new: FloatArray, held: BoolArray) -> BoolArray:
        pushed = np.zeros_like(held)
        hook_held, button_held = held[:, self._hook_m], held[:, self._button_m]
        rows = np.flatnonzero(hook_held != button_held)
        if not rows.size:
            return pushed
        lx, ly, lth, lw, l1, l2 = new[rows][:, self._hook].T
        circle = new[rows][:, self._button]
        boxes = lshape_pairs(lx, ly, lth, lw, l1, l2)  # (R, 2, 6)
        touch = obb_circle_pairs(boxes[:, 0], circle) | obb_circle_pairs(boxes[:, 1], circle)
        rows, circle = rows[touch], circle[touch]
        if not rows.size:
            return pushed
        lx, ly, lth, lw, l1, l2 = (v[touch] for v in (lx, ly, lth, lw, l1, l2))
        px, py = lshape_closest_point(lx, ly, lth, lw, l1, l2, circle[:, 0], circle[:, 1])
        dx, dy = circle[:, 0] - px, circle[:, 1] - py
        by_hook = hook_held[rows]
        target = np.where(by_hook[:, None], self._button[None, :2], self._hook[None, :2])
        new[rows[:, None], target] += np.stack([dx, dy], -1)
        pushed[rows, np.where(by_hook, self._button_m, self._hook_m)] = True
        return pushed

    def transition(self, data: FloatArray, action: FloatArray) -> FloatArray:
        new = super().transition(data, action)
        m, t = new[:, self._button], new[:, self._target]
        close = py_hypot(m[:, 0] - t[:, 0], m[:, 1] - t[:, 1]) < self._press_distance
        new[np.flatnonzero(close)[:, None], self._colors.reshape(-1)] = np.tile(BUTTON_GREEN, 2)
        return new

    def goal(self, data: FloatArray) -> BoolArray:
        return all_green(data, self._colors)

    def reward(self, terminated: BoolArray) -> FloatArray:
        out: FloatArray = np.where(terminated, 0.0, -1.0)
        return out


def lshape_closest_point(
    x: FloatArray,
    y: FloatArray,
    theta: FloatArray,
    width: FloatArray,
    side1: FloatArray,
    side2: FloatArray,
    px: FloatArray,
    py: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """The point of each L-shape's outline closest to ``(px, py)``
    (``lshape_closest_boundary_point`` for every row; ties go to the first edge)."""
    zero = np.zeros_like(x)
    lxs = np.stack([zero, -side1, -side1, -width, -width, zero], -1)
    lys = np.stack([zero, zero, -width, -width, -side2, -side2], -1)
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    vx = (lxs * c - lys * s) + x[:, None]
    vy = (lxs * s + lys * c) + y[:, None]
    x2, y2 = np.roll(vx, -1, axis=1), np.roll(vy, -1, axis=1)
    dx, dy = x2 - vx, y2 - vy
    pxc, pyc = px[:, None], py[:, None]
    t = np.clip(((pxc - vx) * dx + (pyc - vy) * dy) / (dx * dx + dy * dy), 0.0, 1.0)
    cx, cy = vx + t * dx, vy + t * dy
    k = np.argmin(np.hypot(cx - pxc, cy - pyc), axis=1)[:, None]
    return np.take_along_axis(cx, k, 1)[:, 0], np.take_along_axis(cy, k, 1)[:, 0]


_WORLDS: dict[type[Kinematic2DEnv], type[_Rules]] = {
    Motion2DEnv: Motion2DWorld,
    Obstruction2DEnv: Obstruction2DWorld,
    ClutteredRetrieval2DEnv: ClutteredRetrieval2DWorld,
    ClutteredStorage2DEnv: ClutteredStorage2DWorld,
    StickButton2DEnv: StickButton2DWorld,
    PushPullHook2DEnv: PushPullHook2DWorld,
}


def batched_world(env: Kinematic2DEnv) -> _Rules:
    """The batched world of a single env's family.

    Raises:
        ValueError: for an env whose family has no batched implementation.
    """
    for cls, world in _WORLDS.items():
        if isinstance(env, cls):
            return world(env)
    raise ValueError(
        f"No batched implementation for {type(env).__name__}; batched families: "
        f"{sorted(c.__name__ for c in _WORLDS)}"
    )
