"""The SweepSimple3D planning model: carry the 1 cm blocks on the kitchen floor into the goal area.

The scene (every variant): blocks (1 cm cubes ``cube_0`` …) lie on the floor in
x ∈ [1.25, 1.75], y ∈ [0.2, 0.7]; the wiper (a T, 30 cm head) lies on the floor just +y of
them; the goal area ``sweep_region`` is a floor box beside the kitchen island (left side,
x ∈ [0.125, 0.875], y ∈ [1.0, 1.375]), or beside the island's other end or the counter in the
two other o50 tasks. The model reads the goal box from the task, so every variant is handled.

Concepts:

* ``HandEmpty(robot)``: the fingers are open (closure below 0.2).
* ``Holding(robot, block)``: the fingers are closed and the pinch point is within 4 cm of the
  block, which is off the floor.
* ``OnFloor(block)``: not held, below 5 cm, and not in the goal area.
* ``InArea(block)``: the env's own goal atom ``on(block, sweep_region)``, so the goal atoms
  (every block ``InArea``, and ``HandEmpty``) imply the env's goal.

Operators: ``Pick(?robot, ?block)`` (pre HandEmpty, OnFloor; add Holding; delete HandEmpty,
OnFloor) and ``Place(?robot, ?block)`` (pre Holding; add HandEmpty, InArea; delete Holding).

Skills (segment following of :mod:`kinder_gym.models.dynamic3d.tidybot`; the floor grasp of
:mod:`kinder_gym.models.dynamic3d.shelf3d` with this family's geometry):

* Pick: fold the arm, drive the base straight to 0.50–0.60 m short of the block facing it along
  a sampled heading (rejected when the chassis would hit the island, the walls or the wiper, or
  its path passes within 5 cm of another block), reach above the block pitched 45° down,
  descend, close, lift the block to 15 cm.
* Place: with the arm held as it is, drive the base so that the pinch point is above a sampled
  spot of the goal area (the base facing the spot along a sampled heading, same rejections),
  lower the block to 2.5 cm, open, back the hand up.

Deviation from upstream (stated plainly): upstream's task is solved by sweeping with the wiper.
This model carries the blocks one by one instead, because the wiper sweeps of
:mod:`kinder_gym.models.dynamic3d.sweep_into_drawer3d` push objects ~20 cm over a table edge,
whereas here every block must travel ~1.3 m across the floor around the island's end, a
closed-loop pushing skill that was not built in the time this model had. The wiper is only an
obstacle. Consequence: a pick and a place take about 150–300 actions (planner-free: o5
1,338–1,467 actions, o10 2,691–2,963), more than the 1000 steps every Dynamic3D id had, so
o5 and o10 have their own limits, 2500 and 4500 (``benchmarks/results/step_limits.md``: 1.5 ×
the most actions the skills took, rounded up to 500; upstream registers no limit). At them BP
solves o5 in 0.94 and o10 in 0.60 of the measured episodes
(``benchmarks/results/bilevel_planning.md``). A wiper sweep that moves many blocks per pass is
what o50 needs.

Findings that shaped the skills: carried at the env's full base speed (0.1 m, 0.1 rad per
action) the 1 cm block was flung out of the fingers on most carries, hence ``CARRY_SPEED``;
the straight drive from the robot's start to the blocks crosses the wiper, and the gaps beside
it (about 0.5 m) only pass a chassis turned to its final heading first; an arm held out while
the base drove along the cooking counter knocked the block out on the counter, hence the hand
clearance checked along every route. Pick and Place draw their parameters again (up to 200
times, geometry only) while the standoff or the route is blocked, because the planner's three
samples per step were otherwise mostly blocked routes.

Imports kinder_garden3d (the ``[3d]`` extra).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.dynamic3d.object_types import MOVABLE_TYPE, ROBOT_TYPE
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.dynamic3d.shelf3d import (
    CHASSIS_RADIUS,
    CLOSED,
    CUBE_CLEARANCE,
    GRIP_STEPS,
    PITCH,
    READY,
    _segment_point_distance,
    _segment_rect_distance,
    _ShelfController,
    _yaw_of,
)
from kinder_gym.models.dynamic3d.tidybot import (
    HOME,
    MAX_DELTA,
    Segment,
    SegmentSource,
    arm_joints,
    base_pose,
    gripper_quat,
    ik_near,
    line_segments,
    pinch_position,
)
from kinder_gym.motion_planning import FloatArray, wrap_angle
from kinder_gym.operators import LiftedOperator
from kinder_gym.skills import Skill, SkillFailure

GOAL_REGION = "sweep_region"
WIPER = "wiper_0"
BLOCK_PREFIX = "cube_"
#: Height (m) of the pinch point when the fingers close on a 1 cm block on the floor.
GRASP_Z = 0.009
#: Height (m) of the pinch point while carrying.
CARRY_Z = 0.15
#: Height (m) of the pinch point when the hand opens over the goal area.
RELEASE_Z = 0.025
#: Largest base step (m, rad per action) while carrying a block: at the env's full speed
#: (0.1) the 1 cm block was flung out of the fingers on most carries.
CARRY_SPEED = (0.05, 0.05)
#: Parameter draws tried by the samplers before they return a blocked one.
SAMPLE_TRIES = 200
#: Inset (m) of the place spots from the goal box's sides.
INSET = 0.06
#: Fixed obstacles as (centre x, centre y, half x, half y): the kitchen island and the counter
#: fronts; the room's walls bound the base (the lab2_kitchen scene).
ISLAND = (0.5, 0.0, 0.375, 1.0)
#: Bounds (m) of the base centre in the room: x below the cooking counter's front (2.19) and y
#: below the left side counter's front (about 2.3), both less the chassis radius.
BASE_X_MAX = 2.19 - CHASSIS_RADIUS
BASE_Y_MAX = 2.3 - CHASSIS_RADIUS
#: Clearance (m) kept between the hand (the pinch point) and the island or the counters.
HAND_CLEARANCE = 0.08
#: Half size (m) of the wiper's footprint (its T fits a 33 × 30 cm box).
WIPER_HALF = np.array([0.12, 0.10])
#: Clearance (m) kept between the base centre and the island or the wiper: the chassis' half
#: width (0.2 m) plus 3 cm. The base turns to its final heading before it drives, so that it
#: passes the 0.5 m gaps beside the wiper side-on rather than corner-first.
PASS_CLEARANCE = 0.23


@dataclass(frozen=True)
class SweepSimpleContext:
    """What the controllers need besides the state."""

    env: ObjectCentricEnv
    robot: Object
    wiper: Object
    blocks: tuple[Object, ...]
    box: tuple[float, float, float, float]  # goal area (xmin, ymin, xmax, ymax)


def _yaw_axes(yaw: float) -> FloatArray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def _base_ok(p: FloatArray, clearance: float = PASS_CLEARANCE) -> bool:
    """Whether a disc of radius ``clearance`` centred at ``p`` (the chassis, or the hand) is
    clear of the island and within the room."""
    cx, cy, hx, hy = ISLAND
    dx = max(abs(float(p[0]) - cx) - hx, 0.0)
    dy = max(abs(float(p[1]) - cy) - hy, 0.0)
    if math.hypot(dx, dy) < clearance:
        return False
    shift = clearance - CHASSIS_RADIUS
    return float(p[0]) < BASE_X_MAX - shift and float(p[1]) < BASE_Y_MAX - shift


def _path_ok(
    ctx: SweepSimpleContext,
    state: ObjectCentricState,
    a: FloatArray,
    b: FloatArray,
    skip: Object | None,
    hand: FloatArray,
) -> bool:
    """Whether the base can drive straight from ``a`` to ``b``: the chassis clear of the island
    (sampled) and the wiper, its centre clear of the blocks still on the floor, and the hand
    (at ``hand`` from the base centre) clear of the island and the counters."""
    n = max(2, math.ceil(float(np.linalg.norm(b - a)) / 0.05) + 1)
    for t in np.linspace(0.0, 1.0, n):
        p = a + t * (b - a)
        if not (_base_ok(p) and _base_ok(p + hand, HAND_CLEARANCE)):
            return False
    wf = state[ctx.wiper]
    centre = np.asarray(wf[:2], dtype=np.float64)
    axes = _yaw_axes(_yaw_of(np.asarray(wf[3:7])))
    if _segment_rect_distance(a, b, centre, axes, WIPER_HALF) < PASS_CLEARANCE:
        return False
    for blk in ctx.blocks:
        if blk == skip or state.get(blk, "z") > 0.05:
            continue
        p = np.array([state.get(blk, "x"), state.get(blk, "y")])
        if _segment_point_distance(a, b, p) < CUBE_CLEARANCE:
            return False
    return True


def _route(
    ctx: SweepSimpleContext,
    state: ObjectCentricState,
    start: FloatArray,
    goal: FloatArray,
    via_x: float,
    skip: Object | None,
    hand: FloatArray,
) -> list[FloatArray]:
    """Base waypoints ``(x, y)`` from ``start`` to ``goal``: straight when clear, else along x to
    ``via_x``, along y to the goal's y, then to the goal; SkillFailure when neither is clear."""
    if _path_ok(ctx, state, start, goal, skip, hand):
        return [goal]
    a = np.array([via_x, start[1]])
    b = np.array([via_x, goal[1]])
    legs = [(start, a), (a, b), (b, goal)]
    if all(_path_ok(ctx, state, p, q, skip, hand) for p, q in legs):
        return [a, b, goal]
    raise SkillFailure("the base has no clear path to its goal")


class _Controller(_ShelfController):
    """Shared: routes, and parameter samples whose standoff and route are clear."""

    @abc.abstractmethod
    def geometry(
        self, state: ObjectCentricState, params: FloatArray
    ) -> tuple[FloatArray, float, list[SegmentSource]]:
        """The base goal, heading and drive segments for ``params`` (SkillFailure: blocked)."""

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Uniform, redrawn (up to ``SAMPLE_TRIES`` times) while the standoff or the base's
        route is blocked: those checks are geometric and cheap, simulation is not."""
        params = super().sample_parameters(state, rng)
        for _ in range(SAMPLE_TRIES):
            try:
                self.geometry(state, params)
            except SkillFailure:
                params = super().sample_parameters(state, rng)
                continue
            break
        return params

    def drive_route(
        self,
        state: ObjectCentricState,
        goal: FloatArray,
        via_x: float,
        arm: FloatArray,
        gripper: float,
        skip: Object | None,
    ) -> list[SegmentSource]:
        """Turn in place to the goal heading, then drive the route's legs."""
        ctx: SweepSimpleContext = self.context
        b0 = base_pose(state, self.robot)
        if not _base_ok(b0[:2]):
            raise SkillFailure("the base is too close to the island")
        heading = float(goal[2])
        hand = pinch_position(np.array([0.0, 0.0, heading]), arm)[:2]
        # The hand sweeps an arc while the base turns in place: check it along the arc.
        turn = wrap_angle(heading - float(b0[2]))
        for f in np.linspace(0.0, 1.0, 9):
            arc = pinch_position(np.array([0.0, 0.0, float(b0[2]) + f * turn]), arm)[:2]
            if not _base_ok(b0[:2] + arc, HAND_CLEARANCE):
                raise SkillFailure("the hand would hit the island or a counter while turning")
        points = _route(ctx, state, b0[:2], goal[:2], via_x, skip, hand)
        segs: list[SegmentSource] = [
            Segment(
                base=(float(b0[0]), float(b0[1]), heading),
                arm=tuple(float(v) for v in arm),
                gripper=gripper,
                arm_tol=0.05,
                base_tol=0.03,
                max_steps=120,
                base_speed=CARRY_SPEED if gripper > 0.5 else (MAX_DELTA, MAX_DELTA),
            )
        ]
        for k, p in enumerate(points):
            last = k == len(points) - 1

            def leg(s: ObjectCentricState, p: FloatArray = p, last: bool = last) -> list[Segment]:
                self.state = s
                seg = self._drive(np.array([p[0], p[1], heading]), arm, gripper,
                                  0.01 if last else 0.04)  # fmt: skip
                if gripper > 0.5:  # carrying: slower, and more steps for it
                    seg = replace(seg, base_speed=CARRY_SPEED, max_steps=2 * seg.max_steps)
                return [seg]

            segs.append(leg)
        return segs


class PickController(_Controller):
    """Pick a block off the floor. Objects: ``(robot, block)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(dist, angle, via): the base stops 0.50 + 0.10·dist metres short of the block, facing "
        "it along the block face nearest to the heading 2π·angle (world frame); when the straight "
        "path is blocked it drives along x to x = 1.0 + 0.9·via, then along y, then to the goal."
    )

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.robot, "pos_gripper") < CLOSED

    def geometry(
        self, state: ObjectCentricState, params: FloatArray
    ) -> tuple[FloatArray, float, list[SegmentSource]]:
        """The base goal, the heading and the drive segments for ``params`` (SkillFailure when
        the standoff or the route is blocked)."""
        block = self.objects[1]
        if state.get(block, "z") > 0.05:
            raise SkillFailure(f"Pick: {block.name} is not on the floor")
        dist = 0.50 + 0.10 * float(params[0])
        c = np.array([state.get(block, "x"), state.get(block, "y")])
        yaw = _yaw_of(np.asarray(state[block][3:7]))
        k = round((2 * math.pi * float(params[1]) - yaw) / (math.pi / 2))
        heading = yaw + k * math.pi / 2
        direction = np.array([math.cos(heading), math.sin(heading)])
        goal = np.array([*(c - dist * direction), heading])
        if not _base_ok(goal[:2]):
            raise SkillFailure("Pick: the standoff is inside the island or out of the room")
        via = 1.0 + 0.9 * float(params[2])
        return goal, heading, self.drive_route(state, goal, via, HOME, 0.0, block)

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        robot, block = self.objects
        c = np.array([state.get(block, "x"), state.get(block, "y")])
        heading, route = self.geometry(state, np.asarray(self.params))[1:]
        direction = np.array([math.cos(heading), math.sin(heading)])
        quat = gripper_quat(heading, PITCH)
        grasp = np.array([*(c - 0.003 * direction), GRASP_Z])
        above = np.array([*(c - 0.01 * direction), 0.15])

        def reach_above(s: ObjectCentricState) -> list[Segment]:
            q = ik_near(above, quat, base_pose(s, robot), READY)
            return [Segment(arm=tuple(q), arm_tol=0.01, max_steps=80)]

        def descend(s: ObjectCentricState) -> list[Segment]:
            return line_segments(s, robot, grasp, heading, PITCH, 0.0)

        def lift(s: ObjectCentricState) -> list[Segment]:
            p = pinch_position(base_pose(s, robot), arm_joints(s, robot))
            return line_segments(s, robot, np.array([p[0], p[1], CARRY_Z]), heading, PITCH, 1.0,
                                 spacing=0.06)  # fmt: skip

        close = Segment(gripper=1.0, arm_tol=1.0, base_tol=1.0, min_steps=GRIP_STEPS)
        plan: list[SegmentSource] = []
        if np.abs(arm_joints(state, robot) - HOME).max() > 0.05:
            plan.append(Segment(arm=tuple(HOME), arm_tol=0.05, max_steps=80))
        plan += [*route, reach_above, descend, close, lift]
        return plan


class PlaceController(_Controller):
    """Put the held block down in the goal area. Objects: ``(robot, block)``."""

    params_space = spaces.Box(0.0, 1.0, (4,), dtype=np.float64)
    params_doc = (
        "(u, v, angle, via): the block goes down at fraction (u, v) of the goal box inset by "
        "6 cm, with the base facing the spot along the heading 2π·angle (world frame); via as "
        "for Pick."
    )

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.robot, "pos_gripper") >= CLOSED

    def geometry(
        self, state: ObjectCentricState, params: FloatArray
    ) -> tuple[FloatArray, float, list[SegmentSource]]:
        """As :meth:`PickController.geometry`."""
        ctx: SweepSimpleContext = self.context
        robot, block = self.objects
        u, v, angle, via = (float(p) for p in params)
        x0, y0, x1, y1 = ctx.box
        spot = np.array([x0 + INSET + u * (x1 - x0 - 2 * INSET),
                         y0 + INSET + v * (y1 - y0 - 2 * INSET)])  # fmt: skip
        heading = 2 * math.pi * angle
        arm = arm_joints(state, robot)
        offset = (
            _yaw_axes(heading)
            @ _yaw_axes(-float(base_pose(state, robot)[2]))
            @ (pinch_position(base_pose(state, robot), arm)[:2] - base_pose(state, robot)[:2])
        )
        goal = np.array([*(spot - offset), heading])
        if not _base_ok(goal[:2]):
            raise SkillFailure("Place: the base spot is inside the island or out of the room")
        return goal, heading, self.drive_route(state, goal, 1.0 + 0.9 * via, arm, 1.0, block)

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        robot = self.robot
        route = self.geometry(state, np.asarray(self.params))[2]

        def lower(s: ObjectCentricState) -> list[Segment]:
            p = pinch_position(base_pose(s, robot), arm_joints(s, robot))
            yaw = float(base_pose(s, robot)[2])
            return line_segments(s, robot, np.array([p[0], p[1], RELEASE_Z]), yaw, PITCH, 1.0)

        def back_up(s: ObjectCentricState) -> list[Segment]:
            p = pinch_position(base_pose(s, robot), arm_joints(s, robot))
            yaw = float(base_pose(s, robot)[2])
            return line_segments(s, robot, np.array([p[0], p[1], 0.12]), yaw, PITCH, 0.0,
                                 spacing=0.06)  # fmt: skip

        release = Segment(gripper=0.0, arm_tol=1.0, base_tol=1.0, min_steps=GRIP_STEPS)
        return [*route, lower, release, back_up]


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The SweepSimple3D planning model (any number of blocks, any of the three goal areas)."""
    objects: dict[str, Object] = env.objects  # type: ignore[attr-defined]
    robot = objects["robot"]
    blocks = tuple(sorted((o for n, o in objects.items() if n.startswith(BLOCK_PREFIX)),
                          key=lambda o: int(o.name[len(BLOCK_PREFIX):])))  # fmt: skip
    boxes = np.asarray(env.task.regions[GOAL_REGION].boxes)  # type: ignore[attr-defined]
    x0, y0, _, x1, y1, _ = (float(v) for v in boxes[0])
    ctx = SweepSimpleContext(env, robot, objects[WIPER], blocks, (x0, y0, x1, y1))
    goal_keys = {b: f"on({b.name}, {GOAL_REGION})" for b in blocks}

    HandEmpty = Predicate("HandEmpty", (ROBOT_TYPE,))
    Holding = Predicate("Holding", (ROBOT_TYPE, MOVABLE_TYPE))
    OnFloor = Predicate("OnFloor", (MOVABLE_TYPE,))
    InArea = Predicate("InArea", (MOVABLE_TYPE,))

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms: set[GroundAtom] = set()
        closed = state.get(robot, "pos_gripper") >= CLOSED
        if not closed:
            atoms.add(HandEmpty.ground([robot]))
        pinch = pinch_position(base_pose(state, robot), arm_joints(state, robot))
        on = env.goal_atoms(state)  # type: ignore[attr-defined]
        for b in blocks:
            pos = np.asarray(state[b][:3])
            if closed and pos[2] > 0.01 and np.linalg.norm(pos - pinch) < 0.04:
                atoms.add(Holding.ground([robot, b]))
            elif on[goal_keys[b]]:
                atoms.add(InArea.ground([b]))
            elif pos[2] < 0.05:
                atoms.add(OnFloor.ground([b]))
        return frozenset(atoms)

    r = Variable("?robot", ROBOT_TYPE)
    b = Variable("?block", MOVABLE_TYPE)
    pick = LiftedOperator(
        "Pick",
        (r, b),
        frozenset({HandEmpty.lift([r]), OnFloor.lift([b])}),
        frozenset({Holding.lift([r, b])}),
        frozenset({HandEmpty.lift([r]), OnFloor.lift([b])}),
    )
    place = LiftedOperator(
        "Place",
        (r, b),
        frozenset({Holding.lift([r, b])}),
        frozenset({HandEmpty.lift([r]), InArea.lift([b])}),
        frozenset({Holding.lift([r, b])}),
    )

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        del state
        return frozenset({HandEmpty.ground([robot])} | {InArea.ground([x]) for x in blocks})

    return PlanningModel(
        name="sweep_simple3d",
        env=env,
        types=(ROBOT_TYPE, MOVABLE_TYPE),
        predicates=(HandEmpty, Holding, OnFloor, InArea),
        skills=(Skill(pick, PickController, ctx), Skill(place, PlaceController, ctx)),
        goal_fn=goal,
        abstraction_fn=abstraction,
        objects_fn=lambda state: [robot, *blocks],
        max_skill_horizon=400,
        max_episode_steps=env.spec.max_episode_steps if env.spec is not None else None,
    )


__all__: Sequence[str] = ["PickController", "PlaceController", "create_model"]
