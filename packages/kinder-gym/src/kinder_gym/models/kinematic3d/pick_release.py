"""Pieces shared by the Kinematic3D models that pick items off the floor and let go of them
elsewhere: KinematicShelf3D, PrplLab3D and KinematicCylinderShelf3D.

* :class:`BlockPickController`: the mobile manipulator's pick
  (:class:`~kinder_gym.models.kinematic3d.tidybot.PickController`), with the fingers closing
  across the block's narrow side (a block is longer than the open gripper is wide).
* :class:`ReleaseController`: retract, drive, reach a little above a release pose, descend, open
  and lift; families give the release pose.
* :func:`board_spot`: a release spot on a shelf board (both shelf families).
* :func:`floor_pick_model`: the planning model over ``OnFloor`` and a family's "placed"
  predicate, with one pick and one place skill (the family gives the test, such as
  :func:`centre_at_least`, and the controllers).

Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.kinematic3d.kinematic_shelf3d import ShelfGeometry
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
    yaw_of,
)
from kinder_gym.motion_planning import FloatArray
from kinder_gym.operators import GroundOperator
from kinder_gym.skills import Controller, Skill

#: How far above the release pose the place reaches first (m). Shorter than the pick's
#: approach: the release pose is near the top of the arm's top-down reach (about 0.92 m).
PLACE_APPROACH = 0.05


class BlockPickController(PickController):
    """Pick a block off the floor from a sampled standoff, the fingers closing across its
    narrower horizontal side. Objects: ``(robot, block)``."""

    def _grasp(self, f: FloatArray, angle: float) -> tuple[FloatArray, float, tuple[int, ...]]:
        """The block's centre; the fingers close across its y side when that is the narrower
        one, else across its x side (two yaws, half a turn apart)."""
        obj_yaw = yaw_of(np.asarray(f[3:7]))
        close_dir = obj_yaw + (math.pi / 2 if f[10] <= f[9] else 0.0)
        return np.asarray(f[:3], dtype=np.float64), close_dir, (0, 2)


class ReleaseController(ReachController):
    """Carry the held object to a release pose and open: retract, drive, reach
    ``PLACE_APPROACH`` above the pose, descend, open, lift (the shared reach sequence with a
    shorter approach). Objects: ``(robot, object)``."""

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.objects[1], "grasp_active") > 0.5

    def _place_sequence(
        self,
        state: ObjectCentricState,
        base_goal: FloatArray,
        ee_pos: FloatArray,
        ee_quat: FloatArray,
    ) -> list[ConfigWaypoint]:
        """Retract, drive, reach ``PLACE_APPROACH`` above the release pose, descend, open, lift."""
        approach = np.array([0.0, 0.0, PLACE_APPROACH])
        return self._sequence(state, base_goal, ee_pos, ee_quat, 1.0, salt=2, approach=approach)


def board_spot(
    shelf: ShelfGeometry, shelf_pos: Sequence[float], u: float, v: float, margin: float
) -> tuple[float, float]:
    """The point (x, y) at fractions (u, v) of the footprint of ``shelf`` (centred at
    ``shelf_pos``) shrunk by ``margin`` on every side (a placed item's half width and a
    clearance)."""
    sx, sy = float(shelf_pos[0]), float(shelf_pos[1])
    hx, hy = max(0.0, shelf.width / 2 - margin), max(0.0, shelf.depth / 2 - margin)
    return sx - hx + 2 * u * hx, sy - hy + 2 * v * hy


def centre_at_least(z: float) -> Callable[[ObjectCentricState, Object], bool]:
    """The test "the object's centre is at height ``z`` or above" (KinematicShelf3D's on-shelf
    test and PrplLab3D's goal test, each with its own height)."""

    def test(state: ObjectCentricState, obj: Object) -> bool:
        return bool(state.get(obj, "pose_z") >= z)

    return test


def floor_pick_model(
    env: ObjectCentricEnv,
    name: str,
    items: Sequence[Object],
    item_var: str,
    placed_name: str,
    is_placed: Callable[[ObjectCentricState, Object], bool],
    controllers: tuple[type[Controller], type[Controller]],
    place_name: str = "Place",
) -> PlanningModel:
    """A planning model that picks every item off the floor and puts it where ``is_placed``
    says it is placed.

    Concepts: ``HandEmpty(robot)`` / ``Holding(robot, item)``; ``placed_name(item)`` when the
    item is not held and ``is_placed`` says so; ``OnFloor(item)`` when it is neither. Operators:
    ``Pick(?robot, item_var)`` (pre HandEmpty, OnFloor; add Holding; delete HandEmpty, OnFloor)
    and ``place_name(?robot, item_var)`` (pre Holding; add HandEmpty, ``placed_name``; delete
    Holding), grounded on the items only, with the skills of ``controllers`` (the pick's, the
    place's). Goal: every item ``placed_name`` and ``HandEmpty``.
    """
    robot_obj: Object = env.robot  # type: ignore[attr-defined]
    HandEmpty, Holding = hand_predicates()
    OnFloor = Predicate("OnFloor", (CUBOID_TYPE,))
    placed = Predicate(placed_name, (CUBOID_TYPE,))

    def resting(state: ObjectCentricState, item: Object) -> GroundAtom:
        return placed.ground([item]) if is_placed(state, item) else OnFloor.ground([item])

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms = hand_atoms(state, robot_obj, HandEmpty)
        return frozenset(atoms | held_or_resting(state, robot_obj, Holding, items, resting))

    v = Variable(item_var, CUBOID_TYPE)
    pick = pick_operator("Pick", HandEmpty, Holding, v, [OnFloor.lift([v])])
    place = place_operator(place_name, HandEmpty, Holding, v, [placed.lift([v])])

    def keep(op: GroundOperator, state: ObjectCentricState) -> bool:
        return op.objects[1] in items

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset({HandEmpty.ground([robot_obj])} | {placed.ground([b]) for b in items})

    return PlanningModel(
        name=name,
        env=env,
        types=(ROBOT_TYPE, CUBOID_TYPE),
        predicates=(HandEmpty, Holding, OnFloor, placed),
        skills=(Skill(pick, controllers[0], env), Skill(place, controllers[1], env)),
        goal_fn=goal,
        abstraction_fn=abstraction,
        max_skill_horizon=300,
        operator_filter=keep,
        objects_fn=lambda s: [robot_obj, *items],
    )


__all__: Sequence[str] = [
    "PLACE_APPROACH",
    "BlockPickController",
    "ReleaseController",
    "board_spot",
    "centre_at_least",
    "floor_pick_model",
]
