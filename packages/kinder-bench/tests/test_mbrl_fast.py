"""MBRL's batched planner makes exactly the decisions of the one-by-one loop.

The models are random-weight state-delta models written straight to a checkpoint (no training,
no torch): what is checked is that scoring the candidates together changes nothing.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from kinder_bench.baselines.mbrl import (
    DeltaModel,
    LearnedModelRollouts,
    MBRLAgent,
    MBRLArgs,
    write_delta_checkpoint,
)
from kinder_bench.evaluation.envs import make_env


def _random_delta_model(
    env_id: str, seed: int, drift: dict[str, float], hidden: int = 32
) -> DeltaModel:
    """A random-weight model over every feature of the env that moves the robot's features and
    those in ``drift`` (the others stay constant); ``drift`` adds a constant delta to its
    features (so that rollouts reach the goal)."""
    env = make_env(env_id)
    box = env.unwrapped.box_space
    names = tuple(box.feature_names)
    d, a = len(names), env.action_space.shape[0]
    rng = np.random.default_rng(seed)
    robot = np.array([i for i, n in enumerate(names) if n.startswith("robot.")], dtype=np.intp)
    rest = np.array([i for i in range(d) if i not in set(robot.tolist())], dtype=np.intp)
    weights = {
        "trunk.0.weight": rng.normal(0, 0.5, (hidden, d + a)),
        "trunk.0.bias": rng.normal(0, 0.1, hidden),
        "trunk.2.weight": rng.normal(0, 0.3, (hidden, hidden)),
        "trunk.2.bias": rng.normal(0, 0.1, hidden),
        "robot_head.weight": rng.normal(0, 0.3, (len(robot), hidden)),
        "robot_head.bias": np.zeros(len(robot)),
        "env_head.weight": rng.normal(0, 0.3, (len(rest), hidden)),
        "env_head.bias": np.zeros(len(rest)),
    }
    delta_mean = np.array([drift.get(n, 0.0) for n in names])
    constant = np.array([not n.startswith("robot.") and n not in drift for n in names])
    return DeltaModel(
        weights, np.zeros(d), np.ones(d), np.zeros(a), np.full(a, 0.1), delta_mean,
        np.full(d, 0.01), robot, rest, constant, np.zeros(d, dtype=bool), names,
    )  # fmt: skip


def _random_model(env_id: str, out: Path, seed: int, drift: dict[str, float]) -> Path:
    """A checkpoint of :func:`_random_delta_model`."""
    model = _random_delta_model(env_id, seed, drift)
    return write_delta_checkpoint(out / "ckpt", model, env_id, 1)


def test_row_stable_prediction_equals_one_row_calls() -> None:
    """A batch of 10 through the paper's 256-wide model: every row bit for bit its one-row call
    (one matrix product over the batch may round differently from a one-row product)."""
    model = _random_delta_model("kinder/Motion2D-p0-v0", 2, {}, hidden=256)
    rng = np.random.default_rng(1000)
    states = rng.normal(size=(10, len(model.names)))
    actions = rng.normal(size=(10, len(model.action_mean)))
    rows = np.concatenate([model.predict(states[i : i + 1], actions[i : i + 1]) for i in range(10)])
    np.testing.assert_array_equal(model.predict(states, actions, row_stable=True), rows)


def _actions(env_id: str, args: dict[str, Any], steps: int) -> tuple[np.ndarray, MBRLAgent]:
    env = make_env(env_id)
    agent = MBRLAgent(env, MBRLArgs(**args), seed=1000)
    obs, info = env.reset(seed=1000)
    agent.reset(obs, info)
    actions = []
    for _ in range(steps):
        a = agent.act(obs)
        actions.append(a)
        obs, _, term, trunc, _ = env.step(a)
        if term or trunc:
            break
    return np.array(actions), agent


def test_batched_mbrl_planner_gives_the_plain_actions_on_the_toy_env(
    toy_id: str, tmp_path: Path
) -> None:
    ckpt = _random_model(toy_id, tmp_path, 0, {"robot.x": 0.03, "robot.y": 0.03})
    args = {"checkpoint": str(ckpt), "horizon": 30, "num_rollouts": 6}
    plain, plain_agent = _actions(toy_id, {**args, "batched": False}, 8)
    fast, fast_agent = _actions(toy_id, args, 8)
    assert isinstance(fast_agent._fast, LearnedModelRollouts)
    np.testing.assert_array_equal(plain, fast)
    assert plain_agent.num_model_steps == fast_agent.num_model_steps
    # Some rollouts reached the (model's) goal, so the batch shrank on the way.
    assert fast_agent.num_model_steps < len(fast) * 30 * 6


def test_batched_mbrl_planner_gives_the_plain_actions_on_motion2d(tmp_path: Path) -> None:
    env_id = "kinder/Motion2D-p0-v0"
    ckpt = _random_model(env_id, tmp_path, 1, {"robot.x": 0.05, "robot.y": 0.02})
    args = {"checkpoint": str(ckpt), "horizon": 40, "num_rollouts": 8}
    plain, plain_agent = _actions(env_id, {**args, "batched": False}, 5)
    fast, fast_agent = _actions(env_id, args, 5)
    rollouts = fast_agent._fast
    assert isinstance(rollouts, LearnedModelRollouts) and rollouts._world is not None
    np.testing.assert_array_equal(plain, fast)
    assert plain_agent.num_model_steps == fast_agent.num_model_steps


def test_batched_mbrl_planner_gives_the_plain_actions_on_dynobstruction2d(tmp_path: Path) -> None:
    """An env without a batched world: the goal check runs through the env's whole-array
    ``goals_reached``, and some rollouts end early."""
    env_id = "kinder/DynObstruction2D-o1-v0"
    # With this drift some candidates' blocks reach the goal region and others do not (checked
    # below).
    ckpt = _random_model(env_id, tmp_path, 3, {"target_block.x": -0.05})
    args = {"checkpoint": str(ckpt), "horizon": 40, "num_rollouts": 6}
    plain, plain_agent = _actions(env_id, {**args, "batched": False}, 3)
    fast, fast_agent = _actions(env_id, args, 3)
    rollouts = fast_agent._fast
    assert isinstance(rollouts, LearnedModelRollouts) and rollouts._world is None
    np.testing.assert_array_equal(plain, fast)
    assert plain_agent.num_model_steps == fast_agent.num_model_steps
    assert len(fast) * 6 < fast_agent.num_model_steps < len(fast) * 40 * 6
