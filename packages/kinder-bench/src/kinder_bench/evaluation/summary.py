"""A run's summary rows (``summary.csv``): one row per env × method with the aggregate, the
command that ran it and the settings that decide whether it is at the paper's protocol.

The runner writes this file for every run directory when a run ends; the report writes it again
for the run directories it aggregates.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from kinder_bench.evaluation.metrics import Stat, Summary
from kinder_bench.evaluation.results import load_config

CSV_FILE = "summary.csv"


def dedupe(records: Iterable[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """Keep the first record of each (run, seed, episode)."""
    seen: set[tuple[str, int, int]] = set()
    out = []
    for r in records:
        key = (r["run_id"], r["seed"], r["episode"])
        if key not in seen:
            seen.add(key)
            out.append(r)
    return out


CSV_COLUMNS = (
    "env_id",
    "method",
    "agent",
    "run_id",
    "max_steps",
    "num_seeds",
    "episodes",
    "errors",
    "sr_mean",
    "sr_std",
    "rwd_mean",
    "rwd_std",
    "rwd_seeds",
    "inf_time_mean",
    "inf_time_std",
    "steps_mean",
    "steps_std",
    "env_time_mean",
    "env_time_std",
    "command",
    "seeds",
    "agent_args",
    "training",
    "provenance",
    "obs_noise",
    "action_noise",
    "subtasks",
)
"""A summary row: the aggregate, the command that ran it, and the settings that decide whether
it is at the paper's protocol (:func:`kinder_bench.reporting.paper.protocol_deviations`): ``seeds``
(space-separated), ``agent_args`` (JSON), ``training`` (a learned agent's training budget, written
by the tool that trained it), ``provenance`` (empty for rows the runner wrote; where a
transcribed row comes from otherwise), ``obs_noise``/``action_noise`` (the noise stds of a
run under noise; empty: none, as in every row written before the columns existed) and
``subtasks`` (JSON, milestone → ``[mean, std]`` over seeds of the rate of episodes that reached
it, for envs with milestones, :mod:`kinder_bench.evaluation.subtasks`; empty otherwise)."""


def subtasks_field(subtasks: Mapping[str, Stat]) -> str:
    """The ``subtasks`` column: JSON milestone → ``[mean, std]`` (empty when none tracked)."""
    if not subtasks:
        return ""
    return json.dumps({k: [st.mean, st.std] for k, st in subtasks.items()})


def parse_subtasks_field(text: str, num_seeds: int) -> dict[str, Stat]:
    """The ``subtasks`` column back as milestone → :class:`Stat` (empty text: none)."""
    if not text.strip():
        return {}
    data = json.loads(text)
    if not isinstance(data, dict) or not all(
        isinstance(v, list) and len(v) == 2 for v in data.values()
    ):
        raise ValueError(f"subtasks: expected a JSON object of [mean, std] pairs, got {text!r}")
    return {
        k: Stat(mean, std, num_seeds if mean is not None else 0) for k, (mean, std) in data.items()
    }


def run_commands(run_dirs: Sequence[Path | str]) -> dict[str, str]:
    """Run id → the command recorded for it in the run directories' ``config.json``."""
    out: dict[str, str] = {}
    for d in run_dirs:
        for run in load_config(d).get("runs", []):
            if run.get("command"):
                out[run["run_id"]] = run["command"]
    return out


def run_trainings(run_dirs: Sequence[Path | str]) -> dict[str, str]:
    """Run id → the training budget recorded for it in the run directories' ``config.json``."""
    out: dict[str, str] = {}
    for d in run_dirs:
        for run in load_config(d).get("runs", []):
            if run.get("training"):
                out[run["run_id"]] = run["training"]
    return out


def csv_table(
    summaries: Sequence[Summary],
    commands: Mapping[str, str] | None = None,
    trainings: Mapping[str, str] | None = None,
) -> str:
    """One row per env × method (empty cells where a value is undefined); ``command``: the
    command recorded for the run (``commands``: run id → command); ``training``: its training
    budget (``trainings``: run id → budget); ``provenance`` is left empty (a runner row)."""
    commands = commands or {}
    trainings = trainings or {}
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)

    def v(x: float | None) -> str:
        return "" if x is None else repr(x)

    for s in summaries:
        writer.writerow(
            [
                s.env_id,
                s.method,
                s.agent,
                s.run_id,
                s.max_steps,
                s.num_seeds,
                s.episodes,
                s.errors,
                v(s.success.mean),
                v(s.success.std),
                v(s.reward.mean),
                v(s.reward.std),
                s.reward.n,
                v(s.inference_time.mean),
                v(s.inference_time.std),
                v(s.steps.mean),
                v(s.steps.std),
                v(s.env_time.mean),
                v(s.env_time.std),
                commands.get(s.run_id, ""),
                " ".join(str(m.seed) for m in s.per_seed),
                json.dumps(s.agent_args, sort_keys=True, default=str),
                trainings.get(s.run_id, ""),
                "",
                v(s.obs_noise) if s.obs_noise else "",
                v(s.action_noise) if s.action_noise else "",
                subtasks_field(s.subtasks),
            ]
        )
    return buf.getvalue()
