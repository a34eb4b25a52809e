"""``kinder serve`` and ``kinder demos export-openpi``: a DP checkpoint behind the policy server,
evaluated by the ``vla`` agent on loopback, must act exactly as the in-process ``dp`` agent,
reset per episode and refuse a second concurrent episode clearly."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("lerobot")
pytest.importorskip("torch")

import torch
from typer.testing import CliRunner

from kinder_bench.agents import make_agent
from kinder_bench.baselines.diffusion import DiffusionTrainArgs, train_diffusion
from kinder_bench.cli import app
from kinder_bench.evaluation.envs import make_env
from kinder_bench.evaluation.runner import RunConfig, run_benchmark
from kinder_bench.policy_server.agent_policy import AgentService
from kinder_bench.policy_server.client import PolicyClient, PolicyServerError

FIXTURE = Path(__file__).parents[2] / "kinder-gym" / "tests" / "data" / "demos" / "Motion2D-p0"
MOTION = "kinder/Motion2D-p0-v0"
STEPS = 11  # two DP chunks: 8 queued actions, then a new prediction


@pytest.fixture(scope="module")
def dp_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """DP trained for 2 steps (the cpu preset) on the Motion2D-p0 fixture."""
    os.environ["HF_HUB_OFFLINE"] = "1"
    os.environ.setdefault("HF_HOME", str(tmp_path_factory.mktemp("hf")))
    torch.set_num_threads(1)
    if not FIXTURE.is_dir():
        pytest.skip(f"the demo fixture {FIXTURE} is not in this checkout")
    root = tmp_path_factory.mktemp("demos") / "Motion2D-p0"
    shutil.copytree(FIXTURE, root)
    out = tmp_path_factory.mktemp("dp") / "run"
    args = DiffusionTrainArgs(
        dataset=root, out=out, steps=2, preset="cpu", batch_size=4, save_every=2, seed=3
    )
    train_diffusion(args, progress=False)
    return out


def _episode(agent_name: str, agent_args: dict[str, Any], seed: int) -> list[np.ndarray]:
    env = make_env(MOTION)
    agent = make_agent(agent_name, env, agent_args, seed=seed)
    obs, info = env.reset(seed=5)
    agent.reset(obs, info)
    actions = []
    for _ in range(STEPS):
        actions.append(agent.act(obs))
        obs = env.step(actions[-1])[0]
    return actions


def test_served_dp_acts_exactly_as_in_process(dp_run: Path) -> None:
    local = _episode("dp", {"checkpoint": str(dp_run)}, seed=7)
    service = AgentService("dp", {"checkpoint": str(dp_run)}, "Motion2D-p0")
    with service.server(port=0) as server:
        served = _episode("vla", {"url": server.url}, seed=7)
        other_seed = _episode("vla", {"url": server.url}, seed=8)  # a new connection each
    np.testing.assert_array_equal(np.array(served), np.array(local))
    assert not np.array_equal(np.array(other_seed), np.array(local))  # the seed is honoured


def test_served_agent_resets_per_episode_on_one_connection(dp_run: Path) -> None:
    env = make_env(MOTION)
    obs, _ = env.reset(seed=5)
    vla = make_agent("vla", env, {"url": "ws://unused"}, seed=7)
    request = vla.request(obs)
    service = AgentService("dp", {"checkpoint": str(dp_run)}, MOTION)
    with service.server(port=0) as server, PolicyClient(server.url, timeout=30) as client:
        assert client.metadata["agent"] == "dp" and client.metadata["action_horizon"] == 1
        first = client.infer(request)["actions"]
        assert first.shape == (1, 5)
        second = client.infer(request)["actions"]  # same episode: DP's queued 2nd action
        request["kinder"]["episode"] += 1
        again = client.infer(request)["actions"]  # a new episode: history and queue reset
    assert not np.array_equal(first, second)
    np.testing.assert_array_equal(again, first)


def test_served_agent_errors_are_clear(dp_run: Path) -> None:
    service = AgentService("dp", {"checkpoint": str(dp_run)}, MOTION, busy_timeout=0.2)
    busy = "busy: this server is serving another"
    with service.server(port=0) as server:
        with PolicyClient(server.url, timeout=30), pytest.raises(PolicyServerError, match=busy):
            PolicyClient(server.url, timeout=30)
        with (
            PolicyClient(server.url, timeout=30) as client,  # free again once closed
            pytest.raises(PolicyServerError, match="needs the full observation"),
        ):
            client.infer({"observation": {"state": np.zeros(9, np.float32)}})
        with (
            PolicyClient(server.url, timeout=30) as client,
            pytest.raises(PolicyServerError, match="have 19 features; the request has 3"),
        ):
            client.infer({"kinder": {"observation": np.zeros(3)}})


def test_bench_run_evaluates_a_served_checkpoint(dp_run: Path, tmp_path: Path) -> None:
    service = AgentService("dp", {"checkpoint": str(dp_run)}, MOTION)
    with service.server(port=0) as server:
        run = RunConfig(MOTION, "vla", {"url": server.url}, seeds=(0,), episodes=1, max_steps=4)
        run_benchmark([run], tmp_path / "eval", executor="inline", progress=False)
    (record,) = [json.loads(line) for line in (tmp_path / "eval/results.jsonl").open()]
    assert record["error"] is None, record["traceback"]
    assert record["steps"] == 4 and record["inference_time"] > 0


def test_serve_cli_refuses_what_cannot_run() -> None:
    result = CliRunner().invoke(app, ["serve", "--agent", "dp", "--env", "Motion2D-p0"])
    assert result.exit_code == 2
    assert "needs a trained checkpoint" in result.output
    result = CliRunner().invoke(app, ["serve", "--agent", "nope", "--env", "Motion2D-p0"])
    assert result.exit_code == 2 and "Unknown agent" in result.output


def test_export_openpi_cli(tmp_path: Path) -> None:
    out = tmp_path / "kinder" / "Motion2D-p0"
    args = ["demos", "export-openpi", str(FIXTURE), str(out), "--no-images", "--no-progress"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "3 episodes, 120 frames of kinder/Motion2D-p0-v0" in result.output
    assert json.loads((out / "meta" / "info.json").read_text())["codebase_version"] == "v2.1"
    result = CliRunner().invoke(app, args)  # OUT is now in use
    assert result.exit_code == 2 and "not empty" in result.output
    result = CliRunner().invoke(app, [*args[:2], str(tmp_path / "none"), str(tmp_path / "o")])
    assert result.exit_code == 2 and "missing" in result.output
