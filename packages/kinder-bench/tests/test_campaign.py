"""The campaign driver: a tiny campaign runs, and a second call resumes (does nothing)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from kinder_bench_toy import TOY_ID
from typer.testing import CliRunner

from kinder_bench.baselines.mbrl import DeltaModel, write_delta_checkpoint
from kinder_bench.campaign import load_campaign, parse_campaign, run_campaign, train_command
from kinder_bench.cli import app
from kinder_bench.evaluation.envs import make_env
from kinder_bench.evaluation.protocol import PAPER_ENVS

ROOT = Path(__file__).resolve().parents[3]

TINY = f"""
[campaign]
name = "tiny"
seeds = "1000"
episodes = 2
imports = ["kinder_bench_toy"]

[[cells]]
name = "mpc-small"
agent = "mpc"
envs = ["{TOY_ID}"]
args = {{ horizon = 10, num_rollouts = 3 }}
label = "mpc-small"

[[cells]]
agent = "mbrl"
envs = ["{TOY_ID}"]
args = {{ horizon = 10, num_rollouts = 3 }}
max_steps = 15

[cells.train]
method = "mbrl"
args = {{ dataset = "datasets/{{env}}", epochs = 2, progress = false }}
budget = "2 epochs"
"""


def _fake_mbrl_training(calls: list[list[str]]) -> object:
    """Stands in for `kinder train mbrl`: writes a random-weight model where --out points."""

    def train(cmd: Sequence[str]) -> None:
        calls.append(list(cmd))
        out = Path(cmd[cmd.index("--out") + 1])
        out.mkdir(parents=True, exist_ok=True)
        env = make_env(TOY_ID)
        names = tuple(env.unwrapped.box_space.feature_names)
        d, a = len(names), env.action_space.shape[0]
        rng = np.random.default_rng(0)
        robot = np.arange(3, dtype=np.intp)
        rest = np.arange(3, d, dtype=np.intp)
        weights = {
            "trunk.0.weight": rng.normal(size=(8, d + a)), "trunk.0.bias": np.zeros(8),
            "trunk.2.weight": rng.normal(size=(8, 8)), "trunk.2.bias": np.zeros(8),
            "robot_head.weight": rng.normal(size=(3, 8)), "robot_head.bias": np.zeros(3),
            "env_head.weight": rng.normal(size=(d - 3, 8)), "env_head.bias": np.zeros(d - 3),
        }  # fmt: skip
        model = DeltaModel(
            weights, np.zeros(d), np.ones(d), np.zeros(a), np.ones(a), np.zeros(d),
            np.full(d, 0.01), robot, rest, np.zeros(d, dtype=bool), np.zeros(d, dtype=bool),
            names,
        )  # fmt: skip
        write_delta_checkpoint(out, model, TOY_ID, 2)

    return train


def test_a_tiny_campaign_runs_then_resumes_without_doing_anything(tmp_path: Path) -> None:
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    campaign = load_campaign(path)
    assert [c.key for c in campaign.cells] == ["mpc-small/BenchReach", "mbrl/BenchReach"]
    calls: list[list[str]] = []
    train = _fake_mbrl_training(calls)
    out = tmp_path / "out"
    kwargs = {"executor": "inline", "progress": False, "log": lambda _: None}
    first = run_campaign(campaign, out, train_fn=train, **kwargs)  # type: ignore[arg-type]
    assert first.trained == 1 and first.episodes_ran == 4 and first.episodes_skipped == 0
    assert calls == [train_command(campaign.cells[1], out)]
    assert calls[0][:3] == ["kinder", "train", "mbrl"]
    assert calls[0][calls[0].index("--dataset") + 1] == "datasets/BenchReach"
    assert "--no-progress" in calls[0]
    results = (out / "eval" / "results.jsonl").read_text()
    records = [json.loads(line) for line in results.splitlines()]
    assert sorted({r["label"] for r in records}) == ["mbrl", "mpc-small"]
    assert {r["seed"] for r in records} == {1000}
    status = json.loads((out / "campaign.json").read_text())["cells"]
    assert all(s["finished"] and s["episodes_done"] == 2 for s in status.values())
    assert status["mbrl/BenchReach"]["train"]["budget"] == "2 epochs"
    config = json.loads((out / "eval" / "config.json").read_text())
    assert sorted(r["training"] for r in config["runs"]) == ["", "2 epochs"]
    assert (out / "eval" / "summary.csv").exists()

    second = run_campaign(load_campaign(path), out, train_fn=train, **kwargs)  # type: ignore[arg-type]
    assert second.trained == 0 and second.episodes_ran == 0 and second.episodes_skipped == 4
    assert len(calls) == 1
    assert (out / "eval" / "results.jsonl").read_text() == results


def test_paper_settings_fill_each_envs_arguments_and_budget() -> None:
    campaign = parse_campaign(
        {"cells": [{"agent": "mpc", "envs": "paper", "paper_settings": True}]}, "t"
    )
    by_env = {c.env_id: c for c in campaign.cells}
    assert list(by_env) == list(PAPER_ENVS)
    assert by_env["kinder/Motion2D-p0-v0"].args["replan_interval"] == 3
    assert by_env["kinder/Transport3D-o2-v0"].args["replan_interval"] == 100
    assert by_env["kinder/SweepIntoDrawer3D-o5-v0"].max_steps == 700
    assert by_env["kinder/Motion2D-p0-v0"].max_steps is None  # the protocol's budget
    assert all(c.args["horizon"] == 100 and c.args["num_rollouts"] == 10 for c in campaign.cells)


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"cells": [{"agent": "mpc", "envs": ["Motion2D-p0"], "args": {"horizn": 3}}]},
         "horizn"),
        ({"cells": [{"agent": "mpc", "envs": ["Motion2D-p0"], "colour": 1}]}, "colour"),
        ({"cells": []}, "at least one"),
        ({"cells": [{"agent": "mpc", "envs": ["Motion2D-p0"]}] * 2}, "twice"),
        ({"cells": [{"agent": "mpc", "envs": ["Motion2D-p0"], "seeds": "a-b"}]}, "seeds"),
        ({"cells": [{"agent": "mbrl", "envs": ["Motion2D-p0"], "train": {"args": {}}}]},
         "method"),
        ({"cells": [{"agent": "mpc", "envs": ["Motion2D-p0"], "obs_noise": -0.1}]},
         "obs_noise -0.1: expected a finite number >= 0"),
        ({"cells": [{"agent": "mpc", "envs": ["Motion2D-p0"], "action_noise": "lots"}]},
         "action_noise 'lots': expected a number"),
    ],
)  # fmt: skip
def test_bad_campaign_files_say_what_is_wrong(data: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        parse_campaign(data, "bad.toml")


def test_a_cells_noise_reaches_its_run() -> None:
    campaign = parse_campaign(
        {"cells": [{"agent": "mpc", "envs": ["Motion2D-p0"], "obs_noise": 0.1}]}, "t"
    )
    (cell,) = campaign.cells
    run = cell.run_config(Path("out"))
    assert (run.obs_noise, run.action_noise) == (0.1, 0.0)


def test_the_committed_noise_campaign_runs_bp_under_each_noise_of_the_paper() -> None:
    campaign = load_campaign(ROOT / "benchmarks" / "campaigns" / "noise.toml")
    levels = {(c.obs_noise, c.action_noise) for c in campaign.cells}
    assert levels == {(0.01, 0.0), (0.1, 0.0), (0.0, 0.01), (0.0, 0.1)}
    assert {c.agent for c in campaign.cells} == {"bilevel_planning"}


def test_the_cli_lists_a_campaign_without_running_it(tmp_path: Path) -> None:
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    result = CliRunner().invoke(
        app, ["bench", "campaign", str(path), "--dry-run", "--out", str(tmp_path / "o")]
    )
    assert result.exit_code == 0, result.output
    assert "mbrl/BenchReach" in result.output and "kinder train mbrl --out" in result.output
    assert not (tmp_path / "o").exists()


@pytest.mark.slow  # loads every learned agent's module (torch, lerobot): ~40 s
def test_the_committed_paper_campaign_loads() -> None:
    campaign = load_campaign(ROOT / "benchmarks" / "campaigns" / "paper.toml")
    assert {c.env_id for c in campaign.cells} == set(PAPER_ENVS)
