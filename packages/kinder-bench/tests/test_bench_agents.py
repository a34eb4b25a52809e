"""Agents: the interface, the registry and argument handling, random and MPC."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from kinder_bench_toy import CrashingAgent

import kinder_bench.agents as agents_module
from kinder_bench.agents import (
    agent_class,
    describe_args,
    field_docs,
    make_agent,
    make_args,
    register_agent,
)
from kinder_bench.baselines.mpc import MPCAgent, MPCArgs, advance_spline, interpolation_matrix
from kinder_bench.baselines.random_agent import RandomAgent
from kinder_bench.evaluation.envs import make_env


def _episode(env_id: str, agent_name: str, args: dict, seed: int, steps: int) -> list[np.ndarray]:
    env = make_env(env_id)
    agent = make_agent(agent_name, env, args, seed=seed)
    obs, info = env.reset(seed=123)
    agent.reset(obs, info)
    actions = []
    for _ in range(steps):
        a = agent.act(obs)
        actions.append(a)
        obs, _, term, trunc, _ = env.step(a)
        if term or trunc:
            break
    return actions


def test_random_agent_is_seeded_and_in_bounds(toy_id: str) -> None:
    a = _episode(toy_id, "random", {}, seed=3, steps=10)
    b = _episode(toy_id, "random", {}, seed=3, steps=10)
    c = _episode(toy_id, "random", {}, seed=4, steps=10)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert np.all(np.abs(a) <= 0.1)


def test_mpc_is_deterministic_for_a_seed(toy_id: str) -> None:
    args = {"horizon": 15, "num_rollouts": 4}
    a = _episode(toy_id, "mpc", args, seed=0, steps=8)
    b = _episode(toy_id, "mpc", args, seed=0, steps=8)
    np.testing.assert_array_equal(a, b)


def test_mpc_never_touches_the_live_episode(toy_id: str) -> None:
    env = make_env(toy_id)
    agent = make_agent("mpc", env, {"horizon": 20}, seed=0)
    obs, info = env.reset(seed=5)
    before = env.unwrapped.get_state()
    agent.reset(obs, info)
    agent.act(obs)
    assert isinstance(agent, MPCAgent)
    assert agent.num_model_steps > 0
    assert env.unwrapped.get_state() == before


def test_mpc_reaches_the_toy_goal(toy_id: str) -> None:
    actions = _episode(toy_id, "mpc", {"horizon": 20}, seed=0, steps=40)
    assert len(actions) < 40  # terminated early: the goal was reached


def _far_start(env, reach: float) -> np.ndarray:
    """A seeded reset whose goal is more than ``reach`` away (the first such seed)."""
    for seed in range(100):
        obs, _ = env.reset(seed=seed)
        if np.linalg.norm(obs[0:2] - obs[3:5]) > reach + 0.1:
            return obs
    raise AssertionError("no far start found")


@pytest.mark.parametrize("shift", ["one_step", "executed"])
def test_mpc_ties_keep_the_warm_started_nominal(toy_id: str, shift: str) -> None:
    # 3 steps of at most 0.1·√2 cannot reach a far goal, so every candidate costs the same: the
    # nominal (the previous best, advanced one step) must win the next solve.
    env = make_env(toy_id)
    args = {"horizon": 3, "num_control_points": 4, "warm_start_shift": shift}
    agent = make_agent("mpc", env, args, seed=0)
    assert isinstance(agent, MPCAgent)
    obs = _far_start(env, reach=4 * 0.1 * np.sqrt(2))
    agent.reset(obs, {})
    agent.act(obs)
    first = agent._solution.copy()
    if shift == "executed":
        shifted = interpolation_matrix(agent._knots, agent._knots + 1) @ first
    else:
        times, shifted = advance_spline(agent._solution_times, first, 1.0)
    obs, *_ = env.step(agent._plan[0])
    agent.act(obs)
    np.testing.assert_array_equal(agent._solution, shifted)
    if shift == "one_step":
        np.testing.assert_array_equal(agent._solution_times, times)
    assert not np.array_equal(shifted, first)


def test_mpc_without_warm_start_resamples(toy_id: str) -> None:
    env = make_env(toy_id)
    agent = make_agent("mpc", env, {"horizon": 1, "warm_start": False}, seed=0)
    assert isinstance(agent, MPCAgent)
    obs, info = env.reset(seed=1)
    agent.reset(obs, info)
    agent.act(obs)
    first = agent._solution.copy()
    agent.act(obs)
    assert not np.array_equal(agent._solution, first)


def test_mpc_replan_interval_executes_the_stored_plan(toy_id: str) -> None:
    env = make_env(toy_id)
    agent = make_agent("mpc", env, {"horizon": 10, "replan_interval": 3}, seed=0)
    assert isinstance(agent, MPCAgent)
    obs, info = env.reset(seed=1)
    agent.reset(obs, info)
    plan = None
    for t in range(3):
        a = agent.act(obs)
        plan = agent._plan if plan is None else plan
        np.testing.assert_array_equal(a, plan[t])
    assert agent.num_solves == 1
    agent.act(obs)
    assert agent.num_solves == 2


def test_interpolation_matrix_is_piecewise_linear() -> None:
    knots = np.array([0.0, 2.0, 4.0])
    w = interpolation_matrix(knots, np.array([0.0, 1.0, 3.0, 5.0]))
    points = np.array([[0.0], [2.0], [-2.0]])
    np.testing.assert_allclose(w @ points, [[0.0], [1.0], [0.0], [-2.0]])


@pytest.mark.parametrize(
    "bad", [{"horizon": 0}, {"num_control_points": 1}, {"replan_interval": 200}]
)
def test_mpc_args_are_validated(bad: dict) -> None:
    with pytest.raises(ValueError, match="MPCArgs"):
        MPCArgs(**bad)


def test_make_args_parses_strings_and_rejects_unknown_fields() -> None:
    args = make_args(MPCAgent, {"horizon": "20", "warm_start": "false", "noise_fraction": "0.5"})
    assert args == MPCArgs(horizon=20, warm_start=False, noise_fraction=0.5)
    with pytest.raises(ValueError, match="horizn"):
        make_args(MPCAgent, {"horizn": 3})
    with pytest.raises(ValueError, match="cannot parse"):
        make_args(MPCAgent, {"warm_start": "maybe"})


def test_every_argument_has_a_docstring() -> None:
    for cls in (MPCAgent, RandomAgent):
        docs = field_docs(cls.Args)
        for f in dataclasses.fields(cls.Args):
            assert docs.get(f.name), f"{cls.__name__}.Args.{f.name} has no docstring"
    assert [d[0] for d in describe_args(MPCAgent)][:2] == ["horizon", "num_rollouts"]


def test_unknown_agent_suggests_close_names() -> None:
    with pytest.raises(ValueError, match="Did you mean 'mpc'"):
        agent_class("mcp")


def test_agents_by_entry_point_and_registration(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(agents_module, "AGENTS", dict(agents_module.AGENTS))
    assert agent_class("kinder_bench_toy:CrashingAgent") is CrashingAgent
    register_agent("crashing", "kinder_bench_toy:CrashingAgent")
    assert agent_class("crashing") is CrashingAgent
    with pytest.raises(ValueError, match="already registered"):
        register_agent("crashing", "kinder_bench_toy:InterruptingAgent")


def test_agent_rejects_wrong_args_type(toy_id: str) -> None:
    with pytest.raises(TypeError, match="MPCArgs"):
        MPCAgent(make_env(toy_id), object(), seed=0)  # type: ignore[arg-type]
