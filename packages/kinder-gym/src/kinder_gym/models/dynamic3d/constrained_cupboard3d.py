"""The ConstrainedCupboard3D planning model: put 30 cm rods lying on the floor onto given shelves
of narrow cupboards standing side by side.

Every cupboard is 0.1 m wide with 2 cm side walls, so its opening is 6 cm wide and 0.3 m deep; a
rod (3 × 30 × 3 cm, as upstream's) fits only lying along the cupboard's depth, and the open
fingers (8.5 cm) do not fit in the opening at all. So the robot grasps a rod near one end, along
its length, and slides it in end first, releasing it with the fingers still outside the opening;
the rod's centre then lies inside the cupboard (the env's ``on`` test is the centre being in the
shelf's goal box).

Concepts:

* ``HandEmpty(robot)``: the fingers are open (measured closure below 0.2).
* ``Holding(robot, rod)``: the fingers are closed, the rod is off the floor and the pinch point
  is within 3 cm of the rod's axis segment.
* ``OnGround(rod)``: not held, on no goal shelf, and the rod's centre is below 5 cm.
* ``OnShelf(rod, cupboard)``: not held and the rod's centre is in that cupboard's goal region
  (the env's own region test, so the goal atoms imply the env's goal).

Operators: ``Pick(?robot, ?rod)`` (pre HandEmpty, OnGround; add Holding; delete HandEmpty,
OnGround) and ``Place(?robot, ?rod, ?cupboard)`` (pre Holding; add HandEmpty, OnShelf; delete
Holding). Goal: every rod OnShelf on its own goal cupboard, and HandEmpty.

Skills (see :mod:`kinder_gym.models.dynamic3d.tidybot` for how targets are tracked):

* Pick: drive the base straight to a standoff beyond one end of the rod, facing along it (the
  straight path must keep the chassis clear of the cupboards), while the arm swings to above the
  sampled grasp point near that end with the gripper pitched 45° down; descend, close, and lift
  to 10 cm. The rod then points straight ahead of the base.
* Place: measure where the rod is in the base frame (the grasp is never exact), drive to a pose
  from which the rod is aligned with the goal cupboard's depth axis and lies 5 cm in front of its
  opening, turn the hand until the rod is level, raise or lower it until the rod's underside is
  1.2 cm above the goal shelf, re-measure and drive in until the rod's centre is at the sampled
  depth, open, and back out.

The skills read the cupboards' poses and goal regions from the state and the env, so every count
variant works (o1/o2 put every rod on shelf 0 of ``cupboard_1``; o3 and larger put rod *i* into
``cupboard_i`` at the shelf its region names). Imports kinder_garden3d (the ``[3d]`` extra).

Parameter spaces: Pick ``(end, grip, dist)`` in [0, 1]³ and Place ``(depth,)`` in [0, 1] (see
the controllers' ``params_doc``: which end, 1–3 cm from it, a 0.50–0.60 m standoff; the rod's
centre 2–7 cm inside the opening).

Differences from upstream: upstream KinDER 0.2.5 has no bilevel-planning model for this family
(baselines.md lists one for Shelf3D only); the decomposition (Pick, Place) follows our Shelf3D
model.

Measured (``benchmarks/results/bilevel_planning.md``, BP defaults, 60 s planning budget): o1
1.00 and o6 0.96 at 5 seeds × 10 episodes, o2–o5 1.00 at 1 × 10; o6 plans take about 735 of
the 1000 steps allowed (about 120 per rod); every failure was a planning timeout. Those figures
predate upstream's 30 cm rods and shelf layout; with them, on development seed 1000 (``kinder
bench run``, 5 episodes of o1, 2 of o6): o1 5/5; o6 0/2 at the 60 s budget on a loaded machine
(10–12 skill samples in the budget) and 1/1 with ``planning_timeout=600`` (652 steps).

Reuse: SortClutteredBlocks3D-o12
(:mod:`kinder_gym.models.dynamic3d.sort_cupboard3d`) subclasses these controllers: the grip
distance (``PickController._grip``), the goal region (``PlaceController._region``), the slide's
depth range, finger clearance, carry speed and height above the shelf are overridable.

Limits and what was found on the way:

* A rod held near one end turns about the fingers' closing axis (the pads are its only pivot):
  carried at the env's full base speed its far end swung 47° up. The carry is slow (3 cm per
  action) and the Place levels the rod by turning the hand before it slides in; a rod that
  turns on the way in (a few degrees) still clears the shelf's front edge by the 1.2 cm margin.
* The rod's centre ends at most as deep as the grasp point is from it, less 1.5 cm (the fingers
  stay outside): 2–6 cm inside the opening, so up to half the rod overhangs the shelf edge.
  The goal holds (the centre is in the box) and the rod rests stably; pushing it further in
  would take another skill.
* Rods are not checked against each other on the floor (the raised chassis passes over them);
  a rod lying across another cannot be grasped flat and makes Pick fail its prediction.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.dynamic3d.geometry import quat_yaw
from kinder_garden3d.dynamic3d.object_types import FIXTURE_TYPE, MOVABLE_TYPE, ROBOT_TYPE
from kinder_garden3d.robot.description import forward_kinematics
from kinder_gym.concepts import GroundAtom
from kinder_gym.model import PlanningModel
from kinder_gym.models.dynamic3d.tidybot import (
    MAX_DELTA,
    Dynamic3DContext,
    Dynamic3DController,
    FloorPickController,
    Segment,
    SegmentSource,
    arm_joints,
    base_pose,
    chassis_clear_of_box,
    dynamic3d_model,
    grip_segment,
    hand_state,
    line_segments,
    pick_place_domain,
    pinch_position,
    placement_goal,
    yaw_axes,
)
from kinder_gym.motion_planning import FloatArray, wrap_angle
from kinder_gym.skills import SkillFailure

ROD_PREFIX = "cuboid_"
#: Height (m) of the pinch point above the centre of a rod lying on the floor when the fingers
#: close on it (4.5 mm: the pads' lower edges stay clear of the floor).
GRASP_ABOVE_CENTRE = 0.0045
#: Height (m) of the pinch point while carrying a rod.
CARRY_Z = 0.10
#: Height (m) of a held rod's underside above the goal shelf while it is slid in.
SLIDE_ABOVE_SHELF = 0.012
#: Largest base step (m, rad per action) while a rod is held: at full speed the rod swings up
#: about the fingers' closing axis (47° measured on ConstrainedCupboard3D-o1, seed 0).
CARRY_SPEED = (0.03, 0.05)
#: Distance (m) in front of the opening at which the rod's tip waits before sliding in.
PRE_PLACE = 0.05
#: Smallest distance (m) the pinch point keeps in front of the opening: the open fingers are
#: wider than it.
FINGER_CLEARANCE = 0.015


@dataclass(frozen=True)
class CupboardContext(Dynamic3DContext):
    """What the ConstrainedCupboard3D controllers need besides the state."""

    cupboards: tuple[Object, ...]
    rods: tuple[Object, ...]
    #: Goal region of each cupboard that has one.
    regions: dict[Object, str]


class _Cupboard:
    """A cupboard's opening and goal shelf in a state (fixed per episode)."""

    def __init__(
        self, ctx: CupboardContext, cupboard: Object, region: str, state: ObjectCentricState
    ) -> None:
        frame = ctx.env.regions.transform(state, region)  # type: ignore[attr-defined]
        self.shelf = np.asarray(frame[:3, 3], dtype=np.float64)  # goal shelf top, centre
        self.front = np.asarray(frame[:2, 1], dtype=np.float64)  # out of the opening
        params = ctx.env.task.fixtures[cupboard.name].params  # type: ignore[attr-defined]
        self.depth = float(params["depth"])
        #: Yaw pointing into the cupboard.
        self.inward_yaw = math.atan2(-self.front[1], -self.front[0])


def _rod_axis(state: ObjectCentricState, rod: Object) -> tuple[FloatArray, FloatArray]:
    """The rod's centre (x, y, z) and the unit vector (x, y) along its length."""
    yaw = quat_yaw(np.asarray(state[rod][3:7]))
    return np.asarray(state[rod][:3], dtype=np.float64), np.array([-math.sin(yaw), math.cos(yaw)])


def rod_length(state: ObjectCentricState, rod: Object) -> float:
    """Length (m) of a rod (its bounding box's y extent)."""
    return float(state.get(rod, "bb_y"))


def nearest_axis_point(state: ObjectCentricState, rod: Object, point: FloatArray) -> FloatArray:
    """The point of the (level) rod's axis segment nearest ``point`` in the plane, at the
    rod's centre height."""
    centre, axis = _rod_axis(state, rod)
    half = rod_length(state, rod) / 2
    t = float(np.clip(np.dot(point[:2] - centre[:2], axis), -half, half))
    return np.array([*(centre[:2] + t * axis), centre[2]])


def _clear_of_cupboards(
    ctx: CupboardContext, state: ObjectCentricState, a: FloatArray, b: FloatArray
) -> bool:
    """Whether the chassis driving straight from ``a`` to ``b`` stays 5 cm clear of every
    cupboard."""
    for cupboard in ctx.cupboards:
        params = ctx.env.task.fixtures[cupboard.name].params  # type: ignore[attr-defined]
        axes = yaw_axes(quat_yaw(np.asarray(state[cupboard][3:7])))
        centre = np.array([state.get(cupboard, "x"), state.get(cupboard, "y")])
        half = np.array([float(params["length"]) / 2, float(params["depth"]) / 2])
        if not chassis_clear_of_box(a, b, centre, axes, half, 0.05):
            return False
    return True


class PickController(FloorPickController):
    """Pick a rod off the floor near one of its ends, the arm swinging to above the grasp point
    while the base drives (the chassis path is checked; the hand passes 15 cm above the floor,
    over the rods). Objects: ``(robot, rod)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(end, grip, dist): approach from the rod's end along +y of its frame if end < 0.5, "
        "else from the other end; close 0.01 + 0.02·grip metres in from that end; the base "
        "stops 0.50 + 0.10·dist metres short of the grasp point."
    )
    swing = True
    grasp_back = 0.0
    lift_z = CARRY_Z
    lift_spacing = 0.04

    def _grip(self, state: ObjectCentricState, rod: Object) -> float:
        """Distance (m) of the grasp point from the rod's end."""
        return 0.01 + 0.02 * float(self.params[1])

    def standoff(self) -> float:
        return 0.50 + 0.10 * float(self.params[2])

    def approach(
        self, state: ObjectCentricState, obj: Object
    ) -> tuple[FloatArray, float, FloatArray]:
        """Along the rod's axis, from the end ``params[0]`` picks."""
        centre, axis = _rod_axis(state, obj)
        if float(self.params[0]) < 0.5:
            axis = -axis  # approach from the +axis end, facing -axis
        # `axis` points from the grasped end towards the rod's centre: the heading.
        end = centre[:2] - axis * rod_length(state, obj) / 2
        return end + self._grip(state, obj) * axis, math.atan2(axis[1], axis[0]), axis

    def route(self, state: ObjectCentricState, goal: FloatArray) -> list[FloatArray]:
        """Straight, clear of every cupboard."""
        if not _clear_of_cupboards(self.context, state, base_pose(state, self.robot)[:2], goal[:2]):
            raise SkillFailure("Pick: the straight base path passes a cupboard")
        return [goal]

    def grasp_z(self, state: ObjectCentricState, obj: Object) -> float:
        return float(state.get(obj, "bb_z") / 2 + GRASP_ABOVE_CENTRE)


def _rod_in_base(state: ObjectCentricState, robot: Object, rod: Object) -> tuple[FloatArray, float]:
    """The held rod's centre (x, y) in the base frame, and the angle of its axis (the direction
    pointing away from the base) relative to the base heading."""
    base = base_pose(state, robot)
    centre, axis = _rod_axis(state, rod)
    c, s = math.cos(base[2]), math.sin(base[2])
    rel = centre[:2] - base[:2]
    local = np.array([c * rel[0] + s * rel[1], -s * rel[0] + c * rel[1]])
    angle = wrap_angle(math.atan2(axis[1], axis[0]) - float(base[2]))
    if abs(angle) > math.pi / 2:  # the half of the axis that points away from the base
        angle = wrap_angle(angle + math.pi)
    return local, angle


def _rod_elevation(state: ObjectCentricState, rod: Object, heading: float) -> float:
    """Angle (rad) by which the half of the rod pointing along ``heading`` rises above the
    horizontal."""
    w, x, y, z = (float(v) for v in state[rod][3:7])
    axis = np.array([2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)])
    if axis[0] * math.cos(heading) + axis[1] * math.sin(heading) < 0:
        axis = -axis
    return math.asin(float(np.clip(axis[2], -1.0, 1.0)))


def _rod_bottom(state: ObjectCentricState, rod: Object) -> float:
    """Height (m) of the rod's lowest point."""
    w, x, y, z = (float(v) for v in state[rod][3:7])
    rot = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    half = np.array([state.get(rod, f) for f in ("bb_x", "bb_y", "bb_z")]) / 2
    return float(state.get(rod, "z") - np.abs(rot[2]) @ half)


def _gripper_pitch(state: ObjectCentricState, robot: Object) -> float:
    """Angle (rad) of the gripper's approach axis below the horizontal."""
    tf = forward_kinematics(tuple(base_pose(state, robot)), arm_joints(state, robot))["pinch_site"]
    return math.asin(float(np.clip(-tf[2, 2], -1.0, 1.0)))


def _base_for_rod(local: FloatArray, angle: float, spot: FloatArray, yaw: float) -> FloatArray:
    """The base pose that puts a rod held at ``(local, angle)`` with its centre at ``spot`` and
    its axis along ``yaw``."""
    heading = wrap_angle(yaw - angle)
    c, s = math.cos(heading), math.sin(heading)
    offset = np.array([c * local[0] - s * local[1], s * local[0] + c * local[1]])
    return np.array([*(spot - offset), heading])


class PlaceController(Dynamic3DController):
    """Slide the held rod onto the goal shelf of a cupboard. Objects: ``(robot, rod, cupboard)``."""

    params_space = spaces.Box(0.0, 1.0, (1,), dtype=np.float64)
    params_doc = (
        "(depth,): the rod's centre ends 0.02 + 0.05·depth metres inside the opening, or less "
        "where the pinch point would otherwise come within 1.5 cm of the opening."
    )

    #: Range (m) of the rod centre's final distance inside the opening.
    depth_range = (0.02, 0.07)
    #: Smallest distance (m) the pinch point keeps in front of the opening (negative: inside).
    finger_clearance = FINGER_CLEARANCE
    carry_speed = CARRY_SPEED
    #: Height (m) of the rod's underside above the goal shelf while it slides in.
    slide_above = SLIDE_ABOVE_SHELF

    hand_must_be = "closed"

    def _region(self, rod: Object, cupboard: Object) -> str | None:
        """The goal region ``rod`` is placed into in ``cupboard`` (None: it has none)."""
        ctx: CupboardContext = self.context
        return ctx.regions.get(cupboard)

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        ctx: CupboardContext = self.context
        robot, rod, cupboard = self.objects
        region = self._region(rod, cupboard)
        if region is None:
            raise SkillFailure(f"Place: {cupboard.name} has no goal region")
        box = _Cupboard(ctx, cupboard, region, state)
        opening = box.shelf[:2] + box.depth / 2 * box.front  # centre of the front edge
        half = rod_length(state, rod) / 2
        lo, hi = self.depth_range
        wanted = lo + (hi - lo) * float(self.params[0])
        local, angle = _rod_in_base(state, robot, rod)
        # The pinch point lies `reach` behind the rod's centre along the rod.
        pinch = pinch_position(base_pose(state, robot), arm_joints(state, robot))
        reach = float(np.linalg.norm(np.asarray(state[rod][:2]) - pinch[:2]))
        depth = min(wanted, reach - self.finger_clearance)
        if depth < 0.015:
            raise SkillFailure("Place: the rod is held too near its centre to slide it in")
        outside = opening + (half + PRE_PLACE) * box.front
        pre = _base_for_rod(local, angle, outside, box.inward_yaw)
        b0 = base_pose(state, robot)
        if not _clear_of_cupboards(ctx, state, b0[:2], pre[:2]):
            raise SkillFailure("Place: the straight base path to the cupboard passes a cupboard")
        arm = arm_joints(state, robot)

        def level(s: ObjectCentricState) -> list[Segment]:
            # Turn the hand about the fingers' closing axis until the rod is level.
            here = pinch_position(base_pose(s, robot), arm_joints(s, robot))
            heading = float(base_pose(s, robot)[2])
            pitch = _gripper_pitch(s, robot) + _rod_elevation(s, rod, heading)
            return line_segments(s, robot, here, heading, pitch, 1.0, pitch_offsets=(0.0,))

        def to_shelf_height(s: ObjectCentricState) -> list[Segment]:
            here = pinch_position(base_pose(s, robot), arm_joints(s, robot))
            heading = float(base_pose(s, robot)[2])
            target_z = here[2] + box.shelf[2] + self.slide_above - _rod_bottom(s, rod)
            pitch = _gripper_pitch(s, robot)
            return line_segments(s, robot, np.array([*here[:2], target_z]), heading, pitch, 1.0)

        def slide_in(s: ObjectCentricState) -> list[Segment]:
            local_now, angle_now = _rod_in_base(s, robot, rod)
            spot = opening - depth * box.front
            inside = _base_for_rod(local_now, angle_now, spot, box.inward_yaw)
            back = _base_for_rod(local_now, angle_now, outside, box.inward_yaw)
            q = arm_joints(s, robot)
            return [
                Segment(base=tuple(inside), arm=tuple(q), gripper=1.0, arm_tol=0.05,
                        base_tol=0.005, max_steps=60, base_speed=self.carry_speed),
                grip_segment(0.0),
                Segment(base=tuple(back), arm=tuple(q), gripper=0.0, arm_tol=0.05,
                        base_tol=0.02, max_steps=60),
            ]  # fmt: skip

        carry = replace(self.drive(pre, arm, 1.0, 0.01), base_speed=self.carry_speed)
        steps = math.ceil(carry.max_steps * MAX_DELTA / self.carry_speed[0])
        carry = replace(carry, max_steps=steps)
        return [carry, level, to_shelf_height, slide_in]


def _goal_pairs(env: ObjectCentricEnv) -> list[tuple[str, str, str]]:
    """(rod, region, cupboard) names of every goal atom of the task."""
    specs = env.task.regions  # type: ignore[attr-defined]

    def rod_on(atom: tuple[Any, ...]) -> bool:
        return bool(atom[0] == "on" and str(atom[1]).startswith(ROD_PREFIX))

    placed = placement_goal(env, "ConstrainedCupboard3D", rod_on)
    return [(rod, region, str(specs[region].target)) for rod, region in placed]


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The ConstrainedCupboard3D planning model (any number of rods and cupboards)."""
    objects: dict[str, Object] = env.objects  # type: ignore[attr-defined]
    robot_obj = objects["robot"]
    rods = tuple(sorted(o for n, o in objects.items() if n.startswith(ROD_PREFIX)))
    cupboards = tuple(sorted(o for n, o in objects.items() if n.startswith("cupboard_")))
    goal_pairs = _goal_pairs(env)
    regions = {objects[cup]: region for _, region, cup in goal_pairs}
    goal_of = {objects[rod]: objects[cup] for rod, _, cup in goal_pairs}
    ctx = CupboardContext(env, robot_obj, cupboards, rods, regions)

    predicates, pick, place = pick_place_domain("?rod")
    HandEmpty, Holding, OnGround, OnShelf = predicates

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms, closed, pinch = hand_state(state, robot_obj, HandEmpty)
        centres = np.array([np.asarray(state[r][:3]) for r in rods])
        inside = {
            cup: env.regions.contains(state, region, centres)  # type: ignore[attr-defined]
            for cup, region in regions.items()
        }
        for i, r in enumerate(rods):
            near = nearest_axis_point(state, r, pinch)
            resting = state.get(r, "bb_z") / 2 + GRASP_ABOVE_CENTRE
            if closed and near[2] > resting and np.linalg.norm(near - pinch) < 0.03:
                atoms.add(Holding.ground([robot_obj, r]))
                continue
            shelves = [cup for cup in regions if inside[cup][i]]
            for cup in shelves:
                atoms.add(OnShelf.ground([r, cup]))
            if not shelves and near[2] < 0.05:
                atoms.add(OnGround.ground([r]))
        return frozenset(atoms)

    return dynamic3d_model(
        "constrained_cupboard3d",
        ctx,
        predicates,
        [(pick, PickController), (place, PlaceController)],
        {HandEmpty.ground([robot_obj])}
        | {OnShelf.ground([rod, cup]) for rod, cup in goal_of.items()},
        abstraction,
        [*sorted(regions), *rods],
        400,
        types=[ROBOT_TYPE, MOVABLE_TYPE, FIXTURE_TYPE],
    )


__all__: Sequence[str] = [
    "PickController",
    "PlaceController",
    "create_model",
    "nearest_axis_point",
    "rod_length",
]
