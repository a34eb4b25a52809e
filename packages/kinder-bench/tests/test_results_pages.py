"""The guard that no success rate lives only in prose: every SR a results page quotes is for a
(method, env) that a committed summary row holds."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from kinder_bench.metrics import Stat
from kinder_bench.paper import Result, results_from_csv
from kinder_bench.results_doc import summary_files, unbacked_quotes

REPO = Path(__file__).resolve().parents[3]
MOTION = "kinder/Motion2D-p0-v0"
BUTTON = "kinder/StickButton2D-b1-v0"


def _row(env_id: str, agent: str, method: str | None = None) -> Result:
    stat = Stat(0.5, 0.1, 5)
    return Result(env_id, method or agent, agent, "r" * 12, stat, stat, stat, 5, 250, 0, "cmd")


def _pages() -> dict[str, str]:
    pages = sorted((REPO / "benchmarks" / "results").glob("*.md"))
    pages += [REPO / "README.md", REPO / "docs" / "results.md"]
    return {str(p.relative_to(REPO)): p.read_text() for p in pages if p.exists()}


def test_every_quoted_success_rate_has_its_summary_row() -> None:
    files = summary_files(REPO / "benchmarks" / "results")
    if not files:
        pytest.skip("not in the repository checkout")
    results = [r for f in files for r in results_from_csv(f)]
    bad = unbacked_quotes(_pages(), results)
    assert not bad, (
        "SR quoted without a committed summary row (add the row, e.g. a transcribed "
        "one with its provenance, to benchmarks/results/*_summary.csv):\n"
        + "\n".join(map(str, bad))
    )


def test_the_guard_finds_tables_and_prose_and_spares_the_papers_figures() -> None:
    rows = [_row(MOTION, "ppo"), _row(BUTTON, "bilevel_planning")]
    page = "\n".join(
        [
            "## MBRL on Motion2D-p0",
            "",
            "| Env | Metric | mbrl | paper MBRL |",  # the report's layout
            "|---|---|---|---|",
            "| Motion2D-p0 | SR ↑ | **0.98 ± 0.04** | 0.16 |",
            "|  | Rwd ↑ | -62.7 | |",
            "",
            "| env | seeds × episodes | SR | paper SR |",  # a column named SR
            "|---|---|---|---|",
            "| kinder/StickButton2D-b1-v0 | 5 × 10 | 0.10 ± 0.07 (0.36) | 0.36 |",
            "",
            "PPO on StickButton2D-b1 reached SR 0.27 ± 0.07 (paper 0.14).",
            "The paper's SR 0.54 on Motion2D-p0 is its MPC.",
        ]
    )
    bad = unbacked_quotes({"page.md": page}, rows)
    assert [(q.line, q.figure, set(q.methods)) for q in bad] == [
        (5, "0.98", {"mbrl"}),
        (10, "0.10", {"mbrl"}),  # no method in the row: the heading's
        (12, "0.27", {"ppo"}),
    ]
    # With the rows, nothing is left; the paper's figures never needed one.
    more = [*rows, _row(MOTION, "mbrl"), _row(BUTTON, "mbrl"), _row(BUTTON, "ppo")]
    assert unbacked_quotes({"page.md": page}, more) == []
    # A labelled variant's row backs a quote of its label.
    dense = dataclasses.replace(_row(MOTION, "ppo", "ppo-dense"))
    quote = "| Env | Metric | ppo-dense |\n|---|---|---|\n| Motion2D-p0 | SR ↑ | 0.68 |"
    assert unbacked_quotes({"p.md": quote}, [dense]) == []
    assert len(unbacked_quotes({"p.md": quote}, [_row(MOTION, "sac")])) == 1
