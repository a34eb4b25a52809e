"""The Tossing3D planning model: get 5 cm cubes into a bin that stands beyond a barrier.

The scene (task file ``Tossing3D.json``, as upstream kindergarden 0.2.5): an open floor; the
robot starts at the origin facing +x; cubes lie at x ∈ [0.5, 0.75], |y| ≤ 0.25; a
6 cm × 10 m × 20 cm, 10 kg *movable* barrier stands across the floor at x = 1.3; the
30 × 30 × 20 cm, 0.1 kg bin (its frame the centre of its bottom face) stands at
x ∈ [1.48, 2.3], |y| ≤ 2.3 (o1) or at x = 2.0, y = 0 (o2). Goal: every cube's centre in the
20 × 20 × 10 cm box above the bin's floor (the env's ``on(cube_i, blocks_goal_region)``; o2's
box is fixed on the floor where the bin starts).

Why this model does not toss (measured, this env): the bundled Tossing3D action is 11-D (as
upstream kindergarden 0.2.5) and the arm tracks joint targets at most 0.1 rad ahead of the
measured angles, so a joint turns at about 0.4–0.6 rad/s and the base drives at 0.87 m/s. The
fastest pinch-point motion found (base driving at full speed while joints 2, 4 and 6 swing at
full speed; ``python benchmarks/speed/tossing_speed.py``) is 1.33 m/s, and a cube released at that
speed from 1 m flies at most 0.63 m (measured with the earlier 2.5 cm cubes and bin placement);
a toss from behind the barrier is not what this model does. (Upstream's tossing skill used its
older 18-D action with unbounded joint-velocity targets.) What the env does allow, and the model
uses, is the barrier's mobility: driven into it, the base topples it (it tips about its bottom
edge), and the base drives on beyond it.
The cube is then carried to the bin and released above it: a drop, closed-loop like every
skill here (the controller observes the state every step, and the planner checks the abstract
outcome of each skill and resamples when it differs).

Concepts:

* ``HandEmpty(robot)``: measured finger closure below 0.2.
* ``Holding(robot, cube)``: the fingers are closed and the pinch point is within 4 cm of the
  cube's centre, which is off the floor.
* ``InBin(cube, bin)``: the env's own goal atom, so the goal atoms are exactly the env's goal.
* ``OnGround(cube)``: not held, not in the bin, and the cube's centre below 5 cm.
* ``Upright(barrier)`` (its local z axis within 45° of vertical) and ``Toppled(barrier)`` (more
  than 70° from vertical); a barrier in between has neither.

Operators: ``Topple(?robot, ?barrier)`` (pre HandEmpty, Upright; add Toppled; delete Upright),
``Pick(?robot, ?cube)`` (pre HandEmpty, OnGround; add Holding; delete HandEmpty, OnGround) and
``Drop(?robot, ?cube, ?bin, ?barrier)`` (pre Holding, Toppled; add HandEmpty, InBin; delete
Holding) and ``DropOver(?robot, ?cube, ?bin, ?barrier)`` (pre Holding, Upright; the same
effects). Goal: every cube InBin.

Skills (segment following of :mod:`kinder_gym.models.dynamic3d.tidybot`; Pick is the mobile
manipulator's :class:`~kinder_gym.models.dynamic3d.tidybot.FloorPickController`: reach above,
descend, close, lift):

* Topple: retract the arm, drive sideways to a sampled lane y (clear of the cubes), turn to
  face +x, and drive straight through the barrier to 0.8 m beyond it.
* Pick: retract, drive straight to a standoff 0.50–0.60 m from the cube along one of its faces
  (the face nearest a sampled heading; the straight path keeps the chassis clear of the other
  cubes on the floor and of the bin), reach above the cube's measured position with the gripper
  pitched 45° down, descend, close, and lift the pinch point to 0.40 m (above the bin's 0.2 m
  rim).
* Drop: with the arm held as it is, drive straight to the base pose that puts the pinch point
  above a sampled spot within 4 cm of the bin's centre, approaching from a sampled heading
  within ±60° of the line from the base to the bin, at most 0.05 m and 0.08 rad per action
  (at full speed the cube was flung out when the base braked); re-aim the base at the bin's
  measured position (closed loop: the bin, 0.1 kg, can be nudged); open, wait, and back the base
  0.3 m away.
* DropOver: with the arm held, drive straight (as Drop, slowly) to face +x 0.24 m short of the
  upright barrier, level with a sampled spot up to 8 cm short of the bin's centre (and within
  4 cm of it across); stretch the arm over the barrier along a straight line until the pinch
  point is 0.40 m above that spot (refused when it lies more than 1.04 m ahead of the base: the
  arm's IK reaches 1.05–1.1 m at that height), open, retract the arm and back the base 0.3 m
  away (a chassis turning that close to the barrier knocks it over). The barrier stays upright
  and the bin unpushed.

Parameter spaces are documented on each controller (``params_doc``). Differences from upstream's
``tidybot3d_tossing3D`` model (spec baselines.md): no toss (see above); the barrier is toppled
by a skill of its own rather than being treated as fixed; ``OnGround`` ignores the cube's
orientation (the grasp approaches along a face of the measured yaw).

Limits (measured on the earlier scene: 2.5 cm cubes, a 3 cm × 5 m × 10 cm barrier, walls, the
bin at x ∈ [2.6, 3.42]): planner-free, each skill with up to 3 samples in a fixed order and no time
budget
(``python benchmarks/probes/skill_success.py toss --env kinder/Tossing3D-o2-v0 --seeds 0-9``),
Topple reached its prediction in 10 of 13 tries, Pick in 13 of 26 and Drop in 11 of 22 (the
failures include cheap refusals of blocked straight base paths), and 5 of the 10 episodes were
solved. What fails: descents that stall against the cube, cubes landing beside the bin, and the
toppled barrier rolling back onto an edge when the base drives over it (it stands again; the
planner sees the mismatch and resamples). A successful o2 plan is about 480 actions, each
100 MuJoCo steps, and simulating them (with the failed samples) is almost all of the planning
time (``mj_step`` was about 80 % of a cProfile'd o1 planning call), so BP's 60 s budget
is sensitive to machine load (see ``benchmarks/results/bilevel_planning.md``). The model needs
the barrier movable (it is a movable 10 kg cuboid in this env and in
upstream 0.2.5); a task file with a fixed barrier and this bin placement would have no solution
with the 11-D action.

On upstream's scene the toppled barrier (6 cm thick) is pushed ahead of the base rather than
driven over, and it shoves the 0.1 kg bin along: harmless on o1, whose goal box moves with the
bin, but o2's goal box is fixed on the floor at x = 2, so o2 needs DropOver. BP on development
seeds (``kinder bench run -a bilevel_planning --env kinder/Tossing3D-o2-v0 --seeds 1000
--episodes 5``, 60 s budget, a loaded 2-core machine): 0 of 5 without DropOver, 3 of 5 with it
(the other two ran out of the budget); o1: 5 of 5. Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.dynamic3d.geometry import quat_to_matrix, quat_yaw
from kinder_garden3d.dynamic3d.object_types import MOVABLE_TYPE
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models import hand
from kinder_gym.models.dynamic3d.tidybot import (
    CHASSIS_RADIUS,
    GRIP_STEPS,
    HOME,
    Dynamic3DContext,
    Dynamic3DController,
    FloorPickController,
    Segment,
    SegmentSource,
    arm_joints,
    base_pose,
    chassis_clear_of_box,
    clear_of_points,
    dynamic3d_model,
    face_approach,
    grip_segment,
    hand_predicates,
    hand_state,
    line_segments,
    pick_operator,
    pinch_position,
    yaw_axes,
)
from kinder_gym.motion_planning import FloatArray
from kinder_gym.operators import GroundOperator
from kinder_gym.skills import SkillFailure

GOAL_REGION = "blocks_goal_region"
#: Height (m) of the pinch point while carrying and dropping (the bin's rim is at 0.2 m).
CARRY_Z = 0.40
#: Largest base step (m, rad per action) while carrying: at the env's full 0.1 the cube was
#: flung out of the fingers when the base braked in front of the bin (seed 0).
CARRY_SPEED = (0.05, 0.08)
#: The area (xmin, xmax, ymin, ymax, m) the base drives in: the floor is open (no walls), and
#: every cube, the barrier's middle and the bin lie inside it.
ROOM = (-1.5, 4.0, -2.7, 2.7)
#: Distance (m) the chassis centre keeps from a floor cube while driving (the cubes are taller
#: than the chassis' 2 cm ground clearance).
CUBE_CLEARANCE = CHASSIS_RADIUS + 0.03
#: Distance (m) from the upright barrier's near face to the base centre for DropOver (the
#: chassis' half-width, 0.2 m, and a margin).
OVER_STANDOFF = 0.24
#: Farthest (m) the pinch point reaches ahead of the base centre at the carry height (the arm's
#: IK reaches 1.05 m at a 45° pitch, 1.1 m at 0° to 20°), less a margin.
OVER_REACH = 1.04
#: Distance (m) the base backs away from the barrier after DropOver.
OVER_BACK_OFF = 0.3
#: Pitch (rad) of the gripper while reaching over the barrier.
OVER_PITCH = math.radians(30.0)
#: Distance (m) beyond the barrier's initial line to which Topple drives.
TOPPLE_OVERSHOOT = 0.8
#: Barrier tilt thresholds (cosine of the angle between its local z axis and the vertical).
UPRIGHT_COS = math.cos(math.radians(45.0))
TOPPLED_COS = math.cos(math.radians(70.0))


@dataclass(frozen=True)
class TossContext(Dynamic3DContext):
    """What the Tossing3D controllers need besides the state."""

    barrier: Object
    bin: Object
    cubes: tuple[Object, ...]


def _xy(state: ObjectCentricState, obj: Object) -> FloatArray:
    return np.array([state.get(obj, "x"), state.get(obj, "y")])


def barrier_cos(state: ObjectCentricState, barrier: Object) -> float:
    """Cosine of the angle between the barrier's local z axis and the world vertical."""
    quat = np.array([state.get(barrier, f) for f in ("qw", "qx", "qy", "qz")])
    return abs(float(quat_to_matrix(quat)[2, 2]))


def _in_room(xy: FloatArray) -> bool:
    x0, x1, y0, y1 = ROOM
    m = CHASSIS_RADIUS + 0.02
    return bool(x0 + m <= xy[0] <= x1 - m and y0 + m <= xy[1] <= y1 - m)


def _path_clear(
    ctx: TossContext,
    state: ObjectCentricState,
    a: FloatArray,
    b: FloatArray,
    skip: Object | None,
) -> bool:
    """Whether the chassis can drive straight from ``a`` to ``b`` (x, y): inside ``ROOM``, clear
    of the bin and of the cubes on the floor other than ``skip``."""
    if not _in_room(b):
        return False
    centre = _xy(state, ctx.bin)
    axes = yaw_axes(quat_yaw(np.asarray(state[ctx.bin][3:7])))
    half = np.array([state.get(ctx.bin, "bb_x"), state.get(ctx.bin, "bb_y")]) / 2
    if not chassis_clear_of_box(a, b, centre, axes, half, 0.03):
        return False
    floor = [  # the cubes on the floor, less those in the bin
        _xy(state, c)
        for c in ctx.cubes
        if c != skip and state.get(c, "z") <= 0.05 and np.linalg.norm(_xy(state, c) - centre) >= 0.2
    ]
    return clear_of_points(a, b, floor, CUBE_CLEARANCE)


class ToppleController(Dynamic3DController):
    """Drive the base through the barrier so that it topples. Objects: ``(robot, barrier)``."""

    params_space = spaces.Box(0.0, 1.0, (1,), dtype=np.float64)
    params_doc = (
        "(lane,): the base drives toward +x along y = 4.0·lane − 2.0 metres (lanes passing "
        "within 0.31 m of a cube on the floor are refused)."
    )

    hand_must_be = "open"

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        ctx: TossContext = self.context
        robot, barrier = self.objects
        lane = 4.0 * float(self.params[0]) - 2.0
        b0 = base_pose(state, robot)
        end_x = state.get(barrier, "x") + TOPPLE_OVERSHOOT
        side = np.array([b0[0], lane])
        if not _path_clear(ctx, state, b0[:2], side, None):
            raise SkillFailure("Topple: the sideways move to the lane is blocked")
        if not _path_clear(ctx, state, side, np.array([end_x, lane]), None):
            raise SkillFailure("Topple: the lane is blocked")
        return [
            *self.retract_arm(state),
            self.drive(np.array([b0[0], lane, 0.0]), HOME, 0.0, 0.02),
            self.drive(np.array([end_x, lane, 0.0]), HOME, 0.0, 0.03),
        ]


class PickController(FloorPickController):
    """Pick a cube off the floor and lift it to the carry height. Objects: ``(robot, cube)``."""

    params_doc = (
        "(dist, heading): the base stops 0.50 + 0.10·dist metres short of the cube, approaching "
        "along the cube face nearest to the world heading (2·heading − 1)·π radians."
    )
    lift_z = CARRY_Z

    def approach(
        self, state: ObjectCentricState, obj: Object
    ) -> tuple[FloatArray, float, FloatArray]:
        return face_approach(state, obj, (2.0 * float(self.params[1]) - 1.0) * math.pi)

    def route(self, state: ObjectCentricState, goal: FloatArray) -> list[FloatArray]:
        """Straight, clear of the bin and of the other cubes on the floor."""
        robot, cube = self.objects
        if not _path_clear(self.context, state, base_pose(state, robot)[:2], goal[:2], cube):
            raise SkillFailure("Pick: the straight base path is blocked")
        return [goal]


class _BinDropController(Dynamic3DController):
    """Carry the held cube, the arm held as it is, straight to a base pose near the bin (slowly:
    :data:`CARRY_SPEED`), release it above the bin and back away. Objects:
    ``(robot, cube, bin, barrier)``."""

    hand_must_be = "closed"
    #: What the refusal of a blocked straight base path says.
    blocked = "the straight base path is blocked"

    @abc.abstractmethod
    def moves(
        self, state: ObjectCentricState, arm: FloatArray
    ) -> tuple[FloatArray, list[SegmentSource], list[SegmentSource]]:
        """The base pose to drive to, the segments there before the hand opens and those after
        (raise SkillFailure when the drop cannot be made)."""

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        robot, cube = self.objects[:2]
        arm = arm_joints(state, robot)
        stand, before, after = self.moves(state, arm)
        if not _path_clear(self.context, state, base_pose(state, robot)[:2], stand[:2], cube):
            raise SkillFailure(self.blocked)
        release = grip_segment(0.0, GRIP_STEPS + 4)
        return [self.drive(stand, arm, 1.0, 0.01, CARRY_SPEED), *before, release, *after]


class DropController(_BinDropController):
    """Carry the held cube over the bin beyond the toppled barrier, re-aim the base at the bin's
    measured position (it may have been nudged) and release the cube. Objects:
    ``(robot, cube, bin, barrier)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(angle, u, v): the base approaches along the heading (angle − 0.5)·2π/3 radians off "
        "the line from the base to the bin's centre; the hand opens with the pinch point "
        "0.08·(u − 0.5), 0.08·(v − 0.5) metres (world x, y) from the bin's centre."
    )
    blocked = "Drop: the straight base path to the bin is blocked"

    def moves(
        self, state: ObjectCentricState, arm: FloatArray
    ) -> tuple[FloatArray, list[SegmentSource], list[SegmentSource]]:
        ctx: TossContext = self.context
        robot = self.robot
        centre = _xy(state, ctx.bin)
        to_bin = centre - base_pose(state, robot)[:2]
        heading = math.atan2(to_bin[1], to_bin[0]) + (float(self.params[0]) - 0.5) * 2 * math.pi / 3
        spot = centre + 0.08 * (np.asarray(self.params[1:3]) - 0.5)
        # The arm is held fixed: the pinch point keeps its offset in the base frame.
        offset = pinch_position(np.array([0.0, 0.0, heading]), arm)[:2]
        goal = np.array([*(spot - offset), heading])
        back = goal[:2] - 0.3 * np.array([math.cos(heading), math.sin(heading)])

        def re_aim(s: ObjectCentricState) -> list[Segment]:
            # Closed loop on the bin: it may have been nudged, and the base stops within 1 cm.
            here = pinch_position(base_pose(s, robot), arm_joints(s, robot))[:2]
            error = _xy(s, ctx.bin) + (spot - centre) - here
            if float(np.linalg.norm(error)) < 0.01:
                return []
            target = base_pose(s, robot)[:2] + error
            return [self.drive(np.array([*target, heading]), arm, 1.0, 0.005, CARRY_SPEED)]

        away = Segment(
            base=(float(back[0]), float(back[1]), heading),
            arm=tuple(arm),
            arm_tol=0.05,
            base_tol=0.03,
        )
        return goal, [re_aim], [away]


class DropOverController(_BinDropController):
    """Release the held cube above the bin with the arm stretched over the upright barrier.
    Objects: ``(robot, cube, bin, barrier)``."""

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(u, v): the hand opens with the pinch point −0.08·u, 0.08·(v − 0.5) metres (world x, y) "
        "from the bin's centre (on the robot's side of it), the base facing +x just short of the "
        "barrier."
    )
    blocked = "DropOver: the straight base path to the barrier is blocked"

    def moves(
        self, state: ObjectCentricState, arm: FloatArray
    ) -> tuple[FloatArray, list[SegmentSource], list[SegmentSource]]:
        ctx: TossContext = self.context
        robot = self.robot
        u, v = (float(x) for x in self.params)
        spot = _xy(state, ctx.bin) + np.array([-0.08 * u, 0.08 * (v - 0.5)])
        front = state.get(ctx.barrier, "x") - state.get(ctx.barrier, "bb_x") / 2
        stand = np.array([front - OVER_STANDOFF, spot[1], 0.0])
        if spot[0] - stand[0] > OVER_REACH:
            raise SkillFailure("DropOver: the bin is out of reach from behind the barrier")
        target = np.array([*spot, CARRY_Z])

        def reach(s: ObjectCentricState) -> list[Segment]:
            return line_segments(s, robot, target, 0.0, OVER_PITCH, 1.0, spacing=0.05)

        back = (float(stand[0]) - OVER_BACK_OFF, float(stand[1]), 0.0)
        return (
            stand,
            [reach],
            [
                Segment(arm=tuple(HOME), arm_tol=0.05, max_steps=80),
                # Back away before anything turns the base: a turning chassis this close to the
                # barrier (its corners reach 0.28 m out) knocks it over.
                Segment(base=back, arm=tuple(HOME), arm_tol=0.05, base_tol=0.03),
            ],
        )


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The Tossing3D planning model (any number of cubes)."""
    objects: dict[str, Object] = env.objects  # type: ignore[attr-defined]
    robot_obj = objects["robot"]
    barrier = objects["cuboid_barrier"]
    bin_obj = objects["bin_0"]
    cubes = tuple(sorted(o for n, o in objects.items() if n.startswith("cube_")))
    ctx = TossContext(env, robot_obj, barrier, bin_obj, cubes)

    HandEmpty, Holding = hand_predicates()
    OnGround = Predicate("OnGround", (MOVABLE_TYPE,))
    InBin = Predicate("InBin", (MOVABLE_TYPE, MOVABLE_TYPE))
    Upright = Predicate("Upright", (MOVABLE_TYPE,))
    Toppled = Predicate("Toppled", (MOVABLE_TYPE,))

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms, closed, pinch = hand_state(state, robot_obj, HandEmpty)
        cos = barrier_cos(state, barrier)
        if cos >= UPRIGHT_COS:
            atoms.add(Upright.ground([barrier]))
        elif cos <= TOPPLED_COS:
            atoms.add(Toppled.ground([barrier]))
        on = env.goal_atoms(state)  # type: ignore[attr-defined]
        for c in cubes:
            pos = np.asarray(state[c][:3])
            if closed and pos[2] > 0.02 and np.linalg.norm(pos - pinch) < 0.04:
                atoms.add(Holding.ground([robot_obj, c]))
            elif on[f"on({c.name}, {GOAL_REGION})"]:
                atoms.add(InBin.ground([c, bin_obj]))
            elif pos[2] < 0.05:
                atoms.add(OnGround.ground([c]))
        return frozenset(atoms)

    c = Variable("?cube", MOVABLE_TYPE)
    b = Variable("?bin", MOVABLE_TYPE)
    w = Variable("?barrier", MOVABLE_TYPE)
    upright, toppled = Upright.lift([w]), Toppled.lift([w])
    topple = hand.empty_hand_operator("Topple", HandEmpty, [w], [upright], [toppled], [upright])
    pick = pick_operator(c, OnGround)
    in_bin = [InBin.lift([c, b])]
    drop = hand.place_operator("Drop", HandEmpty, Holding, c, in_bin, [toppled], params=[b, w])
    drop_over = hand.place_operator(
        "DropOver", HandEmpty, Holding, c, in_bin, [upright], params=[b, w]
    )

    def keep(op: GroundOperator, state: ObjectCentricState) -> bool:
        """Only the bin, the barrier and the cubes in their operators' roles."""
        del state
        if op.parent is topple:
            return op.objects[1] == barrier
        if op.parent is pick:
            return op.objects[1] in cubes
        return op.objects[1] in cubes and op.objects[2:] == (bin_obj, barrier)  # both drops

    return dynamic3d_model(
        "tossing3d",
        ctx,
        [HandEmpty, Holding, OnGround, InBin, Upright, Toppled],
        [
            (topple, ToppleController),
            (pick, PickController),
            (drop, DropController),
            (drop_over, DropOverController),
        ],
        (InBin.ground([c, bin_obj]) for c in cubes),
        abstraction,
        [barrier, bin_obj, *cubes],
        400,
        step_limit=True,
        operator_filter=keep,
    )


__all__: Sequence[str] = [
    "DropController",
    "DropOverController",
    "PickController",
    "ToppleController",
    "create_model",
]
