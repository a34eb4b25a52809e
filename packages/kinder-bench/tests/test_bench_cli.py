"""The ``kinder`` command end to end, on a real Kinematic2D env (Motion2D-p0)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

import kinder_core
from kinder_bench.cli import app
from kinder_bench.cli.common import parse_seeds
from kinder_bench.demo import DemoEnv, run_demo
from kinder_bench.evaluation.results import load_records

runner = CliRunner()
REAL_ENV = "kinder/Motion2D-p0-v0"


@pytest.fixture(scope="module")
def e2e() -> tuple[str, list[str]]:
    """The env the CLI is exercised on (a real Kinematic2D env), and extra options."""
    return REAL_ENV, []


def _ok(args: list[str]) -> str:
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    return result.output


def test_envs_lists_ids(e2e: tuple[str, list[str]]) -> None:
    env_id, opts = e2e
    assert env_id in _ok(["envs", *opts])
    assert "kinder/BenchReach-v0" in _ok(["envs", "--import", "kinder_bench_toy"])
    out = _ok(["envs", "--category", "Kinematic2D"])
    for i in kinder_core.list_envs("Kinematic2D"):
        assert i in out
    bad = runner.invoke(app, ["envs", "--category", "Kinematic4D"])
    assert bad.exit_code == 2 and "Unknown category" in bad.output


def test_agents_lists_arguments() -> None:
    out = _ok(["agents"])
    assert "mpc" in out and "random" in out and "horizon: int = 100" in out


def test_show(e2e: tuple[str, list[str]], tmp_path: Path) -> None:
    import imageio.v3 as iio

    env_id, opts = e2e
    png = tmp_path / "init.png"
    out = _ok(["show", env_id, "--seed", "3", "--out", str(png), *opts])
    assert env_id in out and "robot" in out
    assert iio.imread(png).ndim == 3


def test_rollout_with_gif(e2e: tuple[str, list[str]], tmp_path: Path) -> None:
    env_id, opts = e2e
    gif = tmp_path / "mpc.gif"
    out = _ok(
        [
            "rollout",
            env_id,
            "--agent",
            "mpc",
            "--arg",
            "horizon=10",
            "--arg",
            "num_rollouts=3",
            "--max-steps",
            "15",
            "--gif",
            str(gif),
            *opts,
        ]
    )
    assert "agent=mpc" in out and gif.exists()


def test_bench_run_then_report(e2e: tuple[str, list[str]], tmp_path: Path) -> None:
    env_id, opts = e2e
    run_dir = tmp_path / "run"
    args = [
        "bench",
        "run",
        "--env",
        env_id,
        "--agent",
        "random",
        "--agent",
        "mpc",
        "--arg",
        "mpc.horizon=10",
        "--arg",
        "num_rollouts=3",
        "--seeds",
        "0-1",
        "--episodes",
        "2",
        "--max-steps",
        "15",
        "--out",
        str(run_dir),
        "--executor",
        "inline",
        "--no-progress",
        *opts,
    ]
    out = _ok(args)
    assert "| SR ↑ |" in out
    recs = load_records(run_dir)
    assert len(recs) == 8
    assert {r["agent_args"].get("horizon") for r in recs if r["agent"] == "mpc"} == {10}
    assert "skipped 8 already done" in _ok(args)  # a rerun resumes
    report_dir = tmp_path / "report"
    out = _ok(["bench", "report", str(run_dir), "--out", str(report_dir)])
    assert "Inf-Time" in out
    assert {p.name for p in report_dir.iterdir()} == {"table.md", "summary.csv", "success.png"}


def test_unknown_env_suggests_close_ids(e2e: tuple[str, list[str]]) -> None:
    env_id, opts = e2e
    typo = env_id.replace("Motion", "Motoin").replace("Reach", "Raech")
    result = runner.invoke(app, ["show", typo, *opts])
    assert result.exit_code == 2
    assert "Unknown environment" in result.output and env_id in result.output


def test_unknown_agent_and_bad_args(e2e: tuple[str, list[str]]) -> None:
    env_id, opts = e2e
    result = runner.invoke(app, ["rollout", env_id, "--agent", "mcp", *opts])
    assert result.exit_code == 2 and "Did you mean 'mpc'" in result.output
    result = runner.invoke(app, ["rollout", env_id, "--agent", "mpc", "--arg", "horizn=3", *opts])
    assert result.exit_code == 2 and "horizn" in result.output
    result = runner.invoke(app, ["bench", "report", "/nonexistent/run"])
    assert result.exit_code == 2 and "not a run directory" in result.output


def test_parse_seeds() -> None:
    assert parse_seeds("0-4") == (0, 1, 2, 3, 4)
    assert parse_seeds("3,0-1,3") == (3, 0, 1)


def test_demo_on_a_small_budget(e2e: tuple[str, list[str]], tmp_path: Path) -> None:
    env_id, opts = e2e
    mpc = {"horizon": 5, "num_rollouts": 2, "num_control_points": 2, "replan_interval": 5}
    result = run_demo(
        tmp_path / "demo",
        workers=1,
        envs=[DemoEnv(env_id, 1, mpc, max_steps=10)],
        seeds=(0,),
        imports=tuple(opts[1:]),
        progress=False,
    )
    assert "| SR ↑ |" in result.table
    assert sum(p.suffix == ".gif" for p in result.files) == 3  # BP, MPC and random
    assert result.html is not None and result.html.name == "report.html"
    assert (tmp_path / "demo" / "paper_table.md").exists()


def test_console_script_runs() -> None:
    exe = Path(sys.executable).with_name("kinder")
    out = subprocess.run([str(exe), "--help"], capture_output=True, text=True, check=True)
    assert "bench" in out.stdout
    out = subprocess.run(
        [sys.executable, "-m", "kinder_bench", "agents"], capture_output=True, text=True, check=True
    )
    assert "mpc" in out.stdout


@pytest.mark.slow
def test_full_demo(tmp_path: Path) -> None:
    out = _ok(["demo", "--out", str(tmp_path / "demo"), "--no-progress"])
    for env in ("Motion2D-p0", "StickButton2D-b1", "BaseMotion3D", "Shelf3D-o1"):
        assert env in out
    assert len(list((tmp_path / "demo" / "videos").glob("*.gif"))) == 24  # 4 envs x 3 x 2 seeds
    assert "Where to look" in out and (tmp_path / "demo" / "report.html").exists()
