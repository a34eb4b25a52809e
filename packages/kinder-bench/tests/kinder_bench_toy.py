"""Test fixtures: a tiny KinDER env and a few misbehaving agents.

Importing this module registers ``kinder/BenchReach-v0`` (the kinder-core toy-env pattern), so it
doubles as the ``imports`` module that worker processes import to make the env.
"""

from __future__ import annotations

import os
import time
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from kinder_bench.agents import Agent, NoArgs
from kinder_core import Object, ObjectCentricEnv, ObjectCentricState, ObjectCentricStateSpace, Type
from kinder_core.state import FloatArray

TOY_ID = "kinder/BenchReach-v0"

POINT = Type("point", ["x", "y"])
ROBOT = Type("robot", ["speed"], parent=POINT)
TARGET = Type("target", ["radius"], parent=POINT)


class BenchReach(ObjectCentricEnv):
    """A point robot reaches a circular target among inert pebbles.

    ## Description
    A toy env for kinder-bench's tests.

    ## Observation Space
    The robot (x, y, speed), the target (x, y, radius), then the pebbles (x, y).

    ## Action Space
    (dx, dy) in [-0.1, 0.1]².

    ## Reward
    −1 per step.

    ## Starting State
    The robot in [0, 0.3]², the target in [0.5, 0.8]², pebbles in the unit square.

    ## Episode End
    The robot is within the target radius.

    ## Version History
    * v0: initial version.
    """

    def __init__(
        self,
        num_pebbles: int = 1,
        render_mode: str | None = "rgb_array",
        target_radius: float = 0.1,
    ) -> None:
        super().__init__(render_mode=render_mode)
        self.target_radius = target_radius
        self.robot = Object("robot", ROBOT)
        self.target = Object("target", TARGET)
        self.pebbles = [Object(f"pebble{i}", POINT) for i in range(num_pebbles)]
        self.action_space = spaces.Box(-0.1, 0.1, shape=(2,), dtype=np.float64)
        self.observation_space = ObjectCentricStateSpace([POINT])

    def box_objects(self) -> list[Object]:
        return [self.robot, self.target, *sorted(self.pebbles)]

    def feature_bounds(self) -> dict[str, tuple[float, float]]:
        return {"x": (-1.0, 2.0), "y": (-1.0, 2.0), "speed": (0.0, 1.0), "radius": (0.0, 1.0)}

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        feats = {
            self.robot: [*rng.uniform(0.0, 0.3, 2), 1.0],
            self.target: [*rng.uniform(0.5, 0.8, 2), self.target_radius],
        }
        feats.update({p: rng.uniform(0, 1, 2) for p in self.pebbles})
        return ObjectCentricState.from_features(feats)

    def _transition(self, state: ObjectCentricState, action: FloatArray) -> ObjectCentricState:
        xy = state[self.robot][:2] + action * state.get(self.robot, "speed")
        state[self.robot][:2] = np.clip(xy, -1.0, 2.0)
        return state

    def goal_reached(self, state: ObjectCentricState) -> bool:
        d = np.linalg.norm(state[self.robot][:2] - state[self.target][:2])
        return bool(d <= state.get(self.target, "radius"))

    def _render_state(self, state: ObjectCentricState) -> NDArray[np.uint8]:
        img = np.full((32, 32, 3), 255, dtype=np.uint8)
        for obj, colour in ((self.target, (0, 200, 0)), (self.robot, (200, 0, 0))):
            x, y = np.clip((state[obj][:2] + 1) / 3 * 31, 0, 31).astype(int)
            img[31 - y, x] = colour
        return img


if TOY_ID not in gymnasium.registry:
    gymnasium.register(
        id=TOY_ID,
        entry_point="kinder_core.registration:make_box_env",
        kwargs={"env_entry_point": "kinder_bench_toy:BenchReach"},
        max_episode_steps=40,
    )

#: An easier variant (target radius 0.3) where RL learns within a few thousand steps.
EASY_ID = "kinder/BenchReachEasy-v0"
if EASY_ID not in gymnasium.registry:
    gymnasium.register(
        id=EASY_ID,
        entry_point="kinder_core.registration:make_box_env",
        kwargs={"env_entry_point": "kinder_bench_toy:BenchReach", "target_radius": 0.3},
        max_episode_steps=25,
    )

CRASH_THINK = 0.05


class CrashingAgent(Agent[NoArgs]):
    """Raises in ``act`` at step 3 of every odd episode seed, after thinking for
    :data:`CRASH_THINK` seconds; else stays still."""

    name = "crashing"

    def __init__(self, env: gymnasium.Env[Any, Any], args: NoArgs, seed: int) -> None:
        super().__init__(env, args, seed)
        self._t = 0
        self._odd = False

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        self._t = 0
        self._odd = bool(self.env.unwrapped.np_random_seed % 2)

    def act(self, obs: Any) -> NDArray[np.float64]:
        self._t += 1
        if self._odd and self._t == 3:
            time.sleep(CRASH_THINK)
            raise ValueError("boom")
        return np.zeros(2)


class InterruptingAgent(Agent[NoArgs]):
    """Stays still; raises KeyboardInterrupt (as Ctrl-C would) in episode 2 of seed 0 while the
    file named by ``KINDER_BENCH_TEST_INTERRUPT`` exists."""

    name = "interrupting"

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        flag = os.environ.get("KINDER_BENCH_TEST_INTERRUPT")
        if flag and os.path.exists(flag) and self.env.unwrapped.np_random_seed == _third_seed():
            raise KeyboardInterrupt

    def act(self, obs: Any) -> NDArray[np.float64]:
        return np.zeros(2)


def _third_seed() -> int:
    from kinder_bench.evaluation.runner import episode_seeds

    return episode_seeds(0, 3)[2]


class SlowAgent(Agent[NoArgs]):
    """Stays still, slowly (5 ms per action): gives a test time to kill a run midway."""

    name = "slow"

    def act(self, obs: Any) -> NDArray[np.float64]:
        time.sleep(0.005)
        return np.zeros(2)


class NeedsCheckpointAgent(Agent[NoArgs]):
    """Stays still; says it cannot run unless ``KINDER_BENCH_TEST_CHECKPOINT`` names a file (the
    way a learned agent reports a missing checkpoint)."""

    name = "needs_checkpoint"

    @classmethod
    def unavailable(cls, args: Any, env_id: str) -> str | None:
        path = os.environ.get("KINDER_BENCH_TEST_CHECKPOINT")
        if path and os.path.exists(path):
            return None
        return "needs a checkpoint: set KINDER_BENCH_TEST_CHECKPOINT"

    def act(self, obs: Any) -> NDArray[np.float64]:
        return np.zeros(2)
