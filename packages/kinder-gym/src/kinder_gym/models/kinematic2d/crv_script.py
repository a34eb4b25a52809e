"""Phase-scripted controllers for the Kinematic2D "CRV" vacuum robot.

A :class:`ScriptController` runs *phases*, each computed from the state observed when the previous
one ended (waypoints followed in straight steps within the action bounds, and :class:`Dwell`
actions that only set the vacuum), with every pose collision-checked. Shared by the
ClutteredStorage2D and PushPullHook2D models, with the tool-frame pose helpers they use.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_gym.models.kinematic2d.crv import (
    ARM_LENGTH,
    BASE_RADIUS,
    GRIPPER_WIDTH,
    CRVCollisionChecker,
    Waypoint,
    check_not_blocked,
    checked_waypoints,
    config_delta4,
    plan_base_path,
    robot_config,
    step_towards,
)
from kinder_gym.motion_planning import FloatArray
from kinder_gym.skills import Controller, SkillFailure

#: Wall-clock seconds per RRT-Connect attempt (two attempts per query). Free paths in these
#: open worlds take milliseconds; a query that runs this long usually has no solution.
RRT_TIMEOUT = 0.5


@dataclass(frozen=True)
class Dwell:
    """One motionless action with this vacuum setting (0 off, 1 on)."""

    vacuum: float


ScriptItem = Waypoint | Dwell
Phase = Callable[[ObjectCentricState], list[ScriptItem]]


class ScriptController(Controller):
    """A CRV controller that runs *phases*: each phase is a function of the state observed when
    the previous phase ended, returning waypoints (followed as
    :class:`~kinder_gym.models.kinematic2d.crv.CRVController` does: straight steps within the
    action bounds) and :class:`Dwell` s (one motionless action that sets the vacuum, which the
    env needs before a grasped object moves and after which a released one stays put).

    The context is the env; the first of ``objects`` is the robot. A step that does not move the
    robot (the env reverted a colliding step) raises :class:`SkillFailure`.
    """

    tolerance = 1e-6

    @abc.abstractmethod
    def phases(self, state: ObjectCentricState) -> list[Phase]:
        """The phases to run from ``state`` (called once, from :meth:`reset`)."""

    @abc.abstractmethod
    def bounds(self, state: ObjectCentricState) -> tuple[tuple[float, float], tuple[float, float]]:
        """``((x_min, x_max), (y_min, y_max))``: where the base centre may go."""

    def in_bounds(self, state: ObjectCentricState, q: FloatArray) -> bool:
        """Is the base centre of ``q`` within :meth:`bounds` and its arm within the joint
        limits?"""
        (x0, x1), (y0, y1) = self.bounds(state)
        v = state[self.robot]
        return bool(
            x0 <= q[0] <= x1
            and y0 <= q[1] <= y1
            and float(v[BASE_RADIUS]) - 1e-9 <= q[3] <= float(v[ARM_LENGTH]) + 1e-9
        )

    @property
    def robot(self) -> Object:
        """The robot object."""
        return self.objects[0]

    @property
    def env(self) -> ObjectCentricEnv:
        """The env (the controller's context)."""
        env: ObjectCentricEnv = self.context
        return env

    @property
    def _max(self) -> FloatArray:
        """The per-step bounds of ``[dx, dy, dtheta, darm]``."""
        out: FloatArray = np.asarray(self.env.action_space.high, dtype=np.float64)[:4]
        return out

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        self._phases = list(self.phases(state))
        self._queue: list[ScriptItem] = []
        self._last: FloatArray | None = None
        self._moved = False

    def _advance(self) -> None:
        """Drop reached waypoints; start the next phase when the current one is done."""
        assert self.state is not None
        q = robot_config(self.state, self.robot)
        while True:
            while self._queue:
                item = self._queue[0]
                if isinstance(item, Waypoint):
                    d = config_delta4(q, item.as_array())
                    if float(np.max(np.abs(d))) <= self.tolerance:
                        self._queue.pop(0)
                        continue
                return
            if not self._phases:
                return
            self._queue = list(self._phases.pop(0)(self.state))

    def terminated(self) -> bool:
        self._advance()
        return not self._queue

    def step(self) -> FloatArray:
        assert self.state is not None
        q = robot_config(self.state, self.robot)
        check_not_blocked(self, q, self._last, self._moved)
        self._advance()
        if not self._queue:
            raise SkillFailure(f"{type(self).__name__}: stepped after finishing")
        item = self._queue[0]
        self._last = q
        if isinstance(item, Dwell):
            self._queue.pop(0)
            self._moved = False
            return np.array([0.0, 0.0, 0.0, 0.0, item.vacuum])
        self._moved = True
        return np.array([*step_towards(config_delta4(q, item.as_array()), self._max), item.vacuum])

    # -- helpers for phases ------------------------------------------------------------------
    def held(self, state: ObjectCentricState) -> list[Object]:
        """The objects the suction holds in ``state``."""
        out: list[Object] = self.env.world.held_objects(state.data)  # type: ignore[attr-defined]
        return out

    def checker(self, state: ObjectCentricState) -> CRVCollisionChecker:
        """A collision checker of the robot (and what it holds) against the rest of ``state``."""
        return CRVCollisionChecker(self.env.world, state)  # type: ignore[attr-defined]

    def checked(
        self,
        checker: CRVCollisionChecker,
        configs: Sequence[FloatArray],
        vacuum: float,
        what: str,
    ) -> list[ScriptItem]:
        """Waypoints through ``configs`` (``[x, y, theta, arm]``, the first being where the
        robot starts), after checking every pose the follower will step through."""
        failure = f"{type(self).__name__}: {what} collides"
        return list(checked_waypoints(checker, configs, self._max, vacuum, failure))

    def base_path(
        self,
        checker: CRVCollisionChecker,
        start: FloatArray,
        goal: FloatArray,
        bounds: tuple[tuple[float, float], tuple[float, float]],
        vacuum: float,
        salt: int,
    ) -> list[ScriptItem]:
        """A collision-free base path (arm fixed at ``start[3]``) from ``start`` to ``goal``'s
        pose, as checked waypoints."""
        checker.arm = float(start[3])
        path = plan_base_path(
            checker,
            start,
            goal,
            bounds,
            seed=param_seed(self.params, salt),
            timeout=RRT_TIMEOUT,
        )
        configs = [np.array([*q[:3], start[3]]) for q in path]
        configs[0] = start
        return self.checked(checker, configs, vacuum, "the base path")


def param_seed(params: FloatArray, salt: int) -> int:
    """A motion-planning seed that depends on the parameters (so a sample is reproducible)."""
    mix = float(np.sum(params * np.arange(1, len(params) + 1))) if len(params) else 0.0
    return (int(1e6 * mix) + 7919 * salt) % (2**31 - 1)


def with_arm(q: FloatArray, arm: float) -> FloatArray:
    """``q`` with the arm joint set to ``arm``."""
    out: FloatArray = q.copy()
    out[3] = arm
    return out


def tool_tip(q: FloatArray, gripper_width: float) -> FloatArray:
    """The tool tip (gripper's outer edge centre) of configuration ``[x, y, theta, arm]``."""
    r = float(q[3]) + 0.5 * gripper_width
    out: FloatArray = np.array([q[0] + r * math.cos(q[2]), q[1] + r * math.sin(q[2])])
    return out


def rect_frame(state: ObjectCentricState, obj: Object) -> tuple[FloatArray, float]:
    """The centre and angle of a rectangle object."""
    x, y, th = (state.get(obj, k) for k in ("x", "y", "theta"))
    w, h = state.get(obj, "width"), state.get(obj, "height")
    c, s = math.cos(th), math.sin(th)
    return np.array([x + 0.5 * (c * w - s * h), y + 0.5 * (s * w + c * h)]), th


def relative_pose(
    state: ObjectCentricState, robot: Object, centre: FloatArray, theta: float
) -> tuple[FloatArray, float]:
    """A pose (``centre``, ``theta``) in the robot's tool-tip frame."""
    v = state[robot]
    q = robot_config(state, robot)
    tip = tool_tip(q, float(v[GRIPPER_WIDTH]))
    c, s = math.cos(q[2]), math.sin(q[2])
    d = centre - tip
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]]), theta - float(q[2])


def tip_for(centre: FloatArray, heading: float, rel: FloatArray) -> FloatArray:
    """The tool tip that puts a held pose with tool-frame offset ``rel`` at ``centre`` when the
    robot faces ``heading``."""
    c, s = math.cos(heading), math.sin(heading)
    out: FloatArray = centre - np.array([c * rel[0] - s * rel[1], s * rel[0] + c * rel[1]])
    return out


__all__: Sequence[str] = [
    "RRT_TIMEOUT",
    "Dwell",
    "Phase",
    "ScriptController",
    "ScriptItem",
    "param_seed",
    "rect_frame",
    "relative_pose",
    "tip_for",
    "tool_tip",
    "with_arm",
]
