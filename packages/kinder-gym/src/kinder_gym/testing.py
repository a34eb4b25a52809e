"""A tiny 1-D pick-and-place env and its planning model, for testing planners, and
:func:`check_planning_model`, the check every planning model's tests run: each skill of a plan
reaches its operator's predicted abstract state.

A robot on a line carries blocks into a region. The region only fits one block, and an
obstruction starts inside it, so the shortest abstract plan (pick and place the target) cannot be
refined: the planner must move the obstruction out first.
"""

from __future__ import annotations

import abc
from collections.abc import Iterable, Sequence

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState, ObjectCentricStateSpace, Type
from kinder_core.state import FloatArray
from kinder_gym.concepts import GroundAtom, Predicate, Variable
from kinder_gym.model import PlanningModel
from kinder_gym.operators import LiftedOperator
from kinder_gym.skills import Controller, Skill, SkillFailure, execute_skill

ROBOT = Type("robot", ["x", "grip"])
BLOCK = Type("block", ["x", "width", "held"])
TARGET_BLOCK = Type("target_block", [], parent=BLOCK)
REGION = Type("region", ["x", "width"])


class ToyPlaceEnv(ObjectCentricEnv):
    """Carry the target block into the region.

    ## Description
    A 1-D toy for the planning tests.

    ## Observation Space
    The robot (x, grip), the blocks (x, width, held) and the region (x, width).

    ## Action Space
    (dx, grip): dx in [−0.1, 0.1], grip in [0, 1] (on when > 0.5).

    ## Reward
    −1 per step.

    ## Starting State
    The obstruction fills the region; the target block and the robot are to its left.

    ## Episode End
    The target block lies inside the region and is not held.

    ## Version History
    * v0: initial version.
    """

    def __init__(self, render_mode: str | None = "rgb_array") -> None:
        super().__init__(render_mode=render_mode)
        self.robot = Object("robot", ROBOT)
        self.target = Object("target", TARGET_BLOCK)
        self.obstruction = Object("obstruction", BLOCK)
        self.region = Object("region", REGION)
        self.blocks = [self.obstruction, self.target]
        self.action_space = spaces.Box(
            np.array([-0.1, 0.0]), np.array([0.1, 1.0]), dtype=np.float64
        )
        self.observation_space = ObjectCentricStateSpace([ROBOT, BLOCK, REGION])

    def feature_bounds(self) -> dict[str, tuple[float, float]]:
        return {"x": (0.0, 1.2), "grip": (0.0, 1.0), "width": (0.0, 1.0), "held": (0.0, 1.0)}

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        return ObjectCentricState.from_features(
            {
                self.robot: [rng.uniform(0.0, 0.2), 0.0],
                self.target: [rng.uniform(0.3, 0.5), 0.1, 0.0],
                self.obstruction: [0.9 + rng.uniform(-0.01, 0.01), 0.15, 0.0],
                self.region: [0.9, 0.2],
            }
        )

    def _transition(self, state: ObjectCentricState, action: FloatArray) -> ObjectCentricState:
        x = float(np.clip(state.get(self.robot, "x") + action[0], 0.0, 1.2))
        state.set(self.robot, "x", x)
        grip = action[1] > 0.5
        held = [b for b in self.blocks if state.get(b, "held") > 0.5]
        for b in held:
            state.set(b, "x", x)
        if grip and not held:
            for b in self.blocks:
                if abs(state.get(b, "x") - x) < state.get(b, "width") / 2:
                    state.set(b, "held", 1.0)
                    break
        if not grip and held:
            b = held[0]
            if not any(blocks_overlap(state, b, o) for o in self.blocks if o != b):
                state.set(b, "held", 0.0)
        state.set(
            self.robot, "grip", 1.0 if any(state.get(b, "held") > 0.5 for b in self.blocks) else 0.0
        )
        return state

    def goal_reached(self, state: ObjectCentricState) -> bool:
        return state.get(self.target, "held") < 0.5 and inside(state, self.target, self.region)

    def _render_state(self, state: ObjectCentricState) -> NDArray[np.uint8]:
        return np.zeros((4, 4, 3), dtype=np.uint8)


def blocks_overlap(state: ObjectCentricState, a: Object, b: Object) -> bool:
    gap = abs(state.get(a, "x") - state.get(b, "x"))
    return gap < (state.get(a, "width") + state.get(b, "width")) / 2


def inside(state: ObjectCentricState, b: Object, region: Object) -> bool:
    lo = state.get(region, "x") - state.get(region, "width") / 2
    hi = state.get(region, "x") + state.get(region, "width") / 2
    half = state.get(b, "width") / 2
    return lo <= state.get(b, "x") - half and state.get(b, "x") + half <= hi


def _holding(state: ObjectCentricState, objs: Sequence[Object]) -> bool:
    return state.get(objs[1], "held") > 0.5


def _hand_empty(state: ObjectCentricState, objs: Sequence[Object]) -> bool:
    return all(state.get(b, "held") < 0.5 for b in state.get_objects(BLOCK))


HandEmpty = Predicate("HandEmpty", (ROBOT,), _hand_empty)
Holding = Predicate("Holding", (ROBOT, BLOCK), _holding)
InRegion = Predicate("InRegion", (BLOCK, REGION), lambda s, o: inside(s, o[0], o[1]))
OutOfRegion = Predicate("OutOfRegion", (BLOCK, REGION), lambda s, o: not inside(s, o[0], o[1]))

R = Variable("?robot", ROBOT)
B = Variable("?block", BLOCK)
G = Variable("?region", REGION)
PICK = LiftedOperator(
    "Pick",
    (R, B),
    frozenset({HandEmpty.lift([R])}),
    frozenset({Holding.lift([R, B])}),
    frozenset({HandEmpty.lift([R])}),
)
PLACE_IN = LiftedOperator(
    "PlaceIn",
    (R, B, G),
    frozenset({Holding.lift([R, B]), OutOfRegion.lift([B, G])}),
    frozenset({HandEmpty.lift([R]), InRegion.lift([B, G])}),
    frozenset({Holding.lift([R, B]), OutOfRegion.lift([B, G])}),
)
PLACE_OUT = LiftedOperator(
    "PlaceOut",
    (R, B, G),
    frozenset({Holding.lift([R, B]), InRegion.lift([B, G])}),
    frozenset({HandEmpty.lift([R]), OutOfRegion.lift([B, G])}),
    frozenset({Holding.lift([R, B]), InRegion.lift([B, G])}),
)


class _MoveThenGrip(Controller):
    """Drive to an x position with the grip held, then set the grip."""

    grip_during = 0.0
    grip_after = 1.0

    @abc.abstractmethod
    def goal_x(self) -> float:
        """Where to go."""

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        super().reset(state, params)
        self._done = False
        self._gripped = False
        self._x = self.goal_x()

    def step(self) -> FloatArray:
        assert self.state is not None
        robot = self.objects[0]
        dx = self._x - self.state.get(robot, "x")
        if abs(dx) > 1e-9:
            return np.array([np.clip(dx, -0.1, 0.1), self.grip_during])
        self._done = True
        return np.array([0.0, self.grip_after])

    def terminated(self) -> bool:
        return self._done


class PickController(_MoveThenGrip):
    """Go to the block's centre and grip (no parameters)."""

    def goal_x(self) -> float:
        assert self.state is not None
        return self.state.get(self.objects[1], "x")


class PlaceController(_MoveThenGrip):
    """Carry the block to an x position and release it (sampler: anywhere on the line)."""

    params_space = spaces.Box(0.0, 1.2, (1,), dtype=np.float64)
    params_doc = "x: where to release the block (metres along the line)."
    grip_during = 1.0
    grip_after = 0.0

    def goal_x(self) -> float:
        assert self.state is not None
        block = self.objects[1]
        x = float(self.params[0])
        for other in self.state.get_objects(BLOCK):
            if (
                other != block
                and abs(self.state.get(other, "x") - x)
                < (self.state.get(other, "width") + self.state.get(block, "width")) / 2
            ):
                raise SkillFailure(f"releasing {block.name} at x={x:.3f} overlaps {other.name}")
        return x


class PlaceInController(PlaceController):
    """As :class:`PlaceController`, but the sampler proposes positions inside the region."""

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        block, region = self.objects[1], self.objects[2]
        half = (state.get(region, "width") - state.get(block, "width")) / 2
        return np.array([state.get(region, "x") + rng.uniform(-half, half)])


def make_toy_model(env: ToyPlaceEnv) -> PlanningModel:
    """The toy env's planning model."""

    def goal(state: ObjectCentricState) -> frozenset[GroundAtom]:
        return frozenset({InRegion.ground([env.target, env.region])})

    return PlanningModel(
        name="toyplace",
        env=env,
        types=(ROBOT, BLOCK, TARGET_BLOCK, REGION),
        predicates=(HandEmpty, Holding, InRegion, OutOfRegion),
        skills=(
            Skill(PICK, PickController, env),
            Skill(PLACE_IN, PlaceInController, env),
            Skill(PLACE_OUT, PlaceController, env),
        ),
        goal_fn=goal,
        max_skill_horizon=40,
    )


def check_planning_model(
    model: PlanningModel,
    state: ObjectCentricState,
    steps: Iterable[str],
    rng: np.random.Generator,
    *,
    samples: int = 1,
    max_steps: int | None = None,
    stop_on_goal: bool = True,
    retry_mispredictions: bool = False,
    monotone_extras: bool = False,
    require_finished: bool = True,
    check_action_bounds: bool = False,
    check_params_space: bool = False,
) -> ObjectCentricState:
    """Run the named ground operators' skills in turn and check each reaches its prediction.

    For each name in ``steps`` the ground operator must be applicable in the current abstract
    state. Its skill then runs with parameters drawn from ``rng`` by its controller's sampler,
    as a planner would, up to ``samples`` times: a sample whose controller raises
    :class:`SkillFailure` is skipped. The first rollout that does not fail must finish and its
    abstract state must equal the operator's prediction; with ``retry_mispredictions`` a
    rollout that misses it is skipped too, and the first one that reaches it is taken. With
    ``monotone_extras`` the reached abstract state may also hold atoms of the model's monotone
    predicates that the operator does not predict. Without ``require_finished`` a rollout cut
    short (by the horizon, or by reaching the env's goal with ``stop_on_goal``) counts when it
    reaches the prediction. With ``check_action_bounds`` every
    action of every rollout must lie within the env's action space bounds, and with
    ``check_params_space`` every sampled parameter vector within the controller's
    ``params_space`` (as float32, the dtype the spaces are declared with). Raises
    ``AssertionError`` naming the step on any miss; returns the state the last skill ends in.
    """
    horizon = model.max_skill_horizon if max_steps is None else max_steps
    for name in steps:
        atoms = model.abstract(state)
        ops = [o for o in model.ground_operators(state) if o.name == name]
        if not ops:
            raise AssertionError(f"{name}: no such ground operator in this state")
        op = ops[0]
        if not op.applicable(atoms):
            raise AssertionError(f"{name}: not applicable in {sorted(map(str, atoms))}")
        expected = op.apply(atoms)
        for _ in range(samples):
            controller = model.skill(op).controller
            params = controller.sample_parameters(state, rng)
            if check_params_space and not controller.params_space.contains(
                np.asarray(params, dtype=np.float32)
            ):
                raise AssertionError(f"{name}: sampled {params} outside {controller.params_space}")
            try:
                out = execute_skill(
                    controller, state, params, model.env.transition, horizon, stop_on_goal
                )
            except SkillFailure:
                continue
            if check_action_bounds:
                space = model.env.action_space
                if not isinstance(space, spaces.Box):
                    raise TypeError(f"action bounds need a Box action space, not {space}")
                high = space.high
                for action in out.actions:
                    if not np.all(np.abs(action) <= high + 1e-9):
                        raise AssertionError(f"{name}: action {action} outside {high}")
            reached = model.abstract(out.states[-1])
            extra = reached - expected
            if monotone_extras:
                extra = frozenset(
                    a for a in extra if a.predicate.name not in model.monotone_predicates
                )
            if (out.finished or not require_finished) and expected <= reached and not extra:
                state = out.states[-1]
                break
            if not retry_mispredictions:
                raise AssertionError(
                    f"{name}: finished={out.finished}, reached {sorted(map(str, reached))}, "
                    f"predicted {sorted(map(str, expected))}"
                )
        else:
            raise AssertionError(f"{name} never reached its prediction in {samples} samples")
    return state


def abstract_atoms(model: PlanningModel, state: ObjectCentricState) -> set[str]:
    """The model's abstract state of ``state`` as strings (``"Holding(robot, cube1)"``), for
    tests that compare it with an expected set."""
    return {str(a) for a in model.abstract(state)}


def move_object(state: ObjectCentricState, obj: Object, xyz: Sequence[float]) -> None:
    """Set ``obj``'s x, y and z features in ``state`` (a hand-built test state)."""
    for feature, value in zip(("x", "y", "z"), xyz, strict=True):
        state.set(obj, feature, float(value))
