"""VLA: a policy served out of process over openpi's protocol (π0.5 in the paper).

The paper's VLA is π0.5 fine-tuned with openpi on the KinDER demonstrations. π0.5 itself cannot
run on this project's stack (its weights and tokenizer live on a model hub these machines cannot
reach, and lerobot 0.4.4's π0.5 needs a git-only transformers fork), so this agent is the
evaluation half: it speaks openpi's WebSocket + msgpack-numpy protocol
(:mod:`kinder_bench.policy_server`) to any policy server, such as openpi's
``scripts/serve_policy.py`` with a fine-tuned checkpoint on a GPU machine, or our own
:class:`~kinder_bench.policy_server.server.PolicyServer`.

Per episode the agent opens one connection. When its action queue is empty it sends an openpi
request::

    {"observation": {"base_0_rgb": uint8 224×224×3,   # 2D: the env render; 3D: see below
                     "state": float32 robot features},
     "prompt": the env's task, "batch_size": None}

with the images, robot state and task text made exactly as the demonstration datasets make them
(``camera_frames`` at ``image_size`` and ``StateSplit`` of :mod:`kinder_gym.demos.layout`,
``env_task`` of :mod:`kinder_gym.demos.lerobot_format`), and executes the first
``action_horizon`` actions (8, as upstream) of the returned chunk, each sliced to the env's action
size and clipped to its bounds. The runner counts the whole request as inference time. A server
that cannot be reached, fails, times out or replies malformed data ends the episode as a failure
whose error names the cause.

Cameras in 3D (``cameras``): upstream's 3D evaluation sent the overview image only (baselines spec
§3.5: its ``scripts/eval.py`` bridge passes the overview image), so the default, ``overview``,
sends the overview camera as ``base_0_rgb`` and no other image. ``all`` sends the three cameras
our openpi export (:mod:`kinder_gym.demos.openpi_format`) writes, as ``base_0_rgb`` (base),
``left_wrist_0_rgb`` (wrist) and ``right_wrist_0_rgb`` (overview), which a policy trained on
that export expects (docs/vla.md's 3D config); a 3D run with ``all`` is a labelled variant of the
paper's VLA (``kinder_bench/data/paper_settings.csv``). In 2D both send the one render.

Deviation: upstream sends no environment state (π0.5 sees images, robot state and the prompt);
we add ``observation["environment_state"]`` (float32, every non-robot feature) so that
DPES-style policies can be served the same way, and a top-level ``"kinder"`` entry
(``observation``: the full float64 Box observation; ``episode``: this agent's episode count,
which changes at every ``reset``; ``seed``: the agent's seed), with which ``kinder serve`` runs
our own agents (DP, DPES, ...) exactly as in process and resets their history per episode
(:mod:`kinder_bench.policy_server.agent_policy`). openpi policies ignore keys they do not use.
A served chunk shorter than ``action_horizon`` (``kinder serve`` answers one action) is executed
whole, and the next step asks again.
"""

from __future__ import annotations

import dataclasses
from collections import deque
from typing import Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_bench.agents.base import Agent, AgentFailure
from kinder_gym.demos.layout import StateSplit, camera_frames
from kinder_gym.demos.lerobot_format import env_task

FloatArray = NDArray[np.float64]

#: The values of :attr:`VLAArgs.cameras`.
CAMERA_MODES = ("all", "overview")


@dataclasses.dataclass(frozen=True)
class VLAArgs:
    """Arguments of the ``vla`` agent."""

    url: str = ""
    """The policy server, ``ws://HOST:PORT`` (required)."""
    action_horizon: int = 8
    """Actions executed from each returned chunk before asking again (upstream: 8)."""
    timeout: float = 60.0
    """Seconds to wait for the connection and for each reply before failing the episode."""
    image_size: int = 224
    """Side of the square images sent (the datasets' and the paper's 224)."""
    prompt: str = ""
    """The language instruction; empty: the env's task description."""
    api_key: str = ""
    """Sent as ``Authorization: Api-Key ...`` when non-empty."""
    cameras: str = "overview"
    """3D images sent: ``overview`` (the overview image only, as upstream's 3D evaluation) or
    ``all`` (base, wrist and overview, as our openpi export writes them; a variant). See the
    module docstring."""

    def __post_init__(self) -> None:
        if self.cameras not in CAMERA_MODES:
            raise ValueError(f"cameras must be one of {CAMERA_MODES}, got {self.cameras!r}")
        if self.action_horizon < 1:
            raise ValueError(f"action_horizon must be >= 1, got {self.action_horizon}")
        if self.image_size < 8:
            raise ValueError(f"image_size must be >= 8, got {self.image_size}")
        if self.timeout <= 0:
            raise ValueError(f"timeout must be > 0, got {self.timeout}")


class VLAAgent(Agent[VLAArgs]):
    """Acts by asking a policy server for action chunks (see the module docstring)."""

    name = "vla"
    Args = VLAArgs

    @classmethod
    def unavailable(cls, args: Any, env_id: str) -> str | None:
        """Needs a policy server (π0.5 needs a GPU machine with openpi; see the README)."""
        del env_id
        if getattr(args, "url", ""):
            return None
        return (
            "needs a policy server: --arg url=ws://HOST:PORT (π0.5 runs in openpi's own "
            "environment on a GPU; see the kinder-bench README, 'VLA')"
        )

    def __init__(self, env: gymnasium.Env[Any, Any], args: VLAArgs, seed: int) -> None:
        super().__init__(env, args, seed)
        if not args.url:
            raise ValueError(
                "the vla agent needs a policy server: --arg url=ws://HOST:PORT (see the "
                "kinder-bench README, 'VLA')"
            )
        self._split = StateSplit.from_env(self.model)
        self._prompt = args.prompt or env_task(env)
        self._queue: deque[FloatArray] = deque()
        self._client: Any = None
        self._episode = -1
        self.last_server_timing: dict[str, float] = {}

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        from kinder_bench.policy_server.client import PolicyClient, PolicyServerError

        del obs, info
        self.close()
        self._queue.clear()
        self._episode += 1
        try:
            self._client = PolicyClient(self.args.url, self.args.timeout, self.args.api_key or None)
        except PolicyServerError as e:
            raise AgentFailure(str(e)) from e

    def request(self, obs: Any) -> dict[str, Any]:
        """The observation message for ``obs`` (the live state's cameras, robot state, prompt)."""
        vector = np.asarray(obs, dtype=np.float64)
        views = camera_frames(self.model, self.observed_state(vector), self.args.image_size)
        robot, environment = self._split.split(vector)
        observation: dict[str, Any] = {
            "state": np.asarray(robot, dtype=np.float32),
            "environment_state": np.asarray(environment, dtype=np.float32),
        }
        if "render" in views:
            observation["base_0_rgb"] = views["render"]
        elif self.args.cameras == "overview":
            observation["base_0_rgb"] = views["overview"]
        else:
            observation["base_0_rgb"] = views["base"]
            observation["left_wrist_0_rgb"] = views["wrist"]
            observation["right_wrist_0_rgb"] = views["overview"]
        kinder = {"observation": vector, "episode": self._episode, "seed": self.seed}
        return {
            "observation": observation,
            "prompt": self._prompt,
            "batch_size": None,
            "kinder": kinder,
        }

    def act(self, obs: Any) -> FloatArray:
        from kinder_bench.policy_server.client import PolicyServerError

        if self._client is None:
            raise AgentFailure("vla: act() before reset()")
        if not self._queue:
            try:
                reply = self._client.infer(self.request(obs))
            except PolicyServerError as e:
                raise AgentFailure(str(e)) from e
            chunk = np.asarray(reply["actions"], dtype=np.float64)
            dim = self.action_space.shape[0]
            if chunk.ndim == 1:
                chunk = chunk[None]
            if chunk.ndim != 2 or chunk.shape[0] == 0 or chunk.shape[1] < dim:
                raise AgentFailure(
                    f"vla: the server's actions have shape {chunk.shape}; expected "
                    f"(horizon, >= {dim})"
                )
            if not np.all(np.isfinite(chunk[:, :dim])):
                raise AgentFailure("vla: the server's actions contain NaN or inf")
            self._queue.extend(chunk[: self.args.action_horizon, :dim])
            timing = reply.get("server_timing")
            self.last_server_timing = dict(timing) if isinstance(timing, dict) else {}
        return self.clip(self._queue.popleft())

    def close(self) -> None:
        if getattr(self, "_client", None) is not None:
            self._client.close()
            self._client = None

    def __del__(self) -> None:
        self.close()
