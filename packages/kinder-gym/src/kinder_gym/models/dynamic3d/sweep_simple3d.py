"""The SweepSimple3D planning model: take the upright wiper and pull the blocks into the goal area.

The scene (upstream kindergarden 0.2.5's): 2 cm cubes ``cube_0`` … lie on the kitchen floor
(x ∈ [1.25, 1.75], y ∈ [0.2, 0.7]; o50: x ∈ [1, 2], y ∈ [−1, 1]); the wiper stands upright on
its head (a 30 × 2 × 4 cm head, o50 40 cm, and a handle rising from its middle) just +y of them
(o50: at x ≈ 2.25, y ≈ −1.75); the goal area ``sweep_region`` is a floor box beside the kitchen
island's +y end (x ∈ [0.075, 0.925], y ∈ [0.95, 1.425] with upstream's 5 cm margin), or beside
its −y end or the cooking counter's end in the two other o50 tasks. The model reads the goal box
from the task, so every variant is handled.

Concepts:

* ``HandEmpty(robot)``: the fingers are open (closure below 0.2).
* ``Holding(robot, wiper)``: the fingers are closed with the pinch point at the wiper's head
  (within 13 cm of its middle in x, y and 7 cm of its bottom in z), and the wiper stands
  (tilted less than ~23°).
* ``Free(wiper)``: the wiper is not held.
* ``OnFloor(block)``: the block is not in the goal area (still to be moved).
* ``InArea(block)``: the env's own goal atom ``on(block, sweep_region)``, so the goal atoms
  (every block ``InArea``) imply the env's goal. Declared *monotone*, with ``OnFloor`` its
  negation: a sweep that brings a neighbour into the goal area too is accepted, and that
  block's own sweep is skipped.

Operators: ``PickWiper(?robot, ?wiper)`` (pre HandEmpty, Free; add Holding; delete HandEmpty,
Free) and ``Sweep(?robot, ?wiper, ?block)`` (pre Holding, OnFloor(block); add InArea(block);
delete OnFloor(block)).

Skills (segment following of :mod:`kinder_gym.models.dynamic3d.tidybot`):

* PickWiper: fold the arm, turn the base in place and drive it (straight, or along x and then
  along y) to stand 0.75 m from a sampled spot of the head 8–11 cm either side of the handle,
  facing it across the head (from one of the two sides); reach top-down 12 cm above the floor,
  drive 25 cm closer, come down and close the fingers across the 2 cm head 2.5 cm above the
  floor, lift the wiper 1 cm.
* Sweep: two pulls, first along y to a sampled y inside the goal box, then along x to a
  sampled x inside it. For each, the head is lifted 4 cm and the hand brought back to where it
  was from the base when the skill started; the base turns (by the head's skew in the fingers
  too, so that the head lies square across the pull) and drives so that the head comes down
  3.5 cm past the block, on the side away from its target, with the block 3 cm from the
  fingers along the head; the head is pressed onto the floor and the base backs away from the
  block at 2 cm per action in 20 cm strokes, pressing the head down again after each, until
  the block is at its target (the base at most 30 cm further than planned). Every pull's base
  poses and path are checked against the kitchen's fixtures (the chassis 23 cm clear, the
  head 8 cm plus its half length clear) before any simulation, and parameters are redrawn while
  one is blocked.

Findings that shaped the skills: a side grasp on the handle (45° pitch) let the wiper turn in
the fingers about their closing axis as soon as the head met the block (the pads resist that
turn by friction alone), so the head rode over it; the top-down grasp across the head takes
the pull on the pads' faces. Held beside the handle, the head turned in the fingers when the
block was at its middle (the block now sits next to the fingers). At the carrying speed
(5 cm per action) the head rode up over the block; the arm yields upward and backward to the
load while the base drives, so the head is pressed down again every 20 cm and the pull runs
until the block (not the base) is at its target. The arm's swing from its folded pose next to
the wiper knocked it over (the base now stands 25 cm further back while the arm reaches out),
and a base passing 23 cm from the 34 cm wiper with its chassis oblique knocked it over too
(the wiper keeps 30 cm). Pulls rather than pushes: the robot stands on the side the block
moves to, which in this scene is open floor (pushing from +x would put the chassis into the
cooking counter). Blocks are no obstacle to the base (its underside is 2 cm above the floor,
the cubes' top; a cube it touches is nudged at most).

Measured (BP, ``kinder bench run -a bilevel_planning --seeds 1000 --episodes 5 --executor
inline``, development seeds): o1 5 of 5 (mean 407 actions; the carrying model of the flat-wiper
scene also 5 of 5 on this scene); o5 0 of 5 (no plan within the 60 s budget: a block takes
about 330–500 actions, a pick about 70, and the planner simulates them all; the carrying model
found plans for 4 of 5 here, at about 300 actions a block); o50 (left side) 0 of 1.
Planner-free, six seeds (1000–1005): the sweep reached the goal on all six, one after a second
draw. The step limits of o5, o10 and o50 were set from the carrying skills' need (about 260
actions a block).

Imports kinder_garden3d (the ``[3d]`` extra).

Version notes:

* Fixtures and o50 (issue 18): the room's bounds became the fixtures' rectangles, so that the
  goal area past the cooking counter's end is reachable; the slide to a turning spot was added
  (beside the island the hand's arc crosses it); ``InArea`` became monotone.
* Upstream's scene (issue 32): the wiper stands upright and the cubes are 2 cm; the skills that
  carried one 1 cm block at a time in the fingers (the wiper only an obstacle) gave way to taking
  the wiper and sweeping with it, as the task is meant to be solved.
"""

from __future__ import annotations

import abc
import contextlib
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden3d.dynamic3d.geometry import quat_yaw
from kinder_garden3d.dynamic3d.object_types import MOVABLE_TYPE, ROBOT_TYPE
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.dynamic3d.tidybot import (
    DOWN,
    GRIP_STEPS,
    HOME,
    MAX_DELTA,
    READY,
    Dynamic3DController,
    Segment,
    SegmentSource,
    arm_joints,
    base_pose,
    drive_segment,
    gripper_quat,
    hand_predicates,
    hand_state,
    ik_near,
    line_segments,
    pinch_position,
    segment_rect_distance,
    top_down_yaw,
)
from kinder_gym.motion_planning import FloatArray, wrap_angle
from kinder_gym.operators import LiftedOperator
from kinder_gym.skills import Skill, SkillFailure

GOAL_REGION = "sweep_region"
WIPER = "wiper_0"
BLOCK_PREFIX = "cube_"
#: Largest base step (m, rad per action) while the wiper is held.
CARRY_SPEED = (0.05, 0.05)
#: Largest base step (m, rad per action) during a pull: at ``CARRY_SPEED`` the head hit the
#: block hard enough to ride up over it; planner-free on seeds 1000–1005, 3 cm per action (in
#: 25 cm strokes) brought 3 of 6 blocks in, 2 cm 6 of 6 (1.5 cm in 12 cm strokes: 5 of 6).
PULL_SPEED = (0.02, 0.05)
#: Actions the arm goes on pressing the head down once it stands on the floor.
PRESS_STEPS = 3
#: Length (m) of one stroke of a pull, after which the head is pressed down again (the arm
#: yields upward to the load while the base drives; without it the head rode up over the block
#: within about 30 cm).
STROKE = 0.2
#: Actions the base stands after a stroke while the hand, which lags behind it under the load,
#: catches up with the arm's pose from before the stroke.
CATCH_UP_STEPS = 3
#: Distance (m) the base may drive beyond a pull's planned end while the block is short of its
#: target (the hand lags behind the base under the load).
OVERDRIVE = 0.3
#: Parameter draws tried by the samplers before they return a blocked one.
SAMPLE_TRIES = 200
#: Horizontal distance (m) from the base centre to the pinch point when the hand closes on the
#: head.
STANDOFF = 0.5
#: Distance (m) the base stands further back while the arm swings out from its folded pose,
#: before it drives up to the wiper (a swing next to it knocked the wiper over).
BACKOFF = 0.25
#: Range (m) of the pinch point's distance from the head's middle, either side of the handle.
HEAD_SPOTS = (0.08, 0.11)
#: Height (m) of the pinch point when the fingers close across the 4 cm head, and of the hand
#: before it comes down to it.
HEAD_GRASP_Z, HEAD_ABOVE = 0.025, 0.12
#: Height (m) of the head's bottom while the base moves the wiper to a pull's start, and the
#: hand's target for it during a pull (5 mm into the floor: the head pressed onto it; at 5 mm
#: above it the head rode up over the block).
HEAD_LIFTED, HEAD_DOWN = 0.04, -0.005
#: Distance (m) between the head's middle plane and the block's centre at a pull's start: the
#: head's half thickness (1 cm), the cube's half size (1 cm) and 1.5 cm.
HEAD_GAP = 0.035
#: Distance (m) along the head between the block's centre and the pinch point at a pull's
#: start: the pads' half width (1.1 cm), the block's half size (1 cm) and 0.9 cm. The fingers
#: close on the head beside the handle, and a block pulled at the head's middle (9 cm from
#: them) turned the wiper in them.
BLOCK_FROM_FINGERS = 0.03
#: Largest sideways jitter (m) of the block from there.
LATERAL = 0.01
#: Inset (m) of a pull's target from the goal box's sides.
INSET = 0.04
#: The kitchen's fixtures as floor rectangles (xmin, ymin, xmax, ymax), from the lab2_kitchen
#: scene: the island, the cooking counter (its front at x = 2.245, less 5.5 cm for the drawer
#: handles) and the side counter with the corner unit (front at y = 2.25, less 5 cm). The scene
#: has no walls; the floor beyond the counters' ends is free, which the goal area beside the
#: cooking counter's end (x ∈ [2.245, 2.995], y ∈ [−1.375, −1.0]) needs.
FIXTURES = (
    (0.125, -1.0, 0.875, 1.0),
    (2.19, -1.0, 2.995, 2.25),
    (0.125, 2.3, 2.995, 3.0),
)
#: Radii (m) and directions of the spots tried for turning in place when the base cannot turn
#: where it stands (the hand's arc would cross a fixture).
TURN_SPOT_RADII = (0.1, 0.2, 0.3, 0.45, 0.6, 0.8)
TURN_SPOT_DIRECTIONS = 16
#: The turning spots' offsets from the base, nearest first.
TURN_SPOT_OFFSETS = np.array(
    [
        (r * math.cos(a), r * math.sin(a))
        for r in TURN_SPOT_RADII
        for a in (2 * math.pi * k / TURN_SPOT_DIRECTIONS for k in range(TURN_SPOT_DIRECTIONS))
    ]
)
#: Clearance (m) kept between the hand (the pinch point) and the island or the counters.
HAND_CLEARANCE = 0.08
#: Clearance (m) kept between the base centre and the island or the counters: the chassis' half
#: width (0.2 m) plus 3 cm. The base turns to its final heading before it drives.
PASS_CLEARANCE = 0.23
#: Clearance (m) kept between the base centre and the standing wiper's footprint: the chassis'
#: half diagonal (0.28 m) plus 2 cm, because a base passing 0.23 m from it with its heading
#: oblique knocked the 34 cm wiper over.
WIPER_CLEARANCE = 0.3
#: Largest tilt of the wiper (its quaternion's x and y parts, about 23 degrees) at which it
#: still counts as standing (and as held, when the hand is closed on its handle).
UPRIGHT_TILT = 0.2


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


def _fixture_gaps(points: FloatArray) -> FloatArray:
    """Distance (m) from each of ``points`` (one ``(x, y)`` or an ``(n, 2)`` array) to the
    nearest of the kitchen's fixtures."""
    pts = np.atleast_2d(points)
    gaps = np.full(len(pts), np.inf)
    for x0, y0, x1, y1 in FIXTURES:
        dx = np.maximum(np.maximum(x0 - pts[:, 0], pts[:, 0] - x1), 0.0)
        dy = np.maximum(np.maximum(y0 - pts[:, 1], pts[:, 1] - y1), 0.0)
        gaps = np.minimum(gaps, np.hypot(dx, dy))
    return gaps


def _clear(points: FloatArray, clearance: float) -> bool:
    """Whether discs of radius ``clearance`` centred at ``points`` are all clear of the
    fixtures; for a path (the points in order) that starts nearer than ``clearance``, whether
    it never comes nearer than where it starts (a base or hand may always back away)."""
    gaps = _fixture_gaps(points)
    return bool(gaps.min() >= min(clearance, float(gaps[0]) - 1e-9))


def _base_ok(p: FloatArray) -> bool:
    """Whether the chassis centred at ``p`` keeps ``PASS_CLEARANCE`` from the fixtures."""
    return bool(_fixture_gaps(p)[0] >= PASS_CLEARANCE)


def _wiper_half(state: ObjectCentricState, wiper: Object) -> FloatArray:
    """Half size (m) of the wiper's footprint (its bounding box), plus 1 cm."""
    return np.array([state.get(wiper, "bb_x"), state.get(wiper, "bb_y")]) / 2.0 + 0.01


def _path_ok(
    ctx: SweepSimpleContext,
    state: ObjectCentricState,
    a: FloatArray,
    b: FloatArray,
    hand: FloatArray,
    held: bool,
) -> bool:
    """Whether the base can drive straight from ``a`` to ``b``: the chassis clear of the fixtures
    (sampled every 5 cm) and, unless the wiper is ``held``, of the wiper, and the hand (at
    ``hand`` from the base centre) clear of the fixtures (by the head's half length more when
    the wiper is held). Blocks are no obstacle. A path that starts nearer the wiper than the
    clearance may not come any nearer."""
    n = max(2, math.ceil(float(np.linalg.norm(b - a)) / 0.05) + 1)
    points = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
    if not (
        _clear(points, PASS_CLEARANCE) and _clear(points + hand, _hand_clearance(ctx, state, held))
    ):
        return False
    if held:
        return True
    wf = state[ctx.wiper]
    centre = np.asarray(wf[:2], dtype=np.float64)
    axes = _yaw_axes(quat_yaw(np.asarray(wf[3:7])))
    half = _wiper_half(state, ctx.wiper)
    # A base that stands closer than that (the wiper was pushed toward it) may still drive away.
    start = segment_rect_distance(a, a, centre, axes, half) - 1e-9
    return segment_rect_distance(a, b, centre, axes, half) >= min(WIPER_CLEARANCE, start)


def _hand_clearance(ctx: SweepSimpleContext, state: ObjectCentricState, held: bool) -> float:
    """The hand's clearance from the fixtures: more by the head's half length with the wiper."""
    return HAND_CLEARANCE + (state.get(ctx.wiper, "bb_x") / 2.0 if held else 0.0)


def _rotated(offset: FloatArray, yaw: FloatArray | float) -> FloatArray:
    """``offset`` (the hand from the base centre at heading 0) turned by ``yaw`` (one angle, or
    an array of them: one row each)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([c * offset[0] - s * offset[1], s * offset[0] + c * offset[1]], axis=-1)


def _turn_ok(
    p: FloatArray, yaw: float, heading: float, offset: FloatArray, clearance: float = HAND_CLEARANCE
) -> bool:
    """Whether the hand (``offset`` from the base centre at heading 0) stays ``clearance`` clear
    of the fixtures while the base at ``p`` turns in place from ``yaw`` to ``heading``, checked
    at 9 points of the arc."""
    angles = yaw + np.linspace(0.0, 1.0, 9) * wrap_angle(heading - yaw)
    return _clear(p + _rotated(offset, angles), clearance)


def _turn_spots(p: FloatArray) -> FloatArray:
    """Spots around ``p`` to turn at, nearest first, where the chassis keeps ``PASS_CLEARANCE``
    from the fixtures (as :func:`_base_ok`, for all spots at once)."""
    spots: FloatArray = p + TURN_SPOT_OFFSETS
    clear: FloatArray = spots[_fixture_gaps(spots) >= PASS_CLEARANCE]
    return clear


def _route(
    ctx: SweepSimpleContext,
    state: ObjectCentricState,
    start: FloatArray,
    goal: FloatArray,
    via_x: float,
    hand: FloatArray,
    held: bool,
) -> list[FloatArray]:
    """Base waypoints ``(x, y)`` from ``start`` to ``goal``: straight when clear, else along x to
    ``via_x``, along y to the goal's y, then to the goal; SkillFailure when neither is clear."""
    if _path_ok(ctx, state, start, goal, hand, held):
        return [goal]
    a = np.array([via_x, start[1]])
    b = np.array([via_x, goal[1]])
    legs = [(start, a), (a, b), (b, goal)]
    if all(_path_ok(ctx, state, p, q, hand, held) for p, q in legs):
        return [a, b, goal]
    raise SkillFailure("the base has no clear path to its goal")


class _Controller(Dynamic3DController):
    """Shared: routes, and parameter samples whose poses and routes are clear."""

    #: Whether the wiper is in the hand while this skill drives the base.
    held = False

    @abc.abstractmethod
    def geometry(self, state: ObjectCentricState, params: FloatArray) -> list[SegmentSource]:
        """The first drive's segments for ``params`` (SkillFailure: a pose or route is blocked)."""

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Uniform, redrawn (up to ``SAMPLE_TRIES`` times) while a pose or a route is blocked:
        those checks are geometric and cheap, simulation is not."""
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
    ) -> list[SegmentSource]:
        """Turn in place to the goal heading, then drive the route's legs. Where the hand's arc
        would hit a fixture or the route is blocked, first slide the base, heading unchanged,
        to the nearest spot from which both are clear."""
        ctx: SweepSimpleContext = self.context
        b0 = base_pose(state, self.robot)
        heading = float(goal[2])
        offset = _hand_offset(b0, arm)
        hand = _rotated(offset, heading)
        clearance = _hand_clearance(ctx, state, self.held)
        segs: list[SegmentSource] = []
        start, points = b0[:2], None
        if _turn_ok(start, float(b0[2]), heading, offset, clearance):
            with contextlib.suppress(SkillFailure):
                points = _route(ctx, state, start, goal[:2], via_x, hand, self.held)
        if points is None:
            now = _rotated(offset, float(b0[2]))
            for spot in _turn_spots(start):
                if not (_turn_ok(spot, float(b0[2]), heading, offset, clearance)
                        and _path_ok(ctx, state, start, spot, now, self.held)):  # fmt: skip
                    continue
                try:
                    points = _route(ctx, state, spot, goal[:2], via_x, hand, self.held)
                except SkillFailure:
                    continue
                start = spot
                segs.append(self._slide(np.array([spot[0], spot[1], b0[2]]), arm, gripper))
                break
            if points is None:
                raise SkillFailure("no spot near the base to turn at and drive from")
        segs.append(
            Segment(
                base=(float(start[0]), float(start[1]), heading),
                arm=tuple(float(v) for v in arm),
                gripper=gripper,
                arm_tol=0.05,
                base_tol=0.03,
                max_steps=120,
                base_speed=CARRY_SPEED if self.held else (MAX_DELTA, MAX_DELTA),
            )
        )
        for k, p in enumerate(points):
            segs.append(self._slide(np.array([p[0], p[1], heading]), arm, gripper,
                                    0.01 if k == len(points) - 1 else 0.04))  # fmt: skip
        return segs

    def _slide(
        self, pose: FloatArray, arm: FloatArray, gripper: float, tol: float = 0.04
    ) -> SegmentSource:
        """A drive of the base to ``pose`` with the arm held, planned from the state it starts
        in (slower, with more steps, while the wiper is held)."""

        def leg(s: ObjectCentricState) -> list[Segment]:
            self.state = s
            seg = self.drive(pose, arm, gripper, tol)
            if self.held:
                seg = replace(seg, base_speed=CARRY_SPEED, max_steps=2 * seg.max_steps)
            return [seg]

        return leg


def _hand_offset(base: FloatArray, arm: FloatArray) -> FloatArray:
    """The pinch point's ``(x, y)`` from the base centre, in the base's frame (heading 0)."""
    return _rotated(pinch_position(base, arm)[:2] - base[:2], -float(base[2]))


def _head_yaw(state: ObjectCentricState, robot: Object, wiper: Object) -> float:
    """The held wiper's head direction relative to the base's heading (rad)."""
    return wrap_angle(quat_yaw(np.asarray(state[wiper][3:7])) - float(base_pose(state, robot)[2]))


def _head_offset(state: ObjectCentricState, robot: Object, wiper: Object) -> FloatArray:
    """The held wiper's middle ``(x, y)`` from the base centre, in the base's frame."""
    b = base_pose(state, robot)
    middle = np.array([state.get(wiper, "x"), state.get(wiper, "y")])
    return _rotated(middle - b[:2], -float(b[2]))


class PickWiperController(_Controller):
    """Close the hand top-down on the upright wiper's head, beside the handle, and lift the
    wiper 1 cm. Objects: ``(robot, wiper)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(side, spot, via): the base faces the wiper across its head from the side nearer its "
        "heading (side < 0.5) or the other; the fingers close across the head 8 to 11 cm from "
        "its middle, on the side of 2·spot − 1 (clear of the handle and of a pulled block); "
        "when the straight path is blocked the base drives along x to x = 1.0 + 0.9·via, then "
        "along y, then to the goal."
    )

    hand_must_be = "open"

    def _grasp(self, state: ObjectCentricState, params: FloatArray) -> tuple[FloatArray, float]:
        """The pinch point ``(x, y)`` on the head and the head's direction (rad)."""
        wiper = self.objects[1]
        yaw = quat_yaw(np.asarray(state[wiper][3:7]))
        t = 2.0 * float(params[1]) - 1.0
        spot = math.copysign(HEAD_SPOTS[0] + (HEAD_SPOTS[1] - HEAD_SPOTS[0]) * abs(t), t)
        c = np.array([state.get(wiper, "x"), state.get(wiper, "y")])
        return c + spot * np.array([math.cos(yaw), math.sin(yaw)]), yaw

    def _pose(self, state: ObjectCentricState, params: FloatArray) -> FloatArray:
        """The base pose ``(x, y, heading)`` ``BACKOFF`` further than ``STANDOFF`` from the
        pinch point, facing it across the head, for ``params``."""
        point, yaw = self._grasp(state, params)
        now = float(base_pose(state, self.robot)[2])
        sides = sorted((wrap_angle(yaw + k * math.pi / 2) for k in (1, -1)),
                       key=lambda h: abs(wrap_angle(h - now)))  # fmt: skip
        heading = sides[0 if params[0] < 0.5 else 1]
        away = STANDOFF + BACKOFF
        return np.array([*(point - away * np.array([math.cos(heading), math.sin(heading)])),
                         heading])  # fmt: skip

    def geometry(self, state: ObjectCentricState, params: FloatArray) -> list[SegmentSource]:
        goal = self._pose(state, params)
        if not _base_ok(goal[:2]):
            raise SkillFailure("PickWiper: the standoff is too close to a fixture")
        return self.drive_route(state, goal, 1.0 + 0.9 * float(params[2]), HOME, 0.0)

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        robot = self.robot
        params = np.asarray(self.params)
        route = self.geometry(state, params)
        heading = float(self._pose(state, params)[2])
        direction = np.array([math.cos(heading), math.sin(heading)])
        point, yaw = self._grasp(state, params)
        # The fingers close across the head: the gripper's heading along it, the nearer way.
        grip_yaw = min((wrap_angle(yaw + k * math.pi) for k in (0, 1)),
                       key=lambda g: abs(wrap_angle(g - heading)))  # fmt: skip

        def reach(s: ObjectCentricState) -> list[Segment]:
            above = np.array([*(point - BACKOFF * direction), HEAD_ABOVE])
            q = ik_near(above, gripper_quat(grip_yaw, DOWN), base_pose(s, robot), READY)
            return [Segment(arm=tuple(q), arm_tol=0.01, max_steps=80)]

        def close_in(s: ObjectCentricState) -> list[Segment]:
            goal = np.array([*(base_pose(s, robot)[:2] + BACKOFF * direction), heading])
            return [drive_segment(s, robot, goal, arm_joints(s, robot), 0.0, 0.01)]

        def descend(s: ObjectCentricState) -> list[Segment]:
            target = np.array([*point, HEAD_GRASP_Z])
            return line_segments(s, robot, target, grip_yaw, DOWN, 0.0, spacing=0.03)

        def lift(s: ObjectCentricState) -> list[Segment]:
            p = pinch_position(base_pose(s, robot), arm_joints(s, robot))
            return line_segments(s, robot, p + np.array([0.0, 0.0, 0.01]), grip_yaw, DOWN, 1.0)

        close = Segment(gripper=1.0, arm_tol=1.0, base_tol=1.0, min_steps=GRIP_STEPS)
        plan: list[SegmentSource] = []
        if np.abs(arm_joints(state, robot) - HOME).max() > 0.05:
            plan.append(Segment(arm=tuple(HOME), arm_tol=0.05, max_steps=80))
        return [*plan, *route, reach, close_in, descend, close, lift]


class SweepController(_Controller):
    """Pull a block into the goal area with the held wiper, along y and then along x. Objects:
    ``(robot, wiper, block)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(lateral, v, u): the block sits (2·lateral − 1)·1 cm from 4.5 cm short of the "
        "fingers along the head; it is pulled along y to fraction v and then along x to "
        "fraction u of the goal box inset by 4 cm."
    )

    hand_must_be = "closed"
    held = True

    def _goal_spot(self, params: FloatArray) -> tuple[float, float, float]:
        """The block's sideways offset on the head and its target ``(x, y)`` for ``params``."""
        x0, y0, x1, y1 = self.context.box
        lateral = (2.0 * float(params[0]) - 1.0) * LATERAL
        ty = y0 + INSET + float(params[1]) * (y1 - y0 - 2 * INSET)
        tx = x0 + INSET + float(params[2]) * (x1 - x0 - 2 * INSET)
        return lateral, tx, ty

    def _pull(
        self,
        block_xy: FloatArray,
        target: float,
        axis: int,
        lateral: float,
        offset: FloatArray,
        grip: FloatArray,
        head_yaw: float,
    ) -> tuple[FloatArray, FloatArray]:
        """Start and end base poses ``(x, y, heading)`` of a pull of a block at ``block_xy``
        along ``axis`` (0: x, 1: y) to ``target``: the base on the target's side facing the
        block, the head ``HEAD_GAP`` past it; ``offset`` and ``grip`` are the head's middle and
        the pinch point from the base centre (heading 0), ``head_yaw`` the head's direction
        relative to the base's heading (about ±90°: the base turns by its difference, so that
        the head lies square across the pull)."""
        sign = 1.0 if target >= block_xy[axis] else -1.0
        facing = np.zeros(2)
        facing[axis] = -sign
        skew = head_yaw % math.pi - math.pi / 2
        heading = math.atan2(float(facing[1]), float(facing[0])) - skew
        head = np.array(block_xy, dtype=np.float64)
        head[axis] -= sign * HEAD_GAP
        head[1 - axis] += lateral
        # The block toward the fingers (BLOCK_FROM_FINGERS from them along the head): the nearer
        # the grasp, the less the push turns the wiper in the fingers.
        side = float(_rotated(grip - offset, heading)[1 - axis])
        head[1 - axis] -= math.copysign(max(abs(side) - BLOCK_FROM_FINGERS, 0.0), side)
        base = head - _rotated(offset, heading)
        end = base.copy()
        end[axis] += target - block_xy[axis]
        return np.array([*base, heading]), np.array([*end, heading])

    def geometry(self, state: ObjectCentricState, params: FloatArray) -> list[SegmentSource]:
        ctx: SweepSimpleContext = self.context
        block = self.objects[2]
        lateral, tx, ty = self._goal_spot(params)
        offset = _head_offset(state, self.robot, self.objects[1])
        grip = _hand_offset(base_pose(state, self.robot), arm_joints(state, self.robot))
        c = np.array([state.get(block, "x"), state.get(block, "y")])
        head_yaw = _head_yaw(state, self.robot, self.objects[1])
        start1, end1 = self._pull(c, ty, 1, lateral, offset, grip, head_yaw)
        start2, end2 = self._pull(np.array([c[0], ty]), tx, 0, lateral, offset, grip, head_yaw)
        for pose in (start1, end1, start2, end2):
            if not _base_ok(pose[:2]):
                raise SkillFailure("Sweep: a pull would take the base too close to a fixture")
        for a, b in ((start1, end1), (start2, end2)):
            hand = _rotated(offset, float(a[2]))
            if not _path_ok(ctx, state, a[:2], b[:2], hand, True):
                raise SkillFailure("Sweep: a pull would take the wiper into a fixture")
        return self.drive_route(state, start1, float(start1[0]), arm_joints(state, self.robot), 1.0)

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        robot, wiper, block = self.objects
        params = np.asarray(self.params)
        lateral, tx, ty = self._goal_spot(params)
        self.geometry(state, params)  # SkillFailure before any step when a pull is blocked

        def head_at(height: float) -> SegmentSource:
            def move(s: ObjectCentricState) -> list[Segment]:
                b, q = base_pose(s, robot), arm_joints(s, robot)
                p = pinch_position(b, q)
                grip_above_bottom = p[2] - s.get(wiper, "z")
                target = np.array([p[0], p[1], height + grip_above_bottom])
                if height >= 0.0:
                    return line_segments(s, robot, target, top_down_yaw(b, q), DOWN, 1.0,
                                         spacing=0.03)  # fmt: skip
                # Pressed onto the floor, the head stops the hand short of its target: the arm
                # goes on pushing toward it for PRESS_STEPS actions.
                try:
                    segs = line_segments(s, robot, target, top_down_yaw(b, q), DOWN, 1.0,
                                         spacing=0.03, final_tol=0.02)  # fmt: skip
                except SkillFailure:
                    return []  # the arm stretched out behind the base: pull on unpressed
                press = Segment(arm=segs[-1].arm, gripper=1.0, arm_tol=1.0, base_tol=1.0,
                                min_steps=PRESS_STEPS)  # fmt: skip
                return [*segs, press]

            return move

        nominal = _hand_offset(base_pose(state, robot), arm_joints(state, robot))

        def recentre(s: ObjectCentricState) -> list[Segment]:
            """Bring the lifted hand back to where it was from the base when the skill started
            (a pull leaves the arm stretched out behind the base)."""
            b, q = base_pose(s, robot), arm_joints(s, robot)
            z = float(pinch_position(b, q)[2])
            point = np.array([*(b[:2] + _rotated(nominal, float(b[2]))), z])
            return line_segments(s, robot, point, top_down_yaw(b, q), DOWN, 1.0, spacing=0.03)

        def pull(axis: int, target: float) -> list[SegmentSource]:
            def to_start(s: ObjectCentricState) -> list[SegmentSource]:
                b, q = base_pose(s, robot), arm_joints(s, robot)
                c = np.array([s.get(block, "x"), s.get(block, "y")])
                head, grip = _head_offset(s, robot, wiper), _hand_offset(b, q)
                yaw = _head_yaw(s, robot, wiper)
                start = self._pull(c, target, axis, lateral, head, grip, yaw)[0]
                return self.drive_route(s, start, float(start[0]), q, 1.0)

            def drag(s: ObjectCentricState) -> list[SegmentSource]:
                b = base_pose(s, robot)
                c = np.array([s.get(block, "x"), s.get(block, "y")])
                limit = float(b[axis] + target - c[axis])
                limit += math.copysign(OVERDRIVE, target - c[axis])
                return [stroke(limit)]

            def stroke(limit: float) -> SegmentSource:
                """Drive at most ``STROKE`` further toward the block's target (the base no
                further than ``limit``), press the head down again (the arm yields upward to
                the load while the base drives), and go on until the block is there."""

                def go(s: ObjectCentricState) -> list[SegmentSource]:
                    b, q = base_pose(s, robot), arm_joints(s, robot)
                    left = target - s.get(block, "xy"[axis])
                    room = limit - float(b[axis])
                    if abs(left) < 0.01 or room * left <= 0.0 or abs(room) < 0.01:
                        return []
                    step = b.copy()
                    step[axis] += math.copysign(min(abs(left), abs(room), STROKE), left)
                    seg = drive_segment(s, robot, step, q, 1.0, 0.01, PULL_SPEED)
                    catch_up = Segment(arm=tuple(q), gripper=1.0, arm_tol=1.0, base_tol=1.0,
                                       min_steps=CATCH_UP_STEPS)  # fmt: skip
                    return [replace(seg, max_steps=seg.max_steps + 20), catch_up,
                            head_at(HEAD_DOWN), stroke(limit)]  # fmt: skip

                return go

            return [head_at(HEAD_LIFTED), recentre, to_start, head_at(HEAD_DOWN), drag]

        return [*pull(1, ty), *pull(0, tx), head_at(HEAD_LIFTED), recentre]


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The SweepSimple3D planning model (any number of blocks, any of the three goal areas)."""
    objects: dict[str, Object] = env.objects  # type: ignore[attr-defined]
    robot, wiper = objects["robot"], objects[WIPER]
    blocks = tuple(sorted((o for n, o in objects.items() if n.startswith(BLOCK_PREFIX)),
                          key=lambda o: int(o.name[len(BLOCK_PREFIX):])))  # fmt: skip
    boxes = np.asarray(env.task.regions[GOAL_REGION].boxes)  # type: ignore[attr-defined]
    x0, y0, _, x1, y1, _ = (float(v) for v in boxes[0])
    ctx = SweepSimpleContext(env, robot, wiper, blocks, (x0, y0, x1, y1))
    goal_keys = {b: f"on({b.name}, {GOAL_REGION})" for b in blocks}

    HandEmpty, Holding = hand_predicates()
    Free = Predicate("Free", (MOVABLE_TYPE,))
    OnFloor = Predicate("OnFloor", (MOVABLE_TYPE,))
    InArea = Predicate("InArea", (MOVABLE_TYPE,))

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms, closed, pinch = hand_state(state, robot, HandEmpty)
        w = np.asarray(state[wiper][:3], dtype=np.float64)
        upright = max(abs(state.get(wiper, "qx")), abs(state.get(wiper, "qy"))) < UPRIGHT_TILT
        reach = HEAD_SPOTS[1] + 0.03
        near = float(np.hypot(*(pinch[:2] - w[:2]))) < reach and w[2] < pinch[2] < w[2] + 0.07
        held = closed and upright and near
        atoms.add(Holding.ground([robot, wiper]) if held else Free.ground([wiper]))
        on = env.goal_atoms(state)  # type: ignore[attr-defined]
        for b in blocks:
            atoms.add((InArea if on[goal_keys[b]] else OnFloor).ground([b]))
        return frozenset(atoms)

    r = Variable("?robot", ROBOT_TYPE)
    w_ = Variable("?wiper", MOVABLE_TYPE)
    b_ = Variable("?block", MOVABLE_TYPE)
    pick = LiftedOperator(
        "PickWiper",
        (r, w_),
        frozenset({HandEmpty.lift([r]), Free.lift([w_])}),
        frozenset({Holding.lift([r, w_])}),
        frozenset({HandEmpty.lift([r]), Free.lift([w_])}),
    )
    sweep = LiftedOperator(
        "Sweep",
        (r, w_, b_),
        frozenset({Holding.lift([r, w_]), OnFloor.lift([b_])}),
        frozenset({InArea.lift([b_])}),
        frozenset({OnFloor.lift([b_])}),
    )

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        del state
        return frozenset(InArea.ground([x]) for x in blocks)

    return PlanningModel(
        name="sweep_simple3d",
        env=env,
        types=(ROBOT_TYPE, MOVABLE_TYPE),
        predicates=(HandEmpty, Holding, Free, OnFloor, InArea),
        skills=(Skill(pick, PickWiperController, ctx), Skill(sweep, SweepController, ctx)),
        goal_fn=goal,
        abstraction_fn=abstraction,
        objects_fn=lambda state: [robot, wiper, *blocks],
        max_skill_horizon=800,
        max_episode_steps=env.spec.max_episode_steps if env.spec is not None else None,
        # A sweep may bring a neighbour into the goal area too; that block's sweep is skipped.
        monotone_predicates=frozenset({"InArea"}),
        monotone_negations={"InArea": "OnFloor"},
    )


__all__: Sequence[str] = ["PickWiperController", "SweepController", "create_model"]
