"""The Table3D planning model: pick any cube off the table and hold it up.

Upstream has no planning model for this family. The env's goal ("some cube is held more than
0.1 m above the table top") is disjunctive over the cubes, so it is one atom about the robot:

* ``HandEmpty(robot)`` / ``Holding(robot, cube)``.
* ``OnTable(cube)``: not held.
* ``HoldingUp(robot)``: the held cube's centre is more than the env's ``lift_height`` above the
  table top (the env's goal test).

One operator, ``Pick(?robot, ?cube)``: pre HandEmpty, OnTable; add Holding, HoldingUp; delete
HandEmpty, OnTable. Goal: ``HoldingUp(robot)``; the search tries the cubes in turn when one
cannot be refined.

The skill is Transport3D's pick
(:class:`~kinder_gym.models.kinematic3d.tidybot.PickController`): retract, drive the base to a
sampled standoff facing the cube (OMPL SE(2) path), reach above it, descend, close and lift by
0.12 m, which puts the cube's centre 0.145 m above the table top. Imports kinder_garden3d (the
``[3d]`` extra).
"""

from __future__ import annotations

from collections.abc import Sequence

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.kinematic3d.object_types import CUBOID_TYPE, ROBOT_TYPE
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.hand import pick_operator
from kinder_gym.models.kinematic3d.tidybot import (
    PickController,
    hand_atoms,
    hand_predicates,
    held_or_resting,
)
from kinder_gym.operators import GroundOperator
from kinder_gym.skills import Skill


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The Table3D planning model (any number of cubes)."""
    robot_obj: Object = env.robot  # type: ignore[attr-defined]
    table_obj: Object = env.table  # type: ignore[attr-defined]
    cubes: list[Object] = list(env.cubes)  # type: ignore[attr-defined]

    HandEmpty, Holding = hand_predicates()
    OnTable = Predicate("OnTable", (CUBOID_TYPE,))
    HoldingUp = Predicate("HoldingUp", (ROBOT_TYPE,))

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms = hand_atoms(state, robot_obj, HandEmpty)
        atoms |= held_or_resting(state, robot_obj, Holding, cubes, lambda s, c: OnTable.ground([c]))
        if env.goal_reached(state):
            atoms.add(HoldingUp.ground([robot_obj]))
        return frozenset(atoms)

    r = Variable("?robot", ROBOT_TYPE)
    c = Variable("?cube", CUBOID_TYPE)
    pick = pick_operator(
        "Pick", HandEmpty, Holding, c, [OnTable.lift([c])], also_add=[HoldingUp.lift([r])]
    )

    def keep(op: GroundOperator, state: ObjectCentricState) -> bool:
        return op.objects[1] in cubes

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset({HoldingUp.ground([robot_obj])})

    return PlanningModel(
        name="table3d",
        env=env,
        types=(ROBOT_TYPE, CUBOID_TYPE),
        predicates=(HandEmpty, Holding, OnTable, HoldingUp),
        skills=(Skill(pick, PickController, env),),
        goal_fn=goal,
        abstraction_fn=abstraction,
        max_skill_horizon=200,
        operator_filter=keep,
        objects_fn=lambda s: [robot_obj, table_obj, *cubes],
    )


__all__: Sequence[str] = ["create_model"]
