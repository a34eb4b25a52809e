"""MPC's fast rollouts give exactly the plain loop's actions (toy env, Motion2D, Dynamic3D)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from kinder_bench.agents import make_agent
from kinder_bench.baselines.mpc import (
    BatchedWorldRollouts,
    MPCAgent,
    MPCArgs,
    RolloutModel,
    ThreadedCloneRollouts,
    lockstep_costs,
    plain_cost,
)
from kinder_bench.evaluation.envs import make_env
from kinder_core import ObjectCentricState


class _PerRowRollouts:
    """A lockstep rollout model whose batch step calls the env's own ``transition`` row by row:
    what the fast path computes differs from the plain loop only in its bookkeeping (which
    rollouts are still running, costs, model-step counts), which is what it checks."""

    def __init__(self, agent: MPCAgent) -> None:
        self.model = agent.model

    def costs(self, state: Any, plans: np.ndarray) -> tuple[np.ndarray, int]:
        layout = state.layout

        def step(data: np.ndarray, actions: np.ndarray) -> Any:
            out = [
                self.model.transition(ObjectCentricState(layout, d), a)
                for d, a in zip(data, actions)
            ]
            nxt = np.stack([s.data for s, _, _ in out])
            return nxt, np.array([r for _, r, _ in out]), np.array([t for _, _, t in out])

        return lockstep_costs(step, state.data, plans)


class _LockstepMPC(MPCAgent):
    name = "mpc_lockstep_test"

    def fast_model(self) -> RolloutModel | None:
        return _PerRowRollouts(self)


def _actions(env_id: str, args: dict[str, Any], steps: int, agent_cls: type[MPCAgent] = MPCAgent,
             ) -> tuple[np.ndarray, int, MPCAgent]:  # fmt: skip
    env = make_env(env_id)
    agent = agent_cls(env, MPCArgs(**args), seed=1000)
    obs, info = env.reset(seed=1000)
    agent.reset(obs, info)
    actions = []
    for _ in range(steps):
        a = agent.act(obs)
        actions.append(a)
        obs, _, term, trunc, _ = env.step(a)
        if term or trunc:
            break
    return np.array(actions), agent.num_model_steps, agent


def test_lockstep_costs_equal_the_plain_loop_when_rollouts_terminate(toy_id: str) -> None:
    env = make_env(toy_id)
    env.reset(seed=1000)
    model = env.unwrapped
    state = model.get_state()
    rng = np.random.default_rng(1000)
    gap = state[model.target][:2] - state[model.robot][:2]
    toward = 0.1 * gap / np.linalg.norm(gap)
    plans = np.concatenate(
        [np.broadcast_to(toward, (3, 30, 2)), rng.uniform(-0.1, 0.1, (3, 30, 2))]
    )
    plans[1] *= 0.5  # reaches the target later than plan 0
    agent = _LockstepMPC(env, MPCArgs(horizon=30), seed=0)
    fast, fast_steps = agent.fast_model().costs(state, plans)  # type: ignore[union-attr]
    plain = [plain_cost(model.transition, state, p) for p in plans]
    assert fast.tolist() == [c for c, _ in plain]
    assert fast_steps == sum(k for _, k in plain)
    assert min(k for _, k in plain) < 30 and max(k for _, k in plain) == 30  # both kinds occur


def test_fast_path_gives_the_plain_actions_on_the_toy_env(toy_id: str) -> None:
    args = {"horizon": 20, "num_rollouts": 6}
    plain, plain_steps, _ = _actions(toy_id, {**args, "batched": False}, 25)
    fast, fast_steps, agent = _actions(toy_id, args, 25, _LockstepMPC)
    assert isinstance(agent._fast, _PerRowRollouts)
    np.testing.assert_array_equal(plain, fast)
    assert plain_steps == fast_steps
    assert len(plain) < 25  # the episode reached the goal, so rollouts terminated on the way


def test_fast_path_gives_the_plain_actions_on_motion2d() -> None:
    env_id = "kinder/Motion2D-p0-v0"
    args = {"horizon": 25, "num_rollouts": 8, "replan_interval": 2}
    plain, plain_steps, _ = _actions(env_id, {**args, "batched": False}, 6)
    fast, fast_steps, agent = _actions(env_id, args, 6)
    assert isinstance(agent._fast, BatchedWorldRollouts)
    np.testing.assert_array_equal(plain, fast)
    assert plain_steps == fast_steps


def test_fast_path_gives_the_plain_actions_on_stickbutton2d() -> None:
    """StickButton2D's reward is 0 on the terminating step: the batched world's reward too."""
    env_id = "kinder/StickButton2D-b1-v0"
    args = {"horizon": 25, "num_rollouts": 8}
    plain, plain_steps, _ = _actions(env_id, {**args, "batched": False}, 4)
    fast, fast_steps, agent = _actions(env_id, args, 4)
    assert isinstance(agent._fast, BatchedWorldRollouts)
    np.testing.assert_array_equal(plain, fast)
    assert plain_steps == fast_steps


def test_envs_without_a_fast_model_keep_the_plain_loop(toy_id: str) -> None:
    agent = make_agent("mpc", make_env(toy_id), {"horizon": 5}, seed=0)
    assert isinstance(agent, MPCAgent) and agent._fast is None


def test_rollout_threads_is_validated() -> None:
    with pytest.raises(ValueError, match="rollout_threads"):
        MPCArgs(rollout_threads=-1)


@pytest.mark.slow
def test_fast_path_gives_the_plain_actions_on_dynamic3d() -> None:
    env_id = "kinder/Shelf3D-o1-v0"
    args = {"horizon": 4, "num_rollouts": 3, "num_control_points": 3, "rollout_threads": 2}
    plain, plain_steps, _ = _actions(env_id, {**args, "batched": False}, 3)
    fast, fast_steps, agent = _actions(env_id, args, 3)
    assert isinstance(agent._fast, ThreadedCloneRollouts) and agent._fast.threads == 2
    np.testing.assert_array_equal(plain, fast)
    assert plain_steps == fast_steps
