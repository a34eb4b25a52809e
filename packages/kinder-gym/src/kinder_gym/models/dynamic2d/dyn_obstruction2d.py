"""The DynObstruction2D planning model: clear the target surface, then push the target onto it.

Most blocks are wider than the open fingers (0.26 m between them), so this model moves blocks by
*pushing* them along the table with a finger, which works for every block size: the robot points
its gripper straight down (arm extended), descends beside the block so a fingertip is just above
the table, and moves sideways; the block slides in front of the finger (pushed low, it does not
topple). Near the end of a push the robot slows down so the block does not slide on.

Pushing needs room behind the block (on the side it is pushed from), and blocks may stand as close
as 0.16 m to a wall or touch each other. The skill tries three postures, roomiest first:

1. fingers open (0.32 m between centres), upright: the base circle (0.24 m radius) straight
   above the fingers needs ~0.46 m between the block and a wall;
2. fingers closed (0.12 m), upright: ~0.36 m, the fingertips raised where needed so the gripper
   base (0.32 m across, now reaching over the block) passes above it;
3. fingers closed and leaning 0.35 or 0.5 rad from vertical, so that the base stands above the
   block and only the fingers reach into the gap; the contact pose is found on the geometry
   (the last base x before the robot touches the block, with only the fingers touching it).

With closed fingers the gripper base passes above every block beside the finger along the push,
not just the pushed one (the fingertips stay at least 6 cm below the pushed block's top). When no
posture fits behind an obstruction, ClearSurface pushes it together with the blocks standing less
than 15 cm behind it (at most two), from the last one's trailing side, until the whole chain is
off the surface; PushTarget never does (the blocks behind the target would end on the surface).

Why postures 2 and 3 exist: with only the first, the first planning call failed on 27 of 50 o1
episodes, 14 of them for want of room behind the target; with them, BP SR went from 0.54 to 0.77 on
o1 (5 × 50) and from 0.78 to 0.98 on o0 (5 × 10) (``benchmarks/results/bilevel_planning.md``).
``NotObstructing`` is declared monotone with ``Obstructing`` as its negation
(``PlanningModel.monotone_negations``): a push that shoves a second obstruction off the surface as
well, common on o3 where obstructions touch each other, is accepted instead of rejected as a
mismatch, and that obstruction's own ``ClearSurface`` is skipped (o3's first planning call: 5 → 20
of 50 episodes solved). What still fails: blocks with no room even for leaning fingers, and pushes
that move another block the wrong way (the target, or an obstruction back onto the surface). The
chain pushes and the gripper-base clearance above neighbours raised o3's first planning call from 20
to 32 of 50 episodes solved, o1's from 37 to 42 (``benchmarks/probes/bp_failure_causes.py``).

Concepts:

* ``OnTarget(block, surface)`` / ``NotOnTarget``: the env's goal test for that block (its two
  lowest corners, moved down by the tolerance, lie on the surface).
* ``Obstructing(block, surface)`` / ``NotObstructing``: the block's footprint overlaps the
  surface's x-range (the target cannot fit there).
* ``HandEmpty(robot)``: nothing is held.

Operators (built per env, over its obstructions):

* ``ClearSurface(?robot, ?obstruction, ?surface)``: pre {HandEmpty, Obstructing}; add
  {NotObstructing}; delete {Obstructing}. Push the obstruction off the surface's x-range.
* ``PushTarget(?robot, ?target, ?surface, ?o1, ...)``: pre {HandEmpty, NotOnTarget(target),
  NotObstructing(o_i) for every obstruction}; add {OnTarget(target)}; delete {NotOnTarget}.

Goal: ``OnTarget(target_block, target_surface)``.

Upstream's model picks blocks with a top grasp (only blocks narrower than the open fingers) and
places them; it reports 8% success on o1.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden2d.dynamic2d import object_types as ot
from kinder_garden2d.dynamic2d.geometry import (
    KinRobotGeometry,
    WorldShape,
    bounds,
    is_on,
    kin_robot_geometry,
    overlaps,
    place,
    rect_shape,
    transform,
)
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.dynamic2d.kin_robot import (
    ARM_LENGTH,
    FINGER_GAP,
    FINGER_HEIGHT,
    FINGER_WIDTH,
    GRIPPER_BASE_HEIGHT,
    GRIPPER_BASE_WIDTH,
    KinRobotController,
    KinWaypoint,
    kin_config,
    wrap,
)
from kinder_gym.models.hand import empty_hand_operator
from kinder_gym.motion_planning import FloatArray
from kinder_gym.operators import GroundOperator
from kinder_gym.skills import Skill, SkillFailure

#: Fingertip height above the table top while pushing (metres).
PUSH_CLEARANCE = 0.012
#: Extra height (metres) the fingertips keep above every block while travelling.
TRAVEL_CLEARANCE = 0.06
#: Gap (metres) between the finger and the block before a push starts.
APPROACH_GAP = 0.03
#: The last part of a push (metres) is done at reduced speed.
SLOW_ZONE = 0.1
SLOW_SPEED = 0.2
#: The closed fingers' tips stay at least this far (metres) below the pushed block's top.
MIN_FINGER_CONTACT = 0.06
#: ClearSurface pushes along the blocks standing less than this (metres) behind the block (at
#: most MAX_CHAIN of them) when there is no room to push the block alone.
CHAIN_GAP = 0.15
MAX_CHAIN = 2
#: Lean (radians from straight down) of the closed fingers when there is no room to push upright.
TILTS = (0.35, 0.5)


def _overlap(a: tuple[float, float], b: tuple[float, float]) -> bool:
    return a[0] < b[1] and b[0] < a[1]


def _width(state: ObjectCentricState, block: Object) -> float:
    lo, hi = footprint(state, block)
    return hi - lo


def _close_behind(
    state: ObjectCentricState, block: Object, sign: float, exclude: Sequence[Object]
) -> Object | None:
    """The nearest block standing less than CHAIN_GAP behind ``block`` (pushed towards
    ``sign``), if any."""
    lo, hi = footprint(state, block)
    trail = lo if sign > 0 else hi
    best: tuple[float, Object] | None = None
    for other in state.get_objects(ot.DYN_RECTANGLE):
        if other == block or other in exclude:
            continue
        o_lo, o_hi = footprint(state, other)
        gap = sign * (trail - (o_hi if sign > 0 else o_lo))
        if -0.01 <= gap < CHAIN_GAP and (best is None or gap < best[0]):
            best = (gap, other)
    return None if best is None else best[1]


def footprint(state: ObjectCentricState, block: Object) -> tuple[float, float]:
    """The x-extent ``(min, max)`` of a rectangle block (any rotation), metres."""
    x, th = state.get(block, "x"), state.get(block, "theta")
    w, h = state.get(block, "width"), state.get(block, "height")
    half = abs(math.cos(th)) * w / 2 + abs(math.sin(th)) * h / 2
    return x - half, x + half


def top(state: ObjectCentricState, block: Object) -> float:
    """The highest point of a rectangle block, metres."""
    y, th = state.get(block, "y"), state.get(block, "theta")
    w, h = state.get(block, "width"), state.get(block, "height")
    return y + abs(math.sin(th)) * w / 2 + abs(math.cos(th)) * h / 2


def block_on(state: ObjectCentricState, block: Object, surface: Object, tol: float) -> bool:
    """The env's goal test, for any block."""
    b, s = state[block], state[surface]
    bw, bh = state.get(block, "width"), state.get(block, "height")
    sw, sh = state.get(surface, "width"), state.get(surface, "height")
    poly_b = transform(rect_shape(bw, bh).polys[0], b[0], b[1], b[2])
    poly_s = transform(rect_shape(sw, sh).polys[0], s[0], s[1], s[2])
    return bool(is_on(poly_b, poly_s, tol))


class PushController(KinRobotController):
    """Push a block along the table so its centre ends at a goal x (see the module docstring).

    Objects: ``(robot, block, surface, ...)``. Subclasses say where the block should go
    (:meth:`goal_x`).
    """

    #: Whether the skill may push the blocks standing close behind the block along with it.
    pushes_chains = False

    @abc.abstractmethod
    def goal_x(self, state: ObjectCentricState) -> float:
        """Where the block's centre should end (metres)."""

    def chain_trail_goal(
        self, state: ObjectCentricState, chain: Sequence[Object], sign: float
    ) -> float:
        """Where the trailing side of the pushed chain (the block, then the blocks pushed along
        behind it, packed) should end (metres). Default: the block's centre at :meth:`goal_x`."""
        block = self.objects[1]
        lo, hi = footprint(state, block)
        trail = self.goal_x(state) - (state.get(block, "x") - (lo if sign > 0 else hi))
        return trail - sign * sum(_width(state, b) for b in chain[1:])

    def waypoints(self, state: ObjectCentricState) -> list[KinWaypoint]:
        v = state[self.objects[0]]
        open_gap, closed_gap = float(v[GRIPPER_BASE_HEIGHT]), 2 * float(v[FINGER_HEIGHT])
        # Roomiest first (module docstring): open fingers; closed fingers (~0.1 m less room, the
        # tips raised so the gripper base passes above the block); closed fingers leaning into
        # the gap so the base stands above the block. Then, where allowed, the same behind the
        # blocks that stand too close behind the block, pushing them along.
        postures = [(open_gap, 0.0), (closed_gap, 0.0), *((closed_gap, t) for t in TILTS)]
        sign = self._direction(state)
        chains = [[self.objects[1]]]
        while self.pushes_chains and len(chains) <= MAX_CHAIN:
            behind = _close_behind(state, chains[-1][-1], sign, exclude=chains[-1])
            if behind is None:
                break
            chains.append([*chains[-1], behind])
        first: SkillFailure | None = None
        for chain in chains:
            for gap, tilt in postures:
                try:
                    return self._push_waypoints(state, gap, tilt, chain)
                except SkillFailure as e:
                    first = first or e
        assert first is not None
        raise first  # the lone block's roomiest posture says best what failed

    def _direction(self, state: ObjectCentricState) -> float:
        """+1 when the block is pushed right, −1 left."""
        return 1.0 if self.goal_x(state) >= state.get(self.objects[1], "x") else -1.0

    def _push_waypoints(
        self,
        state: ObjectCentricState,
        gap: float,
        tilt: float = 0.0,
        chain: Sequence[Object] = (),
    ) -> list[KinWaypoint]:
        env = self.context
        cfg = env.config
        robot = self.objects[0]
        chain = list(chain) or [self.objects[1]]
        block = chain[-1]  # the block the finger touches
        v = state[robot]
        arm = float(v[ARM_LENGTH])
        finger_len = float(v[FINGER_WIDTH])
        reach = arm + float(v[GRIPPER_BASE_WIDTH]) / 2 + finger_len
        half_span = gap / 2 + float(v[FINGER_HEIGHT]) / 2  # outer face of a finger
        blocks = [o for o in state.get_objects(ot.DYN_RECTANGLE)]
        table_top = float(cfg.table_height)
        highest = max([top(state, b) for b in blocks] + [table_top])
        y_safe = highest + TRAVEL_CLEARANCE + reach
        if y_safe + float(v[16]) > cfg.world_max_y - 0.01:
            raise SkillFailure("no room to travel above the blocks")
        sign = self._direction(state)
        lo, hi = footprint(state, block)
        # The leading finger's outer face touches the chain's trailing side.
        contact = lo if sign > 0 else hi
        trail_goal = self.chain_trail_goal(state, chain, sign)
        x_push0 = contact - sign * (half_span + APPROACH_GAP)
        x_push1 = trail_goal - sign * half_span
        # Fingertips just above the table; the base must clear the pushed block's top, and with
        # the fingers closed the gripper base (which then reaches over the block) too.
        tip = max(table_top + PUSH_CLEARANCE, top(state, block) - (reach - float(v[16])) + 0.01)
        if half_span < float(v[GRIPPER_BASE_HEIGHT]) / 2:
            # The gripper base reaches over the pushed block and whatever stands beside the
            # finger along the push: it passes above them all, the finger still below the
            # pushed block's top.
            reach_x = float(v[GRIPPER_BASE_HEIGHT]) / 2
            span = (min(x_push0, x_push1) - reach_x, max(x_push0, x_push1) + reach_x)
            under = [b for b in blocks if _overlap(footprint(state, b), span)]
            tip = max([tip] + [top(state, b) - finger_len + 0.01 for b in under])
            if tip > top(state, block) - MIN_FINGER_CONTACT:
                raise SkillFailure(
                    "the gripper base cannot pass above the blocks beside the finger"
                )
        y_push = tip + reach
        down = -math.pi / 2
        theta = down
        if tilt > 0.0:
            theta = wrap(down - sign * tilt)
            contact_x, y_push = self._leaning_contact(state, block, gap, theta, sign)
            x_push0 = contact_x - sign * APPROACH_GAP
            x_push1 = contact_x + (trail_goal - contact)
        q = kin_config(state, robot)
        margin = float(q[3]) + float(v[GRIPPER_BASE_WIDTH]) / 2 + float(v[FINGER_WIDTH]) + 0.03
        x_turn = float(np.clip(q[0], cfg.world_min_x + margin, cfg.world_max_x - margin))
        wps = [
            KinWaypoint(q[0], max(q[1], y_safe), q[2], q[3], gap),
            KinWaypoint(x_turn, max(q[1], y_safe), q[2], q[3], gap),
            KinWaypoint(x_turn, max(q[1], y_safe), theta, q[3], gap),
            KinWaypoint(x_turn, max(q[1], y_safe), theta, arm, gap),
            KinWaypoint(x_push0, y_safe, theta, arm, gap),
            KinWaypoint(x_push0, y_push, theta, arm, gap),
        ]
        self._check_pose(state, wps[-1], exclude=())
        slow_start = x_push1 - sign * min(SLOW_ZONE, abs(x_push1 - x_push0))
        wps += [
            KinWaypoint(slow_start, y_push, theta, arm, gap),
            KinWaypoint(x_push1, y_push, theta, arm, gap, speed=SLOW_SPEED, wait=2),
            KinWaypoint(x_push1 - sign * 0.01, y_push, theta, arm, gap, speed=SLOW_SPEED),
            KinWaypoint(x_push1 - sign * 0.01, y_safe, theta, arm, gap, wait=3),
        ]
        return wps

    def _leaning_contact(
        self, state: ObjectCentricState, block: Object, gap: float, theta: float, sign: float
    ) -> tuple[float, float]:
        """Base ``(x, y)`` at which the leaning fingers (and nothing else of the robot) touch the
        block's trailing side, the fingertips as low as the gripper base lets them be."""
        env = self.context
        robot = self.objects[0]
        vec = state[robot].copy()
        vec[2], vec[17], vec[FINGER_GAP] = theta, vec[ARM_LENGTH], gap
        w, h = state.get(block, "width"), state.get(block, "height")
        f = state[block]
        block_shape = place(rect_shape(w, h), f[0], f[1], f[2])
        x_now = float(f[0])

        def geometry(x: float, y: float) -> KinRobotGeometry:
            vec[0], vec[1] = x, y
            return kin_robot_geometry(vec)

        lowest = bounds(geometry(0.0, 0.0).shape)[2]
        y0 = float(env.config.table_height) + PUSH_CLEARANCE - lowest
        for lift in np.arange(0.0, 0.3, 0.02):
            y = y0 + float(lift)
            far, near = x_now - sign * 1.5, x_now
            if overlaps(geometry(far, y).shape, block_shape):
                continue
            for _ in range(30):  # the last base x before the robot touches the block
                mid = (far + near) / 2
                touching = overlaps(geometry(mid, y).shape, block_shape)
                far, near = (far, mid) if touching else (mid, near)
            g = geometry(near, y)
            fingers = WorldShape((g.finger_l, g.finger_r))
            rest = WorldShape((g.arm, g.gripper), (g.base,))
            if overlaps(fingers, block_shape) and not overlaps(rest, block_shape):
                return far, y
        raise SkillFailure("no leaning pose touches the block with the fingers only")

    def _check_pose(
        self, state: ObjectCentricState, wp: KinWaypoint, exclude: Sequence[Object]
    ) -> None:
        """SkillFailure when the robot at ``wp`` would touch a block, the table or a wall."""
        env = self.context
        cfg = env.config
        vec = state[self.objects[0]].copy()
        vec[0], vec[1], vec[2], vec[17], vec[FINGER_GAP] = wp.x, wp.y, wp.theta, wp.arm, wp.gap
        shape = kin_robot_geometry(vec).shape
        x0, x1, y0, _ = bounds(shape)
        if x0 <= cfg.world_min_x or x1 >= cfg.world_max_x or y0 <= cfg.table_height:
            raise SkillFailure(f"the robot would touch a wall or the table at x={wp.x:.3f}")
        for b in state.get_objects(ot.DYN_RECTANGLE):
            if b in exclude:
                continue
            w, h = state.get(b, "width"), state.get(b, "height")
            f = state[b]
            if overlaps(shape, place(rect_shape(w, h), f[0], f[1], f[2])):
                raise SkillFailure(f"the robot would touch {b.name} at x={wp.x:.3f}")


class ClearSurfaceController(PushController):
    """Push an obstruction off the surface's x-range. Objects: ``(robot, obstruction, surface)``."""

    pushes_chains = True

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(side, extra): side < 0.5 pushes the block to the left of the surface, else to the "
        "right; its near edge ends extra·0.2 + 0.02 metres beyond the surface's edge."
    )

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Prefer pushing away from the target block (80%)."""
        surface = self.objects[2]
        targets = state.get_objects(ot.TARGET_BLOCK)
        away_right = bool(targets) and state.get(targets[0], "x") < state.get(surface, "x")
        side = rng.uniform(0.5, 1.0) if away_right else rng.uniform(0.0, 0.5)
        if rng.uniform() < 0.2:
            side = 1.0 - side
        return np.array([side, rng.uniform()])

    def goal_x(self, state: ObjectCentricState) -> float:
        _, block, surface = self.objects[:3]
        side, extra = (float(p) for p in self.params)
        lo, hi = footprint(state, block)
        half = (hi - lo) / 2
        s_lo, s_hi = footprint(state, surface)
        gap = 0.02 + 0.2 * extra
        return s_hi + gap + half if side >= 0.5 else s_lo - gap - half

    def chain_trail_goal(
        self, state: ObjectCentricState, chain: Sequence[Object], sign: float
    ) -> float:
        """The whole chain ends beyond the surface's edge (the blocks pushed along behind the
        obstruction would otherwise end on the surface)."""
        surface = self.objects[2]
        s_lo, s_hi = footprint(state, surface)
        gap = 0.02 + 0.2 * float(self.params[1])
        return s_hi + gap if sign > 0 else s_lo - gap


class PushTargetController(PushController):
    """Push the target block onto the surface. Objects: ``(robot, target, surface, ...)``."""

    params_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float64)
    params_doc = (
        "(offset,): the block's centre ends offset·0.5·(surface width − block width)/2 metres "
        "from the surface's centre."
    )

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Centred pushes first: offsets concentrate around 0."""
        return np.array([float(np.clip(rng.normal(0.0, 0.3), -1.0, 1.0))])

    def goal_x(self, state: ObjectCentricState) -> float:
        _, block, surface = self.objects[:3]
        lo, hi = footprint(state, block)
        s_lo, s_hi = footprint(state, surface)
        slack = max(0.0, (s_hi - s_lo) - (hi - lo)) / 2
        return state.get(surface, "x") + float(self.params[0]) * 0.5 * slack


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The DynObstruction2D planning model (any number of obstructions)."""
    tol = float(env.config.goal_tolerance)  # type: ignore[attr-defined]
    robot_t, block_t, target_t, surface_t = (
        ot.KIN_ROBOT,
        ot.DYN_RECTANGLE,
        ot.TARGET_BLOCK,
        ot.TARGET_SURFACE,
    )

    def on_target(s: ObjectCentricState, o: Sequence[Object]) -> bool:
        return block_on(s, o[0], o[1], tol)

    def obstructing(s: ObjectCentricState, o: Sequence[Object]) -> bool:
        lo, hi = footprint(s, o[0])
        s_lo, s_hi = footprint(s, o[1])
        return hi > s_lo and lo < s_hi

    def hand_empty(s: ObjectCentricState, o: Sequence[Object]) -> bool:
        return all(s.get(b, "held") < 0.5 for b in s.get_objects(block_t))

    OnTarget = Predicate("OnTarget", (block_t, surface_t), on_target)
    NotOnTarget = Predicate("NotOnTarget", (block_t, surface_t), lambda s, o: not on_target(s, o))
    Obstructing = Predicate("Obstructing", (block_t, surface_t), obstructing)
    NotObstructing = Predicate(
        "NotObstructing", (block_t, surface_t), lambda s, o: not obstructing(s, o)
    )
    HandEmpty = Predicate("HandEmpty", (robot_t,), hand_empty)

    obstructions = sorted(env.obstructions, key=lambda o: o.name)  # type: ignore[attr-defined]
    t = Variable("?target", target_t)
    s = Variable("?surface", surface_t)
    b = Variable("?block", block_t)
    os_ = [Variable(f"?o{i}", block_t) for i in range(len(obstructions))]
    in_the_way = [Obstructing.lift([b, s])]
    clear = empty_hand_operator(
        "ClearSurface", HandEmpty, [b, s], in_the_way, [NotObstructing.lift([b, s])], in_the_way
    )
    off_target = [NotOnTarget.lift([t, s])]
    push = empty_hand_operator(
        "PushTarget",
        HandEmpty,
        [t, s, *os_],
        [*off_target, *(NotObstructing.lift([o, s]) for o in os_)],
        [OnTarget.lift([t, s])],
        off_target,
    )
    target_obj = env.target_block  # type: ignore[attr-defined]
    surface_obj = env.target_surface  # type: ignore[attr-defined]

    def keep(op: GroundOperator, state: ObjectCentricState) -> bool:
        # Only the real target is pushed onto the surface, only obstructions are cleared, and
        # PushTarget lists the obstructions in name order.
        if op.parent is clear:
            return op.objects[1] in obstructions
        return list(op.objects[3:]) == obstructions

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset({OnTarget.ground([target_obj, surface_obj])})

    robot_obj = env.robot  # type: ignore[attr-defined]

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        # On-target atoms only for the target, obstruction atoms only for the obstructions.
        ts = (target_obj, surface_obj)
        atoms = {(OnTarget if on_target(state, ts) else NotOnTarget).ground(ts)}
        for o in obstructions:
            os = (o, surface_obj)
            atoms.add((Obstructing if obstructing(state, os) else NotObstructing).ground(os))
        if hand_empty(state, ()):
            atoms.add(HandEmpty.ground([robot_obj]))
        return frozenset(atoms)

    return PlanningModel(
        name="dynobstruction2d",
        env=env,
        types=(robot_t, block_t, target_t, surface_t),
        predicates=(OnTarget, NotOnTarget, Obstructing, NotObstructing, HandEmpty),
        skills=(
            Skill(clear, ClearSurfaceController, env),
            Skill(push, PushTargetController, env),
        ),
        goal_fn=goal,
        abstraction_fn=abstraction,
        max_skill_horizon=200,
        operator_filter=keep,
        # A push may shove a second obstruction off the surface as well: accepted, and that
        # block's own ClearSurface is then skipped.
        monotone_predicates=frozenset({"NotObstructing"}),
        monotone_negations={"NotObstructing": "Obstructing"},
    )
