"""Our results beside the KinDER paper's: Table II's layout with the paper's value in every cell.

The paper's figures live in one data file, ``kinder_bench/data/paper_results.csv`` (its header
comment names the tables: Table II for the means, the appendix's standard-deviation table for the
std), loaded and checked by :func:`load_paper`. Our side is a list of :class:`Result` rows, made
from run directories (:func:`results_from_summaries`) or from committed ``summary.csv`` files
(:func:`results_from_csv`), so the same table comes from a fresh run and from
``benchmarks/results/``.

One rule decides what fills a cell beside the paper: a run at the paper's protocol, i.e. seeds 0–4
× 50 episodes, the protocol's step budget (:mod:`kinder_bench.evaluation.protocol`), the baseline's
paper settings and its paper training budget (``kinder_bench/data/paper_settings.csv``, loaded by
:func:`load_settings`). :func:`protocol_deviations` lists what a run's recorded settings (seeds,
episodes, step budget, agent arguments, training budget) do differently; a run with none, labelled
with its agent's name and measured by us (not transcribed from a page) on the env as it is now (not
listed in ``kinder_bench/data/pre_conformance_runs.csv``, the runs measured before their env was
made to follow upstream), is at the paper's protocol. Every other run is a variant, named by what
differs (:func:`variant_name`: ``MPC · 2×2, horizon=20``) and listed in its own row with its budget,
never in the paper's column. A paper cell is therefore at the paper's protocol, covered by variants
only, or not run (``n/r``) — and only then does it say why, as a lettered note under the table: the
agent's own :meth:`~kinder_bench.agents.Agent.unavailable` reason (a checkpoint, an endpoint, a GPU,
a planning model), that no such agent exists here, or that it can run here but is not in the given
runs. When several runs of one agent at the paper's protocol cover a paper env, the one with the
most episodes fills the cell and the others are listed as variants."""

from __future__ import annotations

import csv
import dataclasses
import functools
import io
import json
from collections.abc import Callable, Iterable, Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

from kinder_bench.agents import agent_name, unavailable_reason
from kinder_bench.evaluation.envs import short_id
from kinder_bench.evaluation.metrics import Stat, Summary
from kinder_bench.evaluation.protocol import (
    DEVELOPMENT_SEED,
    PAPER_EPISODES,
    PAPER_MAX_STEPS,
    PAPER_SEEDS,
)
from kinder_bench.evaluation.summary import parse_subtasks_field

METRICS = ("SR", "Rwd", "Inf-Time")
METRIC_LABELS = {"SR": "SR ↑", "Rwd": "Rwd ↑", "Inf-Time": "Inf-Time (s) ↓"}
PAPER_FILE = "paper_results.csv"
SETTINGS_FILE = "paper_settings.csv"
_COLUMNS = ("env_id", "method", "agent", "metric", "mean", "std")

#: The reason of a paper cell whose agent can run here but is not in the runs reported.
NOT_IN_RUNS = "can run here; not in these runs"


@dataclasses.dataclass(frozen=True)
class PaperValue:
    """One printed figure of the paper: the text as printed and its value (None for ``--``)."""

    mean_text: str
    std_text: str

    @property
    def mean(self) -> float | None:
        return _number(self.mean_text)

    @property
    def std(self) -> float | None:
        return _number(self.std_text)

    def text(self) -> str:
        """``mean ± std`` as printed (``--`` when the paper has no value)."""
        if self.mean is None:
            return "--"
        return self.mean_text if self.std is None else f"{self.mean_text} ± {self.std_text}"


@dataclasses.dataclass(frozen=True)
class PaperResults:
    """The paper's table: its envs and methods in column order, and every cell."""

    envs: tuple[str, ...]
    methods: tuple[str, ...]
    agents: Mapping[str, str]
    """Paper method → our agent name."""
    cells: Mapping[tuple[str, str, str], PaperValue]
    """(env id, paper method, metric) → value."""

    def method_of(self, agent: str) -> str | None:
        """The paper method an agent name stands for, if any."""
        return next((m for m, a in self.agents.items() if a == agent), None)


def _number(text: str) -> float | None:
    return None if text == "--" else float(text)


def parse_paper(text: str, source: str = PAPER_FILE) -> PaperResults:
    """Parse and check the paper's data file (``#`` lines are comments).

    Raises ValueError naming the line when a row is malformed, a metric unknown, a value neither
    a number nor ``--``, a method mapped to two agents, a cell given twice, or a cell missing
    from the full (env × method × metric) grid.
    """
    lines = [(n, line) for n, line in enumerate(text.splitlines(), 1) if not line.startswith("#")]
    rows = list(csv.reader(line for _, line in lines if line.strip()))
    numbers = [n for n, line in lines if line.strip()]
    if not rows or tuple(rows[0]) != _COLUMNS:
        raise ValueError(f"{source}: expected the header {','.join(_COLUMNS)}")
    envs: dict[str, None] = {}
    agents: dict[str, str] = {}
    cells: dict[tuple[str, str, str], PaperValue] = {}
    for n, row in zip(numbers[1:], rows[1:]):
        where = f"{source}:{n}"
        if len(row) != len(_COLUMNS):
            raise ValueError(f"{where}: expected {len(_COLUMNS)} fields, got {row}")
        env_id, method, agent, metric, mean, std = (f.strip() for f in row)
        if metric not in METRICS:
            raise ValueError(f"{where}: metric {metric!r} is not one of {METRICS}")
        for value in (mean, std):
            try:
                _number(value)
            except ValueError:
                raise ValueError(f"{where}: {value!r} is neither a number nor '--'") from None
        if agents.setdefault(method, agent) != agent:
            raise ValueError(f"{where}: {method} maps to {agent!r} and {agents[method]!r}")
        key = (env_id, method, metric)
        if key in cells:
            raise ValueError(f"{where}: the cell {key} is given twice")
        envs[env_id] = None
        cells[key] = PaperValue(mean, std)
    missing = [(e, m, k) for e in envs for m in agents for k in METRICS if (e, m, k) not in cells]
    if missing:
        raise ValueError(f"{source}: {len(missing)} cells are missing, e.g. {missing[:3]}")
    return PaperResults(tuple(envs), tuple(agents), agents, cells)


@functools.cache
def load_paper() -> PaperResults:
    """The paper's results, from the package's data file."""
    text = resources.files("kinder_bench.data").joinpath(PAPER_FILE).read_text(encoding="utf-8")
    return parse_paper(text)


@dataclasses.dataclass(frozen=True)
class Result:
    """Our aggregate of one method on one env, whatever it was read from."""

    env_id: str
    method: str
    """The method's label in our runs."""
    agent: str
    """The agent's registered name (or its entry point when it has none)."""
    run_id: str
    success: Stat
    reward: Stat
    inference_time: Stat
    num_seeds: int
    episodes: int
    errors: int
    command: str = ""
    """The command that produced it, when known."""
    settings: str = ""
    """What tells this run from others of its label (``search=gbfs``), shown after its name."""
    seeds: tuple[int, ...] | None = None
    """The run seeds (None: not recorded)."""
    max_steps: int | None = None
    """The step budget per episode (None: not recorded)."""
    agent_args: Mapping[str, Any] | None = None
    """The agent's full arguments (None: not recorded)."""
    training: str = ""
    """The training budget of a learned agent's checkpoints (``1M env steps``; empty: not
    recorded)."""
    provenance: str = ""
    """Where a row not made from a run directory comes from (``transcribed from rl.md @ 39c729e``);
    empty for rows the runner wrote."""
    summary: str = ""
    """The name of the summary file the row was read from (empty: not read from one)."""
    obs_noise: float = 0.0
    """The observation noise std of a run under noise (0: none)."""
    action_noise: float = 0.0
    """The action noise std of a run under noise (0: none)."""
    subtasks: Mapping[str, Stat] = dataclasses.field(default_factory=dict)
    """Milestone → the rate of episodes that reached it (empty: not tracked)."""

    @property
    def name(self) -> str:
        """The method's label with its settings: ``bilevel_planning (search=gbfs)``."""
        return f"{self.method} ({self.settings})" if self.settings else self.method

    @property
    def is_variant(self) -> bool:
        """Labelled other than its agent's name (``ppo-dense``), not counting the run id that
        :func:`~kinder_bench.evaluation.metrics.aggregate` appends to tell runs of one label
        apart."""
        return self.method.removesuffix(f"[{self.run_id[:6]}]") != self.agent

    def stat(self, metric: str) -> Stat:
        return {"SR": self.success, "Rwd": self.reward, "Inf-Time": self.inference_time}[metric]


def results_from_summaries(
    summaries: Iterable[Summary],
    commands: Mapping[str, str] | None = None,
    trainings: Mapping[str, str] | None = None,
) -> list[Result]:
    """Results from :func:`~kinder_bench.evaluation.metrics.aggregate`'s summaries (``commands``:
    run id → the command that ran it; ``trainings``: run id → its training budget)."""
    commands = commands or {}
    trainings = trainings or {}
    return [
        Result(
            env_id=s.env_id,
            method=agent_name(s.method),
            agent=agent_name(s.agent),
            run_id=s.run_id,
            success=s.success,
            reward=s.reward,
            inference_time=s.inference_time,
            num_seeds=s.num_seeds,
            episodes=s.episodes,
            errors=s.errors,
            command=commands.get(s.run_id, ""),
            seeds=tuple(m.seed for m in s.per_seed),
            max_steps=s.max_steps,
            agent_args=dict(s.agent_args),
            training=trainings.get(s.run_id, ""),
            obs_noise=s.obs_noise,
            action_noise=s.action_noise,
            subtasks=dict(s.subtasks),
        )
        for s in summaries
    ]


def _stat(row: Mapping[str, str], prefix: str, n: int) -> Stat:
    mean, std = row.get(f"{prefix}_mean", ""), row.get(f"{prefix}_std", "")
    return Stat(float(mean) if mean else None, float(std) if std else None, n if mean else 0)


def _optional_int(text: str | None) -> int | None:
    return int(text) if text else None


def parse_seeds_field(text: str) -> tuple[int, ...] | None:
    """The ``seeds`` field of a summary row (space-separated integers; empty: not recorded)."""
    return tuple(int(x) for x in text.split()) if text.strip() else None


def results_from_csv(path: Path | str) -> list[Result]:
    """Results from a ``summary.csv`` written by the report (extra columns are ignored; the
    ``command``, ``seeds``, ``max_steps``, ``agent_args`` (JSON), ``training``, ``provenance``,
    ``obs_noise``, ``action_noise`` and ``subtasks`` columns, when there, are kept)."""
    path = Path(path)
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    out = []
    for n, row in enumerate(rows, start=2):
        try:
            seeds = int(row["num_seeds"])
            rwd_seeds = int(row.get("rwd_seeds") or 0)
            out.append(
                Result(
                    env_id=row["env_id"],
                    method=agent_name(row["method"]),
                    agent=agent_name(row["agent"]),
                    run_id=row["run_id"],
                    success=_stat(row, "sr", seeds),
                    reward=_stat(row, "rwd", rwd_seeds),
                    inference_time=_stat(row, "inf_time", seeds),
                    num_seeds=seeds,
                    episodes=int(row["episodes"]),
                    errors=int(row.get("errors") or 0),
                    command=row.get("command", "") or "",
                    seeds=parse_seeds_field(row.get("seeds") or ""),
                    max_steps=_optional_int(row.get("max_steps")),
                    agent_args=json.loads(row["agent_args"]) if row.get("agent_args") else None,
                    training=row.get("training", "") or "",
                    provenance=row.get("provenance", "") or "",
                    summary=path.name,
                    obs_noise=float(row.get("obs_noise") or 0.0),
                    action_noise=float(row.get("action_noise") or 0.0),
                    subtasks=parse_subtasks_field(row.get("subtasks") or "", seeds),
                )
            )
        except (KeyError, ValueError) as e:
            raise ValueError(f"{path}:{n}: not a summary row ({type(e).__name__}: {e})") from e
    return out


#: Digits of a std in the paper's appendix table.
STD_DIGITS = 3


def fmt_stat(stat: Stat, digits: int, std_digits: int | None = None) -> str:
    """``mean ± std`` (just the mean with one seed; ``--`` when undefined); the std with
    ``std_digits`` digits (default: ``digits``)."""
    if stat.mean is None:
        return "--"
    text = f"{stat.mean:.{digits}f}"
    if stat.std is not None:
        text += f" ± {stat.std:.{digits if std_digits is None else std_digits}f}"
    return text


def metric_digits(metric: str, stat: Stat) -> int:
    """Digits as the paper prints them: SR 2, Rwd 1, Inf-Time 2 (3 below 0.1 s)."""
    if metric == "SR":
        return 2
    if metric == "Rwd":
        return 1
    return 3 if stat.mean is not None and abs(stat.mean) < 0.1 else 2


_SETTINGS_COLUMNS = ("agent", "env_id", "setting", "value", "source")
#: Settings whose value is plain text, not a JSON literal.
_TEXT_SETTINGS = ("training",)
#: Settings that are not agent arguments.
_RUN_SETTINGS = ("max_steps", "training")

Settings = Mapping[tuple[str, str], Mapping[str, Any]]
"""(agent, env id or ``*``) → {setting: value}: the baselines' paper settings."""


def parse_settings(text: str, source: str = SETTINGS_FILE) -> dict[tuple[str, str], dict[str, Any]]:
    """Parse and check the paper-settings data file (``#`` lines are comments).

    Raises ValueError naming the line when a row is malformed, its env is neither ``*`` nor a
    benchmark env, a value is not a JSON literal (``training`` is plain text) or a setting is
    given twice for one (agent, env).
    """
    lines = [(n, line) for n, line in enumerate(text.splitlines(), 1) if not line.startswith("#")]
    lines = [(n, line) for n, line in lines if line.strip()]
    rows = list(csv.reader(line for _, line in lines))
    if not rows or tuple(rows[0]) != _SETTINGS_COLUMNS:
        raise ValueError(f"{source}: expected the header {','.join(_SETTINGS_COLUMNS)}")
    out: dict[tuple[str, str], dict[str, Any]] = {}
    for (n, _), row in zip(lines[1:], rows[1:]):
        where = f"{source}:{n}"
        if len(row) != len(_SETTINGS_COLUMNS) or not all(f.strip() for f in row[:4]):
            raise ValueError(
                f"{where}: expected {len(_SETTINGS_COLUMNS)} non-empty fields, got {row}"
            )
        agent, env_id, setting, value = (f.strip() for f in row[:4])
        if env_id != "*" and env_id not in PAPER_MAX_STEPS:
            raise ValueError(f"{where}: env {env_id!r} is neither '*' nor a benchmark env")
        parsed: Any = value
        if setting not in _TEXT_SETTINGS:
            try:
                parsed = json.loads(value)
            except json.JSONDecodeError:
                raise ValueError(f"{where}: {value!r} is not a JSON literal") from None
        group = out.setdefault((agent, env_id), {})
        if setting in group:
            raise ValueError(f"{where}: {setting} of {agent} on {env_id} is given twice")
        group[setting] = parsed
    return out


@functools.cache
def load_settings() -> Settings:
    """The baselines' paper settings, from the package's data file."""
    text = resources.files("kinder_bench.data").joinpath(SETTINGS_FILE).read_text(encoding="utf-8")
    return parse_settings(text)


def paper_settings(agent: str, env_id: str, settings: Settings | None = None) -> dict[str, Any]:
    """What a run of ``agent`` on ``env_id`` must use to be at the paper's protocol (the env's
    own rows over the ``*`` rows)."""
    table = load_settings() if settings is None else settings
    out = dict(table.get((agent, "*"), {}))
    out.update(table.get((agent, env_id), {}))
    return out


PRE_CONFORMANCE_FILE = "pre_conformance_runs.csv"
_PRE_CONFORMANCE_COLUMNS = ("run_id", "env_id", "changed_at", "summary")


def csv_rows(text: str) -> list[list[str]]:
    """The CSV rows of a data file's text, blank lines and ``#`` comment lines left out."""
    lines = [line for line in text.splitlines() if line.strip() and not line.startswith("#")]
    return list(csv.reader(lines))


def parse_pre_conformance(
    text: str, source: str = PRE_CONFORMANCE_FILE
) -> frozenset[tuple[str, str, str]]:
    """The (run id, env id, summary file) triples of a pre-conformance list (``#`` lines are
    comments).

    Raises ValueError naming the line when a row lacks a field or the header is not
    ``run_id,env_id,changed_at,summary``.
    """
    rows = csv_rows(text)
    header = ",".join(_PRE_CONFORMANCE_COLUMNS)
    if not rows or tuple(rows[0]) != _PRE_CONFORMANCE_COLUMNS:
        raise ValueError(f"{source}: expected the header {header}")
    out = set()
    for n, row in enumerate(rows[1:], start=2):
        if len(row) != len(_PRE_CONFORMANCE_COLUMNS) or not all(f.strip() for f in row):
            raise ValueError(f"{source}: data row {n - 1}: expected {header}, got {row}")
        out.add((row[0].strip(), row[1].strip(), row[3].strip()))
    return frozenset(out)


@functools.cache
def load_pre_conformance() -> frozenset[tuple[str, str, str]]:
    """Committed runs measured on an env that has changed since, to follow upstream (the
    package's data file says which and why)."""
    data = resources.files("kinder_bench.data").joinpath(PRE_CONFORMANCE_FILE)
    return parse_pre_conformance(data.read_text(encoding="utf-8"))


def measured_before_conformance(result: Result) -> bool:
    """Whether ``result`` is a listed pre-conformance run: its run id and env, and, for a row
    read from a summary file, that file (a re-run on the changed env shares the run id)."""
    return any(
        (run_id, env_id) == (result.run_id, result.env_id)
        and (not result.summary or summary == result.summary)
        for run_id, env_id, summary in load_pre_conformance()
    )


#: How :func:`protocol_deviations` names a run measured before its env followed upstream.
PRE_CONFORMANCE = "env before upstream conformance"


def _value_text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def _same(got: Any, want: Any) -> bool:
    """Equal as settings: ``1 == 1.0``, but a bool only equals a bool."""
    if isinstance(got, bool) or isinstance(want, bool):
        return isinstance(got, bool) and isinstance(want, bool) and got == want
    return bool(got == want)


def protocol_deviations(result: Result, settings: Settings | None = None) -> tuple[str, ...]:
    """What a run does differently from the paper's protocol, from its recorded settings, in
    words short enough for a name (``5×10``, ``horizon=20``, ``training not recorded``); empty
    when the run is at the paper's protocol. A setting the row does not record counts as a
    difference: a cell is filled only by what is known to match."""
    want = paper_settings(result.agent, result.env_id, settings)
    out: list[str] = []
    per_seed = result.episodes // max(1, result.num_seeds)
    if (
        result.num_seeds != len(PAPER_SEEDS)
        or per_seed != PAPER_EPISODES
        or result.episodes != result.num_seeds * per_seed
    ):
        out.append(f"{result.num_seeds}×{per_seed}")
        if result.seeds and min(result.seeds) >= DEVELOPMENT_SEED:
            out.append("development seeds " + " ".join(str(s) for s in result.seeds))
    elif result.seeds is None:
        out.append("seeds not recorded")
    elif tuple(sorted(result.seeds)) != PAPER_SEEDS:
        out.append("seeds " + " ".join(str(s) for s in result.seeds))
    budget = want.get("max_steps", PAPER_MAX_STEPS.get(result.env_id))
    if result.max_steps is None:
        out.append("step budget not recorded")
    elif budget is not None and result.max_steps != budget:
        out.append(f"{result.max_steps} steps")
    args = {k: v for k, v in want.items() if k not in _RUN_SETTINGS}
    if args and result.agent_args is None:
        out.append("args not recorded")
    elif result.agent_args is not None:
        for key, value in args.items():
            if key not in result.agent_args:
                out.append(f"{key} not recorded")
            elif not _same(result.agent_args[key], value):
                out.append(f"{key}={_value_text(result.agent_args[key])}")
    if "training" in want and result.training != want["training"]:
        out.append(f"training {result.training}" if result.training else "training not recorded")
    if result.obs_noise:
        out.append(f"obs noise {result.obs_noise:g}")
    if result.action_noise:
        out.append(f"action noise {result.action_noise:g}")
    if result.provenance:
        out.append("transcribed")
    if measured_before_conformance(result):
        out.append(PRE_CONFORMANCE)
    return tuple(out)


def variant_name(
    result: Result, paper: PaperResults | None = None, settings: Settings | None = None
) -> str:
    """A run's name in the comparison: its paper method (or its label, for an agent the paper
    does not have or a run labelled otherwise), its settings, then what differs from the
    paper's protocol (``MPC · 2×2, horizon=20``)."""
    paper = paper or load_paper()
    method = paper.method_of(result.agent)
    if method is None or result.is_variant:
        base = result.name
    else:
        base = f"{method} ({result.settings})" if result.settings else method
    deviations = protocol_deviations(result, settings)
    return f"{base} · {', '.join(deviations)}" if deviations else base


def at_paper_protocol(
    result: Result, paper: PaperResults | None = None, settings: Settings | None = None
) -> bool:
    """Whether a run may fill its paper cell: an agent and env of the paper's table, labelled
    with its agent's name, measured here, and without deviation from the paper's protocol."""
    paper = paper or load_paper()
    return (
        paper.method_of(result.agent) is not None
        and result.env_id in paper.envs
        and not result.is_variant
        and not protocol_deviations(result, settings)
    )


@dataclasses.dataclass(frozen=True)
class Column:
    """One column of the comparison: a paper method and our agent for it."""

    key: str
    title: str
    agent: str
    paper_method: str | None


PAPER = "paper"
VARIANTS_ONLY = "variants only"
NOT_RUN = "n/r"


@dataclasses.dataclass(frozen=True)
class Cell:
    """One (env, paper method, metric) of the comparison."""

    env_id: str
    column: Column
    metric: str
    ours: Result | None
    """Our run at the paper's protocol, if any."""
    paper: PaperValue | None
    reason: str | None
    """Why no run of any kind exists (None when one does)."""
    variants: tuple[Result, ...] = ()
    """Our runs of this baseline on this env that are not at the paper's protocol."""

    @property
    def status(self) -> str:
        """:data:`PAPER`, :data:`VARIANTS_ONLY` or :data:`NOT_RUN`."""
        if self.ours is not None:
            return PAPER
        return VARIANTS_ONLY if self.variants else NOT_RUN

    @property
    def ours_text(self) -> str:
        if self.ours is None:
            return ""
        stat = self.ours.stat(self.metric)
        return fmt_stat(stat, metric_digits(self.metric, stat), STD_DIGITS)


@dataclasses.dataclass(frozen=True)
class Comparison:
    """Every cell of the paper's table, with its envs and columns in order, and every run that
    does not fill a cell (variants, other agents, other envs) with its name."""

    envs: tuple[str, ...]
    columns: tuple[Column, ...]
    cells: Mapping[tuple[str, str, str], Cell]
    """(env id, column key, metric) → cell."""
    others: tuple[tuple[str, Result], ...] = ()
    """(name, run) of every run that fills no paper cell, paper envs first."""

    def cell(self, env_id: str, column: Column, metric: str) -> Cell:
        return self.cells[(env_id, column.key, metric)]

    def paper_cells(self) -> list[Cell]:
        """One cell (its SR) per (env, paper method)."""
        return [self.cell(e, c, "SR") for e in self.envs for c in self.columns]


Reasoner = Callable[[str, str], str | None]
"""(agent name, env id) → why it cannot run here, or None."""


def compare(
    results: Sequence[Result],
    paper: PaperResults | None = None,
    reason: Reasoner | None = None,
    settings: Settings | None = None,
) -> Comparison:
    """Pair our results with the paper's cells (see the module docstring for the rule)."""
    paper = paper or load_paper()
    reason = reason or (lambda agent, env: unavailable_reason(agent, env))
    primary: dict[tuple[str, str], Result] = {}
    for r in results:
        if not at_paper_protocol(r, paper, settings):
            continue
        best = primary.get((r.env_id, r.agent))
        if best is None or r.episodes > best.episodes:
            primary[(r.env_id, r.agent)] = r
    filling = {id(r) for r in primary.values()}
    others = [r for r in results if id(r) not in filling]
    env_order = {e: i for i, e in enumerate(paper.envs)}
    others.sort(key=lambda r: env_order.get(r.env_id, len(env_order)))
    columns = tuple(
        Column(m, f"{m} ({paper.agents[m]})", paper.agents[m], m) for m in paper.methods
    )
    cells: dict[tuple[str, str, str], Cell] = {}
    for env in paper.envs:
        for col in columns:
            ours = primary.get((env, col.agent))
            variants = tuple(r for r in others if r.env_id == env and r.agent == col.agent)
            why = None
            if ours is None and not variants:
                why = reason(col.agent, env) or NOT_IN_RUNS
            for metric in METRICS:
                pv = paper.cells.get((env, col.key, metric))
                cells[(env, col.key, metric)] = Cell(env, col, metric, ours, pv, why, variants)
    named = tuple((variant_name(r, paper, settings), r) for r in others)
    return Comparison(paper.envs, columns, cells, named)


def _notes(comparison: Comparison) -> dict[str, str]:
    """Reason → its letter, in order of first appearance."""
    letters: dict[str, str] = {}
    for cell in comparison.cells.values():
        if cell.reason is not None and cell.reason not in letters:
            n = len(letters)
            letters[cell.reason] = chr(ord("a") + n) if n < 26 else f"n{n}"
    return letters


def _short_reason(reason: str) -> str:
    """A reason's first clause (up to its first colon or semicolon)."""
    for stop in (":", ";"):
        reason = reason.split(stop, 1)[0]
    return reason.strip().rstrip(".")


def cell_counts(comparison: Comparison) -> list[tuple[str, int]]:
    """(state, count) of the paper's (method × env) cells: at the paper's protocol, covered by
    variants only, then not run per reason (with its note letter), then the total."""
    cells = comparison.paper_cells()
    out = [
        ("at the paper's protocol", sum(c.status == PAPER for c in cells)),
        ("variants only (listed under the table)", sum(c.status == VARIANTS_ONLY for c in cells)),
    ]
    for why, letter in _notes(comparison).items():
        out.append((f"n/r [{letter}]: {_short_reason(why)}", sum(c.reason == why for c in cells)))
    out.append(("total", len(cells)))
    return out


def counts_markdown(comparison: Comparison) -> str:
    """:func:`cell_counts` as a markdown table."""
    lines = [
        f"| The paper's {len(comparison.columns)} × {len(comparison.envs)} cells | count |",
        "|---|---|",
    ]
    lines += [f"| {state} | {n} |" for state, n in cell_counts(comparison)]
    return "\n".join(lines) + "\n"


def _budget(result: Result) -> str:
    per_seed = result.episodes // max(1, result.num_seeds)
    text = f"{result.num_seeds} × {per_seed}"
    if result.max_steps is not None:
        text += f", {result.max_steps} steps"
    if result.training:
        text += f", trained {result.training}"
    return text


def others_markdown(comparison: Comparison) -> str:
    """Every run that fills no paper cell, one row each with its budget, beside the paper's
    figure for its baseline (when the paper has the baseline and the env)."""
    paper = load_paper()
    lines = [
        "| Env | Run | Seeds × episodes, budget | SR ↑ | Rwd ↑ | Inf-Time (s) ↓ "
        "| Paper SR (its baseline) | Provenance |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, r in comparison.others:
        stats = [fmt_stat(r.stat(m), metric_digits(m, r.stat(m)), STD_DIGITS) for m in METRICS]
        method = paper.method_of(r.agent)
        pv = paper.cells.get((r.env_id, method, "SR")) if method else None
        ref = f"{pv.text()} ({method})" if pv is not None else ""
        where = r.provenance or "measured (run summary)"
        lines.append(
            f"| {short_id(r.env_id)} | {name} | {_budget(r)} | "
            + " | ".join(stats)
            + f" | {ref} | {where} |"
        )
    return "\n".join(lines) + "\n"


def paper_markdown(comparison: Comparison) -> str:
    """The counts, the paper's Table II layout (every cell ``ours (paper)`` for a run at the
    paper's protocol, ``var.`` when only variants ran, ``n/r [x]`` with a note when nothing
    ran), then every other run in rows of its own."""
    notes = _notes(comparison)
    cols = comparison.columns
    lines = [
        counts_markdown(comparison).rstrip("\n"),
        "",
        "Each cell: ours (paper), mean ± std over seeds (the std with three digits, as the "
        "paper's appendix prints it; the paper's mean from Table II, its std from the appendix), "
        "filled only by a run at the paper's protocol (seeds 0–4 × 50 episodes, the paper's step "
        "budget, the baseline's paper settings and training budget). `var.`: only variants ran "
        "(rows below the table); `n/r [x]`: no run of any kind, note x below; `--`: undefined "
        "(no success, or no episode).",
        "",
        "| Env | Metric | " + " | ".join(c.title for c in cols) + " |",
        "|---|---|" + "---|" * len(cols),
    ]
    for env in comparison.envs:
        srs = [comparison.cell(env, c, "SR").ours for c in cols]
        best = max((r.success.mean or 0.0 for r in srs if r is not None), default=0.0)
        for i, metric in enumerate(METRICS):
            row = []
            for c in cols:
                cell = comparison.cell(env, c, metric)
                if cell.ours is not None:
                    ours = cell.ours_text
                    if metric == "SR" and best > 0 and cell.ours.success.mean == best:
                        ours = f"**{ours}**"
                elif cell.variants:
                    ours = "var."
                elif cell.reason is not None:
                    ours = f"n/r [{notes[cell.reason]}]"
                else:
                    ours = ""
                if cell.paper is not None:
                    ours = f"{ours} ({cell.paper.text()})".strip()
                row.append(ours)
            label = short_id(env) if i == 0 else ""
            lines.append(f"| {label} | {METRIC_LABELS[metric]} | " + " | ".join(row) + " |")
    if notes:
        lines += ["", "Not run: no run of any kind exists for these cells.", ""]
        lines += [f"- [{letter}] {why}" for why, letter in notes.items()]
    if comparison.others:
        lines += [
            "",
            "Variants and other runs: every run that does not fill a cell above, named by what "
            "differs from the paper's protocol (`5×10`: 5 seeds × 10 episodes; `transcribed`: "
            "copied from the page its provenance names, its run directory gone).",
            "",
            others_markdown(comparison).rstrip("\n"),
        ]
    return "\n".join(lines) + "\n"


PAPER_CSV_COLUMNS = (
    "env_id",
    "column",
    "agent",
    "paper_method",
    "metric",
    "status",
    "ours_mean",
    "ours_std",
    "ours_seeds",
    "ours_episodes",
    "paper_mean",
    "paper_std",
    "not_run_reason",
    "variants",
)


def paper_csv(comparison: Comparison) -> str:
    """One row per (env, paper method, metric): its status, ours (at the paper's protocol), the
    paper's (as printed), why not run, and the names of the variants that ran."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(PAPER_CSV_COLUMNS)
    names = {id(r): name for name, r in comparison.others}

    def v(x: float | None) -> str:
        return "" if x is None else repr(x)

    for cell in comparison.cells.values():
        stat = cell.ours.stat(cell.metric) if cell.ours is not None else None
        writer.writerow(
            [
                cell.env_id,
                cell.column.key,
                cell.column.agent,
                cell.column.paper_method or "",
                cell.metric,
                cell.status,
                v(stat.mean) if stat else "",
                v(stat.std) if stat else "",
                cell.ours.num_seeds if cell.ours else "",
                cell.ours.episodes if cell.ours else "",
                cell.paper.mean_text if cell.paper else "",
                cell.paper.std_text if cell.paper else "",
                cell.reason or "",
                "; ".join(names[id(r)] for r in cell.variants),
            ]
        )
    return buf.getvalue()


def comparison_json(comparison: Comparison) -> list[dict[str, Any]]:
    """The cells as plain dicts (for the HTML report)."""
    names = {id(r): name for name, r in comparison.others}
    out = []
    for cell in comparison.cells.values():
        out.append(
            {
                "env": cell.env_id,
                "column": cell.column.key,
                "agent": cell.column.agent,
                "paper_method": cell.column.paper_method,
                "metric": cell.metric,
                "status": cell.status,
                "ours": cell.ours_text if cell.ours is not None else None,
                "paper": cell.paper.text() if cell.paper is not None else None,
                "reason": cell.reason,
                "variants": [names[id(r)] for r in cell.variants],
            }
        )
    return out
