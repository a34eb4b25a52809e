"""A tiny object-centric env that exercises the kinder-core contract in the tests."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState, ObjectCentricStateSpace, Type
from kinder_core.state import FloatArray

POINT = Type("point", ["x", "y"])
ROBOT = Type("robot", ["speed"], parent=POINT)
TARGET = Type("target", ["radius"], parent=POINT)


class ToyReach(ObjectCentricEnv):
    """A point robot reaches a circular target among inert pebbles.

    ## Description
    A toy env for kinder-core's tests.

    ## Observation Space
    The robot (x, y, speed), the target (x, y, radius), then the pebbles (x, y).

    ## Action Space
    (dx, dy) in [-0.1, 0.1]².

    ## Reward
    −1 per step.

    ## Starting State
    Uniform positions in the unit square.

    ## Episode End
    The robot is within the target radius.

    ## Version History
    * v0: initial version.
    """

    def __init__(self, num_pebbles: int = 2, render_mode: str | None = "rgb_array") -> None:
        super().__init__(render_mode=render_mode)
        self.num_pebbles = num_pebbles
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
            self.robot: [*rng.uniform(0, 1, 2), 1.0],
            self.target: [*rng.uniform(0, 1, 2), 0.1],
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


class LeakyToyReach(ToyReach):
    """ToyReach whose dynamics read a hidden counter: set_state cannot reproduce it.

    ## Description
    A deliberately broken env: the test kit must catch it.

    ## Observation Space
    As ToyReach.

    ## Action Space
    As ToyReach.

    ## Reward
    −1 per step.

    ## Starting State
    As ToyReach.

    ## Episode End
    As ToyReach.

    ## Version History
    * v0: initial version.
    """

    def __init__(self, num_pebbles: int = 2, render_mode: str | None = "rgb_array") -> None:
        super().__init__(num_pebbles=num_pebbles, render_mode=render_mode)
        self._hidden = 0

    def _transition(self, state: ObjectCentricState, action: FloatArray) -> ObjectCentricState:
        self._hidden += 1
        state = super()._transition(state, action)
        state[self.pebbles[0]][0] += 1e-3 * self._hidden
        return state


class UnboundedToyReach(ToyReach):
    """ToyReach without finite feature bounds (every Box entry is ±inf).

    ## Description
    Checks that unbounded Box views pass the test kit.

    ## Observation Space
    As ToyReach, unbounded.

    ## Action Space
    As ToyReach.

    ## Reward
    −1 per step.

    ## Starting State
    As ToyReach.

    ## Episode End
    As ToyReach.

    ## Version History
    * v0: initial version.
    """

    def feature_bounds(self) -> dict[str, tuple[float, float]]:
        return {}
