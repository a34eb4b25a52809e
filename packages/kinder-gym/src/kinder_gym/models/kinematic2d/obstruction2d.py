"""The Obstruction2D planning model: clear the target surface, then put the target block on it.

Every block rests upright on the table and the robot keeps pointing down (θ = −π/2), so all the
skills are top-down: rise to a safe height, move across, descend. No sampling-based motion
planning is needed; every step the follower will take is collision-checked before execution.

Concepts (the blocks are ``target_block`` and the obstructions; the target surface is not a
block and operators are not grounded over it):

* ``HandEmpty(robot)``: nothing is suctioned. ``Holding(robot, block)``: the block touches the
  suction zone with the vacuum on.
* ``OnTarget(block)``: not held and the env's ``is_on(block, target_surface)`` (tolerance
  0.025 m). ``OnTable(block)``: not held and not on the target.
* ``Clear(obstruction)``: the obstruction's x-extent stays more than ``CLEAR_MARGIN`` (0.01 m)
  away from the target surface's x-extent (held or not: picking lifts nothing sideways).

Operators (and skills):

* ``PickFromTable(?robot, ?block)``: pre {HandEmpty, OnTable(b)}; add {Holding}; delete
  {HandEmpty, OnTable(b)}. ``PickFromTarget``: the same with ``OnTarget(b)``. Skill: rise to
  ``SAFE_Y`` (0.8 m, base centre), extend the arm fully (0.2 m) and move over the grasp point,
  descend until the gripper's outer edge is ``GRASP_GAP`` (0.0075 m) above the block's top,
  vacuum on. Param ``u ∈ [0, 1]``: the gripper centre's x runs from ``x_b − g/2 + 5 mm`` to
  ``x_b + w_b + g/2 − 5 mm`` (g = gripper height 0.07 m), so the suction zone overlaps the top
  face by at least 5 mm. Rejected when the grasp pose collides or the suction zone would touch
  another block.
* ``PlaceOnTable(?robot, ?obstruction)``: pre {Holding}; add {HandEmpty, OnTable, Clear};
  delete {Holding}. Skill: rise to ``SAFE_Y``, move over, descend until the block's bottom is
  ``PLACE_GAP`` (5 mm) above the table, vacuum off. Param ``u ∈ [0, 1]``: the block's new x,
  as a fraction of the total length of the free table intervals (not overlapping other blocks
  by less than 0.01 m and keeping clear of the target surface by ``CLEAR_MARGIN``).
* ``PlaceOnTarget(?robot, ?target, ?o0, …, ?o{N−1})``: pre {Holding(target), Clear(o_i) for
  every obstruction}; add {HandEmpty, OnTarget(target)}; delete {Holding}. Same skill; param
  ``u ∈ [0, 1]``: the block's x from ``x_s + 1 mm`` to ``x_s + w_s − w_b − 1 mm`` (the surface's
  x and width). The obstruction parameters are filled with ``obstruction0 … obstruction{N−1}``
  in that order only (``operator_filter``), so there is one grounding.

Goal: ``OnTarget(target_block)``.

Differences from the upstream model (which has Holding/HandEmpty/OnTarget/OnTable and the four
pick/place operators with fixed waypoints at y = 0.8):

* ``Clear`` and the ``PlaceOnTarget`` preconditions on it: upstream's abstraction cannot tell
  which obstructions are in the way, so A* enumerates plans by length and the one that moves
  exactly the obstructions on the surface is often not among the first ten; here the abstract
  plan already moves every blocking obstruction, and only those.
* ``PlaceOnTable`` samples only free table intervals away from the target surface (upstream:
  an absolute x in [0, 1], which may put an obstruction back on the surface); it is not offered
  for the target block (putting it back on the table never helps).
* ``OnTarget`` excludes a held block, so a pick ends at the grasp (no lift step) and its
  predicted abstract state is exact.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden2d.kinematic2d.object_types import CRV_ROBOT, RECTANGLE, TARGET_BLOCK
from kinder_garden2d.kinematic2d.predicates import is_on
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.hand import pick_operator, place_operator
from kinder_gym.models.kinematic2d.crv import (
    ARM_LENGTH,
    GRIPPER_HEIGHT,
    GRIPPER_WIDTH,
    VACUUM,
    CRVCollisionChecker,
    CRVController,
    Waypoint,
    checked_waypoints,
    hand_predicates,
    robot_config,
)
from kinder_gym.motion_planning import FloatArray
from kinder_gym.operators import GroundOperator
from kinder_gym.skills import Skill, SkillFailure

#: Height (metres) of the base centre while moving across: a held block (≤ 0.2 m tall, under a
#: fully extended arm) then clears every block on the table (≤ 0.3 m high).
SAFE_Y = 0.8
#: Gap (metres) between the gripper's outer edge and the block's top when grasping: the suction
#: zone starts 0.005 m beyond the edge and is 0.01 m deep, so it overlaps the top face.
GRASP_GAP = 0.0075
#: Height (metres) of a released block's bottom above the table top (within the env's on-surface
#: tolerance of 0.025 m).
PLACE_GAP = 0.005
#: An obstruction within this distance (metres, in x) of the target surface blocks it.
CLEAR_MARGIN = 0.01
#: Least x distance (metres) kept between a placed block and the other blocks.
BLOCK_MARGIN = 0.01
#: Least overlap (metres) of the suction zone with the grasped block's top face, in x.
SUCTION_OVERLAP = 0.005
#: The heading of every skill: the gripper points down.
DOWN = -math.pi / 2


def _blocks(env: ObjectCentricEnv) -> list[Object]:
    return [env.target_block, *env.obstructions]  # type: ignore[attr-defined]


def _held(env: ObjectCentricEnv, data: FloatArray) -> list[Object]:
    return env.world.held_objects(data)  # type: ignore[attr-defined, no-any-return]


def _span(state: ObjectCentricState, obj: Object) -> tuple[float, float]:
    """The x-extent of an upright rectangle."""
    x = state.get(obj, "x")
    return x, x + state.get(obj, "width")


def is_clear(state: ObjectCentricState, obstruction: Object, surface: Object) -> bool:
    """Whether the obstruction's x-extent keeps ``CLEAR_MARGIN`` away from the surface's."""
    o0, o1 = _span(state, obstruction)
    s0, s1 = _span(state, surface)
    return o1 < s0 - CLEAR_MARGIN or o0 > s1 + CLEAR_MARGIN


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The Obstruction2D planning model (any number of obstructions)."""
    robot_obj: Object = env.robot  # type: ignore[attr-defined]
    target: Object = env.target_block  # type: ignore[attr-defined]
    surface: Object = env.target_surface  # type: ignore[attr-defined]
    obstructions: list[Object] = list(env.obstructions)  # type: ignore[attr-defined]
    tol = float(env.config.on_tolerance)  # type: ignore[attr-defined]

    def on_target(s: ObjectCentricState, b: Object) -> bool:
        return b not in _held(env, s.data) and is_on(s, b, surface, tol)

    HandEmpty, Holding = hand_predicates(env, RECTANGLE)
    OnTarget = Predicate("OnTarget", (RECTANGLE,), lambda s, o: on_target(s, o[0]))
    OnTable = Predicate(
        "OnTable",
        (RECTANGLE,),
        lambda s, o: o[0] not in _held(env, s.data) and not on_target(s, o[0]),
    )
    Clear = Predicate("Clear", (RECTANGLE,), lambda s, o: is_clear(s, o[0], surface))

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        held = set(_held(env, state.data))
        atoms = {Holding.ground([robot_obj, b]) for b in held}
        if not held:
            atoms.add(HandEmpty.ground([robot_obj]))
        for b in _blocks(env):
            if b in held:
                continue
            if is_on(state, b, surface, tol):
                atoms.add(OnTarget.ground([b]))
            else:
                atoms.add(OnTable.ground([b]))
        for o in obstructions:
            if is_clear(state, o, surface):
                atoms.add(Clear.ground([o]))
        return frozenset(atoms)

    b = Variable("?block", RECTANGLE)
    t = Variable("?target", TARGET_BLOCK)
    os_ = [Variable(f"?o{i}", RECTANGLE) for i in range(len(obstructions))]
    pick_from_table = pick_operator("PickFromTable", HandEmpty, Holding, b, [OnTable.lift([b])])
    pick_from_target = pick_operator("PickFromTarget", HandEmpty, Holding, b, [OnTarget.lift([b])])
    place_on_table = place_operator(
        "PlaceOnTable", HandEmpty, Holding, b, [OnTable.lift([b]), Clear.lift([b])]
    )
    place_on_target = place_operator(
        "PlaceOnTarget",
        HandEmpty,
        Holding,
        t,
        [OnTarget.lift([t])],
        also_need=[Clear.lift([o]) for o in os_],
        params=os_,
    )
    ordered = tuple(obstructions)

    def keep(op: GroundOperator, state: ObjectCentricState) -> bool:
        del state
        name = op.parent.name
        if name == "PlaceOnTable":
            return op.objects[1] in ordered
        if name == "PlaceOnTarget":
            return op.objects[2:] == ordered
        return True

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        del state
        return frozenset({OnTarget.ground([target])})

    return PlanningModel(
        name="obstruction2d",
        env=env,
        types=(CRV_ROBOT, RECTANGLE, TARGET_BLOCK),
        predicates=(HandEmpty, Holding, OnTarget, OnTable, Clear),
        skills=(
            Skill(pick_from_table, PickController, env),
            Skill(pick_from_target, PickController, env),
            Skill(place_on_table, PlaceOnTableController, env),
            Skill(place_on_target, PlaceOnTargetController, env),
        ),
        goal_fn=goal,
        abstraction_fn=abstraction,
        objects_fn=lambda state: [robot_obj, *_blocks(env)],
        operator_filter=keep,
        max_skill_horizon=200,
    )


class _TopDownController(CRVController):
    """Rise to ``SAFE_Y``, move across (turning down and setting the arm), descend to a goal
    configuration; the goal comes from the parameters, which are sampled by rejection.

    Objects: ``(robot, block, ...)``.
    """

    params_space = spaces.Box(0.0, 1.0, (1,), dtype=np.float64)
    #: Vacuum setting (0 off, 1 on) while moving.
    vacuum = 0.0
    #: Rejection-sampling attempts of :meth:`sample_parameters`.
    tries = 30

    @property
    def block(self) -> Object:
        """The block picked or placed."""
        return self.objects[1]

    @abc.abstractmethod
    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray | None:
        """The goal ``[x, y, theta, arm]`` for ``params`` (None: no such configuration)."""

    def goal_ok(self, state: ObjectCentricState, data: FloatArray) -> bool:
        """Whether the goal configuration (the state's data with the robot there, held objects
        carried) gives the intended outcome, besides being collision-free."""
        del state, data
        return True

    def _valid(
        self, state: ObjectCentricState, checker: CRVCollisionChecker, goal: FloatArray | None
    ) -> bool:
        return goal is not None and checker(goal) and self.goal_ok(state, checker.data_at(goal))

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Uniform, rejecting parameters whose goal collides or misses the intended outcome."""
        checker = CRVCollisionChecker(self.context.world, state)
        params = super().sample_parameters(state, rng)
        for _ in range(self.tries):
            if self._valid(state, checker, self.goal_config(state, params)):
                return params
            params = super().sample_parameters(state, rng)
        return params

    def waypoints(self, state: ObjectCentricState) -> list[Waypoint]:
        name = type(self).__name__
        checker = CRVCollisionChecker(self.context.world, state)
        goal = self.goal_config(state, self.params)
        if goal is None:
            raise SkillFailure(f"{name}: no goal configuration for parameters {self.params}")
        if not checker(goal):
            raise SkillFailure(f"{name}: goal {goal.round(3)} is in collision")
        if not self.goal_ok(state, checker.data_at(goal)):
            raise SkillFailure(f"{name}: goal {goal.round(3)} misses the intended outcome")
        q0 = robot_config(state, self.robot)
        path = [
            q0,
            np.array([q0[0], SAFE_Y, q0[2], q0[3]]),
            np.array([goal[0], SAFE_Y, goal[2], goal[3]]),
            goal,
        ]
        high = np.asarray(self.context.action_space.high, dtype=np.float64)[:4]
        failure = f"{name}: an execution step collides"
        return checked_waypoints(checker, path, high, self.vacuum, failure)


class PickController(_TopDownController):
    """Grasp a block from above with the arm fully extended; ends with the vacuum on.

    Objects: ``(robot, block)``.
    """

    params_doc = (
        "u: the gripper centre's x is x_block − g/2 + 0.005 + u·(w_block + g − 0.01) metres "
        "(g = gripper height), so the suction zone overlaps the block's top by ≥ 5 mm."
    )
    vacuum = 0.0
    vacuum_after = 1.0

    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray | None:
        v = state[self.robot]
        gh, gw, arm = float(v[GRIPPER_HEIGHT]), float(v[GRIPPER_WIDTH]), float(v[ARM_LENGTH])
        b = self.block
        x0, x1 = _span(state, b)
        lo = x0 - 0.5 * gh + SUCTION_OVERLAP
        x = lo + float(params[0]) * (x1 + 0.5 * gh - SUCTION_OVERLAP - lo)
        top = state.get(b, "y") + state.get(b, "height")
        return np.array([x, top + 0.5 * gw + GRASP_GAP + arm, DOWN, arm])

    def goal_ok(self, state: ObjectCentricState, data: FloatArray) -> bool:
        on = data.copy()
        on[self.context.world.robot_idx[VACUUM]] = 1.0
        return _held(self.context, on) == [self.block]


class _PlaceController(_TopDownController):
    """Carry the held block to a resting pose and release it. Objects: ``(robot, block, ...)``.

    The block keeps its offset from the gripper, so the robot's goal is its current
    configuration shifted by the block's displacement (the arm is kept).
    """

    vacuum = 1.0
    vacuum_after = 0.0

    @abc.abstractmethod
    def block_x(self, state: ObjectCentricState, u: float) -> float | None:
        """The block's resting x for parameter ``u`` (None: nowhere)."""

    def initiable(self, state: ObjectCentricState) -> bool:
        return self.block in _held(self.context, state.data)

    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray | None:
        x = self.block_x(state, float(params[0]))
        if x is None:
            return None
        b = self.block
        y = float(self.context.config.table_height) + PLACE_GAP
        q = robot_config(state, self.robot)
        return np.array([q[0] + x - state.get(b, "x"), q[1] + y - state.get(b, "y"), DOWN, q[3]])


class PlaceOnTableController(_PlaceController):
    """Put the held block down on a free part of the table, away from the target surface."""

    params_doc = (
        "u: the block's x, as the fraction u of the total length of the free table intervals "
        "(clear of other blocks by 0.01 m and of the target surface by 0.01 m), left to right."
    )

    def free_intervals(self, state: ObjectCentricState) -> list[tuple[float, float]]:
        """The intervals (metres) of block x positions on free table."""
        env = self.context
        b = self.block
        w = state.get(b, "width")
        xmax = float(env.config.world_max_x)
        blocked = [
            (x0 - w - BLOCK_MARGIN, x1 + BLOCK_MARGIN)
            for x0, x1 in (_span(state, o) for o in _blocks(env) if o != b)
        ]
        s0, s1 = _span(state, env.target_surface)
        blocked.append((s0 - CLEAR_MARGIN - w - BLOCK_MARGIN, s1 + CLEAR_MARGIN + BLOCK_MARGIN))
        free = []
        lo = BLOCK_MARGIN
        for a, c in sorted(blocked):
            if a > lo:
                free.append((lo, min(a, xmax - w - BLOCK_MARGIN)))
            lo = max(lo, c)
        free.append((lo, xmax - w - BLOCK_MARGIN))
        return [(a, c) for a, c in free if c > a]

    def block_x(self, state: ObjectCentricState, u: float) -> float | None:
        free = self.free_intervals(state)
        total = sum(c - a for a, c in free)
        if total <= 0.0:
            return None
        d = u * total
        for a, c in free:
            if d <= c - a:
                return a + d
            d -= c - a
        return free[-1][1]

    def goal_ok(self, state: ObjectCentricState, data: FloatArray) -> bool:
        after = state.copy()
        after.data[:] = data
        surface = self.context.target_surface
        return is_clear(after, self.block, surface) and not is_on(after, self.block, surface)


class PlaceOnTargetController(_PlaceController):
    """Put the held target block down on the target surface.

    Objects: ``(robot, target_block, obstruction0, ...)``.
    """

    params_doc = (
        "u: the block's x is x_s + 0.001 + u·(w_s − w_b − 0.002) metres (target surface x and "
        "width, block width)."
    )

    def block_x(self, state: ObjectCentricState, u: float) -> float | None:
        s0, s1 = _span(state, self.context.target_surface)
        lo, hi = s0 + 1e-3, s1 - state.get(self.block, "width") - 1e-3
        if hi < lo:
            return None
        return lo + u * (hi - lo)

    def goal_ok(self, state: ObjectCentricState, data: FloatArray) -> bool:
        after = state.copy()
        after.data[:] = data
        env = self.context
        return is_on(after, self.block, env.target_surface, float(env.config.on_tolerance))


__all__: Sequence[str] = [
    "PickController",
    "PlaceOnTableController",
    "PlaceOnTargetController",
    "create_model",
    "is_clear",
]
