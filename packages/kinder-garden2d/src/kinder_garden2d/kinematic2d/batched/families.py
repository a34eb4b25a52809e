"""Each Kinematic2D family's goal, reward and extra rules over a batch of states.

Every function mirrors the single env's predicate in :mod:`~kinder_garden2d.kinematic2d.predicates`
or its ``_transition`` extension expression for expression, so the batched answers equal the
single env's bit for bit. :func:`batched_world` picks the family's :class:`BatchedWorld`.
"""

from __future__ import annotations

import numpy as np

from kinder_core import Object
from kinder_garden2d.geometry import BoolArray, FloatArray
from kinder_garden2d.kinematic2d.base import Kinematic2DEnv
from kinder_garden2d.kinematic2d.batched.world import BatchedWorld
from kinder_garden2d.kinematic2d.clutteredretrieval2d import ClutteredRetrieval2DEnv
from kinder_garden2d.kinematic2d.clutteredstorage2d import ClutteredStorage2DEnv
from kinder_garden2d.kinematic2d.motion2d import Motion2DEnv
from kinder_garden2d.kinematic2d.obstruction2d import Obstruction2DConfig, Obstruction2DEnv
from kinder_garden2d.kinematic2d.predicates import EPS

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


class _Rules(BatchedWorld):
    """A batched world with the family's goal and reward (−1 per step by default)."""

    def rect(self, obj: Object, features: tuple[str, ...] = _RECT) -> FloatArray:
        """Indices of one object's rectangle features in the state array."""
        return np.array([self.env.layout.index(obj, f) for f in features], dtype=np.intp)

    def goal(self, data: FloatArray) -> BoolArray:
        """``(N,)``: the family's ``goal_reached`` of every state."""
        raise NotImplementedError(f"{type(self).__name__} defines no goal")

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


_WORLDS: dict[type[Kinematic2DEnv], type[_Rules]] = {
    Motion2DEnv: Motion2DWorld,
    Obstruction2DEnv: Obstruction2DWorld,
    ClutteredRetrieval2DEnv: ClutteredRetrieval2DWorld,
    ClutteredStorage2DEnv: ClutteredStorage2DWorld,
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
