"""The BaseMotion3D planning model: drive the mobile base onto the target point.

Concepts: ``AtTarget(robot, target)`` (the env's own goal test: base xy within the goal tolerance
of the target) and ``NotAtTarget``. Goal: ``AtTarget(robot, target)``.

Operator and skill: ``MoveBaseToTarget(?robot, ?target)`` (pre NotAtTarget; add AtTarget; delete
NotAtTarget). The controller plans an SE(2) base path with OMPL (the floor has no obstacles, so
the straight segment is valid) to the target's xy (keeping the yaw), and follows it with base
deltas within the action bounds, the arm still and the gripper command neutral.

Imports kinder_garden3d (the ``[3d]`` extra); kinder-gym imports this module only when a
BaseMotion3D model is made.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.kinematic3d.object_types import POINT_TYPE, ROBOT_TYPE
from kinder_gym.concepts import Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.hand import first_objects_goal, goal_operator, goal_predicates
from kinder_gym.motion_planning import FloatArray, config_delta, plan_se2
from kinder_gym.skills import Controller, Skill, SkillFailure


class BaseFollower(Controller):
    """Follow base waypoints ``(x, y, yaw)`` of a Kinematic3D/Dynamic3D-style robot whose action
    starts with ``[dx, dy, dyaw]`` (the rest of the action is zero: arm still, gripper neutral).

    The context is the env; its action bounds limit every step. Subclasses implement
    :meth:`base_waypoints`.
    """

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        high = np.asarray(self.context.action_space.high, dtype=np.float64)
        self._dim = len(high)
        self._max = high[:3]
        self._plan = self.base_waypoints(state)
        self._k = 0

    def base_waypoints(self, state: ObjectCentricState) -> list[FloatArray]:
        """The base poses to visit, in order (the first one is the next)."""
        del state
        return []

    def step(self) -> FloatArray:
        assert self.state is not None
        q = np.asarray(self.state[self.objects[0]][:3], dtype=np.float64)
        while self._k < len(self._plan):
            d = config_delta(q, self._plan[self._k], wrap_dims=(2,))
            if np.max(np.abs(d)) > 1e-9:
                n = max(1, math.ceil(float(np.max(np.abs(d) / self._max)) - 1e-9))
                action = np.zeros(self._dim)
                action[:3] = d / n
                return action
            self._k += 1
        raise SkillFailure(f"{type(self).__name__}: stepped after the last waypoint")

    def terminated(self) -> bool:
        if self.state is None:
            return False
        q = np.asarray(self.state[self.objects[0]][:3], dtype=np.float64)
        while self._k < len(self._plan):
            if np.max(np.abs(config_delta(q, self._plan[self._k], wrap_dims=(2,)))) > 1e-9:
                return False
            self._k += 1
        return True


class MoveBaseToTargetController(BaseFollower):
    """Drive the base centre onto the target's xy. Objects: ``(robot, target)``."""

    def base_waypoints(self, state: ObjectCentricState) -> list[FloatArray]:
        robot, target = self.objects
        start = np.asarray(state[robot][:3], dtype=np.float64)
        goal = np.array([state.get(target, "x"), state.get(target, "y"), start[2]])
        span = float(max(np.max(np.abs(start[:2])), np.max(np.abs(goal[:2])))) + 1.0
        path = plan_se2(start, goal, lambda q: True, ((-span, span), (-span, span)))
        if path is None:
            raise SkillFailure("no base path to the target")
        return path[1:]


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The BaseMotion3D planning model."""

    def at_target(state: ObjectCentricState, objs: Sequence[Object]) -> bool:
        del objs
        return bool(env.goal_reached(state))

    AtTarget, NotAtTarget = goal_predicates("AtTarget", (ROBOT_TYPE, POINT_TYPE), at_target)
    r = Variable("?robot", ROBOT_TYPE)
    t = Variable("?target", POINT_TYPE)
    move = goal_operator("MoveBaseToTarget", (r, t), AtTarget, NotAtTarget, (r, t))

    return PlanningModel(
        name="basemotion3d",
        env=env,
        types=(ROBOT_TYPE, POINT_TYPE),
        predicates=(AtTarget, NotAtTarget),
        skills=(Skill(move, MoveBaseToTargetController, env),),
        goal_fn=first_objects_goal(AtTarget),
        max_skill_horizon=100,
    )
