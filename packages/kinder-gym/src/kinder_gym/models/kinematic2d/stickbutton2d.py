"""The StickButton2D planning model: press every button, with the stick for those on the table.

Concepts:

* ``Pressed(button)``: the button is green. Presses latch and every button must be pressed, so
  ``Pressed`` is declared *monotone*: a skill that presses other buttons on its way is still a
  successful refinement, and later plan steps whose button is already pressed are skipped.
* ``Grasped(robot, stick)`` / ``HandEmpty(robot)``: the stick is (not) in the suction zone with
  the vacuum on.
* ``OnFloor(button)`` / ``OnTable(button)`` (static): the button's centre is below / on the
  table (``y ≥ table_min_y``). The base can reach every floor button; table buttons need the
  stick.

Operators (and skills):

* ``RobotPress(?robot, ?button)``: pre {HandEmpty, OnFloor}; add {Pressed}. Drive the base onto
  the button along a collision-free SE(2) path (around the stick).
* ``PickStick(?robot, ?stick)``: pre {HandEmpty}; add {Grasped}; delete {HandEmpty}. Drive to a
  pose facing a sampled point of the stick's lower end (its lowest end face or a long face),
  with the gripper just short of it, and switch the vacuum on.
* ``StickPress(?robot, ?stick, ?button)``: pre {Grasped, OnTable}; add {Pressed}. Move the
  robot (vacuum on; a sampled turn of up to ±π/4) so that a sampled point of the stick's centre
  line lies on the button.
* ``PlaceStick(?robot, ?stick)``: pre {Grasped}; add {HandEmpty}; delete {Grasped}. Vacuum off.

Goal: ``Pressed`` for every button.

Differences from the upstream model: upstream tracks where the robot and stick rest
(``RobotAboveButton``, ``StickAboveButton``, ``AboveNoButton``) and requires the exact predicted
abstract state after each skill, so a skill that brushes a second button on its way fails
refinement; with more buttons that happens more often, which is why upstream success falls to
0.26 / 0.02 / 0.00 with 3 / 5 / 10 buttons. Here positions are not part of the abstraction and
presses are monotone.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden2d.kinematic2d.object_types import CIRCLE, CRV_ROBOT, RECTANGLE
from kinder_garden2d.kinematic2d.predicates import is_pressed
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.hand import (
    empty_hand_operator,
    pick_operator,
    place_operator,
    tool_operator,
)
from kinder_gym.models.kinematic2d.crv import (
    ARM_JOINT,
    ARM_LENGTH,
    BASE_RADIUS,
    GRIPPER_WIDTH,
    CRVCollisionChecker,
    CRVController,
    Waypoint,
    checked_base_waypoints,
    hand_predicates,
    plan_base_path,
    robot_config,
    world_sampling_bounds,
)
from kinder_gym.motion_planning import FloatArray, params_seed
from kinder_gym.skills import Skill, SkillFailure

#: Gap (metres) between the gripper's outer edge and the stick face when grasping: the suction
#: zone starts half a gripper width beyond the edge, so the zone overlaps the face.
GRASP_GAP = 0.0075
#: Clearance (metres) kept from the table edge by the base.
TABLE_MARGIN = 1e-3


def _held(env: ObjectCentricEnv, state: ObjectCentricState) -> list[Object]:
    return env.world.held_objects(state.data)  # type: ignore[attr-defined, no-any-return]


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The StickButton2D planning model (any number of buttons)."""
    table_y = float(env.config.table_min_y)  # type: ignore[attr-defined]

    Pressed = Predicate("Pressed", (CIRCLE,), lambda s, o: is_pressed(s, o[0]))
    HandEmpty, Grasped = hand_predicates(env, RECTANGLE, "Grasped")
    OnFloor = Predicate("OnFloor", (CIRCLE,), lambda s, o: s.get(o[0], "y") < table_y)
    OnTable = Predicate("OnTable", (CIRCLE,), lambda s, o: s.get(o[0], "y") >= table_y)

    s = Variable("?stick", RECTANGLE)
    b = Variable("?button", CIRCLE)
    pressed = [Pressed.lift([b])]
    robot_press = empty_hand_operator("RobotPress", HandEmpty, [b], [OnFloor.lift([b])], pressed)
    pick = pick_operator("PickStick", HandEmpty, Grasped, s, [])
    stick_press = tool_operator("StickPress", Grasped, s, [b], [OnTable.lift([b])], pressed)
    place = place_operator("PlaceStick", HandEmpty, Grasped, s, [])

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset(Pressed.ground([o]) for o in state.get_objects(CIRCLE))

    return PlanningModel(
        name="stickbutton2d",
        env=env,
        types=(CRV_ROBOT, RECTANGLE, CIRCLE),
        predicates=(Pressed, Grasped, HandEmpty, OnFloor, OnTable),
        skills=(
            Skill(robot_press, RobotPressController, env),
            Skill(pick, PickStickController, env),
            Skill(stick_press, StickPressController, env),
            Skill(place, PlaceStickController, env),
        ),
        goal_fn=goal,
        max_skill_horizon=400,
        monotone_predicates=frozenset({"Pressed"}),
    )


def _base_limits(
    env: ObjectCentricEnv, state: ObjectCentricState, robot: Object
) -> tuple[tuple[float, float], tuple[float, float]]:
    """Where the base centre may go: the world shrunk by the base radius, below the table."""
    margin = float(state[robot][BASE_RADIUS]) + TABLE_MARGIN
    (x0, x1), (y0, _) = world_sampling_bounds(env, margin)
    return (x0, x1), (y0, float(env.config.table_min_y) - margin)  # type: ignore[attr-defined]


def _feasible_interval(
    b0: FloatArray, v: FloatArray, lo: Sequence[float], hi: Sequence[float]
) -> tuple[float, float] | None:
    """The ``t`` in [0, 1] with ``lo <= b0 + t·v <= hi`` (componentwise), or None if empty."""
    t0, t1 = 0.0, 1.0
    for i in range(len(b0)):
        if abs(v[i]) < 1e-12:
            if not lo[i] <= b0[i] <= hi[i]:
                return None
            continue
        a, b = (lo[i] - b0[i]) / v[i], (hi[i] - b0[i]) / v[i]
        t0, t1 = max(t0, min(a, b)), min(t1, max(a, b))
    return (t0, t1) if t0 <= t1 else None


class _RejectionSampled(CRVController):
    """Samples parameters uniformly, rejecting those whose goal configuration is invalid."""

    tries = 50

    @abc.abstractmethod
    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray | None:
        """The goal ``[x, y, theta, arm]`` for ``params`` (None when it is out of limits)."""

    def checker(self, state: ObjectCentricState) -> CRVCollisionChecker:
        """The collision checker of this skill's motions."""
        return CRVCollisionChecker(self.context.world, state)

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        checker = self.checker(state)
        params = super().sample_parameters(state, rng)
        for _ in range(self.tries):
            goal = self.goal_config(state, params)
            if goal is not None and checker(goal):
                return params
            params = super().sample_parameters(state, rng)
        return params

    def _path_to(self, state: ObjectCentricState, vacuum: float, salt: int) -> list[Waypoint]:
        robot = self.robot
        goal = self.goal_config(state, self.params)
        if goal is None:
            raise SkillFailure(f"{type(self).__name__}: parameters {self.params} out of limits")
        checker = self.checker(state)
        if not checker(goal):
            raise SkillFailure(f"{type(self).__name__}: goal {goal.round(3)} is in collision")
        start = robot_config(state, robot)
        waypoints: list[Waypoint] = []
        if abs(goal[3] - start[3]) > 1e-9:
            # Set the arm first, in place.
            start = start.copy()
            start[3] = goal[3]
            if not checker(start):
                raise SkillFailure(f"{type(self).__name__}: cannot set the arm in place")
            waypoints.append(
                Waypoint(float(start[0]), float(start[1]), float(start[2]), float(start[3]), vacuum)
            )
        checker.arm = float(goal[3])
        (x0, x1), (y0, y1) = _base_limits(self.context, state, robot)
        path = plan_base_path(
            checker, start, goal, ((x0, x1), (y0, y1)), seed=params_seed(self.params, salt)
        )
        return waypoints + checked_base_waypoints(
            checker, path, float(goal[3]), self.context, vacuum
        )


class RobotPressController(_RejectionSampled):
    """Drive the base onto a floor button (vacuum off). Objects: ``(robot, button)``."""

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(rho, phi): the base centre goes to the button centre plus an offset of "
        "rho·(base_radius + radius)·0.8 metres at angle phi·2π (then clipped to below the table "
        "and inside the world); the heading is kept."
    )
    vacuum_after = 0.0

    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray | None:
        robot, button = self.objects
        rho, phi = float(params[0]), float(params[1])
        reach = 0.8 * (float(state[robot][BASE_RADIUS]) + state.get(button, "radius"))
        bx, by = state.get(button, "x"), state.get(button, "y")
        (x0, x1), (y0, y1) = _base_limits(self.context, state, robot)
        x = float(np.clip(bx + rho * reach * math.cos(2 * math.pi * phi), x0, x1))
        y = float(np.clip(by + rho * reach * math.sin(2 * math.pi * phi), y0, y1))
        if math.hypot(x - bx, y - by) >= float(state[robot][BASE_RADIUS]) + state.get(
            button, "radius"
        ):
            return None
        v = state[robot]
        return np.array([x, y, v[2], v[ARM_JOINT]])

    def checker(self, state: ObjectCentricState) -> CRVCollisionChecker:
        return CRVCollisionChecker(self.context.world, state, check_held=False)

    def waypoints(self, state: ObjectCentricState) -> list[Waypoint]:
        return self._path_to(state, vacuum=0.0, salt=1)


def _grasp_faces(
    state: ObjectCentricState, stick: Object
) -> list[tuple[FloatArray, FloatArray, FloatArray, float]]:
    """The faces the stick may be grasped on: its lowest short face, then its two long faces
    (the "U" of the stick's lower end). Each is ``(start corner, unit tangent, inward unit
    normal, length)``. A stick without area (a noisy observation clipped to a zero width, say)
    has no faces: :class:`SkillFailure`."""
    x, y, th = (state.get(stick, k) for k in ("x", "y", "theta"))
    w, h = state.get(stick, "width"), state.get(stick, "height")
    if not (w > 0 and h > 0):
        raise SkillFailure(f"the stick has no area to grasp (width {w}, height {h})")
    c, s = math.cos(th), math.sin(th)
    ax_w = np.array([c, s])
    ax_h = np.array([-s, c])
    p0 = np.array([x, y])
    corners = [p0, p0 + w * ax_w, p0 + w * ax_w + h * ax_h, p0 + h * ax_h]
    centre = p0 + 0.5 * w * ax_w + 0.5 * h * ax_h
    faces = []
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        length = float(np.linalg.norm(b - a))
        tangent = (b - a) / length
        mid = 0.5 * (a + b)
        inward = (centre - mid) / float(np.linalg.norm(centre - mid))
        faces.append((a, tangent, inward, length))
    short = [f for f in faces if f[3] <= min(w, h) + 1e-12]
    lowest = min(short, key=lambda f: float((f[0] + 0.5 * f[3] * f[1])[1]))
    longs = [f for f in faces if f is not lowest and f[3] > min(w, h) + 1e-12]
    if len(longs) < 2:  # a square stick: every other face counts as a side
        longs = [f for f in faces if f is not lowest][:2]
    return [lowest, *longs[:2]]


class PickStickController(_RejectionSampled):
    """Face a point of the stick's lower end ("U" of faces) and switch the vacuum on.

    Objects: ``(robot, stick)``.
    """

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(f, t, a): f picks the face (f < 1/3: the lowest end face, else one of the two long "
        "faces); t is the grasp point along that face (end face: ±0.02 m around its middle; long "
        "face: from one end to the other, 0.01 m in); a is the arm extension as a fraction of "
        "the way from the base radius to the arm length (metres)."
    )
    vacuum_after = 1.0

    def _base_line(
        self, state: ObjectCentricState, f: float, a: float
    ) -> tuple[FloatArray, FloatArray, float, float]:
        """For face choice ``f`` and arm fraction ``a``: base position = ``b0 + t·v``, the goal
        heading, and the arm extension."""
        robot, stick = self.objects
        v = state[robot]
        br, al, gw = float(v[BASE_RADIUS]), float(v[ARM_LENGTH]), float(v[GRIPPER_WIDTH])
        corner, tangent, inward, length = _grasp_faces(state, stick)[min(2, int(f * 3))]
        if f < 1 / 3:
            lo, span = 0.5 * length - 0.02, 0.04
        else:
            lo, span = 0.01, max(0.0, length - 0.02)
        arm = br + a * (al - br)
        b0 = corner + lo * tangent - inward * (arm + 0.5 * gw + GRASP_GAP)
        return b0, span * tangent, math.atan2(inward[1], inward[0]), arm

    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray | None:
        f, t, a = (float(p) for p in params)
        b0, v, heading, arm = self._base_line(state, f, a)
        base = b0 + t * v
        (x0, x1), (y0, y1) = _base_limits(self.context, state, self.robot)
        if not (x0 <= base[0] <= x1 and y0 <= base[1] <= y1):
            return None
        return np.array([base[0], base[1], heading, arm])

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Face and arm uniform; the grasp point over the part of the face whose grasp pose keeps
        the base inside its limits (half the draws biased to the face's lower end); rejecting
        poses in collision."""
        checker = self.checker(state)
        (x0, x1), (y0, y1) = _base_limits(self.context, state, self.robot)
        params = rng.uniform(0.0, 1.0, 3)
        for _ in range(self.tries):
            f, _, a = params
            b0, v, _, _ = self._base_line(state, f, a)
            interval = _feasible_interval(b0, v, (x0, y0), (x1, y1))
            if interval is not None:
                # Half the draws favour the lower end of the face: grasping the stick near its
                # lower end leaves most of it free to reach up the table.
                u = rng.uniform()
                if rng.uniform() < 0.5:
                    u = u**3 if v[1] >= 0 else 1 - u**3
                params[1] = interval[0] + u * (interval[1] - interval[0])
                goal = self.goal_config(state, params)
                if goal is not None and checker(goal):
                    return params
            params = rng.uniform(0.0, 1.0, 3)
        return params

    def checker(self, state: ObjectCentricState) -> CRVCollisionChecker:
        return CRVCollisionChecker(self.context.world, state, check_held=False)

    def waypoints(self, state: ObjectCentricState) -> list[Waypoint]:
        return self._path_to(state, vacuum=0.0, salt=2)


class StickPressController(_RejectionSampled):
    """Move the robot, holding the stick, so the stick covers a table button.

    Objects: ``(robot, stick, button)``.
    """

    params_space = spaces.Box(
        np.array([0.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0]), dtype=np.float64
    )
    params_doc = (
        "(lam, delta, turn): with m = 0.8·button radius (metres), the button centre is put on "
        "the stick's centre line at lam·(length + 2m) − m metres from the stick's end nearest "
        "the gripper, offset sideways by delta·(width/2 + m) metres, after turning the robot "
        "(and the stick with it) by turn·π/4 radians."
    )
    tries = 200

    def initiable(self, state: ObjectCentricState) -> bool:
        return self.objects[1] in _held(self.context, state)

    def _base_line(
        self, state: ObjectCentricState, delta: float, turn: float
    ) -> tuple[FloatArray, FloatArray, float]:
        """For ``delta`` and ``turn``: base position = ``b0 + lam·v``, and the goal heading."""
        robot, stick, button = self.objects
        x, y, th = (state.get(stick, k) for k in ("x", "y", "theta"))
        w, h = state.get(stick, "width"), state.get(stick, "height")
        c, s = math.cos(th), math.sin(th)
        ax_w, ax_h = np.array([c, s]), np.array([-s, c])
        anchor = np.array([x, y])
        length, side = (h, w) if h >= w else (w, h)
        axis, across = (ax_h, ax_w) if h >= w else (ax_w, ax_h)
        start = anchor + 0.5 * side * across
        end = start + length * axis
        rv = state[robot]
        tip = rv[:2] + (rv[ARM_JOINT] + 0.5 * rv[GRIPPER_WIDTH]) * np.array(
            [math.cos(rv[2]), math.sin(rv[2])]
        )
        if np.linalg.norm(end - tip) < np.linalg.norm(start - tip):
            start, axis = end, -axis
        # Turning the robot about its base centre turns the held stick rigidly with it.
        dth = turn * math.pi / 4
        cd, sd = math.cos(dth), math.sin(dth)
        rot = np.array([[cd, -sd], [sd, cd]])
        # The button may sit just beyond the stick's end or side: it only has to overlap.
        reach = 0.8 * state.get(button, "radius")
        rel0 = rot @ (start - reach * axis + delta * (0.5 * side + reach) * across - rv[:2])
        target = np.array([state.get(button, "x"), state.get(button, "y")])
        heading = (float(rv[2]) + dth + math.pi) % (2 * math.pi) - math.pi
        return target - rel0, -(rot @ ((length + 2 * reach) * axis)), heading

    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray | None:
        lam, delta, turn = (float(p) for p in params)
        b0, v, heading = self._base_line(state, delta, turn)
        base = b0 + lam * v
        (x0, x1), (y0, y1) = _base_limits(self.context, state, self.robot)
        if not (x0 <= base[0] <= x1 and y0 <= base[1] <= y1):
            return None
        return np.array([base[0], base[1], heading, state[self.robot][ARM_JOINT]])

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """``delta`` and ``turn`` uniform; ``lam`` uniform over the part of the stick that keeps
        the base inside its limits; rejecting poses in collision."""
        checker = self.checker(state)
        (x0, x1), (y0, y1) = _base_limits(self.context, state, self.robot)
        params = np.zeros(3)
        for _ in range(self.tries):
            params = np.array([0.0, rng.uniform(-1, 1), rng.uniform(-1, 1)])
            b0, v, _ = self._base_line(state, params[1], params[2])
            interval = _feasible_interval(b0, v, (x0, y0), (x1, y1))
            if interval is None:
                continue
            params[0] = rng.uniform(*interval)
            goal = self.goal_config(state, params)
            if goal is not None and checker(goal):
                return params
        return params

    def waypoints(self, state: ObjectCentricState) -> list[Waypoint]:
        return self._path_to(state, vacuum=1.0, salt=3)


class PlaceStickController(CRVController):
    """Switch the vacuum off where the robot is. Objects: ``(robot, stick)``."""

    vacuum_after = 0.0

    def waypoints(self, state: ObjectCentricState) -> list[Waypoint]:
        return []


__all__: Sequence[str] = [
    "PickStickController",
    "PlaceStickController",
    "RobotPressController",
    "StickPressController",
    "create_model",
]
