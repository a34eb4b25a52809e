"""The benchmark's metrics and their one aggregation rule.

Per episode: ``success`` (the env terminated: goal reached within the step budget), ``reward``
(sum of env rewards), ``steps``, ``inference_time`` (wall-clock seconds inside the agent's
``reset`` and ``act``) and ``env_time`` (seconds inside the env's ``reset`` and ``step``). An
episode that ended in an error counts as a failure with what it had accumulated.

Aggregation, for one method on one env:

1. Per seed, over that seed's episodes: success rate = mean of ``success``; Rwd = mean ``reward``
   over the *successful* episodes only (undefined when none succeeded); Inf-Time = mean
   ``inference_time`` over all episodes (likewise ``steps`` and ``env_time``).
2. Across seeds: the mean and the sample standard deviation (``ddof=1``) of the per-seed values;
   seeds where a value is undefined are left out (Rwd of a seed without success); the std is
   undefined with fewer than two values.

Envs with subtask milestones (:mod:`kinder_bench.evaluation.subtasks`) add, per milestone, the
rate of episodes that reached it, aggregated by the same two steps.
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from kinder_bench.evaluation.subtasks import in_order

METRICS = ("success", "reward", "inference_time", "steps", "env_time")


@dataclasses.dataclass(frozen=True)
class Stat:
    """Mean and sample std (ddof=1) of per-seed values; ``n`` = number of seeds that had one."""

    mean: float | None
    std: float | None
    n: int

    @classmethod
    def of(cls, values: Sequence[float | None]) -> Stat:
        vals = np.array([v for v in values if v is not None], dtype=np.float64)
        if len(vals) == 0:
            return cls(None, None, 0)
        std = float(np.std(vals, ddof=1)) if len(vals) > 1 else None
        return cls(float(np.mean(vals)), std, len(vals))


@dataclasses.dataclass(frozen=True)
class SeedMetrics:
    """One seed's per-episode means (``reward``: successful episodes only, None without any)."""

    seed: int
    episodes: int
    success: float
    reward: float | None
    inference_time: float
    steps: float
    env_time: float
    errors: int
    subtasks: dict[str, float] | None = None
    """Milestone → the rate of this seed's episodes that reached it (None: not tracked)."""


def subtask_rates(records: Sequence[Mapping[str, Any]]) -> dict[str, float] | None:
    """Milestone → the rate of ``records`` that reached it; None unless every record tracked
    the same milestones."""
    tracked: list[Mapping[str, int | None]] = []
    for r in records:
        t = r.get("subtasks")
        if t is None:
            return None
        tracked.append(t)
    if not tracked:
        return None
    names = in_order(records[0]["env_id"], tracked[0])
    if any(set(t) != set(names) for t in tracked):
        return None
    return {n: float(np.mean([t[n] is not None for t in tracked])) for n in names}


def seed_metrics(records: Sequence[Mapping[str, Any]]) -> SeedMetrics:
    """Step 1 of the aggregation, for the records of one seed."""
    if not records:
        raise ValueError("No episodes to aggregate")
    seeds = {r["seed"] for r in records}
    if len(seeds) != 1:
        raise ValueError(f"seed_metrics takes the episodes of one seed, got seeds {sorted(seeds)}")
    wins = [float(r["reward"]) for r in records if r["success"]]
    return SeedMetrics(
        seed=int(records[0]["seed"]),
        episodes=len(records),
        success=float(np.mean([bool(r["success"]) for r in records])),
        reward=float(np.mean(wins)) if wins else None,
        inference_time=float(np.mean([r["inference_time"] for r in records])),
        steps=float(np.mean([r["steps"] for r in records])),
        env_time=float(np.mean([r["env_time"] for r in records])),
        errors=sum(r.get("error") is not None for r in records),
        subtasks=subtask_rates(records),
    )


@dataclasses.dataclass(frozen=True)
class Summary:
    """The aggregate of one method on one env."""

    env_id: str
    method: str
    agent: str
    run_id: str
    agent_args: dict[str, Any]
    max_steps: int
    episodes: int
    errors: int
    per_seed: tuple[SeedMetrics, ...]
    success: Stat
    reward: Stat
    inference_time: Stat
    steps: Stat
    env_time: Stat
    obs_noise: float = 0.0
    """The run's observation noise std (records written before noise existed: 0)."""
    action_noise: float = 0.0
    """The run's action noise std."""
    subtasks: dict[str, Stat] = dataclasses.field(default_factory=dict)
    """Milestone → the rate of episodes that reached it, over seeds (empty: not tracked)."""

    @property
    def num_seeds(self) -> int:
        return len(self.per_seed)


def summarize(records: Sequence[Mapping[str, Any]], method: str | None = None) -> Summary:
    """Steps 1 and 2 of the aggregation for the records of one run (one method on one env)."""
    runs = {r["run_id"] for r in records}
    if len(runs) != 1:
        raise ValueError(f"summarize takes the episodes of one run, got runs {sorted(runs)}")
    by_seed: dict[int, list[Mapping[str, Any]]] = defaultdict(list)
    for r in records:
        by_seed[int(r["seed"])].append(r)
    per_seed = tuple(seed_metrics(by_seed[s]) for s in sorted(by_seed))
    first = records[0]
    return Summary(
        env_id=first["env_id"],
        method=method or first["label"],
        agent=first["agent"],
        run_id=first["run_id"],
        agent_args=dict(first["agent_args"]),
        max_steps=int(first["max_steps"]),
        episodes=len(records),
        errors=sum(s.errors for s in per_seed),
        per_seed=per_seed,
        success=Stat.of([s.success for s in per_seed]),
        reward=Stat.of([s.reward for s in per_seed]),
        inference_time=Stat.of([s.inference_time for s in per_seed]),
        steps=Stat.of([s.steps for s in per_seed]),
        env_time=Stat.of([s.env_time for s in per_seed]),
        obs_noise=float(first.get("obs_noise", 0.0)),
        action_noise=float(first.get("action_noise", 0.0)),
        subtasks=_subtask_stats(per_seed),
    )


def _subtask_stats(per_seed: Sequence[SeedMetrics]) -> dict[str, Stat]:
    """Milestone → its per-seed rates aggregated; empty unless every seed tracked them."""
    rates: list[dict[str, float]] = []
    for s in per_seed:
        if s.subtasks is None:
            return {}
        rates.append(s.subtasks)
    if not rates:
        return {}
    return {n: Stat.of([r.get(n) for r in rates]) for n in rates[0]}


def aggregate(records: Iterable[Mapping[str, Any]]) -> list[Summary]:
    """One :class:`Summary` per run (env × method), in order of first appearance.

    A method's name is its label; when one label covers runs with different arguments on the same
    env, the run id is appended to tell them apart.
    """
    groups: dict[str, list[Mapping[str, Any]]] = {}
    for r in records:
        groups.setdefault(r["run_id"], []).append(r)
    labels: dict[tuple[str, str], set[str]] = defaultdict(set)
    for recs in groups.values():
        labels[(recs[0]["env_id"], recs[0]["label"])].add(recs[0]["run_id"])
    out = []
    for rid, recs in groups.items():
        label = recs[0]["label"]
        if len(labels[(recs[0]["env_id"], label)]) > 1:
            label = f"{label}[{rid[:6]}]"
        out.append(summarize(recs, method=label))
    return out
