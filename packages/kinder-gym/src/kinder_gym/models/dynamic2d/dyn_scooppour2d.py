"""The DynScoopPour2D planning model: grasp the scoop, then scoop and pour, trip after trip.

The scoop (the env's ``hook``) is an L standing right of the wall: its handle (``length_side1``)
upright, its foot (``length_side2``) on the floor pointing left from the corner. The robot grasps
the handle from above (gripper pointing down, fingers across the handle near its top), so the
scoop hangs below the gripper with its foot level.

A trip (closed loop: every phase starts from the observed state, so it uses where the scoop and
the objects actually are):

1. carry the scoop over the wall to the left, its foot tilted ``tilt`` radians tip-down;
2. put the corner near the wall (x = 1.62) and lower until the foot's tip is 3 cm above the
   floor;
3. slide left (at 3/4 speed) until the tip reaches ``tip_stop``, 2–5 cm from the left wall: the
   tilted foot is a wedge, small objects ride up onto it, and those it pushes ahead pile up
   against the wall, where the end of the slide gets under them;
4. raise 10 cm, then turn the scoop about its corner until the tip is ``carry_tilt`` radians
   up: the objects roll into the corner against the handle;
5. lift over the wall (base at y = 2.45), carry to x = 2.7 and turn by ``pour`` radians
   (tip down) so the objects fall out on the right. The lift moves right at the same time, as
   far as keeps the robot and the scoop 5 cm left of the wall until they are above it (a
   diagonal costs no more actions than its longer side).

Trips repeat until the env's goal holds (the skill ends there) or the step budget ends; a trip
that could not move at all (the robot wedged in a high pile) fails the skill. Poured objects fall
slowly (gravity −1, heavy damping), so the goal holds some tens of steps after the last pour.

Concepts: ``HandEmpty(robot)``, ``Holding(robot, hook)``, ``Poured(hook)`` (the env's goal test:
at least half of the small objects rest right of the wall below y = 0.75).

Operators: ``GraspScoop(?robot, ?hook)``: pre {HandEmpty}; add {Holding}; delete {HandEmpty}.
``ScoopAndPour(?robot, ?hook)``: pre {Holding}; add {Poured}. Goal: ``Poured(hook)``.

Upstream has no planning model for DynScoopPour2D. Limits (measured, see
``benchmarks/results/bilevel_planning.md``): the grasp takes about 100–160 actions and a trip
about 300 (the robot moves at most 0.03 m per action, and the scoop goes from the floor over
the 1.5 m wall and back), so the 1000-step episode limit leaves room for two or three trips.
Version notes: the first version slid half speed with the foot tilted 0.4–0.55 rad and stopped
the tip 8–15 cm from the left wall; the objects it pushed ahead gathered against the wall out of
reach, a trip brought 3–5 of o10's ten objects, and BP solved 0.56 of o10. The shallower tilt
(0.30–0.42 rad), the slide to 2–5 cm from the wall and the faster slide raised a single
parameter sample's success on 20–40 seeded o10 instances from 6/20 to 29/30 (o20 14/20 → 26/30,
o30 1/20 → 11/30). o50 needs 25 objects, about three full trips, and stays limited by the step
budget; in its high pile the robot can wedge itself, which is what the stuck-trip failure is for.
The lift of step 5 is diagonal (rather than straight up, then right), about 30 actions
less per trip; one parameter sample on seeds 0–9 (``benchmarks/probes/skill_success.py scoop``): o10
9/10 before and after, o30 6/10 → 9/10, o50 0/10 → 1/10. Pouring nearer the wall (x = 2.35)
was tried and lost objects (7–11 instead of 17 on the right after three trips): not adopted.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Sequence

import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_garden2d.dynamic2d import object_types as ot
from kinder_garden2d.dynamic2d.geometry import bounds
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.models.dynamic2d.kin_robot import (
    ARM_JOINT,
    BASE_RADIUS,
    FINGER_GAP,
    FINGER_HEIGHT,
    GRIPPER_BASE_HEIGHT,
    THETA,
    X,
    Y,
    hook_shape,
    wrap,
)
from kinder_gym.models.hand import pick_operator, tool_operator
from kinder_gym.motion_planning import FloatArray
from kinder_gym.skills import Controller, Skill, SkillFailure

DOWN = -math.pi / 2
#: Height (metres) of the robot's base while it carries the scoop over the wall.
CARRY_Y = 2.45
#: x (metres) of the scoop's corner when it goes down into the pile (just left of the wall).
SCOOP_CORNER_X = 1.62
#: x (metres) of the robot's base when it pours.
POUR_X = 2.7
#: How far (metres) down from the handle's top the fingertips reach.
# A target counts as reached within this (metres, radians): upstream's PD controller leaves
# residuals of up to ~1e-5 after an action.
REACHED = 1e-4
#: Speed of the slide into the pile (fraction of the action bounds).
SLIDE_SPEED = 0.75
#: Clearance (metres) the robot and the scoop keep from the wall's left face while rising.
WALL_MARGIN = 0.05
#: Steps held still after a pour.
POUR_WAIT = 0
#: A trip of fewer actions than this was blocked (a free trip takes about 300).
MIN_TRIP_STEPS = 60

Target = tuple[FloatArray, float, int]  # (x, y, theta, arm, gap), speed, wait
Phase = Callable[[ObjectCentricState], list[Target]]


def scoop_tip(state: ObjectCentricState, hook: Object) -> FloatArray:
    """The foot's free end (mid-thickness), world metres."""
    h = state[hook]
    w, s2 = state.get(hook, "width"), state.get(hook, "length_side2")
    c, s = math.cos(h[2]), math.sin(h[2])
    lx, ly = -w / 2, -s2
    return np.array([h[0] + c * lx - s * ly, h[1] + s * lx + c * ly])


class _PhasedController(Controller):
    """Follows phases of targets for the kin robot; each phase is computed from the state observed
    when it starts. A step that should move the base or arm but does not (a static contact
    reverted it) ends the current target."""

    keep_grip = False  # never open the fingers (a skill that carries what it holds)

    @abc.abstractmethod
    def phases(self) -> list[Phase]:
        """The skill's phases, in order (each subclass defines its own)."""

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        self._max = np.asarray(self.context.action_space.high, dtype=np.float64)
        self._phases = self.phases()
        self._targets: list[Target] = []
        self._waited = 0
        self._last: FloatArray | None = None
        self._done = False

    def _q(self, state: ObjectCentricState) -> FloatArray:
        v = state[self.objects[0]]
        return np.array([v[X], v[Y], v[THETA], v[ARM_JOINT], v[FINGER_GAP]])

    def _next_action(self) -> FloatArray | None:
        assert self.state is not None
        q = self._q(self.state)
        while True:
            if not self._targets:
                if not self._phases:
                    return None
                self._targets = list(self._phases.pop(0)(self.state))
                self._waited = 0
                self._last = None
                continue
            target, speed, wait = self._targets[0]
            d = target - q
            d[2] = wrap(float(d[2]))
            if self.keep_grip:
                # Any opening of the fingers releases what they hold; closing fingers pass
                # through a held object, so the gap may end below the one a phase planned.
                d[4] = min(float(d[4]), 0.0)
            tol = REACHED
            stuck = self._last is not None and (
                (np.max(np.abs(d[:4])) > tol and np.allclose(q[:4], self._last[:4], atol=1e-9))
                or (np.max(np.abs(d[:4])) <= tol and abs(q[4] - self._last[4]) <= 1e-9)
            )
            if np.max(np.abs(d)) > tol and not stuck:
                n = max(1, math.ceil(float(np.max(np.abs(d) / (self._max * speed))) - 1e-9))
                self._last = q
                return d / n
            if self._waited < wait:
                self._waited += 1
                self._last = None
                return np.zeros(5)
            self._targets.pop(0)
            self._waited = 0
            self._last = None

    def step(self) -> FloatArray:
        action = self._next_action()
        if action is None:
            self._done = True
            return np.zeros(5)
        return action

    def terminated(self) -> bool:
        return self._done


class GraspScoopController(_PhasedController):
    """Grasp the scoop's handle from above. Objects: ``(robot, hook)``."""

    params_space = spaces.Box(0.0, 1.0, (0,), dtype=np.float64)
    params_doc = "No continuous parameters."

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.objects[1], "held") < 0.5

    def phases(self) -> list[Phase]:
        return [self._grasp]

    def _grasp(self, state: ObjectCentricState) -> list[Target]:
        robot, hook = self.objects
        v = state[robot]
        h = state[hook]
        if abs(wrap(float(h[2]) - DOWN)) > 0.1:
            raise SkillFailure("GraspScoop: the scoop's handle is not upright")
        w, s1 = state.get(hook, "width"), state.get(hook, "length_side1")
        br = float(v[BASE_RADIUS])
        gx = float(h[0]) - w / 2
        # A grasp needs a finger contact on the fingers' first half (which start at the gripper
        # base's centre): the gripper base's centre stops 0.03 above the handle's top.
        gy = float(h[1]) + s1 + br + 0.03
        open_gap = float(v[GRIPPER_BASE_HEIGHT])
        closed = max(2 * float(v[FINGER_HEIGHT]), w + float(v[FINGER_HEIGHT]) - 0.04)
        return [
            (np.array([gx, CARRY_Y - 0.05, DOWN, br, open_gap]), 1.0, 0),
            (np.array([gx, gy, DOWN, br, open_gap]), 1.0, 0),
            (np.array([gx, gy, DOWN, br, closed]), 1.0, 1),
        ]

    def terminated(self) -> bool:
        return self._done or (
            self.state is not None
            and not self._phases
            and not self._targets
            and self.state.get(self.objects[1], "held") > 0.5
        )


class ScoopAndPourController(_PhasedController):
    """Scoop and pour trip after trip until the goal holds. Objects: ``(robot, hook)``."""

    params_space = spaces.Box(
        np.array([0.3, 0.02, 0.9, 1.0]), np.array([0.42, 0.05, 1.2, 1.4]), dtype=np.float64
    )
    params_doc = (
        "(tilt, tip_stop, carry_tilt, pour): the foot goes into the pile tilted tilt radians "
        "tip-down, slides left until its tip is at x = tip_stop metres, is carried tilted "
        "carry_tilt radians tip-up, and pours turned pour radians tip-down."
    )

    keep_grip = True

    def initiable(self, state: ObjectCentricState) -> bool:
        return state.get(self.objects[1], "held") > 0.5

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        self._env = self.context
        self._trip_steps = 0

    def phases(self) -> list[Phase]:
        return [self._to_pile, self._lower, self._slide, self._level, self._pour]

    def _gap(self, state: ObjectCentricState) -> float:
        return float(state.get(self.objects[0], "finger_gap"))

    def _to_pile(self, state: ObjectCentricState) -> list[Target]:
        hook = self.objects[1]
        tilt = float(self.params[0])
        q = self._q(state)
        br, g = float(q[3]), self._gap(state)
        h = state[hook]
        # Where the corner ends relative to the base once turned to DOWN + tilt.
        rel = np.array([h[0] - q[0], h[1] - q[1]])
        a = wrap(DOWN + tilt - float(q[2]))
        c, s = math.cos(a), math.sin(a)
        rel = np.array([c * rel[0] - s * rel[1], s * rel[0] + c * rel[1]])
        x = SCOOP_CORNER_X - float(rel[0])
        return [
            (np.array([q[0], CARRY_Y, q[2], br, g]), 1.0, 0),
            (np.array([x, CARRY_Y, DOWN + tilt, br, g]), 1.0, 0),
        ]

    def _lower(self, state: ObjectCentricState) -> list[Target]:
        q = self._q(state)
        tip = scoop_tip(state, self.objects[1])
        return [(np.array([q[0], q[1] - (tip[1] - 0.03), q[2], q[3], q[4]]), 1.0, 0)]

    def _slide(self, state: ObjectCentricState) -> list[Target]:
        q = self._q(state)
        tip = scoop_tip(state, self.objects[1])
        dx = float(tip[0]) - float(self.params[1])
        return [
            (np.array([q[0] - max(dx, 0.0), q[1], q[2], q[3], q[4]]), SLIDE_SPEED, 0),
            (np.array([q[0] - max(dx, 0.0), q[1] + 0.1, q[2], q[3], q[4]]), 1.0, 0),
        ]

    def _level(self, state: ObjectCentricState) -> list[Target]:
        """Turn about the scoop's corner to DOWN − carry_tilt (in eight straight pieces)."""
        q = self._q(state)
        h = state[self.objects[1]]
        pivot = np.array([h[0], h[1]])
        th0 = float(q[2])
        turn = wrap(DOWN - float(self.params[2]) - th0)
        b = q[:2] - pivot
        out: list[Target] = []
        for k in range(1, 9):
            a = turn * k / 8
            c, s = math.cos(a), math.sin(a)
            nb = pivot + np.array([c * b[0] - s * b[1], s * b[0] + c * b[1]])
            out.append((np.array([nb[0], nb[1], th0 + a, q[3], q[4]]), 1.0, 0))
        return out

    def _pour(self, state: ObjectCentricState) -> list[Target]:
        q = self._q(state)
        # Rise and move right at once (a diagonal costs no more steps than its longer side), as
        # far right as keeps the robot and the scoop left of the wall until they are above it.
        cfg = self._env.config
        scoop_right = bounds(hook_shape(state, self.objects[1]))[1] - q[0]
        v = state[self.objects[0]]
        right = max(scoop_right, float(v[BASE_RADIUS]), float(v[GRIPPER_BASE_HEIGHT]) / 2)
        wall_left = cfg.wall_center_x - cfg.wall_width / 2
        x_up = float(np.clip(wall_left - WALL_MARGIN - right, q[0], POUR_X))
        return [
            (np.array([x_up, CARRY_Y, q[2], q[3], q[4]]), 1.0, 0),
            (np.array([POUR_X, CARRY_Y, q[2], q[3], q[4]]), 1.0, 0),
            (np.array([POUR_X, CARRY_Y, DOWN + float(self.params[3]), q[3], q[4]]), 1.0, POUR_WAIT),
        ]

    def step(self) -> FloatArray:
        assert self.state is not None
        if self.state.get(self.objects[1], "held") < 0.5:
            raise SkillFailure("ScoopAndPour: the scoop was dropped")
        action = self._next_action()
        if action is None:
            # A trip whose moves all ended at once was blocked throughout (the robot wedged in
            # a high pile): repeating it would only spend the episode.
            if self._trip_steps < MIN_TRIP_STEPS:
                raise SkillFailure("ScoopAndPour: the scoop is stuck (a whole trip moved nothing)")
            self._phases = self.phases()
            self._trip_steps = 0
            action = self._next_action()
            assert action is not None
        self._trip_steps += 1
        return action

    def terminated(self) -> bool:
        return self.state is not None and bool(self._env.goal_reached(self.state))


def create_model(env: ObjectCentricEnv) -> PlanningModel:
    """The DynScoopPour2D planning model (any number of small objects)."""
    robot_t, hook_t = ot.KIN_ROBOT, ot.HOOK
    robot_obj, hook_obj = env.robot, env.hook  # type: ignore[attr-defined]

    def holding(s: ObjectCentricState, o: Sequence[Object]) -> bool:
        return s.get(o[1], "held") > 0.5

    def poured(s: ObjectCentricState, o: Sequence[Object]) -> bool:
        return bool(env.goal_reached(s))

    HandEmpty = Predicate("HandEmpty", (robot_t,), lambda s, o: s.get(hook_obj, "held") < 0.5)
    Holding = Predicate("Holding", (robot_t, hook_t), holding)
    Poured = Predicate("Poured", (hook_t,), poured)
    h = Variable("?hook", hook_t)
    grasp = pick_operator("GraspScoop", HandEmpty, Holding, h, [])
    pour = tool_operator("ScoopAndPour", Holding, h, [], [], [Poured.lift([h])])

    def abstraction(state: ObjectCentricState) -> frozenset[GroundAtom]:
        atoms: set[GroundAtom] = set()
        if holding(state, (robot_obj, hook_obj)):
            atoms.add(Holding.ground([robot_obj, hook_obj]))
        else:
            atoms.add(HandEmpty.ground([robot_obj]))
        if poured(state, ()):
            atoms.add(Poured.ground([hook_obj]))
        return frozenset(atoms)

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset({Poured.ground([hook_obj])})

    max_steps = env.spec.max_episode_steps if env.spec is not None else None
    return PlanningModel(
        name="dynscooppour2d",
        env=env,
        types=(robot_t, hook_t),
        predicates=(HandEmpty, Holding, Poured),
        skills=(
            Skill(grasp, GraspScoopController, env),
            Skill(pour, ScoopAndPourController, env),
        ),
        goal_fn=goal,
        abstraction_fn=abstraction,
        objects_fn=lambda s: [robot_obj, hook_obj],
        max_skill_horizon=max_steps or 1000,
        max_episode_steps=max_steps,
    )
