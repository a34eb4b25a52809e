"""VLA: a policy served out of process over openpi's protocol (π0.5 in the paper).

The paper's VLA is π0.5 fine-tuned with openpi on the KinDER demonstrations. π0.5 itself cannot
run on this project's stack (its weights and tokenizer live on a model hub these machines cannot
reach, and lerobot 0.4.4's π0.5 needs a git-only transformers fork), so this agent is the
evaluation half: it speaks openpi's WebSocket + msgpack-numpy protocol
(:mod:`kinder_bench.policy_server`) to any policy server, such as openpi's
``scripts/serve_policy.py`` with a fine-tuned checkpoint on a GPU machine, or our own
:class:`~kinder_bench.policy_server.server.PolicyServer`.

Per episode the agent opens one connection. When its action queue is empty it sends the request
upstream KinDER's openpi bridge sends::

    {"observation": {"base_0_rgb": uint8 224×224×3,        # 3D: base camera; 2D: the env render
                     "left_wrist_0_rgb": uint8 224×224×3,  # 3D: wrist camera (absent in 2D)
                     "right_wrist_0_rgb": uint8 224×224×3, # 3D: overview camera (absent in 2D)
                     "state": float32 robot features},
     "prompt": the env's task, "batch_size": None}

images resized with padding to ``image_size`` (aspect kept, black bars), and executes the first
``action_horizon`` actions (8, as upstream) of the returned chunk, each sliced to the env's action
size and clipped to its bounds. The runner counts the whole request as inference time. A server
that cannot be reached, fails, times out or replies malformed data ends the episode as a failure
whose error names the cause.

Deviation: upstream sends no environment state (π0.5 sees images, robot state and the prompt);
we add ``observation["environment_state"]`` (float32, every non-robot feature) so that
DPES-style policies can be served the same way. openpi policies ignore keys they do not use.
"""

from __future__ import annotations

import dataclasses
from collections import deque
from typing import Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_bench.agents.base import Agent, AgentFailure
from kinder_core import ObjectCentricEnv, ObjectCentricState

FloatArray = NDArray[np.float64]


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
    """Side of the square images sent (resize with padding; the paper's 224)."""
    prompt: str = ""
    """The language instruction; empty: the env's task description."""
    api_key: str = ""
    """Sent as ``Authorization: Api-Key ...`` when non-empty."""

    def __post_init__(self) -> None:
        if self.action_horizon < 1:
            raise ValueError(f"action_horizon must be >= 1, got {self.action_horizon}")
        if self.image_size < 8:
            raise ValueError(f"image_size must be >= 8, got {self.image_size}")
        if self.timeout <= 0:
            raise ValueError(f"timeout must be > 0, got {self.timeout}")


def resize_with_pad(image: NDArray[np.uint8], size: int) -> NDArray[np.uint8]:
    """``image`` scaled to fit a ``size`` × ``size`` square (bilinear), centred on black."""
    from PIL import Image

    h, w = image.shape[:2]
    scale = size / max(h, w)
    nh, nw = max(1, round(h * scale)), max(1, round(w * scale))
    resized = np.asarray(Image.fromarray(image).resize((nw, nh), Image.Resampling.BILINEAR))
    out = np.zeros((size, size, 3), dtype=np.uint8)
    top, left = (size - nh) // 2, (size - nw) // 2
    out[top : top + nh, left : left + nw] = resized[..., :3]
    return out


def camera_images(model: ObjectCentricEnv, state: ObjectCentricState) -> dict[str, Any]:
    """The views a policy sees, keyed ``base``/``wrist``/``overview`` (3D) or ``render`` (2D)."""
    render_cameras = getattr(model, "render_cameras", None)
    if render_cameras is None:
        return {"render": model.render_state(state)}
    frames: dict[str, Any] = render_cameras(state)
    if {"base", "wrist", "overview"} <= frames.keys():  # Kinematic3D
        return {k: frames[k] for k in ("base", "wrist", "overview")}
    # Dynamic3D: the task's cameras first, then robot_base and robot_wrist.
    task_cameras = [k for k in frames if k not in ("robot_base", "robot_wrist")]
    return {
        "base": frames["robot_base"],
        "wrist": frames["robot_wrist"],
        "overview": frames[task_cameras[0]],
    }


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
        model = self.model
        names = model.box_space.feature_names
        self._robot = np.asarray([i for i, n in enumerate(names) if n.startswith("robot.")])
        self._other = np.asarray([i for i, n in enumerate(names) if not n.startswith("robot.")])
        self._prompt = args.prompt or str(model.metadata.get("summary", ""))
        self._queue: deque[FloatArray] = deque()
        self._client: Any = None
        self.last_server_timing: dict[str, float] = {}

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        from kinder_bench.policy_server.client import PolicyClient, PolicyServerError

        del obs, info
        self.close()
        self._queue.clear()
        try:
            self._client = PolicyClient(self.args.url, self.args.timeout, self.args.api_key or None)
        except PolicyServerError as e:
            raise AgentFailure(str(e)) from e

    def request(self, obs: Any) -> dict[str, Any]:
        """The observation message for ``obs`` (the live state's cameras, robot state, prompt)."""
        vector = np.asarray(obs, dtype=np.float64)
        state = self.observed_state(vector)
        size = self.args.image_size
        views = {k: resize_with_pad(v, size) for k, v in camera_images(self.model, state).items()}
        observation: dict[str, Any] = {
            "state": vector[self._robot].astype(np.float32),
            "environment_state": vector[self._other].astype(np.float32),
        }
        if "render" in views:
            observation["base_0_rgb"] = views["render"]
        else:
            observation["base_0_rgb"] = views["base"]
            observation["left_wrist_0_rgb"] = views["wrist"]
            observation["right_wrist_0_rgb"] = views["overview"]
        return {"observation": observation, "prompt": self._prompt, "batch_size": None}

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
