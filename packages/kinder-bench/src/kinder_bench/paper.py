"""Our results beside the KinDER paper's: Table II's layout with the paper's value in every cell.

The paper's figures live in one data file, ``kinder_bench/data/paper_results.csv`` (its header
comment names the tables: Table II for the means, the appendix's standard-deviation table for the
std), loaded and checked by :func:`load_paper`. Our side is a list of :class:`Result` rows, made
from run directories (:func:`results_from_summaries`) or from committed ``summary.csv`` files
(:func:`results_from_csv`), so the same table comes from a fresh run and from
``benchmarks/results/``.

:func:`paper_markdown` writes the paper's layout: one column per paper method (BP, LLMCon, ...,
SAC, with our agent's name), then one per method we ran that the paper does not have; per env
(the paper's eight first, then any other env we ran) the rows SR ↑, Rwd ↑ and Inf-Time ↓. Each
cell is ``ours (paper)``, both ``mean ± std`` in the paper's form (the mean with Table II's digits,
the std with its appendix's three): ours over seeds as in :mod:`kinder_bench.metrics`, the
paper's as printed. A paper cell we have no result for says why, as a
lettered note under the table: the agent's own :meth:`~kinder_bench.agents.Agent.unavailable`
reason (a checkpoint, an endpoint, a GPU, a planning model), that no such agent exists here, or
that it can run here but is not in the given runs.

When several of our runs of one agent cover a paper env (e.g. two argument settings), the one
with the most episodes fills the paper column and the others get columns of their own. A run
labelled other than its agent's name (e.g. ``ppo-dense``, PPO trained on BaseMotion3D's dense
reward by ``benchmarks/rl_bench.py``) is a variant of the paper's setting and never fills the
paper column: it gets its own.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import io
from collections.abc import Callable, Iterable, Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

from kinder_bench.agents import agent_name, unavailable_reason
from kinder_bench.envs import short_id
from kinder_bench.metrics import Stat, Summary

METRICS = ("SR", "Rwd", "Inf-Time")
METRIC_LABELS = {"SR": "SR ↑", "Rwd": "Rwd ↑", "Inf-Time": "Inf-Time (s) ↓"}
PAPER_FILE = "paper_results.csv"
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

    @property
    def name(self) -> str:
        """The method's label with its settings: ``bilevel_planning (search=gbfs)``."""
        return f"{self.method} ({self.settings})" if self.settings else self.method

    @property
    def is_variant(self) -> bool:
        """Labelled other than its agent's name (``ppo-dense``), not counting the run id that
        :func:`~kinder_bench.metrics.aggregate` appends to tell runs of one label apart."""
        return self.method.removesuffix(f"[{self.run_id[:6]}]") != self.agent

    def stat(self, metric: str) -> Stat:
        return {"SR": self.success, "Rwd": self.reward, "Inf-Time": self.inference_time}[metric]


def results_from_summaries(
    summaries: Iterable[Summary], commands: Mapping[str, str] | None = None
) -> list[Result]:
    """Results from :func:`~kinder_bench.metrics.aggregate`'s summaries (``commands``: run id →
    the command that ran it)."""
    commands = commands or {}
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
        )
        for s in summaries
    ]


def _stat(row: Mapping[str, str], prefix: str, n: int) -> Stat:
    mean, std = row.get(f"{prefix}_mean", ""), row.get(f"{prefix}_std", "")
    return Stat(float(mean) if mean else None, float(std) if std else None, n if mean else 0)


def results_from_csv(path: Path | str) -> list[Result]:
    """Results from a ``summary.csv`` written by the report (extra columns are ignored; a
    ``command`` column, when there, is kept)."""
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


@dataclasses.dataclass(frozen=True)
class Column:
    """One column of the comparison: a paper method (with our agent) or one of our methods."""

    key: str
    title: str
    agent: str
    paper_method: str | None


@dataclasses.dataclass(frozen=True)
class Cell:
    """One (env, column, metric) of the comparison."""

    env_id: str
    column: Column
    metric: str
    ours: Result | None
    paper: PaperValue | None
    reason: str | None
    """Why ours is missing (None when we have it, or when the paper has no such cell either)."""

    @property
    def ours_text(self) -> str:
        if self.ours is None:
            return ""
        stat = self.ours.stat(self.metric)
        return fmt_stat(stat, metric_digits(self.metric, stat), STD_DIGITS)


@dataclasses.dataclass(frozen=True)
class Comparison:
    """Every cell of the comparison table, with its envs and columns in order."""

    envs: tuple[str, ...]
    columns: tuple[Column, ...]
    cells: Mapping[tuple[str, str, str], Cell]
    """(env id, column key, metric) → cell."""

    def cell(self, env_id: str, column: Column, metric: str) -> Cell:
        return self.cells[(env_id, column.key, metric)]


Reasoner = Callable[[str, str], str | None]
"""(agent name, env id) → why it cannot run here, or None."""


def compare(
    results: Sequence[Result],
    paper: PaperResults | None = None,
    reason: Reasoner | None = None,
) -> Comparison:
    """Pair our results with the paper's cells (see the module docstring for the rules)."""
    paper = paper or load_paper()
    reason = reason or (lambda agent, env: unavailable_reason(agent, env))
    # Per (env, agent), the run with the most episodes fills the paper column; variants never do.
    primary: dict[tuple[str, str], Result] = {}
    for r in results:
        if paper.method_of(r.agent) is None or r.is_variant:
            continue
        best = primary.get((r.env_id, r.agent))
        if best is None or r.episodes > best.episodes:
            primary[(r.env_id, r.agent)] = r
    columns = [Column(m, f"{m} ({paper.agents[m]})", paper.agents[m], m) for m in paper.methods]
    extra = [r for r in results if primary.get((r.env_id, r.agent)) is not r]
    # A method's column is its label, with the run id appended when the label covers
    # several runs on one env.
    labels: dict[tuple[str, str], set[str]] = {}
    for r in extra:
        labels.setdefault((r.env_id, r.name), set()).add(r.run_id)
    clash = {m for (_, m), ids in labels.items() if len(ids) > 1}
    extra_key = {
        r.run_id: f"{r.name}[{r.run_id[:6]}]" if r.name in clash else r.name for r in extra
    }
    seen: set[str] = set()
    for r in extra:
        key = extra_key[r.run_id]
        if key not in seen:
            seen.add(key)
            columns.append(Column(key, key, r.agent, None))
    envs = list(paper.envs) + list(
        dict.fromkeys(r.env_id for r in results if r.env_id not in paper.envs)
    )
    ours_by_key = {(r.env_id, extra_key[r.run_id]): r for r in extra}
    cells: dict[tuple[str, str, str], Cell] = {}
    for env in envs:
        for col in columns:
            if col.paper_method is not None:
                ours = primary.get((env, col.agent))
            else:
                ours = ours_by_key.get((env, col.key))
            why = None
            if ours is None and col.paper_method is not None and env in paper.envs:
                why = reason(col.agent, env) or NOT_IN_RUNS
            for metric in METRICS:
                pv = None
                if col.paper_method is not None:
                    pv = paper.cells.get((env, col.paper_method, metric))
                cells[(env, col.key, metric)] = Cell(env, col, metric, ours, pv, why)
    return Comparison(tuple(envs), tuple(columns), cells)


def _notes(comparison: Comparison) -> dict[str, str]:
    """Reason → its letter, in order of first appearance."""
    letters: dict[str, str] = {}
    for cell in comparison.cells.values():
        if cell.reason is not None and cell.reason not in letters:
            n = len(letters)
            letters[cell.reason] = chr(ord("a") + n) if n < 26 else f"n{n}"
    return letters


def paper_markdown(comparison: Comparison) -> str:
    """The paper's Table II layout; every cell ``ours (paper)``, notes for the cells not run."""
    notes = _notes(comparison)
    cols = comparison.columns
    lines = [
        "Each cell: ours (paper), mean ± std over seeds (the std with three digits, as the "
        "paper's appendix prints it; the paper's mean from Table II, its std from the appendix). "
        "`--`: undefined (no success, or no episode); `n/r [x]`: not run, note x below.",
        "",
        "| Env | Metric | " + " | ".join(c.title for c in cols) + " |",
        "|---|---|" + "---|" * len(cols),
    ]
    for env in comparison.envs:
        srs = [
            comparison.cell(env, c, "SR").ours
            for c in cols
            if comparison.cell(env, c, "SR").ours is not None
        ]
        best = max((r.success.mean or 0.0 for r in srs if r is not None), default=0.0)
        for i, metric in enumerate(METRICS):
            row = []
            for c in cols:
                cell = comparison.cell(env, c, metric)
                if cell.ours is not None:
                    ours = cell.ours_text
                    if metric == "SR" and best > 0 and cell.ours.success.mean == best:
                        ours = f"**{ours}**"
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
        lines += ["", "Not run:", ""]
        lines += [f"- [{letter}] {why}" for why, letter in notes.items()]
    return "\n".join(lines) + "\n"


PAPER_CSV_COLUMNS = (
    "env_id",
    "column",
    "agent",
    "paper_method",
    "metric",
    "ours_mean",
    "ours_std",
    "ours_seeds",
    "ours_episodes",
    "paper_mean",
    "paper_std",
    "not_run_reason",
)


def paper_csv(comparison: Comparison) -> str:
    """One row per (env, column, metric): ours, the paper's (as printed), and why not run."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(PAPER_CSV_COLUMNS)

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
                v(stat.mean) if stat else "",
                v(stat.std) if stat else "",
                cell.ours.num_seeds if cell.ours else "",
                cell.ours.episodes if cell.ours else "",
                cell.paper.mean_text if cell.paper else "",
                cell.paper.std_text if cell.paper else "",
                cell.reason or "",
            ]
        )
    return buf.getvalue()


def comparison_json(comparison: Comparison) -> list[dict[str, Any]]:
    """The cells as plain dicts (for the HTML report)."""
    out = []
    for cell in comparison.cells.values():
        out.append(
            {
                "env": cell.env_id,
                "column": cell.column.key,
                "agent": cell.column.agent,
                "paper_method": cell.column.paper_method,
                "metric": cell.metric,
                "ours": cell.ours_text if cell.ours is not None else None,
                "paper": cell.paper.text() if cell.paper is not None else None,
                "reason": cell.reason,
            }
        )
    return out
