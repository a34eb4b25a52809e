"""The SweepSimple3D planning model: carry the 1 cm blocks on the kitchen floor into the goal area.

The scene (every variant): blocks (1 cm cubes ``cube_0`` …) lie on the floor in
x ∈ [1.25, 1.75], y ∈ [0.2, 0.7]; the wiper (a T, 30 cm head) lies on the floor just +y of
them; the goal area ``sweep_region`` is a floor box beside the kitchen island (left side,
x ∈ [0.125, 0.875], y ∈ [1.0, 1.375]), or beside the island's other end or the counter in the
two other o50 tasks. The model reads the goal box from the task, so every variant is handled.

Concepts:

* ``HandEmpty(robot)``: the fingers are open (closure below 0.2).
* ``Holding(robot, block)``: the fingers are closed and the block is the lifted one nearest the
  pinch point, within 4 cm.
* ``OnFloor(block)``: neither held nor in the goal area (still to be moved; this includes a
  neighbour the fingers closed on together with the held block).
* ``InArea(block)``: the env's own goal atom ``on(block, sweep_region)``, so the goal atoms
  (every block ``InArea``, and ``HandEmpty``) imply the env's goal. Declared *monotone*, with
  ``OnFloor`` its negation: a place that lets a carried neighbour down in the goal area too is
  accepted, and that block's own pick and place are skipped.

Operators: ``Pick(?robot, ?block)`` (pre HandEmpty, OnFloor; add Holding; delete HandEmpty,
OnFloor) and ``Place(?robot, ?block)`` (pre Holding; add HandEmpty, InArea; delete Holding).

Skills (segment following of :mod:`kinder_gym.models.dynamic3d.tidybot`; the floor grasp of
:mod:`kinder_gym.models.dynamic3d.shelf3d` with this family's geometry):

* Pick: fold the arm, turn the base in place to a sampled heading and drive it (straight, or
  along x to a sampled ``via`` x and then along y) to 0.50–0.60 m short of the block facing it
  (rejected when the chassis would come within 23 cm of the kitchen's fixtures or the wiper, or
  the hand within 8 cm of a fixture), reach above the block pitched 45° down, descend, close,
  lift the block to 15 cm. Where the hand's arc would hit a fixture while turning (beside the
  island after a place) or the route from where the base stands is blocked, the base first
  slides, heading unchanged, to the nearest spot (0.1–0.8 m away) from which both are clear.
* Place: with the arm held as it is, drive the base so that the pinch point is above a sampled
  spot of the goal area (the base facing the spot along a sampled heading, same rejections and
  slide), lower the block to 2.5 cm, open, back the hand up.

Blocks are no obstacle to the base: its collision box is 2 cm above the floor and the 1 cm blocks
pass under it (an earlier version kept the base's path 5 cm from every block, which with 50
blocks left almost no route, so o50's measurement ran for hours without finishing).

Deviation from upstream (stated plainly): upstream's task is solved by sweeping with the wiper.
This model carries the blocks one by one instead, because the wiper sweeps of
:mod:`kinder_gym.models.dynamic3d.sweep_into_drawer3d` push objects ~20 cm over a table edge,
whereas here every block must travel ~1.3 m across the floor around the island's end, a
closed-loop pushing skill that was not built in the time this model had. The wiper is only an
obstacle. Consequence: a pick and a place take about 150–300 actions (planner-free: o5
1,399–1,555 actions, o10 2,671–2,998, o50 12,961–14,057 on one seed of each of its three
tasks), more than the 1000 steps every Dynamic3D id had, so o5, o10 and o50 have their own
limits, 2500, 4500 and 19,500–21,500 (``benchmarks/results/step_limits.md``: 1.5 × the most
actions the skills took, rounded up to 500; upstream registers no limit). BP results are in
``benchmarks/results/bilevel_planning.md``; o50's ~13,000-step plans cannot be simulated within
the planner's 60 s budget (the measurement took 11–15 minutes per episode), so a wiper sweep
that moves many blocks per pass is what would let a planner solve o50.

Findings that shaped the skills: carried at the env's full base speed (0.1 m, 0.1 rad per
action) the 1 cm block was flung out of the fingers on most carries, hence ``CARRY_SPEED``;
the straight drive from the robot's start to the blocks crosses the wiper, and the gaps beside
it (about 0.5 m) only pass a chassis turned to its final heading first; an arm held out while
the base drove along the cooking counter knocked the block out on the counter, hence the hand
clearance checked along every route. Pick and Place draw their parameters again (up to 200
times, geometry only) while the standoff or the route is blocked, because the planner's three
samples per step were otherwise mostly blocked routes.

Imports kinder_garden3d (the ``[3d]`` extra).

Version notes:

* Fixtures and o50 (issue 18): the room's bounds (x below the cooking counter's
  front everywhere, y below the side counter's) became the fixtures' rectangles, because the
  goal area of the "right side of the kitchen counter" task lies past the counter's end, beyond
  the old x bound (no place could reach it); the blocks stopped being obstacles to the base;
  the slide to a turning spot was added (after the first place, every pick was blocked: the
  hand's arc crossed the island); ``Holding`` became the nearest lifted block and ``InArea``
  monotone, because with 50 blocks the fingers often close on a neighbour too.
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
    GRIP_STEPS,
    HOME,
    MAX_DELTA,
    PITCH,
    READY,
    Dynamic3DController,
    Segment,
    SegmentSource,
    arm_joints,
    base_pose,
    gripper_quat,
    hand_predicates,
    hand_state,
    ik_near,
    line_segments,
    pick_operator,
    pinch_position,
    place_operator,
    segment_rect_distance,
)
from kinder_gym.motion_planning import FloatArray, wrap_angle
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
#: where it stands (beside the island after a place, the hand's arc crosses it).
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


def _path_ok(
    ctx: SweepSimpleContext,
    state: ObjectCentricState,
    a: FloatArray,
    b: FloatArray,
    hand: FloatArray,
) -> bool:
    """Whether the base can drive straight from ``a`` to ``b``: the chassis clear of the fixtures
    (sampled every 5 cm) and of the wiper, and the hand (at ``hand`` from the base centre) clear
    of the fixtures. Blocks are no obstacle: the chassis' collision box is 2 cm above the floor,
    and the 1 cm blocks pass under it. A path that starts nearer the wiper than the clearance
    may not come any nearer."""
    n = max(2, math.ceil(float(np.linalg.norm(b - a)) / 0.05) + 1)
    points = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
    if not (_clear(points, PASS_CLEARANCE) and _clear(points + hand, HAND_CLEARANCE)):
        return False
    wf = state[ctx.wiper]
    centre = np.asarray(wf[:2], dtype=np.float64)
    axes = _yaw_axes(quat_yaw(np.asarray(wf[3:7])))
    # A base that stands closer than that (the wiper was pushed toward it) may still drive away.
    start = segment_rect_distance(a, a, centre, axes, WIPER_HALF) - 1e-9
    return segment_rect_distance(a, b, centre, axes, WIPER_HALF) >= min(PASS_CLEARANCE, start)


def _rotated(offset: FloatArray, yaw: FloatArray | float) -> FloatArray:
    """``offset`` (the hand from the base centre at heading 0) turned by ``yaw`` (one angle, or
    an array of them: one row each)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([c * offset[0] - s * offset[1], s * offset[0] + c * offset[1]], axis=-1)


def _turn_ok(p: FloatArray, yaw: float, heading: float, offset: FloatArray) -> bool:
    """Whether the hand (``offset`` from the base centre at heading 0) stays clear of the
    fixtures while the base at ``p`` turns in place from ``yaw`` to ``heading``, checked at 9
    points of the arc."""
    angles = yaw + np.linspace(0.0, 1.0, 9) * wrap_angle(heading - yaw)
    return _clear(p + _rotated(offset, angles), HAND_CLEARANCE)


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
) -> list[FloatArray]:
    """Base waypoints ``(x, y)`` from ``start`` to ``goal``: straight when clear, else along x to
    ``via_x``, along y to the goal's y, then to the goal; SkillFailure when neither is clear."""
    if _path_ok(ctx, state, start, goal, hand):
        return [goal]
    a = np.array([via_x, start[1]])
    b = np.array([via_x, goal[1]])
    legs = [(start, a), (a, b), (b, goal)]
    if all(_path_ok(ctx, state, p, q, hand) for p, q in legs):
        return [a, b, goal]
    raise SkillFailure("the base has no clear path to its goal")


class _Controller(Dynamic3DController):
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
    ) -> list[SegmentSource]:
        """Turn in place to the goal heading, then drive the route's legs. Where the hand's arc
        would hit a fixture (beside the island after a place) or the route is blocked, first
        slide the base, heading unchanged, to the nearest spot from which both are clear."""
        ctx: SweepSimpleContext = self.context
        b0 = base_pose(state, self.robot)
        heading = float(goal[2])
        offset = pinch_position(np.zeros(3), arm)[:2]  # the hand, base at the origin facing +x
        hand = _rotated(offset, heading)
        segs: list[SegmentSource] = []
        start, points = b0[:2], None
        if _turn_ok(start, float(b0[2]), heading, offset):
            with contextlib.suppress(SkillFailure):
                points = _route(ctx, state, start, goal[:2], via_x, hand)
        if points is None:
            now = _rotated(offset, float(b0[2]))
            for spot in _turn_spots(start):
                if not (_turn_ok(spot, float(b0[2]), heading, offset)
                        and _path_ok(ctx, state, start, spot, now)):  # fmt: skip
                    continue
                try:
                    points = _route(ctx, state, spot, goal[:2], via_x, hand)
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
                base_speed=CARRY_SPEED if gripper > 0.5 else (MAX_DELTA, MAX_DELTA),
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
        in (slower, with more steps, while carrying)."""

        def leg(s: ObjectCentricState) -> list[Segment]:
            self.state = s
            seg = self.drive(pose, arm, gripper, tol)
            if gripper > 0.5:  # carrying: slower, and more steps for it
                seg = replace(seg, base_speed=CARRY_SPEED, max_steps=2 * seg.max_steps)
            return [seg]

        return leg


class PickController(_Controller):
    """Pick a block off the floor. Objects: ``(robot, block)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(dist, angle, via): the base stops 0.50 + 0.10·dist metres short of the block, facing "
        "it along the block face nearest to the heading 2π·angle (world frame); when the straight "
        "path is blocked it drives along x to x = 1.0 + 0.9·via, then along y, then to the goal."
    )

    hand_must_be = "open"

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
        yaw = quat_yaw(np.asarray(state[block][3:7]))
        k = round((2 * math.pi * float(params[1]) - yaw) / (math.pi / 2))
        heading = yaw + k * math.pi / 2
        direction = np.array([math.cos(heading), math.sin(heading)])
        goal = np.array([*(c - dist * direction), heading])
        if not _base_ok(goal[:2]):
            raise SkillFailure("Pick: the standoff is too close to a fixture")
        via = 1.0 + 0.9 * float(params[2])
        return goal, heading, self.drive_route(state, goal, via, HOME, 0.0)

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

    hand_must_be = "closed"

    def geometry(
        self, state: ObjectCentricState, params: FloatArray
    ) -> tuple[FloatArray, float, list[SegmentSource]]:
        """As :meth:`PickController.geometry`."""
        ctx: SweepSimpleContext = self.context
        robot = self.objects[0]
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
            raise SkillFailure("Place: the base spot is too close to a fixture")
        return goal, heading, self.drive_route(state, goal, 1.0 + 0.9 * via, arm, 1.0)

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

    HandEmpty, Holding = hand_predicates()
    OnFloor = Predicate("OnFloor", (MOVABLE_TYPE,))
    InArea = Predicate("InArea", (MOVABLE_TYPE,))

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms, closed, pinch = hand_state(state, robot, HandEmpty)
        on = env.goal_atoms(state)  # type: ignore[attr-defined]
        held: Object | None = None
        if closed:  # the lifted block nearest the pinch point, within 4 cm
            near = [
                (float(np.linalg.norm(np.asarray(state[b][:3]) - pinch)), b)
                for b in blocks
                if state.get(b, "z") > 0.01
            ]
            gap, nearest = min(near, default=(1.0, None), key=lambda g: g[0])
            held = nearest if gap < 0.04 else None
        for b in blocks:
            if b == held:
                atoms.add(Holding.ground([robot, b]))
            elif on[goal_keys[b]]:
                atoms.add(InArea.ground([b]))
            else:
                atoms.add(OnFloor.ground([b]))
        return frozenset(atoms)

    b = Variable("?block", MOVABLE_TYPE)
    pick = pick_operator(b, OnFloor)
    place = place_operator(b, InArea)

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
        # A pick that closes on a neighbour too carries both; a place that lets both down in
        # the goal area is a success, and the neighbour's own pick and place are then skipped.
        monotone_predicates=frozenset({"InArea"}),
        monotone_negations={"InArea": "OnFloor"},
    )


__all__: Sequence[str] = ["PickController", "PlaceController", "create_model"]
