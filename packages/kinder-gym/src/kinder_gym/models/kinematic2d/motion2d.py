"""The Motion2D planning model: drive the robot's base centre into the target region.

Concepts: ``AtTarget(robot, region)`` (the base centre lies inside the target region) and its
negation ``NotAtTarget(robot, region)``. Goal: ``AtTarget(robot, target_region)``.

Operator and skill: ``MoveToTarget(?robot, ?region)`` (pre NotAtTarget; add AtTarget; delete
NotAtTarget). Its controller samples a goal pose inside the region, rejects it when the robot would
collide there, plans a collision-free SE(2) path with RRT-Connect (OMPL) through the passages, and
follows it with the arm retracted and the vacuum off.

The upstream model adds passage predicates (``AtPassage``/``NotAtPassage``) and operators through
them; its own notes say the one-step plan is the one that refines, because the motion planner goes
through every passage itself, so this model keeps only that operator (one abstract plan, no
unrefinable alternatives to waste samples on).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden2d.kinematic2d.object_types import CRV_ROBOT, RECTANGLE, TARGET_REGION
from kinder_garden2d.kinematic2d.predicates import robot_in_region
from kinder_gym.concepts import Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.hand import first_objects_goal, goal_operator, goal_predicates
from kinder_gym.models.kinematic2d.crv import (
    ARM_JOINT,
    BASE_RADIUS,
    CRVCollisionChecker,
    CRVController,
    Waypoint,
    checked_base_waypoints,
    plan_base_path,
    robot_config,
    world_sampling_bounds,
)
from kinder_gym.motion_planning import FloatArray, path_valid
from kinder_gym.skills import Skill, SkillFailure


def _at_target(state: ObjectCentricState, objs: Sequence[Object]) -> bool:
    return robot_in_region(state, objs[0], objs[1])


AtTarget, NotAtTarget = goal_predicates("AtTarget", (CRV_ROBOT, TARGET_REGION), _at_target)
_R = Variable("?robot", CRV_ROBOT)
_T = Variable("?region", TARGET_REGION)
MOVE_TO_TARGET = goal_operator("MoveToTarget", (_R, _T), AtTarget, NotAtTarget, (_R, _T))


class MoveToTargetController(CRVController):
    """Drive into the target region along a collision-free path (arm retracted, vacuum off).

    Objects: ``(robot, region)``.
    """

    params_space = spaces.Box(
        np.array([0.1, 0.1, 0.0]), np.array([0.9, 0.9, 1.0]), dtype=np.float64
    )
    params_doc = (
        "(u, v, w): the goal base position is the point at fractions (u, v) of the target "
        "region's width and height from its bottom-left corner; the goal heading is "
        "w·2π − π radians."
    )

    def _goal(self, state: ObjectCentricState, params: FloatArray) -> FloatArray:
        robot, region = self.objects
        u, v, w = (float(p) for p in params)
        rx, ry, rth = state[region][:3]
        width, height = state.get(region, "width"), state.get(region, "height")
        c, s = math.cos(rth), math.sin(rth)
        return np.array(
            [
                rx + c * u * width - s * v * height,
                ry + s * u * width + c * v * height,
                w * 2 * math.pi - math.pi,
                state[robot][ARM_JOINT],
            ]
        )

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Uniform over the params space, rejecting goal poses in collision (50 tries)."""
        checker = CRVCollisionChecker(self.context.world, state, ignore=[self.objects[1]])
        params = super().sample_parameters(state, rng)
        for _ in range(50):
            if checker(self._goal(state, params)):
                break
            params = super().sample_parameters(state, rng)
        return params

    def waypoints(self, state: ObjectCentricState) -> list[Waypoint]:
        robot, region = self.objects
        env = self.context
        start = robot_config(state, robot)
        goal = self._goal(state, self.params)
        checker = CRVCollisionChecker(env.world, state, ignore=[region])
        if not checker(goal):
            raise SkillFailure(f"goal pose {goal[:3].round(3)} is in collision")
        arm = float(state[robot][ARM_JOINT])
        path = passage_path(state, checker, start, goal, env.config.world_bounds)
        if path is None:
            margin = float(state[robot][BASE_RADIUS])
            seed = int(1e6 * float(np.sum(self.params * [1.0, 3.0, 7.0]))) % (2**31 - 1)
            path = plan_base_path(
                checker, start, goal, world_sampling_bounds(env, margin), seed=seed
            )
        return checked_base_waypoints(checker, path, arm, env, vacuum=0.0)


def passage_gaps(
    state: ObjectCentricState, ymin: float, ymax: float
) -> list[tuple[float, float, float]]:
    """``(wall centre x, gap bottom y, gap top y)`` of every wall (obstacles sharing an x),
    sorted by x; the gap is the widest free interval of the wall within ``[ymin, ymax]``."""
    walls: dict[float, list[tuple[float, float, float]]] = {}
    for o in state.get_objects(RECTANGLE):
        if o.type.is_subtype_of(TARGET_REGION):
            continue
        x, y = state.get(o, "x"), state.get(o, "y")
        w, h = state.get(o, "width"), state.get(o, "height")
        walls.setdefault(round(x, 6), []).append((x + w / 2, y, y + h))
    out = []
    for _, parts in sorted(walls.items()):
        cx = parts[0][0]
        free_lo, best = ymin, (cx, ymin, ymin)
        for _, lo, hi in sorted(parts, key=lambda p: p[1]):
            if min(lo, ymax) - free_lo > best[2] - best[1]:
                best = (cx, free_lo, min(lo, ymax))
            free_lo = max(free_lo, hi)
        if ymax - free_lo > best[2] - best[1]:
            best = (cx, free_lo, ymax)
        out.append(best)
    return out


def passage_path(
    state: ObjectCentricState,
    checker: CRVCollisionChecker,
    start: FloatArray,
    goal: FloatArray,
    world_bounds: tuple[float, float, float, float],
) -> list[FloatArray] | None:
    """A path through the middle of each passage between ``start`` and ``goal`` (heading along
    the x axis, where the robot is narrowest), or None if any of its segments collides."""
    robot = state.get_objects(CRV_ROBOT)[0]
    _, _, ymin, ymax = world_bounds
    clearance = float(state[robot][BASE_RADIUS]) + 0.05
    heading = 0.0 if abs(math.remainder(float(start[2]), 2 * math.pi)) <= math.pi / 2 else math.pi
    x0, x1 = float(start[0]), float(goal[0])
    gaps = [g for g in passage_gaps(state, ymin, ymax) if min(x0, x1) < g[0] < max(x0, x1)]
    if x1 < x0:
        gaps.reverse()
    sign = 1.0 if x1 >= x0 else -1.0
    path = [start[:3].copy()]
    for cx, lo, hi in gaps:
        mid = (lo + hi) / 2
        path.append(np.array([cx - sign * clearance, mid, heading]))
        path.append(np.array([cx + sign * clearance, mid, heading]))
    path.append(goal[:3].copy())
    max_step = np.array([0.01, 0.01, math.pi / 64])
    if path_valid(path, checker, max_step, wrap_dims=(2,)):
        return path
    return None


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The Motion2D planning model (any number of passages)."""

    return PlanningModel(
        name="motion2d",
        env=env,
        types=(CRV_ROBOT, RECTANGLE, TARGET_REGION),
        predicates=(AtTarget, NotAtTarget),
        skills=(Skill(MOVE_TO_TARGET, MoveToTargetController, env),),
        goal_fn=first_objects_goal(AtTarget),
        max_skill_horizon=400,
    )
