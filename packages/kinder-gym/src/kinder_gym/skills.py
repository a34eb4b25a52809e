"""Skills: parameterized controllers (options) paired with the operators they implement.

A :class:`Controller` is a *ground* option: it is built for a tuple of objects (matching an
operator's parameters) and reset with a vector of continuous parameters from its
:attr:`Controller.params_space`. It has

* a sampler (:meth:`Controller.sample_parameters`) proposing parameters for a state,
* an initiation check (:meth:`Controller.initiable`),
* internal state (typically a motion plan computed in :meth:`Controller.reset`),
* a policy (:meth:`Controller.step`) that emits env actions, fed the latest state through
  :meth:`Controller.observe`,
* termination (:meth:`Controller.terminated`).

A controller that cannot be executed (no feasible motion, a goal pose in collision, a sampler out
of attempts, ...) raises :class:`SkillFailure` and nothing else, so planners can resample.

A :class:`Skill` pairs a :class:`~kinder_gym.operators.LiftedOperator` with a controller class and
a *context* (usually the env model the controller reads its constants from); grounding it on
objects gives a :class:`GroundSkill`. :func:`execute_skill` rolls a ground skill out with a
transition function (for planners, the env's own ``transition``).
"""

from __future__ import annotations

import abc
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricState
from kinder_gym.operators import GroundOperator, LiftedOperator

FloatArray = NDArray[np.float64]

#: ``transition(state, action) -> (next_state, reward, terminated)``, as ``ObjectCentricEnv``.
TransitionFn = Callable[[ObjectCentricState, FloatArray], tuple[ObjectCentricState, float, bool]]


class SkillFailure(RuntimeError):
    """A skill cannot be executed from this state with these parameters (planners resample)."""


class Controller(abc.ABC):
    """A ground parameterized controller (see the module docstring).

    Subclasses set the class attributes :attr:`params_space` (a ``Box``) and :attr:`params_doc`
    (what each dimension means, with units), and implement :meth:`reset` and :meth:`step`
    (and usually :meth:`terminated`).

    Args:
        objects: The objects the controller acts on, in its operator's parameter order.
        context: Whatever the controller needs besides the state (typically the env model).
    """

    params_space: ClassVar[spaces.Box] = spaces.Box(0.0, 1.0, (0,), dtype=np.float64)
    params_doc: ClassVar[str] = "No continuous parameters."

    def __init__(self, objects: Sequence[Object], context: Any) -> None:
        self.objects = tuple(objects)
        self.context = context
        self.state: ObjectCentricState | None = None
        self.params: FloatArray = np.zeros(self.params_space.shape, dtype=np.float64)

    def sample_parameters(self, state: ObjectCentricState, rng: np.random.Generator) -> FloatArray:
        """Propose parameters for ``state``. Default: uniform over :attr:`params_space`."""
        low = self.params_space.low.astype(np.float64)
        high = self.params_space.high.astype(np.float64)
        return rng.uniform(low, high)

    def initiable(self, state: ObjectCentricState) -> bool:
        """Whether the skill may start in ``state``. Default: always."""
        del state
        return True

    def reset(self, state: ObjectCentricState, params: Sequence[float] | FloatArray) -> None:
        """Start from ``state`` with ``params``; raise :class:`SkillFailure` if infeasible.

        Subclasses call ``super().reset`` first (it stores the state and validated params).
        """
        p = np.asarray(params, dtype=np.float64).reshape(-1)
        if p.shape != self.params_space.shape:
            raise ValueError(
                f"{type(self).__name__}: params must have shape {self.params_space.shape}, got "
                f"{p.shape}"
            )
        if not np.all(np.isfinite(p)):
            raise ValueError(f"{type(self).__name__}: params contain NaN or inf: {p}")
        self.params = p
        self.state = state

    def observe(self, state: ObjectCentricState) -> None:
        """Feed the state reached after the last action."""
        self.state = state

    @abc.abstractmethod
    def step(self) -> FloatArray:
        """The next env action (raise :class:`SkillFailure` if the skill cannot continue)."""

    @abc.abstractmethod
    def terminated(self) -> bool:
        """Whether the skill has finished."""

    @classmethod
    def describe(cls) -> str:
        """The parameter space and its meaning (used in prompts and docs)."""
        low = np.round(cls.params_space.low, 4).tolist()
        high = np.round(cls.params_space.high, 4).tolist()
        return f"params_space=Box(low={low}, high={high}): {cls.params_doc}"


@dataclass(frozen=True)
class Skill:
    """A lifted skill: an operator and the controller class that implements it.

    Args:
        operator: The operator whose effects a successful execution achieves.
        controller_cls: The controller class; instantiated as ``controller_cls(objects, context)``.
        context: Passed to every controller (typically the env model).
    """

    operator: LiftedOperator
    controller_cls: type[Controller]
    context: Any = field(default=None, compare=False, repr=False)

    @property
    def name(self) -> str:
        """The operator's name."""
        return self.operator.name

    @property
    def params_space(self) -> spaces.Box:
        """The controller's parameter space."""
        return self.controller_cls.params_space

    def ground(self, objects: Sequence[Object]) -> GroundSkill:
        """The ground skill on ``objects`` (a fresh controller)."""
        op = self.operator.ground(objects)
        return GroundSkill(self, op, self.controller_cls(op.objects, self.context))

    def describe(self) -> str:
        """``Name(?a:type, ...)`` and the parameter space (for prompts)."""
        return f"{self.operator!r} {self.controller_cls.describe()}"


@dataclass
class GroundSkill:
    """A skill grounded on objects: its ground operator and a controller instance."""

    skill: Skill
    operator: GroundOperator
    controller: Controller

    @property
    def name(self) -> str:
        """The ground operator's name, e.g. ``Pick(robot, block0)``."""
        return self.operator.name


@dataclass
class SkillRollout:
    """The result of :func:`execute_skill`: ``len(states) == len(actions) + 1``."""

    states: list[ObjectCentricState]
    actions: list[FloatArray]
    terminated: bool
    """Whether the env's goal was reached on the last transition."""
    finished: bool
    """Whether the controller said it was done (else the step budget or the time ran out)."""
    timed_out: bool = False
    """Whether the rollout stopped because the deadline passed."""


def execute_skill(
    controller: Controller,
    state: ObjectCentricState,
    params: Sequence[float] | FloatArray,
    transition: TransitionFn,
    max_steps: int,
    stop_on_goal: bool = True,
    deadline: float = math.inf,
    clock: Callable[[], float] = time.perf_counter,
) -> SkillRollout:
    """Run ``controller`` from ``state`` with ``params`` through ``transition``.

    Stops when the controller terminates, after ``max_steps`` actions, or (with ``stop_on_goal``)
    when a transition reports that the env's goal is reached, or when ``deadline`` (a
    ``clock()`` value: wall-clock by default) passes. Raises :class:`SkillFailure` if the
    controller is not initiable or fails.

    The controller is handed copies of the states: one that edits what it is given (a skill
    once shifted a grasp target in place and so moved a cube in the planner's state) cannot
    change ``state`` or the rollout.
    """
    if not controller.initiable(state):
        raise SkillFailure(f"{type(controller).__name__}{controller.objects} is not initiable")
    controller.reset(state.copy(), params)
    states = [state]
    actions: list[FloatArray] = []
    terminated = False
    for k in range(max_steps):
        if controller.terminated():
            break
        if k % 16 == 0 and clock() > deadline:
            return SkillRollout(states, actions, False, False, timed_out=True)
        action = controller.step()
        state, _, terminated = transition(state, action)
        controller.observe(state.copy())
        states.append(state)
        actions.append(action)
        if terminated and stop_on_goal:
            break
    return SkillRollout(states, actions, terminated, controller.terminated())
