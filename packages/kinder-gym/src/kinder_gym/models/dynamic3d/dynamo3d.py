"""The Dynamo3D planning model: drive the robot base into a goal area that movable chairs obstruct.

The task (``Dynamo3D.json``; navigation among movable obstacles, not a catch-and-throw task;
upstream kindergarden 0.2.5's layout): the robot starts anywhere in [-1, 1]² m at any heading,
at least 0.9 m from every chair; the goal is the robot base's centre ``(x, y)`` inside the goal
area (the env's ``on(robot, ground_goal_region)``). o1: the area is x ∈ [0.8, 1.2], |y| ≤ 0.2
and a 6 kg 70 × 80 cm armchair (``obstacle_chair``) stands on it. o3 and o12: the area is
(3.45..4.2)² m, ``obstacle_chair_1`` stands across its corner and the others (2 in o3, 10 in
o12: 50–70 cm chairs) each in its own region between the start and the goal.

Measured (this env): the base is a stiff position servo (60 kg chassis, targets at most 0.1 m
ahead), and driven into a chair it shoves the chair along the floor at almost its full speed
(``test_models_dynamo3d.py`` drives straight at the goal's centre on o3 and checks that the goal
is reached and the chair on it was moved). Making room is therefore part of driving: the
model has one operator whose skill pushes whatever stands in its way, and its samples choose
the route and the stopping point (a route that jams chairs against each other stalls the
drive, the skill fails and the planner resamples). Deliberate chair pushing (picking a chair
and a direction, as a NAMO planner would) would need a predicate per chair that the goal
operator requires clear: with no negative preconditions in the operator language and 11
chairs, that is an operator with 11 chair parameters (11! groundings), so it was not built;
no seed measured needed it.

Concepts:

* ``AtGoal(robot)``: the env's goal atom (the goal atoms are exactly the env's goal).
* ``HandEmpty(robot)``: measured finger closure below 0.2 (the gripper stays open throughout;
  kept so that abstract states describe the robot).

Operator: ``MoveToGoal(?robot)`` (pre HandEmpty; add AtGoal).

Skill MoveToGoal (segment following of :mod:`kinder_gym.models.dynamic3d.tidybot`, so closed
loop: every action is the clipped error between the target and the *measured* base pose, and
the chairs' reactions are absorbed as they happen): retract the arm if it is out, drive the base
(heading kept) to a via point beside the straight line from the start to the target, then to
the target inside the goal area; the episode ends as soon as the base centre enters the goal
area. Parameters: see :attr:`MoveToGoalController.params_doc`.

Differences from upstream: upstream kindergarden 0.2.5 has no Dynamo3D planning model (spec
baselines.md); this one is new. Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.dynamic3d.object_types import ROBOT_TYPE
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models import hand
from kinder_gym.models.dynamic3d.tidybot import (
    CLOSED,
    HOME,
    MAX_DELTA,
    Dynamic3DContext,
    Dynamic3DController,
    Segment,
    SegmentSource,
    base_pose,
    dynamic3d_model,
    hand_predicates,
)
from kinder_gym.skills import Skill

GOAL_REGION = "ground_goal_region"
#: Margin (m) kept inside the goal area's edges by the drive's target.
MARGIN = 0.03
#: Largest sideways offset (m) of the via point from the straight line.
MAX_DETOUR = 0.8


class MoveToGoalController(Dynamic3DController):
    """Drive the base into the goal area, pushing chairs aside. Objects: ``(robot,)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(u, v, w): the target is the point (u, v) of the goal area (fractions of its x and y "
        "extents, 3 cm inside its edges); the base first drives to the midpoint of the straight "
        "line to the target, shifted 0.8·(2w − 1) metres to its left."
    )

    hand_must_be = "open"

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        env = self.context
        box = env.task.regions[GOAL_REGION].boxes[0]
        frame = env.regions.transform(state, GOAL_REGION)
        u, v, w = (float(p) for p in self.params)
        local = np.array(
            [
                box[0] + MARGIN + u * (box[3] - box[0] - 2 * MARGIN),
                box[1] + MARGIN + v * (box[4] - box[1] - 2 * MARGIN),
                0.0,
            ]
        )
        target = (frame[:3, :3] @ local + frame[:3, 3])[:2]
        b0 = base_pose(state, self.robot)
        line = target - b0[:2]
        length = float(np.linalg.norm(line))
        left = np.array([-line[1], line[0]]) / max(length, 1e-9)
        via = b0[:2] + line / 2 + MAX_DETOUR * (2 * w - 1) * left
        yaw = float(b0[2])
        plan = self.retract_arm(state)
        start = b0[:2]
        for point, tol in ((via, 0.05), (target, 0.02)):
            steps = math.ceil(float(np.linalg.norm(point - start)) / MAX_DELTA) + 30
            plan.append(
                Segment(
                    base=(float(point[0]), float(point[1]), yaw),
                    arm=tuple(HOME),
                    arm_tol=0.1,
                    base_tol=tol,
                    max_steps=steps,
                )
            )
            start = point
        return plan


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The Dynamo3D planning model (any number of chairs)."""
    objects: dict[str, Object] = env.objects  # type: ignore[attr-defined]
    robot_obj = objects["robot"]

    AtGoal = Predicate("AtGoal", (ROBOT_TYPE,))
    HandEmpty = hand_predicates()[0]
    goal_atom = f"on(robot, {GOAL_REGION})"

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms: set[GroundAtom] = set()
        if state.get(robot_obj, "pos_gripper") < CLOSED:
            atoms.add(HandEmpty.ground([robot_obj]))
        if env.goal_atoms(state)[goal_atom]:  # type: ignore[attr-defined]
            atoms.add(AtGoal.ground([robot_obj]))
        return frozenset(atoms)

    r = Variable("?robot", ROBOT_TYPE)
    move = hand.empty_hand_operator("MoveToGoal", HandEmpty, [], [], [AtGoal.lift([r])])
    return dynamic3d_model(
        "dynamo3d",
        Dynamic3DContext(env, robot_obj),
        [AtGoal, HandEmpty],
        [Skill(move, MoveToGoalController, env)],
        [AtGoal.ground([robot_obj])],
        abstraction,
        [],
        200,
        types=[ROBOT_TYPE],
        step_limit=True,
    )


__all__: Sequence[str] = ["MoveToGoalController", "create_model"]
