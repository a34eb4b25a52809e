"""The Rearrange3D planning model: put household objects into a spatial relation with a bowl.

Every Rearrange3D task (o1: the boxed drink; o2: the boxed drink and the can) names, per object,
a goal region in the bowl's frame (upstream kindergarden 0.2.5's boxes: behind = -x, in front =
+x, left = -y, right = +y, 5–12 cm from the bowl's centre; "next to" is the whole 24 × 24 cm
square). The model reads the goal's ``on`` atoms and their regions from the task file, so every
language variant works with the same code.

Concepts:

* ``HandEmpty(robot)``: the fingers are open (measured closure below 0.2).
* ``Holding(robot, obj)``: the fingers are closed, the object's centre is within 8 cm of the
  pinch point and at least 1.5 cm above where it rests on the island.
* ``Loose(obj)``: not held and not in its goal region (it still has to be moved).
* ``Placed(obj)``: not held and its centre is in its goal region (the env's own ``on`` test, so
  the goal atoms imply the env's goal).

Operators: ``Pick(?robot, ?obj)`` (pre HandEmpty, Loose; add Holding; delete HandEmpty, Loose)
and ``Place(?robot, ?obj)`` (pre Holding; add HandEmpty, Placed; delete Holding). Goal: every
goal object Placed, and HandEmpty.

Skills (targets tracked closed-loop by :mod:`kinder_gym.models.dynamic3d.tidybot`): the base
keeps its heading and its distance from the island (it starts 0.3–0.5 m in front of it); when
a pose is out of the arm's top-down reach, the skill first drives it sideways by the smallest of
0.1–0.5 m (steps of 0.1 m) that brings every pose of the skill into reach.

* Pick: move the pinch point above the object at the travel height (top-down gripper, fingers
  closing across one of the drink's faces, the one whose heading is nearest the base's; any
  heading for the can), descend straight to a sampled depth below the object's top, close, and
  lift straight up to the travel height.
* Place: carry the object (held offset measured at the start) straight above a sampled spot of
  its goal region, lower it straight down until its bottom is 5 mm above the island top, open,
  and rise straight back to the travel height. The spot keeps the object's footprint clear of
  the bowl and of the other objects.

Parameter spaces: Pick ``(depth,)`` in [0, 1]: the fingers close 2.5 + 1.5·depth cm below the
object's top. Place ``(box, u, v)`` in [0, 1]³: ``box`` picks one box of the goal region (every
upstream region has one), ``(u, v)`` the spot of the object's centre in it (uniform along
its x and y extents); spots whose footprint would overlap the bowl or another object are
redrawn by the sampler (up to 100 times) and rejected by the skill.

Differences from upstream: upstream's Rearrange3D has no bilevel-planning model (baselines.md
lists none), so this one is new; it uses the project's robot controller and IK as Shelf3D.

Limits: the objects are assumed upright (a tipped drink is grasped around its footprint as if
upright and usually fails, after which the planner resamples). Imports kinder_garden3d (the
``[3d]`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.dynamic3d.object_types import MOVABLE_TYPE
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.dynamic3d.tidybot import (
    Dynamic3DContext,
    SegmentSource,
    TopDownController,
    base_pose,
    dynamic3d_model,
    grasp_yaws,
    hand_predicates,
    hand_state,
    pick_operator,
    place_operator,
    placement_goal,
    region_spot,
)
from kinder_gym.motion_planning import FloatArray
from kinder_gym.skills import SkillFailure

BOWL = "bowl_0"
#: Height (m) of the island top (the task files' ``shelf:2`` frame).
TABLE_Z = 0.46
#: Radius (m) of the bowl's rim (its bounding box is 12 cm wide).
BOWL_RADIUS = 0.06
#: Clearance (m) kept between a placed object's footprint and the bowl or another object.
MARGIN = 0.005
#: Height (m) of a placed object's bottom above the island top when the hand opens.
RELEASE_GAP = 0.005
#: Distance (m) from the pinch point within which a lifted object counts as held.
HOLD_RADIUS = 0.08


@dataclass(frozen=True)
class RearrangeContext(Dynamic3DContext):
    """What the Rearrange3D controllers need besides the state."""

    bowl: Object
    movables: tuple[Object, ...]
    #: Goal region of each goal object, by object name.
    regions: dict[str, str]


def footprint_radius(state: ObjectCentricState, obj: Object) -> float:
    """Radius (m) of a circle around the object's footprint."""
    return 0.5 * math.hypot(state.get(obj, "bb_x"), state.get(obj, "bb_y"))


def _spot(
    ctx: RearrangeContext,
    state: ObjectCentricState,
    obj: Object,
    params: Sequence[float] | FloatArray,
) -> FloatArray:
    """The (x, y) spot of the object's centre selected by Place's parameters."""
    region = ctx.regions[obj.name]
    n = len(ctx.env.task.regions[region].boxes)  # type: ignore[attr-defined]
    k = min(int(float(params[0]) * n), n - 1)
    return region_spot(ctx.env, state, region, k, float(params[1]), float(params[2]))


def _spot_free(
    ctx: RearrangeContext, state: ObjectCentricState, obj: Object, spot: FloatArray
) -> bool:
    """Whether the object's footprint at ``spot`` keeps clear of the bowl and the others."""
    r = footprint_radius(state, obj)
    bowl = np.array([state.get(ctx.bowl, "x"), state.get(ctx.bowl, "y")])
    if np.linalg.norm(spot - bowl) < BOWL_RADIUS + r + MARGIN:
        return False
    for other in ctx.movables:
        if other == obj:
            continue
        p = np.array([state.get(other, "x"), state.get(other, "y")])
        if np.linalg.norm(spot - p) < footprint_radius(state, other) + r + MARGIN:
            return False
    return True


class PickController(TopDownController):
    """Pick an object up from the island top. Objects: ``(robot, obj)``."""

    params_space = spaces.Box(0.0, 1.0, (1,), dtype=np.float64)
    params_doc = "(depth,): the fingers close 2.5 + 1.5·depth cm below the object's top."

    hand_must_be = "open"

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        robot, obj = self.objects
        self.grip = 0.0
        c = np.array([state.get(obj, f) for f in ("x", "y", "z")])
        top = float(c[2]) + 0.5 * state.get(obj, "bb_z")
        grasp_z = top - 0.025 - 0.015 * float(self.params[0])
        base = base_pose(state, robot)
        points = [np.array([*c[:2], self.travel_z]), np.array([*c[:2], grasp_z])]
        goal, heading = self.base_for(state, points, grasp_yaws(state, obj, float(base[2])))

        return [*self.shift_base(state, goal), *self.grasp_from_above(c[:2], grasp_z, heading, 0.0)]


class PlaceController(TopDownController):
    """Put the held object down on a spot of its goal region. Objects: ``(robot, obj)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(box, u, v): box ⌊box·n⌋ of the object's n-box goal region, and the object's centre at "
        "fractions (u, v) of that box's x and y extents (in the region's frame, metres)."
    )

    hand_must_be = "closed"

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Uniform, redrawn (up to 100 times) while the spot is not free."""
        ctx: RearrangeContext = self.context
        obj = self.objects[1]
        params = rng.uniform(0.0, 1.0, 3)
        for _ in range(100):
            if _spot_free(ctx, state, obj, _spot(ctx, state, obj, params)):
                break
            params = rng.uniform(0.0, 1.0, 3)
        return params

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        ctx: RearrangeContext = self.context
        obj = self.objects[1]
        self.grip = 1.0
        spot = _spot(ctx, state, obj, self.params)
        if not _spot_free(ctx, state, obj, spot):
            raise SkillFailure("Place: the spot overlaps the bowl or another object")
        pinch, yaw, offset, bottom = self.held(state, obj)
        release_z = float(pinch[2]) - (bottom - TABLE_Z - RELEASE_GAP)
        target_xy = spot - offset[:2]
        points = [np.array([*target_xy, self.travel_z]), np.array([*target_xy, release_z])]
        goal, _ = self.base_for(state, points, [yaw])

        return [*self.shift_base(state, goal), *self.release_at(target_xy, release_z, yaw, 0.0)]


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The Rearrange3D planning model (any language variant, o1 and o2)."""
    objects: dict[str, Object] = env.objects  # type: ignore[attr-defined]
    robot_obj = objects["robot"]
    regions = dict(placement_goal(env, "Rearrange3D", lambda atom: atom[0] in ("on", "in")))
    movables = tuple(sorted(o for n, o in objects.items() if o.type == MOVABLE_TYPE and n != BOWL))
    goal_objs = tuple(o for o in movables if o.name in regions)
    ctx = RearrangeContext(env, robot_obj, objects[BOWL], movables, regions)

    HandEmpty, Holding = hand_predicates()
    Loose = Predicate("Loose", (MOVABLE_TYPE,))
    Placed = Predicate("Placed", (MOVABLE_TYPE,))

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms, closed, pinch = hand_state(state, robot_obj, HandEmpty)
        on = env.goal_atoms(state)  # type: ignore[attr-defined]
        for o in goal_objs:
            pos = np.asarray(state[o][:3])
            rest_z = TABLE_Z + 0.5 * state.get(o, "bb_z")
            if closed and pos[2] > rest_z + 0.015 and np.linalg.norm(pos - pinch) < HOLD_RADIUS:
                atoms.add(Holding.ground([robot_obj, o]))
            elif on[f"on({o.name}, {regions[o.name]})"]:
                atoms.add(Placed.ground([o]))
            else:
                atoms.add(Loose.ground([o]))
        return frozenset(atoms)

    o = Variable("?obj", MOVABLE_TYPE)
    pick = pick_operator(o, Loose)
    place = place_operator(o, Placed)

    return dynamic3d_model(
        "rearrange3d",
        ctx,
        [HandEmpty, Holding, Loose, Placed],
        [(pick, PickController), (place, PlaceController)],
        {HandEmpty.ground([robot_obj])} | {Placed.ground([g]) for g in goal_objs},
        abstraction,
        goal_objs,
        300,
    )


__all__: Sequence[str] = [
    "PickController",
    "PlaceController",
    "create_model",
    "footprint_radius",
]
