"""The Transport3D planning model: pick every cube and the box off the floor onto the table.

Concepts (over the movable objects: the cubes and the box):

* ``HandEmpty(robot)`` / ``Holding(robot, object)``.
* ``OnFloor(object)``: not held, centre below 0.3 m.
* ``OnTable(object, table)``: not held, centre at 0.3 m or higher (the env's goal height).

Operators: ``Pick(?robot, ?object)`` (pre HandEmpty, OnFloor; add Holding; delete HandEmpty,
OnFloor) and ``Place(?robot, ?object, ?table)`` (pre Holding; add HandEmpty, OnTable; delete
Holding). Goal: every cube and the box ``OnTable``, and ``HandEmpty``; the last Place retracts the
arm, which the env's goal also asks for (end effector 0.2 m from every object, gripper open).

Skills (all motion collision-checked with the env's own pybullet geometry; OMPL RRT-Connect for
the base in SE(2) and for the arm in joint space; IK with the robot model's mink solver):

* Pick: retract the arm, drive the base to a sampled standoff facing the object, reach a point
  above the grasp (a cube's centre, or the top of the box's nearest wall), descend, close,
  and lift back.
* Place: retract the arm (carrying the object), drive to a sampled standoff beside the table,
  reach above a sampled spot on the table, descend until the object is 3 mm above the top, open,
  lift, retract.

Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.kinematic3d.object_types import CUBOID_TYPE, ROBOT_TYPE
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.hand import pick_operator, place_operator
from kinder_gym.models.kinematic3d.tidybot import (
    ConfigWaypoint,
    PickController,
    ReachController,
    hand_atoms,
    hand_predicates,
    held_or_resting,
    release_pose,
    top_down_quat,
)
from kinder_gym.operators import GroundOperator
from kinder_gym.skills import Skill

#: Centre height from which an object counts as on the table (the env's goal threshold).
TABLE_Z = 0.3


class PlaceController(ReachController):
    """Place the held object on the table. Objects: ``(robot, object, table)``."""

    params_space = spaces.Box(0.0, 1.0, (4,), dtype=np.float64)
    params_doc = (
        "(u, v, dist, side): the object's centre goes to fractions (u, v) of the table top "
        "(shrunk by the object's half extents and 2 cm), 3 mm above it; the base stands "
        "0.45 + 0.2·dist metres away, on the table's −x side (side < 1/3), −y side (< 2/3) or "
        "+y side."
    )

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.objects[1], "grasp_active") > 0.5

    def waypoints(self, state: ObjectCentricState) -> list[ConfigWaypoint]:
        robot, obj, table = self.objects
        u, v, dist_p, side = (float(p) for p in self.params)
        t = state[table]
        t_half = np.asarray(t[9:12], dtype=np.float64)
        o_half = np.asarray(state[obj][9:12], dtype=np.float64)
        r = float(np.hypot(o_half[0], o_half[1])) + 0.02
        px = t[0] - t_half[0] + r + u * max(0.0, 2 * (t_half[0] - r))
        py = t[1] - t_half[1] + r + v * max(0.0, 2 * (t_half[1] - r))
        pz = t[2] + t_half[2] + o_half[2] + 0.003
        angle = (0.0, math.pi / 2, -math.pi / 2)[min(2, int(side * 3))]
        dist = 0.45 + 0.2 * dist_p
        # The end effector points down along the approach, the object hanging below it.
        ee_p, ee_q = release_pose(state, robot, np.array([px, py, pz]), top_down_quat(angle))
        base_goal = self._standoff(state, np.array([px, py]), dist, angle)
        return self._sequence(state, base_goal, ee_p, ee_q, 1.0, salt=2)


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The Transport3D planning model (any number of cubes)."""
    robot_obj: Object = env.robot  # type: ignore[attr-defined]
    table_obj: Object = env.table  # type: ignore[attr-defined]
    cubes: list[Object] = list(env.cubes)  # type: ignore[attr-defined]
    movables = sorted([*cubes, env.box], key=lambda o: o.name)  # type: ignore[attr-defined]

    HandEmpty, Holding = hand_predicates()
    OnFloor = Predicate("OnFloor", (CUBOID_TYPE,))
    OnTable = Predicate("OnTable", (CUBOID_TYPE, CUBOID_TYPE))

    def resting(state: ObjectCentricState, o: Object) -> GroundAtom:
        if state.get(o, "pose_z") >= TABLE_Z:
            return OnTable.ground([o, table_obj])
        return OnFloor.ground([o])

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms = hand_atoms(state, robot_obj, HandEmpty)
        return frozenset(atoms | held_or_resting(state, robot_obj, Holding, movables, resting))

    o = Variable("?object", CUBOID_TYPE)
    t = Variable("?table", CUBOID_TYPE)
    pick = pick_operator("Pick", HandEmpty, Holding, o, [OnFloor.lift([o])])
    place = place_operator("Place", HandEmpty, Holding, o, [OnTable.lift([o, t])], params=[t])

    def keep(op: GroundOperator, state: ObjectCentricState) -> bool:
        if op.objects[1] not in movables:
            return False
        return op.parent is not place or op.objects[2] == table_obj

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset(
            {HandEmpty.ground([robot_obj])} | {OnTable.ground([m, table_obj]) for m in movables}
        )

    return PlanningModel(
        name="transport3d",
        env=env,
        types=(ROBOT_TYPE, CUBOID_TYPE),
        predicates=(HandEmpty, Holding, OnFloor, OnTable),
        skills=(Skill(pick, PickController, env), Skill(place, PlaceController, env)),
        goal_fn=goal,
        abstraction_fn=abstraction,
        max_skill_horizon=300,
        operator_filter=keep,
    )


__all__: Sequence[str] = ["PlaceController", "create_model"]
