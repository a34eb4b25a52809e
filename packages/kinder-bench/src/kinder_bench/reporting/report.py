"""Results tables (the paper's SR / Rwd / Inf-Time layout) as markdown and CSV, and a plot."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from kinder_bench.evaluation.envs import short_id
from kinder_bench.evaluation.metrics import Stat, Summary, aggregate
from kinder_bench.evaluation.results import load_config, load_records, write_text
from kinder_bench.evaluation.summary import CSV_FILE, csv_table, dedupe, run_commands, run_trainings

TABLE_FILE = "table.md"
PLOT_FILE = "success.png"
PAPER_TABLE_FILE = "paper_table.md"
PAPER_CSV_FILE = "paper_comparison.csv"


def load_run_dirs(run_dirs: Sequence[Path | str]) -> list[Mapping[str, Any]]:
    """Every record of the given run directories (duplicates dropped)."""
    records: list[Mapping[str, Any]] = []
    for d in run_dirs:
        if not (Path(d) / "results.jsonl").exists():
            raise FileNotFoundError(f"{d} is not a run directory (no results.jsonl)")
        records += load_records(d)
    return dedupe(records)


def _fmt(stat: Stat, digits: int) -> str:
    if stat.mean is None:
        return "--"
    text = f"{stat.mean:.{digits}f}"
    if stat.std is not None:
        text += f" ± {stat.std:.{digits}f}"
    return text


def _time_digits(stat: Stat) -> int:
    return 3 if stat.mean is not None and abs(stat.mean) < 0.1 else 2


def markdown_table(summaries: Sequence[Summary]) -> str:
    """The paper's layout: one column per method; per env, rows SR ↑, Rwd ↑, Inf-Time ↓
    (mean ± std across seeds; the best SR per env in bold)."""
    methods = list(dict.fromkeys(s.method for s in summaries))
    envs = list(dict.fromkeys(s.env_id for s in summaries))
    cell = {(s.env_id, s.method): s for s in summaries}
    lines = [
        "| Env | Metric | " + " | ".join(methods) + " |",
        "|---|---|" + "---|" * len(methods),
    ]
    for env in envs:
        present = [cell[(env, m)] for m in methods if (env, m) in cell]
        best = max((s.success.mean or 0.0 for s in present), default=0.0)
        rows: list[tuple[str, list[str]]] = [("SR ↑", []), ("Rwd ↑", []), ("Inf-Time (s) ↓", [])]
        for m in methods:
            s = cell.get((env, m))
            if s is None:
                for _, row in rows:
                    row.append("")
                continue
            sr = _fmt(s.success, 2)
            if s.success.mean is not None and s.success.mean == best and best > 0:
                sr = f"**{sr}**"
            rows[0][1].append(sr)
            rows[1][1].append(_fmt(s.reward, 1))
            rows[2][1].append(_fmt(s.inference_time, _time_digits(s.inference_time)))
        for i, (name, row) in enumerate(rows):
            label = short_id(env) if i == 0 else ""
            lines.append(f"| {label} | {name} | " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


def subtasks_table(summaries: Sequence[Summary]) -> str:
    """Per env with subtask milestones (:mod:`kinder_bench.evaluation.subtasks`), one row per
    method: the rate of episodes that reached each milestone (mean ± std across seeds); empty
    when no run tracked any."""
    tracked = [s for s in summaries if s.subtasks]
    lines: list[str] = []
    for env in dict.fromkeys(s.env_id for s in tracked):
        rows = [s for s in tracked if s.env_id == env]
        names = list(dict.fromkeys(n for s in rows for n in s.subtasks))
        lines += [
            f"Subtasks on {short_id(env)}: the rate of episodes that reached each.",
            "",
            "| Method | " + " | ".join(names) + " |",
            "|---|" + "---|" * len(names),
        ]
        for s in rows:
            cells = [_fmt(s.subtasks[n], 2) if n in s.subtasks else "" for n in names]
            lines.append(f"| {s.method} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def plot_success(summaries: Sequence[Summary], path: Path | str) -> Path:
    """A grouped bar chart of success rates per env and method, with ±std error bars."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    methods = list(dict.fromkeys(s.method for s in summaries))
    envs = list(dict.fromkeys(s.env_id for s in summaries))
    cell = {(s.env_id, s.method): s for s in summaries}
    x = np.arange(len(envs))
    width = 0.8 / max(1, len(methods))
    fig, ax = plt.subplots(figsize=(max(4.0, 1.6 * len(envs) * max(1, len(methods)) ** 0.5), 3.2))
    for i, m in enumerate(methods):
        means = [np.nan if (e, m) not in cell else (cell[(e, m)].success.mean or 0.0) for e in envs]
        stds = [(cell[(e, m)].success.std or 0.0) if (e, m) in cell else 0.0 for e in envs]
        # Error bars clipped to [0, 1]: a success rate cannot leave it.
        errs = [
            [0.0 if np.isnan(mu) else min(sd, mu) for sd, mu in zip(stds, means)],
            [0.0 if np.isnan(mu) else min(sd, 1.0 - mu) for sd, mu in zip(stds, means)],
        ]
        ax.bar(
            x + (i - (len(methods) - 1) / 2) * width, means, width, yerr=errs, capsize=3, label=m
        )
    ax.set_xticks(x, [short_id(e) for e in envs], rotation=20, ha="right")
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("success rate")
    ax.legend(fontsize="small", ncols=min(4, len(methods)))
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def write_report(
    run_dirs: Sequence[Path | str],
    out_dir: Path | str | None = None,
    plot: bool = True,
    paper: bool = False,
    html: bool = False,
    title: str = "KinDERBench report",
    note: str = "",
    first_episodes: int | None = None,
) -> tuple[str, dict[str, Path]]:
    """Aggregate run directories and write the report to ``out_dir`` (default: the first run
    directory): ``table.md``, ``summary.csv`` and (``plot``) ``success.png``; with ``paper`` the
    paper comparison ``paper_table.md`` and ``paper_comparison.csv``
    (:mod:`kinder_bench.reporting.paper`); with ``html`` the self-contained ``report.html``
    (:mod:`kinder_bench.reporting.html_report`, with the not-run paper cells when ``paper``).

    ``first_episodes`` aggregates only the first N episodes of each seed. A runner's episode
    ``k`` of seed ``s`` is the same instance whatever the run's episode count (its env seed is
    the ``k``-th draw of ``default_rng(s)``), so this compares a 5 × 50 run with a 5 × 10 run on
    the same 50 instances. Each row's command then says how the subset was taken, and the
    report is written to ``out_dir``, which must be given (a run directory's own summary stays
    the whole run's).

    Returns the markdown (the paper comparison's when ``paper``, else the results table) and the
    paths written.
    """
    records = load_run_dirs(run_dirs)
    if first_episodes is not None:
        if first_episodes < 1:
            raise ValueError(f"first_episodes {first_episodes}: expected an integer >= 1")
        if out_dir is None:
            raise ValueError(
                "first_episodes needs an output directory (--out): the run directory's "
                "summary.csv describes all its episodes"
            )
        records = [r for r in records if int(r["episode"]) < first_episodes]
    summaries = aggregate(records)
    if not summaries:
        raise ValueError(f"No results in {[str(d) for d in run_dirs]}")
    out = Path(out_dir if out_dir is not None else run_dirs[0])
    out.mkdir(parents=True, exist_ok=True)
    commands = run_commands(run_dirs)
    if first_episodes is not None:
        sources = " ".join(str(d) for d in run_dirs)
        subset = f"kinder bench report {sources} --first-episodes {first_episodes} --out {out}"
        commands = {
            s.run_id: f"{commands[s.run_id]}; then {subset}" if s.run_id in commands else subset
            for s in summaries
        }
    trainings = run_trainings(run_dirs)
    md = markdown_table(summaries)
    if subtasks := subtasks_table(summaries):
        md += "\n" + subtasks
    paths = {"table": out / TABLE_FILE, "csv": out / CSV_FILE}
    write_text(paths["table"], md)
    write_text(paths["csv"], csv_table(summaries, commands, trainings))
    if plot:
        paths["plot"] = plot_success(summaries, out / PLOT_FILE)
    comparison = None
    if paper or html:
        from kinder_bench.reporting.paper import (
            compare,
            paper_csv,
            paper_markdown,
            results_from_summaries,
        )

        results = results_from_summaries(summaries, commands, trainings)
        if paper:
            comparison = compare(results)
            md = paper_markdown(comparison)
            paths["paper_table"] = out / PAPER_TABLE_FILE
            paths["paper_csv"] = out / PAPER_CSV_FILE
            write_text(paths["paper_table"], md)
            write_text(paths["paper_csv"], paper_csv(comparison))
        if html:
            from kinder_bench.reporting.html_report import HTML_FILE, RunDirInfo, render_html

            dirs = [RunDirInfo(str(d), load_config(d)) for d in run_dirs]
            page = render_html(results, records, dirs, comparison, title=title, note=note)
            paths["html"] = write_text(out / HTML_FILE, page)
    return md, paths
