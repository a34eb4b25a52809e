"""The agent interface every KinDERBench baseline implements.

An agent is made once per episode from the evaluation env (for its spaces and, for planners, its
model), a dataclass of arguments and an integer seed. The runner then calls :meth:`Agent.reset`
with the first observation and info, and :meth:`Agent.act` once per step. Only the time spent
inside these two calls counts as the agent's inference time.

Planners reach the environment's model through :attr:`Agent.model`, the object-centric env behind
the Box view: its ``transition(state, action)`` is pure, so rolling out candidate plans never
disturbs the live episode. Planners must not call ``step``/``reset``/``set_state`` on it.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import Any, ClassVar, Generic, TypeVar, cast

import gymnasium
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from kinder_core import ObjectCentricEnv, ObjectCentricState


class AgentFailure(RuntimeError):
    """An agent gives up on an episode (e.g. a planner found no plan). Scored as a failure."""


@dataclasses.dataclass(frozen=True)
class NoArgs:
    """An agent without arguments."""


ArgsT = TypeVar("ArgsT")


class Agent(abc.ABC, Generic[ArgsT]):
    """Base class of all agents.

    Subclasses set the class attributes ``name`` (the id used on the command line) and ``Args`` (a
    frozen dataclass with a docstring per field, CleanRL style), and implement :meth:`act` (and
    :meth:`reset` when they keep per-episode state).

    **Can it run here?** An agent that needs something this machine may lack (a trained
    checkpoint, a model endpoint, a GPU, a planning model for the env's family) overrides the
    classmethod :meth:`unavailable`, which returns ``None`` when the agent can run on an env with
    given arguments, else one short line saying what is missing and how to supply it. The line
    starts with "needs" so it reads well in tables, e.g.:

    * ``"needs a checkpoint: --arg checkpoint=DIR (train one with `kinder train ppo`)"``
    * ``"needs a model endpoint: --arg base_url=URL or OPENAI_BASE_URL"``
    * ``"needs a CUDA GPU"``
    * ``"needs a planning model for the Dynamo3D family"``

    It must be cheap and side-effect free (look at files, environment variables, registries; do
    not load weights, start processes or touch the network), because it is asked for every agent
    × env pair: ``kinder bench run --agent all`` skips (and lists) the pairs with a reason and
    ``kinder bench run --agent NAME`` refuses them with it, ``kinder bench report --paper`` writes
    the reason in the cells that were not run, and ``kinder agents`` shows it. The default says
    every agent can run everywhere.

    Args:
        env: The evaluation env (a registered id's Box view). Used for its spaces and its model.
        args: The agent's arguments (an instance of ``Args``).
        seed: Seeds :attr:`rng`, the agent's only source of randomness.
    """

    name: ClassVar[str]
    Args: ClassVar[type[Any]] = NoArgs

    def __init__(self, env: gymnasium.Env[Any, Any], args: ArgsT, seed: int) -> None:
        if not isinstance(args, self.Args):
            raise TypeError(
                f"{type(self).__name__} expects arguments of type {self.Args.__name__}, "
                f"got {type(args).__name__}"
            )
        self.env = env
        self.args = args
        self.seed = seed
        self.rng = np.random.default_rng(seed)
        self.observation_space = env.observation_space
        if not isinstance(env.action_space, spaces.Box):
            raise ValueError(
                f"{type(self).__name__} needs a Box action space, got {env.action_space}"
            )
        self.action_space: spaces.Box = env.action_space

    @classmethod
    def unavailable(cls, args: Any, env_id: str) -> str | None:
        """Why this agent cannot run on ``env_id`` here with ``args`` (an ``Args``), or None.

        See the class docstring: one short line starting with "needs", naming what is missing
        and how to supply it; cheap and without side effects. The default: None (it can run).
        """
        del args, env_id
        return None

    @property
    def model(self) -> ObjectCentricEnv:
        """The env's object-centric model (``transition``, ``goal_reached``, ``box_space``)."""
        model = self.env.unwrapped
        if not isinstance(model, ObjectCentricEnv):
            raise TypeError(
                f"{type(self).__name__} plans on the env's model and needs a KinDER env "
                f"(ObjectCentricEnv), got {type(model).__name__}"
            )
        return model

    def observed_state(self, obs: Any) -> ObjectCentricState:
        """The observation as a state of :attr:`model`.

        When the observation is exactly the live state (no observation noise) this is the live
        state, which also carries any hidden simulator state; otherwise it is the devectorized
        observation.
        """
        model = self.model
        if isinstance(obs, ObjectCentricState):
            return obs.copy()
        live = model.get_state()
        if np.array_equal(model.box_space.vectorize(live), np.asarray(obs, dtype=np.float64)):
            return live
        return model.box_space.devectorize(obs)

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        """Start an episode from its first observation and info."""
        del obs, info

    def episode_info(self) -> dict[str, Any]:
        """Per-episode facts the runner stores in the record's ``agent_info`` (JSON-able; called
        after the episode, also when it ended in an error). Default: nothing."""
        return {}

    @abc.abstractmethod
    def act(self, obs: Any) -> NDArray[np.float64]:
        """The action for the current observation."""

    def clip(self, action: Any) -> NDArray[np.float64]:
        """An action clipped to the action bounds, as float64."""
        return cast(
            NDArray[np.float64],
            np.clip(
                np.asarray(action, dtype=np.float64), self.action_space.low, self.action_space.high
            ),
        )


def needs_checkpoint(args: Any, train_command: str) -> str | None:
    """The :meth:`Agent.unavailable` reason of a learned agent run without ``checkpoint``."""
    if getattr(args, "checkpoint", ""):
        return None
    return (
        f"needs a trained checkpoint: --arg checkpoint=DIR (train one with "
        f"`kinder train {train_command}`)"
    )
