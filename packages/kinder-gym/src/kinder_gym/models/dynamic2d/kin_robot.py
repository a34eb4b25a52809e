"""Controllers for the Dynamic2D two-finger "kin robot".

The robot's action is ``[dx, dy, dtheta, darm, dgap]`` (``dgap > 0`` opens the fingers) with
per-step bounds. A :class:`KinRobotController` follows :class:`KinWaypoint` s closed-loop: each
step moves straight towards the current waypoint's ``(x, y, theta, arm, gap)`` by ``delta / n``,
``n`` the fewest steps within the bounds (scaled down by the waypoint's ``speed``), and a waypoint
with ``wait > 0`` then holds still for that many steps (to let objects settle). The robot is
kinematic in these envs, so a step that does not move it means a static contact reverted it: the
controller then fails fast with :class:`~kinder_gym.skills.SkillFailure`.

:func:`hook_shape` is the L-shaped object the robot grasps in two families (DynPushPullHook2D's
hook, DynScoopPour2D's scoop), so both models draw it the same way.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_garden2d.dynamic2d.geometry import LocalShape, WorldShape, lobject_shape, place
from kinder_gym.motion_planning import FloatArray
from kinder_gym.skills import Controller, SkillFailure

#: Indices of the kin robot's features.
X, Y, THETA = 0, 1, 2
BASE_RADIUS, ARM_JOINT, ARM_LENGTH = 16, 17, 18
GRIPPER_BASE_WIDTH, GRIPPER_BASE_HEIGHT, FINGER_GAP, FINGER_HEIGHT, FINGER_WIDTH = range(19, 24)


@dataclass(frozen=True)
class KinWaypoint:
    """A target configuration: base pose (metres, metres, radians), arm extension and finger gap
    (metres); ``speed`` scales the per-step bounds (≤ 1); ``wait`` zero actions follow."""

    x: float
    y: float
    theta: float
    arm: float
    gap: float
    speed: float = 1.0
    wait: int = 0

    def as_array(self) -> FloatArray:
        """``[x, y, theta, arm, gap]``."""
        return np.array([self.x, self.y, self.theta, self.arm, self.gap])


def kin_config(state: ObjectCentricState, robot: Object) -> FloatArray:
    """``[x, y, theta, arm_joint, finger_gap]`` of the robot."""
    v = state[robot]
    return np.array([v[X], v[Y], v[THETA], v[ARM_JOINT], v[FINGER_GAP]])


def wrap(theta: float) -> float:
    """An angle wrapped to [−π, π)."""
    return (theta + math.pi) % (2 * math.pi) - math.pi


def hook_local(state: ObjectCentricState, hook: Object) -> LocalShape:
    """An L-shaped object's (a hook's, a scoop's) two boxes in its own frame."""
    w, s1, s2 = (state.get(hook, k) for k in ("width", "length_side1", "length_side2"))
    return lobject_shape(w, s1, s2)


def hook_shape(state: ObjectCentricState, hook: Object) -> WorldShape:
    """An L-shaped object's (a hook's, a scoop's) two boxes in the world."""
    h = state[hook]
    return place(hook_local(state, hook), h[0], h[1], h[2])


class KinRobotController(Controller):
    """Waypoint following for the kin robot (see the module docstring).

    The context is the env (its action bounds limit each step). Subclasses implement
    :meth:`waypoints`; the first of ``objects`` is the robot.
    """

    # A waypoint counts as reached within this (metres, radians): upstream's PD controller
    # leaves residuals of up to ~1e-5 after an action.
    tolerance = 1e-4

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        self._max = np.asarray(self.context.action_space.high, dtype=np.float64)
        self._last: FloatArray | None = None
        self._follow(list(self.waypoints(state)))
        self._last_moved_base = False

    @property
    def robot(self) -> Object:
        """The robot object."""
        return self.objects[0]

    @abc.abstractmethod
    def waypoints(self, state: ObjectCentricState) -> list[KinWaypoint]:
        """The waypoints to follow from ``state`` (raise SkillFailure when there are none)."""

    def _follow(self, waypoints: list[KinWaypoint]) -> None:
        """Follow ``waypoints`` from the start (a skill whose next phase is planned from the
        state its first phase left)."""
        self._plan, self._k, self._waited, self._last = waypoints, 0, 0, None

    def _advance(self, q: FloatArray) -> FloatArray | None:
        """The next action, or None when every waypoint is done."""
        while self._k < len(self._plan):
            wp = self._plan[self._k]
            d = wp.as_array() - q
            d[2] = wrap(float(d[2]))
            gap_stalled = (
                self._last is not None
                and np.max(np.abs(d[:4])) <= self.tolerance
                and abs(q[4] - self._last[4]) <= 1e-9
            )
            if gap_stalled:
                # A held object stops the closing fingers: the gap target is as reached as it
                # will get.
                x, y, th, arm, gap = (float(c) for c in q)
                self._plan[self._k] = KinWaypoint(x, y, th, arm, gap, wp.speed, wp.wait)
                self._last = None
                continue
            if np.max(np.abs(d)) > self.tolerance:
                bound = self._max * wp.speed
                n = max(1, math.ceil(float(np.max(np.abs(d) / bound)) - 1e-9))
                self._last = q
                self._last_moved_base = bool(np.max(np.abs(d[:4])) > self.tolerance)
                return d / n
            if self._waited < wp.wait:
                self._waited += 1
                self._last = None
                return np.zeros(5)
            self._k += 1
            self._waited = 0
        return None

    def step(self) -> FloatArray:
        assert self.state is not None
        q = kin_config(self.state, self.robot)
        if (
            self._last is not None
            and self._last_moved_base
            and np.allclose(q[:4], self._last[:4], atol=1e-9, rtol=0.0)
        ):
            raise SkillFailure(f"{type(self).__name__}: the robot is blocked at {q.round(3)}")
        action = self._advance(q)
        # None: the last waypoint turned out to be reached (a stalled gap); hold still.
        return np.zeros(5) if action is None else action

    def terminated(self) -> bool:
        if self.state is None:
            return False
        q = kin_config(self.state, self.robot)
        k, waited = self._k, self._waited
        # Peek: finished when no waypoint is left to move to or wait at.
        while k < len(self._plan):
            wp = self._plan[k]
            d = wp.as_array() - q
            d[2] = wrap(float(d[2]))
            if np.max(np.abs(d)) > self.tolerance or waited < wp.wait:
                return False
            k, waited = k + 1, 0
        return True
