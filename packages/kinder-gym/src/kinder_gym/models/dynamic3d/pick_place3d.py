"""The PickPlace3D planning model: pick cubes off the floor and put them down in a floor region.

PickPlace3D-o1 (upstream kindergarden 0.2.5's task): one 4 cm cube lies 0.55–0.85 m in front of
the mobile manipulator on a plain floor; the goal region is a 30 × 30 cm square on the floor
about 1.2 m away. The model reads the goal's ``on`` atoms and their regions from the task file.

Concepts:

* ``HandEmpty(robot)``: the fingers are open (measured closure below 0.2).
* ``Holding(robot, cube)``: the fingers are closed and the pinch point is within 4 cm of the
  cube's centre, which is off the floor.
* ``Loose(cube)``: not held and not in its goal region.
* ``Placed(cube)``: not held and in its goal region (the env's own ``on`` test, so the goal
  atoms imply the env's goal).

Operators: ``Pick(?robot, ?cube)`` (pre HandEmpty, Loose; add Holding; delete HandEmpty, Loose)
and ``Place(?robot, ?cube)`` (pre Holding; add HandEmpty, Placed; delete Holding). Goal: every
goal cube Placed, and HandEmpty.

Skills (targets tracked closed-loop by :mod:`kinder_gym.models.dynamic3d.tidybot`):

* Pick (:class:`~kinder_gym.models.dynamic3d.tidybot.FloorPickController`): drive the base to a
  sampled standoff facing one of the cube's faces, the arm swinging to above it with the gripper
  pitched 45° down; descend, close, and lift the cube straight up to 10 cm.
* Place: keep the arm as the Pick left it and drive the base (at most 6 cm and 0.06 rad per
  action) so that the held cube comes above a sampled spot of its goal region, the base heading
  from where it stands towards the spot; lower the cube straight down until its bottom is 5 mm
  above the floor, open the fingers, and rise straight back up 10 cm.

Parameter spaces: Pick ``(dist, angle)`` in [0, 1]²: the base stops 0.50 + 0.10·dist metres
short of the cube, approaching along the cube face nearest to the heading (angle − 0.5)·π/2
radians off the one that points from the robot to the cube. Place ``(u, v)`` in [0, 1]²: the
cube's centre at fractions (u, v) of the region box's x and y extents, shrunk by 5 cm on every
side.

Differences from upstream: upstream 0.2.5 has no bilevel-planning model for this family, so
this one is new; it uses the project's robot controller and IK as Shelf3D. Imports
kinder_garden3d (the ``[3d]`` extra).

The env's goal (the cube's centre in the region's box, up to 10 cm above the floor) already
holds while the held cube, lifted to 10 cm, passes over the region, so an episode usually ends
during the Place's drive; the planner counts a rollout that reaches the env's goal as done.

Measured (2026-11-27, development seeds, ``kinder bench run -a bilevel_planning --env
kinder/PickPlace3D-o1-v0 --executor inline``): BP success 1.00 with ``--seeds 1000 --episodes 5``
(93 steps, 0.37 s of inference per episode) and 1.00 with ``--seeds 1000-1004 --episodes 10``
(50 of 50; 94 steps, 0.41 s).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.dynamic3d.object_types import MOVABLE_TYPE
from kinder_garden3d.robot.description import forward_kinematics
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.dynamic3d.tidybot import (
    PITCH,
    Dynamic3DContext,
    Dynamic3DController,
    FloorPickController,
    SegmentSource,
    arm_joints,
    base_pose,
    drive_segment,
    dynamic3d_model,
    face_approach,
    grip_segment,
    hand_predicates,
    hand_state,
    line_segments,
    pick_operator,
    pinch_position,
    place_operator,
    placement_goal,
    region_spot,
)
from kinder_gym.motion_planning import FloatArray, wrap_angle

#: Height (m) of the pinch point to which a picked cube is lifted, and that the hand rises to
#: after letting go.
LIFT = 0.10
#: Largest base step (m, rad per action) while carrying the cube.
CARRY_SPEED = (0.06, 0.06)
#: Height (m) of the held cube's bottom above the floor when the hand opens.
RELEASE_GAP = 0.005
#: Margin (m) kept inside the goal region's box when sampling the spot of the cube's centre.
MARGIN = 0.05
#: Distance (m) from the pinch point within which a lifted cube counts as held.
HOLD_RADIUS = 0.04


@dataclass(frozen=True)
class PickPlaceContext(Dynamic3DContext):
    """What the PickPlace3D controllers need besides the state."""

    #: Goal region of each goal cube, by name.
    regions: dict[str, str]


class PickController(FloorPickController):
    """Pick a cube off the floor. Objects: ``(robot, cube)``."""

    params_doc = (
        "(dist, angle): the base stops 0.50 + 0.10·dist metres short of the cube, approaching "
        "along the cube face nearest to the heading (angle − 0.5)·π/2 radians off the one that "
        "points from the robot to the cube."
    )
    swing = True
    lift_z = LIFT
    lift_spacing = 0.05
    via_tol = 0.05

    def approach(
        self, state: ObjectCentricState, obj: Object
    ) -> tuple[FloatArray, float, FloatArray]:
        base = base_pose(state, self.robot)
        d = np.array([state.get(obj, "x"), state.get(obj, "y")]) - base[:2]
        wanted = math.atan2(d[1], d[0]) + (float(self.params[1]) - 0.5) * math.pi / 2
        return face_approach(state, obj, wanted)


def _spot(
    ctx: PickPlaceContext, state: ObjectCentricState, cube: Object, params: FloatArray
) -> FloatArray:
    """The (x, y) spot of the cube's centre selected by Place's parameters."""
    region = ctx.regions[cube.name]
    return region_spot(ctx.env, state, region, 0, float(params[0]), float(params[1]), margin=MARGIN)


class PlaceController(Dynamic3DController):
    """Put the held cube down on a spot of its goal region. Objects: ``(robot, cube)``."""

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(u, v): the cube's centre at fractions (u, v) of the goal region box's x and y extents "
        "(shrunk by 5 cm on every side)."
    )
    hand_must_be = "closed"

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        ctx: PickPlaceContext = self.context
        robot, cube = self.objects
        spot = _spot(ctx, state, cube, self.params)
        base = base_pose(state, robot)
        arm = arm_joints(state, robot)
        pinch = pinch_position(base, arm)
        centre = np.array([state.get(cube, f) for f in ("x", "y", "z")])
        # The pinch point in the base frame (the arm is held while the base drives) and the
        # cube's centre relative to the pinch point, in the world frame (kept while driving
        # up to a turn of the base, which changes it by little for a cube this close).
        c, s = math.cos(base[2]), math.sin(base[2])
        rot = np.array([[c, -s], [s, c]])
        local = rot.T @ (pinch[:2] - base[:2])
        offset = rot.T @ (centre[:2] - pinch[:2])
        to_spot = spot - base[:2]
        heading = math.atan2(to_spot[1], to_spot[0])
        # Turn the pinch point's local offset so the base's heading points at the spot: the
        # base then drives mostly forwards. Solve for the base position that puts the cube there.
        c, s = math.cos(heading), math.sin(heading)
        rot = np.array([[c, -s], [s, c]])
        goal_xy = spot - rot @ (local + offset)
        goal = np.array([*goal_xy, heading])
        bottom = float(centre[2]) - 0.5 * state.get(cube, "bb_z")
        release_z = float(pinch[2]) - (bottom - RELEASE_GAP)
        gripper_yaw = wrap_angle(heading + _gripper_yaw_offset(base, arm))

        def lower(s: ObjectCentricState) -> list[SegmentSource]:
            here = pinch_position(base_pose(s, robot), arm_joints(s, robot))
            target = np.array([here[0], here[1], release_z])
            return list(line_segments(s, robot, target, gripper_yaw, PITCH, 1.0))

        def rise(s: ObjectCentricState) -> list[SegmentSource]:
            here = pinch_position(base_pose(s, robot), arm_joints(s, robot))
            target = np.array([here[0], here[1], LIFT])
            return list(line_segments(s, robot, target, gripper_yaw, PITCH, 0.0, spacing=0.05))

        return [
            drive_segment(state, robot, goal, arm, 1.0, 0.01, CARRY_SPEED),
            lower,
            grip_segment(0.0),
            rise,
        ]


def _gripper_yaw_offset(base: FloatArray, arm: FloatArray) -> float:
    """The gripper's heading relative to the base's (the side grasp points along its approach,
    the pinch frame's z axis projected on the floor)."""
    tf = forward_kinematics((float(base[0]), float(base[1]), float(base[2])), arm)["pinch_site"]
    approach = tf[:3, 2]
    return wrap_angle(math.atan2(float(approach[1]), float(approach[0])) - float(base[2]))


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The PickPlace3D planning model (cubes from the floor into floor regions)."""
    objects: dict[str, Object] = env.objects  # type: ignore[attr-defined]
    robot_obj = objects["robot"]
    regions = dict(placement_goal(env, "PickPlace3D", lambda atom: atom[0] == "on"))
    for name in regions:
        if name not in objects or objects[name].type != MOVABLE_TYPE:
            raise ValueError(f"PickPlace3D model: goal object {name!r} is not a movable object")
    goal_objs = tuple(sorted(objects[n] for n in regions))
    ctx = PickPlaceContext(env, robot_obj, regions)

    HandEmpty, Holding = hand_predicates()
    Loose = Predicate("Loose", (MOVABLE_TYPE,))
    Placed = Predicate("Placed", (MOVABLE_TYPE,))

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms, closed, pinch = hand_state(state, robot_obj, HandEmpty)
        on = env.goal_atoms(state)  # type: ignore[attr-defined]
        for o in goal_objs:
            pos = np.asarray(state[o][:3])
            rest_z = 0.5 * state.get(o, "bb_z")
            if closed and pos[2] > rest_z + 0.01 and np.linalg.norm(pos - pinch) < HOLD_RADIUS:
                atoms.add(Holding.ground([robot_obj, o]))
            elif on[f"on({o.name}, {regions[o.name]})"]:
                atoms.add(Placed.ground([o]))
            else:
                atoms.add(Loose.ground([o]))
        return frozenset(atoms)

    c = Variable("?cube", MOVABLE_TYPE)
    return dynamic3d_model(
        "pick_place3d",
        ctx,
        [HandEmpty, Holding, Loose, Placed],
        [(pick_operator(c, Loose), PickController), (place_operator(c, Placed), PlaceController)],
        {HandEmpty.ground([robot_obj])} | {Placed.ground([g]) for g in goal_objs},
        abstraction,
        goal_objs,
        400,
    )


__all__: Sequence[str] = ["PickController", "PlaceController", "create_model"]
