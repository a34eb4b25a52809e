"""The PushPullHook2D planning model: grasp the hook, then shove the movable button with a flat
face of it straight onto the target button.

The buttons lie on the table, beyond the reach of the robot (whose base may not enter the table);
the L-shaped hook (arms 1.25 and 0.625 m, 0.05 m wide) reaches them. While the robot holds the
hook, a button that the hook overlaps moves by the vector from the hook outline's closest point
to the button's centre (upstream's rule), so a flat face that moves along its own outward normal
in short steps (``PUSH_STEP``) carries the button ahead of it along that normal. The model
therefore turns the hook so that one of its long faces has its outward normal along
``d = (target − movable) / |target − movable|``, puts that face just behind the movable button,
and moves the robot straight along ``d`` until the button's centre reaches the target's (the
env's goal fires once the centres are closer than 0.10 m). Depending on the face, this pushes
(the face is between the robot and the button) or pulls (the inside of the L reaches over the
button).

Concepts:

* ``Holding(robot, hook)`` / ``HandEmpty(robot)``: the hook is (nothing is) in the suction zone
  with the vacuum on.
* ``Pressed(button)``: the button is green (the env's ``is_pressed``; presses latch).

Goal: ``Pressed`` for both buttons.

Operators (and skills):

* ``GraspHook(?robot, ?hook)``: pre {HandEmpty}; add {Holding}; delete {HandEmpty}. Drive
  (RRT-Connect in SE(2), arm retracted, the movable button an obstacle) to face a point on one
  of the eight outer faces of the hook's two boxes, extend the arm until the gripper is 0.0075 m
  short of the face, vacuum on. Params (face, along, arm): face·8 picks the face, ``along`` the
  point from 0.01 m after the face's start to 0.01 m before its end, and the arm extension is
  base_radius + arm·(arm_length − base_radius) metres. The sampler looks ahead: it prefers
  grasps after which a push (on a grid of 8 faces × 5 contact points) is feasible, since most
  grasps hold the hook too short to reach the buttons from the floor.
* ``PushButton(?robot, ?hook, ?movable, ?target)``: pre {Holding}; add {Pressed(movable),
  Pressed(target)}. Compute the hook pose that puts the chosen face's point 0.03 m behind the
  movable button (outward normal along ``d``), the robot pose that holds the hook there (the
  grasp is rigid), drive there (RRT-Connect carrying the hook, the button an obstacle), then move
  straight along ``d`` in 0.01 m steps by the gap plus the buttons' distance minus 0.03 m.
  Params (face, along): face·8 picks one of the eight faces, ``along`` the contact point along
  it, at least the button radius + 0.01 m from the face's ends (rejection-sampled: the base
  must stay off the table and inside the world, and the approach and the push must be
  collision-free). Groundings whose
  ``movable`` is static are filtered out.

Upstream's models do not cover this env (the baselines spec lists no PushPullHook2D model); the
design follows the Dynamic2D hook model's idea (hold the hook rigidly, use it as a rake) but,
because the Kinematic2D push rule moves the button along the contact normal, pushes along any
direction with a face chosen for it rather than only pulling down.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden2d.geometry import lshape_obbs
from kinder_garden2d.kinematic2d.object_types import CIRCLE, CRV_ROBOT, LOBJECT
from kinder_garden2d.kinematic2d.predicates import is_pressed
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.hand import pick_operator, tool_operator
from kinder_gym.models.kinematic2d.crv import (
    ARM_JOINT,
    ARM_LENGTH,
    BASE_RADIUS,
    GRIPPER_WIDTH,
    CRVCollisionChecker,
    hand_predicates,
    robot_config,
)
from kinder_gym.models.kinematic2d.crv_script import (
    Dwell,
    Phase,
    ScriptController,
    ScriptItem,
    relative_pose,
    tip_for,
    with_arm,
)
from kinder_gym.motion_planning import FloatArray
from kinder_gym.operators import GroundOperator
from kinder_gym.skills import Skill, SkillFailure

#: Gap between the gripper's outer edge and the grasped face, as a fraction of the gripper width.
GRASP_GAP_FRACTION = 0.75
#: Clearance (metres) of the base from the table and the walls.
BASE_MARGIN = 1e-3
#: Gap (metres) between the pushing face and the button before the push.
PUSH_GAP = 0.03
#: The push stops when the movable button's centre is this far (metres) short of the target's.
PUSH_SHORTFALL = 0.03
#: Length (metres) of each push step. The env moves a touched button by the distance from the
#: hook's outline to the button's centre, so a face advancing by less than half the button
#: radius per step carries the button ahead of it; a longer step can pass the centre, after
#: which the button is pulled into the hook.
PUSH_STEP = 0.01
#: Contact points keep this much (metres) more than the button radius from a face's ends.
FACE_END_MARGIN = 0.01
#: Faces of the hook: 2 boxes × 4 sides.
NUM_FACES = 8
#: Contact positions along a face tried by the grasp sampler's push lookahead.
LOOKAHEAD_ALONG = (0.1, 0.3, 0.5, 0.7, 0.9)


def hook_faces(
    state: ObjectCentricState, hook: Object
) -> list[tuple[FloatArray, FloatArray, FloatArray, float]]:
    """The eight faces of the hook's two boxes as ``(start corner, unit tangent, outward unit
    normal, length)``, in the world."""
    f = [state.get(hook, k) for k in ("x", "y", "theta", "width", "length_side1", "length_side2")]
    out = []
    for cx, cy, c, s, hw, hh in lshape_obbs(*f):
        centre, u, v = np.array([cx, cy]), np.array([c, s]), np.array([-s, c])
        for normal, tangent, half_n, half_t in ((u, v, hw, hh), (v, -u, hh, hw)):
            for sign in (1.0, -1.0):
                n, t = sign * normal, sign * tangent
                out.append((centre + half_n * n - half_t * t, t, n, 2.0 * half_t))
    return out


def _face(index_param: float) -> int:
    return min(NUM_FACES - 1, int(index_param * NUM_FACES))


class _HookController(ScriptController):
    """Shared geometry; objects start ``(robot, hook, ...)``."""

    tries = 200

    @property
    def hook(self) -> Object:
        """The hook object."""
        return self.objects[1]

    def bounds(self, state: ObjectCentricState) -> tuple[tuple[float, float], tuple[float, float]]:
        """Where the base centre may go: the world shrunk by the radius, below the table."""
        r = float(state[self.robot][BASE_RADIUS]) + BASE_MARGIN
        c = self.env.config  # type: ignore[attr-defined]
        return (c.world_min_x + r, c.world_max_x - r), (c.world_min_y + r, c.table_min_y - r)


class GraspHookController(_HookController):
    """Face a point on an outer face of the hook and switch the vacuum on. Objects: ``(robot,
    hook)``."""

    params_space = spaces.Box(0.0, 1.0, (3,), dtype=np.float64)
    params_doc = (
        "(face, along, arm): face·8 picks one of the 8 faces of the hook's two boxes; the grasp "
        "point runs from 0.01 m after the face's start (along = 0) to 0.01 m before its end "
        "(along = 1); the arm extension is base_radius + arm·(arm_length − base_radius) metres."
    )

    def initiable(self, state: ObjectCentricState) -> bool:
        return not self.held(state)

    def goal_config(self, state: ObjectCentricState, params: FloatArray) -> FloatArray:
        """The grasp configuration for ``params``."""
        v = state[self.robot]
        br, al, gw = float(v[BASE_RADIUS]), float(v[ARM_LENGTH]), float(v[GRIPPER_WIDTH])
        start, tangent, outward, length = hook_faces(state, self.hook)[_face(float(params[0]))]
        point = start + (0.01 + float(params[1]) * max(0.0, length - 0.02)) * tangent
        arm = br + float(params[2]) * (al - br)
        base = point + (arm + (0.5 + GRASP_GAP_FRACTION) * gw) * outward
        return np.array([base[0], base[1], math.atan2(-outward[1], -outward[0]), arm])

    def checker(self, state: ObjectCentricState) -> CRVCollisionChecker:
        return CRVCollisionChecker(self.env.world, state, check_held=False)  # type: ignore[attr-defined]

    def _feasible(
        self, state: ObjectCentricState, checker: CRVCollisionChecker, p: FloatArray
    ) -> bool:
        goal = self.goal_config(state, p)
        br = float(state[self.robot][BASE_RADIUS])
        return self.in_bounds(state, goal) and checker(goal) and checker(with_arm(goal, br))

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Uniform, rejecting grasps whose base is out of bounds or whose pose collides, and
        preferring grasps from which some push of the movable button onto the target is
        feasible (most grasps hold the hook too short to reach the buttons from the floor)."""
        checker = self.checker(state)
        fallback: FloatArray | None = None
        for _ in range(self.tries):
            params = rng.uniform(0.0, 1.0, 3)
            if not self._feasible(state, checker, params):
                continue
            if fallback is None:
                fallback = params
            if self._push_possible(state, self.goal_config(state, params)):
                return params
        return rng.uniform(0.0, 1.0, 3) if fallback is None else fallback

    def _push_possible(self, state: ObjectCentricState, grasp: FloatArray) -> bool:
        """Would some push (on a coarse grid of push parameters) be feasible after grasping the
        hook at configuration ``grasp``?"""
        buttons = state.get_objects(CIRCLE)
        movable = [b for b in buttons if state.get(b, "static") < 0.5]
        target = [b for b in buttons if state.get(b, "static") >= 0.5]
        if len(movable) != 1 or len(target) != 1:
            return True  # not this env's layout: no lookahead
        held = state.copy()
        for k, name in enumerate(("x", "y", "theta", "arm_joint")):
            held.set(self.robot, name, float(grasp[k]))
        held.set(self.robot, "vacuum", 1.0)
        if self.held(held) != [self.hook]:
            return False
        push = PushButtonController((self.robot, self.hook, movable[0], target[0]), self.env)
        checker, push_checker = push.checker(held), push._push_checker(held)
        return any(
            push._feasible(held, checker, push_checker, np.array([(f + 0.5) / NUM_FACES, a]))
            for f in range(NUM_FACES)
            for a in LOOKAHEAD_ALONG
        )

    def phases(self, state: ObjectCentricState) -> list[Phase]:
        def approach(s: ObjectCentricState) -> list[ScriptItem]:
            goal = self.goal_config(s, self.params)
            if not self.in_bounds(s, goal):
                raise SkillFailure("GraspHook: the grasp pose is out of bounds")
            checker = self.checker(s)
            start = robot_config(s, self.robot)
            retracted = float(s[self.robot][BASE_RADIUS])
            items: list[ScriptItem] = []
            if abs(start[3] - retracted) > 1e-9:
                items += self.checked(checker, [start, with_arm(start, retracted)], 0.0, "retract")
                start = with_arm(start, retracted)
            pre = with_arm(goal, retracted)
            items += self.base_path(checker, start, pre, self.bounds(s), 0.0, salt=1)
            items += self.checked(checker, [pre, goal], 0.0, "the arm extension")
            return [*items, Dwell(1.0)]

        return [approach]


class PushButtonController(_HookController):
    """Shove the movable button onto the target with a face of the held hook. Objects:
    ``(robot, hook, movable, target)``."""

    params_space = spaces.Box(0.0, 1.0, (2,), dtype=np.float64)
    params_doc = (
        "(face, along): face·8 picks the pushing face of the hook's two boxes (its outward normal "
        "is turned to point from the movable button to the target); the contact point runs "
        "along the face, keeping the button radius + 0.01 m from its ends."
    )

    def initiable(self, state: ObjectCentricState) -> bool:
        return self.held(state) == [self.hook]

    def plan_configs(
        self, state: ObjectCentricState, params: FloatArray
    ) -> tuple[FloatArray, FloatArray] | None:
        """The pre-push and end-of-push configurations (None when the base would leave its
        bounds)."""
        _, _, movable, target = self.objects
        v = state[self.robot]
        gw = float(v[GRIPPER_WIDTH])
        m = np.array([state.get(movable, "x"), state.get(movable, "y")])
        t = np.array([state.get(target, "x"), state.get(target, "y")])
        r = state.get(movable, "radius")
        dist = float(np.linalg.norm(t - m))
        if dist < 1e-9:
            return None
        d = (t - m) / dist
        start, tangent, outward, length = hook_faces(state, self.hook)[_face(float(params[0]))]
        margin = r + FACE_END_MARGIN
        if length < 2 * margin:
            return None
        point = start + (margin + float(params[1]) * (length - 2 * margin)) * tangent
        # Turning the robot by ``turn`` about anything turns the hook (rigidly held) by ``turn``.
        turn = math.atan2(d[1], d[0]) - math.atan2(outward[1], outward[0])
        heading = float(v[2]) + turn
        rel, _ = relative_pose(state, self.robot, point, 0.0)
        tip = tip_for(m - (r + PUSH_GAP) * d, heading, rel)
        arm = float(v[ARM_JOINT])
        u = np.array([math.cos(heading), math.sin(heading)])
        base = tip - (arm + 0.5 * gw) * u
        heading = math.remainder(heading, 2 * math.pi)
        pre = np.array([base[0], base[1], heading, arm])
        end = pre.copy()
        end[:2] += (PUSH_GAP + dist - PUSH_SHORTFALL) * d
        if not (self.in_bounds(state, pre) and self.in_bounds(state, end)):
            return None
        return pre, end

    def _push_checker(self, state: ObjectCentricState) -> CRVCollisionChecker:
        # During the push the movable button is meant to be touched (the env pushes it).
        return CRVCollisionChecker(self.env.world, state, ignore=[self.objects[2]])  # type: ignore[attr-defined]

    def _feasible(
        self,
        state: ObjectCentricState,
        checker: CRVCollisionChecker,
        push_checker: CRVCollisionChecker,
        params: FloatArray,
    ) -> bool:
        got = self.plan_configs(state, params)
        if got is None or not checker(got[0]):
            return False
        try:
            self.checked(push_checker, list(got), 1.0, "the push")
        except SkillFailure:
            return False
        return True

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Uniform, rejecting pushes whose base leaves its bounds or that collide."""
        checker, push_checker = self.checker(state), self._push_checker(state)
        params = rng.uniform(0.0, 1.0, 2)
        for _ in range(self.tries):
            if self._feasible(state, checker, push_checker, params):
                break
            params = rng.uniform(0.0, 1.0, 2)
        return params

    def phases(self, state: ObjectCentricState) -> list[Phase]:
        def push(s: ObjectCentricState) -> list[ScriptItem]:
            got = self.plan_configs(s, self.params)
            if got is None:
                raise SkillFailure("PushButton: the push poses are out of bounds")
            pre, end = got
            start = robot_config(s, self.robot)
            items = self.base_path(self.checker(s), start, pre, self.bounds(s), 1.0, salt=2)
            n = max(1, math.ceil(float(np.linalg.norm(end[:2] - pre[:2])) / PUSH_STEP))
            line = [pre + (end - pre) * (k / n) for k in range(n + 1)]
            return items + self.checked(self._push_checker(s), line, 1.0, "the push")

        return [push]


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The PushPullHook2D planning model."""

    HandEmpty, Holding = hand_predicates(env, LOBJECT)
    Pressed = Predicate("Pressed", (CIRCLE,), lambda s, o: is_pressed(s, o[0]))

    h = Variable("?hook", LOBJECT)
    m = Variable("?movable", CIRCLE)
    t = Variable("?target", CIRCLE)
    grasp = pick_operator("GraspHook", HandEmpty, Holding, h, [])
    push = tool_operator(
        "PushButton", Holding, h, [m, t], [], [Pressed.lift([m]), Pressed.lift([t])]
    )

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset(Pressed.ground([o]) for o in state.get_objects(CIRCLE))

    def movable_first(op: GroundOperator, state: ObjectCentricState) -> bool:
        # Only the non-static button can be pushed.
        return op.parent.name != "PushButton" or state.get(op.objects[2], "static") < 0.5

    return PlanningModel(
        name="pushpullhook2d",
        env=env,
        types=(CRV_ROBOT, LOBJECT, CIRCLE),
        predicates=(Holding, HandEmpty, Pressed),
        skills=(
            Skill(grasp, GraspHookController, env),
            Skill(push, PushButtonController, env),
        ),
        goal_fn=goal,
        max_skill_horizon=500,
        operator_filter=movable_first,
        monotone_predicates=frozenset({"Pressed"}),
    )


__all__: Sequence[str] = [
    "GraspHookController",
    "PushButtonController",
    "create_model",
    "hook_faces",
]
