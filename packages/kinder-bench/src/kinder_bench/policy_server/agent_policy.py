"""Serve any runner agent (DP, DPES, ...) over the policy protocol (``kinder serve``).

:class:`AgentService` holds one agent configuration (name, arguments, env id) and the env the
agent is made on; :meth:`AgentService.server` returns a
:class:`~kinder_bench.policy_server.server.PolicyServer` whose connections are
:class:`AgentPolicy` sessions. The ``vla`` agent (``kinder bench run --agent vla --arg
url=ws://HOST:PORT``) then evaluates the agent out of process, exactly as it evaluates π0.5.

**What a request must carry.** The agent acts from the env's full Box observation, which upstream
openpi requests do not hold. The ``vla`` agent adds a ``"kinder"`` entry to every request (openpi
policies ignore it: their input transforms pick the keys they use)::

    "kinder": {"observation": float64 (D,),  # the full Box observation, exactly
               "episode": int,               # changes when a new episode starts
               "seed": int}                  # the agent seed the runner drew for the episode

Without ``kinder.observation`` the observation is rebuilt from ``observation["state"]`` and
``observation["environment_state"]`` (float32, so rounded) with the env's
:class:`~kinder_gym.demos.layout.StateSplit`; a request with neither is refused.

**Episodes (the protocol extension).** A session makes a fresh agent, with seed ``kinder.seed``
(default: the service's ``seed``), and calls its ``reset`` on its first request and whenever
``kinder.episode`` differs from the previous request's, so an observation history (DP's two
frames, its action queue) never crosses episodes, whether a client opens one connection per
episode (as the ``vla`` agent does) or keeps one for many. ``reset`` gets an empty ``info``.

**One action per request.** The reply's ``actions`` is ``(1, A)``: the agent's next action. DP
conditions on the last two observations and keeps its own queue of 8 actions; answering its
8-action chunk at once would let the client skip the 7 observations in between, and the served
policy would differ from the in-process one. With one action per request the ``vla`` agent asks
every step, and a served agent's actions equal the in-process agent's exactly (tested), at the
cost of one round trip per step (counted as inference time, as for any served policy).

**One episode at a time.** Agents may share state across instances (DP's loaded policy keeps its
observation queues), so a service serves one session at a time: a second connection waits up to
``busy_timeout`` seconds for the first to close, then gets a server error naming the cause. Run
``kinder bench run --workers 1`` against one server, or one server per worker.

The service makes one agent when it starts, so imports and checkpoint loading happen before
the first client waits (inside its timeout). The env is the runner's (``make_env``). The agent
sees, as ``obs``, the received observation; the env's own state (reset once per episode, seed 0)
is never stepped, so agents that read the live state through
:meth:`~kinder_bench.agents.base.Agent.observed_state` get the state rebuilt from the
observation (exact for the Box vector; hidden simulator state is not sent).
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from typing import Any

import numpy as np

from kinder_bench.agents import Agent, make_agent
from kinder_bench.agents.base import AgentFailure
from kinder_gym.demos.layout import StateSplit


class AgentService:
    """One served agent configuration and the env it acts in.

    Args:
        agent: An agent name (``kinder agents``) or ``module:Class``.
        agent_args: Its arguments (strings are parsed by type, as on the command line).
        env_id: The env the agent acts in (any spelling ``kinder`` accepts).
        seed: The agent seed when a request carries none.
        busy_timeout: Seconds a second connection waits for the current one to end.
    """

    def __init__(
        self,
        agent: str,
        agent_args: Mapping[str, Any] | None,
        env_id: str,
        seed: int = 0,
        busy_timeout: float = 5.0,
    ) -> None:
        from kinder_bench.agents import agent_class, make_args
        from kinder_bench.evaluation.envs import make_env, resolve_env_id

        self.agent = agent
        self.env_id = resolve_env_id(env_id)
        cls = agent_class(agent)
        self.args = make_args(cls, agent_args)
        why = cls.unavailable(self.args, self.env_id)
        if why is not None:
            raise ValueError(f"agent {agent} cannot run on {self.env_id}: {why}")
        self.seed = seed
        self.busy_timeout = busy_timeout
        self.env = make_env(self.env_id, render_mode="rgb_array")
        self.split = StateSplit.from_env(self.env)
        self.dim = int(self.env.observation_space.shape[0])  # type: ignore[index]
        # Make one agent now, so that imports and checkpoint loading (DP's policy is cached per
        # process) happen before the first client waits on them, not inside its timeout.
        self.env.reset(seed=0)
        make_agent(agent, self.env, self.args, seed=seed)
        self.lock = threading.Lock()
        self.metadata: dict[str, Any] = {
            "policy": "kinder-agent",
            "agent": agent,
            "env_id": self.env_id,
            "action_horizon": 1,
        }

    def session(self) -> AgentPolicy:
        """A new connection's policy (waits for the previous session to end)."""
        if not self.lock.acquire(timeout=self.busy_timeout):
            raise RuntimeError(
                "busy: this server is serving another episode; it serves one at a time "
                "(run `kinder bench run --workers 1`, or one `kinder serve` per worker)"
            )
        return AgentPolicy(self)

    def server(self, host: str = "127.0.0.1", port: int = 8000) -> Any:
        """A :class:`~kinder_bench.policy_server.server.PolicyServer` of this service."""
        from kinder_bench.policy_server.server import PolicyServer

        return PolicyServer(self.session, host=host, port=port)

    def observation(self, message: Mapping[str, Any]) -> np.ndarray:
        """The full Box observation of a request (module docstring)."""
        kinder = message.get("kinder")
        if isinstance(kinder, Mapping) and kinder.get("observation") is not None:
            vector = np.asarray(kinder["observation"], dtype=np.float64).reshape(-1)
        else:
            obs = message.get("observation")
            if not (isinstance(obs, Mapping) and "state" in obs and "environment_state" in obs):
                raise ValueError(
                    f"the served agent {self.agent} needs the full observation: "
                    f"'kinder.observation', or 'observation.state' and "
                    f"'observation.environment_state' (the vla agent sends both)"
                )
            vector = self.split.join(
                np.asarray(obs["state"], dtype=np.float64).reshape(-1),
                np.asarray(obs["environment_state"], dtype=np.float64).reshape(-1),
            )
        if vector.shape != (self.dim,):
            raise ValueError(
                f"{self.env_id} observations have {self.dim} features; the request has "
                f"{vector.shape[0]} (is the client on the same env?)"
            )
        return vector


class AgentPolicy:
    """One connection's session: the agent of the current episode (module docstring)."""

    def __init__(self, service: AgentService) -> None:
        self.service = service
        self.metadata = dict(service.metadata)
        self._agent: Agent[Any] | None = None
        self._episode: Any = None
        self._closed = False

    def infer(self, observation: dict[str, Any]) -> dict[str, Any]:
        service = self.service
        obs = service.observation(observation)
        kinder = observation.get("kinder")
        kinder = kinder if isinstance(kinder, Mapping) else {}
        episode = kinder.get("episode")
        if self._agent is None or episode != self._episode:
            seed = int(kinder.get("seed", service.seed))
            service.env.reset(seed=0)
            self._agent = make_agent(service.agent, service.env, service.args, seed=seed)
            self._agent.reset(obs, {})
            self._episode = episode
        try:
            action = self._agent.act(obs)
        except AgentFailure as e:
            raise RuntimeError(f"the served agent {service.agent} gave up: {e}") from e
        return {"actions": np.asarray(action, dtype=np.float64).reshape(1, -1)}

    def close(self) -> None:
        """End the session (frees the service for the next connection); idempotent."""
        if not self._closed:
            self._closed = True
            self._agent = None
            self.service.lock.release()
