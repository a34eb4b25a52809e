"""The random baseline: uniform actions from the agent's seeded RNG."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_bench.agents.base import Agent, NoArgs


class RandomAgent(Agent[NoArgs]):
    """Samples every action uniformly from the action box (a lower bound for every method)."""

    name = "random"
    Args = NoArgs

    def __init__(self, env: gymnasium.Env[Any, Any], args: NoArgs, seed: int) -> None:
        super().__init__(env, args, seed)
        low, high = self.action_space.low, self.action_space.high
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
            raise ValueError(f"RandomAgent needs finite action bounds, got {self.action_space}")
        self._low = low.astype(np.float64)
        self._high = high.astype(np.float64)

    def act(self, obs: Any) -> NDArray[np.float64]:
        return self.rng.uniform(self._low, self._high)
