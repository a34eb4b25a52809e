"""Aggregation against a hand-computed example, and the report formats."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import pytest

from kinder_bench.evaluation.metrics import Stat, aggregate, seed_metrics, summarize
from kinder_bench.evaluation.summary import csv_table
from kinder_bench.reporting.report import markdown_table, write_report


def _rec(
    seed: int,
    ep: int,
    success: bool,
    reward: float,
    t: float,
    run: str = "r1",
    label: str = "mpc",
    env: str = "kinder/Motion2D-p0-v0",
    error: str | None = None,
) -> dict[str, Any]:
    return {
        "run_id": run,
        "env_id": env,
        "agent": label,
        "label": label,
        "agent_args": {},
        "max_steps": 50,
        "seed": seed,
        "episode": ep,
        "success": success,
        "reward": reward,
        "steps": int(-reward),
        "inference_time": t,
        "env_time": t / 10,
        "error": error,
    }


# (success, reward, inference time) per episode; steps = -reward.
EXAMPLE = {
    0: [(True, -10, 1.0), (False, -50, 3.0), (True, -20, 2.0), (False, -50, 2.0)],
    1: [(True, -30, 1.0), (True, -40, 1.0), (True, -20, 4.0), (False, -50, 2.0)],
    2: [(False, -50, 1.0)] * 4,
}


def _example(**kw: Any) -> list[dict[str, Any]]:
    return [_rec(seed, i, *ep, **kw) for seed, eps in EXAMPLE.items() for i, ep in enumerate(eps)]


def test_per_seed_metrics_by_hand() -> None:
    s0 = seed_metrics([r for r in _example() if r["seed"] == 0])
    assert (s0.success, s0.reward, s0.inference_time, s0.steps) == (0.5, -15.0, 2.0, 32.5)
    s2 = seed_metrics([r for r in _example() if r["seed"] == 2])
    assert (s2.success, s2.reward, s2.inference_time) == (0.0, None, 1.0)


def test_aggregation_by_hand() -> None:
    s = summarize(_example())
    # SR per seed 0.5, 0.75, 0 → mean 0.41667, sample std sqrt(0.291667 / 2).
    assert s.success.mean == pytest.approx(0.4166667, abs=1e-6)
    assert s.success.std == pytest.approx(0.3818813, abs=1e-6)
    # Rwd over successes only, per seed -15, -30 (seed 2 has none and is left out).
    assert (s.reward.mean, s.reward.n) == (-22.5, 2)
    assert s.reward.std == pytest.approx(10.6066017, abs=1e-6)
    # Inf-Time over all episodes, per seed 2, 2, 1.
    assert s.inference_time.mean == pytest.approx(5 / 3)
    assert s.inference_time.std == pytest.approx(0.5773503, abs=1e-6)
    assert (s.num_seeds, s.episodes, s.errors) == (3, 12, 0)


def test_stat_edge_cases() -> None:
    assert Stat.of([]) == Stat(None, None, 0)
    assert Stat.of([0.5]) == Stat(0.5, None, 1)  # no std from one seed
    assert Stat.of([None, 1.0, 3.0]) == Stat(2.0, pytest.approx(1.4142136), 2)


def test_errors_count_as_failures() -> None:
    recs = [_rec(0, 0, True, -5, 1.0), _rec(0, 1, False, -2, 0.5, error="ValueError: x")]
    s = summarize(recs)
    assert (s.success.mean, s.errors, s.reward.mean) == (0.5, 1, -5.0)


def test_labels_are_disambiguated_per_run() -> None:
    recs = _example() + _example(run="r2")
    methods = [s.method for s in aggregate(recs)]
    assert methods == ["mpc[r1]", "mpc[r2]"]


def test_markdown_table_has_the_paper_layout() -> None:
    recs = [
        *_example(),
        _rec(0, 0, False, -50, 0.001, run="r3", label="random"),
        _rec(0, 0, True, -9, 0.5, run="r4", label="mpc", env="kinder/StickButton2D-b1-v0"),
    ]
    md = markdown_table(aggregate(recs))
    lines = md.splitlines()
    assert lines[0] == "| Env | Metric | mpc | random |"
    assert lines[2] == "| Motion2D-p0 | SR ↑ | **0.42 ± 0.38** | 0.00 |"
    assert lines[3] == "|  | Rwd ↑ | -22.5 ± 10.6 | -- |"
    assert lines[4] == "|  | Inf-Time (s) ↓ | 1.67 ± 0.58 | 0.001 |"
    assert lines[5] == "| StickButton2D-b1 | SR ↑ | **1.00** |  |"


def test_csv_round_trip() -> None:
    rows = list(csv.DictReader(io.StringIO(csv_table(aggregate(_example())))))
    assert len(rows) == 1
    row = rows[0]
    assert float(row["sr_mean"]) == pytest.approx(0.4166667, abs=1e-6)
    assert float(row["rwd_mean"]) == -22.5 and row["rwd_seeds"] == "2"
    assert row["num_seeds"] == "3" and row["episodes"] == "12"


def test_write_report(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in _example()))
    md, paths = write_report([run, run], tmp_path / "report")  # duplicates are dropped
    assert "0.42 ± 0.38" in md
    assert paths["plot"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert paths["csv"].read_text().count("\n") == 2
    with pytest.raises(FileNotFoundError, match="not a run directory"):
        write_report([tmp_path / "missing"])


def test_write_report_of_the_first_episodes_of_each_seed(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in _example()))
    (run / "config.json").write_text(json.dumps({"runs": [{"run_id": "r1", "command": "go"}]}))
    _, paths = write_report([run], tmp_path / "first", plot=False, first_episodes=1)
    (row,) = csv.DictReader(io.StringIO(paths["csv"].read_text()))
    episodes = {(r["seed"], r["episode"]) for r in _example() if r["episode"] < 1}
    assert row["episodes"] == str(len(episodes))
    assert float(row["sr_mean"]) == pytest.approx(2 / 3)  # seeds 0 and 1 succeed at episode 0
    assert row["command"].startswith("go; then kinder bench report ")
    assert row["command"].endswith(f"--first-episodes 1 --out {tmp_path / 'first'}")
    # The run directory's own summary describes the whole run: a subset needs its own folder.
    with pytest.raises(ValueError, match="needs an output directory"):
        write_report([run], first_episodes=1)
    with pytest.raises(ValueError, match="expected an integer >= 1"):
        write_report([run], tmp_path / "none", first_episodes=0)
