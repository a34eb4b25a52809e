"""The environment contract every KinDER environment follows.

:class:`ObjectCentricEnv` is a ``gymnasium.Env`` whose observations are
:class:`~kinder_core.state.ObjectCentricState` objects. A family implements four things:

* ``_sample_initial_state(rng)``: draw a valid initial state from the env's seeded RNG;
* ``_transition(state, action)``: the dynamics, a function of the state and action alone;
* ``goal_reached(state)``: the task's success predicate;
* ``_render_state(state)``: an RGB frame of a state.

The base class turns these into ``reset``/``step`` with the paper's sparse reward (−1 per step,
``terminated`` when the goal holds), a pure ``transition`` for planners,
``get_state``/``set_state``, action validation, pickling and ``metadata`` parsed from the class
docstring.

Determinism is part of the contract: the same seed gives the same episode in any process, and
``set_state(s); step(a)`` gives the same result on every call. Simulator-backed families therefore
load ``state`` into their simulator at the start of every ``_transition`` (skipping the load when
the simulator already holds exactly that state is a valid optimisation).
"""

from __future__ import annotations

import abc
from collections.abc import Mapping
from typing import Any, SupportsFloat

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from numpy.typing import ArrayLike, NDArray

from kinder_core.docs import parse_doc_sections
from kinder_core.objects import Object
from kinder_core.spaces import FeatureBounds, ObjectCentricBoxSpace, ObjectCentricStateSpace
from kinder_core.state import FloatArray, ObjectCentricState, StateLayout

RESET_OPTIONS = ("init_state",)


class ObjectCentricEnv(gymnasium.Env[ObjectCentricState, FloatArray], abc.ABC):
    """Base class of all KinDER environments (see the module docstring for the contract).

    Subclasses set ``self.action_space`` (a ``Box``) and ``self.observation_space`` (an
    :class:`ObjectCentricStateSpace`) in ``__init__`` after calling ``super().__init__``, and write
    their user documentation as the class docstring with the sections listed in
    :data:`kinder_core.docs.REQUIRED_SECTIONS`.

    Actions: a wrong shape, NaN or inf raises ``ValueError`` naming the env and the expected space;
    finite values outside the bounds are clipped to the bounds.
    """

    metadata: dict[str, Any] = {  # noqa: RUF012 (gymnasium's convention; copied per instance)
        "render_modes": ["rgb_array"],
        "render_fps": 20,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }
    action_space: spaces.Box  # type: ignore[assignment]
    observation_space: ObjectCentricStateSpace

    _init_args: tuple[tuple[Any, ...], dict[str, Any]]

    def __new__(cls, *args: Any, **kwargs: Any) -> ObjectCentricEnv:
        self = super().__new__(cls)
        # Remembered so that pickling can rebuild the env (simulators are not picklable).
        self._init_args = (args, dict(kwargs))
        return self

    def __init__(self, render_mode: str | None = "rgb_array") -> None:
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(
                f"{type(self).__name__}: render_mode must be None or one of "
                f"{self.metadata['render_modes']}, got {render_mode!r}"
            )
        self.render_mode = render_mode
        self._state: ObjectCentricState | None = None
        self._exemplar: ObjectCentricState | None = None
        self._box_space: ObjectCentricBoxSpace | None = None
        self._action_bounds: tuple[FloatArray, FloatArray] | None = None
        args, kwargs = self._init_args
        call = ", ".join([*map(repr, args), *(f"{k}={v!r}" for k, v in kwargs.items())])
        self.metadata = {
            **type(self).metadata,
            **parse_doc_sections(type(self)),
            "variant": f"{type(self).__name__}({call})",
        }

    # -- what a family implements ---------------------------------------------------------------
    @abc.abstractmethod
    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        """A valid initial state drawn from ``rng`` (and nothing else)."""

    @abc.abstractmethod
    def _transition(self, state: ObjectCentricState, action: FloatArray) -> ObjectCentricState:
        """The next state. ``state`` is a private copy the method may modify and return;
        ``action`` is already validated and clipped."""

    @abc.abstractmethod
    def goal_reached(self, state: ObjectCentricState) -> bool:
        """The task's success predicate."""

    def goals_reached(self, data: FloatArray, layout: StateLayout) -> NDArray[np.bool_]:
        """``(N,)``: :meth:`goal_reached` of the ``N`` states whose feature vectors are the rows
        of ``data`` in ``layout``. Planners that score many candidate states at once (MBRL's
        learned-model rollouts) call it. The default loops over the rows; a family may override
        it with whole-array numpy that computes each row's verdict with the same operations as
        :meth:`goal_reached`, so the verdicts are the same."""
        return np.array(
            [self.goal_reached(ObjectCentricState(layout, row)) for row in data], dtype=bool
        )

    @abc.abstractmethod
    def _render_state(self, state: ObjectCentricState) -> NDArray[np.uint8]:
        """An H×W×3 uint8 image of ``state``."""

    def reward(
        self,
        state: ObjectCentricState,
        action: FloatArray,
        next_state: ObjectCentricState,
        terminated: bool,
    ) -> float:
        """The paper's sparse reward: −1 on every step. Families may override."""
        return -1.0

    def box_objects(self) -> list[Object]:
        """The Box view's objects in vector order. Default: sorted by name; families override
        (typically the robot first, then the others by name)."""
        return sorted(self.exemplar_state().objects, key=lambda o: o.name)

    def feature_bounds(self) -> FeatureBounds:
        """Finite bounds per feature (``"x"``) or per type and feature (``"robot.x"``)."""
        return {}

    # -- derived --------------------------------------------------------------------------------
    def exemplar_state(self) -> ObjectCentricState:
        """An initial state from a fixed private RNG (seed 0); the live episode's RNG is untouched.
        Used to fix the object list of the Box view."""
        if self._exemplar is None:
            self._exemplar = self._sample_initial_state(np.random.default_rng(0))
        return self._exemplar

    @property
    def box_space(self) -> ObjectCentricBoxSpace:
        """The fixed-object Box view of this env's states."""
        if self._box_space is None:
            self._box_space = self.observation_space.to_box(
                self.box_objects(), bounds=self.feature_bounds()
            )
            self.metadata["observation_table"] = self._box_space.markdown_table()
        return self._box_space

    @property
    def env_name(self) -> str:
        """The registered id if made through the registry, else the class name."""
        return self.spec.id if self.spec is not None else type(self).__name__

    # -- gymnasium API --------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[ObjectCentricState, dict[str, Any]]:
        """Start an episode: sample an initial state, or use ``options["init_state"]`` (a state
        or a Box vector)."""
        super().reset(seed=seed)
        options = options or {}
        unknown = sorted(set(options) - set(RESET_OPTIONS))
        if unknown:
            raise ValueError(
                f"{self.env_name}: unknown reset option(s) {unknown}; known: {list(RESET_OPTIONS)}"
            )
        if options.get("init_state") is not None:
            state = self._coerce_state(options["init_state"], "options['init_state']")
        else:
            state = self._sample_initial_state(self.np_random)
        self._state = state
        return state.copy(), {"success": self.goal_reached(state)}

    def step(
        self, action: ArrayLike
    ) -> tuple[ObjectCentricState, SupportsFloat, bool, bool, dict[str, Any]]:
        """Advance the live episode by one action."""
        if self._state is None:
            raise RuntimeError(f"{self.env_name}: call reset() before step()")
        a = self.check_action(action)
        next_state, reward, terminated = self._advance(self._state, a)
        self._state = next_state
        return next_state.copy(), reward, terminated, False, {"success": terminated}

    def transition(
        self, state: ObjectCentricState | ArrayLike, action: ArrayLike
    ) -> tuple[ObjectCentricState, float, bool]:
        """``(next_state, reward, terminated)`` from ``state`` under ``action``.

        Pure: the live episode (``get_state()``) is not disturbed. This is the model planners
        and MPC roll out.
        """
        s = self._coerce_state(state, "state")
        next_state, reward, terminated = self._advance(s, self.check_action(action))
        return next_state, reward, terminated

    def _advance(
        self, state: ObjectCentricState, action: FloatArray
    ) -> tuple[ObjectCentricState, float, bool]:
        next_state = self._transition(state.copy(), action)
        terminated = bool(self.goal_reached(next_state))
        return next_state, float(self.reward(state, action, next_state, terminated)), terminated

    def get_state(self) -> ObjectCentricState:
        """A copy of the live state."""
        if self._state is None:
            raise RuntimeError(f"{self.env_name}: call reset() before get_state()")
        return self._state.copy()

    def set_state(self, state: ObjectCentricState | ArrayLike) -> None:
        """Replace the live state (a state or a Box vector)."""
        self._state = self._coerce_state(state, "state")

    def render(self) -> NDArray[np.uint8] | None:
        """An RGB frame of the live state (``None`` with a warning when ``render_mode`` is None)."""
        if self.render_mode is None:
            gymnasium.logger.warn(
                f"{self.env_name}: render() called without a render_mode; make the env with "
                f"render_mode='rgb_array'"
            )
            return None
        if self._state is None:
            raise RuntimeError(f"{self.env_name}: call reset() before render()")
        return self.render_state(self._state)

    def render_state(self, state: ObjectCentricState) -> NDArray[np.uint8]:
        """An RGB frame of any state of this env."""
        return self._render_state(state)

    # -- validation -----------------------------------------------------------------------------
    def check_action(self, action: ArrayLike) -> FloatArray:
        """Validate an action and clip it to the bounds (see the class docstring)."""
        if self._action_bounds is None:
            self._action_bounds = (
                self.action_space.low.astype(np.float64),
                self.action_space.high.astype(np.float64),
            )
        low, high = self._action_bounds
        try:
            a = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise ValueError(
                f"{self.env_name}: action {action!r} is not numeric; expected an array in "
                f"{self.action_space}"
            ) from e
        if a.shape != low.shape:
            raise ValueError(
                f"{self.env_name}: action has shape {a.shape}; expected shape {low.shape} in "
                f"{self.action_space}"
            )
        if not np.all(np.isfinite(a)):
            raise ValueError(
                f"{self.env_name}: action contains NaN or inf ({a}); expected finite values in "
                f"{self.action_space}"
            )
        return np.clip(a, low, high)

    def _coerce_state(self, x: ObjectCentricState | ArrayLike, what: str) -> ObjectCentricState:
        box = self.box_space
        if isinstance(x, ObjectCentricState):
            if x.layout is not box.layout and x.objects != box.layout.objects:
                raise ValueError(
                    f"{self.env_name}: {what} has objects {x.layout.names}; this env's states "
                    f"have {box.layout.names}"
                )
            state = x.copy()
        else:
            try:
                state = box.devectorize(x)
            except ValueError as e:
                raise ValueError(f"{self.env_name}: {what}: {e}") from None
        if not np.all(np.isfinite(state.data)):
            raise ValueError(f"{self.env_name}: {what} contains NaN or inf")
        return state

    # -- pickling -------------------------------------------------------------------------------
    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        args, kwargs = self._init_args
        rng_state = self._np_random.bit_generator.state if self._np_random is not None else None
        return (
            _rebuild_env,
            (type(self), args, kwargs, self._state, rng_state, self._np_random_seed, self.spec),
        )


def _rebuild_env(
    cls: type[ObjectCentricEnv],
    args: tuple[Any, ...],
    kwargs: Mapping[str, Any],
    state: ObjectCentricState | None,
    rng_state: dict[str, Any] | None,
    rng_seed: int | None,
    spec: Any,
) -> ObjectCentricEnv:
    env = cls(*args, **kwargs)
    env.spec = spec
    env._state = state
    if rng_state is not None:
        bit_gen = getattr(np.random, rng_state["bit_generator"])()
        bit_gen.state = rng_state
        env._np_random = np.random.Generator(bit_gen)
        env._np_random_seed = rng_seed
    return env
