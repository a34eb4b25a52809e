"""A stand-in policy that replays a recorded episode, for testing the policy path end to end.

It finds the received ``state`` among the episode's recorded robot states (in step order, from the
last match on) and answers the recorded actions from there, so an agent that sends the right
observation and executes the chunk correctly reproduces the episode exactly, and one that does
not drifts off it. With no match it answers zeros, which a test sees as a failed episode.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


class ReplayPolicy:
    """Replays ``actions`` given robot ``states`` (``states[i]`` is seen before ``actions[i]``).

    Args:
        states: ``(T + 1, robot_dim)`` robot states of the episode, as float32 on the wire.
        actions: ``(T, act_dim)`` actions.
        horizon: Length of each answered chunk (padded with the last action).
    """

    def __init__(self, states: NDArray[Any], actions: NDArray[Any], horizon: int = 10) -> None:
        self.states = np.asarray(states, dtype=np.float32)
        self.actions = np.asarray(actions)  # sent as given: float64 replays exactly
        if len(self.states) < len(self.actions):
            raise ValueError(
                f"ReplayPolicy: {len(self.states)} states for {len(self.actions)} actions"
            )
        self.horizon = horizon
        self.metadata: dict[str, Any] = {"policy": "replay", "steps": len(self.actions)}
        self._cursor = 0

    def infer(self, observation: dict[str, Any]) -> dict[str, Any]:
        state = np.asarray(observation["observation"]["state"], dtype=np.float32)
        matches = [
            i
            for i in range(self._cursor, len(self.actions))
            if np.array_equal(self.states[i], state)
        ]
        if not matches:
            return {"actions": np.zeros((self.horizon, self.actions.shape[1]))}
        start = self._cursor = matches[0]
        chunk = self.actions[start : start + self.horizon]
        pad = np.repeat(chunk[-1:], self.horizon - len(chunk), axis=0)
        return {"actions": np.concatenate([chunk, pad])}
